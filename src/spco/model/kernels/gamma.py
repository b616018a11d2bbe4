"""Gamma variates in log space, exact for tiny shapes (α^w = 0.01, δ^w φ^w ≪ 1).

Marsaglia–Tsang with ziggurat normals; shapes below 1 by G(a) = G(a + 1) · U^{1/a} in log space.
:func:`log_gamma_variates` is the batched entry point; :func:`_log_gamma_row` draws one Dirichlet
row in vectorised passes, :func:`_log_gamma_short_row` a short one entry by entry.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spco.model.kernels.dispatch import _call_in_parts
from spco.model.kernels.normal import _normal_from_bits, _stream_normal, _ziggurat_first_step
from spco.model.kernels.rng import (
    _ONE_MINUS_HALF_ULP,
    _ROW_STREAMS,
    _fill_stream_words,
    _stream_open,
    _stream_start,
    _words_to_uniforms,
)
from spco.model.kernels.special import _log_minus, _sum_exp

#: log Gamma(a) variates below this are clipped (they arise for a < 1e-298 and mean "zero").
_LOG_GAMMA_FLOOR = -1e300


@njit(cache=True, error_model="numpy")
def _stream_gamma(state: np.uint64, a: float) -> tuple[np.uint64, float]:
    """The next state and a Gamma(a, 1) variate, a ≥ 1 (Marsaglia & Tsang 2000)."""
    d = a - 1.0 / 3.0
    c = 1.0 / np.sqrt(9.0 * d)
    while True:
        state, x = _stream_normal(state)
        v = 1.0 + c * x
        if v <= 0.0:
            continue
        v = v * v * v
        state, u = _stream_open(state)
        x2 = x * x
        if u < 1.0 - 0.0331 * x2 * x2 or np.log(u) < 0.5 * x2 + d * (1.0 - v + np.log(v)):
            return state, d * v


@njit(cache=True, error_model="numpy")
def _stream_log_gamma_small(state: np.uint64, a: float) -> tuple[np.uint64, float]:
    """The next state and log G for G ~ Gamma(a, 1), 0 < a < 1, by the boost
    G(a) = G(a + 1) U^{1/a} taken in log space: finite (clipped at −1e300) where G underflows."""
    state, g = _stream_gamma(state, a + 1.0)
    state, u = _stream_open(state)
    return state, np.log(g) + max(np.log(u) / a, _LOG_GAMMA_FLOOR)


#: Entries per random stream in :func:`log_gamma_variates` (blocks run in parallel).
_GAMMA_BLOCK = 4096


@njit(cache=True, nogil=True, error_model="numpy")
def _gamma_blocks(shape: np.ndarray, seed: np.uint64, block: int, out: np.ndarray, first: int,
                  stop: int) -> None:
    """Gamma(a) variates for a ≥ 1, Gamma(a + 1) for 0 < a < 1 (the caller applies the boost),
    0 for a ≤ 0, into ``out``, for blocks first..stop−1 of ``block`` entries; one random stream
    per block: the same draws whichever thread runs which blocks (:func:`_call_in_parts`)."""
    n = shape.size
    for b in range(first, stop):
        state = _stream_start(seed, np.uint64(b))
        for j in range(b * block, min(n, (b + 1) * block)):
            a = shape[j]
            if a >= 1.0:
                state, out[j] = _stream_gamma(state, a)
            elif a > 0.0:
                state, out[j] = _stream_gamma(state, a + 1.0)
            else:
                out[j] = 0.0




def log_gamma_variates(shape: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """log of Gamma(shape, 1) variates, exact in log space for any shape > 0.

    For shape < 1 uses G(a) = G(a + 1) · U^{1/a}, i.e. log G(a) = log G(a + 1) + log(U)/a, which
    stays finite where G(a) itself underflows to 0 (a = 1e-3 gives G < 1e-300 with probability
    ~0.5). A shape of exactly 0 gives -inf (a point mass at 0).

    The variates come from a compiled kernel (Marsaglia–Tsang with ziggurat normals) in parallel
    blocks of 4,096 entries, each with its own random stream seeded from ``rng``: the result
    depends on the seed only.
    """
    return _gamma_draw(shape, rng)[1]


def _gamma_draw(shape: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gamma(shape) variates as (linear values, logarithms, flat indices of the boosted shapes < 1).

    The linear value of a boosted entry is exp of its logarithm (it may underflow to 0: use the
    logarithm wherever that matters)."""
    shape = np.asarray(shape, dtype=np.float64)
    flat = np.ascontiguousarray(shape).ravel()
    seed = np.uint64(rng.integers(0, 2**63 - 1, dtype=np.int64))
    values = np.empty(flat.size)
    n_blocks = (flat.size + _GAMMA_BLOCK - 1) // _GAMMA_BLOCK
    _call_in_parts(_gamma_blocks, (flat, seed, _GAMMA_BLOCK, values), n_blocks, parallel=True)
    with np.errstate(divide="ignore"):
        logs = np.log(values)  # vectorised; a = 0 gives log 0 = -inf
    boosted = np.flatnonzero((flat < 1.0) & (flat > 0.0))
    if boosted.size:
        a = flat[boosted]
        log_u = np.log(rng.random(boosted.size) + 0.5 / 2**53)  # U in (0, 1)
        with np.errstate(over="ignore"):
            logs[boosted] += np.maximum(log_u / a, _LOG_GAMMA_FLOOR)
        values[boosted] = np.exp(logs[boosted])
    return values.reshape(shape.shape), logs.reshape(shape.shape), boosted


@njit(cache=True, error_model="numpy")
def _marsaglia_tsang_first(shape: np.ndarray, x: np.ndarray, fast: np.ndarray, uniforms: np.ndarray,
                           g: np.ndarray, accepted: np.ndarray, v_out: np.ndarray) -> None:
    """The first Marsaglia–Tsang proposal of every entry, vectorised: g[j] = d (1 + c x_j)³ for
    the shape a (a + 1 below 1, boosted later), v_out[j] = 1 + c x_j, and accepted[j] = 1 where
    the normal is complete and the squeeze u < 1 − 0.0331 x⁴ accepts it (u from ``words``; ≈ 90 %
    of entries)."""
    for j in range(shape.size):
        a = shape[j]
        d = a + np.float64(a < 1.0) - 1.0 / 3.0
        xj = x[j]
        v = 1.0 + xj / np.sqrt(9.0 * d)
        u = uniforms[j] - _ONE_MINUS_HALF_ULP
        x2 = xj * xj
        accepted[j] = fast[j] * np.float64(v > 0.0) * np.float64(u < 1.0 - 0.0331 * x2 * x2)
        g[j] = d * v * v * v
        v_out[j] = v


@njit(cache=True, error_model="numpy")
def _marsaglia_tsang_rest(shape: np.ndarray, x: np.ndarray, fast: np.ndarray, v_first: np.ndarray,
                          first_words: np.ndarray, second_uniforms: np.ndarray, g: np.ndarray,
                          accepted: np.ndarray, todo: np.ndarray, log_u: np.ndarray, log_v: np.ndarray,
                          scratch: np.ndarray, state: np.uint64) -> np.uint64:
    """Finish the gamma variates that the squeeze did not accept: first Marsaglia–Tsang's
    logarithmic test on the same proposal (its two logarithms vectorised over the entries
    concerned), then, for the few left (≈ 3 %), the rest of the ziggurat draw if its first step
    did not return, and fresh proposals from the random stream ``state`` while rejected — each
    entry gets exactly the variate of :func:`_stream_gamma`'s loop. Returns the stream's state."""
    m = 0
    for j in range(shape.size):  # compaction without branches
        todo[m] = j
        m += np.int64(accepted[j] == 0.0)
    for i in range(m):
        j = todo[i]
        log_u[i] = second_uniforms[j] - _ONE_MINUS_HALF_ULP
        v = v_first[j]
        v3 = v * v * v
        log_v[i] = v3 if v3 > 1e-300 else 1.0  # (v ≤ 0 is rejected below; keep the log finite)
    _log_minus(log_u[:m], 0.0, scratch[:m])
    _log_minus(log_v[:m], 0.0, scratch[:m])
    left = 0
    for i in range(m):
        j = todo[i]
        a = shape[j]
        d = a + np.float64(a < 1.0) - 1.0 / 3.0
        xj = x[j]
        v = v_first[j]
        v3 = v * v * v
        passes = log_u[i] < 0.5 * xj * xj + d * (1.0 - v3 + log_v[i])
        ok = (fast[j] > 0.0) & (v > 0.0) & (v3 > 1e-300) & passes
        todo[left] = j
        left += np.int64(not ok)
    for i in range(left):
        j = todo[i]
        a = shape[j]
        if a <= 0.0:
            g[j] = 0.0
            continue
        shifted = a + np.float64(a < 1.0)
        d = shifted - 1.0 / 3.0
        if fast[j] == 0.0:  # complete this normal, then the same test as in _stream_gamma
            state, xj = _normal_from_bits(state, first_words[j])
            v = 1.0 + xj / np.sqrt(9.0 * d)
            if v > 0.0:
                v = v * v * v
                u = second_uniforms[j] - _ONE_MINUS_HALF_ULP
                x2 = xj * xj
                if u < 1.0 - 0.0331 * x2 * x2 or np.log(u) < 0.5 * x2 + d * (1.0 - v + np.log(v)):
                    g[j] = d * v
                    continue
        state, g[j] = _stream_gamma(state, shifted)
    return state


#: Scratch of :func:`_log_gamma_row` (:func:`_row_scratch`): random words, uint64 (8 + 3·padded);
#: work rows, float64 (7, width), the last one free for the caller; compaction indices, int64
#: (2, width).
RowScratch = tuple


@njit(cache=True)
def _row_scratch(width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scratch of :func:`_log_gamma_row` for rows of up to ``width`` entries: allocated once per
    row of a parallel batch, once for a whole batch on one thread."""
    padded = (width + _ROW_STREAMS - 1) // _ROW_STREAMS * _ROW_STREAMS
    return (np.empty(_ROW_STREAMS + 3 * padded, dtype=np.uint64), np.empty((7, width)),
            np.empty((2, width), dtype=np.int64))


#: Rows up to this length are drawn entry by entry (:func:`_log_gamma_short_row`): the passes of
#: :func:`_log_gamma_row` cost ~1 µs per row whatever its length.
_SHORT_ROW = 64


@njit(cache=True, error_model="numpy")
def _log_gamma_short_row(shape: np.ndarray, out: np.ndarray, state: np.uint64, normalise: bool) -> None:
    """:func:`_log_gamma_row` for a short row, one entry after the other on the random stream
    ``state``: Marsaglia–Tsang (:func:`_stream_gamma`), boosted in log space below 1
    (:func:`_stream_log_gamma_small`), normalised by a log-sum-exp."""
    top = -np.inf
    for j in range(shape.size):
        a = shape[j]
        if a <= 0.0:
            out[j] = -np.inf
            continue
        if a >= 1.0:
            state, g = _stream_gamma(state, a)
            out[j] = np.log(g)
        else:
            state, out[j] = _stream_log_gamma_small(state, a)
        top = max(top, out[j])
    if not normalise or top == -np.inf:
        return
    acc = 0.0
    for j in range(shape.size):
        acc += np.exp(out[j] - top)
    log_total = top + np.log(acc)
    for j in range(shape.size):
        out[j] -= log_total


@njit(cache=True, error_model="numpy")
def _log_gamma_row(shape: np.ndarray, out: np.ndarray, seed: np.uint64, stream: int, normalise: bool,
                   scratch: RowScratch) -> None:
    """out[j] ← log G_j for independent G_j ~ Gamma(shape[j], 1) (−inf where shape ≤ 0), minus
    log Σ_j G_j when ``normalise`` (then ``out`` is the logarithm of a Dirichlet draw).
    ``scratch``: from :func:`_row_scratch` for at least ``shape.size`` entries.

    A row of at most :data:`_SHORT_ROW` entries is drawn by :func:`_log_gamma_short_row` (stream
    8·stream of ``seed``). A longer row's random words come from eight streams numbered
    8·stream + k (k < 8) of ``seed``, and Marsaglia–Tsang runs in vectorised passes: the
    ziggurat's first step, the proposal and its squeeze for every entry; the logarithmic test for
    those the squeeze leaves; the few still rejected continue one by one. A shape a < 1 is
    boosted, G(a) = G(a + 1) U^{1/a}, in log space: finite even where G underflows (clipped at
    −1e300). The normaliser Σ_j G_j sums linear values (an exp only for the boosted entries)
    unless the row has no entry with a ≥ 1 or a variate below 1e-300, where it is a
    log-sum-exp."""
    width = shape.size
    if width <= _SHORT_ROW:
        _log_gamma_short_row(shape, out, _stream_start(seed, np.uint64(stream * _ROW_STREAMS)), normalise)
        return
    padded = (width + _ROW_STREAMS - 1) // _ROW_STREAMS * _ROW_STREAMS
    all_words, work, todo = scratch
    states = all_words[:_ROW_STREAMS]
    for k in range(_ROW_STREAMS):
        states[k] = _stream_start(seed, np.uint64(stream * _ROW_STREAMS + k))
    words = all_words[_ROW_STREAMS:_ROW_STREAMS + 2 * padded]
    _fill_stream_words(states, words)
    first = words[:width]
    second = _words_to_uniforms(words[padded:padded + width])
    # the boosted entries (0 < a < 1) and the uniforms of their boost (the next words)
    boosted = todo[1, :width]
    n_boosted = 0
    for j in range(width):
        a = shape[j]
        boosted[n_boosted] = j
        n_boosted += np.int64(a < 1.0) * np.int64(a > 0.0)
    boosted = boosted[:n_boosted]
    boost_words = all_words[_ROW_STREAMS + 2 * padded:]
    boost_words = boost_words[:(n_boosted + _ROW_STREAMS - 1) // _ROW_STREAMS * _ROW_STREAMS]
    _fill_stream_words(states, boost_words)
    boost_uniforms = _words_to_uniforms(boost_words[:n_boosted])
    x = work[0, :width]
    fast = work[1, :width]
    accepted = work[2, :width]
    buffer_1 = work[3, :width]
    buffer_2 = work[4, :width]
    v_first = work[5, :width]
    g = out
    _ziggurat_first_step(first, x, fast)
    _marsaglia_tsang_first(shape, x, fast, second, g, accepted, v_first)
    _marsaglia_tsang_rest(shape, x, fast, v_first, first, second, g, accepted, todo[0, :width], buffer_1,
                          buffer_2, accepted, states[0])
    # sums, and the boosted entries in log space: log G(a + 1) + log(U)/a
    total = 0.0
    n_tiny = 0
    for j in range(width):
        a = shape[j]
        total += g[j] * np.float64(a >= 1.0)
        n_tiny += np.int64(g[j] < 1e-300) * np.int64(a > 0.0)
    log_boosted = buffer_1[:n_boosted]
    log_u = buffer_2[:n_boosted]
    for i in range(n_boosted):
        log_boosted[i] = g[boosted[i]]
        log_u[i] = boost_uniforms[i] - _ONE_MINUS_HALF_ULP
    _log_minus(log_u, 0.0, x[:n_boosted])
    if n_tiny == 0:
        _log_minus(log_boosted, 0.0, x[:n_boosted])
    else:  # (the vectorised log needs normal numbers)
        for i in range(n_boosted):
            log_boosted[i] = np.log(log_boosted[i])
    top = -np.inf
    for i in range(n_boosted):
        y = log_boosted[i] + max(log_u[i] / shape[boosted[i]], _LOG_GAMMA_FLOOR)
        log_boosted[i] = y
        top = max(top, y)
    if not normalise:
        log_total = 0.0
    elif total > 1e-280 and n_tiny == 0:
        total += _sum_exp(log_boosted, x[:n_boosted], fast[:n_boosted])  # (below e^−708: 0, harmless)
        x[0] = total  # the same logarithm as the entries' (a single entry then gives exactly 0)
        _log_minus(x[:1], 0.0, fast[:1])
        log_total = x[0]
    else:  # log-sum-exp: no entry with a ≥ 1, or tiny variates
        for j in range(width):
            if shape[j] >= 1.0:
                top = max(top, np.log(g[j]))
        acc = 0.0
        for j in range(width):
            if shape[j] >= 1.0:
                acc += np.exp(np.log(g[j]) - top)
        for i in range(n_boosted):
            acc += np.exp(log_boosted[i] - top)
        log_total = top + np.log(acc) if acc > 0.0 else 0.0
    if n_tiny == 0:
        _log_minus(g, log_total, x)  # (entries with a < 1 are overwritten below)
    else:
        for j in range(width):
            out[j] = np.log(g[j]) - log_total if shape[j] >= 1.0 else 0.0
    for i in range(n_boosted):
        out[boosted[i]] = log_boosted[i] - log_total
    for j in range(width):
        if shape[j] <= 0.0:
            out[j] = -np.inf


@njit(cache=True, error_model="numpy")
def _stream_gamma_any(state: np.uint64, a: float) -> tuple[np.uint64, float]:
    """The next state and a Gamma(a, 1) variate for any a > 0 (boosted below 1: G(a + 1) U^{1/a})."""
    if a >= 1.0:
        return _stream_gamma(state, a)
    state, log_g = _stream_log_gamma_small(state, a)
    return state, np.exp(log_g)
