"""A served home's snapshots between the writer process and the server: sent without the arrays the
other side holds already (:class:`SnapshotChannel`), and the heap memory the replaced snapshots
free given back to the system (:func:`trim_heap`)."""

from __future__ import annotations

import ctypes
import io
import pickle
from typing import Any

import numpy as np

from spco import knowledge as kn

__all__ = ["TRIM_EVERY", "SnapshotChannel", "trim_heap"]


class SnapshotChannel:
    """Snapshots from the writer process to the server without sending unchanged arrays again.

    A teaching by sample id changes the sampler's state and the posterior, not the home's views or
    the knowledge: arrays of at least :attr:`MIN_BYTES` that the last snapshot held already (the same
    objects) travel as a reference, so that the server unpickles about 1 MB instead of 6 (for a
    SIGVerse home) while readers wait for its global lock. :meth:`pack` (writer side) returns
    ``(new arrays, snapshot, keys in use)`` as bytes; :meth:`unpack` (server side) rebuilds it.
    """

    MIN_BYTES = 32 * 1024

    def __init__(self) -> None:
        self._keys: dict[int, tuple[int, Any]] = {}  # writer: id(array) -> (key, array kept alive)
        self._objects: dict[int, Any] = {}  # server: key -> array
        self._next = 0

    def pack(self, snapshot: kn.HomeModel) -> tuple[bytes, bytes, list[int]]:
        """The snapshot as ``(pickled new arrays, pickled snapshot referring to arrays by key, keys)``."""
        new: dict[int, Any] = {}
        used: dict[int, tuple[int, Any]] = {}
        channel = self

        class Pickler(pickle.Pickler):
            def persistent_id(self, obj: Any) -> int | None:
                if not isinstance(obj, np.ndarray) or obj.nbytes < channel.MIN_BYTES:
                    return None
                entry = channel._keys.get(id(obj))
                if entry is None or entry[1] is not obj:
                    entry = (channel._next, obj)
                    channel._next += 1
                    new[entry[0]] = obj
                used[id(obj)] = entry
                return entry[0]

        buffer = io.BytesIO()
        Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(snapshot)
        self._keys = used
        return (pickle.dumps(new, protocol=pickle.HIGHEST_PROTOCOL), buffer.getvalue(),
                [key for key, _ in used.values()])

    def unpack(self, packed: tuple[bytes, bytes, list[int]]) -> kn.HomeModel:
        """The snapshot :meth:`pack` made, with the arrays sent before."""
        new, data, keys = packed
        self._objects.update(pickle.loads(new))
        objects = self._objects

        class Unpickler(pickle.Unpickler):
            def persistent_load(self, key: Any) -> Any:
                return objects[key]

        snapshot = Unpickler(io.BytesIO(data)).load()
        self._objects = {key: objects[key] for key in keys}
        return snapshot


#: Snapshots (server) or rounds (writer) between two returns of freed heap memory to the system.
TRIM_EVERY = 8


def trim_heap() -> None:
    """Give the heap memory freed since to the system (glibc's ``malloc_trim``; nothing elsewhere).

    Each teaching replaces the snapshot: without this the freed pieces stay with the process and its
    memory creeps up over a long run.
    """
    global _LIBC
    if _LIBC is None:
        try:
            _LIBC = ctypes.CDLL("libc.so.6")
            _LIBC.malloc_trim.argtypes = [ctypes.c_size_t]
        except (OSError, AttributeError):
            _LIBC = False
    if _LIBC:
        _LIBC.malloc_trim(0)  # (ctypes releases the global lock meanwhile)


_LIBC: Any = None
