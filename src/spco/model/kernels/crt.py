"""Table counts of the Chinese restaurant process, m ~ CRT(n, a) (Antoniak).

Exact Bernoulli sums for small n, a moment-matched normal for the tail of large n.
:func:`sample_crt` draws every entry; :func:`sample_crt_totals` their sums over homes directly, as
the shared parameters need.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spco.model.kernels.dispatch import _PARALLEL_MIN, _call_in_parts
from spco.model.kernels.normal import _stream_normal
from spco.model.kernels.rng import _stream_next, _stream_start
from spco.model.kernels.special import (
    _digamma,
    _digamma_large,
    _digamma_large_minus_log,
    _trigamma,
    _trigamma_large,
)


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


@njit(cache=True, nogil=True, error_model="numpy")
def _crt_entries(counts: np.ndarray, conc: np.ndarray, seed: np.uint64, exact_max: int, head: int,
                 out: np.ndarray, first: int, stop: int) -> None:
    """:func:`sample_crt` of entries first..stop−1 into ``out``, entry j on the stream j: the same
    draws whichever thread runs which entries (:func:`_call_in_parts`)."""
    for j in range(first, stop):
        out[j] = _crt_entry(counts[j], conc[j], seed, exact_max, head, j)


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
    out = np.zeros(flat_n.size, dtype=np.int64)
    _call_in_parts(_crt_entries, (flat_n, flat_a, seed, int(exact_max), int(head), out), flat_n.size,
                   parallel=flat_n.size >= _PARALLEL_MIN // 8)
    return out.reshape(counts.shape)


@njit(cache=True, nogil=True, error_model="numpy")
def _crt_totals_rows(counts: np.ndarray, conc: np.ndarray, seed: np.uint64, exact_max: int, out: np.ndarray,
                     first: int, stop: int) -> None:
    """:func:`sample_crt_totals` of rows first..stop−1 into ``out``, column k of row r on the stream
    r·width + k: the same draws whichever thread runs which rows (:func:`_call_in_parts`)."""
    for r in range(first, stop):
        _crt_totals_row(counts, conc, seed, exact_max, r, out[r])


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
    # column k's stream starts at its first draw (0: not started; a started state is never 0): a
    # column without Bernoulli terms never draws, and most columns of one home's counts have none
    states = np.zeros(width, dtype=np.uint64)
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
            if state == 0:
                state = _stream_start(seed, np.uint64(r * width + k))
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
        state = states[k]
        if state == 0:
            state = _stream_start(seed, np.uint64(r * width + k))
        _, extra = _bernoulli_sum_moment_matched(terms[k], mean, var, state)
        opened[k] += extra


@njit(cache=True, nogil=True, error_model="numpy")
def _crt_totals_rows_each(counts: np.ndarray, conc: np.ndarray, seeds: np.ndarray, exact_max: int,
                          out: np.ndarray, first: int, stop: int) -> None:
    """:func:`sample_crt_totals_each` of rows first..stop−1 into ``out``: for each group g its own
    :func:`_crt_totals_row` pass with ``seeds[g]``, added up."""
    for r in range(first, stop):
        for g in range(counts.shape[0]):
            _crt_totals_row(counts[g:g + 1], conc, seeds[g], exact_max, r, out[r])


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
    if counts.flags.writeable:  # a read-only view (no copy): one compiled signature, whoever owns counts
        counts = counts.view()
        counts.flags.writeable = False
    out = np.zeros((counts.shape[1], counts.shape[2]), dtype=np.int64)
    _call_in_parts(_crt_totals_rows, (counts, conc, seed, int(exact_max), out), counts.shape[1],
                   counts.size >= _PARALLEL_MIN)
    return out


def sample_crt_totals_each(counts: np.ndarray, concentration: np.ndarray, seeds: np.ndarray,
                           exact_max: int = 40) -> np.ndarray:
    """Σ_g of :func:`sample_crt_totals` of each group alone, group g drawn from ``seeds[g]``: the
    sum, bit for bit, of the calls ``sample_crt_totals(counts[g:g + 1], concentration, rng_g)``
    where ``rng_g`` gives ``seeds[g]`` — the table counts of homes that each draw from their own
    stream (:class:`~spco.model.shard_group.ShardGroup`), in one call.

    Parameters
    ----------
    counts: (G, R, W) integer counts n ≥ 0; concentration: (R, W) a ≥ 0; seeds: (G,) uint64.

    Returns
    -------
    (R, W) int64 table counts summed over the G groups.
    """
    counts = np.ascontiguousarray(counts, dtype=np.int64)
    if counts.ndim != 3 or len(seeds) != counts.shape[0]:
        raise ValueError("sample_crt_totals_each needs counts (groups, rows, width) and a seed per group")
    conc = np.ascontiguousarray(np.broadcast_to(concentration, counts.shape[1:]), dtype=np.float64)
    if counts.flags.writeable:  # a read-only view (no copy), as sample_crt_totals passes it
        counts = counts.view()
        counts.flags.writeable = False
    out = np.zeros((counts.shape[1], counts.shape[2]), dtype=np.int64)
    _call_in_parts(_crt_totals_rows_each, (counts, conc, np.asarray(seeds, dtype=np.uint64), int(exact_max),
                                           out), counts.shape[1], counts.size >= _PARALLEL_MIN)
    return out
