"""How the kernels are called: the one-thread threshold, the SLP-vectorised compilation, and
the CSR arrays in the dtypes the kernels take.
"""

from __future__ import annotations

import os
import threading

import numpy as np

#: Entries below which a batch of draws runs on one thread: waking Numba's worker threads costs
#: ~60–90 µs, more than such a batch takes.
_PARALLEL_MIN = 32_768


#: (kernel, argument kinds) already compiled by :func:`_call_vectorised`: later calls go straight
#: to the kernel (``numba.typeof`` of every argument costs ~12 µs per array).
_VECTORISED_READY: set = set()


def _argument_kind(value) -> tuple:
    """What decides Numba's type of an argument: for arrays dtype, dimensions, layout, whether
    writeable and aligned; for scalars their Python type."""
    if isinstance(value, np.ndarray):
        flags = value.flags
        return (value.dtype.str, value.ndim, flags.c_contiguous, flags.f_contiguous, flags.writeable,
                flags.aligned)
    return (type(value),)


def _call_vectorised(kernel, args: tuple):
    """Call a compiled kernel whose code is written for LLVM's SLP vectoriser (independent scalar
    accumulators over adjacent memory), compiling it first with that vectoriser switched on.

    Numba leaves the SLP vectoriser off by default because it has miscompiled some code
    (numba#8852); it is switched on here only while compiling the kernels passed in, whose
    results the tests compare with NumPy. Without it the same code runs, at scalar speed. A
    kernel already compiled (or loaded from Numba's cache) for these argument types is called
    directly."""
    _prepare_vectorised(kernel, args)
    return kernel(*args)


def _prepare_vectorised(kernel, args: tuple) -> None:
    """Compile ``kernel`` for the types of ``args`` with the SLP vectoriser on (see
    :func:`_call_vectorised`), unless it already is."""
    key = (kernel, tuple(_argument_kind(a) for a in args))
    if key not in _VECTORISED_READY:
        from numba import typeof
        from numba.core import config

        signature = tuple(typeof(a) for a in args)
        if signature not in kernel.signatures:
            previous = config.SLP_VECTORIZE
            config.SLP_VECTORIZE = 1
            try:
                kernel.compile(signature)
            finally:
                config.SLP_VECTORIZE = previous
        _VECTORISED_READY.add(key)


class _Worker:
    """A thread that runs one kernel call at a time when told to: two locks as signals (go, done),
    ~15–20 µs per round trip, where a ThreadPoolExecutor's futures cost ~40 µs (Numba's own
    threads: ~12 µs)."""

    def __init__(self) -> None:
        self._go = threading.Lock()
        self._go.acquire()
        self._done = threading.Lock()
        self._done.acquire()
        self._job: tuple = ()
        self._error: BaseException | None = None
        threading.Thread(target=self._loop, name="spco-kernel", daemon=True).start()

    def _loop(self) -> None:
        while True:
            self._go.acquire()
            kernel, args = self._job
            try:
                kernel(*args)
            except BaseException as error:  # returned to the caller by wait()
                self._error = error
            finally:
                self._done.release()

    def start(self, kernel, args: tuple) -> None:
        """Run ``kernel(*args)`` on this thread."""
        self._job, self._error = (kernel, args), None
        self._go.release()

    def wait(self) -> BaseException | None:
        """Wait for the call started last; returns its exception, if any."""
        self._done.acquire()
        return self._error


#: Worker threads of :func:`_call_in_parts` (made on first use), and the lock of their use: a call
#: from a second Python thread while they are busy runs on one thread (the same result).
_workers: list[_Worker] = []
_workers_busy = threading.Lock()


def _forget_workers() -> None:
    global _workers_busy
    _workers.clear()  # a forked child has none of the parent's threads
    _workers_busy = threading.Lock()


os.register_at_fork(after_in_child=_forget_workers)


def _call_in_parts(kernel, args: tuple, n_items: int, parallel: bool, vectorised: bool = False) -> None:
    """``kernel(*args, first, stop)`` for contiguous parts [first, stop) of ``range(n_items)``: one
    part on this thread, or, when ``parallel``, one per Numba thread (``numba.get_num_threads()``),
    run at once. ``kernel`` is compiled with ``nogil=True`` and treats every item on its own (its
    own random stream), so the result does not depend on the parts.

    This is the threaded variant of a serial kernel at no compile cost: a ``parallel=True``
    (prange) twin of the same loop took 2–5 s more to compile per kernel, and here the same
    compiled code serves both. ``vectorised``: compile with the SLP vectoriser
    (:func:`_call_vectorised`)."""
    from numba import get_num_threads

    if vectorised:
        _prepare_vectorised(kernel, (*args, 0, n_items))  # (compiled here, not by two threads at once)
    n_parts = max(1, min(get_num_threads(), n_items)) if parallel else 1
    if n_parts == 1 or not _workers_busy.acquire(blocking=False):
        kernel(*args, 0, n_items)
        return
    try:
        while len(_workers) < n_parts - 1:
            _workers.append(_Worker())
        bounds = [n_items * i // n_parts for i in range(n_parts + 1)]
        for i in range(1, n_parts):
            _workers[i - 1].start(kernel, (*args, bounds[i], bounds[i + 1]))
        try:
            kernel(*args, bounds[0], bounds[1])
        finally:
            errors = [_workers[i - 1].wait() for i in range(1, n_parts)]
        for error in errors:
            if error is not None:
                raise error
    finally:
        _workers_busy.release()


def _as(array: np.ndarray, dtype: type) -> np.ndarray:
    """``array`` as a contiguous array of ``dtype``, without a copy when it already is one."""
    return np.ascontiguousarray(array, dtype=dtype)


def _index_array(indices: np.ndarray) -> np.ndarray:
    """CSR column indices as the kernels take them: int32 kept as it is, anything else int64."""
    return indices if indices.dtype == np.int32 and indices.flags.c_contiguous else _as(indices, np.int64)


def _value_array(values: np.ndarray) -> np.ndarray:
    """CSR values as the kernels take them: float32 kept as it is (:func:`stack_counts`),
    anything else float64. The kernels multiply in float64, so both give the same results."""
    return values if values.dtype == np.float32 and values.flags.c_contiguous else _as(values, np.float64)
