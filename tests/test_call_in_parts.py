"""Kernels run in parts on several threads (``dispatch._call_in_parts``) give exactly the draws of
one thread: every row, chunk or home has its own random stream, whichever thread draws it."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from numba import njit

from spco.model.kernels import dispatch
from spco.model.kernels.crt import _crt_totals_rows
from spco.model.kernels.dirichlet import _dirichlet_rows, _hierarchical_dirichlet_rows
from spco.model.random import log_dirichlet_hierarchical, sample_crt_totals, sample_joint_assignment


def _both(kernel, args: tuple, n_items: int, out: np.ndarray, vectorised: bool = False) -> tuple:
    """``out`` after the kernel on one thread, and after it in parts on every thread."""
    out[...] = 0
    dispatch._call_in_parts(kernel, args, n_items, parallel=False, vectorised=vectorised)
    serial = out.copy()
    out[...] = 0
    dispatch._call_in_parts(kernel, args, n_items, parallel=True, vectorised=vectorised)
    return serial, out.copy()


@pytest.mark.parametrize("n_rows", [1, 2, 7])
def test_dirichlet_rows_same_in_parts(n_rows: int) -> None:
    rng = np.random.default_rng(n_rows)
    shape = rng.gamma(0.3, 1.0, size=(n_rows, 300)) + 1e-3
    out = np.empty(shape.shape)
    serial, parts = _both(_dirichlet_rows, (shape, np.uint64(5), out), n_rows, out, vectorised=True)
    np.testing.assert_array_equal(serial, parts)
    assert np.allclose(np.exp(serial).sum(axis=1), 1.0)


def test_hierarchical_rows_and_crt_totals_same_in_parts() -> None:
    rng = np.random.default_rng(0)
    counts = rng.poisson(0.8, size=(3, 5, 200)).astype(np.int64)
    base = rng.gamma(0.5, 1.0, size=(5, 200))
    counts.flags.writeable = base.flags.writeable = False  # (as the public functions pass them)
    out = np.empty(counts.shape, dtype=np.float64)
    serial, parts = _both(_hierarchical_dirichlet_rows, (base, counts, np.uint64(9), out), 15, out,
                          vectorised=True)
    np.testing.assert_array_equal(serial, parts)
    totals = np.zeros((5, 200), dtype=np.int64)
    serial, parts = _both(_crt_totals_rows, (counts, base, np.uint64(9), 40, totals), 5, totals)
    np.testing.assert_array_equal(serial, parts)
    assert (serial <= counts.sum(axis=0)).all() and (serial >= (counts > 0).sum(axis=0)).all()


def test_public_draws_do_not_depend_on_the_thread_count(monkeypatch: pytest.MonkeyPatch) -> None:
    """The draws above the one-thread threshold, on Numba's threads and on one."""
    rng = np.random.default_rng(1)
    counts = rng.poisson(0.5, size=(4, 9, 1024)).astype(np.int64)  # 36,864 entries: threaded
    base = rng.gamma(0.5, 1.0, size=(9, 1024))
    homes = np.repeat(np.arange(4), 100)
    log_g = np.log(rng.dirichlet(np.ones(9), size=4))
    log_pi = np.log(rng.dirichlet(np.ones(6), size=(4, 9)))
    concept_ll, region_ll = rng.normal(size=(400, 9)) * 20, rng.normal(size=(400, 6)) * 5

    def draws() -> list[np.ndarray]:
        return [log_dirichlet_hierarchical(base, counts, np.random.default_rng(2)),
                sample_crt_totals(counts, base, np.random.default_rng(3)),
                sample_joint_assignment(log_g, log_pi, homes, concept_ll, region_ll,
                                        np.random.default_rng(4))]

    threaded = draws()
    monkeypatch.setattr("numba.get_num_threads", lambda: 1)
    for one, many in zip(draws(), threaded, strict=True):
        np.testing.assert_array_equal(one, many)


@njit(nogil=True, cache=False)
def _fails_from(values: np.ndarray, bad: int, first: int, stop: int) -> None:
    for i in range(first, stop):
        if i >= bad:
            raise ValueError("bad item")
        values[i] = i


def test_an_error_in_a_part_reaches_the_caller_and_the_workers_stay_usable() -> None:
    values = np.zeros(10)
    with pytest.raises(ValueError, match="bad item"):
        dispatch._call_in_parts(_fails_from, (values, 8), 10, parallel=True)
    values[:] = 0
    dispatch._call_in_parts(_fails_from, (values, 10), 10, parallel=True)
    np.testing.assert_array_equal(values, np.arange(10))


def test_calls_from_several_python_threads_at_once() -> None:
    """A second caller while the workers are busy runs on its own thread: the same results."""
    rng = np.random.default_rng(3)
    shape = rng.gamma(0.3, 1.0, size=(6, 500)) + 1e-3
    expected = np.empty(shape.shape)
    dispatch._call_in_parts(_dirichlet_rows, (shape, np.uint64(1), expected), 6, parallel=False,
                            vectorised=True)
    results = [np.empty(shape.shape) for _ in range(4)]

    def run(out: np.ndarray) -> None:
        for _ in range(20):
            dispatch._call_in_parts(_dirichlet_rows, (shape, np.uint64(1), out), 6, parallel=True,
                                    vectorised=True)

    threads = [threading.Thread(target=run, args=(out,)) for out in results]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for out in results:
        np.testing.assert_array_equal(out, expected)
