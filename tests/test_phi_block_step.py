"""The power target's blocked φ^v step (:meth:`HierarchicalMultinomial.accept_shared`, issue 29) against
the exact posterior of φ on a tiny problem: D = 6 dimensions, three homes with real (fractional)
counts, p(φ | n) ∝ Dir(φ | α) Π_e Π_k Γ(δ φ_k + n_ek) / Γ(δ φ_k) (θ integrated out), its moments by
importance sampling. Thousands of independent chains of the φ step alone (CRT tables of ⌊n⌋, then the
blocked Metropolis–Hastings step) are compared with those moments by a chi-square on the chains' own
covariance; a step with a wrong ratio fails the same test."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import gammaln
from scipy.stats import chi2

from spco.model import observations
from spco.model.observations import HierarchicalMultinomial

pytestmark = pytest.mark.usefixtures("single_numba_thread")

DELTA, ALPHA = 2.0, 0.8
COUNTS = np.array([[0.35, 1.6, 0.0, 2.25, 0.8, 0.1],
                   [1.0, 0.45, 0.7, 0.0, 3.3, 0.05],
                   [0.6, 2.0, 0.15, 1.4, 0.0, 0.9]])  # (E, D): whole counts, fractions below 1, both
CHAINS, STEPS = 3000, 40


def _log_posterior(phi: np.ndarray) -> np.ndarray:
    """ln p(φ | n) up to a constant for φ (S, D)."""
    a = DELTA * phi
    value = ((ALPHA - 1.0) * np.log(phi)).sum(-1)
    for n in COUNTS:
        value += (gammaln(a + n) - gammaln(a)).sum(-1)
    return value


def _statistics(phi: np.ndarray) -> np.ndarray:
    """(S, 2D − 1): φ_1..φ_{D−1} and ln φ_1..ln φ_D."""
    return np.concatenate([phi[:, :-1], np.log(phi)], axis=1)


def _exact_moments() -> tuple[np.ndarray, float]:
    """E[statistics] under p(φ | n) by self-normalised importance sampling from Dir(α + n̄), and the
    effective sample size."""
    rng = np.random.default_rng(11)
    proposal = ALPHA + 0.5 * COUNTS.sum(0)
    phi = rng.dirichlet(proposal, size=400_000)
    phi = np.maximum(phi, 1e-300)
    log_q = ((proposal - 1.0) * np.log(phi)).sum(-1)
    log_w = _log_posterior(phi) - log_q
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    return w @ _statistics(phi), float(1.0 / (w ** 2).sum())


def _tilt_free_terms(n: np.ndarray, log_phi: np.ndarray) -> np.ndarray:
    """A wrong weight (mutant): Σ_e ln Γ(a + n) − ln Γ(a + ⌊n⌋) per dimension, without the proposal's
    [⌊n⌋ = 0] n ln a."""
    a = DELTA * np.exp(log_phi)[None]
    whole = np.floor(n)
    return np.where(n != whole, gammaln(a + n) - gammaln(a + whole), 0.0).sum(0)


def _run(step, seed: int) -> np.ndarray:
    """CHAINS chains (the concept axis) of ``step(n, log φ, rng)`` for STEPS steps from Dir(α)."""
    rng = np.random.default_rng(seed)
    n = np.ascontiguousarray(np.broadcast_to(COUNTS[:, None, :], (COUNTS.shape[0], CHAINS, COUNTS.shape[1])))
    log_phi = np.log(rng.dirichlet(np.full(COUNTS.shape[1], ALPHA), size=CHAINS))
    for _ in range(STEPS):
        log_phi = step(n, log_phi, rng)
    return np.exp(log_phi)


def _chi_square(phi: np.ndarray) -> tuple[float, float]:
    """The chains' mean statistics against the exact moments: z' Σ⁻¹ z / (1/CHAINS + 1/ESS) and its
    0.999 quantile (chi-square with 2D − 1 degrees of freedom)."""
    exact, ess = _exact_moments()
    s = _statistics(phi)
    z = s.mean(0) - exact
    value = float(z @ np.linalg.solve(np.cov(s.T), z) / (1.0 / len(s) + 1.0 / ess))
    return value, float(chi2.ppf(1 - 1e-3, s.shape[1]))


def _step(weights, block_size: int, passes: int):
    def step(n, log_phi, rng):
        tables, frac, fractional = HierarchicalMultinomial.table_parts(n, log_phi, DELTA, rng)
        return HierarchicalMultinomial.accept_shared(lambda phi: weights(n, phi), log_phi, ALPHA, tables,
                                                     frac, rng, fractional > 0, block_size=block_size,
                                                     passes=passes)
    return step


def _library_weights(n, phi):
    return HierarchicalMultinomial.fractional_log_weight_terms(n, phi, DELTA)


@pytest.mark.parametrize(("block_size", "passes"), [(2, 1), (2, 4), (3, 2), (6, 1)])
def test_the_blocked_step_keeps_the_exact_posterior(block_size: int, passes: int) -> None:
    """Blocks of 2 and 3 of the 6 dimensions (a fresh random partition each pass), and one block of all
    six (the independence sampler of the whole vector)."""
    value, limit = _chi_square(_run(_step(_library_weights, block_size, passes), 21 + block_size + passes))
    print(f"chi-square {value:.1f} (0.999 quantile {limit:.1f})")
    assert value < limit, (value, limit)


def test_the_library_s_step_keeps_the_exact_posterior(monkeypatch: pytest.MonkeyPatch) -> None:
    """:meth:`HierarchicalMultinomial.sample_shared_given_counts` itself, the block size made 2 so that
    D = 6 is split."""
    monkeypatch.setattr(observations, "PHI_BLOCK_SIZE", 2)

    def step(n, log_phi, rng):
        return HierarchicalMultinomial.sample_shared_given_counts(n, log_phi, DELTA, ALPHA, rng)
    value, limit = _chi_square(_run(step, 5))
    print(f"chi-square {value:.1f} (0.999 quantile {limit:.1f})")
    assert value < limit, (value, limit)


def test_a_wrong_ratio_fails() -> None:
    """The test has power: the blocked step with the weight's proposal term left out (the ratio of
    ln Γ(a + n) − ln Γ(a + ⌊n⌋) only, a target other than the posterior) leaves it."""
    value, limit = _chi_square(_run(_step(_tilt_free_terms, 2, 4), 8))
    print(f"mutant chi-square {value:.1f} (0.999 quantile {limit:.1f})")
    assert value > 10 * limit, (value, limit)


def test_whole_counts_draw_the_crt_step_and_nothing_else() -> None:
    """Without a fractional count the step is the CRT step's one Dirichlet draw: the same numbers from the
    same generator, and the generator left where that draw leaves it."""
    rng = np.random.default_rng(2)
    n = rng.integers(0, 9, size=(2, 3, 10)).astype(float)
    log_phi = np.log(rng.dirichlet(np.ones(10), size=3))
    a, b = np.random.default_rng(4), np.random.default_rng(4)
    tables = HierarchicalMultinomial.sample_tables(n.astype(np.int64), log_phi, 3.0, a)
    expected = HierarchicalMultinomial.sample_shared(tables, 0.5, a)
    got = HierarchicalMultinomial.sample_shared_given_counts(n, log_phi, 3.0, 0.5, b)
    assert np.array_equal(expected, got)
    assert a.random() == b.random()


def test_a_concept_without_fractions_takes_the_exact_draw() -> None:
    """Concepts whose counts are whole get the proposal Dir(α + M) itself; the others move by blocks."""
    rng = np.random.default_rng(3)
    log_phi = np.log(rng.dirichlet(np.ones(8), size=2))
    tables = rng.integers(0, 5, size=(2, 8)).astype(float)
    frac = np.zeros((2, 8))
    fractional = np.zeros((2, 8), dtype=bool)
    fractional[1, 3] = True
    a, b = np.random.default_rng(6), np.random.default_rng(6)
    draw = observations.log_dirichlet(0.5 + tables, a)
    got = HierarchicalMultinomial.accept_shared(lambda phi: np.zeros(phi.shape), log_phi, 0.5, tables, frac,
                                                b, fractional, block_size=2, passes=2)
    assert np.array_equal(got[0], draw[0])
    np.testing.assert_allclose(np.exp(got).sum(1), 1.0)
    with pytest.raises(ValueError, match="block_size"):
        HierarchicalMultinomial.accept_shared(lambda phi: np.zeros(phi.shape), log_phi, 0.5, tables, frac, b,
                                              fractional, block_size=1)


@pytest.mark.parametrize("delta", [0.05, 3.0, 5e4])
def test_the_terms_per_dimension_are_the_weight_s_definition(delta: float) -> None:
    """:meth:`HierarchicalMultinomial.fractional_log_weight_terms` entry by entry against SciPy's ln Γ, and
    its sum over dimensions is the weight."""
    rng = np.random.default_rng(4)
    n = rng.gamma(0.3, 2.0, size=(3, 4, 6))
    n[1, 2, 1] = 2.75
    n[:, 3] = 0.0
    log_phi = np.log(rng.dirichlet(np.full(6, 0.4), size=4))
    a = delta * np.exp(log_phi)[None]
    whole = np.floor(n)
    tilt = np.where(whole == 0, n, 0.0) * np.log(a)
    expected = np.where(n != whole, gammaln(a + n) - gammaln(a + whole) - tilt, 0.0).sum(0)
    got = HierarchicalMultinomial.fractional_log_weight_terms(n, log_phi, delta)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * max(1.0, float(gammaln(delta + 10.0))))
    np.testing.assert_allclose(got.sum(1), HierarchicalMultinomial.fractional_log_weight(n, log_phi, delta),
                               rtol=1e-12, atol=1e-9)
    assert not HierarchicalMultinomial.fractional_log_weight_terms(n.astype(np.int64), log_phi, delta).any()


@pytest.mark.parametrize("passes", [1, 2])
def test_the_library_s_step_keeps_the_exact_posterior_with_fewer_passes(monkeypatch: pytest.MonkeyPatch,
                                                                        passes: int) -> None:
    """:meth:`HierarchicalMultinomial.sample_shared_given_counts` with ``passes`` (the fit's
    ``TransferHyperparameters.phi_passes``, branch powercost21), the block size made 2."""
    monkeypatch.setattr(observations, "PHI_BLOCK_SIZE", 2)

    def step(n, log_phi, rng):
        return HierarchicalMultinomial.sample_shared_given_counts(n, log_phi, DELTA, ALPHA, rng,
                                                                  passes=passes)
    value, limit = _chi_square(_run(step, 6 + passes))
    print(f"chi-square {value:.1f} (0.999 quantile {limit:.1f})")
    assert value < limit, (value, limit)
