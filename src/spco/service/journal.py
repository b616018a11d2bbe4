"""The append-only journal of a served home: teachings are durable before they are acknowledged.

A home served by ``spco serve`` (:class:`spco.service.LiveHome`) is not rewritten on every
teaching: each teaching is appended to a journal beside the home file, ``<home>.journal``, and
``fsync``-ed before the teaching is acknowledged; the journal is *compacted* into the home file
from time to time (the home file is written atomically with the sequence number of the last
teaching it holds, then the journal is rewritten without the records up to it).

File layout (UTF-8 text, one record a line)::

    <crc32 of the JSON, 8 hex digits> <JSON object>\\n

The first line is the header ``{"format": "spco-journal", "version": 1, "journal": ID, "home":
NAME, "base_seq": N, "created": ISO}``: ``journal`` ties the journal to the home file, whose
provenance holds the same ID (``provenance["served"]["journal"]``); records with a sequence number
≤ the home file's ``last_seq`` are already in it and are skipped, so a crash between writing the
home file and rewriting the journal never applies a teaching twice. Every other line is one
teaching (or undo), with its own ``seq`` and everything needed to replay it to the same state:
the batch it was applied in (``batch``: ``[first_seq, last_seq]``, teachings that arrived together
are applied by one :func:`spco.knowledge.teach` call), the batch's random ``seed`` and ``sweeps``
(see :mod:`spco.service.teaching` for the record kinds).

Reading (:func:`read_journal`) checks every line's CRC: a last line cut short or failing its CRC
(the process died while writing it) is a *torn* record, dropped with a :class:`TornRecordWarning`,
and so is a last batch of which only some records were written — neither was acknowledged, since
a batch is acknowledged after the ``fsync`` of all its records. A bad line followed by good ones
is not a torn write but damage: :class:`JournalError`, naming the file and the line.
"""

from __future__ import annotations

import contextlib
import json
import os
import uuid
import warnings
import zlib
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path
from typing import Any

from spco.errors import SpcoError
from spco.timestamps import utc_now

__all__ = [
    "JOURNAL_FORMAT",
    "JOURNAL_VERSION",
    "Journal",
    "JournalContents",
    "JournalError",
    "TornRecordWarning",
    "encode_record",
    "journal_path",
    "new_journal_id",
    "read_journal",
]

JOURNAL_FORMAT = "spco-journal"
JOURNAL_VERSION = 1


class JournalError(SpcoError):
    """A journal that cannot be replayed: damaged in the middle, from a newer spco, or another home's."""


class TornRecordWarning(UserWarning):
    """The journal ended with a record (or batch) cut short by a crash; it was never acknowledged."""


def journal_path(home_path: str | PathLike[str]) -> Path:
    """The journal of the home file ``home_path``: ``<home_path>.journal`` in the same folder."""
    target = Path(home_path).expanduser().absolute()
    return target.with_name(target.name + ".journal")


def new_journal_id() -> str:
    """A fresh random identifier tying a journal to its home file."""
    return uuid.uuid4().hex


def encode_record(record: dict[str, Any]) -> bytes:
    """One journal line: the CRC-32 of the record's JSON (8 hex digits), a space, the JSON, a newline.

    NaN and infinities are refused (``ValueError``): a record must read back as it was written.
    """
    text = json.dumps(record, ensure_ascii=False, allow_nan=False, separators=(",", ":"))
    data = text.encode("utf-8")
    return b"%08x " % zlib.crc32(data) + data + b"\n"


def _decode_line(line: bytes) -> dict[str, Any] | None:
    """The record of a complete line, or ``None`` if its CRC or JSON is bad."""
    if len(line) < 10 or line[8:9] != b" ":
        return None
    try:
        crc = int(line[:8], 16)
    except ValueError:
        return None
    data = line[9:]
    if zlib.crc32(data) != crc:
        return None
    try:
        record = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None
    return record if isinstance(record, dict) else None


@dataclass
class JournalContents:
    """What :func:`read_journal` found.

    Attributes
    ----------
    header: the header record (``None`` for a missing or empty file).
    records: the complete records after the header, in order (whole batches only).
    torn: a sentence saying what was dropped at the end, or ``None``.
    good_bytes: the length of the file's intact prefix (header and ``records``).
    """

    header: dict[str, Any] | None
    records: list[dict[str, Any]] = field(default_factory=list)
    torn: str | None = None
    good_bytes: int = 0


def _check_header(path: Path, header: dict[str, Any] | None) -> dict[str, Any]:
    if header is None or header.get("format") != JOURNAL_FORMAT:
        raise JournalError(f"{path}: not an spco journal (its first line is not a journal header); move it "
                           "away if it is not one")
    version = header.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise JournalError(f"{path}: invalid journal version {version!r}")
    if version > JOURNAL_VERSION:
        raise JournalError(f"{path}: written by a newer spco (journal version {version}); this spco reads "
                           f"up to version {JOURNAL_VERSION} — upgrade spco")
    if not isinstance(header.get("journal"), str):
        raise JournalError(f"{path}: the journal header has no identifier")
    return header


def _check_record(path: Path, number: int, record: dict[str, Any]) -> None:
    seq, batch, seed = record.get("seq"), record.get("batch"), record.get("seed")
    ok = (isinstance(seq, int) and not isinstance(seq, bool) and seq >= 1
          and isinstance(batch, list) and len(batch) == 2 and all(isinstance(b, int) for b in batch)
          and batch[0] <= seq <= batch[1] and isinstance(seed, int) and isinstance(record.get("op"), str))
    if not ok:
        raise JournalError(f"{path}, line {number}: a record without a valid seq, batch, seed and op: "
                           f"{json.dumps(record)[:200]}")


def _decoded_lines(raw: bytes) -> tuple[list[tuple[int, dict[str, Any] | None, int]], str | None]:
    """The journal's lines as (line number, record or ``None`` if damaged, end offset), without the
    damaged or unfinished lines at its end (a torn write), and why those were dropped (or ``None``)."""
    lines = raw.split(b"\n")
    complete = lines[:-1]  # the part after the last newline is an unfinished line (or b"")
    tail = lines[-1]
    decoded: list[tuple[int, dict[str, Any] | None, int]] = []
    offset = 0
    for number, line in enumerate(complete, start=1):
        offset += len(line) + 1
        decoded.append((number, _decode_line(line), offset))
    torn = None
    if tail:
        torn = f"its last line ({len(tail)} bytes) was cut short"
    while decoded and decoded[-1][1] is None:  # bad lines at the end: a torn write
        number = decoded.pop()[0]
        torn = f"line {number} fails its checksum" if torn is None else torn
    return decoded, torn


def read_journal(path: str | PathLike[str], warn: bool = True) -> JournalContents:
    """Read the journal at ``path``; a missing or empty file gives an empty :class:`JournalContents`.

    Drops a torn last record or incomplete last batch (with a :class:`TornRecordWarning` if
    ``warn``; the sentence is in ``torn`` either way). Raises :class:`JournalError` for a damaged
    line followed by good ones, records out of order, or a bad header.
    """
    file = Path(path)
    try:
        raw = file.read_bytes()
    except FileNotFoundError:
        return JournalContents(header=None)
    except OSError as exc:
        raise JournalError(f"{file}: cannot read the journal ({exc.strerror or exc})") from None
    if not raw:
        return JournalContents(header=None)
    decoded, torn = _decoded_lines(raw)
    bad = next((number for number, record, _ in decoded if record is None), None)
    if bad is not None:
        raise JournalError(f"{file}, line {bad}: damaged record (checksum mismatch) followed by intact "
                           "ones; the journal was modified or the disk is failing; restore it from a "
                           "backup or move it away (its teachings after the last compaction are then lost)")
    if not decoded:
        if torn is not None and warn:
            warnings.warn(f"{file}: {torn}; it was never acknowledged and is dropped", TornRecordWarning,
                          stacklevel=2)
        return JournalContents(header=None, torn=torn)
    header = _check_header(file, decoded[0][1])
    records: list[dict[str, Any]] = []
    good = decoded[0][2]
    pending: list[tuple[dict[str, Any], int]] = []  # records of the batch being read
    previous = int(header.get("base_seq", 0))
    for number, record, end in decoded[1:]:
        assert record is not None
        _check_record(file, number, record)
        if record["seq"] <= previous:
            raise JournalError(f"{file}, line {number}: seq {record['seq']} after seq {previous}: records "
                               "out of order")
        previous = record["seq"]
        if pending and record["batch"] != pending[0][0]["batch"]:
            first = pending[0][0]
            raise JournalError(f"{file}, line {number}: batch {first['batch']} is incomplete but followed "
                               "by another batch")
        pending.append((record, end))
        if record["seq"] == record["batch"][1]:
            records.extend(r for r, _ in pending)
            good = end
            pending = []
    if pending:
        first = pending[0][0]
        torn = (f"its last batch (seq {first['batch'][0]}…{first['batch'][1]}) has only "
                f"{len(pending)} of its records") + (f" and {torn}" if torn else "")
    if torn is not None and warn:
        warnings.warn(f"{file}: {torn}; it was never acknowledged and is dropped", TornRecordWarning,
                      stacklevel=2)
    return JournalContents(header=header, records=records, torn=torn, good_bytes=good)


def _fsync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):  # not every file system lets a folder be opened
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


class Journal:
    """The open journal of a served home, written by its one writer.

    :meth:`rewrite` replaces the file atomically (temporary file, ``fsync``, rename, ``fsync`` of
    the folder) with a new header and the given records; :meth:`append` adds whole batches with one
    ``write`` and an ``fsync`` before it returns.
    """

    def __init__(self, path: str | PathLike[str]) -> None:
        self.path = Path(path)
        self._fd = -1

    def rewrite(self, header: dict[str, Any], records: list[dict[str, Any]]) -> None:
        """Make the journal ``header`` followed by ``records``, atomically, and open it for appending."""
        header = {"format": JOURNAL_FORMAT, "version": JOURNAL_VERSION,
                  "created": utc_now(), **header}
        data = encode_record(header) + b"".join(encode_record(r) for r in records)
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            os.write(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, self.path)
        _fsync_folder(self.path.parent)
        self.close()
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)

    def append(self, records: list[dict[str, Any]]) -> None:
        """Append ``records`` (whole batches) and ``fsync``: durable when this returns."""
        if self._fd < 0:
            raise JournalError(f"{self.path}: the journal is not open")
        data = b"".join(encode_record(r) for r in records)
        view = memoryview(data)
        while view:
            written = os.write(self._fd, view)
            view = view[written:]
        os.fsync(self._fd)

    def close(self) -> None:
        """Close the file (nothing is lost: every append was ``fsync``-ed)."""
        if self._fd >= 0:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = -1
