"""The archive every spco file is: a NumPy ``.npz`` with a JSON header stored as a ``uint8`` array and
a SHA-256 of every array in it (``array_checksums``), read back without pickle; written atomically
(:func:`write_npz_atomic`). Model files (:mod:`spco.model.io`), knowledge and home files
(:mod:`spco.knowledge.files`) are such archives."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from collections.abc import Callable, Mapping
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from spco.errors import ModelFileError

__all__ = ["check_format_version", "checksum", "file_mode", "write_npz_atomic"]


def checksum(array: np.ndarray) -> str:
    """sha256 of an array's dtype, shape and bytes (C order)."""
    digest = hashlib.sha256()
    digest.update(array.dtype.str.encode())
    digest.update(repr(tuple(int(s) for s in array.shape)).encode())
    digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def write_npz_atomic(path: str | PathLike[str], header: dict[str, Any], arrays: Mapping[str, np.ndarray],
                     overwrite: bool, what: str,
                     seal: Callable[[dict[str, Any]], str] | None = None) -> Path:
    """Write ``arrays`` and a JSON ``header`` as one ``.npz`` (no pickle), atomically.

    Adds ``header["array_checksums"]`` (sha256 per array) and, with ``seal``, ``header["checksum"]
    = seal(header)``. The data go to a temporary file in the same folder, flushed to disk, then
    renamed over ``path`` (permissions: those of the file replaced, else the usual ones); on any
    error the temporary file is removed and ``path`` is left as it was. An existing ``path`` is
    replaced only with ``overwrite``; problems raise :class:`~spco.errors.ModelFileError` naming
    the ``what`` ("model file", "knowledge file", …).
    """
    target = Path(path).expanduser()
    if target.is_dir():
        raise ModelFileError(target, f"is a folder; give the name of the {what} to write")
    folder = target.parent
    if not folder.is_dir():
        raise ModelFileError(target, f"cannot write the {what}: the folder {str(folder)!r} does not exist")
    if target.exists() and not overwrite:
        raise ModelFileError(target, "the file already exists; pass overwrite=True (or --force on the "
                             "command line) to replace it")
    arrays = {name: np.asarray(a) for name, a in arrays.items()}
    header = dict(header)
    header["array_checksums"] = {name: checksum(a) for name, a in arrays.items()}
    if seal is not None:
        header["checksum"] = seal(header)
    encoded = np.frombuffer(json.dumps(header, ensure_ascii=False, allow_nan=True).encode("utf-8"),
                            dtype=np.uint8)
    tmp_name: str | None = None
    try:
        with tempfile.NamedTemporaryFile(mode="wb", delete=False, dir=folder, prefix=f".{target.name}.",
                                         suffix=".tmp") as handle:
            tmp_name = handle.name
            np.savez(handle, header=encoded, **arrays)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp_name, file_mode(target))
        os.replace(tmp_name, target)
        tmp_name = None
    except OSError as exc:
        raise ModelFileError(target, f"cannot write the {what}: {exc.strerror or exc}") from exc
    finally:
        if tmp_name is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp_name)
    _fsync_folder(folder)
    return target


def file_mode(target: Path) -> int:
    """Permissions for a file written to ``target``: those of the file it replaces, else the
    usual ones (0o666 less the umask; temporary files are created 0o600)."""
    try:
        return target.stat().st_mode & 0o777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def _fsync_folder(folder: Path) -> None:
    """Make the rename durable (POSIX); a no-op where folders cannot be opened."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def check_format_version(path: Path, header: Mapping[str, Any], what: str, newest: int) -> int:
    """The ``format_version`` of a file's ``header``; :class:`~spco.errors.ModelFileError` naming
    ``path`` when it is not a whole number ≥ 1, or newer than ``newest`` (written by a newer spco: the
    ``what`` file format's version that this spco reads up to)."""
    version = header.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise ModelFileError(path, f"invalid format_version {version!r}")
    if version > newest:
        raise ModelFileError(path, f"written by a newer spco ({what} format version {version}, spco "
                             f"{header.get('spco_version', '?')}); this spco reads up to version "
                             f"{newest} — upgrade spco to read it")
    return version

