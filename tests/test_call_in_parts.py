"""Kernels run in parts on several threads (``dispatch._call_in_parts``) give exactly the draws of
one thread: every row, chunk or home has its own random stream, whichever thread draws it."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import scipy.sparse as sp
from numba import njit

from spco.model.kernels import dispatch
from spco.model.kernels.categorical import sample_joint_assignment
from spco.model.kernels.counts import _grouped_row_sums, grouped_row_sums
from spco.model.kernels.crt import _crt_entries, _crt_totals_rows, sample_crt, sample_crt_totals
from spco.model.kernels.dirichlet import (
    _COUNT_DTYPE,
    _hierarchical_dirichlet_rows,
    _read_only,
    log_dirichlet_hierarchical,
)
from spco.model.kernels.likelihood import (
    LANES,
    _blocked_sparse_rows,
    _likelihood_table_blocks,
    blocked_sparse_dot,
    likelihood_table,
)
from spco.model.kernels.niw import _niw_rows, sample_niw


def _rows_args(shape: np.ndarray, seed: np.uint64, out: np.ndarray) -> tuple:
    """The hierarchical kernel's arguments for plain Dirichlet rows of ``shape`` into ``out`` (no
    counts), as ``log_dirichlet`` passes them."""
    counts = np.zeros((1, *shape.shape), dtype=_COUNT_DTYPE)
    return (_read_only(shape), _read_only(counts), seed, out.reshape(1, *shape.shape))


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
    serial, parts = _both(_hierarchical_dirichlet_rows, _rows_args(shape, np.uint64(5), out), n_rows, out,
                          vectorised=True)
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
    dispatch._call_in_parts(_hierarchical_dirichlet_rows, _rows_args(shape, np.uint64(1), expected), 6,
                            parallel=False, vectorised=True)
    results = [np.empty(shape.shape) for _ in range(4)]

    def run(out: np.ndarray) -> None:
        for _ in range(20):
            dispatch._call_in_parts(_hierarchical_dirichlet_rows, _rows_args(shape, np.uint64(1), out), 6,
                                    parallel=True, vectorised=True)

    threads = [threading.Thread(target=run, args=(out,)) for out in results]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for out in results:
        np.testing.assert_array_equal(out, expected)


def _spd(rng: np.random.Generator, n: int, d: int) -> np.ndarray:
    """``n`` random symmetric positive definite (d, d) matrices."""
    a = rng.normal(size=(n, d, d))
    return a @ a.transpose(0, 2, 1) + d * np.eye(d)


@pytest.mark.parametrize("n_threads", [2, 3, 5])
def test_former_prange_kernels_same_in_parts(monkeypatch: pytest.MonkeyPatch, n_threads: int) -> None:
    """The kernels that replaced prange twins (row sums, CRT entries, NIW draws, likelihood table
    and its sparse product) give on 2, 3 or 5 parts exactly what they give on one."""
    monkeypatch.setattr("numba.get_num_threads", lambda: n_threads)
    rng = np.random.default_rng(n_threads)
    dense = np.where(rng.random((60, 50)) < 0.3, rng.integers(1, 9, size=(60, 50)), 0)
    matrix = sp.csr_array(dense.astype(np.float32))
    homes = np.sort(rng.integers(0, 7, size=60))
    groups = homes * 2 + rng.integers(0, 2, size=60)
    chunks = np.concatenate([[0], np.flatnonzero(np.diff(homes)) + 1, [60]]).astype(np.int64)
    sums = np.zeros((14, 50), dtype=np.int64)
    csr = (matrix.indptr.astype(np.int64), matrix.indices.astype(np.int32), matrix.data,
           groups.astype(np.int64))
    serial, parts = _both(_grouped_row_sums, (*csr, chunks, sums), chunks.size - 1, sums)
    np.testing.assert_array_equal(serial, parts)
    np.testing.assert_array_equal(serial, np.stack([dense[groups == g].sum(0) for g in range(14)]))

    counts = rng.integers(0, 200, size=300).astype(np.int64)
    conc = rng.gamma(1.0, 2.0, size=300)
    tables = np.zeros(300, dtype=np.int64)
    serial, parts = _both(_crt_entries, (counts, conc, np.uint64(4), 40, 8, tables), 300, tables)
    np.testing.assert_array_equal(serial, parts)
    assert ((serial >= (counts > 0)) & (serial <= counts)).all()

    n, d = 9, 3
    mu, sigma, failed = np.empty((n, d)), np.empty((n, d, d)), np.zeros(n, dtype=np.bool_)
    niw_args = (rng.normal(size=(n, d)), rng.gamma(2.0, 1.0, size=n), _spd(rng, n, d), d + 2 + rng.random(n),
                np.uint64(6), mu, sigma, failed)
    serial_mu, parts_mu = _both(_niw_rows, niw_args, n, mu)
    parts_sigma = sigma.copy()  # (Σ of the run in parts; now once more on one thread)
    _niw_rows(*niw_args, 0, n)
    np.testing.assert_array_equal(serial_mu, parts_mu)
    np.testing.assert_array_equal(sigma, parts_sigma)
    assert not failed.any()

    log_p = np.log(rng.dirichlet(np.ones(50), size=(7, 5)))  # (G, R, W): 7 homes, 5 concepts
    table = np.empty((7, 1, 50, LANES))
    table_serial, parts = _both(_likelihood_table_blocks, (log_p, -30.0, table), 7, table)
    np.testing.assert_array_equal(table_serial, parts)
    product = np.empty((60, 5))
    product_args = (*csr[:3], homes.astype(np.int64), table_serial, 5, product)
    serial, parts = _both(_blocked_sparse_rows, product_args, 60, product, vectorised=True)
    np.testing.assert_array_equal(serial, parts)
    np.testing.assert_allclose(serial, np.einsum("tw,trw->tr", dense, np.maximum(log_p, -30.0)[homes]),
                               rtol=1e-12)


def test_former_prange_public_draws_same_on_any_thread_count(monkeypatch: pytest.MonkeyPatch) -> None:
    """Above their one-thread thresholds, sample_crt, sample_niw, likelihood_table,
    blocked_sparse_dot and grouped_row_sums give on Numba's threads what they give on one."""
    rng = np.random.default_rng(7)
    counts = rng.integers(0, 60, size=5000)
    conc = rng.gamma(1.0, 1.0, size=5000)
    n, d = 2100, 2
    psi = _spd(rng, n, d)
    mu_n, kappa, nu = rng.normal(size=(n, d)), rng.gamma(2.0, 1.0, size=n), d + 1 + rng.random(n)
    log_p = np.log(rng.dirichlet(np.ones(700), size=(4, 15)))  # 42,000 entries
    dense = np.where(rng.random((400, 700)) < 0.15, rng.integers(1, 9, size=(400, 700)), 0)  # ~42,000 nnz
    homes = np.sort(rng.integers(0, 4, size=400))

    def draws() -> list[np.ndarray]:
        table = likelihood_table(log_p, -30.0)
        matrix = sp.csr_array(dense.astype(np.float32))
        return [sample_crt(counts, conc, np.random.default_rng(1)),
                *sample_niw(mu_n, kappa, psi, nu, np.random.default_rng(2)), table,
                blocked_sparse_dot(matrix, homes, table, 15),
                grouped_row_sums(matrix, homes * 15 + np.arange(400) % 15, 60, blocks=homes)]

    threaded = draws()
    monkeypatch.setattr("numba.get_num_threads", lambda: 1)
    for one, many in zip(draws(), threaded, strict=True):
        np.testing.assert_array_equal(one, many)
