"""The sampler's random primitives against their exact distributions (spco.model.kernels).

Every statistical test runs at a fixed seed, so it is deterministic; thresholds (p > 1e-3, |z| < 4)
are loose enough for a correct sampler and tight enough to catch a wrong formula (a wrong mean,
variance, degrees of freedom or normalisation moves these statistics by tens of standard errors
at the sample sizes used).
"""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
import scipy.sparse as sp
from numpy.testing import assert_allclose, assert_array_equal
from scipy import stats
from scipy.special import gammainc, gammaln, logsumexp, softmax

from spco.model.kernels.categorical import sample_categorical_log, sample_joint_assignment
from spco.model.kernels.counts import grouped_row_sums
from spco.model.kernels.crt import sample_crt
from spco.model.kernels.dirichlet import dirichlet_log_density, log_dirichlet
from spco.model.kernels.gamma import log_gamma_variates
from spco.model.kernels.gaussian import grouped_gaussian_log_density
from spco.model.kernels.likelihood import grouped_sparse_dot
from spco.model.kernels.niw import niw_posterior, sample_niw

P_MIN = 1e-3
Z_MAX = 4.0


# ----------------------------------------------------------------------------- helpers


def z_mean(samples: np.ndarray, mean: np.ndarray | float, var: np.ndarray | float,
           axis: int = 0) -> np.ndarray:
    """z-scores of sample means against exact means and variances."""
    n = samples.shape[axis]
    return (samples.mean(axis=axis) - mean) / np.sqrt(np.asarray(var) / n)


def z_variance(samples: np.ndarray, var: np.ndarray | float, axis: int = 0) -> np.ndarray:
    """z-scores of sample variances against exact variances (SE from the sample fourth moment)."""
    n = samples.shape[axis]
    centred = samples - samples.mean(axis=axis, keepdims=True)
    m2 = (centred**2).mean(axis=axis)
    m4 = (centred**4).mean(axis=axis)
    se = np.sqrt(np.maximum(m4 - m2**2, 1e-300) / n)
    return (samples.var(axis=axis, ddof=1) - var) / se


def chisquare_counts(observed: np.ndarray, probs: np.ndarray, min_expected: float = 5.0) -> float:
    """p-value of a chi-square goodness-of-fit test, pooling cells with small expected counts."""
    observed = np.asarray(observed, dtype=float)
    expected = np.asarray(probs, dtype=float) * observed.sum()
    # anything observed where the probability is 0 is an outright failure
    assert observed[expected == 0].sum() == 0, "draws in a cell of probability 0"
    keep = expected >= min_expected
    obs = list(observed[keep])
    exp = list(expected[keep])
    if (~keep).any():
        obs.append(observed[~keep].sum())
        exp.append(expected[~keep].sum())
    obs_a, exp_a = np.array(obs), np.array(exp)
    if exp_a[-1] < min_expected and len(exp_a) > 1:  # fold a small pooled cell into the smallest other
        obs_a[-2] += obs_a[-1]
        exp_a[-2] += exp_a[-1]
        obs_a, exp_a = obs_a[:-1], exp_a[:-1]
    if len(obs_a) < 2:
        return 1.0
    return float(stats.chisquare(obs_a, exp_a * obs_a.sum() / exp_a.sum()).pvalue)


def poisson_binomial_pmf(probs: np.ndarray) -> np.ndarray:
    """Exact pmf of a sum of independent Bernoulli(p_i) (dynamic programming)."""
    pmf = np.zeros(probs.size + 1)
    pmf[0] = 1.0
    for i, p in enumerate(probs):
        pmf[1:i + 2] = pmf[1:i + 2] * (1 - p) + pmf[:i + 1] * p
        pmf[0] *= 1 - p
    return pmf


def crt_probs(n: int, a: float) -> np.ndarray:
    """Success probabilities a/(a+i), i = 0..n-1, of the CRT(n, a) Bernoulli sum."""
    return a / (a + np.arange(n))


def log_gamma_cdf(y: np.ndarray, a: float) -> np.ndarray:
    """P(log G <= y) for G ~ Gamma(a, 1), exact also where exp(y) underflows.

    For x = exp(y) < 1e-250, P(G <= x) = x^a / Γ(a + 1) · (1 + O(x)), computed in log space.
    """
    y = np.asarray(y, dtype=float)
    out = np.empty_like(y)
    tiny = y < np.log(1e-250)
    out[tiny] = np.exp(a * y[tiny] - gammaln(a + 1.0))
    out[~tiny] = gammainc(a, np.exp(y[~tiny]))
    return out


def random_spd(rng: np.random.Generator, d: int, scale: float = 1.0) -> np.ndarray:
    a = rng.normal(size=(d, d))
    return scale * (a @ a.T / d + 0.5 * np.eye(d))


# ----------------------------------------------------------------------------- gamma and Dirichlet


@pytest.mark.parametrize("shape", [1e-3, 0.05, 0.7, 1.0, 3.5, 50.0])
def test_log_gamma_variates_match_gamma_distribution(shape: float) -> None:
    rng = np.random.default_rng(1)
    draws = log_gamma_variates(np.full(20_000, shape), rng)
    assert np.isfinite(draws).all()
    result = stats.kstest(draws, lambda y: log_gamma_cdf(y, shape))
    assert result.pvalue > P_MIN, result


def test_vectorised_log_is_within_one_ulp_of_numpy() -> None:
    """The Dirichlet kernels' in-place log (fdlibm's algorithm in branch-free loops) against
    np.log: 1 M values spread over the whole range of normal doubles, plus the awkward ones; then
    with the shift the kernels subtract (the row's log total)."""
    from spco.model.kernels.special import _log_minus

    rng = np.random.default_rng(35)
    values = np.exp(rng.uniform(-700.0, 709.0, 1_000_000))
    values[:8] = [1.0, 2.0, 0.5, np.sqrt(2.0), np.sqrt(0.5), 1.0 - 2**-52, 1.0 + 2**-52,
                  2.2250738585072014e-308]  # the smallest normal double
    expected = np.log(values)
    got = values.copy()
    _log_minus(got, 0.0, np.empty(got.size))
    ulp = np.abs(got - expected) / np.spacing(np.maximum(np.abs(expected), 2**-1074))
    assert ulp.max() <= 1.0
    assert got[0] == 0.0 and got[1] == np.log(2.0)
    shifted = values.copy()
    _log_minus(shifted, 3.25, np.empty(shifted.size))
    assert_allclose(shifted, expected - 3.25, rtol=0, atol=4 * np.spacing(np.abs(expected).max()))


def test_vectorised_exp_sum_matches_numpy() -> None:
    """The Dirichlet rows' sum of exponentials (boosted entries) against np.exp: values over the
    whole range used, including ones that underflow (counted as 0) and large positive ones."""
    from spco.model.kernels.special import _sum_exp

    rng = np.random.default_rng(36)
    for values in (rng.uniform(-30.0, 5.0, 100_000), rng.uniform(-800.0, 700.0, 100_000),
                   np.array([0.0, np.log(2.0), -708.5, -1e300, 709.0, -0.5 * np.log(2.0)])):
        expected = math.fsum(np.exp(values[values >= -708.0]))  # exact sum of the exact terms
        got = _sum_exp(values, np.empty(values.size), np.empty(values.size))
        assert got == pytest.approx(expected, rel=1e-11)  # each term within 1 ulp, summed in order
        head = values[:200]
        singles = np.array([_sum_exp(head[j:j + 1], np.empty(1), np.empty(1)) for j in range(head.size)])
        reference = np.where(head >= -708.0, np.exp(head), 0.0)
        assert (np.abs(singles - reference) <= np.spacing(reference)).all()
    assert _sum_exp(np.array([0.0]), np.empty(1), np.empty(1)) == 1.0


def _row_log_gammas(shape: np.ndarray, seed: int, normalise: bool = False) -> np.ndarray:
    """The Dirichlet kernels' row function on one row (compiled as the kernels compile it)."""
    from spco.model.kernels.dispatch import _call_vectorised
    from spco.model.kernels.gamma import _log_gamma_row, _row_scratch

    out = np.empty(shape.size)
    _call_vectorised(_log_gamma_row, (np.ascontiguousarray(shape, dtype=np.float64), out, np.uint64(seed),
                                      0, normalise, _row_scratch(shape.size)))
    return out


@pytest.mark.parametrize("shape", [1e-4, 0.02, 0.3, 0.7, 0.999])
def test_dirichlet_rows_small_shapes_match_gamma_distribution(shape: float) -> None:
    """The gamma variates of the Dirichlet kernels for shapes below 1 (boosted, G(a + 1) U^{1/a}
    in log space): the logarithms follow the log-gamma law, including where the variate
    underflows (shape 1e-4: log G < −690 with probability ~0.93)."""
    logs = _row_log_gammas(np.full(20_000, shape), 987654321)
    assert np.isfinite(logs).all()
    assert (logs < -745.0).any() == (shape < 1e-3)
    result = stats.kstest(logs, lambda y: log_gamma_cdf(y, shape))
    assert result.pvalue > P_MIN, result


@pytest.mark.parametrize("shape", [1.0, 1.7, 3.5, 50.0, 4000.0])
def test_dirichlet_rows_large_shapes_match_gamma_distribution(shape: float) -> None:
    """Shapes ≥ 1 in the row function's vectorised passes (ziggurat first step, squeeze, the
    logarithmic test, then the one-by-one continuation): 200,000 variates follow Gamma(a), so
    that a wrong treatment of the ≈ 2 % of draws that leave the fast path would show."""
    logs = _row_log_gammas(np.full(200_000, shape), 11 + int(shape))
    assert np.isfinite(logs).all()
    assert stats.kstest(logs, lambda y: log_gamma_cdf(y, shape)).pvalue > P_MIN
    values = np.exp(logs)
    assert abs(values.mean() - shape) < 5 * np.sqrt(shape / values.size)


@pytest.mark.parametrize("shape", [1e-3, 0.3, 2.5])
def test_short_dirichlet_rows_match_gamma_distribution(shape: float) -> None:
    """Rows of at most 64 entries (words, π, G: drawn entry by entry on one stream): 2,000 rows of
    ten variates, each row from its own seed, follow the gamma law; normalised, they sum to 1."""
    draws = np.concatenate([_row_log_gammas(np.full(10, shape), seed) for seed in range(2_000)])
    assert np.isfinite(draws).all()
    assert stats.kstest(draws, lambda y: log_gamma_cdf(y, shape)).pvalue > P_MIN
    normalised = _row_log_gammas(np.array([shape, 0.0, 2.0 * shape]), 3, normalise=True)
    assert np.isneginf(normalised[1]) and abs(logsumexp(normalised)) < 1e-12


def test_dirichlet_rows_mixed_shapes_normalise_exactly() -> None:
    """One row mixing zero, tiny, boosted and large shapes: each column follows its own gamma
    law across rows, and the normalised row equals the unnormalised one minus its log-sum-exp."""
    pattern = np.array([0.0, 1e-5, 0.4, 1.0, 2.5, 300.0])
    shape = np.tile(pattern, 5_000)
    logs = _row_log_gammas(shape, 5)
    assert np.isneginf(logs[shape == 0.0]).all()
    for a in pattern[1:]:
        assert stats.kstest(logs[shape == a], lambda y, a=a: log_gamma_cdf(y, a)).pvalue > P_MIN, a
    normalised = _row_log_gammas(shape, 5, normalise=True)
    finite = shape > 0.0
    assert_allclose(normalised[finite], logs[finite] - logsumexp(logs[finite]), rtol=0, atol=1e-9)
    assert np.isneginf(normalised[~finite]).all()
    # only tiny shapes: the log-sum-exp path
    tiny = _row_log_gammas(np.full(40, 1e-4), 6, normalise=True)
    assert np.isfinite(tiny).all() and abs(logsumexp(tiny)) < 1e-12


def test_log_gamma_variates_mixed_shapes_and_zero() -> None:
    rng = np.random.default_rng(2)
    shapes = np.tile([1e-4, 0.3, 2.0, 0.0], 10_000).reshape(10_000, 4)
    draws = log_gamma_variates(shapes, rng)
    assert draws.shape == shapes.shape
    assert np.isneginf(draws[:, 3]).all()
    for j, a in enumerate([1e-4, 0.3, 2.0]):
        assert np.isfinite(draws[:, j]).all()
        assert stats.kstest(draws[:, j], lambda y, a=a: log_gamma_cdf(y, a)).pvalue > P_MIN


def test_log_gamma_variates_blocks_are_correct_seeded_and_thread_independent() -> None:
    shape = np.full((400, 600), 2.5)  # 240,000 entries: 59 blocks, each its own random stream
    first = log_gamma_variates(shape, np.random.default_rng(3))
    again = log_gamma_variates(shape, np.random.default_rng(3))
    assert_array_equal(first, again)
    assert not np.array_equal(first, log_gamma_variates(shape, np.random.default_rng(4)))
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        assert_array_equal(first, log_gamma_variates(shape, np.random.default_rng(3)))
        assert_array_equal(log_dirichlet(shape, np.random.default_rng(3)),
                           log_dirichlet(shape, np.random.default_rng(3)))
    finally:
        numba.set_num_threads(threads)
    flat = first.ravel()
    for part in (flat[:120_000:6], flat[120_000::6]):  # 20,000 draws from each half
        assert stats.kstest(part, lambda y: log_gamma_cdf(y, 2.5)).pvalue > P_MIN
    # neighbouring blocks are independent streams
    assert abs(np.corrcoef(flat[:4096 * 29], flat[4096:4096 * 30])[0, 1]) < 0.02


def test_standard_normals_of_the_compiled_streams() -> None:
    """The ziggurat normals behind the gamma kernel: distribution, tails, independence."""
    from spco.model.kernels.normal import _stream_normal
    from spco.model.kernels.rng import _stream_start

    @numba.njit
    def normals(seed, rows, width):
        out = np.empty((rows, width))
        for r in range(rows):
            state = _stream_start(seed, np.uint64(r))
            for j in range(width):
                state, out[r, j] = _stream_normal(state)
        return out

    z = normals(np.uint64(2024), 1000, 1000)
    assert stats.kstest(z.ravel(), "norm").pvalue > P_MIN
    for t in (2.0, 3.0, 4.0):  # tails, including the ziggurat's tail beyond r = 3.65
        expected = 2 * stats.norm.sf(t)
        observed = (np.abs(z) > t).mean()
        assert abs(observed - expected) < 5 * np.sqrt(expected / z.size), t
    assert abs(np.corrcoef(z[:, :-1].ravel(), z[:, 1:].ravel())[0, 1]) < 0.005  # within a stream
    assert abs(np.corrcoef(z[:-1].ravel(), z[1:].ravel())[0, 1]) < 0.005  # across streams


def dirichlet_moments(alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a0 = alpha.sum()
    mean = alpha / a0
    var = alpha * (a0 - alpha) / (a0**2 * (a0 + 1))
    return mean, var


@pytest.mark.parametrize("alpha", [
    [0.5, 1.0, 2.0, 5.0],
    [30.0, 0.2, 7.0],
    [1e-3, 2e-3, 3e-3, 4e-3],  # plain gamma variates underflow to 0 for about half of these
    [1e-2] * 12,
])
def test_log_dirichlet_moments(alpha: list[float]) -> None:
    alpha_a = np.asarray(alpha)
    n = 40_000
    log_p = log_dirichlet(np.tile(alpha_a, (n, 1)), np.random.default_rng(5))
    assert not np.isnan(log_p).any()
    assert not np.isposinf(log_p).any()
    assert np.isfinite(log_p).all(), "every entry with α > 0 must have a finite log-probability"
    assert_allclose(logsumexp(log_p, axis=1), 0.0, atol=1e-12)
    p = np.exp(log_p)
    mean, var = dirichlet_moments(alpha_a)
    assert np.abs(z_mean(p, mean, var)).max() < Z_MAX
    if alpha_a.min() > 0.1:  # variance z-tests need a not-too-heavy fourth moment
        assert np.abs(z_variance(p, var)).max() < Z_MAX


def test_log_dirichlet_marginals_are_beta() -> None:
    alpha = np.array([0.3, 1.5, 4.0])
    p = np.exp(log_dirichlet(np.tile(alpha, (20_000, 1)), np.random.default_rng(6)))
    for k in range(3):
        dist = stats.beta(alpha[k], alpha.sum() - alpha[k])
        assert stats.kstest(p[:, k], dist.cdf).pvalue > P_MIN


def test_log_dirichlet_tiny_concentrations_pick_vertices_by_weight() -> None:
    """As α0 → 0 a Dirichlet draw concentrates on vertex k with probability α_k/α0."""
    alpha = np.array([1e-6, 2e-6, 3e-6, 4e-6])
    log_p = log_dirichlet(np.tile(alpha, (20_000, 1)), np.random.default_rng(7))
    assert np.isfinite(log_p).all()
    winner = log_p.argmax(axis=1)
    assert (log_p.max(axis=1) > -1e-3).mean() > 0.995  # one entry holds (nearly) all the mass
    assert chisquare_counts(np.bincount(winner, minlength=4), alpha / alpha.sum()) > P_MIN


def test_log_dirichlet_zero_entries_and_batch_shape() -> None:
    alpha = np.array([[[2.0, 0.0, 1.0], [0.0, 0.0, 5.0]]])
    log_p = log_dirichlet(alpha, np.random.default_rng(8))
    assert log_p.shape == alpha.shape
    assert np.isneginf(log_p[alpha == 0]).all()
    assert_allclose(log_p[0, 1, 2], 0.0)
    assert_allclose(logsumexp(log_p, axis=-1), 0.0, atol=1e-12)


def test_batches_of_short_rows_are_dirichlet() -> None:
    """Batches of many short rows below the parallel threshold (π: E × L rows of K = 20; θ^w:
    rows of a few words) are drawn as one flat batch of gamma variates normalised row by row:
    moments and Beta marginals per column, zero shapes exactly 0, rows of zeros all −inf."""
    from spco.model.kernels.dispatch import _PARALLEL_MIN
    from spco.model.kernels.gamma import _SHORT_ROW

    alpha = np.array([0.05, 0.5, 1.0, 3.0, 0.0, 10.0, 0.3, 2.5, 1e-3, 7.0, 0.8, 1.5])
    rows_per_batch = 1_500  # 18,000 entries per call: the one-thread flat path
    assert alpha.size <= _SHORT_ROW and rows_per_batch * alpha.size < _PARALLEL_MIN
    rng = np.random.default_rng(41)
    log_p = np.concatenate([log_dirichlet(np.tile(alpha, (rows_per_batch, 1)), rng) for _ in range(20)])
    assert np.isneginf(log_p[:, 4]).all() and np.isfinite(np.delete(log_p, 4, axis=1)).all()
    assert_allclose(logsumexp(log_p, axis=1), 0.0, atol=1e-12)
    p = np.exp(log_p)
    mean, var = dirichlet_moments(alpha)
    positive = alpha > 0
    assert np.abs(z_mean(p[:, positive], mean[positive], var[positive])).max() < Z_MAX
    for k in (1, 3, 5, 6):
        dist = stats.beta(alpha[k], alpha.sum() - alpha[k])
        assert stats.kstest(p[:, k], dist.cdf).pvalue > P_MIN, k
    batch = np.zeros((300, 20))
    batch[::2, 3] = 0.7
    out = log_dirichlet(batch, rng)
    assert np.isneginf(out[1::2]).all() and (out[::2, 3] == 0.0).all()


def test_batches_of_short_hierarchical_rows_are_dirichlet() -> None:
    """θ^w for few words: log_dirichlet_hierarchical on a small batch of short rows (the flat
    one-thread path) follows Dir(base + counts) row by row."""
    from spco.model.kernels.dirichlet import log_dirichlet_hierarchical

    base = np.array([[0.5, 1e-3, 3.0, 20.0, 0.2, 1.0], [2e-4, 1e-4, 0.3, 0.05, 4.0, 0.0]])
    counts = np.array([[[0, 0, 2, 5, 0, 1], [0, 0, 0, 0, 1, 0]], [[4, 0, 0, 1, 0, 0], [0, 3, 0, 0, 0, 0]]])
    reps = 600  # (1,200, 2, 6): 14,400 entries per call
    rng = np.random.default_rng(42)
    log_p = np.concatenate([log_dirichlet_hierarchical(base, np.tile(counts, (reps, 1, 1)), rng)
                            for _ in range(25)])
    assert_allclose(logsumexp(log_p, axis=-1), 0.0, atol=1e-12)
    assert np.isneginf(log_p[:, 1, 5]).all()
    p = np.exp(log_p).reshape(-1, 2, 2, 6)
    for g in range(2):
        for r in range(2):
            alpha = base[r] + counts[g, r]
            mean, var = dirichlet_moments(alpha)
            kept = alpha > 0
            assert np.abs(z_mean(p[:, g, r][:, kept], mean[kept], var[kept])).max() < Z_MAX, (g, r)


def test_scaled_exp_matches_numpy() -> None:
    """scale · exp(x), compiled (δ φ from log φ each sweep): within 2 ulp of NumPy over the range
    used, and NumPy's values outside it (underflow to subnormals and 0, overflow, ±inf, NaN)."""
    from spco.model.kernels.special import scaled_exp

    rng = np.random.default_rng(43)
    cases = ((rng.uniform(-40.0, 5.0, (15, 4096)), 3e5), (rng.uniform(-708.0, 709.0, 50_000), 1.0))
    for values, scale in cases:
        expected = scale * np.exp(values)
        got = scaled_exp(values, scale)
        assert got.shape == values.shape
        assert (np.abs(got - expected) <= 2 * np.spacing(expected)).all()
    edges = np.array([-np.inf, -1e300, -745.5, -720.0, -708.5, 709.5, 710.0, np.inf, np.nan, 0.0, 1e-320])
    with np.errstate(over="ignore"):
        assert_array_equal(scaled_exp(edges, 2.0), 2.0 * np.exp(edges))
    assert scaled_exp(np.array(0.0), 5.0).shape == () and scaled_exp(np.array(0.0), 5.0) == 5.0
    assert scaled_exp(np.zeros((0, 3))).shape == (0, 3)


def test_dirichlet_log_density_matches_scipy() -> None:
    rng = np.random.default_rng(9)
    alpha = np.array([0.7, 2.0, 3.5, 1.0])
    p = rng.dirichlet(alpha, size=5)
    expected = [stats.dirichlet.logpdf(row, alpha) for row in p]
    assert_allclose(dirichlet_log_density(np.log(p), alpha), expected, rtol=1e-10)


# ----------------------------------------------------------------------------- Normal–inverse-Wishart


def test_niw_posterior_matches_textbook_formula() -> None:
    rng = np.random.default_rng(10)
    d = 4
    mu0 = rng.normal(size=d) * 3
    kappa0, nu0 = 0.05, 10.0
    psi0 = random_spd(rng, d, 0.1)
    groups = [rng.normal(loc=5.0, scale=2.0, size=(n, d)) for n in (0, 1, 2, 7, 50)]
    count = np.array([g.shape[0] for g in groups], dtype=float)
    total = np.stack([g.sum(0) for g in groups])
    scatter = np.stack([g.T @ g for g in groups])
    mu_n, kappa_n, psi_n, nu_n = niw_posterior(count, total, scatter, mu0, kappa0, psi0, nu0)
    for i, x in enumerate(groups):
        n = x.shape[0]
        k_n = kappa0 + n
        assert kappa_n[i] == pytest.approx(k_n)
        assert nu_n[i] == pytest.approx(nu0 + n)
        if n == 0:
            assert_allclose(mu_n[i], mu0)
            assert_allclose(psi_n[i], psi0, atol=1e-12)
            continue
        xbar = x.mean(0)
        centred = x - xbar
        s = centred.T @ centred
        expected_mu = (kappa0 * mu0 + n * xbar) / k_n
        expected_psi = psi0 + s + kappa0 * n / k_n * np.outer(xbar - mu0, xbar - mu0)
        assert_allclose(mu_n[i], expected_mu, rtol=1e-10, atol=1e-12)
        assert_allclose(psi_n[i], expected_psi, rtol=1e-9, atol=1e-9)
        assert_allclose(psi_n[i], psi_n[i].T)


def test_niw_posterior_batched_prior_mean() -> None:
    rng = np.random.default_rng(11)
    mu0 = rng.normal(size=(2, 3, 4))  # per-group prior means (the sampler's per-home μ0)
    x = rng.normal(size=(2, 3, 5, 4))
    count = np.full((2, 3), 5.0)
    mu_n, _, psi_n, _ = niw_posterior(count, x.sum(2), np.einsum("abni,abnj->abij", x, x), mu0, 1.0,
                                      np.eye(4), 6.0)
    for a in range(2):
        for b in range(3):
            single = niw_posterior(np.array(5.0), x[a, b].sum(0), x[a, b].T @ x[a, b], mu0[a, b], 1.0,
                                   np.eye(4), 6.0)
            assert_allclose(mu_n[a, b], single[0])
            assert_allclose(psi_n[a, b], single[2])


def test_sample_niw_moments_and_bartlett_distribution() -> None:
    rng = np.random.default_rng(12)
    d = 4
    n = 30_000
    mu_n = np.array([1.0, -2.0, 0.5, 3.0])
    psi = random_spd(rng, d, 2.0)
    kappa, nu = 3.0, 9.0
    mu, sigma = sample_niw(np.tile(mu_n, (n, 1)), np.full(n, kappa), np.tile(psi, (n, 1, 1)), np.full(n, nu),
                           np.random.default_rng(13))
    assert mu.shape == (n, d) and sigma.shape == (n, d, d)
    assert_allclose(sigma, np.swapaxes(sigma, 1, 2))
    assert (np.linalg.eigvalsh(sigma) > 0).all()
    # E[μ] = μ_n, Cov[μ] = E[Σ]/κ
    mean_sigma = psi / (nu - d - 1)
    assert np.abs(z_mean(mu, mu_n, np.diag(mean_sigma) / kappa)).max() < Z_MAX
    # E[Σ] = Ψ/(ν − d − 1): z-test of every entry with its sample standard error
    entries = sigma.reshape(n, -1)
    z = (entries.mean(0) - mean_sigma.ravel()) / (entries.std(0) / np.sqrt(n))
    assert np.abs(z).max() < Z_MAX
    # Bartlett correctness: Σ^{-1} ~ W(Ψ^{-1}, ν), so aᵀΣ^{-1}a / aᵀΨ^{-1}a ~ χ²(ν) for any fixed a
    inv_sigma = np.linalg.inv(sigma)
    inv_psi = np.linalg.inv(psi)
    for a in (np.eye(d)[0], np.eye(d)[3], np.array([1.0, -1.0, 2.0, 0.5])):
        ratio = np.einsum("i,nij,j->n", a, inv_sigma, a) / (a @ inv_psi @ a)
        assert stats.kstest(ratio, stats.chi2(nu).cdf).pvalue > P_MIN
    # the diagonal of an inverse-Wishart: Σ_ii ~ InvGamma((ν − d + 1)/2, Ψ_ii/2)
    for i in range(d):
        dist = stats.invgamma((nu - d + 1) / 2, scale=psi[i, i] / 2)
        assert stats.kstest(sigma[:, i, i], dist.cdf).pvalue > P_MIN
    # μ | Σ ~ N(μ_n, Σ/κ): the Mahalanobis distance is χ²(d)
    diff = mu - mu_n
    maha = kappa * np.einsum("ni,nij,nj->n", diff, inv_sigma, diff)
    assert stats.kstest(maha, stats.chi2(d).cdf).pvalue > P_MIN


def test_sample_niw_batch_uses_each_elements_parameters() -> None:
    rng = np.random.default_rng(14)
    d = 4
    psis = np.stack([random_spd(rng, d, 0.5), random_spd(rng, d, 5.0)])
    nus = np.array([7.0, 30.0])
    mus = np.array([[0.0, 0.0, 0.0, 0.0], [10.0, -5.0, 1.0, 2.0]])
    n = 20_000
    idx = np.tile([0, 1], n)
    mu, sigma = sample_niw(mus[idx], np.full(idx.size, 2.0), psis[idx], nus[idx], np.random.default_rng(15))
    for g in (0, 1):
        sig = sigma[idx == g]
        expected = psis[g] / (nus[g] - d - 1)
        z = (sig.reshape(n, -1).mean(0) - expected.ravel()) / (sig.reshape(n, -1).std(0) / np.sqrt(n))
        assert np.abs(z).max() < Z_MAX
        assert np.abs(z_mean(mu[idx == g], mus[g], np.diag(expected) / 2.0)).max() < Z_MAX


# ----------------------------------------------------------------------------- CRT


def crt_draws(n: int, a: float, size: int, seed: int) -> np.ndarray:
    return sample_crt(np.full(size, n), np.full(size, a), np.random.default_rng(seed))


@pytest.mark.parametrize("n", [1, 2, 5, 17, 40])
@pytest.mark.parametrize("a", [1e-3, 0.3, 1.0, 12.0, 1e4])
def test_crt_exact_region_pmf(n: int, a: float) -> None:
    draws = crt_draws(n, a, 20_000, seed=n * 1000 + int(a * 10))
    assert draws.min() >= 1 and draws.max() <= n
    pmf = poisson_binomial_pmf(crt_probs(n, a))
    assert chisquare_counts(np.bincount(draws, minlength=n + 1), pmf) > P_MIN


@pytest.mark.parametrize("n", [41, 50, 120, 400, 1000, 5000])
@pytest.mark.parametrize("a", [1e-3, 0.05, 1.0, 7.0, 100.0, 1e4])
def test_crt_tail_mean_and_variance(n: int, a: float) -> None:
    size = 20_000
    draws = crt_draws(n, a, size, seed=n + int(a * 1000) % 7919)
    assert draws.min() >= 1 and draws.max() <= n
    p = crt_probs(n, a)
    mean, var = p.sum(), (p * (1 - p)).sum()
    assert abs(z_mean(draws.astype(float), mean, var)) < Z_MAX
    if var > 0.05:
        # the rounded normal of the tail adds at most 1/12 to the variance (rounding)
        assert abs(z_variance(draws.astype(float), var)) < Z_MAX + (1 / 12) / (var * np.sqrt(2.0 / size))


@pytest.mark.parametrize(("n", "a"), [(45, 0.5), (60, 3.0), (120, 20.0), (250, 1.0), (300, 500.0),
                                      (80, 0.02)])
def test_crt_tail_whole_pmf_close_to_exact(n: int, a: float) -> None:
    """The moment-matched tail against the exact pmf: a chi-square test at a moderate sample size
    (what the sampler needs: indistinguishable from exact sums at that size), and a small total
    variation distance at a large one."""
    exact = poisson_binomial_pmf(crt_probs(n, a))
    moderate = crt_draws(n, a, 4_000, seed=n * 7 + 1)
    assert chisquare_counts(np.bincount(moderate, minlength=n + 1), exact) > P_MIN
    large = crt_draws(n, a, 200_000, seed=n * 7 + 2)
    empirical = np.bincount(large, minlength=n + 1) / large.size
    assert 0.5 * np.abs(empirical - exact).sum() < 0.02


def test_crt_against_simulated_exact_sums() -> None:
    """Two-sample chi-square: sample_crt in its approximated range against explicit Bernoulli sums."""
    rng = np.random.default_rng(16)
    n, a, size = 200, 4.0, 5_000
    exact = (rng.random((size, n)) < crt_probs(n, a)).sum(1)
    approx = crt_draws(n, a, size, seed=17)
    values = np.arange(n + 1)
    table = np.stack([np.bincount(exact, minlength=n + 1), np.bincount(approx, minlength=n + 1)])
    keep = table.sum(0) >= 10
    lumped = np.column_stack([table[:, keep], table[:, ~keep].sum(1)]) if (~keep).any() else table[:, keep]
    lumped = lumped[:, lumped.sum(0) > 0]
    assert values.size == n + 1
    assert stats.chi2_contingency(lumped).pvalue > P_MIN


def test_crt_edge_cases_shapes_and_independence() -> None:
    rng = np.random.default_rng(18)
    counts = np.array([[0, 3, 5], [100, 0, 1]])
    conc = np.array([[1.0, 0.0, 2.0], [3.0, 5.0, 1e-9]])
    out = sample_crt(counts, conc, rng)
    assert out.shape == counts.shape and out.dtype == np.int64
    assert out[0, 0] == 0 and out[0, 1] == 0 and out[1, 1] == 0  # n = 0 or a = 0
    assert out[1, 2] == 1  # n = 1: the first customer always opens a table
    # broadcasting of the concentration
    b = sample_crt(np.full((3, 4), 30), np.array([0.5, 1.0, 2.0, 4.0]), rng)
    assert b.shape == (3, 4)
    # consecutive calls differ, neighbouring entries are uncorrelated
    first = crt_draws(30, 2.0, 20_000, seed=19)
    second = sample_crt(np.full(20_000, 30), np.full(20_000, 2.0), np.random.default_rng(20))
    assert not np.array_equal(first, second)
    assert abs(np.corrcoef(first[:-1], first[1:])[0, 1]) < Z_MAX / np.sqrt(first.size)
    # same seed, same draws (counter-based uniforms, independent of threads)
    assert_array_equal(first, crt_draws(30, 2.0, 20_000, seed=19))
    with pytest.raises(ValueError):
        sample_crt(counts, conc, rng, head=3)


# ----------------------------------------------------------------------------- categorical draws


def test_sample_categorical_log_matches_softmax() -> None:
    rows = np.array([
        [np.log(0.2), np.log(0.5), np.log(0.3), -1e100],
        [-3000.0, -3000.0 + np.log(2.0), -1e100, -6000.0],  # gaps of thousands of nats
        [5000.0, 5000.0 - 1.0, 5000.0 - 2.0, 5000.0 - 0.5],
        [-np.inf, 0.0, 0.0, -np.inf],
    ])
    n = 20_000
    log_p = np.repeat(rows, n, axis=0)
    draws = sample_categorical_log(log_p, np.random.default_rng(21)).reshape(len(rows), n)
    for r, row in enumerate(rows):
        probs = softmax(row)
        assert chisquare_counts(np.bincount(draws[r], minlength=4), probs) > P_MIN


def test_sample_categorical_log_degenerate_rows() -> None:
    log_p = np.array([[1000.0, -1000.0, -1e100], [-1e100, -1e100, 0.0], [-745.0, -745.0, -2e4]])
    draws = np.stack([sample_categorical_log(log_p, np.random.default_rng(s)) for s in range(200)])
    assert (draws[:, 0] == 0).all()
    assert (draws[:, 1] == 2).all()
    assert set(np.unique(draws[:, 2])) == {0, 1}


def joint_probabilities(log_g: np.ndarray, log_pi: np.ndarray, concept_ll: np.ndarray,
                        region_ll: np.ndarray, e: int, t: int) -> np.ndarray:
    """Brute force p(C = l, R = m) of sample t of home e, flattened as l·K + m."""
    table = log_g[e][:, None] + log_pi[e] + concept_ll[t][:, None] + region_ll[t][None, :]
    return softmax(table.ravel())


def test_sample_joint_assignment_matches_enumeration() -> None:
    rng = np.random.default_rng(22)
    E, L, K = 2, 3, 4
    log_g = np.log(rng.dirichlet(np.ones(L), size=E))
    log_pi = np.log(rng.dirichlet(np.ones(K), size=(E, L)))
    log_pi[0, 1, :2] = -1e100  # concept 1 of home 0 never uses regions 0, 1
    log_pi[1, 2] = [-1e100, -1e100, -1e100, 0.0]
    # distinct samples: ordinary, gaps of thousands of nats, and a concept whose Σ_m π N underflows
    concept_ll = np.array([
        [-10.0, -11.0, -9.5],
        [-4000.0, -4001.0, -4000.5],
        [-5.0, -3.0, -4.0],
        [-20000.0, -20001.5, -20000.2],
    ])
    region_ll = np.array([
        [-2.0, -1.0, -3.0, -2.5],
        [-1500.0, -1502.0, -1501.0, -1499.0],
        [0.0, -1000.0, -2.0, -0.5],  # region 0 dominates; concept 1 of home 0 cannot use it
        [-800.0, -800.0, -2000.0, -30.0],  # region 3 dominates: home 1 concept 2 lives there
    ])
    homes_of = np.array([0, 1, 0, 1])
    # the exact log-sum-exp fallback: every region the concept can use is ~1000 nats below the best
    region_ll[2] = [0.0, -1000.0, -1001.0, -1002.0]
    n = 20_000
    homes = np.repeat(homes_of, n)
    flat = sample_joint_assignment(log_g, log_pi, homes, np.repeat(concept_ll, n, axis=0),
                                   np.repeat(region_ll, n, axis=0), np.random.default_rng(23))
    assert flat.shape == (4 * n,)
    for t in range(4):
        probs = joint_probabilities(log_g, log_pi, concept_ll, region_ll, homes_of[t], t)
        observed = np.bincount(flat[t * n:(t + 1) * n], minlength=L * K)
        assert chisquare_counts(observed, probs) > P_MIN, t


def test_sample_joint_assignment_underflow_fallback_is_exact() -> None:
    """A concept whose region mass lies only where the position is thousands of nats unlikely must
    keep its exact (tiny but comparable) weight against another equally unlikely concept."""
    log_g = np.log(np.array([[0.5, 0.5]]))
    log_pi = np.array([[[-1e100, 0.0, -1e100], [-1e100, -1e100, 0.0]]])  # concept 0 → region 1, 1 → 2
    region_ll = np.array([[0.0, -1000.0, -1000.0 + np.log(3.0)]])  # region 0 is unused by both
    concept_ll = np.zeros((1, 2))
    n = 20_000
    flat = sample_joint_assignment(log_g, log_pi, np.zeros(n, dtype=np.int64), np.repeat(concept_ll, n, 0),
                                   np.repeat(region_ll, n, 0), np.random.default_rng(24))
    probs = joint_probabilities(log_g, log_pi, concept_ll, region_ll, 0, 0)
    assert_allclose(probs.reshape(2, 3)[:, 0], 0.0, atol=1e-300)
    assert chisquare_counts(np.bincount(flat, minlength=6), probs) > P_MIN
    assert abs((flat == 5).mean() - 0.75) < 0.02  # 3 : 1 for concept 1 (region 2)


# ----------------------------------------------------------------------------- densities and sparse helpers


def test_grouped_gaussian_log_density_matches_scipy() -> None:
    rng = np.random.default_rng(25)
    G, K, d, n = 3, 4, 4, 50
    means = rng.normal(size=(G, K, d)) * 3
    covs = np.stack([[random_spd(rng, d, s) for s in (0.01, 0.5, 2.0, 10.0)] for _ in range(G)])
    x = rng.normal(size=(n, d)) * 3
    groups = rng.integers(0, G, size=n)
    out = grouped_gaussian_log_density(x, groups, means, covs)
    assert out.shape == (n, K)
    expected = np.array([[stats.multivariate_normal.logpdf(x[t], means[groups[t], m], covs[groups[t], m])
                          for m in range(K)] for t in range(n)])
    assert_allclose(out, expected, rtol=1e-9, atol=1e-8)


def test_grouped_sparse_dot_and_row_sums_match_dense() -> None:
    rng = np.random.default_rng(26)
    n, D, G, W = 40, 30, 3, 5
    dense = np.where(rng.random((n, D)) < 0.3, rng.integers(1, 400, size=(n, D)), 0)
    dense[5] = 0  # an empty row
    matrix = sp.csr_array(dense.astype(np.float64))
    groups = rng.integers(0, G, size=n)
    table = rng.normal(size=(G, D, W))
    out = grouped_sparse_dot(matrix, groups, table)
    expected = np.stack([dense[t] @ table[groups[t]] for t in range(n)])
    assert_allclose(out, expected, rtol=1e-12, atol=1e-9)
    sums = grouped_row_sums(sp.csr_array(dense), groups, G + 1)
    assert sums.dtype == np.int64
    expected_sums = np.stack([dense[groups == g].sum(0) for g in range(G + 1)])
    assert_array_equal(sums, expected_sums)
    # int32 index arrays and int64 data give the same results
    as_int = sp.csr_array(dense)
    as_int.indices = as_int.indices.astype(np.int32)
    assert_allclose(grouped_sparse_dot(as_int, groups, table), expected, rtol=1e-12, atol=1e-9)


def test_grouped_row_sums_one_thread_and_parallel_agree() -> None:
    """Below 32,768 non-zeros the row sums run on one thread, above in parallel over runs of
    rows: both equal the dense sums."""
    from spco.model.kernels.counts import grouped_row_sums

    rng = np.random.default_rng(38)
    for n in (50, 2_000):  # ~750 and ~40,000 non-zeros
        dense = np.where(rng.random((n, 40)) < 0.5, rng.integers(1, 50, size=(n, 40)), 0)
        blocks = np.sort(rng.integers(0, 6, size=n))
        groups = blocks * 3 + rng.integers(0, 3, size=n)  # runs of blocks write disjoint groups
        expected = np.stack([dense[groups == g].sum(0) for g in range(18)])
        assert_array_equal(grouped_row_sums(sp.csr_array(dense), groups, 18, blocks=blocks), expected)
        assert_array_equal(grouped_row_sums(sp.csr_array(dense), groups, 18), expected)


def test_grouped_moments_match_numpy() -> None:
    from spco.model.kernels.counts import grouped_moments

    rng = np.random.default_rng(39)
    x = rng.normal(size=(300, 4)) * [100.0, 50.0, 1.0, 1.0]
    groups = rng.integers(0, 7, size=300)
    count, total, scatter = grouped_moments(x, groups, 8)  # group 7 is empty
    for g in range(8):
        rows = x[groups == g]
        assert count[g] == rows.shape[0]
        assert_allclose(total[g], rows.sum(0), rtol=1e-12, atol=1e-12)
        assert_allclose(scatter[g], rows.T @ rows, rtol=1e-12, atol=1e-9)


def test_blocked_sparse_dot_over_several_blocks_of_lanes_matches_dense() -> None:
    """More rows than one 16-lane block (L = 20 concepts): the likelihood table is split in two
    zero-padded blocks, entries below the floor are clipped, and the result is the dense product
    (the kernel is compiled with the SLP vectoriser, which must not change any sum)."""
    from numba.core import config

    from spco.model.kernels.counts import stack_counts
    from spco.model.kernels.likelihood import LANES, blocked_sparse_dot, likelihood_table

    rng = np.random.default_rng(27)
    n, D, G, L = 60, 50, 2, 20
    dense = np.where(rng.random((n, D)) < 0.3, rng.integers(1, 7000, size=(n, D)), 0)
    groups = rng.integers(0, G, size=n)
    log_theta = np.log(rng.dirichlet(np.full(D, 0.5), size=(G, L)))
    log_theta[0, 3, :5] = -1e305  # below the floor
    slp_before = config.SLP_VECTORIZE
    table = likelihood_table(log_theta, -1e300)
    assert table.shape == (G, 2, D, LANES)
    assert_array_equal(table[:, 1, :, L - LANES:], 0.0)  # padding lanes
    out = blocked_sparse_dot(stack_counts(sp.csr_array(dense)), groups, table, L)
    assert config.SLP_VECTORIZE == slp_before  # switched on only while compiling the kernel
    floored = np.maximum(log_theta, -1e300)
    expected = np.stack([dense[t] @ floored[groups[t]].T for t in range(n)])
    assert out.shape == (n, L)
    assert_allclose(out, expected, rtol=1e-12)


@pytest.mark.parametrize("sizes", [(13, 0, 21, 8), (70_000, 3)])
def test_dimension_major_dot_equals_blocked_dot_bit_for_bit(sizes: tuple[int, ...]) -> None:
    """The sampler's visual likelihood (the counts regrouped by home and dimension) gives exactly
    the row-major kernel's sums: over two blocks of lanes (L = 20), with an empty home, columns
    no sample uses, and a home of more than 65,535 rows (row numbers stored in int64)."""
    from spco.model.kernels.counts import stack_counts
    from spco.model.kernels.likelihood import (
        blocked_sparse_dot,
        dimension_major,
        dimension_major_dot,
        likelihood_table,
    )

    rng = np.random.default_rng(37)
    D, L = 40, 20
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    n = int(offsets[-1])
    dense = np.where(rng.random((n, D)) < 0.25, rng.integers(1, 7000, size=(n, D)), 0)
    dense[:, 7] = 0  # a dimension no sample uses
    counts = stack_counts(sp.csr_array(dense))
    homes = np.repeat(np.arange(len(sizes)), sizes)
    log_theta = np.log(rng.dirichlet(np.full(D, 0.5), size=(len(sizes), L)))
    table = likelihood_table(log_theta, -1e300)
    layout = dimension_major(counts, offsets)
    assert layout.rows.dtype == (np.uint16 if max(sizes) < 65_536 else np.int64)
    assert layout.colptr.shape == (len(sizes), D + 1) and layout.colptr[-1, -1] == counts.nnz
    log_theta[0, 4, :3] = -1e305  # below the floor
    table = likelihood_table(log_theta, -1e300)
    assert_array_equal(dimension_major_dot(layout, log_theta, -1e300),
                       blocked_sparse_dot(counts, homes, table, L))
    with pytest.raises(ValueError, match="offsets"):
        dimension_major(counts, offsets[:-1])
    with pytest.raises(ValueError, match="do not fit"):
        dimension_major_dot(layout, log_theta[:, :, :-1], -1e300)


# ----------------------------------------------------------------------------- summed CRT, θ draws


@pytest.mark.parametrize(("counts", "a"), [
    ((3, 5, 0, 7), 0.5),  # exact Bernoulli sums (13 terms)
    ((20, 30, 1, 50), 2.0),  # moment-matched, small concentration
    ((100, 200, 5), 73.0),  # the visual regime: a = δ^v φ^v of tens
    ((400,) * 10, 14.0),  # normal range
    ((2, 3, 4) * 5 + (5,), 300.0),  # many homes, few customers each, large a
])
def test_crt_totals_match_explicit_bernoulli_sums(counts: tuple[int, ...], a: float) -> None:
    """Σ_e CRT(n_e, a), drawn in one go, against explicit sums of the Bernoulli(a/(a+i)) terms."""
    from spco.model.kernels.crt import sample_crt_totals

    size = 20_000
    n = np.array(counts)
    grid = np.tile(n[:, None, None], (1, 1, size))
    drawn = sample_crt_totals(grid, np.full((1, size), a), np.random.default_rng(31))[0]
    rng = np.random.default_rng(32)
    exact = sum((rng.random((size, k)) < a / (a + np.arange(k))).sum(1) for k in n if k > 0)
    p = np.concatenate([a / (a + np.arange(k)) for k in n if k > 0])
    mean, var = p.sum(), (p * (1 - p)).sum()
    assert abs(z_mean(drawn.astype(float), mean, var)) < Z_MAX
    assert stats.ks_2samp(drawn, exact).pvalue > P_MIN
    assert drawn.min() >= (n > 0).sum() and drawn.max() <= n.sum()


def test_crt_totals_edge_cases() -> None:
    from spco.model.kernels.crt import sample_crt_totals

    counts = np.array([[[0, 3, 1]], [[0, 0, 1]]])
    out = sample_crt_totals(counts, np.array([[1.0, 0.0, 2.0]]), np.random.default_rng(33))
    assert out.shape == (1, 3) and out.dtype == np.int64
    assert out[0, 0] == 0 and out[0, 1] == 0  # n = 0, or a = 0
    assert out[0, 2] == 2  # one customer in each of two homes: one table each
    with pytest.raises(ValueError, match="groups, rows, width"):
        sample_crt_totals(np.zeros((2, 3)), np.ones(3), np.random.default_rng(0))


def test_hierarchical_dirichlet_matches_dirichlet_of_the_sum() -> None:
    """log θ_{g,r} ~ Dir(base_r + counts_{g,r}) without forming the sum: moments per entry, rows
    normalised, and tiny concentrations (stored as logarithms in the kernel) finite."""
    from spco.model.kernels.dirichlet import log_dirichlet_hierarchical

    base = np.array([[0.5, 1e-3, 3.0, 20.0], [2e-4, 1e-4, 0.3, 0.05]])
    counts = np.array([[[0, 0, 2, 5], [0, 0, 0, 0]], [[4, 0, 0, 1], [0, 3, 0, 0]]])
    reps = 20_000
    tiled = np.tile(counts, (reps, 1, 1))
    log_p = log_dirichlet_hierarchical(base, tiled, np.random.default_rng(34))
    assert log_p.shape == tiled.shape and np.isfinite(log_p).all()
    assert_allclose(logsumexp(log_p, axis=-1), 0.0, atol=1e-12)
    p = np.exp(log_p).reshape(reps, 2, 2, 4)
    for g in range(2):
        for r in range(2):
            alpha = base[r] + counts[g, r]
            mean, var = dirichlet_moments(alpha)
            assert np.abs(z_mean(p[:, g, r], mean, var)).max() < Z_MAX, (g, r)
    out = np.empty(tiled.shape)
    again = log_dirichlet_hierarchical(base, tiled, np.random.default_rng(34), out=out)
    assert again is out
    assert_array_equal(again, log_p)
