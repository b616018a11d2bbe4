"""A home held in memory while a robot runs: answers in a millisecond, teachings never lost.

:class:`LiveHome` is what ``spco serve`` serves, and what a program on the robot (a ROS node) can
hold itself::

    from spco.service import LiveHome

    with LiveHome("home.spco") as live:          # takes the home's lock: `spco teach` is refused
        live.what(1.2, -0.4, 1.57)["names"]      # [{"name": "kitchen", "probability": …}, …]
        live.where("kitchen", n=5)["positions"]  # [{"x": …, "y": …, "theta": …, "probability": …}, …]
        live.teach(x=1.2, y=-0.4, theta=1.57, sentence="this is the study")   # durable when it returns
        live.teach(id=12, sentence="this is Emma's room")

Readers (:meth:`~LiveHome.where`, :meth:`~LiveHome.what`, :meth:`~LiveHome.regions`,
:attr:`~LiveHome.home`) answer from the last committed snapshot, an immutable
:class:`~spco.knowledge.HomeModel`, and never wait for a teaching. Teachings go to the home's one
writer (:mod:`spco.service.writer`, by default in a process of its own so that it does not hold
this process's global lock), which applies the teachings that arrive together as one batch,
appends them to the journal beside the home file and ``fsync``-s it (:mod:`spco.service.journal`),
then publishes the new snapshot: :meth:`~LiveHome.teach` returns after that, and the next answer
uses it. The journal is compacted into the home file now and then and on :meth:`~LiveHome.close`.

Events (:meth:`~LiveHome.subscribe`): ``{"type": "taught", "seq", "op", "id", "sentence", …}``
after a teaching, ``{"type": "undone", "seq", "undoes", …}`` after an undo and ``{"type":
"answer", "kind": "what" | "where", …}`` after an answer (only built while someone listens).
"""

from __future__ import annotations

import contextlib
import json
import os
import queue
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from dataclasses import replace
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from spco import knowledge as kn
from spco.data.lexicon import lexicon
from spco.errors import ConfigurationError, SpcoError, TeachingLimitError, TeachingRateError
from spco.features.pixels import SERVED_MAX_PIXELS, decode_image
from spco.knowledge import locking
from spco.knowledge.requests import (
    MAX_POSES,
    MAX_QUESTIONS,
    MAX_TOP,
    Ask,
    Pose,
    Teach,
    Undo,
    View,
    What,
    Where,
)
from spco.service.answers import ask_answer, regions_answer, what_answer, where_answer
from spco.service.journal import TornRecordWarning, journal_path
from spco.service.teaching import ConflictError, NotFoundError, served_info
from spco.service.writer import ProcessWriter, ThreadWriter, WriterUnavailableError

__all__ = ["MAX_POSES", "MAX_QUESTIONS", "MAX_TOP", "LiveHome", "Subscription"]

_RESULT_ERRORS: dict[str, type[SpcoError]] = {
    "NotFoundError": NotFoundError, "ConflictError": ConflictError,
    "WriterUnavailableError": WriterUnavailableError, "ConfigurationError": ConfigurationError,
}


class Subscription:
    """Events of a :class:`LiveHome`, from :meth:`LiveHome.subscribe`: a queue, or a callback.

    Without a callback, events wait in a queue of ``maxsize``; when it is full the oldest is dropped
    (``dropped`` counts them), so a slow reader never slows the home down. Iterate it, or
    :meth:`get` with a timeout; :meth:`close` (or leaving a ``with`` block) ends it.
    """

    def __init__(self, owner: LiveHome, callback: Callable[[dict[str, Any]], None] | None,
                 maxsize: int, types: frozenset[str] | None) -> None:
        self._owner = owner
        self._callback = callback
        self.types = types
        self._queue: queue.Queue[dict[str, Any] | None] = queue.Queue(maxsize=max(1, maxsize))
        self.dropped = 0
        self.closed = False

    def _deliver(self, event: dict[str, Any]) -> None:
        if self.types is not None and event["type"] not in self.types:
            return
        if self._callback is not None:
            try:
                self._callback(event)
            except Exception as exc:  # a listener's bug must not break the home
                warnings.warn(f"an event callback failed: {type(exc).__name__}: {exc}", RuntimeWarning,
                              stacklevel=2)
            return
        while True:
            try:
                self._queue.put_nowait(event)
                return
            except queue.Full:
                with contextlib.suppress(queue.Empty):
                    self._queue.get_nowait()
                    self.dropped += 1

    def get(self, timeout: float | None = None) -> dict[str, Any]:
        """The next event; raises ``queue.Empty`` after ``timeout`` seconds, ``EOFError`` once closed."""
        if self.closed and self._queue.empty():
            raise EOFError("the subscription is closed")
        event = self._queue.get(timeout=timeout)
        if event is None:
            raise EOFError("the subscription is closed")
        return event

    def __iter__(self) -> Iterator[dict[str, Any]]:
        while True:
            try:
                yield self.get()
            except EOFError:
                return

    def close(self) -> None:
        """Stop receiving events (an iterating reader ends)."""
        if not self.closed:
            self.closed = True
            self._owner._unsubscribe(self)
            with contextlib.suppress(queue.Full):
                self._queue.put_nowait(None)

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class LiveHome:
    """A served home: the last committed snapshot for readers, one writer for teachings, a journal.

    Parameters
    ----------
    path: the home file (``spco adapt``). Its journal is ``<path>.journal``.
    seed: base seed of the teachings (each batch's seed derives from it and its first seq and is
        journalled); ``None``: fresh entropy.
    sweeps: Gibbs sweeps per teaching (10, as ``spco teach``).
    writer: ``"process"`` (default: a writer process; readers never wait for Python's global lock)
        or ``"thread"`` (in this process: simpler, readers wait a few ms at p99 during teachings).
    holder: how other writers are told who holds the home (``spco serve`` gives its address).
    max_pixels: the largest image accepted.
    compact_records, compact_idle: when the writer compacts (see :mod:`spco.service.writer`).
    undo_limit: how many of the last teachings can be undone exactly (100).
    limits: what a teaching may bring (:class:`spco.knowledge.TeachingLimits`, ``None``: no limits);
        a teaching beyond them raises :class:`~spco.errors.TeachingLimitError` (HTTP 422) or
        :class:`~spco.errors.TeachingRateError` (HTTP 429), naming the limit.

    Opening takes the home's write lock for as long as it is open (:func:`spco.knowledge.locking.hold`:
    ``spco teach`` on it is refused at once, naming ``holder``), replays the journal's teachings
    that the file lacks (a torn last record is dropped with a :class:`TornRecordWarning`) and
    compacts. Raises :class:`~spco.knowledge.locking.HomeServedError` if another server holds it, and
    :class:`~spco.errors.ModelFileError` / :class:`~spco.service.journal.JournalError` for a bad
    file or journal.
    """

    def __init__(self, path: str | PathLike[str], *, seed: int | None = None,
                 sweeps: int = kn.DEFAULT_TEACH_SWEEPS, writer: str = "process", holder: str | None = None,
                 max_pixels: int = SERVED_MAX_PIXELS, compact_records: int | None = None,
                 compact_idle: float | None = None, undo_limit: int | None = None,
                 limits: kn.TeachingLimits | None = kn.DEFAULT_LIMITS) -> None:
        if writer not in ("process", "thread"):
            raise ConfigurationError(f"writer must be 'process' or 'thread', got {writer!r}")
        self.path = Path(path)
        self.journal_path = journal_path(path)
        self.max_pixels = max_pixels
        self.holder = holder or f"a LiveHome of process {os.getpid()}"
        self._subscribers: list[Subscription] = []
        self._subscribers_lock = threading.Lock()
        self._extractor: Any = None
        self._extractor_key: str | None = None
        self._regions: tuple[int, dict[str, Any]] | None = None
        self._closed = False
        self._quiet = threading.Event()
        self._lock = locking.hold(path, self.holder)
        options = {"seed": seed, "sweeps": sweeps, "compact_records": compact_records,
                   "compact_idle": compact_idle, "undo_limit": undo_limit}
        options = {k: v for k, v in options.items() if v is not None}
        options["limits"] = limits
        # WordNet, loaded while the writer starts: `where` of a name nobody said looks it up there
        words = threading.Thread(target=lexicon, name="spco-lexicon", daemon=True)
        words.start()
        try:
            if writer == "process":
                self._writer: ProcessWriter | ThreadWriter = ProcessWriter(
                    path, self._on_applied, lock_fd=self._lock.fd, holder=self.holder, **options)
            else:
                self._writer = ThreadWriter(path, self._on_applied, lock=self._lock, **options)
        except BaseException:
            self._lock.release()
            raise
        words.join()
        self._snapshot: kn.HomeModel = self._writer.first_snapshot
        #: what opening found: ``replayed`` journal records, ``torn`` (what was dropped, or None)
        self.startup: dict[str, Any] = dict(self._writer.startup)
        if self.startup.get("torn"):
            warnings.warn(f"{self.journal_path}: {self.startup['torn']}; it was never acknowledged and is "
                          "dropped", TornRecordWarning, stacklevel=2)
        self.started = time.time()

    # ------------------------------------------------------------------ reading
    @property
    def home(self) -> kn.HomeModel:
        """The last committed snapshot (immutable; a teaching publishes a new one)."""
        return self._snapshot

    @property
    def writer_pid(self) -> int:
        """The writer process's id (this process's for a thread writer)."""
        return int(getattr(self._writer, "pid", os.getpid()))

    # ------------------------------------------------------------------ the questions
    def answer(self, request: Where | What | Ask) -> dict[str, Any]:
        """Answer a checked question (:mod:`spco.knowledge.requests`) from the current snapshot: the
        one way every reader (HTTP, ROS, the methods below) asks the home.

        - :class:`~spco.knowledge.requests.Where`: the payload of ``spco where HOME NAME -n N --json``
          (:func:`spco.service.answers.where_answer`): ``{"home", "name", "region",
          "region_probability", "learnt", "support", "positions"}``, ``positions`` most probable
          first. Raises :class:`~spco.model.prediction.UnknownNameError` for a name the home cannot use.
        - :class:`~spco.knowledge.requests.What`: the payload of ``spco what HOME … --json``
          (:func:`spco.service.answers.what_answer`): ``{"home", "pose", "vision", "ranked_by",
          "names", …}``, ``"warning"`` too for a pose off the map; a pose far off it or a view
          that does not fit the home raise :class:`ConfigurationError`.
        - :class:`~spco.knowledge.requests.Ask`: :func:`spco.service.answers.ask_answer`.
        """
        home = self._snapshot
        if isinstance(request, Where):
            answer = where_answer(home, request.name, n=request.n, seed=request.seed)
            if self._listening("answer"):
                self._publish({"type": "answer", "kind": "where", "name": answer["name"],
                               "positions": answer["positions"][:3]})
            return answer
        if isinstance(request, What):
            knowledge = home.knowledge
            answer = what_answer(home, self._decoded(request),
                                 extractor=lambda: self._extractor_of(knowledge))
            if self._listening("answer"):
                self._publish({"type": "answer", "kind": "what", "pose": answer["pose"],
                               "vision": answer["vision"], "names": answer["names"]})
            return answer
        if isinstance(request, Ask):
            return ask_answer(home, request.n, criterion=request.criterion, unsure_only=request.unsure_only)
        raise ConfigurationError(f"not a question: {type(request).__name__} (Where, What or Ask)")

    def _decoded(self, request: What | Teach) -> Any:
        """``request`` with its view's image bytes decoded into pixels where it entered, in the caller's
        thread (:func:`spco.features.pixels.decode_image`: its size checked from its header first,
        against ``max_pixels``; a bad image raises at once); the home turns the pixels into counts."""
        view = request.view
        if view is None or view.image is None:
            return request
        pixels = decode_image(view.image, view.encoding, width=view.width, height=view.height,
                              max_pixels=self.max_pixels)
        return replace(request, view=View(image=pixels, encoding="bgr8"))

    def _extractor_of(self, knowledge: kn.Knowledge) -> Any:
        """``knowledge``'s extractor, built once and kept while the served knowledge stays the same."""
        key = json.dumps(knowledge.extractor, sort_keys=True)
        if self._extractor is None or key != self._extractor_key:
            self._extractor, self._extractor_key = knowledge.image_extractor(), key
        return self._extractor

    def where(self, name: str, n: int = 10, *, seed: int = 0) -> dict[str, Any]:
        """Poses for the place ``name`` (read like a sentence: ``"Living Room"`` → ``living room``):
        :meth:`answer` of :class:`~spco.knowledge.requests.Where` ``(name, n, seed)``; ``n`` poses,
        1…:data:`~spco.knowledge.requests.MAX_POSES`, each ``{"x", "y", "theta", "probability"}``."""
        return self.answer(Where(name, n, seed))

    def what(self, x: float, y: float, theta: float, *, image: Any = None, encoding: str | None = None,
             visual: Any = None, top: int = 3) -> dict[str, Any]:
        """The ``top`` place names at pose (x, y, θ): :meth:`answer` of
        :class:`~spco.knowledge.requests.What`.

        ``image``, ``encoding``: the camera view (optional): JPEG/PNG bytes, or an (H, W, 3) / (H, W)
        uint8 array in ``encoding`` ``bgr8`` (default for three channels), ``rgb8`` or ``mono8``;
        ``visual``: the view's visual counts (D,) instead; ``top``: 1…:data:`MAX_TOP` names.
        """
        return self.answer(What(Pose(x, y, theta), _view(image, encoding, visual), top))

    def ask(self, n: int = 5, *, unsure_only: bool = False) -> dict[str, Any]:
        """Where to ask "what is this place?" next (the payload of ``spco ask HOME --n N --json``):
        :meth:`answer` of :class:`~spco.knowledge.requests.Ask`; ``n`` questions,
        1…:data:`MAX_QUESTIONS`, each ``{"id", "x", "y", "theta", "gain", "reason", "names",
        "unknown", …}``, best first."""
        return self.answer(Ask(n, unsure_only))

    def regions(self) -> dict[str, Any]:
        """The learnt regions, concepts and samples of the current snapshot, for drawing them.

        Returns
        -------
        :func:`spco.service.answers.regions_answer` (regions with ``mean`` [x, y], 2×2
        ``covariance``, 95 % ``ellipse``, ``concept``, ``names`` with ``p``; ``concepts``;
        ``samples``; ``extent``) plus ``teachings`` and ``seq``. Computed once per snapshot.
        """
        home = self._snapshot
        cached = self._regions
        if cached is not None and cached[0] == id(home):
            return cached[1]
        answer = regions_answer(home)
        answer["teachings"] = int(served_info(home).get("teachings", 0))
        answer["seq"] = int(served_info(home).get("last_seq", 0))
        self._regions = (id(home), answer)
        return answer

    def health(self) -> dict[str, Any]:
        """``{"status", "home", "file", "samples", "taught", "teachings", "seq", "names", "writer",
        "uptime_seconds"}``; ``status`` is ``"ok"``, or ``"degraded"`` when the writer is gone
        (answers go on, teachings are refused)."""
        home = self._snapshot
        served = served_info(home)
        alive = self._writer.alive
        return {"status": "ok" if alive else "degraded", "home": home.name, "file": str(self.path),
                "samples": home.n_samples, "taught": home.n_taught,
                "teachings": int(served.get("teachings", 0)),
                "seq": int(served.get("last_seq", 0)), "names": len(home.known_names),
                "writer": {"alive": alive, "pid": self.writer_pid,
                           "kind": "process" if isinstance(self._writer, ProcessWriter) else "thread"},
                "uptime_seconds": round(time.time() - self.started, 1)}

    # ------------------------------------------------------------------ teaching
    def _submit(self, request: Teach | Undo) -> Future[dict[str, Any]]:
        """Send ``request`` to the writer; the future gets the answer, or the error it raised."""
        answer: Future[dict[str, Any]] = Future()
        if self._closed:
            answer.set_exception(WriterUnavailableError("the served home is closed"))
            return answer

        def done(result_future: Future[dict[str, Any]]) -> None:
            try:
                result = result_future.result()
            except BaseException as exc:
                answer.set_exception(exc)
                return
            if result.get("ok"):
                answer.set_result({k: v for k, v in result.items() if k != "ok"})
            elif result.get("kind") == "InternalError":
                answer.set_exception(RuntimeError(result["error"]))
            else:
                kind = result.get("kind", "")
                if kind in ("TeachingLimitError", "TeachingRateError"):
                    error_class = TeachingRateError if kind == "TeachingRateError" else TeachingLimitError
                    answer.set_exception(error_class(
                        result["error"], result.get("limit", ""), int(result.get("value", 0)),
                        int(result.get("allowed", 0))))
                else:
                    answer.set_exception(_RESULT_ERRORS.get(kind, SpcoError)(result["error"]))

        self._writer.submit(request).add_done_callback(done)
        return answer

    def submit(self, request: Teach | Undo) -> Future[dict[str, Any]]:
        """Hand a checked teaching or undo (:mod:`spco.knowledge.requests`) to the writer; a future of
        its answer (or of its error). The one way every teacher (HTTP, ROS, the methods below)
        teaches the home: the writer teaches it with one call of the home
        (:func:`spco.service.teaching.teach_batch`, :func:`spco.knowledge.teach_requests`), which
        checks what needs the home (a known sample, the pose on the map, the view's counts) and
        turns an image into counts. A view's image bytes are decoded here, in the caller's thread
        (:func:`spco.features.pixels.decode_image`, its size checked against ``max_pixels``: a bad
        image raises at once)."""
        if isinstance(request, Undo):
            return self._submit(request)
        if not isinstance(request, Teach):
            raise ConfigurationError(f"not a teaching: {type(request).__name__} (Teach or Undo)")
        return self._submit(self._decoded(request))

    def submit_teach(self, *, sentence: str | None = None, id: int | None = None, x: float | None = None,
                     y: float | None = None, theta: float | None = None, image: Any = None,
                     encoding: str | None = None, visual: Any = None) -> Future[dict[str, Any]]:
        """:meth:`teach` without waiting: :meth:`submit` of a :class:`~spco.knowledge.requests.Teach`."""
        return self.submit(_teaching(sentence, id, x, y, theta, _view(image, encoding, visual)))

    def teach(self, *, sentence: str | None = None, id: int | None = None, x: float | None = None,
              y: float | None = None, theta: float | None = None, image: Any = None,
              encoding: str | None = None, visual: Any = None, timeout: float | None = None
              ) -> dict[str, Any]:
        """Teach the home: a ``sentence`` for the known sample ``id``, or a new observation at pose
        (``x``, ``y``, ``theta``) with an optional view (``image`` or ``visual``) and ``sentence``.

        Without a view the observation holds the pose and the words only. Returns when the teaching
        is in the journal on disk (``fsync``) and in the snapshot the next answer uses:
        ``{"seq", "op", "id", "sentence", "teachings", "samples", "taught", "new_words", "notes",
        "batch", "seconds", …}`` (``id``: the sample taught or added; ``notes``: why a new word is
        not a place name yet). Raises :class:`~spco.service.teaching.NotFoundError` (no such
        sample), :class:`~spco.service.teaching.ConflictError` (an id taken),
        :class:`ConfigurationError` (a bad pose, view or sentence) or
        :class:`~spco.service.writer.WriterUnavailableError`.
        """
        return self.submit_teach(sentence=sentence, id=id, x=x, y=y, theta=theta, image=image,
                                 encoding=encoding, visual=visual).result(timeout)

    def submit_undo(self, seq: int) -> Future[dict[str, Any]]:
        """:meth:`undo` without waiting: :meth:`submit` of an :class:`~spco.knowledge.requests.Undo`."""
        return self.submit(Undo(seq))

    def undo(self, seq: int, *, timeout: float | None = None) -> dict[str, Any]:
        """Undo teaching ``seq``: restore the sentence it replaced, or remove the sample it added; as
        durable as a teaching. Returns ``{"seq" (the undo's), "undoes", "teachings", …}``. Raises
        :class:`~spco.service.teaching.NotFoundError` for an unknown seq and
        :class:`~spco.service.teaching.ConflictError` for one undone already or changed since."""
        return self.submit_undo(seq).result(timeout)

    def _on_applied(self, pairs: list[tuple[dict[str, Any], dict[str, Any]]], snapshot: kn.HomeModel | None
                    ) -> None:
        if snapshot is not None:
            self._snapshot = snapshot
        if not self._subscribers:
            return
        for _, result in pairs:
            if result.get("ok"):
                kind = "undone" if result.get("op") == "undo" else "taught"
                self._publish({"type": kind, **{k: v for k, v in result.items() if k != "ok"}})

    # ------------------------------------------------------------------ events
    def subscribe(self, callback: Callable[[dict[str, Any]], None] | None = None, maxsize: int = 1000,
                  types: set[str] | None = None) -> Subscription:
        """Receive the home's events (``taught``, ``undone``, ``answer``; see the module), or only
        those whose type is in ``types``.

        With ``callback``, it is called with each event in the thread that publishes it (keep it
        short: hand the event on); without, events wait in the returned :class:`Subscription`.
        """
        subscription = Subscription(self, callback, maxsize, None if types is None else frozenset(types))
        with self._subscribers_lock:
            self._subscribers = [*self._subscribers, subscription]
        return subscription

    def _unsubscribe(self, subscription: Subscription) -> None:
        with self._subscribers_lock:
            self._subscribers = [s for s in self._subscribers if s is not subscription]

    def _listening(self, kind: str) -> bool:
        if kind == "answer" and self._quiet.is_set():
            return False
        return any(s.types is None or kind in s.types for s in self._subscribers)

    @contextlib.contextmanager
    def quiet(self) -> Iterator[None]:
        """Answers given meanwhile publish no ``answer`` event (``spco serve``'s warm-up before it
        says it is ready: its own requests are nobody's answers; teachings still publish theirs)."""
        self._quiet.set()
        try:
            yield
        finally:
            self._quiet.clear()

    def _publish(self, event: dict[str, Any]) -> None:
        event.setdefault("time", time.time())
        for subscription in self._subscribers:
            subscription._deliver(event)

    # ------------------------------------------------------------------ closing
    def close(self) -> None:
        """Finish the queued teachings, compact the journal into the home file, release the lock."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.close()
        finally:
            self._lock.release()
            for subscription in list(self._subscribers):
                subscription.close()

    def __enter__(self) -> LiveHome:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        home = self._snapshot
        return f"<LiveHome {self.path} ({home.name}: {home.n_samples} samples, {home.n_taught} taught)>"


def _view(image: Any, encoding: str | None, visual: Any) -> View | None:
    """The :class:`~spco.knowledge.requests.View` of the library methods' keyword arguments."""
    if image is None and visual is None and encoding is None:
        return None
    if isinstance(image, np.ndarray) and encoding is None:  # an array says its shape; bytes do not
        encoding = "mono8" if image.ndim == 2 else "bgr8"
    return View(image=image, encoding=encoding, visual=visual)


def _teaching(sentence: str | None, id: int | None, x: float | None, y: float | None, theta: float | None,
              view: View | None) -> Teach:
    pose = (x, y, theta)
    if id is None and any(v is not None for v in pose):
        if any(v is None for v in pose):
            raise ConfigurationError("a new observation needs all of x, y and theta")
        return Teach(sentence=sentence, pose=Pose(x, y, theta), view=view)  # type: ignore[arg-type]
    if id is not None and (any(v is not None for v in pose) or view is not None):
        raise ConfigurationError("give either id and sentence (a known sample) or a pose x, y, theta "
                                 "with an optional image (a new observation), not both")
    return Teach(sentence=sentence, id=id)
