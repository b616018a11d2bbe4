"""How the kernels are called: the one-thread threshold, the SLP-vectorised compilation, and
the CSR arrays in the dtypes the kernels take.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor, wait

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


#: The threads of :func:`_call_in_parts` (a standard thread pool, made on first use and grown to
#: Numba's thread count), and the lock of their use: a call from a second Python thread while they
#: are busy runs on one thread (the same result).
_pool: ThreadPoolExecutor | None = None
_pool_size = 0
_pool_busy = threading.Lock()


def _forget_pool() -> None:
    global _pool, _pool_size, _pool_busy
    _pool, _pool_size = None, 0  # a forked child has none of the parent's threads: it makes its own
    _pool_busy = threading.Lock()


os.register_at_fork(after_in_child=_forget_pool)


def _call_in_parts(kernel, args: tuple, n_items: int, parallel: bool, vectorised: bool = False) -> None:
    """``kernel(*args, first, stop)`` for contiguous parts [first, stop) of ``range(n_items)``: one
    part on this thread, or, when ``parallel``, one per Numba thread (``numba.get_num_threads()``),
    run at once on a standard thread pool. ``kernel`` is compiled with ``nogil=True`` and treats
    every item on its own (its own random stream), so the result does not depend on the parts.

    This is the threaded variant of a serial kernel at no compile cost: a ``parallel=True``
    (prange) twin of the same loop took 2–5 s more to compile per kernel, and here the same
    compiled code serves both. ``vectorised``: compile with the SLP vectoriser
    (:func:`_call_vectorised`)."""
    from numba import get_num_threads

    if vectorised:
        _prepare_vectorised(kernel, (*args, 0, n_items))  # (compiled here, not by two threads at once)
    global _pool, _pool_size
    n_parts = max(1, min(get_num_threads(), n_items)) if parallel else 1
    if n_parts == 1 or not _pool_busy.acquire(blocking=False):
        kernel(*args, 0, n_items)
        return
    try:
        if _pool is None or _pool_size < n_parts - 1:
            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool_size = n_parts - 1
            _pool = ThreadPoolExecutor(_pool_size, thread_name_prefix="spco-kernel")
        bounds = [n_items * i // n_parts for i in range(n_parts + 1)]
        parts = [_pool.submit(kernel, *args, bounds[i], bounds[i + 1]) for i in range(1, n_parts)]
        try:
            kernel(*args, bounds[0], bounds[1])
        finally:
            wait(parts)  # every part ends before the caller goes on (or raises)
        for part in parts:
            part.result()  # an error in a part reaches the caller
    finally:
        _pool_busy.release()


def _as(array: np.ndarray, dtype: type) -> np.ndarray:
    """``array`` as a contiguous array of ``dtype``, without a copy when it already is one."""
    return np.ascontiguousarray(array, dtype=dtype)


def _index_array(indices: np.ndarray) -> np.ndarray:
    """CSR column indices as the kernels take them: int32 (one compiled specialisation per kernel;
    SciPy's slicing and arithmetic give int64, converted here: column numbers fit)."""
    if indices.dtype == np.int32 and indices.flags.c_contiguous:
        return indices
    if indices.size and int(indices.max()) >= 2**31:
        raise ValueError("sparse matrices of 2^31 columns or more are not supported")
    return _as(indices, np.int32)


def _value_array(values: np.ndarray) -> np.ndarray:
    """CSR values as the kernels take them: float32 kept as it is (:func:`stack_counts`),
    anything else float64. The kernels multiply in float64, so both give the same results."""
    return values if values.dtype == np.float32 and values.flags.c_contiguous else _as(values, np.float64)
