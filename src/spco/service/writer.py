"""The one writer of a served home: teachings in batches, journalled before they are acknowledged.

:class:`HomeWriter` owns the home's mutable state. On start it reads the home file and its journal
(:mod:`spco.service.journal`), replays the teachings the file lacks (:func:`~spco.service.teaching.replay`)
and compacts: the home file is rewritten atomically with the last seq it holds, then the journal
anew. :meth:`HomeWriter.handle` takes the requests that arrived together, validates each against
the current home, applies the valid ones as batches (one :func:`spco.knowledge.teach` call per
batch of up to ``max_batch`` teachings; an undo alone), appends the batch's records to the journal
and ``fsync``-s it, and only then reports them applied. It compacts again after
``compact_records`` records, after ``compact_idle`` seconds without a teaching, and on close.

It runs in a process of its own (:class:`ProcessWriter`, the default of
:class:`spco.service.LiveHome`: ``python -m spco.service.writer``), so that the readers of the
serving process, which answer from the last committed snapshot, never wait for Python's global
lock while a teaching runs; or in a thread of the serving process (:class:`ThreadWriter`), which
is simpler and costs readers a few milliseconds at the 99th percentile during teachings
(``benchmarks/README.md``, "spco serve").
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import ctypes
import dataclasses
import json
import os
import queue
import signal
import socket
import subprocess
import sys
import threading
import time
import traceback
import warnings
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import replace
from multiprocessing.connection import Connection
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from spco import knowledge as kn
from spco.data.lexicon import lexicon
from spco.errors import ConfigurationError, SpcoError, TeachingLimitError, TeachingRateError
from spco.knowledge.requests import Teach, Undo
from spco.service.journal import Journal, journal_path, new_journal_id, read_journal
from spco.service.snapshots import TRIM_EVERY, SnapshotChannel, trim_heap
from spco.service.teaching import (
    CHECKPOINT_EVERY,
    DEFAULT_UNDO_LIMIT,
    SERVED,
    UndoCheckpoints,
    apply_batch,
    check_journal_matches,
    file_digest,
    history_of,
    plan_undo,
    replay,
    served_info,
    teach_batch,
    undo_base_path,
    undo_base_seq,
    with_history,
)
from spco.timestamps import utc_now

__all__ = ["DEFAULT_COMPACT_IDLE", "DEFAULT_COMPACT_RECORDS", "DEFAULT_MAX_BATCH", "HomeWriter",
           "ProcessWriter", "ThreadWriter", "WriterUnavailableError", "error_result"]

#: Records after which the writer compacts the journal into the home file.
DEFAULT_COMPACT_RECORDS = 100
#: Seconds without a teaching after which pending records are compacted.
DEFAULT_COMPACT_IDLE = 2.0
#: The most teachings applied by one :func:`spco.knowledge.teach` call.
DEFAULT_MAX_BATCH = 32


class WriterUnavailableError(SpcoError):
    """The writer of a served home is gone (it died, or the home was closed): no teaching is possible."""


def error_result(exc: BaseException) -> dict[str, Any]:
    """A failed request's result: ``{"ok": False, "error": message, "kind": exception class name}``."""
    if isinstance(exc, TeachingLimitError):
        return {"ok": False, "error": str(exc), "kind": type(exc).__name__, "limit": exc.limit,
                "value": exc.value, "allowed": exc.allowed}
    if isinstance(exc, SpcoError):
        return {"ok": False, "error": str(exc), "kind": type(exc).__name__}
    return {"ok": False, "error": f"internal error of the writer: {type(exc).__name__}: {exc}",
            "kind": "InternalError"}


class HomeWriter:
    """The home being served, its journal and its teaching history; one instance per served file.

    Parameters
    ----------
    path: the home file (held by the server's lock: :func:`spco.knowledge.locking.hold`).
    seed: base seed; each batch's seed is derived from it and the batch's first seq (and recorded).
        ``None``: fresh entropy.
    sweeps: Gibbs sweeps of each teaching (:data:`spco.knowledge.DEFAULT_TEACH_SWEEPS`).
    compact_records, compact_idle: when to compact (records since the last compaction; seconds idle).
    max_batch: the most teachings applied together.
    undo_limit: how many of the last teachings can be undone exactly
        (:data:`~spco.service.teaching.DEFAULT_UNDO_LIMIT`; see :mod:`spco.service.teaching`).
    limits: what a teaching may bring (:class:`spco.knowledge.TeachingLimits`); a request beyond
        them is refused with a :class:`~spco.errors.TeachingLimitError` naming the limit.
    """

    def __init__(self, path: str | PathLike[str], *, seed: int | None = None,
                 sweeps: int = kn.DEFAULT_TEACH_SWEEPS, compact_records: int = DEFAULT_COMPACT_RECORDS,
                 compact_idle: float = DEFAULT_COMPACT_IDLE, max_batch: int = DEFAULT_MAX_BATCH,
                 undo_limit: int = DEFAULT_UNDO_LIMIT,
                 limits: kn.TeachingLimits | None = kn.DEFAULT_LIMITS) -> None:
        if isinstance(sweeps, bool) or not isinstance(sweeps, int) or sweeps < 0:
            raise ConfigurationError(f"sweeps must be an integer >= 0, got {sweeps!r}")
        if isinstance(undo_limit, bool) or not isinstance(undo_limit, int) or undo_limit < 0:
            raise ConfigurationError(f"undo_limit must be an integer >= 0, got {undo_limit!r}")
        self.path = Path(path)
        self.undo_limit = undo_limit
        self.limits = limits
        self._observed: collections.deque[float] = collections.deque()  # when observations came
        self._extractor: Any = None
        self._extractor_key: str | None = None
        self.sweeps = sweeps
        self.compact_records, self.compact_idle, self.max_batch = compact_records, compact_idle, max_batch
        self.journal = Journal(journal_path(path))
        home = kn.load_home_model(path)
        contents = read_journal(self.journal.path, warn=False)
        check_journal_matches(home, contents.header, contents.records, self.journal.path, path)
        history = history_of(home)
        before = int(served_info(home).get("last_seq", 0))
        base_file = undo_base_path(path)
        fresh_base = not base_file.exists() or (served_info(home).get("undo_base") is None)
        if fresh_base:  # no undo base yet: the home as it is (its teachings so far cannot be undone)
            self.checkpoints = UndoCheckpoints(home, before)
        else:
            self.checkpoints = UndoCheckpoints(lambda: kn.load_home_model(base_file), undo_base_seq(home))
        home = replay(home, contents.records, history, self.checkpoints)
        replayed = int(served_info(home).get("last_seq", 0)) - before
        #: what start-up found: records replayed, a torn record dropped
        self.startup = {"replayed": replayed, "torn": contents.torn}
        compacted = served_info(home).get("journal")
        served = {**served_info(home), "journal": compacted or new_journal_id()}
        served.setdefault("last_seq", 0)
        served.setdefault("teachings", 0)
        served["undo_base"] = self.checkpoints.base_seq
        if fresh_base:  # the undo base is the home file as it is (until its first compaction says otherwise)
            _copy_atomically(self.path, base_file)
        self.home = _with_served(home, served)
        self.history = history
        self._since_checkpoint = 0
        self._base_seed = int(np.random.SeedSequence().entropy if seed is None else seed)  # type: ignore[arg-type]
        self._since_compaction = replayed
        self._last_teaching = time.monotonic()
        self._last_snapshot: kn.HomeModel | None = None
        if replayed:
            self.compact()
        else:  # the file is left as it is: a journal anew, tied to the file (by its ID, or by its bytes)
            header = {"journal": served["journal"], "home": home.name, "base_seq": served["last_seq"]}
            if compacted is None:
                header["base_sha256"] = file_digest(self.path)
            self.journal.rewrite(header, [])
        self._warm_up()

    def _warm_up(self) -> None:
        """Run one throw-away teaching holding every kind (a sentence with a word never heard, new
        observations with and without a view) before the home is said to be ready, so that the first
        real one does not wait for the sampler's compiled kernels to load or for anything a teaching
        needs first (the image extractor, the snapshot's parameters), and load WordNet (a word that the
        lexicon's facts files lack is looked up in it: seconds to load): the first teaching after start
        takes as long as any other (``benchmarks/first_teaching.py``)."""
        home = self.home
        with contextlib.suppress(SpcoError), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            word = "spcowarmupword"
            while home.vocabulary.index(word) is not None:
                word += "x"
            x, y = (float(v) for v in home.positions[0, :2])
            theta = float(np.arctan2(home.positions[0, 2], home.positions[0, 3]))
            observations = [kn.Observation(x=x, y=y, theta=theta, sentence=f"this is the {word} room")]
            if not home.view_missing[0] and home.knowledge.n_features:
                observations.append(kn.Observation(x=x, y=y, theta=theta, visual=home.visual[[0]],
                                                   sentence=f"the {word} room"))
            # one teaching of every kind at once, as a batch of teachings is taught (``teach_batch``)
            taught = kn.teach(home, {int(home.ids[0]): f"this is the {word}"}, observations=observations,
                              n_sweeps=self.sweeps, random_state=0)
            if home.knowledge.fitted_on_images:  # the extractor built and run once (teach_batch keeps it)
                self._image_extractor().extract(np.zeros((48, 64, 3), dtype=np.uint8), "bgr8")
            _ = replace(taught, state=replace(taught.state, visual_cache=None)).parameters
        lexicon()  # WordNet itself: a word the facts files lack is looked up there, not loaded first

    # ------------------------------------------------------------------ state
    @property
    def last_seq(self) -> int:
        """The seq of the last teaching applied."""
        return int(served_info(self.home)["last_seq"])

    def snapshot(self) -> kn.HomeModel:
        """The current home for readers: without the teaching history and the sampler's cache, its
        derived data computed (here, not by the first reader). Arrays that did not change since the
        last snapshot are the same objects (what :class:`SnapshotChannel` does not send again)."""
        home = with_history(self.home, None)
        snap = replace(home, state=replace(home.state, visual_cache=None))
        data = snap.data
        previous = self._last_snapshot
        if previous is not None and snap.visual is previous.visual:  # the same views: the same counts
            snap.__dict__["data"] = replace(data, visual=previous.data.visual)
        _ = snap.parameters
        self._last_snapshot = snap
        return snap

    def _seed_for(self, first_seq: int) -> int:
        state = np.random.SeedSequence([self._base_seed, first_seq]).generate_state(1, np.uint64)
        return int(state[0] >> np.uint64(1))

    # ------------------------------------------------------------------ teaching
    def handle(self, requests: list[Teach | Undo]) -> list[dict[str, Any]]:
        """Apply ``requests`` (in order) and return one result each.

        A request is checked where it entered (:meth:`spco.service.LiveHome.submit`): a
        :class:`~spco.knowledge.requests.Teach` or an :class:`~spco.knowledge.requests.Undo`.
        Teachings that arrive together are taught as batches of up to ``max_batch`` by one call
        each (:func:`~spco.service.teaching.teach_batch`: the home checks what needs it); an undo is
        a batch of its own (:func:`~spco.service.teaching.plan_undo`); the rate limit is checked
        here. A result is ``{"ok": True, "seq", …}`` once the teaching is in the journal
        (``fsync``-ed), or :func:`error_result`.
        """
        results: list[dict[str, Any] | None] = [None] * len(requests)
        batch: list[tuple[int, Teach | dict[str, Any]]] = []

        def flush() -> None:
            if batch:
                self._apply(list(batch), results)
                batch.clear()

        for index, request in enumerate(requests):
            try:
                if isinstance(request, Undo):
                    flush()
                    undo = plan_undo(self.home, self.history, request.seq, self.undo_limit,
                                     self.checkpoints.base_seq)
                    self._apply([(index, undo)], results)
                    continue
                if not isinstance(request, Teach):
                    raise ConfigurationError(f"expected a Teach or an Undo request, got "
                                             f"{type(request).__name__}")
                if request.observation:
                    self._check_rate()
                batch.append((index, request))
                if len(batch) >= self.max_batch:
                    flush()
            except Exception as exc:  # SpcoError: the request's fault; anything else: a bug, said as such
                results[index] = error_result(exc)
        flush()
        return [r if r is not None else error_result(RuntimeError("no result")) for r in results]

    def _check_rate(self) -> None:
        """Count a new observation; raise :class:`~spco.errors.TeachingRateError` if the last minute
        had the limit's number already (the words' limits are the home's to check: ``teach_batch``)."""
        limits = self.limits
        if limits is None or limits.max_observations_per_minute is None:
            return
        now = time.monotonic()
        while self._observed and now - self._observed[0] > 60.0:
            self._observed.popleft()
        if len(self._observed) >= limits.max_observations_per_minute:
            raise TeachingRateError(
                f"{len(self._observed)} new observations in the last minute; the home takes at most "
                f"{limits.max_observations_per_minute} a minute (limit max_observations_per_minute): "
                f"try again in {60.0 - (now - self._observed[0]):.0f} s", "max_observations_per_minute",
                len(self._observed) + 1, limits.max_observations_per_minute)
        self._observed.append(now)

    def _image_extractor(self) -> Any:
        """The home's image extractor (:meth:`spco.knowledge.Knowledge.image_extractor`), built once and
        kept while the home's extractor stays the same (teachings never change it)."""
        knowledge = self.home.knowledge
        key = json.dumps(knowledge.extractor, sort_keys=True)
        if self._extractor is None or key != self._extractor_key:
            self._extractor, self._extractor_key = knowledge.image_extractor(), key
        return self._extractor

    def _apply(self, batch: list[tuple[int, Any]], results: list[dict[str, Any] | None]) -> None:
        """Apply a batch (teachings, or one undo record), journal it (fsync), then record its results;
        a batch that fails is retried one teaching at a time, so that one bad teaching does not fail
        the others."""
        start = time.perf_counter()
        first = self.last_seq + 1
        seed = self._seed_for(first)
        history = dict(self.history)
        words_before = self.home.knowledge.n_words
        undoing = isinstance(batch[0][1], dict)
        try:
            if undoing:
                records = [{"seq": first, "batch": [first, first], "seed": seed, "sweeps": self.sweeps,
                            "time": utc_now("milliseconds"), **batch[0][1]}]
                updated = apply_batch(self.home, records, history, self.checkpoints)
            else:
                updated, records = teach_batch(self.home, [request for _, request in batch], first, seed,
                                               self.sweeps, self.limits, history, self._image_extractor)
        except Exception as exc:
            if undoing:  # the checkpoints after the undone teaching may be half rebuilt
                self.checkpoints.drop_from(int(batch[0][1]["undoes"]))
            if len(batch) > 1:
                for item in batch:
                    self._apply([item], results)
                return
            results[batch[0][0]] = error_result(exc)
            return
        try:
            self.journal.append(records)
        except OSError as exc:  # not durable: not applied
            if undoing:  # the checkpoints rebuilt for the undo do not hold
                self.checkpoints.drop_from(int(records[0]["undoes"]))
            for index, _ in batch:
                results[index] = error_result(WriterUnavailableError(
                    f"{self.journal.path}: cannot write the journal ({exc.strerror or exc}); the teaching "
                    "was not kept"))
            return
        self.home, self.history = updated, history
        self._since_compaction += len(records)
        if undoing:
            self._since_checkpoint = 0
            self.checkpoints.add(self.last_seq, self.home)
        else:
            self._since_checkpoint += len(records)
            if self._since_checkpoint >= CHECKPOINT_EVERY:
                self.checkpoints.add(self.last_seq, self.home)
                self._since_checkpoint = 0
        self._last_teaching = time.monotonic()
        seconds = time.perf_counter() - start
        new_words = list(updated.vocabulary.words[words_before:])
        served = served_info(updated)
        # a new name spreading (teach)
        said = list((updated.provenance.get("last_teach") or {}).get("warnings", []))
        for (index, _), record in zip(batch, records, strict=True):
            result = {k: v for k, v in record.items() if k not in ("view", "seed", "sweeps", "batch")}
            result.update(ok=True, home=updated.name, teachings=served["teachings"],
                          samples=updated.n_samples, taught=updated.n_taught, new_words=new_words,
                          batch=len(records), seconds=round(seconds, 4),
                          notes=_notes(updated, record) + said)
            results[index] = result
        if self._since_compaction >= self.compact_records:
            self.compact()

    # ------------------------------------------------------------------ compaction
    def compact(self) -> None:
        """Write the home (with its history and last seq) atomically, then start the journal anew.

        First the undo base moves on if the last ``undo_limit`` teachings allow it
        (:meth:`UndoCheckpoints.advance`): the new base is written, then the home file, whose history
        keeps the records of the teachings after it (a crash in between leaves the old home file,
        whose records cover the new base too)."""
        base = self.checkpoints.advance(self.history, self.undo_limit)
        if base is not None:
            seq = self.checkpoints.base_seq
            _with_served(base, {**served_info(base), "last_seq": seq}).save(undo_base_path(self.path),
                                                                            overwrite=True)
            for k, entry in self.history.items():  # records before the base are never replayed again
                if k <= seq and "record" in entry:
                    self.history[k] = {key: v for key, v in entry.items() if key != "record"}
            self.home = _with_served(self.home, {**served_info(self.home), "undo_base": seq})
        served = served_info(self.home)
        self.journal.close()
        with_history(self.home, self.history).save(self.path, overwrite=True)
        self.journal.rewrite({"journal": served["journal"], "home": self.home.name,
                              "base_seq": served["last_seq"]}, [])
        self._since_compaction = 0

    def maybe_compact(self) -> bool:
        """Compact if records wait and no teaching came for ``compact_idle`` seconds; whether it did."""
        if self._since_compaction and time.monotonic() - self._last_teaching >= self.compact_idle:
            self.compact()
            return True
        return False

    def close(self) -> None:
        """Compact what is pending and close the journal."""
        if self._since_compaction:
            self.compact()
        self.journal.close()


def _copy_atomically(source: Path, target: Path) -> None:
    """Copy ``source`` to ``target`` through a temporary file renamed over it (fsync-ed first)."""
    import shutil

    temporary = target.with_name(target.name + ".tmp")
    shutil.copyfile(source, temporary)
    with open(temporary, "rb+") as handle:
        os.fsync(handle.fileno())
    os.replace(temporary, target)


def _with_served(home: kn.HomeModel, served: dict[str, Any]) -> kn.HomeModel:
    return replace(home, provenance={**home.provenance, SERVED: served})


def _notes(home: kn.HomeModel, record: dict[str, Any]) -> list[str]:
    """What ``spco teach`` notes about the home's own words of a taught sentence (not usable yet)."""
    from spco.data.language import tokenize

    notes = []
    for word in dict.fromkeys(tokenize(record.get("sentence"))):
        index = home.vocabulary.index(word)
        if index is not None and index >= home.n_knowledge_words:
            hint = kn.unused_word_hint(home, word)
            if hint is not None:
                notes.append(hint.replace("spco teach HOME ", "POST /teach "))
    return notes


# ============================================================================ running it
Applied = Callable[[list[tuple[dict[str, Any], dict[str, Any]]], "kn.HomeModel | None"], None]


class ThreadWriter:
    """A :class:`HomeWriter` in a thread of this process; ``on_applied(pairs, snapshot)`` is called
    in that thread after each round, with (request, result) pairs and the new snapshot (or ``None``).
    ``lock``: the :class:`spco.knowledge.locking.HeldLock` of the file, which the thread is permitted
    to write."""

    def __init__(self, path: str | PathLike[str], on_applied: Applied, *, lock: Any = None,
                 **options: Any) -> None:
        self._writer = HomeWriter(path, **options)
        self._lock_held = lock
        self.startup = dict(self._writer.startup)
        self.first_snapshot = self._writer.snapshot()
        self._on_applied = on_applied
        self._queue: queue.Queue[tuple[dict[str, Any], Future[dict[str, Any]]] | None] = queue.Queue()
        self._closed = False
        self._thread = threading.Thread(target=self._run, name="spco-home-writer", daemon=True)
        self._thread.start()

    def submit(self, request: dict[str, Any]) -> Future[dict[str, Any]]:
        """Queue a request; the future gets its result."""
        future: Future[dict[str, Any]] = Future()
        if self._closed:
            future.set_exception(WriterUnavailableError("the served home is closed"))
            return future
        self._queue.put((request, future))
        return future

    def _run(self) -> None:
        if self._lock_held is not None:
            self._lock_held.permit()  # this thread writes the file it holds
        while True:
            try:
                item = self._queue.get(timeout=self._writer.compact_idle / 2)
            except queue.Empty:
                self._writer.maybe_compact()
                continue
            items = [item]
            while True:  # what arrived meanwhile is one round (batched)
                try:
                    items.append(self._queue.get_nowait())
                except queue.Empty:
                    break
            work = [i for i in items if i is not None]
            if work:
                results = self._writer.handle([r for r, _ in work])
                changed = any(r.get("ok") for r in results)
                self._on_applied([(r, res) for (r, _), res in zip(work, results, strict=True)],
                                 self._writer.snapshot() if changed else None)
                for (_, future), result in zip(work, results, strict=True):
                    future.set_result(result)
            if any(i is None for i in items):
                self._writer.close()
                return

    def close(self, timeout: float = 60.0) -> None:
        """Finish the queued requests, compact, stop the thread."""
        if not self._closed:
            self._closed = True
            self._queue.put(None)
            self._thread.join(timeout)

    @property
    def alive(self) -> bool:
        """Whether the writer still takes teachings."""
        return self._thread.is_alive() and not self._closed


class ProcessWriter:
    """A :class:`HomeWriter` in a child process (``python -m spco.service.writer``).

    The child inherits the descriptor of the home's lock (held by this process with
    :func:`spco.knowledge.locking.hold`) and declares it (:func:`spco.knowledge.locking.adopt`); it is
    killed when this process dies (``PR_SET_PDEATHSIG`` on Linux; elsewhere it exits when its
    connection closes). It runs the sampler on one thread, leaving the other cores to the readers, at
    the server's scheduling priority. ``on_applied`` is called in a receiving thread of this process.
    """

    def __init__(self, path: str | PathLike[str], on_applied: Applied, *, lock_fd: int, holder: str,
                 start_timeout: float = 600.0, **options: Any) -> None:
        ours, theirs = socket.socketpair()
        # blocking whatever socket.setdefaulttimeout() says (rospy's init_node sets 60 s, which makes new
        # sockets non-blocking underneath: a snapshot larger than the socket's buffer then fails half-way
        # with BlockingIOError on both sides)
        ours.setblocking(True)
        theirs.setblocking(True)
        args = [sys.executable, "-m", "spco.service.writer", "--path", str(Path(path).absolute()),
                "--lock-fd", str(lock_fd), "--conn-fd", str(theirs.fileno()), "--holder", holder,
                "--parent", str(os.getpid())]
        for key, value in options.items():
            if key == "limits":  # always given: None (no limits) too
                args += ["--limits", json.dumps(None if value is None else dataclasses.asdict(value))]
            elif value is not None:
                args += [f"--{key.replace('_', '-')}", str(value)]
        # one sampler thread: the other core stays with the readers (the result does not depend on it)
        environment = {**os.environ, "NUMBA_NUM_THREADS": "1"}
        self._process = subprocess.Popen(args, pass_fds=(lock_fd, theirs.fileno()), stdin=subprocess.DEVNULL,
                                         env=environment)
        theirs.close()
        self._conn = Connection(ours.detach())
        self._on_applied = on_applied
        self._pending: dict[int, tuple[dict[str, Any], Future[dict[str, Any]]]] = {}
        self._next = 0
        self._lock = threading.Lock()
        self._closed = False
        self._dead: str | None = None
        deadline = time.monotonic() + start_timeout
        while not self._conn.poll(0.2):
            if self._process.poll() is not None or time.monotonic() > deadline:
                self._kill()
                raise WriterUnavailableError(f"{path}: the writer process did not start (exit status "
                                             f"{self._process.returncode}); see the messages above")
        try:
            message = self._conn.recv()
        except (EOFError, OSError):
            self._kill()
            raise WriterUnavailableError(f"{path}: the writer process ended while starting") from None
        if message[0] == "error":
            self._kill()
            kind, text = message[1], message[2]
            raise (_ERRORS.get(kind, SpcoError))(text)
        self._channel = SnapshotChannel()
        self.first_snapshot = self._channel.unpack(message[1])
        self.startup = message[2]
        self.pid = self._process.pid
        # requests leave through a sender thread: a caller (the server's event loop) never blocks on a
        # full socket, and the receiver never waits for a sender (the writer may be sending a snapshot
        # while requests pile up: both directions must drain independently)
        self._outbox: queue.Queue[tuple[Any, ...] | None] = queue.Queue()
        self._sender = threading.Thread(target=self._send, name="spco-writer-sender", daemon=True)
        self._sender.start()
        self._receiver = threading.Thread(target=self._receive, name="spco-writer-receiver", daemon=True)
        self._receiver.start()

    def submit(self, request: dict[str, Any]) -> Future[dict[str, Any]]:
        """Queue a request for the writer; the future gets its result."""
        future: Future[dict[str, Any]] = Future()
        with self._lock:
            if self._closed or self._dead:
                future.set_exception(WriterUnavailableError(self._dead or "the served home is closed"))
                return future
            key = self._next
            self._next += 1
            self._pending[key] = (request, future)
        self._outbox.put(("teach", key, request))
        return future

    def _send(self) -> None:
        while True:
            message = self._outbox.get()
            if message is None:
                return
            try:
                self._conn.send(message)
            except OSError:  # the writer is gone: the receiver fails what is pending
                return

    def _receive(self) -> None:
        received = 0
        while True:
            try:
                message = self._conn.recv()
            except (EOFError, OSError):
                message = ("gone",)
            if message[0] == "applied":
                _, keyed, packed = message
                snapshot = None if packed is None else self._channel.unpack(packed)
                if snapshot is not None:
                    received += 1
                    if received % TRIM_EVERY == 0:
                        trim_heap()
                with self._lock:
                    done = [(self._pending.pop(key), result) for key, result in keyed]
                self._on_applied([(request, result) for (request, _), result in done], snapshot)
                for (_, future), result in done:
                    future.set_result(result)
                continue
            code = self._process.wait(timeout=30) if message[0] == "gone" else 0
            with self._lock:
                if message[0] == "gone" and not self._closed:
                    self._dead = f"the writer process of the served home died (exit status {code})"
                    print(f"spco serve: error: {self._dead}; teachings are refused until the server is "
                          "restarted (every acknowledged teaching is in the journal)", file=sys.stderr)
                error = WriterUnavailableError(self._dead or "the served home is closed")
                for _, future in self._pending.values():
                    future.set_exception(error)
                self._pending.clear()
            return

    def close(self, timeout: float = 60.0) -> None:
        """Let the writer finish its requests and compact, then wait for it to exit."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._outbox.put(("close",))  # after every request queued before it
        self._outbox.put(None)
        try:
            self._process.wait(timeout)
        except subprocess.TimeoutExpired:
            self._kill()
        self._receiver.join(timeout=5)
        self._sender.join(timeout=5)
        self._conn.close()

    def _kill(self) -> None:
        with contextlib.suppress(OSError):
            self._process.kill()
        self._process.wait()

    @property
    def alive(self) -> bool:
        """Whether the writer still takes teachings."""
        return not self._closed and self._dead is None and self._process.poll() is None


def _die_with_parent(parent: int) -> None:
    """Have the kernel kill this process when its parent dies (Linux), so that the lock it inherited
    is released with the server's; elsewhere the closed connection ends it."""
    with contextlib.suppress(Exception):
        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:  # the parent died before the request was made
        os._exit(1)


def _serve_connection(conn: Connection, writer: HomeWriter, channel: SnapshotChannel) -> None:
    idle = writer.compact_idle / 2
    rounds = 0
    while True:
        if not conn.poll(idle):
            writer.maybe_compact()
            continue
        messages = []
        try:
            messages.append(conn.recv())
            while conn.poll(0):  # what arrived meanwhile is one round (batched)
                messages.append(conn.recv())
        except (EOFError, OSError):  # the server is gone: nothing left to acknowledge
            writer.close()
            return
        work = [(m[1], m[2]) for m in messages if m[0] == "teach"]
        if work:
            results = writer.handle([request for _, request in work])
            changed = any(r.get("ok") for r in results)
            conn.send(("applied", [(key, result) for (key, _), result in zip(work, results, strict=True)],
                       channel.pack(writer.snapshot()) if changed else None))
            rounds += 1
            if rounds % TRIM_EVERY == 0:
                trim_heap()
        if any(m[0] == "close" for m in messages):
            writer.close()
            return


_ERRORS: dict[str, type[SpcoError]] = {"ConfigurationError": ConfigurationError,
                                       "WriterUnavailableError": WriterUnavailableError}


def main(argv: list[str] | None = None) -> int:
    """The writer process: ``python -m spco.service.writer --path HOME --lock-fd N --conn-fd M …``."""
    from spco.knowledge import locking

    parser = argparse.ArgumentParser(prog="python -m spco.service.writer")
    parser.add_argument("--path", required=True)
    parser.add_argument("--lock-fd", type=int, required=True)
    parser.add_argument("--conn-fd", type=int, required=True)
    parser.add_argument("--holder", required=True)
    parser.add_argument("--parent", type=int, required=True)
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--sweeps", type=int, default=kn.DEFAULT_TEACH_SWEEPS)
    parser.add_argument("--compact-records", type=int, default=DEFAULT_COMPACT_RECORDS)
    parser.add_argument("--compact-idle", type=float, default=DEFAULT_COMPACT_IDLE)
    parser.add_argument("--max-batch", type=int, default=DEFAULT_MAX_BATCH)
    parser.add_argument("--undo-limit", type=int, default=DEFAULT_UNDO_LIMIT)
    parser.add_argument("--limits", default=None, help="the teaching limits as JSON (null: none)")
    args = parser.parse_args(argv)
    _die_with_parent(args.parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the server, which closes us in order
    os.set_blocking(args.conn_fd, True)  # as the server made it (see WriterProcess)
    conn = Connection(args.conn_fd)
    try:
        locking.adopt(args.path, args.lock_fd, args.holder)
        writer = HomeWriter(args.path, seed=args.seed, sweeps=args.sweeps,
                            compact_records=args.compact_records, compact_idle=args.compact_idle,
                            max_batch=args.max_batch, undo_limit=args.undo_limit,
                            limits=kn.DEFAULT_LIMITS if args.limits is None else (
                                None if json.loads(args.limits) is None
                                else kn.TeachingLimits(**json.loads(args.limits))))
    except SpcoError as exc:
        conn.send(("error", type(exc).__name__ if type(exc).__name__ in _ERRORS else "SpcoError", str(exc)))
        return 2
    except Exception as exc:
        traceback.print_exc()
        conn.send(("error", "SpcoError", f"the writer could not start: {type(exc).__name__}: {exc}"))
        return 1
    channel = SnapshotChannel()
    conn.send(("ready", channel.pack(writer.snapshot()), dict(writer.startup)))
    _serve_connection(conn, writer, channel)
    return 0


if __name__ == "__main__":  # pragma: no cover - run as the writer process
    sys.exit(main())
