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

A resident server (``spco serve``, :class:`spco.service.LiveHome`) holds the lock for as long as it
runs (:func:`hold`) and writes who it is into the lock file (``served-by: spco serve (pid …) at
http://…``): every other writer is then refused at once with :class:`HomeServedError` naming the
server, instead of waiting for a lock that is not going to be released. Its writer process, which
inherits the lock's descriptor, declares it with :func:`adopt`, so that its own saves pass.
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

__all__ = ["DEFAULT_TIMEOUT", "HeldLock", "HomeServedError", "LockTimeoutError", "adopt", "hold", "lock_path",
           "locked", "served_by"]

#: Seconds a writer waits for another writer of the same file before giving up.
DEFAULT_TIMEOUT = 60.0
_POLL_SECONDS = 0.02
_held = threading.local()  # lock path -> [file descriptor, depth], per thread
_held_by_process: dict[str, HeldLock] = {}  # lock path -> lock held for this whole process (hold, adopt)
#: The line of a lock file that says a resident server holds it (see :func:`hold`).
SERVED_MARK = "served-by: "


class LockTimeoutError(SpcoError):
    """Another process held the lock of a file for longer than the writer would wait."""


class HomeServedError(LockTimeoutError):
    """The file is held by a resident server (``spco serve``): other writers are refused at once."""


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


def _holder_info(fd: int) -> tuple[int | None, str | None]:
    """The process id and the ``served-by`` description written by the current holder (best effort)."""
    with contextlib.suppress(OSError, ValueError):
        os.lseek(fd, 0, os.SEEK_SET)
        lines = os.read(fd, 4096).decode("utf-8", "replace").splitlines()
        pid = int(lines[0]) if lines and lines[0].strip().isdigit() else None
        served = next((line[len(SERVED_MARK):].strip() for line in lines[1:] if line.startswith(SERVED_MARK)),
                      None)
        return pid, served
    return None, None


def _holder(fd: int) -> str:
    """The process id written by the current holder (best effort, for messages)."""
    pid, _ = _holder_info(fd)
    return "another process" if pid is None else f"process {pid}"


def _alive(pid: int | None) -> bool:
    if pid is None:
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: alive
        return True
    return True


def _served_error(path: str | PathLike[str], served: str) -> HomeServedError:
    return HomeServedError(f"{Path(path)} is served by {served}: teach it through the server (POST "
                           "/teach, or spco.service.client.Client.teach), or stop the server first; its "
                           "teachings are in the file once it has stopped")


def served_by(path: str | PathLike[str]) -> str | None:
    """Who serves ``path`` now (the ``served-by`` description of a running ``spco serve``), or ``None``.

    Reads the lock file and probes its lock without taking it for long; a server that was killed
    is not reported (the kernel released its lock).
    """
    sidecar = lock_path(path)
    if str(sidecar) in _held_by_process:
        return _held_by_process[str(sidecar)].description
    try:
        fd = os.open(sidecar, os.O_RDWR)
    except OSError:
        return None
    try:
        if _try_lock(fd):
            _unlock(fd)
            return None
        _, served = _holder_info(fd)
        return served
    finally:
        os.close(fd)


def _open_lock_file(path: str | PathLike[str], sidecar: Path) -> int:
    """A descriptor of ``path``'s lock file ``sidecar``, created if missing; :class:`SpcoError` if
    the folder does not allow it."""
    try:
        return os.open(sidecar, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as exc:
        raise SpcoError(f"{Path(path)}: cannot create the lock file {sidecar}: "
                        f"{exc.strerror or exc}") from None


@contextlib.contextmanager
def locked(path: str | PathLike[str], timeout: float | None = None) -> Iterator[Path]:
    """Hold the exclusive write lock of ``path`` (a knowledge or home file) inside the block.

    Waits at most ``timeout`` seconds (default ``$SPCO_LOCK_TIMEOUT`` or 60; 0 = do not wait) for
    another writer, then raises :class:`LockTimeoutError`. Re-entrant within a thread. Yields the
    lock file's path. A folder where the lock file cannot be created raises :class:`SpcoError`.
    """
    sidecar = lock_path(path)
    key = str(sidecar)
    if key in _held_by_process:  # a resident server of this process holds it (hold, adopt)
        server = _held_by_process[key]
        if not server.permits(threading.get_ident()):
            raise _served_error(path, server.description)
        yield sidecar
        return
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
    fd = _open_lock_file(path, sidecar)
    try:
        deadline = time.monotonic() + wait
        while not _try_lock(fd):
            pid, served = _holder_info(fd)
            if served is not None and _alive(pid):
                raise _served_error(path, served)
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


class HeldLock:
    """The write lock of a file held for the life of a resident server (:func:`hold`, :func:`adopt`).

    Attributes
    ----------
    path: the knowledge or home file; sidecar: its lock file; fd: the lock file's descriptor (a child
    process given it keeps the lock alive with the server); description: who holds it, as other
    writers are told.
    """

    def __init__(self, path: Path, sidecar: Path, fd: int, description: str, owner: bool) -> None:
        self.path, self.sidecar, self.fd, self.description = path, sidecar, fd, description
        self._owner = owner
        # the threads of this process that may write the file (None: all, in an adopting writer process)
        self._threads: set[int] | None = {threading.get_ident()} if owner else None

    def permit(self, thread: int | None = None) -> None:
        """Let a thread of this process (default: the calling one) write the file: the served home's
        writer thread. The thread that took the lock may; other threads are refused like other processes."""
        if self._threads is not None:
            self._threads.add(threading.get_ident() if thread is None else thread)

    def permits(self, thread: int) -> bool:
        """Whether ``thread`` may write the file while it is held."""
        return self._threads is None or thread in self._threads

    def release(self) -> None:
        """Give the lock up (the owner unlocks it; an adopter only forgets it) and close the descriptor."""
        if _held_by_process.get(str(self.sidecar)) is self:
            del _held_by_process[str(self.sidecar)]
        if self.fd < 0:
            return
        with contextlib.suppress(OSError):
            if self._owner:
                os.ftruncate(self.fd, 0)
                _unlock(self.fd)
            os.close(self.fd)
        self.fd = -1

    def __enter__(self) -> HeldLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def hold(path: str | PathLike[str], description: str, timeout: float | None = None,
         dead_server_grace: float = 10.0) -> HeldLock:
    """Take the write lock of ``path`` for a resident server, until :meth:`HeldLock.release`.

    Writes ``<pid>`` and ``served-by: <description>`` into the lock file: any writer in another
    process (:func:`locked`) is then refused at once with :class:`HomeServedError` naming it, and
    :func:`served_by` reports it; so is every thread of this process but the calling one and those
    given :meth:`HeldLock.permit` (the served home's writer). Waits like a writer (``timeout``) for
    another writer (a ``spco teach``) to finish; refuses at once when another live server holds it;
    waits at most ``dead_server_grace`` seconds for the lock of a killed server to be released (its
    writer process exits with it).
    """
    sidecar = lock_path(path)
    if str(sidecar) in _held_by_process:
        raise _served_error(path, _held_by_process[str(sidecar)].description)
    wait = _timeout(timeout)
    fd = _open_lock_file(path, sidecar)
    try:
        start = time.monotonic()
        while not _try_lock(fd):
            pid, served = _holder_info(fd)
            waited = time.monotonic() - start
            if served is not None and (_alive(pid) or waited >= dead_server_grace):
                raise _served_error(path, served)
            if served is None and waited >= wait:
                raise LockTimeoutError(f"{Path(path)}: {_holder(fd)} is still writing this file after "
                                       f"{wait:g} s of waiting (lock file {sidecar})")
            time.sleep(_POLL_SECONDS)
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)
        os.write(fd, f"{os.getpid()}\n{SERVED_MARK}{description}\n".encode())
    except BaseException:
        os.close(fd)
        raise
    lock = HeldLock(Path(path), sidecar, fd, description, owner=True)
    _held_by_process[str(sidecar)] = lock
    return lock


def adopt(path: str | PathLike[str], fd: int, description: str) -> HeldLock:
    """Declare the lock of ``path`` held by this process through ``fd``, a descriptor of its lock file
    inherited from the server that took it with :func:`hold` (``subprocess.Popen(pass_fds=…)``).

    :func:`locked` on ``path`` then passes in every thread of this process (a writer process saving
    the file its server holds). Raises :class:`SpcoError` if ``fd`` is not that lock file.
    """
    sidecar = lock_path(path)
    try:
        same = os.path.samestat(os.fstat(fd), os.stat(sidecar))
    except OSError as exc:
        raise SpcoError(f"{Path(path)}: descriptor {fd} is not its lock file "
                        f"({exc.strerror or exc})") from None
    if not same:
        raise SpcoError(f"{Path(path)}: descriptor {fd} is not its lock file {sidecar}")
    lock = HeldLock(Path(path), sidecar, fd, description, owner=False)
    _held_by_process[str(sidecar)] = lock
    return lock
