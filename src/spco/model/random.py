"""Batched random draws used by the Gibbs sampler, all vectorised or compiled.

- :func:`log_gamma_variates`, :func:`log_dirichlet` — many gamma and Dirichlet draws at once,
  returned as logarithms, exact even for tiny concentrations (α^w = 0.01, δ^w φ^w ≪ 1) where plain
  gamma variates underflow to 0; Marsaglia–Tsang with ziggurat normals, each Dirichlet row in
  vectorised passes (:func:`_log_gamma_row`), small batches on one thread, many short rows (π over
  K = 20 regions, θ^w over a few words) as one flat batch of variates normalised row by row.
- :func:`sample_niw` — a batch of Normal–inverse-Wishart draws by the Bartlett decomposition
  (compiled, one random stream per batch element).
- :func:`sample_crt` — table counts m ~ CRT(n, a) of the Chinese restaurant process (Antoniak),
  exact Bernoulli sums for small n, moment-matched normal for the tail of large n;
  :func:`sample_crt_totals` draws their sums over homes directly, as the shared parameters need.
- :func:`sample_categorical_log` — one categorical draw per row of a log-probability matrix;
  :func:`sample_joint_assignment` — the joint (C, R) draw of every sample.

Deterministic kernels of the likelihoods live here too: counts · log θᵀ for every sample and
concept of its home, row by row (:func:`likelihood_table`, :func:`blocked_sparse_dot`) or home by
home and dimension by dimension (:func:`dimension_major`, :func:`dimension_major_dot`, the
sampler's visual likelihood; the same sums bit for bit), :func:`grouped_gaussian_log_density`, and
the statistics (:func:`grouped_row_sums`, :func:`grouped_moments`, :func:`move_rows`), the NIW
posterior parameters (:func:`niw_posterior`) and δ φ from log φ (:func:`scaled_exp`: NumPy's exp
runs at ~6 ns per float64 on a CPU without AVX-512, which made it a visible part of a sweep).

Every random draw takes a :class:`numpy.random.Generator`; the compiled kernels draw their own
random numbers from counter-seeded streams (a seed taken from that generator), so results do not
depend on the number of threads.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from numba import get_num_threads, njit, prange

# ----------------------------------------------------------------------------- random streams
#
# The compiled kernels draw their own random numbers: xorshift64* streams whose starting states
# are counter-based hashes (splitmix64) of a seed taken from the caller's Generator and of the
# block (or entry) index. Results therefore depend on the seed only — never on the number of
# threads or on how Numba schedules the blocks.

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_XORSHIFT_MULT = np.uint64(0x2545F4914F6CDD1D)


@njit(cache=True, inline="always")
def _splitmix(x: np.uint64) -> np.uint64:
    z = x + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


@njit(cache=True, inline="always")
def _stream_start(seed: np.uint64, j: np.uint64) -> np.uint64:
    """Start of the random stream of block or entry ``j``: a counter-based seed, never zero."""
    return _splitmix(seed ^ _splitmix(j)) | np.uint64(1)


@njit(cache=True, inline="always")
def _stream_bits(state: np.uint64) -> tuple[np.uint64, np.uint64]:
    """xorshift64* step: the next state and 64 output bits."""
    state ^= state >> np.uint64(12)
    state ^= state << np.uint64(25)
    state ^= state >> np.uint64(27)
    return state, state * _XORSHIFT_MULT


@njit(cache=True, inline="always")
def _stream_next(state: np.uint64) -> tuple[np.uint64, float]:
    """The next state and a uniform in [0, 1) (53 bits)."""
    state, bits = _stream_bits(state)
    # through int64 (exact for 53 bits): x86 converts signed integers in one instruction
    return state, np.int64(bits >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, inline="always")
def _stream_open(state: np.uint64) -> tuple[np.uint64, float]:
    """The next state and a uniform in (0, 1): never exactly 0, so its logarithm is finite."""
    state, bits = _stream_bits(state)
    return state, (np.int64(bits >> np.uint64(11)) + 0.5) * (1.0 / 9007199254740992.0)


def _ziggurat_tables(layers: int = 256, r: float = 3.6541528853610088,
                     area: float = 4.92867323399e-3) -> tuple[np.ndarray, ...]:
    """Tables of the ziggurat method for the standard normal (Marsaglia & Tsang 2000).

    Layer 0 is the base strip [0, area/f(r)] × [0, f(r)] plus the tail beyond ``r``; layer i ≥ 1
    is the box [0, e_{i-1}] × [f(e_{i-1}), f(e_i)] with edges r = e_0 > e_1 > … > e_255 = 0 and
    f(x) = exp(−x²/2), every layer of the same ``area``. Returns the scale turning 52 random bits
    into an abscissa, the 52-bit threshold below which that abscissa is under the curve, and
    f at the layer's bottom and top edges.
    """
    f = lambda x: np.exp(-0.5 * x * x)  # noqa: E731
    edges = np.zeros(layers)
    edges[0] = r
    for i in range(layers - 2):
        edges[i + 1] = np.sqrt(-2.0 * np.log(area / edges[i] + f(edges[i])))
    width = np.concatenate([[area / f(r)], edges[:-1]])
    threshold = np.floor(edges / width * 2.0**52).astype(np.uint64)
    bottom = np.concatenate([[0.0], f(edges[:-1])])
    return width / 2.0**52, threshold, bottom, f(edges)


_ZIG_SCALE, _ZIG_THRESHOLD, _ZIG_BOTTOM, _ZIG_TOP = _ziggurat_tables()
_ZIG_R = 3.6541528853610088


@njit(cache=True, inline="always")
def _stream_normal(state: np.uint64) -> tuple[np.uint64, float]:
    """The next state and a standard normal variate (ziggurat; ~99 % of draws take one step)."""
    state, bits = _stream_bits(state)
    return _normal_from_bits(state, bits)


@njit(cache=True, inline="always", error_model="numpy")
def _normal_from_bits(state: np.uint64, bits: np.uint64) -> tuple[np.uint64, float]:
    """A ziggurat normal whose first 64 random bits are ``bits``, further ones (if the first step
    does not return) from the stream ``state``: returns the stream's next state and the variate."""
    while True:
        layer = np.int64(bits & np.uint64(255))
        negative = (bits >> np.uint64(8)) & np.uint64(1)
        u = bits >> np.uint64(12)
        x = np.int64(u) * _ZIG_SCALE[layer]
        if u < _ZIG_THRESHOLD[layer]:  # the sign by arithmetic: a branch on a random bit mispredicts
            return state, x * (1.0 - 2.0 * np.int64(negative))
        if layer == 0:  # the tail beyond r (Marsaglia 1964)
            while True:
                state, u1 = _stream_open(state)
                state, u2 = _stream_open(state)
                xx = -np.log(u1) / _ZIG_R
                if -2.0 * np.log(u2) > xx * xx:
                    return state, -(_ZIG_R + xx) if negative else _ZIG_R + xx
        state, u1 = _stream_next(state)
        if _ZIG_BOTTOM[layer] + u1 * (_ZIG_TOP[layer] - _ZIG_BOTTOM[layer]) < np.exp(-0.5 * x * x):
            return state, -x if negative else x
        state, bits = _stream_bits(state)


#: log Gamma(a) variates below this are clipped (they arise for a < 1e-298 and mean "zero").
_LOG_GAMMA_FLOOR = -1e300


@njit(cache=True, inline="always", error_model="numpy")
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


@njit(cache=True, inline="always", error_model="numpy")
def _stream_log_gamma_small(state: np.uint64, a: float) -> tuple[np.uint64, float]:
    """The next state and log G for G ~ Gamma(a, 1), 0 < a < 1, by the boost
    G(a) = G(a + 1) U^{1/a} taken in log space: finite (clipped at −1e300) where G underflows."""
    state, g = _stream_gamma(state, a + 1.0)
    state, u = _stream_open(state)
    return state, np.log(g) + max(np.log(u) / a, _LOG_GAMMA_FLOOR)


#: Entries per random stream in :func:`log_gamma_variates` (blocks run in parallel).
_GAMMA_BLOCK = 4096


@njit(parallel=True, cache=True, error_model="numpy")
def _gamma_kernel(shape: np.ndarray, seed: np.uint64, block: int) -> np.ndarray:
    """Gamma(a) variates for a ≥ 1, Gamma(a + 1) for 0 < a < 1 (the caller applies the boost),
    0 for a ≤ 0; one random stream per block of entries."""
    n = shape.size
    out = np.empty(n)
    for b in prange((n + block - 1) // block):
        state = _stream_start(seed, np.uint64(b))
        for j in range(b * block, min(n, (b + 1) * block)):
            a = shape[j]
            if a >= 1.0:
                state, out[j] = _stream_gamma(state, a)
            elif a > 0.0:
                state, out[j] = _stream_gamma(state, a + 1.0)
            else:
                out[j] = 0.0
    return out


# ----------------------------------------------------------------------------- gamma and Dirichlet


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
    values = _gamma_kernel(flat, seed, _GAMMA_BLOCK)
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


#: Random streams per row in the Dirichlet kernels: eight xorshift64* streams advanced side by side
#: (LLVM's SLP vectoriser runs them in AVX2 lanes) fill the row's random words in one pass.
_ROW_STREAMS = 8
_ZIG_THRESHOLD_SIGNED = _ZIG_THRESHOLD.astype(np.int64)  # thresholds < 2^52: signed compares


@njit(cache=True, inline="always")
def _fill_stream_words(states: np.ndarray, words: np.ndarray) -> None:
    """words[8i + k] ← output i of stream k (xorshift64*) for the eight streams of ``states``,
    which are advanced in place; ``words.size`` is a multiple of 8. Written as eight scalar
    streams so that the SLP vectoriser packs them into vector lanes."""
    s0, s1, s2, s3 = states[0], states[1], states[2], states[3]
    s4, s5, s6, s7 = states[4], states[5], states[6], states[7]
    a, b, c, m = np.uint64(12), np.uint64(25), np.uint64(27), _XORSHIFT_MULT
    for i in range(words.size // 8):
        s0 ^= s0 >> a
        s1 ^= s1 >> a
        s2 ^= s2 >> a
        s3 ^= s3 >> a
        s4 ^= s4 >> a
        s5 ^= s5 >> a
        s6 ^= s6 >> a
        s7 ^= s7 >> a
        s0 ^= s0 << b
        s1 ^= s1 << b
        s2 ^= s2 << b
        s3 ^= s3 << b
        s4 ^= s4 << b
        s5 ^= s5 << b
        s6 ^= s6 << b
        s7 ^= s7 << b
        s0 ^= s0 >> c
        s1 ^= s1 >> c
        s2 ^= s2 >> c
        s3 ^= s3 >> c
        s4 ^= s4 >> c
        s5 ^= s5 >> c
        s6 ^= s6 >> c
        s7 ^= s7 >> c
        j = 8 * i
        words[j] = s0 * m
        words[j + 1] = s1 * m
        words[j + 2] = s2 * m
        words[j + 3] = s3 * m
        words[j + 4] = s4 * m
        words[j + 5] = s5 * m
        words[j + 6] = s6 * m
        words[j + 7] = s7 * m
    states[0], states[1], states[2], states[3] = s0, s1, s2, s3
    states[4], states[5], states[6], states[7] = s4, s5, s6, s7


_ONE_BITS = np.uint64(0x3FF0000000000000)
#: 1 − 2^-53: (1 + m 2^-52) minus this is the open uniform (m + 1/2) 2^-52 in (0, 1), exactly.
_ONE_MINUS_HALF_ULP = 1.0 - 2.0**-53


@njit(cache=True, inline="always")
def _words_to_uniforms(words: np.ndarray) -> np.ndarray:
    """Turn 64-bit random words into open uniforms (m + 1/2) 2^-52, m their top 52 bits, in place,
    and return them as float64: the words become the bit patterns of 1 + m 2^-52 in [1, 2) (an
    integer operation that vectorises, where converting a 64-bit integer to a double does not on
    AVX2), from which the consumer subtracts :data:`_ONE_MINUS_HALF_ULP`."""
    for j in range(words.size):
        words[j] = (words[j] >> np.uint64(12)) | _ONE_BITS
    return words.view(np.float64)


_TWO52_BITS = np.uint64(0x4330000000000000)  # the bit pattern of 2^52


@njit(cache=True, error_model="numpy")
def _ziggurat_first_step(words: np.ndarray, x: np.ndarray, fast: np.ndarray) -> None:
    """The first step of :func:`_stream_normal` for every word, without branches: the abscissa
    x[j] and fast[j] = 1 where that step already returns it (≈ 98 % of words), else 0 (the draw
    continues in :func:`_normal_from_bits`). The 52-bit integer becomes a double through the bit
    pattern of 2^52 + u (no integer conversion, which AVX2 lacks for 64-bit integers)."""
    patterns = x.view(np.uint64)
    for j in range(x.size):
        patterns[j] = (words[j] >> np.uint64(12)) | _TWO52_BITS
    for j in range(x.size):
        bits = words[j]
        layer = np.int64(bits & np.uint64(255))
        sign = 1.0 - 2.0 * np.float64(np.int64((bits >> np.uint64(8)) & np.uint64(1)))
        x[j] = (x[j] - 4503599627370496.0) * _ZIG_SCALE[layer] * sign
        fast[j] = np.float64(np.int64(bits >> np.uint64(12)) < _ZIG_THRESHOLD_SIGNED[layer])


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


# fdlibm's log (Sun Microsystems, 1993; as in musl): x = 2^k (1 + f) with 1 + f in [√2/2, √2),
# log(1 + f) = f − f²/2 + s (f²/2 + R(s²)), s = f/(2 + f), R a degree-7 polynomial; error < 1 ulp
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_LG1, _LG2, _LG3 = 6.666666666666735130e-01, 3.999999999940941908e-01, 2.857142874366239149e-01
_LG4, _LG5, _LG6 = 2.222219843214978396e-01, 1.818357216161805012e-01, 1.531383769920937332e-01
_LG7 = 1.479819860511658591e-01


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def _log_minus(values: np.ndarray, shift: float, exponents: np.ndarray) -> None:
    """values[j] ← log(values[j]) − shift in place, for positive normal (not subnormal) finite
    values; other entries get meaningless finite numbers that the caller overwrites.

    The same arithmetic as the C library's log (fdlibm), written as two branch-free loops —
    integer bit operations, then a polynomial — that LLVM vectorises (4 doubles per AVX2
    instruction; NumPy's error model, so no zero-division check per element). About twice as fast
    as one ``np.log`` call per element; within 1 ulp of it (a test checks 1 M values over the whole
    double range). ``exponents``: scratch of the size of ``values``."""
    bits = values.view(np.int64)
    for j in range(values.size):
        b = bits[j]
        high = (b >> 32) + (0x3FF00000 - 0x3FE6A09E)  # 1 + f in [√2/2, √2): shift the exponent
        exponents[j] = np.float64((high >> 20) - 0x3FF)
        bits[j] = (((high & 0x000FFFFF) + 0x3FE6A09E) << 32) | (b & 0xFFFFFFFF)
    for j in range(values.size):
        f = values[j] - 1.0
        half_f2 = 0.5 * f * f
        s = f / (2.0 + f)
        z = s * s
        w = z * z
        r = w * (_LG2 + w * (_LG4 + w * _LG6)) + z * (_LG1 + w * (_LG3 + w * (_LG5 + w * _LG7)))
        k = exponents[j]
        values[j] = s * (half_f2 + r) + k * _LN2_LO - half_f2 + f + k * _LN2_HI - shift


_INV_LN2 = 1.44269504088896338700e+00
#: 1/i! for the Taylor polynomial of exp on |r| ≤ ln 2 / 2 (degree 13: truncation error < 2e-16)
_EXP_TAYLOR = tuple(1.0 / float(np.prod(np.arange(1, i + 1))) for i in range(14))


@njit(cache=True, inline="always")
def _exp_parts(y: float) -> tuple[float, float]:
    """exp(y) = p · 2^k for y in [−708, 709]: k = round(y / ln 2), r = y − k ln 2 (ln 2 split in
    two as in fdlibm), p = exp(r) by its degree-13 Taylor polynomial; returns p and k + 1023 +
    2^52, whose bit pattern :func:`_powers_of_two` turns into 2^k (AVX2 has no vector conversion
    from double to 64-bit integer). Inlined into branch-free loops that LLVM vectorises."""
    c = _EXP_TAYLOR
    k = np.floor(y * _INV_LN2 + 0.5)
    r = (y - k * _LN2_HI) - k * _LN2_LO
    p = c[13]
    p = p * r + c[12]
    p = p * r + c[11]
    p = p * r + c[10]
    p = p * r + c[9]
    p = p * r + c[8]
    p = p * r + c[7]
    p = p * r + c[6]
    p = p * r + c[5]
    p = p * r + c[4]
    p = p * r + c[3]
    p = p * r + c[2]
    p = p * r + c[1]
    p = p * r + c[0]
    return p, k + (1023.0 + 4503599627370496.0)


@njit(cache=True, inline="always")
def _powers_of_two(powers: np.ndarray) -> None:
    """powers[j] ← 2^k from the k + 1023 + 2^52 of :func:`_exp_parts`, in place: the integer
    k + 1023 sits in the low mantissa bits and moves into the exponent field."""
    bits = powers.view(np.int64)
    for j in range(powers.size):
        bits[j] = bits[j] << 52


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def _sum_exp(values: np.ndarray, poly: np.ndarray, scale: np.ndarray) -> float:
    """Σ_j exp(values[j]) for values ≤ 709 by :func:`_exp_parts`, in branch-free loops that LLVM
    vectorises; terms with y < −708 (below 3e-308) count as 0. Within 2 ulp of summing np.exp.
    ``poly``, ``scale``: scratch of the size of ``values``."""
    n = values.size
    for j in range(n):
        p, power = _exp_parts(max(values[j], -708.0))
        poly[j] = p * np.float64(values[j] >= -708.0)
        scale[j] = power
    _powers_of_two(scale)
    total = 0.0
    for j in range(n):
        total += poly[j] * scale[j]
    return total


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def _scaled_exp(values: np.ndarray, scale: float, out: np.ndarray, powers: np.ndarray) -> None:
    """out[j] ← scale · exp(values[j]) for 1-D contiguous arrays (``powers``: scratch of the same
    size), by :func:`_exp_parts` in branch-free passes that LLVM vectorises; 0 below −745.2
    (where exp rounds to 0); np.exp for the rare entries in [−745.2, −708) (subnormal results),
    above 709 or NaN."""
    outside = 0
    for j in range(values.size):
        x = values[j]
        outside += np.int64(not (((x >= -708.0) & (x <= 709.0)) | (x < -745.2)))
        p, power = _exp_parts(min(max(x, -708.0), 709.0))
        out[j] = p * scale * np.float64(x >= -708.0)
        powers[j] = power
    _powers_of_two(powers)
    for j in range(values.size):
        out[j] *= powers[j]
    if outside:
        for j in range(values.size):
            x = values[j]
            if not ((x >= -708.0 and x <= 709.0) or x < -745.2):
                out[j] = scale * np.exp(x)


def scaled_exp(log_values: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """scale · exp(log_values), elementwise, compiled (NumPy's exp runs at ~6 ns per float64 on
    a CPU without AVX-512, this at under 1 ns): the concentrations δ φ from log φ each sweep.
    Within a few ulp of ``scale * np.exp(log_values)``."""
    shape = np.shape(log_values)
    values = np.ascontiguousarray(log_values, dtype=np.float64).reshape(-1)
    out = np.empty(values.size)
    _scaled_exp(values, float(scale), out, np.empty(values.size))
    return out.reshape(shape)


#: Entries below which a batch of draws runs on one thread: waking Numba's worker threads costs
#: ~60–90 µs, more than such a batch takes.
_PARALLEL_MIN = 32_768


@njit(parallel=True, cache=True, error_model="numpy")
def _dirichlet_kernel(shape: np.ndarray, seed: np.uint64, out: np.ndarray) -> None:
    for r in prange(shape.shape[0]):
        _log_gamma_row(shape[r], out[r], seed, r, True, _row_scratch(shape.shape[1]))


@njit(cache=True, error_model="numpy")
def _dirichlet_serial(shape: np.ndarray, seed: np.uint64, out: np.ndarray) -> None:
    # _dirichlet_kernel on one thread, for small batches: the same draws, except for many short
    # rows (see _short_rows)
    if _short_rows(shape.shape[0], shape.shape[1]):
        _dirichlet_short_rows(shape, seed, out)
        return
    scratch = _row_scratch(shape.shape[1])
    for r in range(shape.shape[0]):
        _log_gamma_row(shape[r], out[r], seed, r, True, scratch)


@njit(cache=True, inline="always")
def _short_rows(n_rows: int, width: int) -> bool:
    """Whether a batch of Dirichlet rows is drawn as one flat batch of gamma variates
    (:func:`_dirichlet_short_rows`): rows short enough for :func:`_log_gamma_row` to take them one
    entry at a time, and enough of them for the vectorised passes to pay."""
    return width <= _SHORT_ROW and n_rows * width >= 4 * _SHORT_ROW


@njit(cache=True, error_model="numpy")
def _dirichlet_short_rows(shape: np.ndarray, seed: np.uint64, out: np.ndarray) -> None:
    """log Dirichlet rows of ``shape`` (R, W) into ``out``, for many short rows (π over K = 20
    regions, θ^w over a few words): the gamma variates of all rows in one vectorised pass of
    :func:`_log_gamma_row` (its eight streams of ``seed``), then each row normalised by a
    log-sum-exp (a row of zero shapes stays −inf)."""
    n_rows, width = shape.shape
    size = n_rows * width
    _log_gamma_row(shape.reshape(-1), out.reshape(-1), seed, 0, False, _row_scratch(size))
    tops = np.empty(n_rows)
    shifted = np.empty((n_rows, width))
    for r in range(n_rows):
        top = -np.inf
        for j in range(width):
            top = max(top, out[r, j])
        tops[r] = top
        for j in range(width):
            shifted[r, j] = out[r, j] - top if top > -np.inf else -np.inf
    weights = np.empty((n_rows, width))
    _scaled_exp(shifted.reshape(-1), 1.0, weights.reshape(-1), np.empty(size))
    for r in range(n_rows):
        if tops[r] == -np.inf:
            continue
        acc = 0.0
        for j in range(width):
            acc += weights[r, j]
        log_total = tops[r] + np.log(acc)
        for j in range(width):
            out[r, j] -= log_total


@njit(parallel=True, cache=True, error_model="numpy")
def _hierarchical_dirichlet_kernel(base: np.ndarray, counts: np.ndarray, seed: np.uint64,
                                   out: np.ndarray) -> None:
    for i in prange(counts.shape[0] * counts.shape[1]):
        _hierarchical_dirichlet_row(base, counts, seed, out, i, _row_scratch(counts.shape[2]))


@njit(cache=True, error_model="numpy")
def _hierarchical_dirichlet_serial(base: np.ndarray, counts: np.ndarray, seed: np.uint64,
                                   out: np.ndarray) -> None:
    # _hierarchical_dirichlet_kernel on one thread, for small batches: the same draws, except
    # for many short rows (see _short_rows)
    rows, width = counts.shape[0] * counts.shape[1], counts.shape[2]
    if _short_rows(rows, width):
        shape = np.empty((rows, width))
        n_concepts = counts.shape[1]
        for i in range(rows):
            g, r = i // n_concepts, i % n_concepts
            for k in range(width):
                shape[i, k] = base[r, k] + counts[g, r, k]
        _dirichlet_short_rows(shape, seed, out.reshape(rows, width))
        return
    scratch = _row_scratch(counts.shape[2])
    for i in range(counts.shape[0] * counts.shape[1]):
        _hierarchical_dirichlet_row(base, counts, seed, out, i, scratch)


@njit(cache=True, inline="always", error_model="numpy")
def _hierarchical_dirichlet_row(base: np.ndarray, counts: np.ndarray, seed: np.uint64, out: np.ndarray,
                                i: int, scratch: RowScratch) -> None:
    rows, width = counts.shape[1], counts.shape[2]
    g, r = i // rows, i % rows
    shape = scratch[1][6, :width]  # (rows 0-5 are the row function's own scratch)
    for k in range(width):
        shape[k] = base[r, k] + counts[g, r, k]
    _log_gamma_row(shape, out[g, r], seed, i, True, scratch)


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
    kernel = _dirichlet_kernel if rows.size >= _PARALLEL_MIN else _dirichlet_serial
    _call_vectorised(kernel, (rows, seed, out))
    return out.reshape(alpha.shape)


def log_dirichlet_hierarchical(base: np.ndarray, counts: np.ndarray, rng: np.random.Generator,
                               out: np.ndarray | None = None) -> np.ndarray:
    """log θ_{g,r} ~ Dir(base_r + counts_{g,r}) for every group g and row r, without forming the
    concentrations: the draw of θ_{e,l} ~ Dir(δ φ_l + n_{e,l}) for all homes at once.

    Parameters
    ----------
    base: (R, D) non-negative concentrations shared by the groups (δ φ).
    counts: (G, R, D) non-negative integer counts (n).
    out: optional (G, R, D) float64 C-contiguous array to write into (e.g. the previous draw).

    Returns
    -------
    (G, R, D) log-probabilities, the same as :func:`log_dirichlet` of ``base + counts`` in
    distribution.
    """
    counts = np.ascontiguousarray(counts, dtype=np.int64)
    base = np.ascontiguousarray(np.broadcast_to(base, counts.shape[1:]), dtype=np.float64)
    if counts.shape[-1] == 0:
        return np.zeros(counts.shape)
    if out is None or out.shape != counts.shape or out.dtype != np.float64 or not out.flags.c_contiguous:
        out = np.empty(counts.shape)
    seed = np.uint64(rng.integers(0, 2**63 - 1, dtype=np.int64))
    parallel = counts.size >= _PARALLEL_MIN
    kernel = _hierarchical_dirichlet_kernel if parallel else _hierarchical_dirichlet_serial
    _call_vectorised(kernel, (base, counts, seed, out))
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


# ----------------------------------------------------------------------------- Normal–inverse-Wishart


def niw_posterior(
    count: np.ndarray, total: np.ndarray, scatter: np.ndarray,
    mu0: np.ndarray, kappa0: float, psi0: np.ndarray, nu0: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Posterior NIW parameters from sufficient statistics, batched over leading axes.

    Parameters
    ----------
    count: (...,) number of points n.
    total: (..., d) sum of the points Σ x.
    scatter: (..., d, d) sum of outer products Σ x xᵀ.
    mu0, kappa0, psi0, nu0: the prior (μ0 of shape (d,) or (..., d); Ψ0 of shape (d, d)).

    Returns
    -------
    (μ_n, κ_n, Ψ_n, ν_n) with κ_n = κ0 + n, ν_n = ν0 + n, μ_n = (κ0 μ0 + n x̄)/κ_n and
    Ψ_n = Ψ0 + S + (κ0 n/κ_n)(x̄ − μ0)(x̄ − μ0)ᵀ, S the centred scatter. Computed in the
    equivalent form Ψ_n = Ψ0 + Σxxᵀ + κ0 μ0μ0ᵀ − κ_n μ_n μ_nᵀ, symmetrised.
    """
    count = np.asarray(count, dtype=np.float64)
    total = np.asarray(total, dtype=np.float64)
    batch, d = total.shape[:-1], total.shape[-1]
    flat_count = np.ascontiguousarray(np.broadcast_to(count, batch)).reshape(-1)
    flat_total = np.ascontiguousarray(total).reshape(-1, d)
    flat_scatter = np.ascontiguousarray(np.broadcast_to(scatter, (*batch, d, d)), dtype=np.float64)
    flat_scatter = flat_scatter.reshape(-1, d, d)
    flat_mu0 = np.ascontiguousarray(np.broadcast_to(mu0, total.shape), dtype=np.float64).reshape(-1, d)
    mu_n = np.empty(flat_total.shape)
    psi_n = np.empty(flat_scatter.shape)
    _niw_posterior_kernel(flat_count, flat_total, flat_scatter, flat_mu0, float(kappa0),
                          np.ascontiguousarray(psi0, dtype=np.float64), mu_n, psi_n)
    return mu_n.reshape(total.shape), kappa0 + count, psi_n.reshape(*batch, d, d), nu0 + count


@njit(cache=True, error_model="numpy")
def _niw_posterior_kernel(count: np.ndarray, total: np.ndarray, scatter: np.ndarray, mu0: np.ndarray,
                          kappa0: float, psi0: np.ndarray, mu_n: np.ndarray, psi_n: np.ndarray) -> None:
    # niw_posterior for a flat batch (~1 µs per 100 elements, where NumPy's broadcasting of
    # the same formulas over (E, K, 4, 4) arrays costs ~0.2 ms)
    d = total.shape[1]
    sum_y = np.empty(d)
    for b in range(count.size):
        n = count[b]
        kappa_n = kappa0 + n
        for i in range(d):
            mu_n[b, i] = (kappa0 * mu0[b, i] + total[b, i]) / kappa_n
            sum_y[i] = total[b, i] - n * mu0[b, i]
        for i in range(d):
            for j in range(d):
                yy = (scatter[b, i, j] - total[b, i] * mu0[b, j] - mu0[b, i] * total[b, j]
                      + n * mu0[b, i] * mu0[b, j])
                psi_n[b, i, j] = psi0[i, j] + yy - sum_y[i] * sum_y[j] / kappa_n
        for i in range(d):
            for j in range(i + 1, d):
                sym = 0.5 * (psi_n[b, i, j] + psi_n[b, j, i])
                psi_n[b, i, j] = sym
                psi_n[b, j, i] = sym


@njit(cache=True, inline="always", error_model="numpy")
def _cholesky_into(matrix: np.ndarray, chol: np.ndarray) -> bool:
    """Lower Cholesky factor of the (d, d) ``matrix`` into ``chol`` (its upper triangle is left
    as it is); returns False if ``matrix`` is not positive definite (a failing pivot is set to 1)."""
    d = matrix.shape[0]
    positive = True
    for j in range(d):
        s = matrix[j, j]
        for k in range(j):
            s -= chol[j, k] * chol[j, k]
        if not s > 0.0:
            positive = False
            s = 1.0
        chol[j, j] = np.sqrt(s)
        for i in range(j + 1, d):
            t = matrix[i, j]
            for k in range(j):
                t -= chol[i, k] * chol[j, k]
            chol[i, j] = t / chol[j, j]
    return positive


@njit(cache=True, inline="always")
def _stream_gamma_any(state: np.uint64, a: float) -> tuple[np.uint64, float]:
    """The next state and a Gamma(a, 1) variate for any a > 0 (boosted below 1: G(a + 1) U^{1/a})."""
    if a >= 1.0:
        return _stream_gamma(state, a)
    state, log_g = _stream_log_gamma_small(state, a)
    return state, np.exp(log_g)


@njit(parallel=True, cache=True)
def _niw_kernel(mu_n: np.ndarray, kappa_n: np.ndarray, psi_n: np.ndarray, nu_n: np.ndarray, seed: np.uint64,
                mu: np.ndarray, sigma: np.ndarray, failed: np.ndarray) -> None:
    for b in prange(mu_n.shape[0]):
        _niw_element(mu_n, kappa_n, psi_n, nu_n, seed, mu, sigma, failed, b)


@njit(cache=True)
def _niw_serial(mu_n: np.ndarray, kappa_n: np.ndarray, psi_n: np.ndarray, nu_n: np.ndarray, seed: np.uint64,
                mu: np.ndarray, sigma: np.ndarray, failed: np.ndarray) -> None:
    # _niw_kernel on one thread, for small batches: the same draws
    for b in range(mu_n.shape[0]):
        _niw_element(mu_n, kappa_n, psi_n, nu_n, seed, mu, sigma, failed, b)


@njit(cache=True, inline="always")
def _niw_element(mu_n: np.ndarray, kappa_n: np.ndarray, psi_n: np.ndarray, nu_n: np.ndarray, seed: np.uint64,
                 mu: np.ndarray, sigma: np.ndarray, failed: np.ndarray, b: int) -> None:
    d = mu_n.shape[1]
    state = _stream_start(seed, np.uint64(b))
    chol = np.zeros((d, d))  # C = chol(Ψ_n), lower
    failed[b] = not _cholesky_into(psi_n[b], chol)
    bartlett = np.zeros((d, d))  # A: A_ii = sqrt(χ²(ν − i)), A_ij ~ N(0, 1) below the diagonal
    for i in range(d):
        state, g = _stream_gamma_any(state, 0.5 * (nu_n[b] - i))
        bartlett[i, i] = np.sqrt(2.0 * g)
        for j in range(i):
            state, bartlett[i, j] = _stream_normal(state)
    factor = np.zeros((d, d))  # F = C A^{-T}: F Aᵀ = C, forward substitution along each row
    for r in range(d):
        for k in range(d):
            t = chol[r, k]
            for j in range(k):
                t -= factor[r, j] * bartlett[k, j]
            factor[r, k] = t / bartlett[k, k]
    for i in range(d):  # Σ = F Fᵀ
        for j in range(i + 1):
            t = 0.0
            for k in range(d):
                t += factor[i, k] * factor[j, k]
            sigma[b, i, j] = t
            sigma[b, j, i] = t
    scale = 1.0 / np.sqrt(kappa_n[b])  # μ = μ_n + F z / √κ_n
    z = np.empty(d)
    for i in range(d):
        state, z[i] = _stream_normal(state)
    for i in range(d):
        t = 0.0
        for k in range(d):
            t += factor[i, k] * z[k]
        mu[b, i] = mu_n[b, i] + t * scale


def sample_niw(
    mu_n: np.ndarray, kappa_n: np.ndarray, psi_n: np.ndarray, nu_n: np.ndarray,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Draw (μ, Σ) ~ NIW(μ_n, κ_n, Ψ_n, ν_n) for a batch, by the Bartlett decomposition.

    Σ ~ IW(Ψ_n, ν_n) is drawn as Σ = (C A^{-T})(C A^{-T})ᵀ with C = chol(Ψ_n) and A the lower
    triangular Bartlett factor (A_ii = sqrt(χ²(ν − i)), A_ij ~ N(0, 1) below the diagonal), since
    Σ^{-1} = C^{-T} A Aᵀ C^{-1} ~ W(Ψ_n^{-1}, ν_n). Then μ ~ N(μ_n, Σ/κ_n). One compiled kernel
    for the whole batch (in parallel), each element with its own random stream seeded from ``rng``.

    Shapes: mu_n (..., d), kappa_n (...,), psi_n (..., d, d), nu_n (...,). Returns μ (..., d) and
    Σ (..., d, d).
    """
    psi_n = np.asarray(psi_n, dtype=np.float64)
    batch, d = psi_n.shape[:-2], psi_n.shape[-1]
    flat_mu = np.ascontiguousarray(np.broadcast_to(mu_n, (*batch, d)), dtype=np.float64).reshape(-1, d)
    flat_kappa = np.ascontiguousarray(np.broadcast_to(kappa_n, batch), dtype=np.float64).ravel()
    flat_nu = np.ascontiguousarray(np.broadcast_to(nu_n, batch), dtype=np.float64).ravel()
    flat_psi = np.ascontiguousarray(psi_n).reshape(-1, d, d)
    if (flat_nu <= d - 1).any():
        raise ValueError(f"sample_niw needs ν > d − 1 = {d - 1}; got min ν = {flat_nu.min()}")
    mu = np.empty(flat_mu.shape)
    sigma = np.empty(flat_psi.shape)
    failed = np.zeros(flat_mu.shape[0], dtype=np.bool_)
    seed = np.uint64(rng.integers(0, 2**63 - 1, dtype=np.int64))
    kernel = _niw_kernel if flat_mu.shape[0] >= _PARALLEL_MIN // 16 else _niw_serial  # (~1 µs each)
    kernel(flat_mu, flat_kappa, flat_psi, flat_nu, seed, mu, sigma, failed)
    if failed.any():
        raise ValueError(f"sample_niw: Ψ_n of {int(failed.sum())} batch element(s) is not positive definite")
    return mu.reshape(*batch, d), sigma.reshape(*batch, d, d)


def gaussian_log_density(x: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """log N(x | mean_m, cov_m) for every point and component.

    Shapes: x (n, d); mean (K, d); cov (K, d, d). Returns (n, K).
    """
    return grouped_gaussian_log_density(x, np.zeros(x.shape[0], dtype=np.int64), mean[None], cov[None])


#: Points per task of :func:`_grouped_gaussian` (their scratch allocated once per task).
_GAUSSIAN_CHUNK = 64


@njit(parallel=True, cache=True)
def _grouped_gaussian(x: np.ndarray, groups: np.ndarray, means_t: np.ndarray, inv_chol_t: np.ndarray,
                      constant: np.ndarray) -> np.ndarray:
    # means_t (G, d, K) and inv_chol_t (G, d, d, K): the components last, so that every inner loop
    # runs over the K components of a point at once (vectorised); each quadratic form is summed in
    # the same order as one component at a time
    n, d = x.shape
    n_components = means_t.shape[2]
    out = np.empty((n, n_components))
    for chunk in prange((n + _GAUSSIAN_CHUNK - 1) // _GAUSSIAN_CHUNK):
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
    return out


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


# ----------------------------------------------------------------------------- CRT (Antoniak)

@njit(cache=True, inline="always", error_model="numpy")
def _digamma_large(x: float) -> float:
    # asymptotic series, accurate to ~1e-12 for x >= 6
    return np.log(x) + _digamma_large_minus_log(x)


@njit(cache=True, inline="always", error_model="numpy")
def _digamma_large_minus_log(x: float) -> float:
    """ψ(x) − log x by the asymptotic series (x ≥ 6): sums of ψ can then take one logarithm of
    the product of their arguments instead of one per term."""
    inv = 1.0 / x
    inv2 = inv * inv
    return -0.5 * inv - inv2 * (1.0 / 12 - inv2 * (1.0 / 120 - inv2 * (1.0 / 252 - inv2 * (1.0 / 240
                                                                           - inv2 / 132))))


@njit(cache=True, inline="always", error_model="numpy")
def _trigamma_large(x: float) -> float:
    inv = 1.0 / x
    inv2 = inv * inv
    return inv + 0.5 * inv2 + inv * inv2 * (1.0 / 6 - inv2 * (1.0 / 30 - inv2 * (1.0 / 42 - inv2 / 30)))


@njit(cache=True, inline="always", error_model="numpy")
def _digamma(x: float) -> float:
    """ψ(x) for x > 0: the recurrence ψ(x) = ψ(x + 1) − 1/x up to x ≥ 6, then the series."""
    shift = 0.0
    while x < 6.0:
        shift -= 1.0 / x
        x += 1.0
    return shift + _digamma_large(x)


@njit(cache=True, inline="always", error_model="numpy")
def _trigamma(x: float) -> float:
    """ψ′(x) for x > 0, the same way."""
    shift = 0.0
    while x < 6.0:
        shift += 1.0 / (x * x)
        x += 1.0
    return shift + _trigamma_large(x)


@njit(cache=True, error_model="numpy")
def _bernoulli_sum_moment_matched(terms: int, mean: float, var: float,
                                  state: np.uint64) -> tuple[np.uint64, int]:
    """A draw of a sum of ``terms`` independent Bernoulli variables with the given mean and
    variance: a rounded normal when the variance is large (>= 25), otherwise the rarer outcome
    (successes or failures) from the binomial with the same mean and variance (a Poisson when
    they coincide). Returns the next state of the random stream and the count, in 0..terms."""
    if var < 0.0:
        var = 0.0
    if mean > terms:
        mean = float(terms)
    rare_is_success = mean <= terms - mean
    rare_mean = mean if rare_is_success else terms - mean
    if var >= 25.0 or rare_mean > 50.0:
        state, z = _stream_normal(state)
        extra = np.floor(mean + np.sqrt(var) * z + 0.5)
        if extra < 0.0:
            extra = 0.0
        if extra > terms:
            extra = float(terms)
        return state, int(extra)
    rare = 0
    if rare_mean > 0.0:
        state, u1 = _stream_next(state)
        p = 1.0 - var / rare_mean
        if p < 1e-6:  # Poisson(rare_mean)
            pmf = np.exp(-rare_mean)
            cdf = pmf
            while u1 > cdf and rare < terms:
                rare += 1
                pmf *= rare_mean / rare
                cdf += pmf
        else:
            if p > 0.999:
                p = 0.999
            trials = max(int(np.floor(rare_mean / p + 0.5)), 1)
            p = min(rare_mean / trials, 1.0)
            if p >= 1.0:
                rare = trials
            else:
                pmf = (1.0 - p) ** trials
                cdf = pmf
                ratio = p / (1.0 - p)
                while u1 > cdf and rare < trials:
                    pmf *= (trials - rare) / (rare + 1.0) * ratio
                    rare += 1
                    cdf += pmf
        if rare > terms:
            rare = terms
    return state, rare if rare_is_success else terms - rare


@njit(cache=True, error_model="numpy")
def _crt_tail(n: int, a: float, head: int, state: np.uint64) -> tuple[np.uint64, int]:
    """Tables opened by customers head..n-1, a sum of independent Bernoulli(a/(a+i)), drawn by
    :func:`_bernoulli_sum_moment_matched` with the exact mean and variance (digamma/trigamma
    series, a + head >= 6)."""
    mean = a * (_digamma_large(a + n) - _digamma_large(a + head))
    var = mean - a * a * (_trigamma_large(a + head) - _trigamma_large(a + n))
    return _bernoulli_sum_moment_matched(n - head, mean, var, state)


@njit(parallel=True, cache=True, error_model="numpy")
def _crt_kernel(counts: np.ndarray, conc: np.ndarray, seed: np.uint64, exact_max: int,
                head: int) -> np.ndarray:
    out = np.zeros(counts.size, dtype=np.int64)
    for j in prange(counts.size):
        out[j] = _crt_entry(counts[j], conc[j], seed, exact_max, head, j)
    return out


@njit(cache=True, error_model="numpy")
def _crt_serial(counts: np.ndarray, conc: np.ndarray, seed: np.uint64, exact_max: int,
                head: int) -> np.ndarray:
    # _crt_kernel on one thread, for small inputs: the same draws
    out = np.zeros(counts.size, dtype=np.int64)
    for j in range(counts.size):
        out[j] = _crt_entry(counts[j], conc[j], seed, exact_max, head, j)
    return out


@njit(cache=True, inline="always", error_model="numpy")
def _crt_entry(n: int, a: float, seed: np.uint64, exact_max: int, head: int, j: int) -> int:
    if n <= 0 or a <= 0.0:
        return 0
    m = 1  # the first customer always opens a table
    # customers 1..start-1 exactly; the series of the tail need a + start >= 6
    start = 1 if a >= 5.0 else head
    limit = n if n <= exact_max else start
    state = _stream_start(seed, np.uint64(j))
    for i in range(1, limit):
        state, u = _stream_next(state)
        if u * (a + i) < a:
            m += 1
    if n > exact_max:
        state, extra = _crt_tail(n, a, start, state)
        m += extra
    return m


def sample_crt(
    counts: np.ndarray, concentration: np.ndarray, rng: np.random.Generator,
    exact_max: int = 40, head: int = 8,
) -> np.ndarray:
    """Number of tables m ~ CRT(n, a) for each entry (Chinese restaurant table distribution).

    m = Σ_{i=0}^{n-1} Bernoulli(a / (a + i)). For n ≤ ``exact_max`` the sum is drawn exactly; for
    larger n the first ``head`` terms (only the first one when a ≥ 5) are drawn exactly and the
    remaining ones by a normal with the exact mean a(ψ(a+n) − ψ(a+h)) and variance
    (mean − a²(ψ′(a+h) − ψ′(a+n))), h the number of exact terms, rounded and clipped to its range
    (by the binomial or Poisson with that mean and variance when the variance is small). With
    a + h ≥ 6 the digamma series used is accurate to 1e-12.

    Parameters
    ----------
    counts: integer array n ≥ 0, any shape.
    concentration: array a ≥ 0 broadcastable to ``counts``; a = 0 or n = 0 gives m = 0.

    Returns
    -------
    int64 array of the shape of ``counts``.
    """
    if head < 6 or exact_max < head:
        raise ValueError("sample_crt needs head >= 6 and exact_max >= head")
    counts = np.asarray(counts)
    conc = np.broadcast_to(np.asarray(concentration, dtype=np.float64), counts.shape)
    flat_n = np.ascontiguousarray(counts, dtype=np.int64).ravel()
    flat_a = np.ascontiguousarray(conc, dtype=np.float64).ravel()
    seed = np.uint64(rng.integers(0, 2**63 - 1, dtype=np.int64))
    kernel = _crt_kernel if flat_n.size >= _PARALLEL_MIN // 8 else _crt_serial
    return kernel(flat_n, flat_a, seed, int(exact_max), int(head)).reshape(counts.shape)


@njit(parallel=True, cache=True, error_model="numpy")
def _crt_totals_kernel(counts: np.ndarray, conc: np.ndarray, seed: np.uint64, exact_max: int) -> np.ndarray:
    out = np.zeros((counts.shape[1], counts.shape[2]), dtype=np.int64)
    for r in prange(counts.shape[1]):
        _crt_totals_row(counts, conc, seed, exact_max, r, out[r])
    return out


@njit(cache=True, error_model="numpy")
def _crt_totals_serial(counts: np.ndarray, conc: np.ndarray, seed: np.uint64, exact_max: int) -> np.ndarray:
    # _crt_totals_kernel on one thread, for small inputs: the same draws
    out = np.zeros((counts.shape[1], counts.shape[2]), dtype=np.int64)
    for r in range(counts.shape[1]):
        _crt_totals_row(counts, conc, seed, exact_max, r, out[r])
    return out


@njit(cache=True, inline="always", error_model="numpy")
def _crt_totals_row(counts: np.ndarray, conc: np.ndarray, seed: np.uint64, exact_max: int, r: int,
                    opened: np.ndarray) -> None:
    n_groups, width = counts.shape[0], counts.shape[2]
    a_row = conc[r]
    # pass 1 (branch-free): tables opened by first customers, Bernoulli terms per column
    terms = np.zeros(width, dtype=np.int64)
    for g in range(n_groups):
        n_row = counts[g, r]
        for k in range(width):
            n = n_row[k]
            active = np.int64(n > 0) * np.int64(a_row[k] > 0.0)
            opened[k] += active
            terms[k] += active * (n - 1)
    # pass 2, groups in memory order, only the entries with n > 1 (gathered without branches
    # first): the exact Bernoulli draws of the columns with few terms (each column continues
    # its own random stream from group to group) and the moments of the others: Σ_i p_i and
    # Σ_i p_i (1 − p_i), p_i = a/(a + i), term by term where a + n < 6, otherwise through
    # Σ_g ψ(a + n_g) and Σ_g ψ′(a + n_g) (series), with ψ(a + 1) once per column
    states = np.empty(width, dtype=np.uint64)
    for k in range(width):
        states[k] = _stream_start(seed, np.uint64(r * width + k))
    exact_mean = np.zeros(width)
    exact_var = np.zeros(width)
    digamma_sum = np.zeros(width)
    trigamma_sum = np.zeros(width)
    product = np.ones(width)  # Π (a + n_g) of the series terms: Σ log = log Π, one log per column
    several = np.zeros(width, dtype=np.int64)
    series_columns = np.empty(width, dtype=np.int64)
    exact_columns = np.empty(width, dtype=np.int64)
    x_buffer = np.empty(width)
    digamma_buffer = np.empty(width)
    trigamma_buffer = np.empty(width)
    for g in range(n_groups):
        n_row = counts[g, r]
        n_series = 0
        n_exact = 0
        for k in range(width):  # the columns of this group in the two regimes, without branches
            active = np.int64(n_row[k] > 1) * np.int64(terms[k] > 0)
            tail = np.int64(terms[k] > exact_max)
            series_columns[n_series] = k
            n_series += active * tail
            exact_columns[n_exact] = k
            n_exact += active * (1 - tail)
        for j in range(n_series):
            k = series_columns[j]
            x_buffer[j] = a_row[k] + n_row[k]
        for j in range(n_series):  # vectorised; used where a + n ≥ 6
            x = x_buffer[j]
            digamma_buffer[j] = _digamma_large_minus_log(x)
            trigamma_buffer[j] = _trigamma_large(x)
        for j in range(n_series):
            k = series_columns[j]
            x = x_buffer[j]
            if x >= 6.0:
                digamma_sum[k] += digamma_buffer[j]
                trigamma_sum[k] += trigamma_buffer[j]
                product[k] *= x
                if product[k] > 1e280:  # x < 2^63: the next product cannot overflow
                    digamma_sum[k] += np.log(product[k])
                    product[k] = 1.0
                several[k] += 1
            else:
                a = a_row[k]
                for i in range(1, n_row[k]):
                    p = a / (a + i)
                    exact_mean[k] += p
                    exact_var[k] += p * (1.0 - p)
        for j in range(n_exact):
            k = exact_columns[j]
            n = n_row[k]
            a = a_row[k]
            state = states[k]
            for i in range(1, n):
                state, u = _stream_next(state)
                opened[k] += np.int64(u * (a + i) < a)
            states[k] = state
    for k in range(width):
        if terms[k] <= exact_max:
            continue
        a = a_row[k]
        mean = exact_mean[k]
        var = exact_var[k]
        if several[k] > 0:
            digamma_sum[k] += np.log(product[k])
            series_mean = a * (digamma_sum[k] - several[k] * _digamma(a + 1.0))
            mean += series_mean
            var += series_mean - a * a * (several[k] * _trigamma(a + 1.0) - trigamma_sum[k])
        _, extra = _bernoulli_sum_moment_matched(terms[k], mean, var, states[k])
        opened[k] += extra


def sample_crt_totals(counts: np.ndarray, concentration: np.ndarray, rng: np.random.Generator,
                      exact_max: int = 40) -> np.ndarray:
    """Σ_g m_g for independent m_g ~ CRT(n_g, a): table counts summed over the first axis.

    This is what the shared parameters need (φ_l | tables ~ Dir(α + Σ_e m_{e,l,·})), drawn in one
    go instead of one CRT draw per home: the sum is itself a sum of independent Bernoulli
    variables, Σ_g [n_g > 0] + Σ_g Σ_{i=1}^{n_g−1} Bernoulli(a/(a+i)). When the Bernoulli terms
    number at most ``exact_max`` they are drawn one by one (exact); otherwise the sum is drawn
    from the normal (variance ≥ 25) or binomial/Poisson with its exact mean
    Σ_g a(ψ(a+n_g) − ψ(a+1)) and variance (mean − Σ_g a²(ψ′(a+1) − ψ′(a+n_g))), as in
    :func:`sample_crt`'s tail.

    Parameters
    ----------
    counts: (G, R, W) integer counts n ≥ 0 (e.g. homes × concepts × dimensions).
    concentration: (R, W) a ≥ 0; a = 0 or n = 0 contributes no table.

    Returns
    -------
    (R, W) int64 table counts summed over the G groups.
    """
    counts = np.ascontiguousarray(counts, dtype=np.int64)
    if counts.ndim != 3:
        raise ValueError("sample_crt_totals needs counts of shape (groups, rows, width)")
    conc = np.ascontiguousarray(np.broadcast_to(concentration, counts.shape[1:]), dtype=np.float64)
    seed = np.uint64(rng.integers(0, 2**63 - 1, dtype=np.int64))
    kernel = _crt_totals_kernel if counts.size >= _PARALLEL_MIN else _crt_totals_serial
    return kernel(counts, conc, seed, int(exact_max))


# ----------------------------------------------------------------------------- categorical


@njit(cache=True)
def _draw_log(log_p: np.ndarray, u: float) -> int:
    """Index drawn from unnormalised log-probabilities ``log_p`` (1-D) with the uniform ``u``;
    overwrites ``log_p`` with the shifted weights."""
    width = log_p.size
    top = -np.inf
    for j in range(width):
        if log_p[j] > top:
            top = log_p[j]
    total = 0.0
    for j in range(width):
        log_p[j] = np.exp(log_p[j] - top)
        total += log_p[j]
    target = u * total
    acc = 0.0
    for j in range(width):
        acc += log_p[j]
        if acc > target:
            return j
    return width - 1


@njit(parallel=True, cache=True)
def _categorical_rows(log_p: np.ndarray, u: np.ndarray) -> np.ndarray:
    n = log_p.shape[0]
    out = np.empty(n, dtype=np.int64)
    for t in prange(n):
        out[t] = _draw_log(log_p[t].copy(), u[t])
    return out


def sample_categorical_log(log_p: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One draw per row from unnormalised log-probabilities ``log_p`` of shape (n, J).

    Subtracts the row maximum before exponentiating, so gaps of thousands of nats are safe. Rows
    must hold at least one finite entry. Returns int64 indices of shape (n,).
    """
    u = rng.random(log_p.shape[0])
    return _categorical_rows(np.ascontiguousarray(log_p, dtype=np.float64), u)


#: Samples per task of :func:`_joint_assignment` (scratch arrays are allocated once per task).
_ASSIGNMENT_CHUNK = 64


@njit(parallel=True, cache=True, error_model="numpy")
def _joint_assignment(log_g: np.ndarray, log_pi: np.ndarray, pi_scaled: np.ndarray, pi_row_max: np.ndarray,
                      homes: np.ndarray, concept_ll: np.ndarray, region_ll: np.ndarray, u_concept: np.ndarray,
                      u_region: np.ndarray) -> np.ndarray:
    # pi_scaled: (E, K, L), regions before concepts, so that the sums over regions run for all
    # concepts side by side (vector lanes); each sum still adds its terms in region order
    n = homes.size
    n_concepts = log_pi.shape[1]
    n_regions = log_pi.shape[2]
    out = np.empty(n, dtype=np.int64)
    n_chunks = (n + _ASSIGNMENT_CHUNK - 1) // _ASSIGNMENT_CHUNK
    for chunk in prange(n_chunks):
        first = chunk * _ASSIGNMENT_CHUNK
        size = min(n, first + _ASSIGNMENT_CHUNK) - first
        # the chunk's exp(region log-likelihood − its row maximum), in one vectorised pass
        shifted = np.empty(size * max(n_regions, n_concepts))
        r = np.empty(size * n_regions)
        powers = np.empty(shifted.size)
        r_max = np.empty(size)
        for i in range(size):
            top = -np.inf
            for m in range(n_regions):
                top = max(top, region_ll[first + i, m])
            r_max[i] = top
            for m in range(n_regions):
                shifted[i * n_regions + m] = region_ll[first + i, m] - top
        _scaled_exp(shifted[:size * n_regions], 1.0, r, powers[:size * n_regions])
        # marginal of C: G · lik · Σ_m π_{c,m} N(x | m), the sum over regions a dot product
        sums = np.zeros(size * n_concepts)
        log_c = np.empty(size * n_concepts)
        tops = np.empty(size)
        linear = np.empty(size, dtype=np.bool_)
        for i in range(size):
            t = first + i
            e = homes[t]
            s = sums[i * n_concepts:(i + 1) * n_concepts]
            for m in range(n_regions):
                rm = r[i * n_regions + m]
                row = pi_scaled[e, m]
                for c in range(n_concepts):
                    s[c] += row[c] * rm
            top = -np.inf
            ok = True
            for c in range(n_concepts):
                ok &= s[c] > 1e-250
                value = log_g[e, c] + concept_ll[t, c] + pi_row_max[e, c]
                log_c[i * n_concepts + c] = value
                top = max(top, value)
            tops[i] = top
            linear[i] = ok
            for c in range(n_concepts):
                shifted[i * n_concepts + c] = log_c[i * n_concepts + c] - top
        weights_c = np.empty(size * n_concepts)
        _scaled_exp(shifted[:size * n_concepts], 1.0, weights_c, powers[:size * n_concepts])
        weights = np.empty(n_regions)
        for i in range(size):
            t = first + i
            e = homes[t]
            s = sums[i * n_concepts:(i + 1) * n_concepts]
            w = weights_c[i * n_concepts:(i + 1) * n_concepts]
            lc = log_c[i * n_concepts:(i + 1) * n_concepts]
            if linear[i]:  # weights exp(log G + loglik + max log π − top) · sum: no logarithm
                acc = 0.0  # (the largest weight is ≥ 1e-250 times the largest sum: no underflow)
                for c in range(n_concepts):
                    w[c] *= s[c]
                    acc += w[c]
                chosen = _draw_linear(w, acc, u_concept[t])
            else:  # some sum too small for the dot product: exact log-sum-exps
                for c in range(n_concepts):
                    if s[c] > 1e-250:
                        log_sum = np.log(s[c])
                    else:
                        for m in range(n_regions):  # (the weights array is free until R | C)
                            weights[m] = log_pi[e, c, m] - pi_row_max[e, c] + region_ll[t, m] - r_max[i]
                        inner_top = weights.max()
                        inner = 0.0
                        for m in range(n_regions):
                            inner += np.exp(weights[m] - inner_top)
                        log_sum = inner_top + np.log(inner)
                    lc[c] += log_sum
                chosen = _draw_log(lc, u_concept[t])
            # R | C: the weights π_{C,m} N(x | m) of the dot product above, or in log space when it
            # underflowed
            if s[chosen] > 1e-250:
                for m in range(n_regions):
                    weights[m] = pi_scaled[e, m, chosen] * r[i * n_regions + m]
                region = _draw_linear(weights, s[chosen], u_region[t])
            else:
                for m in range(n_regions):
                    weights[m] = log_pi[e, chosen, m] + region_ll[t, m]
                region = _draw_log(weights, u_region[t])
            out[t] = chosen * n_regions + region
    return out


@njit(cache=True)
def _draw_linear(weights: np.ndarray, total: float, u: float) -> int:
    """Index drawn from non-negative ``weights`` summing to ``total`` with the uniform ``u``
    (never an index of weight 0)."""
    target = u * total
    acc = 0.0
    last = 0
    for j in range(weights.size):
        if weights[j] > 0.0:
            acc += weights[j]
            last = j
            if acc > target:
                return j
    return last


def sample_joint_assignment(log_g: np.ndarray, log_pi: np.ndarray, homes: np.ndarray,
                            concept_ll: np.ndarray, region_ll: np.ndarray,
                            rng: np.random.Generator) -> np.ndarray:
    """Flat index C·K + R of one draw per sample from
    p(C=l, R=m) ∝ exp(log_g[e,l] + log_pi[e,l,m] + concept_ll[t,l] + region_ll[t,m]), e = homes[t].

    Shapes: log_g (E, L), log_pi (E, L, K), homes (N,), concept_ll (N, L), region_ll (N, K).
    Drawn as C from its marginal (Σ over regions), then R | C, row by row without materialising
    the (N, L, K) table; the sum over regions is a dot product of exp-scaled factors, with an
    exact log-sum-exp wherever that product would underflow.
    """
    u = rng.random((2, homes.shape[0]))
    log_pi = np.ascontiguousarray(log_pi, dtype=np.float64)
    pi_row_max = log_pi.max(axis=2)
    pi_scaled = np.ascontiguousarray(np.swapaxes(np.exp(log_pi - pi_row_max[:, :, None]), 1, 2))
    return _joint_assignment(np.ascontiguousarray(log_g, dtype=np.float64), log_pi, pi_scaled, pi_row_max,
                             np.ascontiguousarray(homes, dtype=np.int64),
                             np.ascontiguousarray(concept_ll, dtype=np.float64),
                             np.ascontiguousarray(region_ll, dtype=np.float64), u[0], u[1])


# ----------------------------------------------------------------------------- sparse helpers


#: Columns of a likelihood table are processed in blocks of this many lanes (4 AVX2 registers).
LANES = 16


@njit(parallel=True, cache=True)
def _blocked_sparse_dot(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray,
                        table: np.ndarray, width: int) -> np.ndarray:
    out = np.empty((indptr.size - 1, width))
    for t in prange(indptr.size - 1):
        _blocked_sparse_row(indptr, indices, data, groups, table, width, t, out)
    return out


@njit(cache=True)
def _blocked_sparse_dot_serial(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray,
                               table: np.ndarray, width: int) -> np.ndarray:
    # _blocked_sparse_dot on one thread, for few non-zeros (the word counts)
    out = np.empty((indptr.size - 1, width))
    for t in range(indptr.size - 1):
        _blocked_sparse_row(indptr, indices, data, groups, table, width, t, out)
    return out


@njit(cache=True, inline="always")
def _blocked_sparse_row(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray,
                        table: np.ndarray, width: int, t: int, out: np.ndarray) -> None:
    # table (G, B, D, 16): sixteen independent accumulators per block of columns, each summed in
    # the order of the row's entries (the same sums as a column-by-column loop, bit for bit);
    # written out lane by lane so that LLVM's SLP vectoriser turns them into 4-wide operations
    g = groups[t]
    for b in range(table.shape[1]):
        block = table[g, b]
        a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
        a8 = a9 = a10 = a11 = a12 = a13 = a14 = a15 = 0.0
        for p in range(indptr[t], indptr[t + 1]):
            row = block[indices[p]]
            v = np.float64(data[p])
            a0 += v * row[0]
            a1 += v * row[1]
            a2 += v * row[2]
            a3 += v * row[3]
            a4 += v * row[4]
            a5 += v * row[5]
            a6 += v * row[6]
            a7 += v * row[7]
            a8 += v * row[8]
            a9 += v * row[9]
            a10 += v * row[10]
            a11 += v * row[11]
            a12 += v * row[12]
            a13 += v * row[13]
            a14 += v * row[14]
            a15 += v * row[15]
        sums = (a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12, a13, a14, a15)
        for c in range(LANES):
            if b * LANES + c < width:
                out[t, b * LANES + c] = sums[c]


@njit(parallel=True, cache=True)
def _likelihood_table(values: np.ndarray, floor: float) -> np.ndarray:
    groups, rows, width = values.shape
    n_blocks = (rows + LANES - 1) // LANES
    out = np.empty((groups, n_blocks, width, LANES))
    for i in prange(groups * n_blocks):
        _table_block(values, floor, out, i)
    return out


@njit(cache=True)
def _likelihood_table_serial(values: np.ndarray, floor: float) -> np.ndarray:
    # _likelihood_table on one thread, for small tables (the words)
    groups, rows, width = values.shape
    n_blocks = (rows + LANES - 1) // LANES
    out = np.empty((groups, n_blocks, width, LANES))
    for i in range(groups * n_blocks):
        _table_block(values, floor, out, i)
    return out


@njit(cache=True, inline="always")
def _table_block(values: np.ndarray, floor: float, out: np.ndarray, i: int) -> None:
    n_blocks = out.shape[1]
    g, b = i // n_blocks, i % n_blocks
    _fill_table_block(values, floor, g, b, out[g, b])


@njit(cache=True, inline="always")
def _fill_table_block(values: np.ndarray, floor: float, g: int, b: int, block: np.ndarray) -> None:
    # block (W, 16) ← rows 16b..16b+15 of values[g] (R, W), transposed, clipped below at the floor,
    # zero past the last row: one block of the likelihood table
    rows, width = values.shape[1], values.shape[2]
    for k in range(width):
        for lane in range(LANES):
            r = b * LANES + lane
            if r < rows:
                v = values[g, r, k]
                block[k, lane] = v if v > floor else floor
            else:
                block[k, lane] = 0.0


def likelihood_table(log_probabilities: np.ndarray, floor: float) -> np.ndarray:
    """The table :func:`blocked_sparse_dot` reads, from log-probabilities of shape (G, R, W) (log θ
    of shape (E, L, D)): entries clipped below at ``floor``, the last two axes swapped, and the R
    rows split into blocks of :data:`LANES` (zero-padded): shape (G, ⌈R/16⌉, W, 16)."""
    values = np.ascontiguousarray(log_probabilities, dtype=np.float64)
    kernel = _likelihood_table if values.size >= _PARALLEL_MIN else _likelihood_table_serial
    return kernel(values, float(floor))


def blocked_sparse_dot(matrix, groups: np.ndarray, table: np.ndarray, width: int) -> np.ndarray:
    """Row t of a CSR ``matrix`` (n, D) times the table of its group, for every row: (n, ``width``).

    ``table`` comes from :func:`likelihood_table` (``width`` its number of rows R). This is the
    visual and word log-likelihood of every sample under every concept of its own home:
    counts · log θᵀ, in float64."""
    args = (_as(matrix.indptr, np.int64), _index_array(matrix.indices), _value_array(matrix.data),
            _as(groups, np.int64), np.ascontiguousarray(table, dtype=np.float64), int(width))
    kernel = _blocked_sparse_dot if matrix.nnz >= _PARALLEL_MIN else _blocked_sparse_dot_serial
    return _call_vectorised(kernel, args)


@dataclass(frozen=True, eq=False)
class DimensionMajorCounts:
    """A CSR count matrix whose rows come in blocks (the homes: block e holds rows
    offsets[e]:offsets[e+1]) regrouped by block and then by column: the entries of column k in
    block e are ``rows``/``values``[colptr[e, k]:colptr[e, k + 1]], rows ascending and numbered
    within their block (row offsets[e] + rows[p] of the matrix). The layout of
    :func:`dimension_major_dot`; built once per fit by :func:`dimension_major`."""

    colptr: np.ndarray  # (E, D + 1) int64, positions in rows/values
    rows: np.ndarray  # (nnz,) row numbers within the block: uint16 (blocks below 65,536 rows) or int64
    values: np.ndarray  # (nnz,) the counts, float32 (exact below 2^24) or float64 as in the CSR
    offsets: np.ndarray  # (E + 1,) int64

    @property
    def n_rows(self) -> int:
        """The number of rows of the matrix."""
        return int(self.offsets[-1])

    @cached_property
    def _parts_by_count(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        return {}

    def parts(self, n_parts: int) -> tuple[np.ndarray, np.ndarray]:
        """The blocks split into ``n_parts`` parts of nearly equal non-zeros
        (:func:`_balanced_parts`), computed once per number of parts."""
        if n_parts not in self._parts_by_count:
            self._parts_by_count[n_parts] = _balanced_parts(self.colptr[:, -1] - self.colptr[:, 0], n_parts)
        return self._parts_by_count[n_parts]


@njit(cache=True)
def _dimension_major(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, offsets: np.ndarray,
                     colptr: np.ndarray, rows: np.ndarray, values: np.ndarray) -> None:
    n_blocks = offsets.size - 1
    width = colptr.shape[1] - 1
    for e in range(n_blocks):  # entries per (block, column)
        for t in range(offsets[e], offsets[e + 1]):
            for p in range(indptr[t], indptr[t + 1]):
                colptr[e, indices[p] + 1] += 1
    running = 0
    for e in range(n_blocks):  # positions: blocks one after the other, columns within each
        colptr[e, 0] = running
        for k in range(width):
            running += colptr[e, k + 1]
            colptr[e, k + 1] = running
    free = colptr[:, :width].copy()
    for e in range(n_blocks):  # rows in increasing order: ascending within every column
        for t in range(offsets[e], offsets[e + 1]):
            for p in range(indptr[t], indptr[t + 1]):
                k = indices[p]
                q = free[e, k]
                rows[q] = t - offsets[e]
                values[q] = data[p]
                free[e, k] = q + 1


def dimension_major(matrix: sp.csr_array, offsets: np.ndarray) -> DimensionMajorCounts:
    """The :class:`DimensionMajorCounts` of a CSR ``matrix`` (n, D) whose rows are in blocks
    ``offsets`` (E + 1 increasing row numbers from 0 to n). The values keep the matrix's type
    (float32 from :func:`stack_counts`); the row numbers, within each block, take two bytes when
    every block has fewer than 65,536 rows: 6 bytes per non-zero with float32 counts (14 MB for
    the 2.4 M visual non-zeros of 16 + 1 SIGVerse homes)."""
    offsets = _as(offsets, np.int64)
    n, width = matrix.shape
    if offsets.ndim != 1 or offsets.size < 1 or offsets[0] != 0 or offsets[-1] != n or np.any(
            np.diff(offsets) < 0):
        raise ValueError(f"offsets must rise from 0 to the matrix's {n} rows")
    values_in = _value_array(matrix.data)
    nnz = int(matrix.indptr[-1])
    colptr = np.zeros((offsets.size - 1, width + 1), dtype=np.int64)
    largest_block = int(np.diff(offsets).max()) if offsets.size > 1 else 0
    rows = np.empty(nnz, dtype=np.uint16 if largest_block <= np.iinfo(np.uint16).max + 1 else np.int64)
    values = np.empty(nnz, dtype=values_in.dtype)
    _dimension_major(_as(matrix.indptr, np.int64), _index_array(matrix.indices), values_in, offsets, colptr,
                     rows, values)
    return DimensionMajorCounts(colptr=colptr, rows=rows, values=values, offsets=offsets)


@njit(parallel=True, cache=True)
def _dimension_major_dot(colptr: np.ndarray, rows: np.ndarray, values: np.ndarray, offsets: np.ndarray,
                         log_p: np.ndarray, floor: float, home_order: np.ndarray,
                         part_starts: np.ndarray) -> np.ndarray:
    # home by home, in parallel: the home's log-probabilities (R, D) are first laid out as a
    # table of sixteen lanes per column (clipped at the floor, zero-padded; what
    # likelihood_table builds for all homes, here one home at a time in the thread's cache);
    # then, for each column, its table row is read once and added, times each entry's count, to
    # that entry's row of sixteen accumulators (a home's accumulators stay in the L1 cache). Each
    # sum runs over the row's entries in column order, as in _blocked_sparse_dot: the same
    # results, bit for bit.
    n_rows = log_p.shape[1]
    n_blocks = (n_rows + LANES - 1) // LANES
    out = np.empty((offsets[-1], n_rows))
    for part in prange(part_starts.size - 1):  # one part per thread, homes balanced by non-zeros
        for position in range(part_starts[part], part_starts[part + 1]):
            _dimension_major_home(colptr, rows, values, offsets, log_p, floor, home_order[position], n_blocks,
                                  out)
    return out


@njit(cache=True, inline="always")
def _dimension_major_home(colptr: np.ndarray, rows: np.ndarray, values: np.ndarray, offsets: np.ndarray,
                          log_p: np.ndarray, floor: float, e: int, n_blocks: int, out: np.ndarray) -> None:
    # one home: its table of sixteen lanes per column, then the column-by-column accumulation
    n_rows, n_columns = log_p.shape[1], log_p.shape[2]
    start = offsets[e]
    acc = np.empty((offsets[e + 1] - start, LANES))
    block = np.empty((n_columns, LANES))
    for b in range(n_blocks):
        _fill_table_block(log_p, floor, e, b, block)
        acc[:] = 0.0
        for k in range(n_columns):
            row = block[k]
            r0, r1, r2, r3 = row[0], row[1], row[2], row[3]
            r4, r5, r6, r7 = row[4], row[5], row[6], row[7]
            r8, r9, r10, r11 = row[8], row[9], row[10], row[11]
            r12, r13, r14, r15 = row[12], row[13], row[14], row[15]
            for p in range(colptr[e, k], colptr[e, k + 1]):
                o = acc[np.int64(rows[p])]
                v = np.float64(values[p])
                o[0] += v * r0
                o[1] += v * r1
                o[2] += v * r2
                o[3] += v * r3
                o[4] += v * r4
                o[5] += v * r5
                o[6] += v * r6
                o[7] += v * r7
                o[8] += v * r8
                o[9] += v * r9
                o[10] += v * r10
                o[11] += v * r11
                o[12] += v * r12
                o[13] += v * r13
                o[14] += v * r14
                o[15] += v * r15
        for t in range(acc.shape[0]):
            for c in range(LANES):
                if b * LANES + c < n_rows:
                    out[start + t, b * LANES + c] = acc[t, c]


def _balanced_parts(loads: np.ndarray, n_parts: int) -> tuple[np.ndarray, np.ndarray]:
    """Items split into ``n_parts`` parts of nearly equal total load (largest first, each to the
    least loaded part): the items in part order and the parts' start positions."""
    n_parts = max(1, min(n_parts, loads.size))
    totals = np.zeros(n_parts)
    members: list[list[int]] = [[] for _ in range(n_parts)]
    for item in np.argsort(-loads, kind="stable"):
        part = int(np.argmin(totals))
        members[part].append(int(item))
        totals[part] += loads[item]
    order = np.array([i for m in members for i in sorted(m)], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum([len(m) for m in members])]).astype(np.int64)
    return order, starts


def dimension_major_dot(counts: DimensionMajorCounts, log_probabilities: np.ndarray,
                        floor: float) -> np.ndarray:
    """Row t of the counts times the log-probabilities of its block (home), clipped below at
    ``floor``, for every row: (n, R) from ``log_probabilities`` (E, R, D) — what
    :func:`blocked_sparse_dot` computes from :func:`likelihood_table`, bit for bit, from the
    :class:`DimensionMajorCounts` layout: each home's table is built in the thread's cache and
    each of its rows read once per home instead of once per entry."""
    log_p = np.ascontiguousarray(log_probabilities, dtype=np.float64)
    n_blocks, n_columns = counts.colptr.shape[0], counts.colptr.shape[1] - 1
    if log_p.ndim != 3 or log_p.shape[0] != n_blocks or log_p.shape[2] != n_columns:
        raise ValueError(f"log-probabilities of shape {log_p.shape} do not fit counts of {n_blocks} blocks "
                         f"and {n_columns} columns")
    order, starts = counts.parts(get_num_threads())
    args = (counts.colptr, counts.rows, counts.values, counts.offsets, log_p, float(floor), order, starts)
    return _call_vectorised(_dimension_major_dot, args)


def grouped_sparse_dot(matrix, groups: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Row t of a CSR ``matrix`` (n, D) times ``table[groups[t]]`` (D, W), for every row: (n, W).

    ``table`` has shape (G, D, W). The same kernel as :func:`blocked_sparse_dot`, which the
    sampler calls with a table it builds once per sweep."""
    table = np.asarray(table, dtype=np.float64)
    blocked = likelihood_table(np.swapaxes(table, 1, 2), -np.inf)
    return blocked_sparse_dot(matrix, groups, blocked, table.shape[2])


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
    return kernel(*args)


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


#: Counts up to this value are exact in float32 (2^24), the value type of :func:`stack_counts`.
FLOAT32_EXACT = 2**24


def stack_counts(*blocks) -> sp.csr_array:
    """The row blocks ``blocks`` (sparse or dense counts with equal numbers of columns) stacked
    into one CSR array in the compact layout of the compiled kernels: float32 values (whole
    numbers below 2^24, exact in float32; larger counts keep float64), int32 column indices,
    int64 row pointers. The kernels multiply in float64, so the layout changes no result; it
    halves the memory of the visual counts of a fit (2.4 M non-zeros for 16 + 1 SIGVerse homes).

    Each output array is allocated once at its final size and filled block by block: no stacked
    intermediate, no second converted copy. The result shares no memory with the blocks, which are
    not modified.
    """
    blocks_csr = [b if isinstance(b, sp.csr_array) else sp.csr_array(b) for b in blocks]
    n_columns = blocks_csr[0].shape[1]
    if any(b.shape[1] != n_columns for b in blocks_csr):
        raise ValueError("the blocks of counts have different numbers of columns")
    n_rows = sum(b.shape[0] for b in blocks_csr)
    nnz = sum(int(b.indptr[-1]) for b in blocks_csr)
    largest = max((float(np.abs(b.data).max()) for b in blocks_csr if b.nnz), default=0.0)
    data = np.empty(nnz, dtype=np.float32 if largest < FLOAT32_EXACT else np.float64)
    indices = np.empty(nnz, dtype=np.int32 if n_columns < 2**31 else np.int64)
    indptr = np.empty(n_rows + 1, dtype=np.int64)
    indptr[0] = row = start = 0
    for b in blocks_csr:
        n, stop = b.shape[0], start + int(b.indptr[-1])
        data[start:stop] = b.data[: stop - start]
        indices[start:stop] = b.indices[: stop - start]
        np.add(b.indptr[1:], start, out=indptr[row + 1: row + 1 + n])
        row, start = row + n, stop
    out = sp.csr_array((n_rows, n_columns), dtype=data.dtype)  # empty; its arrays are replaced (the
    out.data, out.indices, out.indptr = data, indices, indptr  # constructor would choose the types)
    return out


@njit(cache=True)
def _grouped_moments(x: np.ndarray, groups: np.ndarray, count: np.ndarray, total: np.ndarray,
                     scatter: np.ndarray) -> None:
    for t in range(x.shape[0]):
        g = groups[t]
        count[g] += 1.0
        for i in range(x.shape[1]):
            total[g, i] += x[t, i]
            for j in range(x.shape[1]):
                scatter[g, i, j] += x[t, i] * x[t, j]


def grouped_moments(x: np.ndarray, groups: np.ndarray,
                    n_groups: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Count, Σ x and Σ x xᵀ of the rows of ``x`` (n, d) in each group (``groups`` (n,) in
    0..n_groups−1): shapes (G,), (G, d), (G, d, d); summed in row order, one pass."""
    x = _as(x, np.float64)
    count = np.zeros(n_groups)
    total = np.zeros((n_groups, x.shape[1]))
    scatter = np.zeros((n_groups, x.shape[1], x.shape[1]))
    _grouped_moments(x, _as(groups, np.int64), count, total, scatter)
    return count, total, scatter


@njit(parallel=True, cache=True)
def _grouped_row_sums(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray,
                      chunks: np.ndarray, out: np.ndarray) -> None:
    # rows chunks[i]:chunks[i+1] write to groups no other chunk writes to, so chunks run in parallel
    for i in prange(chunks.size - 1):
        _add_rows(indptr, indices, data, groups, chunks[i], chunks[i + 1], out)


@njit(cache=True, inline="always")
def _add_rows(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray, first: int,
              stop: int, out: np.ndarray) -> None:
    for t in range(first, stop):
        g = groups[t]
        for p in range(indptr[t], indptr[t + 1]):
            out[g, indices[p]] += np.int64(data[p])


@njit(cache=True)
def _row_sums_serial(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray,
                     out: np.ndarray) -> None:
    # _grouped_row_sums on one thread, for few non-zeros
    _add_rows(indptr, indices, data, groups, 0, indptr.size - 1, out)


def grouped_row_sums(matrix, groups: np.ndarray, n_groups: int,
                     blocks: np.ndarray | None = None) -> np.ndarray:
    """Sum of the rows of a CSR ``matrix`` (n, D) within each group: returns (n_groups, D) int64.

    Used for the count statistics n^v_{e,l,·} and n^w_{e,l,·} (group = e·L + l). ``blocks``
    (optional, (n,) non-decreasing) splits the rows into runs such that no two runs share a group
    (e.g. the home of each row, rows sorted by home); the runs are summed in parallel.
    """
    out = np.zeros((n_groups, matrix.shape[1]), dtype=np.int64)
    n = matrix.shape[0]
    if matrix.nnz < _PARALLEL_MIN:
        _row_sums_serial(_as(matrix.indptr, np.int64), _index_array(matrix.indices),
                         _value_array(matrix.data), _as(groups, np.int64), out)
        return out
    if blocks is not None and n > 1 and np.all(blocks[1:] >= blocks[:-1]):
        chunks = np.concatenate([[0], np.flatnonzero(blocks[1:] != blocks[:-1]) + 1, [n]]).astype(np.int64)
    else:
        chunks = np.array([0, n], dtype=np.int64)
    _grouped_row_sums(_as(matrix.indptr, np.int64), _index_array(matrix.indices),
                      _value_array(matrix.data), _as(groups, np.int64), chunks, out)
    return out


@njit(cache=True)
def move_rows(n: np.ndarray, indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, rows: np.ndarray,
              homes: np.ndarray, old: np.ndarray, new: np.ndarray) -> None:
    """n[homes[i], old[i], :] −= row rows[i] of a CSR matrix and n[homes[i], new[i], :] += it, for
    every i (integer counts, exact). ``n`` has shape (E, L, D), int64."""
    for i in range(rows.size):
        t, e, a, b = rows[i], homes[i], old[i], new[i]
        if a == b:
            continue
        for p in range(indptr[t], indptr[t + 1]):
            k = indices[p]
            v = np.int64(data[p])
            n[e, a, k] -= v
            n[e, b, k] += v
