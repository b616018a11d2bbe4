"""`spco serve` says it is ready once every route has answered once (issue 30: the first teaching after
ready costs what any other does): the warm-up's requests reach every route, and teach nothing."""

from __future__ import annotations

import contextlib
from pathlib import Path

import pytest
from serve_helpers import Server, build_home, copy_home

from spco import knowledge as kn
from spco.service.client import Client
from spco.service.server import warm_requests


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_home(tmp_path_factory.mktemp("ready"))


def test_ready_after_every_route_answered_once_and_nothing_taught(built: Path, tmp_path: Path) -> None:
    home = copy_home(built, tmp_path)
    model = kn.load_home_model(home)
    server = Server(home)
    try:
        client = Client(server.url)
        health = client.health()
        assert health["teachings"] == 0 and health["seq"] == 0  # the warm-up taught nothing
        assert health["samples"] == model.n_samples
        statuses = warm_requests(server.url, None, model)
        # health, page, where, what (GET, POST, POST with a view), ask, regions, openapi: answered;
        # a teaching of a sample the home does not have and an undo of a seq never given: refused by
        # the writer (404); an observation without theta: refused by validation
        assert statuses == [200, 200, 200, 200, 200, 200, 200, 200, 200, 404, 422, 404], statuses
        assert client.health()["teachings"] == 0
        first = client.teach(id=int(model.ids[0]), sentence="this is the quokka room")
        assert first["seq"] == 1  # the first real teaching is the first the home records
    finally:
        assert server.stop() == 0


def test_answers_given_while_quiet_publish_no_event(built: Path, tmp_path: Path) -> None:
    from spco.service import LiveHome

    home = copy_home(built, tmp_path)
    name = kn.load_home_model(home).known_names[0]
    with LiveHome(home, writer="thread", seed=0) as live, live.subscribe() as events:
        with live.quiet():
            live.where(name, n=3)
        live.what(0.0, 0.0, 0.0)
        event = events.get(timeout=10)
        assert event["type"] == "answer" and event["kind"] == "what"  # the where above published nothing


def test_wordnet_is_loaded_before_ready(built: Path, tmp_path: Path, wordnet: object,
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A word that the lexicon's facts files lack is looked up in WordNet: loading it takes seconds,
    so a served home loads it before it says it is ready, not in the first such teaching or `where`."""
    from spco.data import lexicon
    from spco.model.prediction import UnknownNameError
    from spco.service import LiveHome

    monkeypatch.setenv("SPCO_CACHE_DIR", str(tmp_path / "cache"))  # the lexicon's files only (Numba's is set)
    home = copy_home(built, tmp_path)
    with LiveHome(home, writer="thread", seed=0):
        pass  # the facts of what the start-up itself asks are now on file
    lexicon._load.cache_clear()
    with LiveHome(home, writer="thread", seed=0) as live:
        assert lexicon._load.cache_info().currsize == 1  # loaded while opening, though no word needed it
        live.teach(sentence="this is the quokka room", id=int(live.home.ids[0]))
        with contextlib.suppress(UnknownNameError):  # a name nobody said: looked up in WordNet
            live.where("solarium", n=1)
        assert lexicon._load.cache_info().misses == 1  # the new word and name: no second load
