"""benchmarks/phi_marginal_evidence.py (issue 29, a diagnosis): the Dirichlet expectations and the
new home's predictive with θ^v and φ^v integrated out, against brute force on tiny problems."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.special import gammaln

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import phi_marginal_evidence as pme


def test_saddlepoint_matches_the_exact_power_expectation():
    """E_Dir(a) Π φ_d^{n_d} = B(a + n)/B(a): the saddlepoint over gammas, at small and large D."""
    rng = np.random.default_rng(3)
    for d, alpha in ((3, 0.5), (400, 0.23)):
        a = alpha + rng.poisson(2.0, d) * (rng.random(d) < 0.4)
        n = rng.random(d) * 3 * (rng.random(d) < 0.5)
        n[0] = 1.5
        got = pme.log_dirichlet_expectation(a, n, 1.0, pme.log_h_power)["value"]
        exact = gammaln(a + n).sum() - gammaln((a + n).sum()) - gammaln(a).sum() + gammaln(a.sum())
        assert abs(got - exact) < 2e-3


def test_saddlepoint_matches_quadrature_for_the_dirichlet_multinomial_factor():
    """ln E_Dir(a) Π Γ(δφ + n)/Γ(δφ) on the 3-simplex: saddlepoint against Gauss–Legendre."""
    for a, n, delta in ((np.array([0.3, 1.2, 2.5]), np.array([1.7, 0.0, 3.2]), 5.0),
                        (np.array([0.23, 0.23, 4.0]), np.array([0.4, 2.0, 6.0]), 50.0)):
        got = pme.log_dirichlet_expectation(a, n, delta)["value"]
        assert abs(got - pme.brute_log_expectation(a, n, delta)) < 1e-3


def test_predictive_with_real_counts_matches_brute_force_and_needs_the_weight():
    """p(n_new | n_others) with real counts: the table mixture with the fractional weight w matches the
    exact integral; the proposal's Dirichlet alone (w left out) does not."""
    rng = np.random.default_rng(11)
    others = rng.integers(0, 5, size=(2, 3)) + np.round(rng.random((2, 3)), 2)
    new = rng.integers(0, 4, size=3) + np.round(rng.random(3), 2)
    exact = pme.brute_predictive(0.4, 6.0, list(others), new)
    got = {}
    for exact_fractions in (True, False):
        r = pme.predictive_estimates(others[:, None, :], np.zeros((1, 3)), {"x": new[None, :]}, 6.0, 0.4,
                                     np.random.default_rng(0), 1500, 100, exact_fractions=exact_fractions)
        got[exact_fractions] = r["variants"]["x"]
    assert abs(got[True]["value"] - exact) < max(0.02, 5 * got[True]["se"])
    assert abs(got[False]["value"] - exact) > 0.03


def test_concept_grid_with_whole_counts_is_the_plain_expectation():
    """Without fractional counts w = 1: E[H | M] is E_Dir(α + M)[H] itself."""
    rng = np.random.default_rng(5)
    a = 0.23 + rng.poisson(3.0, 50).astype(float)
    others = rng.integers(0, 4, size=(3, 50)).astype(float)
    n = rng.random(50) * 2 * (rng.random(50) < 0.5)
    grid = pme.ConceptGrid(a, others, 30.0, n)
    plain = pme.log_dirichlet_expectation(a, n, 30.0)["value"]
    assert abs(grid.denominator["value"]) < 1e-4  # ln E_Dir[1] = 0: the saddlepoint's own error
    assert abs(grid.log_expectation(n)["value"] - plain) < 1e-4
