"""Time stamps of spco's files and records: the current time in UTC as ISO 8601 text."""

from __future__ import annotations

from datetime import UTC, datetime

__all__ = ["utc_now"]


def utc_now(timespec: str = "seconds") -> str:
    """The current UTC time as ISO 8601 text, e.g. ``2026-12-06T03:00:00+00:00``: to the second for
    files' provenance (``"seconds"``), to the millisecond for journal records (``"milliseconds"``);
    ``timespec`` as :meth:`datetime.datetime.isoformat` takes it."""
    return datetime.now(UTC).isoformat(timespec=timespec)
