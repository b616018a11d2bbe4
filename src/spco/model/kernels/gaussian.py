"""Gaussian log densities of positions: every point under every region of its home.

:func:`grouped_gaussian_log_density` (compiled, one inverse Cholesky factor per region) and the
single-group :func:`gaussian_log_density`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spco.model.kernels.dispatch import _PARALLEL_MIN, _call_in_parts
from spco.model.kernels.niw import _cholesky_into


def gaussian_log_density(x: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """log N(x | mean_m, cov_m) for every point and component.

    Shapes: x (n, d); mean (K, d); cov (K, d, d). Returns (n, K).
    """
    return grouped_gaussian_log_density(x, np.zeros(x.shape[0], dtype=np.int64), mean[None], cov[None])


#: Points per task of :func:`_grouped_gaussian` (their scratch allocated once per task).
_GAUSSIAN_CHUNK = 64


def _grouped_gaussian(x: np.ndarray, groups: np.ndarray, means_t: np.ndarray, inv_chol_t: np.ndarray,
                      constant: np.ndarray) -> np.ndarray:
    """(n, K) log densities: :func:`_grouped_gaussian_chunks` over all chunks of
    :data:`_GAUSSIAN_CHUNK` points, on Numba's thread count when there are at least
    :data:`~spco.model.kernels.dispatch._PARALLEL_MIN` densities (one home's ~160 points run on
    this thread: handing them to the pool cost 3× their CPU)."""
    out = np.empty((x.shape[0], means_t.shape[2]))
    n_chunks = (x.shape[0] + _GAUSSIAN_CHUNK - 1) // _GAUSSIAN_CHUNK
    _call_in_parts(_grouped_gaussian_chunks, (x, groups, means_t, inv_chol_t, constant, out), n_chunks,
                   out.size >= _PARALLEL_MIN)
    return out


@njit(cache=True, nogil=True)
def _grouped_gaussian_chunks(x: np.ndarray, groups: np.ndarray, means_t: np.ndarray, inv_chol_t: np.ndarray,
                             constant: np.ndarray, out: np.ndarray, first: int, stop: int) -> None:
    # the points of chunks first..stop-1 into out; means_t (G, d, K) and inv_chol_t (G, d, d, K):
    # the components last, so that every inner loop runs over the K components of a point at
    # once (vectorised); each quadratic form is summed in the same order as one component at a time
    n, d = x.shape
    n_components = means_t.shape[2]
    for chunk in range(first, stop):
        diff = np.empty((d, n_components))
        acc = np.empty(n_components)
        quad = np.empty(n_components)
        for t in range(chunk * _GAUSSIAN_CHUNK, min(n, (chunk + 1) * _GAUSSIAN_CHUNK)):
            g = groups[t]
            for j in range(d):
                for m in range(n_components):
                    diff[j, m] = x[t, j] - means_t[g, j, m]
            quad[:] = 0.0
            for i in range(d):
                acc[:] = 0.0
                for j in range(i + 1):
                    for m in range(n_components):
                        acc[m] += inv_chol_t[g, i, j, m] * diff[j, m]
                for m in range(n_components):
                    quad[m] += acc[m] * acc[m]
            for m in range(n_components):
                out[t, m] = constant[g, m] - 0.5 * quad[m]


def grouped_gaussian_log_density(x: np.ndarray, groups: np.ndarray, means: np.ndarray,
                                 covariances: np.ndarray) -> np.ndarray:
    """log N(x_t | μ_{g_t,m}, Σ_{g_t,m}) for every point and every component of its group.

    Shapes: x (n, d); groups (n,) int; means (G, K, d); covariances (G, K, d, d). Returns (n, K).
    Uses the inverse Cholesky factor, so the quadratic form is a triangular product.
    """
    covariances = np.ascontiguousarray(covariances, dtype=np.float64)
    inv_chol = np.empty(covariances.shape)
    constant = np.empty(covariances.shape[:-2])
    failed = np.zeros(covariances.shape[:-2], dtype=np.bool_)
    _inverse_cholesky(covariances, inv_chol, constant, failed)
    if failed.any():
        raise ValueError(f"{int(failed.sum())} covariance matri{'x is' if failed.sum() == 1 else 'ces are'} "
                         "not positive definite")
    return _grouped_gaussian(np.ascontiguousarray(x, dtype=np.float64),
                             np.ascontiguousarray(groups, dtype=np.int64),
                             np.ascontiguousarray(np.moveaxis(np.asarray(means, dtype=np.float64), 1, 2)),
                             np.ascontiguousarray(np.moveaxis(inv_chol, 1, 3)), constant)


@njit(cache=True)
def _inverse_cholesky(covariances: np.ndarray, inv_chol: np.ndarray, constant: np.ndarray,
                      failed: np.ndarray) -> None:
    """For each (G, K) covariance: the inverse of its lower Cholesky factor and the Gaussian's log
    normaliser −(log det Σ + d log 2π)/2; ``failed`` marks matrices that are not positive definite."""
    groups, n_components, d, _ = covariances.shape
    chol = np.zeros((d, d))
    for g in range(groups):
        for m in range(n_components):
            failed[g, m] = not _cholesky_into(covariances[g, m], chol)
            log_det = 0.0
            for j in range(d):
                log_det += 2.0 * np.log(chol[j, j])
            inv = inv_chol[g, m]  # L^{-1}, lower triangular, column by column
            for j in range(d):
                for i in range(d):
                    if i < j:
                        inv[i, j] = 0.0
                    elif i == j:
                        inv[i, j] = 1.0 / chol[i, i]
                    else:
                        t = 0.0
                        for k in range(j, i):
                            t -= chol[i, k] * inv[k, j]
                        inv[i, j] = t / chol[i, i]
            constant[g, m] = -0.5 * (log_det + d * np.log(2.0 * np.pi))
