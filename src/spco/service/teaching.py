"""Teachings of a served home as journal records: validated, applied in batches, replayed, undone.

A teaching arrives as a request (a sentence for a known sample, or a new observation: a pose, an
optional view and a sentence), is validated against the home (:func:`sentence_record`,
:func:`observation_record`), given a sequence number, and applied together with the teachings
that arrived with it by one :func:`spco.knowledge.teach` call (:func:`apply_batch`). The journal
record (:mod:`spco.service.journal`) holds the request as applied — the sample id an observation
got, its visual counts (an image is turned into counts before it is recorded), the batch, its seed
and its sweeps — so that :func:`replay` of the records from the home file gives the same home,
bit for bit.

Record kinds (``op``), besides ``seq``, ``batch``, ``seed``, ``sweeps`` and ``time``:

``sentence``
    ``id``, ``sentence`` (``null`` forgets the sample's sentence).
``observation``
    ``id`` (the new sample's), ``x``, ``y``, ``theta`` (metres, radians), ``sentence``, ``view``:
    ``{"indices": [...], "counts": [...]}`` of the view's visual counts, or ``null`` for a pose
    without a view (its visual likelihood is 1: only the position and the words are learnt from it).
``undo``
    ``undoes`` (the seq of the teaching undone), ``restore`` (sample id → the sentence it had
    before, for a sentence) and ``remove`` (the sample ids an observation added). An undo is
    self-contained, so it replays after the undone teaching was compacted into the home file.

The home file remembers what it needs in ``provenance["served"]``: ``journal`` (the ID of its
journal), ``last_seq`` (the last teaching it holds), ``teachings`` (teachings applied through the
journal and not undone) and ``history`` (seq → what the teaching did and what it replaced, for the
last :data:`HISTORY_LIMIT` teachings; what :func:`plan_undo` needs).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import replace
from datetime import UTC, datetime
from os import PathLike
from typing import Any

import numpy as np
import scipy.sparse as sp

from spco import knowledge as kn
from spco.errors import ConfigurationError, SpcoError
from spco.knowledge.requests import MAX_SENTENCE_CHARS
from spco.model.prediction import validate_visual_counts
from spco.service.answers import check_pose
from spco.service.journal import JournalError, journal_path, read_journal

__all__ = [
    "HISTORY_LIMIT",
    "MAX_SENTENCE_CHARS",
    "ConflictError",
    "NotFoundError",
    "apply_batch",
    "batches",
    "check_journal_matches",
    "check_pose",
    "file_digest",
    "history_of",
    "load_current",
    "observation_record",
    "pending_teachings",
    "plan_undo",
    "replay",
    "sentence_record",
    "served_info",
    "view_record",
    "with_history",
    "without_samples",
]

#: How many teachings the home file remembers for :func:`plan_undo` (older ones cannot be undone).
HISTORY_LIMIT = 10_000
SERVED = "served"


class NotFoundError(SpcoError, LookupError):
    """A sample id or teaching seq the home does not have (HTTP 404)."""


class ConflictError(SpcoError):
    """A request that contradicts the home's current state (HTTP 409): an id taken, an undo of a
    teaching that a later one changed or that was undone already."""


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def served_info(home: kn.HomeModel) -> dict[str, Any]:
    """``provenance["served"]`` of ``home`` without its history: ``journal``, ``last_seq``, ``teachings``
    (empty for a home never served)."""
    served = home.provenance.get(SERVED) or {}
    return {k: v for k, v in served.items() if k != "history"}


def history_of(home: kn.HomeModel) -> dict[int, dict[str, Any]]:
    """A copy of the teaching history kept in ``home``'s file (seq → entry)."""
    served = home.provenance.get(SERVED) or {}
    return {int(k): dict(v) for k, v in (served.get("history") or {}).items()}


def with_history(home: kn.HomeModel, history: dict[int, dict[str, Any]] | None) -> kn.HomeModel:
    """``home`` with ``history`` (the last :data:`HISTORY_LIMIT` entries) in ``provenance["served"]``,
    or without any history for ``None`` (a snapshot for readers: they do not need it)."""
    served = served_info(home)
    if history is not None:
        kept = sorted(history)[-HISTORY_LIMIT:]
        served["history"] = {str(k): history[k] for k in kept}
    return replace(home, provenance={**home.provenance, SERVED: served})


# ---------------------------------------------------------------------------- requests -> records
def _clean_sentence(sentence: object) -> str | None:
    if sentence is None:
        return None
    if not isinstance(sentence, str):
        raise ConfigurationError(f"sentence: expected a string or null, got {type(sentence).__name__}")
    if len(sentence) > MAX_SENTENCE_CHARS:
        raise ConfigurationError(f"sentence: {len(sentence)} characters; at most {MAX_SENTENCE_CHARS}")
    return sentence.strip() or None


def _sample_id(value: object, what: str = "id") -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise ConfigurationError(f"{what}: expected an integer sample id, got {value!r}")
    return int(value)


def _check_known(home: kn.HomeModel, sample_id: int) -> None:
    if not (home.ids == sample_id).any():
        raise NotFoundError(f"home {home.name!r} has no sample with id {sample_id} (its {home.n_samples} "
                            f"samples have ids {int(home.ids.min())}…{int(home.ids.max())}); teach a new "
                            "place by its pose instead")


def sentence_record(home: kn.HomeModel, sample_id: object, sentence: object) -> dict[str, Any]:
    """The record of a sentence for the known sample ``sample_id`` (``None`` or ``""`` forgets it).

    Raises :class:`NotFoundError` for an id the home does not have, :class:`ConfigurationError` for
    a sentence that is not a string (or longer than :data:`MAX_SENTENCE_CHARS`).
    """
    sample = _sample_id(sample_id)
    _check_known(home, sample)
    return {"op": "sentence", "id": sample, "sentence": _clean_sentence(sentence)}


def view_record(home: kn.HomeModel, counts: object) -> dict[str, list[int]] | None:
    """A view's visual counts as ``{"indices", "counts"}`` (its non-zero entries), ``None`` for none.

    ``counts``: a (D,) vector of whole numbers ≥ 0, D the home's visual dimension (an image is
    turned into counts by :func:`spco.service.images.view_counts` first)."""
    if counts is None:
        return None
    if not sp.issparse(counts) and np.ndim(counts) != 1:
        raise ConfigurationError(f"visual: expected one view's counts (a vector), got shape "
                                 f"{np.shape(counts)}")
    row = validate_visual_counts(counts, home.knowledge.n_features)
    if row.shape[0] != 1:
        raise ConfigurationError(f"visual: expected one view's counts, got {row.shape[0]} rows")
    row.eliminate_zeros()
    row.sort_indices()
    return {"indices": [int(i) for i in row.indices], "counts": [int(c) for c in row.data]}


def observation_record(home: kn.HomeModel, x: object, y: object, theta: object, sentence: object = None,
                       counts: object = None, sample_id: object = None) -> dict[str, Any]:
    """The record of a new observation: a pose, an optional view (visual counts) and a sentence.

    ``sample_id`` (optional) must be new to the home (:class:`ConflictError` otherwise); without it
    the writer gives the sample one more than the largest id. Raises :class:`ConfigurationError`
    for a bad pose (:func:`check_pose`), view or sentence.
    """
    px, py, ptheta = check_pose(home, x, y, theta)
    record: dict[str, Any] = {"op": "observation", "id": None, "x": px, "y": py, "theta": ptheta,
                              "sentence": _clean_sentence(sentence), "view": view_record(home, counts)}
    if sample_id is not None:
        sample = _sample_id(sample_id)
        if (home.ids == sample).any():
            raise ConflictError(f"home {home.name!r} already has a sample with id {sample}")
        record["id"] = sample
    return record


def plan_undo(home: kn.HomeModel, history: dict[int, dict[str, Any]], seq: object) -> dict[str, Any]:
    """The record undoing teaching ``seq``: restore the sentence it replaced, or remove the sample it added.

    Raises :class:`NotFoundError` for a seq not in the history, :class:`ConflictError` for a teaching
    already undone, or whose sample was changed since (by a later teaching: undo that first).
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
    sample = int(entry["id"])
    later = [k for k, e in history.items() if k > seq and e.get("undone_by") is None
             and e["op"] != "undo" and int(e["id"]) == sample]
    index = np.flatnonzero(home.ids == sample)
    current = home.sentences[int(index[0])] if index.size else None
    if later or index.size == 0 or current != entry["sentence"]:
        by = f"teaching {later[-1]} (undo it first)" if later else "a teaching since"
        raise ConflictError(f"teaching {seq} cannot be undone: sample {sample} was changed by {by}")
    if entry["op"] == "sentence":
        return {"op": "undo", "undoes": seq, "restore": {str(sample): entry["previous"]}, "remove": []}
    return {"op": "undo", "undoes": seq, "restore": {}, "remove": [sample]}


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


def apply_batch(home: kn.HomeModel, records: list[dict[str, Any]],
                history: dict[int, dict[str, Any]] | None = None) -> kn.HomeModel:
    """Apply one batch of journal records (all with the same ``batch``, ``seed`` and ``sweeps``).

    Teachings become one :func:`spco.knowledge.teach` call (sentences and observations together);
    an undo is a batch of its own: the samples an observation added are removed
    (:func:`without_samples`) and replaced sentences restored, then the sweeps run (with nothing to
    restore, the first sample's sentence is re-asserted: it changes no data and runs the sweeps).
    Updates ``provenance["served"]`` (``last_seq``, ``teachings``) and ``history`` in place.
    """
    first = records[0]
    seed, sweeps = int(first["seed"]), int(first["sweeps"])
    served = served_info(home)
    teachings = int(served.get("teachings", 0))
    stamp = first.get("time") or _now()
    entries: dict[int, dict[str, Any]] = {}  # merged into history once the teaching succeeded
    with warnings.catch_warnings(record=True) as caught:  # said in the answer (notes), not on stderr
        warnings.simplefilter("always", kn.OwnNamesSpreadWarning)
        if first["op"] == "undo":
            if len(records) != 1:
                raise JournalError(f"an undo (seq {first['seq']}) must be a batch of its own")
            updated = home
            if first["remove"]:
                updated = without_samples(updated, [int(i) for i in first["remove"]])
            restore = {int(k): v for k, v in first["restore"].items()}
            if not restore:
                restore = {int(updated.ids[0]): updated.sentences[0]}
            updated = kn.teach(updated, restore, n_sweeps=sweeps, random_state=seed)
            undone = (history or {}).get(int(first["undoes"]))
            if undone is not None:
                entries[int(first["undoes"])] = {**undone, "undone_by": first["seq"]}
            entries[first["seq"]] = {"op": "undo", "undoes": first["undoes"], "time": stamp}
            teachings -= 1
        else:
            sentences: dict[int, str | None] = {}
            observations = []
            current = dict(zip(home.ids.tolist(), home.sentences, strict=True))
            for r in records:
                if r["op"] == "sentence":
                    sample = int(r["id"])
                    previous = sentences.get(sample, current.get(sample))
                    sentences[sample] = r["sentence"]
                    entries[r["seq"]] = {"op": "sentence", "id": sample, "sentence": r["sentence"],
                                         "previous": previous, "time": r.get("time", stamp)}
                elif r["op"] == "observation":
                    observations.append(kn.Observation(
                        x=float(r["x"]), y=float(r["y"]), theta=float(r["theta"]),
                        visual=None if r["view"] is None else _view_row(r["view"], home.knowledge.n_features),
                        sentence=r["sentence"],  # no view: a sample without one (its likelihood left out)
                        id=int(r["id"])))
                    entries[r["seq"]] = {"op": "observation", "id": int(r["id"]), "sentence": r["sentence"],
                                         "x": r["x"], "y": r["y"], "theta": r["theta"],
                                         "time": r.get("time", stamp)}
                else:
                    raise JournalError(f"seq {r['seq']}: unknown record kind {r['op']!r}")
            updated = kn.teach(home, sentences, observations, n_sweeps=sweeps, random_state=seed)
            teachings += len(records)
    if history is not None:
        history.update(entries)
    served.update(last_seq=int(records[-1]["seq"]), teachings=teachings)
    provenance = {**updated.provenance, SERVED: served}
    said = [str(w.message) for w in caught if issubclass(w.category, kn.OwnNamesSpreadWarning)]
    if said and isinstance(provenance.get("last_teach"), dict):
        provenance["last_teach"] = {**provenance["last_teach"], "warnings": said}
    return replace(updated, provenance=provenance)


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
           history: dict[int, dict[str, Any]] | None = None) -> kn.HomeModel:
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
        home = apply_batch(home, group, history)
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
        home = replay(home, pending, history)
        return with_history(home, history), len(pending)
    raise JournalError(f"{journal}: it does not continue {path} (records missing after the file's last "
                       f"teaching) in {attempts} readings; is the server compacting it over and over?")
