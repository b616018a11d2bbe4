"""Dirichlet rows in log space: :func:`log_dirichlet`, :func:`log_dirichlet_hierarchical`.

Each row is one :func:`~spco.model.kernels.gamma._log_gamma_row` pass normalised; small batches run
on one thread, many short rows (π over K = 20 regions, θ^w over a few words) as one flat batch.
:func:`dirichlet_log_density` evaluates the density of log-probability rows.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from spco.model.kernels.dispatch import _PARALLEL_MIN, _call_in_parts, _call_vectorised
from spco.model.kernels.gamma import _SHORT_ROW, _log_gamma_row, _row_scratch
from spco.model.kernels.special import _scaled_exp

# Every call of _log_gamma_row passes its stream as an int64 and ``normalise`` as a run-time bool
# (np.bool_): Numba compiles a callee once per argument type, and a literal True, False or 0 is a
# type of its own, as is the uint64 index of a prange loop; one type each, one compilation (~5 s).


def _short_rows(n_rows: int, width: int) -> bool:
    """Whether a batch of Dirichlet rows is drawn as one flat batch of gamma variates
    (:func:`_dirichlet_short_rows`): rows short enough for :func:`_log_gamma_row` to take them one
    entry at a time, and enough of them for the vectorised passes to pay."""
    return width <= _SHORT_ROW and n_rows * width >= 4 * _SHORT_ROW


def _dirichlet_short_rows(shape: np.ndarray, seed: np.uint64, out: np.ndarray) -> None:
    """log Dirichlet rows of ``shape`` (R, W) into ``out`` (both float64, C-contiguous), for many
    short rows (π over K = 20 regions, θ^w over a few words): the gamma variates of all rows in one
    vectorised pass of the compiled :func:`_log_gamma_row` (its eight streams of ``seed``), then each
    row normalised by a log-sum-exp here (a row of zero shapes stays −inf). Not a kernel of its own,
    which would compile the gamma row sampler into itself once more; the sums are taken left to
    right (``cumsum``) and the logarithms by the C library's ``log``, as a compiled loop takes
    them."""
    n_rows, width = shape.shape
    flat = shape.reshape(-1)
    if not flat.flags.writeable:  # (one compiled signature of the row sampler)
        flat = flat.copy()
    _call_vectorised(_log_gamma_row, (flat, out.reshape(-1), seed, np.int64(0), np.bool_(False),
                                      _row_scratch(n_rows * width)))
    tops = out.max(axis=1)
    live = tops > -np.inf
    shift = np.where(live, tops, 0.0)  # (a row of −inf stays −inf)
    weights = np.empty(n_rows * width)
    _scaled_exp((out - shift[:, None]).reshape(-1), 1.0, weights, np.empty(n_rows * width))
    sums = np.cumsum(weights.reshape(n_rows, width), axis=1)[:, -1]
    log_total = np.array([top + math.log(total) if alive else 0.0  # (math.log: the C library's, as compiled)
                          for top, total, alive in zip(tops.tolist(), sums.tolist(), live.tolist(),
                                                       strict=True)])
    out -= log_total[:, None]


@njit(cache=True, nogil=True, error_model="numpy")
def _hierarchical_dirichlet_rows(base: np.ndarray, counts: np.ndarray, seed: np.uint64, out: np.ndarray,
                                 first: int, stop: int) -> None:
    """log θ_{g,r} ~ Dir(base_r + counts_{g,r}) for the flat rows i = g R + r in first..stop−1, row i
    on the streams of i (:func:`_call_in_parts`)."""
    rows, width = counts.shape[1], counts.shape[2]
    scratch = _row_scratch(width)
    shape = scratch[1][6, :width]  # (rows 0-5 are the row function's own scratch)
    for i in range(first, stop):
        g, r = i // rows, i % rows
        for k in range(width):
            shape[k] = base[r, k] + counts[g, r, k]
        _log_gamma_row(shape, out[g, r], seed, i, np.bool_(True), scratch)


def log_dirichlet(alpha: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Draw Dirichlet vectors along the last axis and return their logarithms.

    Each row is a set of gamma variates (compiled Marsaglia–Tsang, one random stream per row,
    rows in parallel) divided by their sum. A variate that would underflow (tiny concentrations:
    α^w = 0.01, δ^w φ^w ≪ 1) is kept as its logarithm, so every entry with α > 0 gets a finite
    log-probability.

    Parameters
    ----------
    alpha: (..., D) non-negative concentrations; each row needs at least one positive entry.
        Entries equal to 0 give probability exactly 0 (log = -inf).

    Returns
    -------
    (..., D) log-probabilities; ``exp`` of each row sums to 1.
    """
    alpha = np.asarray(alpha, dtype=np.float64)
    if alpha.shape[-1] == 0:  # no dimension at all (e.g. no word was ever taught)
        return np.zeros(alpha.shape)
    rows = np.ascontiguousarray(alpha).reshape(-1, alpha.shape[-1])
    out = np.empty(rows.shape)
    seed = np.uint64(rng.integers(0, 2**63 - 1, dtype=np.int64))
    parallel = rows.size >= _PARALLEL_MIN
    if not parallel and _short_rows(*rows.shape):
        _dirichlet_short_rows(rows, seed, out)
    else:  # the hierarchical draw with no counts: base + 0 is base, row r on the streams of r
        base, no_counts = _read_only(rows), _read_only(np.zeros((1, *rows.shape), dtype=_COUNT_DTYPE))
        _call_in_parts(_hierarchical_dirichlet_rows, (base, no_counts, seed, out.reshape(1, *rows.shape)),
                       rows.shape[0], parallel, vectorised=True)
    return out.reshape(alpha.shape)


#: The whole counts' dtype of :func:`_hierarchical_dirichlet_rows` (and of the no counts of
#: :func:`log_dirichlet`: one compiled signature for both).
_COUNT_DTYPE = np.int64


def _read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array`` (no copy): the kernels' signatures take read-only inputs, so
    whoever owns an array, one compilation serves."""
    if array.flags.writeable:
        array = array.view()
        array.flags.writeable = False
    return array


def log_dirichlet_hierarchical(base: np.ndarray, counts: np.ndarray, rng: np.random.Generator,
                               out: np.ndarray | None = None) -> np.ndarray:
    """log θ_{g,r} ~ Dir(base_r + counts_{g,r}) for every group g and row r, without forming the
    concentrations: the draw of θ_{e,l} ~ Dir(δ φ_l + n_{e,l}) for all homes at once.

    Parameters
    ----------
    base: (R, D) non-negative concentrations shared by the groups (δ φ).
    counts: (G, R, D) non-negative counts n, whole or real (a power likelihood's weighted counts).
    out: optional (G, R, D) float64 C-contiguous array to write into (e.g. the previous draw).

    Returns
    -------
    (G, R, D) log-probabilities, the same as :func:`log_dirichlet` of ``base + counts`` in
    distribution.
    """
    # whole counts as int64 (the cut sampler's, compiled ahead), real ones (the power target's) as float64
    counts = np.asarray(counts)
    counts = np.ascontiguousarray(counts, dtype=_COUNT_DTYPE if counts.dtype.kind in "iub" else np.float64)
    base = np.ascontiguousarray(np.broadcast_to(base, counts.shape[1:]), dtype=np.float64)
    if counts.shape[-1] == 0:
        return np.zeros(counts.shape)
    if out is None or out.shape != counts.shape or out.dtype != np.float64 or not out.flags.c_contiguous:
        out = np.empty(counts.shape)
    seed = np.uint64(rng.integers(0, 2**63 - 1, dtype=np.int64))
    counts = _read_only(counts)  # (and base, below: one compiled signature, whoever owns them)
    parallel = counts.size >= _PARALLEL_MIN
    n_rows, width = counts.shape[0] * counts.shape[1], counts.shape[2]
    if not parallel and _short_rows(n_rows, width):  # (the same sums base + counts as the kernel's)
        _dirichlet_short_rows((base + counts).reshape(n_rows, width), seed, out.reshape(n_rows, width))
    else:
        _call_in_parts(_hierarchical_dirichlet_rows, (_read_only(base), counts, seed, out), n_rows, parallel,
                       vectorised=True)
    return out


def dirichlet(alpha: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Draw Dirichlet vectors along the last axis (probabilities, see :func:`log_dirichlet`)."""
    return np.exp(log_dirichlet(alpha, rng))


def dirichlet_log_density(log_p: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """log Dir(p | α) of each row, given log p (shape (..., D)); entries with α = 0 are skipped."""
    from scipy.special import gammaln

    alpha = np.broadcast_to(alpha, log_p.shape)
    active = alpha > 0
    term = np.where(active, (alpha - 1.0) * np.where(active, log_p, 0.0), 0.0)
    return (gammaln(alpha.sum(-1)) - np.where(active, gammaln(np.where(active, alpha, 1.0)), 0.0).sum(-1)
            + term.sum(-1))
