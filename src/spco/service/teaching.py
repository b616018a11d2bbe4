"""Teachings of a served home as journal records: taught in batches, replayed, undone.

A teaching arrives as a request checked where it entered (a
:class:`~spco.knowledge.requests.Teach`), is given a sequence number, and taught together with the
teachings that arrived with it by one :func:`spco.knowledge.teach_requests` call
(:func:`teach_batch`), which checks what needs the home (a known sample, a new id, a pose on the
map, a view's counts, the teaching limits). The journal record (:mod:`spco.service.journal`)
holds the request as applied (:func:`record_of`) — the sample id an observation got, its visual
counts (an image is turned into counts by the teaching), the batch, its seed and its sweeps — so
that :func:`replay` of the records (:func:`request_of`, the same call) gives the same home, bit
for bit.

Record kinds (``op``), besides ``seq``, ``batch``, ``seed``, ``sweeps`` and ``time``:

``sentence``
    ``id``, ``sentence`` (``null`` forgets the sample's sentence).
``observation``
    ``id`` (the new sample's), ``x``, ``y``, ``theta`` (metres, radians), ``sentence``, ``view``:
    ``{"indices": [...], "counts": [...]}`` of the view's visual counts, or ``null`` for a pose
    without a view (its visual likelihood is 1: only the position and the words are learnt from it).
``undo``
    ``undoes`` (the seq of the teaching undone).

An undo restores exactly (:func:`rebuild`): the home becomes what it would be had the teaching
never been made — every later teaching replayed, batch by batch with its recorded seed, from a
checkpoint of the home taken before the undone one (:class:`UndoCheckpoints`). Every answer and the
vocabulary are then bit for bit those of that home; undoing the last teaching gives back the home
as it was before it. The last :data:`DEFAULT_UNDO_LIMIT` teachings can be undone (configurable);
an older one is refused (:class:`ConflictError`, HTTP 409) saying why.

What that keeps: the home file's history holds the journal record of each teaching after the
*undo base* (``history[seq]["record"]``: a few hundred bytes, a view's counts more); the undo base
is a home file of its own next to the home (:func:`undo_base_path`, ``HOME.undo``: the home as it
was before the oldest teaching that can still be undone, one more home file on disk), and the
writer keeps in memory a checkpoint every :data:`CHECKPOINT_EVERY` teachings (at most
``limit / CHECKPOINT_EVERY + 2`` homes), so that an undo replays at most that many teachings before
the undone one, and every teaching after it.

The home file remembers what it needs in ``provenance["served"]``: ``journal`` (the ID of its
journal), ``last_seq`` (the last teaching it holds), ``teachings`` (teachings applied through the
journal and not undone) and ``history`` (seq → what the teaching did, its record, and what undid it,
for the last :data:`HISTORY_LIMIT` teachings; what :func:`plan_undo` needs).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import replace
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from spco import knowledge as kn
from spco.errors import ConfigurationError, ConflictError, NotFoundError
from spco.knowledge.requests import MAX_SENTENCE_CHARS, Pose, Teach, View
from spco.service.journal import JournalError, journal_path, read_journal
from spco.timestamps import utc_now

__all__ = [
    "CHECKPOINT_EVERY",
    "DEFAULT_UNDO_LIMIT",
    "HISTORY_LIMIT",
    "MAX_SENTENCE_CHARS",
    "ConflictError",
    "NotFoundError",
    "UndoCheckpoints",
    "apply_batch",
    "batches",
    "check_journal_matches",
    "file_digest",
    "history_of",
    "load_current",
    "pending_teachings",
    "plan_undo",
    "rebuild",
    "record_of",
    "replay",
    "request_of",
    "served_info",
    "teach_batch",
    "undo_base_path",
    "undo_base_seq",
    "with_history",
    "without_samples",
]

#: How many teachings the home file remembers for :func:`plan_undo` (older ones cannot be undone).
HISTORY_LIMIT = 10_000
#: How many of the last teachings can be undone exactly (``spco serve --undo-limit``).
DEFAULT_UNDO_LIMIT = 100
#: The writer keeps a checkpoint of the home every this many teachings (what an undo replays from).
CHECKPOINT_EVERY = 10
SERVED = "served"



def served_info(home: kn.HomeModel) -> dict[str, Any]:
    """``provenance["served"]`` of ``home`` without its history: ``journal``, ``last_seq``, ``teachings``
    (empty for a home never served)."""
    served = home.provenance.get(SERVED) or {}
    return {k: v for k, v in served.items() if k != "history"}


def history_of(home: kn.HomeModel) -> dict[int, dict[str, Any]]:
    """A copy of the teaching history kept in ``home``'s file (seq → entry)."""
    served = home.provenance.get(SERVED) or {}
    return {int(k): dict(v) for k, v in (served.get("history") or {}).items()}


def undo_base_seq(home: kn.HomeModel) -> int:
    """The seq of the home's undo base (``provenance["served"]["undo_base"]``): before the first
    compaction that moved it, the undo base is a copy of the home file itself, its ``last_seq``."""
    served = home.provenance.get(SERVED) or {}
    return int(served.get("undo_base", served.get("last_seq", 0)))


def with_history(home: kn.HomeModel, history: dict[int, dict[str, Any]] | None) -> kn.HomeModel:
    """``home`` with ``history`` (the last :data:`HISTORY_LIMIT` entries) in ``provenance["served"]``,
    or without any history for ``None`` (a snapshot for readers: they do not need it)."""
    served = served_info(home)
    if history is not None:
        kept = sorted(history)[-HISTORY_LIMIT:]
        served["history"] = {str(k): history[k] for k in kept}
    return replace(home, provenance={**home.provenance, SERVED: served})


# ---------------------------------------------------------------------------- requests <-> records

def record_of(request: Teach) -> dict[str, Any]:
    """The journal record of a teaching as applied (:func:`spco.knowledge.teach_requests`' second
    result: a new observation with its id and its view as counts), without its seq and batch."""
    if not request.observation:
        return {"op": "sentence", "id": int(request.id), "sentence": request.sentence}  # type: ignore[arg-type]
    pose = request.pose
    assert pose is not None and request.id is not None  # an applied observation has both
    view = None
    if request.view is not None:
        row = sp.csr_array(request.view.visual)
        row.sort_indices()
        view = {"indices": [int(i) for i in row.indices], "counts": [int(c) for c in row.data]}
    return {"op": "observation", "id": int(request.id), "x": pose.x, "y": pose.y, "theta": pose.theta,
            "sentence": request.sentence, "view": view}


def request_of(record: dict[str, Any], n_features: int) -> Teach:
    """The :class:`~spco.knowledge.requests.Teach` a journal record holds (what :func:`record_of`
    wrote): the same teaching, applied again."""
    if record["op"] == "sentence":
        return Teach(sentence=record["sentence"], id=int(record["id"]))
    if record["op"] == "observation":
        view = None if record["view"] is None else View(visual=_view_row(record["view"], n_features))
        return Teach(sentence=record["sentence"], id=int(record["id"]),
                     pose=Pose(float(record["x"]), float(record["y"]), float(record["theta"])), view=view)
    raise JournalError(f"seq {record['seq']}: unknown record kind {record['op']!r}")


def _effective(history: dict[int, dict[str, Any]], after: int = 0) -> list[int]:
    """The seqs of the teachings in ``history`` after seq ``after`` that hold now: not undos, not undone."""
    return sorted(k for k, e in history.items()
                  if k > after and e["op"] != "undo" and e.get("undone_by") is None)


def plan_undo(home: kn.HomeModel, history: dict[int, dict[str, Any]], seq: object,
              limit: int = DEFAULT_UNDO_LIMIT, base_seq: int = 0) -> dict[str, Any]:
    """The record undoing teaching ``seq``: ``{"op": "undo", "undoes": seq}``.

    Raises :class:`NotFoundError` for a seq not in the history, :class:`ConflictError` for an undo,
    a teaching already undone, one older than the last ``limit`` teachings or than the undo base
    ``base_seq`` (the home before it is no longer kept), and one whose new sample a later teaching
    gave a sentence (undo that one first).
    """
    if isinstance(seq, bool) or not isinstance(seq, int | np.integer):
        raise ConfigurationError(f"seq: expected an integer, got {seq!r}")
    seq = int(seq)
    entry = history.get(seq)
    if entry is None:
        known = f" (it remembers seq {min(history)}…{max(history)})" if history else ""
        raise NotFoundError(f"home {home.name!r} has no teaching with seq {seq} to undo{known}")
    if entry["op"] == "undo":
        raise ConflictError(f"seq {seq} is an undo (of seq {entry['undoes']}); teach the sentence again "
                            "instead")
    if entry.get("undone_by") is not None:
        raise ConflictError(f"teaching {seq} was undone already (by seq {entry['undone_by']})")
    later = _effective(history, seq - 1)
    if len(later) > limit:
        raise ConflictError(f"teaching {seq} cannot be undone: it is not among the last {limit} teachings "
                            f"({len(later) - 1} came after it), and only those are undone exactly (the home "
                            "before them is kept; the server's --undo-limit keeps more); teach the place "
                            "again instead")
    if entry.get("record") is None or seq <= base_seq:
        raise ConflictError(f"teaching {seq} cannot be undone: the home as it was before it is no longer "
                            "kept (it was taught before the oldest undo checkpoint); teach the place again "
                            "instead")
    if entry["op"] == "observation":
        sample = int(entry["id"])
        uses = [k for k in later
                if k != seq and history[k]["op"] == "sentence" and int(history[k]["id"]) == sample]
        if uses:
            raise ConflictError(f"teaching {seq} cannot be undone: it added sample {sample}, which teaching "
                                f"{uses[-1]} gave a sentence since (undo that one first)")
    return {"op": "undo", "undoes": seq}


def undo_base_path(path: str | PathLike[str]) -> Path:
    """The undo base of the served home file ``path``: ``HOME.undo`` (a home file)."""
    return Path(str(path) + ".undo")


class UndoCheckpoints:
    """Homes as they were after the teachings up to some seqs: what an undo replays from.

    ``base``: the undo base (a home, or a function loading it, called at the first need) and its
    seq ``base_seq`` (its ``last_seq``); further checkpoints are added by :meth:`add` (the writer,
    every :data:`CHECKPOINT_EVERY` teachings) and by the replays of :func:`rebuild`.
    """

    def __init__(self, base: kn.HomeModel | Callable[[], kn.HomeModel], base_seq: int) -> None:
        self._loader = base if callable(base) else None
        self._homes: dict[int, kn.HomeModel] = {} if callable(base) else {int(base_seq): base}
        self.base_seq = int(base_seq)

    def before(self, seq: int) -> tuple[int, kn.HomeModel]:
        """The latest checkpoint taken before teaching ``seq``: (its seq, the home)."""
        if seq <= self.base_seq:
            raise ConflictError(f"teaching {seq} is older than the undo base (seq {self.base_seq})")
        if self.base_seq not in self._homes:
            assert self._loader is not None
            self._homes[self.base_seq] = self._loader()
        best = max(k for k in self._homes if k < seq)
        return best, self._homes[best]

    def add(self, seq: int, home: kn.HomeModel) -> None:
        """Keep ``home`` as it is after the teachings up to ``seq``."""
        self._homes[int(seq)] = home

    def drop_from(self, seq: int) -> None:
        """Forget the checkpoints at or after ``seq`` (an undo of ``seq`` changed what follows)."""
        for k in [k for k in self._homes if k >= seq and k != self.base_seq]:
            del self._homes[k]

    def advance(self, history: dict[int, dict[str, Any]], limit: int) -> kn.HomeModel | None:
        """Move the base to the latest checkpoint that still precedes the last ``limit`` teachings;
        returns the new base (to be written) or ``None`` if it did not move. Older checkpoints go."""
        teachings = _effective(history, self.base_seq)
        if len(teachings) <= limit:
            return None
        oldest = teachings[-limit]  # the oldest teaching that must stay undoable
        candidates = [k for k in self._homes if self.base_seq < k < oldest]
        if not candidates:
            return None
        new = max(candidates)
        for k in [k for k in self._homes if k < new]:
            del self._homes[k]
        self.base_seq = new
        return self._homes[new]

    def __len__(self) -> int:
        return len(self._homes)


def rebuild(start: kn.HomeModel, start_seq: int, history: dict[int, dict[str, Any]],
            checkpoints: UndoCheckpoints | None = None) -> kn.HomeModel:
    """The home after the teachings of ``history`` that hold (not undone) after ``start_seq``,
    replayed on ``start`` (the home after the teachings up to ``start_seq``) batch by batch, each
    batch with its recorded seed and sweeps (less its undone teachings): what the home is had the
    undone teachings never been made. Keeps a checkpoint in ``checkpoints`` every
    :data:`CHECKPOINT_EVERY` teachings replayed."""
    groups: dict[tuple[int, int], list[dict[str, Any]]] = {}
    for k in _effective(history, start_seq):
        record = history[k].get("record")
        if record is None:
            raise ConflictError(f"teaching {k} has no record to replay (taught before exact undo existed)")
        groups.setdefault(tuple(record["batch"]), []).append(record)
    home, since = start, 0
    for _, records in sorted(groups.items()):
        home = _teach_records(home, records)[0]
        since += len(records)
        if checkpoints is not None and since >= CHECKPOINT_EVERY:
            checkpoints.add(int(records[-1]["seq"]), home)
            since = 0
    return home


# ---------------------------------------------------------------------------- applying
def without_samples(home: kn.HomeModel, ids: list[int]) -> kn.HomeModel:
    """``home`` without the samples ``ids`` (their assignments dropped, region counts recounted).

    Its posterior is dropped too: the sweeps that follow (:func:`apply_batch` runs them) average it
    anew without the removed samples.
    """
    keep = ~np.isin(home.ids, np.asarray(ids, dtype=np.int64))
    rows = np.flatnonzero(keep)
    s = home.state
    regions = s.regions[keep].copy()
    counts = np.bincount(regions, minlength=s.region_counts.shape[1]).astype(s.region_counts.dtype)
    state = replace(s, concepts=s.concepts[keep].copy(), regions=regions, region_counts=counts[None, :],
                    visual_cache=None)
    return replace(home, state=state, ids=home.ids[keep], positions=home.positions[keep],
                   visual=sp.csr_array(home.visual[rows]), view_missing=home.view_missing[keep],
                   sentences=tuple(t for t, k in zip(home.sentences, keep, strict=True) if k), posterior=None)


def _view_row(view: dict[str, list[int]] | None, n_features: int) -> sp.csr_array:
    if view is None:
        return sp.csr_array((1, n_features), dtype=np.int64)
    indices = np.asarray(view["indices"], dtype=np.int64)
    return sp.csr_array((np.asarray(view["counts"], dtype=np.int64), (np.zeros_like(indices), indices)),
                        shape=(1, n_features))


def _entries(home: kn.HomeModel, records: list[dict[str, Any]]) -> dict[int, dict[str, Any]]:
    """The history entries of teaching ``records`` applied together to ``home`` (a sentence's
    entry remembers the one it replaced: what an undo restores)."""
    stamp = records[0].get("time") or utc_now()
    entries: dict[int, dict[str, Any]] = {}
    current = dict(zip(home.ids.tolist(), home.sentences, strict=True))
    for r in records:
        if r["op"] == "sentence":
            sample = int(r["id"])
            entries[r["seq"]] = {"op": "sentence", "id": sample, "sentence": r["sentence"],
                                 "previous": current.get(sample), "time": r.get("time", stamp), "record": r}
            current[sample] = r["sentence"]
        else:
            entries[r["seq"]] = {"op": "observation", "id": int(r["id"]), "sentence": r["sentence"],
                                 "x": r["x"], "y": r["y"], "theta": r["theta"],
                                 "time": r.get("time", stamp), "record": r}
            current[int(r["id"])] = r["sentence"]
    return entries


def _teach_records(home: kn.HomeModel, records: list[dict[str, Any]]
                   ) -> tuple[kn.HomeModel, dict[int, dict[str, Any]]]:
    """Teaching records of one batch applied again (its seed and sweeps; accepted under the writer's
    limits when they arrived, so replayed without them): the home and the records' history entries."""
    requests = [request_of(r, home.knowledge.n_features) for r in records]
    taught, _ = kn.teach_requests(home, requests, int(records[0]["sweeps"]), int(records[0]["seed"]),
                                  limits=None)
    return taught, _entries(home, records)


def teach_batch(home: kn.HomeModel, requests: list[Teach], first_seq: int, seed: int, sweeps: int,
                limits: kn.TeachingLimits | None, history: dict[int, dict[str, Any]],
                extractor: Callable[[], Any] | None = None
                ) -> tuple[kn.HomeModel, list[dict[str, Any]]]:
    """Teach checked requests as one batch from seq ``first_seq``: the home's one teaching call
    (:func:`spco.knowledge.teach_requests`, which checks what needs the home: known samples, new
    ids, poses on the map, views' counts, ``limits``), then the batch's journal records (the
    requests as applied, with ``seed`` and ``sweeps``). Updates ``history`` in place, as
    :func:`apply_batch` does; raises what the home refuses, with nothing changed."""
    stamp = utc_now("milliseconds")
    with warnings.catch_warnings(record=True) as caught:  # said in the answer (notes), not on stderr
        warnings.simplefilter("always", kn.OwnNamesSpreadWarning)
        updated, applied = kn.teach_requests(home, requests, sweeps, seed, limits, on_map=True,
                                             extractor=extractor)
    last = first_seq + len(applied) - 1
    records = [{"seq": first_seq + k, "batch": [first_seq, last], "seed": seed, "sweeps": sweeps,
                "time": stamp, **record_of(r)} for k, r in enumerate(applied)]
    entries = _entries(home, records)
    teachings = int(served_info(home).get("teachings", 0)) + len(records)
    return _served(updated, home, records, entries, teachings, caught, history), records


def _served(updated: kn.HomeModel, home: kn.HomeModel, records: list[dict[str, Any]],
            entries: dict[int, dict[str, Any]], teachings: int, caught: list[warnings.WarningMessage],
            history: dict[int, dict[str, Any]] | None) -> kn.HomeModel:
    """``updated`` (``home`` after ``records``) with its ``provenance["served"]`` (``last_seq``,
    ``teachings``) and the spreading-name warnings ``caught`` in ``last_teach``; ``history``
    updated in place with ``entries``."""
    if history is not None:
        history.update(entries)
    served = served_info(home)
    served.update(last_seq=int(records[-1]["seq"]), teachings=teachings)
    provenance = {**updated.provenance, SERVED: served}
    said = [str(w.message) for w in caught if issubclass(w.category, kn.OwnNamesSpreadWarning)]
    if isinstance(provenance.get("last_teach"), dict):
        provenance["last_teach"] = {**provenance["last_teach"], "warnings": said}
    return replace(updated, provenance=provenance)


def apply_batch(home: kn.HomeModel, records: list[dict[str, Any]],
                history: dict[int, dict[str, Any]] | None = None,
                checkpoints: UndoCheckpoints | None = None) -> kn.HomeModel:
    """Apply one batch of journal records (all with the same ``batch``, ``seed`` and ``sweeps``) again.

    Teachings become one :func:`spco.knowledge.teach_requests` call (sentences and observations
    together), as when they were taught (:func:`teach_batch`). An undo is a batch of its own: the
    home is rebuilt (:func:`rebuild`) from the latest of ``checkpoints`` before the undone teaching,
    with the teachings after it replayed; ``history`` (the records of the teachings since the
    checkpoint) and ``checkpoints`` are required for it. Updates ``provenance["served"]``
    (``last_seq``, ``teachings``) and ``history`` in place.
    """
    first = records[0]
    teachings = int(served_info(home).get("teachings", 0))
    with warnings.catch_warnings(record=True) as caught:  # said in the answer (notes), not on stderr
        warnings.simplefilter("always", kn.OwnNamesSpreadWarning)
        if first["op"] == "undo":
            if len(records) != 1:
                raise JournalError(f"an undo (seq {first['seq']}) must be a batch of its own")
            undone_seq = int(first["undoes"])
            if history is None or checkpoints is None:
                raise JournalError(f"seq {first['seq']} undoes teaching {undone_seq}: replaying it needs the "
                                   f"home's teaching history and its undo base ({undo_base_path('HOME')})")
            undone = history.get(undone_seq)
            if undone is None or undone.get("record") is None:
                raise JournalError(f"seq {first['seq']} undoes teaching {undone_seq}, whose record the home "
                                   "file does not hold")
            stamp = first.get("time") or utc_now()
            entries = {undone_seq: {**undone, "undone_by": first["seq"]},
                       first["seq"]: {"op": "undo", "undoes": undone_seq, "time": stamp}}
            start_seq, start = checkpoints.before(undone_seq)
            checkpoints.drop_from(undone_seq)
            updated = rebuild(start, start_seq, {**history, **entries}, checkpoints)
            teachings -= 1
        else:
            updated, entries = _teach_records(home, records)
            teachings += len(records)
    return _served(updated, home, records, entries, teachings, caught, history)


def batches(records: list[dict[str, Any]]) -> list[list[dict[str, Any]]]:
    """``records`` grouped by their ``batch`` (consecutive records with the same one)."""
    groups: list[list[dict[str, Any]]] = []
    for r in records:
        if groups and groups[-1][0]["batch"] == r["batch"]:
            groups[-1].append(r)
        else:
            groups.append([r])
    return groups


def replay(home: kn.HomeModel, records: list[dict[str, Any]],
           history: dict[int, dict[str, Any]] | None = None,
           checkpoints: UndoCheckpoints | None = None) -> kn.HomeModel:
    """Apply the journal ``records`` after the home's ``last_seq``, batch by batch (:func:`apply_batch`).

    Records up to ``last_seq`` are in the home already and skipped. Raises :class:`JournalError` if
    a record is missing between ``last_seq`` and the first one applied.
    """
    last = int(served_info(home).get("last_seq", 0))
    pending = [r for r in records if int(r["seq"]) > last]
    if pending and int(pending[0]["batch"][0]) != last + 1:
        raise JournalError(f"the journal continues at seq {pending[0]['batch'][0]} but the home file holds "
                           f"the teachings up to seq {last}: records {last + 1}…{pending[0]['batch'][0] - 1} "
                           "are missing")
    for group in batches(pending):
        home = apply_batch(home, group, history, checkpoints)
    return home


def file_digest(path: str | PathLike[str]) -> str:
    """sha256 of a file's bytes: how a journal started on a never-compacted home file names its base."""
    import hashlib

    with open(path, "rb") as handle:
        return hashlib.file_digest(handle, "sha256").hexdigest()


def check_journal_matches(home: kn.HomeModel, header: dict[str, Any] | None, records: list[dict[str, Any]],
                          journal: Any, path: str | PathLike[str]) -> None:
    """Raise :class:`JournalError` if the journal is not that of the home file ``path`` (another home file
    was put in its place) while it still holds teachings the file lacks. A journal belongs to the file
    whose ``provenance["served"]["journal"]`` is its ID, or, before the first compaction, to the file
    whose bytes its header's ``base_sha256`` names."""
    if header is None:
        return
    ident = served_info(home).get("journal")
    last = int(served_info(home).get("last_seq", 0))
    if not any(int(r["seq"]) > last for r in records) or header["journal"] == ident:
        return
    if header.get("base_sha256") is None or header["base_sha256"] != file_digest(path):
        raise JournalError(f"{journal} holds teachings of another version of {home.name!r} (journal "
                           f"{header['journal']}, the home file's is {ident}): the home file was replaced "
                           "while it had teachings not compacted into it; move the journal away to use the "
                           "file as it is")


def pending_teachings(path: str | PathLike[str]) -> int:
    """How many records of the journal of the home file ``path`` are not compacted into the file yet."""
    contents = read_journal(journal_path(path), warn=False)
    last = int(served_info(kn.load_home_model(path)).get("last_seq", 0))
    return sum(int(r["seq"]) > last for r in contents.records)


def load_current(path: str | PathLike[str], attempts: int = 5) -> tuple[kn.HomeModel, int]:
    """The home file at ``path`` with the teachings of its journal not yet compacted into it.

    What the read-only commands (``spco where``, ``what``, ``show``, ``inspect``) answer with while
    a home is served: the last compacted file plus its journal, so that no acknowledged teaching is
    missing. Returns the home and how many journal records were replayed (0 without a journal).
    The home's file and journal are read without a lock: when the server compacts between the two
    reads (records missing between them), they are read again, at most ``attempts`` times.
    """
    journal = journal_path(path)
    for attempt in range(attempts):
        home = kn.load_home_model(path)
        contents = read_journal(journal, warn=attempt == 0)
        check_journal_matches(home, contents.header, contents.records, journal, path)
        last = int(served_info(home).get("last_seq", 0))
        pending = [r for r in contents.records if int(r["seq"]) > last]
        if not pending:
            return home, 0
        if int(pending[0]["batch"][0]) != last + 1:  # compacted in between: read both again
            time.sleep(0.05)
            continue
        history = history_of(home)
        checkpoints = None
        if any(r["op"] == "undo" for r in pending):
            checkpoints = UndoCheckpoints(lambda: kn.load_home_model(undo_base_path(path)),
                                          undo_base_seq(home))
        home = replay(home, pending, history, checkpoints)
        return with_history(home, history), len(pending)
    raise JournalError(f"{journal}: it does not continue {path} (records missing after the file's last "
                       f"teaching) in {attempts} readings; is the server compacting it over and over?")
