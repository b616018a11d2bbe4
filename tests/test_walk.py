"""The walk of a request through the layers: checked once where it enters, one call of the home, then
the journal (docs/development.md, "One boundary: a request's way in").

A profiler in every thread records each call from code of ``spco.service`` into code of
``spco.knowledge`` while one ``POST /teach`` is served (a thread writer: the same
:class:`~spco.service.writer.HomeWriter` as the writer process, in this process where it can be
traced). The request types of ``spco.knowledge.requests`` are the boundary itself (building one is
the check) and reading a property of the home is not a call into its work; every other call
counts. Up to the journal's append there must be exactly one: the home's teaching.
"""

from __future__ import annotations

import inspect
import pkgutil
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import CodeType, FrameType
from typing import Any

import cv2
import numpy as np
import pytest
from serve_helpers import build_home, copy_home

import spco.knowledge
from spco import knowledge as kn
from spco.knowledge.requests import Pose
from spco.service import LiveHome
from spco.service.journal import Journal

pytest.importorskip("fastapi", reason="spco serve needs its extra: pip install -e '.[serve]'")
from fastapi.testclient import TestClient

from spco.service.app import create_app

KNOWLEDGE = str(Path(spco.knowledge.__file__).parent) + "/"
SERVICE = str(Path(spco.knowledge.__file__).parents[1] / "service") + "/"
REQUESTS = KNOWLEDGE + "requests.py"


def _property_code() -> set[CodeType]:
    """The code of every property (and cached property) of spco.knowledge's classes: reads, not calls."""
    import importlib

    codes: set[CodeType] = set()
    for info in pkgutil.iter_modules(spco.knowledge.__path__):
        module = importlib.import_module(f"spco.knowledge.{info.name}")
        for _, cls in inspect.getmembers(module, inspect.isclass):
            for value in vars(cls).values():
                function = getattr(value, "fget", None) or getattr(value, "func", None)
                if function is not None and hasattr(function, "__code__"):
                    codes.add(function.__code__)
    return codes


class Walk:
    """The calls from ``spco.service`` into ``spco.knowledge`` while recording, in every thread, up to
    the first :meth:`Journal.append`; and how often a pose was checked."""

    def __init__(self) -> None:
        self.recording = False
        self.calls: list[str] = []
        self.journalled = False
        self.poses_checked = 0
        self._skip = _property_code()
        self._append = Journal.append.__code__
        self._pose = Pose.__post_init__.__code__
        self._lock = threading.Lock()

    def __call__(self, frame: FrameType, event: str, arg: Any) -> None:
        if event != "call" or not self.recording:
            return
        code = frame.f_code
        with self._lock:
            if code is self._append:
                self.journalled = True
            elif code is self._pose:
                self.poses_checked += 1
            elif (not self.journalled and code.co_filename.startswith(KNOWLEDGE)
                  and code.co_filename != REQUESTS and code not in self._skip):
                caller = frame.f_back
                if caller is not None and caller.f_code.co_filename.startswith(SERVICE):
                    module = code.co_filename[len(KNOWLEDGE):-3]
                    self.calls.append(f"spco.knowledge.{module}.{code.co_qualname}")

    @contextmanager
    def installed(self) -> Iterator[Walk]:
        """The profiler in this thread and every thread started meanwhile (the writer, the server's)."""
        threading.setprofile(self)
        sys.setprofile(self)
        try:
            yield self
        finally:
            sys.setprofile(None)
            threading.setprofile(None)  # type: ignore[arg-type]

    @contextmanager
    def recorded(self) -> Iterator[Walk]:
        """Record what happens inside the block (one request)."""
        self.calls, self.journalled, self.poses_checked = [], False, 0
        self.recording = True
        try:
            yield self
        finally:
            self.recording = False


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_home(tmp_path_factory.mktemp("walk"))


def _jpeg(seed: int) -> str:
    import base64

    pixels = np.random.default_rng(seed).integers(0, 256, (96, 128, 3), dtype=np.uint8)
    ok, data = cv2.imencode(".jpg", pixels)
    assert ok
    return base64.b64encode(data.tobytes()).decode()


def test_a_teaching_crosses_into_the_home_once_before_the_journal(built: Path, tmp_path: Path) -> None:
    home = copy_home(built, tmp_path)
    sample = int(kn.load_home_model(home).ids[0])
    walk = Walk()
    with walk.installed(), LiveHome(home, writer="thread", seed=0) as live, \
            TestClient(create_app(live), base_url="http://127.0.0.1") as client:
        bodies = [{"x": 0.2, "y": 0.1, "theta": 0.5, "sentence": "this is the larder", "image": _jpeg(1)},
                  {"x": 0.3, "y": 0.2, "theta": 0.1, "sentence": "the pantry is here"},
                  {"id": sample, "sentence": "this is the scullery"}]
        for body in bodies:
            with walk.recorded():
                answer = client.post("/teach", json=body)
            assert answer.status_code == 200, answer.text
            assert walk.journalled, "the teaching never reached the journal"
            assert walk.calls == ["spco.knowledge.updating.teach_requests"], (body.keys(), walk.calls)
            assert walk.poses_checked == ("x" in body), "a pose is checked once, where it enters"
        # a request the home refuses (no such sample) crosses once too, and reaches no journal
        with walk.recorded():
            refused = client.post("/teach", json={"id": 10**9, "sentence": "this is the attic"})
        assert refused.status_code == 404, refused.text
        assert walk.calls == ["spco.knowledge.updating.teach_requests"] and not walk.journalled


def test_each_question_is_one_call_of_the_home(built: Path, tmp_path: Path) -> None:
    """``where``, ``what`` (with a view as an image) and ``ask``: one function of the home each."""
    home = copy_home(built, tmp_path)
    walk = Walk()
    with walk.installed(), LiveHome(home, writer="thread", seed=0) as live, \
            TestClient(create_app(live), base_url="http://127.0.0.1") as client:
        name = live.home.known_names[0]
        view = {"x": 0.2, "y": 0.1, "theta": 0.5, "image": _jpeg(2)}
        assert client.post("/what", json=view).status_code == 200  # the extractor built (once per home)
        questions = [("/where", {"name": name, "n": 3}, "spco.knowledge.queries.where"),
                     ("/what", view, "spco.knowledge.queries.what_request"),
                     ("/what", {"x": 0.2, "y": 0.1, "theta": 0.5}, "spco.knowledge.queries.what_request"),
                     ("/ask", {"n": 2}, "spco.knowledge.asking.ask")]
        for path, arguments, call in questions:
            with walk.recorded():
                if path == "/what" and "image" in arguments:
                    answer = client.post(path, json=arguments)
                else:
                    answer = client.get(path, params=arguments)
            assert answer.status_code == 200, answer.text
            # an ask's questions say themselves (Question.to_dict): the answer's own form, not a question
            calls = [c for c in walk.calls if not c.endswith("Question.to_dict")]
            assert calls == [call], (path, walk.calls)


def test_the_walk_tracer_sees_a_second_call(built: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                            ) -> None:
    """The tracer itself: a service that asks the home twice before the journal is caught."""
    import spco.service.teaching as teaching
    import spco.service.writer as writer
    from spco.service.answers import regions_answer

    original = teaching.teach_batch

    def twice(home: kn.HomeModel, *args: Any, **kwargs: Any) -> Any:
        regions_answer(home)  # the service asks the home something else first
        return original(home, *args, **kwargs)

    monkeypatch.setattr(writer, "teach_batch", twice)
    home = copy_home(built, tmp_path)
    walk = Walk()
    with walk.installed(), LiveHome(home, writer="thread", seed=0) as live:
        with walk.recorded():
            live.teach(x=0.2, y=0.1, theta=0.5, sentence="this is the larder")
    assert walk.journalled
    assert len(walk.calls) >= 2 and walk.calls[-1] == "spco.knowledge.updating.teach_requests", walk.calls
