"""Safe concurrent use of a knowledge or home file: one writer at a time, readers never blocked.

Every spco writer of a knowledge or home file (``spco fit``, ``adapt``, ``teach``; the library's
``Knowledge.save`` and ``HomeModel.save``) holds an exclusive lock on the file while it reads,
updates and replaces it, so two processes teaching the same home at once both keep their teaching:
the second waits for the first, then reads the file the first wrote. Readers (``where``, ``what``,
``show``) take no lock: a file is written to a temporary file and renamed into place, so a reader
sees either the old or the new file, never a half-written one.

The lock is ``fcntl.flock`` on a sidecar file ``<file>.lock`` beside the file (created on first use
and left in place; it holds the process id of the last holder, for the error message). The kernel
releases a flock when its holder exits or is killed, so a lock is never stale: a crashed writer does
not block the next one. A writer that cannot get the lock within ``timeout`` seconds (default 60, or
``$SPCO_LOCK_TIMEOUT``) gives up with :class:`LockTimeoutError` naming the file and the holder.

Locks are re-entrant within a thread: ``Knowledge.save`` inside ``with locked(path):`` does not wait
for itself. On Linux, macOS and the BSDs the lock is ``fcntl.flock`` (on NFS it depends on the
server); on Windows, where there is no ``fcntl``, it is ``msvcrt.locking`` of the lock file's first
byte (also released by the system when the holder dies; not exercised by the tests, which run on
Linux).

Usage (what ``spco teach`` does)::

    with locked(path):
        home = load_home_model(path)
        home = teach(home, {12: "this is the kitchen"})
        home.save(path, overwrite=True)
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Iterator
from os import PathLike
from pathlib import Path

from spco.errors import SpcoError

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None  # type: ignore[assignment]
    import msvcrt

__all__ = ["DEFAULT_TIMEOUT", "LockTimeoutError", "lock_path", "locked"]

#: Seconds a writer waits for another writer of the same file before giving up.
DEFAULT_TIMEOUT = 60.0
_POLL_SECONDS = 0.02
_held = threading.local()  # lock path -> [file descriptor, depth], per thread


class LockTimeoutError(SpcoError):
    """Another process held the lock of a file for longer than the writer would wait."""


def lock_path(path: str | PathLike[str]) -> Path:
    """The sidecar lock file of ``path``: ``<path>.lock`` in the same folder."""
    target = Path(path).expanduser().absolute()
    return target.with_name(target.name + ".lock")


def _timeout(timeout: float | None) -> float:
    if timeout is not None:
        return float(timeout)
    text = os.environ.get("SPCO_LOCK_TIMEOUT", "").strip()
    if not text:
        return DEFAULT_TIMEOUT
    try:
        value = float(text)
    except ValueError:
        raise SpcoError(f"SPCO_LOCK_TIMEOUT must be a number of seconds, got {text!r}") from None
    if not value >= 0:
        raise SpcoError(f"SPCO_LOCK_TIMEOUT must be ≥ 0 seconds, got {text!r}")
    return value


def _try_lock(fd: int) -> bool:
    """Take the exclusive lock of the open lock file ``fd`` if it is free; whether it was taken."""
    if fcntl is not None:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        return True
    os.lseek(fd, 0, os.SEEK_SET)
    try:
        msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
    except OSError:
        return False
    return True


def _unlock(fd: int) -> None:
    if fcntl is not None:
        fcntl.flock(fd, fcntl.LOCK_UN)
    else:
        os.lseek(fd, 0, os.SEEK_SET)
        msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)


def _holder(fd: int) -> str:
    """The process id written by the current holder (best effort, for messages)."""
    with contextlib.suppress(OSError, ValueError):
        os.lseek(fd, 0, os.SEEK_SET)
        text = os.read(fd, 32).decode("ascii", "replace").strip()
        if text.isdigit():
            return f"process {text}"
    return "another process"


@contextlib.contextmanager
def locked(path: str | PathLike[str], timeout: float | None = None) -> Iterator[Path]:
    """Hold the exclusive write lock of ``path`` (a knowledge or home file) inside the block.

    Waits at most ``timeout`` seconds (default ``$SPCO_LOCK_TIMEOUT`` or 60; 0 = do not wait) for
    another writer, then raises :class:`LockTimeoutError`. Re-entrant within a thread. Yields the
    lock file's path. A folder where the lock file cannot be created raises :class:`SpcoError`.
    """
    sidecar = lock_path(path)
    key = str(sidecar)
    held: dict[str, list[int]] = getattr(_held, "locks", None) or {}
    _held.locks = held
    if key in held:  # this thread holds it already
        held[key][1] += 1
        try:
            yield sidecar
        finally:
            held[key][1] -= 1
        return
    wait = _timeout(timeout)
    try:
        fd = os.open(sidecar, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as exc:
        raise SpcoError(f"{Path(path)}: cannot create the lock file {sidecar}: "
                        f"{exc.strerror or exc}") from None
    try:
        deadline = time.monotonic() + wait
        while not _try_lock(fd):
            if time.monotonic() >= deadline:
                raise LockTimeoutError(
                    f"{Path(path)}: {_holder(fd)} is still writing this file after {wait:g} s of waiting "
                    f"(lock file {sidecar}); try again when it is done, or wait longer with "
                    "SPCO_LOCK_TIMEOUT=SECONDS")
            time.sleep(_POLL_SECONDS)
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.lseek(fd, 0, os.SEEK_SET)
            os.write(fd, f"{os.getpid()}\n".encode("ascii"))
        held[key] = [fd, 1]
        try:
            yield sidecar
        finally:
            del held[key]
            _unlock(fd)
    finally:
        os.close(fd)
