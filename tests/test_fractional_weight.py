"""The power target's compiled sums: φ^v's acceptance weight
(:meth:`HierarchicalMultinomial.fractional_log_weight`) against its definition, entry by entry with
SciPy's ln Γ, and the views' weighted counts (:func:`spco.model.kernels.counts.grouped_weighted_row_sums`)
against SciPy's product of a one-hot weight matrix with the counts, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.special import gammaln

from spco.model.kernels.counts import grouped_weighted_row_sums, stack_counts
from spco.model.observations import HierarchicalMultinomial


def brute_force(n: np.ndarray, log_phi: np.ndarray, delta: float) -> np.ndarray:
    """Σ_e Σ_k over entries with a fractional part of ln Γ(a + n) − ln Γ(a + ⌊n⌋) − [⌊n⌋ = 0] n ln a,
    a = δ φ_{l,k}, one entry at a time; −inf where such an entry's a is 0."""
    out = np.zeros(log_phi.shape[0])
    for e, c, k in np.ndindex(*n.shape):
        x = float(n[e, c, k])
        whole = math.floor(x)
        if x == whole:
            continue
        a = delta * math.exp(log_phi[c, k])
        if a == 0.0:
            out[c] = -math.inf
            continue
        out[c] += gammaln(a + x) - gammaln(a + whole) - (x * math.log(a) if whole == 0 else 0.0)
    return out


@pytest.mark.parametrize("delta", [0.05, 3.0, 5e4])
def test_the_weight_is_its_definition(delta: float) -> None:
    rng = np.random.default_rng(4)
    n = rng.gamma(0.3, 2.0, size=(3, 4, 6))
    n[0, 0, :3] = np.floor(n[0, 0, :3]) + 1.0  # whole counts: no term
    n[1, 2, 1] = 2.75  # a whole part and a fraction
    n[:, 3] = 0.0  # concept 3: no counts in any home
    log_phi = np.log(rng.dirichlet(np.full(6, 0.4), size=4))
    got = HierarchicalMultinomial.fractional_log_weight(n, log_phi, delta)
    # ln Γ's rounding at its arguments (up to δ + n) bounds how far two exact sums can differ
    tolerance = 1e-14 * max(1.0, float(gammaln(delta + 10.0))) * n.size
    np.testing.assert_allclose(got, brute_force(n, log_phi, delta), rtol=0, atol=tolerance)
    assert got[3] == 0.0  # a concept without counts


def test_a_proposal_with_no_mass_where_a_fraction_is_counted_is_refused() -> None:
    n = np.array([[[0.5, 1.0], [0.25, 0.0]]])
    log_phi = np.array([[0.0, -np.inf], [math.log(0.5), math.log(0.5)]])  # concept 0: none on dimension 1
    n_under = n.copy()
    n_under[0, 0, 1] = 0.5
    got = HierarchicalMultinomial.fractional_log_weight(n_under, log_phi, 2.0)
    assert got[0] == -math.inf and np.isfinite(got[1])
    np.testing.assert_allclose(got, brute_force(n_under, log_phi, 2.0))
    # where the empty dimension's count is whole, nothing is counted there
    np.testing.assert_allclose(HierarchicalMultinomial.fractional_log_weight(n, log_phi, 2.0),
                               brute_force(n, log_phi, 2.0))


def test_whole_counts_weigh_nothing() -> None:
    n = np.arange(24, dtype=np.int64).reshape(2, 3, 4)
    log_phi = np.log(np.full((3, 4), 0.25))
    assert not HierarchicalMultinomial.fractional_log_weight(n, log_phi, 3.0).any()
    assert not HierarchicalMultinomial.fractional_log_weight(n.astype(float), log_phi, 3.0).any()


def test_the_ratio_of_two_proposals_is_the_difference_of_their_weights() -> None:
    rng = np.random.default_rng(9)
    n = rng.gamma(0.5, 1.5, size=(2, 3, 5))
    old, new = (np.log(rng.dirichlet(np.ones(5), size=3)) for _ in range(2))
    ratio = HierarchicalMultinomial.fractional_log_ratio(n, old, new, 7.0)
    np.testing.assert_allclose(ratio, brute_force(n, new, 7.0) - brute_force(n, old, 7.0), rtol=1e-11,
                               atol=1e-10)


@pytest.mark.parametrize("layout", ["stacked", "float64"])
def test_weighted_row_sums_are_the_one_hot_product_bit_for_bit(layout: str) -> None:
    rng = np.random.default_rng(3)
    n, D, G = 40, 30, 7
    dense = rng.integers(0, 50, size=(n, D)) * (rng.random((n, D)) < 0.3)
    dense[5] = 0  # a row without counts
    counts = stack_counts(dense) if layout == "stacked" else sp.csr_array(dense.astype(np.float64))
    weights = 16.0 / np.maximum(dense.sum(1), 1) * rng.random(n)
    groups = rng.integers(0, G, size=n)
    onehot = sp.csr_array((weights, (groups, np.arange(n))), shape=(G, n))
    expected = (onehot @ sp.csr_array(counts, dtype=np.float64)).toarray()
    got = grouped_weighted_row_sums(counts, weights, groups, G)
    assert got.dtype == np.float64 and got.shape == (G, D)
    assert np.array_equal(got, expected)
    loop = np.zeros((G, D))
    for t in range(n):
        loop[groups[t]] += weights[t] * dense[t]
    np.testing.assert_allclose(got, loop, rtol=1e-13, atol=1e-12)
