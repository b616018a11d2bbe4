"""The power target (``target="power"``) is exact for the tempered visual likelihood, checked by brute
force on tiny problems.

The model (docs/model.md, "The model the sampler targets"): a view v_t enters as
Mult(v_t | θ^v_{e,C_t})^{s_t}, s_t = min(1, w / Σ_d v_td) (w = ``view_counts``). Every visual
conditional then sees the weighted counts n = Σ_t s_t v_t, real numbers:

(a) the weighted statistics against a loop over the samples;
(b) θ^v | φ, data against the tempered posterior integrated numerically from its definition
    (the multinomial pmf to the power s_t, SciPy);
(c) the φ^v step (CRT tables of the whole parts, Metropolis–Hastings for the fractional parts)
    leaves the exact p(φ | n) invariant, and the test has power (the step without its acceptance
    test fails it);
(d) the label-swap acceptance ratio equals the ratio of the collapsed tempered marginal, θ^v
    integrated numerically;
(e) the whole chain: on a home of three views, the sampler's distribution of the partition matches
    the exact posterior of the tempered model (every parameter integrated out numerically) within
    Monte Carlo error, and differs from the untempered model's.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from conftest import csr
from scipy import stats
from scipy.special import expit, gammaln, logit, logsumexp

from spco.model import assignments, gibbs, moves, sweep_statistics
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.observations import HierarchicalMultinomial

P_MIN = 1e-3

pytestmark = pytest.mark.usefixtures("single_numba_thread")


def prepared(visual: np.ndarray, homes: np.ndarray, n_words: int = 1, seed: int = 0) -> gibbs.PreparedData:
    """Tiny data: the given views, positions near the origin, no words."""
    rng = np.random.default_rng(seed)
    n = homes.size
    E = int(homes.max()) + 1
    return gibbs.PreparedData(
        positions=rng.normal(size=(n, 4)) * 0.3, homes=homes, visual=csr(visual),
        words=csr(np.zeros((n, n_words))), n_homes=E,
        offsets=np.concatenate([[0], np.cumsum(np.bincount(homes, minlength=E))]), position_scale=1.0,
        map_centres=np.zeros((E, 4)),
    )


def grid_cdf(log_density_p) -> tuple[np.ndarray, np.ndarray]:
    """CDF on a logit grid of a density on (0, 1) given by its unnormalised log."""
    u = np.linspace(-30.0, 30.0, 300_001)
    p = expit(u)
    log_dens_u = log_density_p(p) + np.log(p) + np.log1p(-p)
    dens = np.exp(log_dens_u - log_dens_u.max())
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(u))])
    return u, cdf / cdf[-1]


def log_integral(log_f) -> float:
    """log ∫_0^1 exp(log_f(p)) dp on a logit grid (trapezoid; log_f vectorised)."""
    u = np.linspace(-30.0, 30.0, 300_001)  # (expit(±30) is still inside (0, 1) in float64)
    p = expit(u)
    log_g = log_f(p) + np.log(p) + np.log1p(-p)
    top = log_g.max()
    g = np.exp(log_g - top)
    return float(top + np.log(np.sum(0.5 * (g[1:] + g[:-1]) * np.diff(u))))


def tempered_log_likelihood(theta1: np.ndarray, views: np.ndarray, powers: np.ndarray) -> np.ndarray:
    """Σ_t s_t log Mult(v_t | θ), θ = (θ1, 1 − θ1), from SciPy's multinomial pmf (D = 2)."""
    out = np.zeros_like(theta1)
    for v, s in zip(views, powers, strict=True):
        out += s * stats.binom.logpmf(v[0], v.sum(), theta1)
    return out


# ----------------------------------------------------------------------------- (a) statistics


def test_weighted_statistics_match_a_loop() -> None:
    rng = np.random.default_rng(1)
    n, D, E, L, w = 9, 5, 2, 3, 7.0
    visual = rng.integers(0, 6, size=(n, D))
    visual[4] = 0  # a sample without a view
    homes = np.repeat([0, 1], [5, 4])
    data = prepared(visual, homes)
    hyper = TransferHyperparameters(n_concepts=L, n_regions=2)
    concepts = rng.integers(0, L, size=n)
    state = gibbs.GibbsState(
        concepts=concepts, regions=np.zeros(n, dtype=np.int64), log_g=np.zeros((E, L)), log_g0=np.zeros(L),
        log_pi=np.zeros((E, L, 2)), means=np.zeros((E, 2, 4)), covariances=np.tile(np.eye(4), (E, 2, 1, 1)),
        log_theta_v=np.zeros((E, L, D)), log_theta_w=np.zeros((E, L, 1)), log_phi_v=np.zeros((L, D)),
        log_phi_w=np.zeros((L, 1)), word_mask=np.ones(1, dtype=bool))
    powers = np.minimum(1.0, w / np.maximum(visual.sum(1), 1))
    expected = np.zeros((E, L, D))
    for t in range(n):
        expected[homes[t], concepts[t]] += powers[t] * visual[t]
    assert np.array_equal(assignments.view_weights(data, w), powers)
    counts = sweep_statistics.sufficient_statistics(data, state, hyper, w).visual
    np.testing.assert_allclose(counts, expected, rtol=1e-13, atol=1e-13)
    assert (counts - np.floor(counts)).any()  # real counts indeed
    whole = sweep_statistics.sufficient_statistics(data, state, hyper, None).visual  # None: every count whole
    expected_whole = np.zeros((E, L, D))
    np.add.at(expected_whole, (homes, concepts), visual)
    assert np.array_equal(whole, expected_whole)


# ----------------------------------------------------------------------------- (b) θ^v


@pytest.mark.parametrize("powers", [np.array([0.1, 0.35, 1.0]), np.array([0.02, 0.05, 0.04])])
def test_theta_draws_are_the_tempered_posterior(powers: np.ndarray) -> None:
    """θ^v_{e,l} | φ, three views at powers s_t: the sampler's draws (from the weighted counts) against
    p(θ) ∝ Dir(θ | δ φ) Π_t Mult(v_t | θ)^{s_t} integrated on a grid (KS test)."""
    views = np.array([[7, 3], [2, 9], [4, 4]])
    delta, phi1 = 3.0, 0.3
    log_phi = np.log(np.array([[phi1, 1.0 - phi1]]))
    n = (powers[:, None] * views).sum(0)
    reps = 20_000
    rng = np.random.default_rng(2)
    log_theta = HierarchicalMultinomial.sample_specific(np.broadcast_to(n, (reps, 1, 2)), log_phi, delta, rng)
    draws = logit(np.exp(log_theta[:, 0, 0]))

    def log_post(p: np.ndarray) -> np.ndarray:
        prior = stats.beta.logpdf(p, delta * phi1, delta * (1.0 - phi1))
        return prior + tempered_log_likelihood(p, views, powers)

    u, cdf = grid_cdf(log_post)
    result = stats.kstest(draws, lambda x: np.interp(x, u, cdf))
    assert result.pvalue > P_MIN, result
    # power: the raw counts' conditional (the former "cut" step) is far from it
    raw = HierarchicalMultinomial.sample_specific(np.broadcast_to(views.sum(0), (reps, 1, 2)), log_phi, delta,
                                                  rng)
    assert stats.kstest(logit(np.exp(raw[:, 0, 0])), lambda x: np.interp(x, u, cdf)).pvalue < 1e-6


# ----------------------------------------------------------------------------- (c) φ^v


def log_phi_posterior(p: np.ndarray, counts: np.ndarray, alpha: float | np.ndarray,
                      delta: float) -> np.ndarray:
    """log [Dir(φ | α) Π_e Γ(δ)/Γ(δ + N_e) Π_k Γ(δ φ_k + n_ek)/Γ(δ φ_k)], φ = (p, 1 − p), n real: the
    tempered likelihood with θ integrated out."""
    phi = np.stack([p, 1.0 - p], axis=-1)
    a = delta * phi
    out = ((np.asarray(alpha) - 1.0) * np.log(phi)).sum(-1)  # α a number or one per dimension
    for n_e in counts:
        out += (gammaln(a + n_e) - gammaln(a)).sum(-1)
    return out


def test_the_collapsed_weight_is_the_integral_of_the_tempered_likelihood() -> None:
    """∫ Π_k θ_k^{n_k} Dir(θ | a) dθ = B(a + n)/B(a) for real n (numerical integral)."""
    for a, n in ((np.array([0.7, 2.5]), np.array([1.3, 0.45])),
                 (np.array([40.0, 3.0]), np.array([0.02, 7.9]))):
        numeric = log_integral(lambda p, a=a, n=n: (stats.beta.logpdf(p, *a) + n[0] * np.log(p)
                                                    + n[1] * np.log1p(-p)))
        closed = gammaln(a.sum()) - gammaln(a.sum() + n.sum()) + (gammaln(a + n) - gammaln(a)).sum()
        assert numeric == pytest.approx(closed, abs=1e-6)


@pytest.mark.parametrize(("counts", "delta", "alpha"), [
    (np.array([[0.3, 2.7], [1.45, 0.05]]), 2.0, 1.0),  # fractions only where n < 1: no table at all
    (np.array([[3.6, 7.2], [10.5, 2.25]]), 5.0, 0.5),  # whole and fractional parts
    (np.array([[0.04, 0.02], [0.01, 0.03], [0.2, 0.0]]), 1.5, 1.0),  # a view's evidence spread thin
    (np.array([[60.4, 140.7], [90.5, 35.1]]), 30.0, 1.0),  # the moment-matched CRT tail (n > 40)
    # a prior with a base measure, Dir(A m) (benchmarks/visual_base_measure.py): one parameter per dimension
    (np.array([[0.04, 0.9], [1.3, 0.2]]), 3.0, np.array([0.03, 2.5])),
])
def test_phi_step_leaves_the_tempered_posterior_invariant(counts: np.ndarray, delta: float,
                                                          alpha: float | np.ndarray) -> None:
    """4,000 independent chains of the φ^v step (the concept axis), 150 steps each, against
    p(φ | n) on a grid (KS test)."""
    chains, steps = 4000, 150
    rng = np.random.default_rng(3)
    n = np.broadcast_to(counts[:, None, :], (counts.shape[0], chains, 2)).copy()
    log_phi = np.log(rng.dirichlet(np.broadcast_to(alpha, 2), size=chains))
    accepted = 0.0
    for _ in range(steps):
        new = HierarchicalMultinomial.sample_shared_given_counts(n, log_phi, delta, alpha, rng)
        accepted += np.mean(np.any(new != log_phi, axis=1))
        log_phi = new
    u, cdf = grid_cdf(lambda p: log_phi_posterior(p, counts, alpha, delta))
    result = stats.kstest(logit(np.exp(log_phi[:, 0])), lambda x: np.interp(x, u, cdf))
    assert result.pvalue > P_MIN, result
    assert accepted / steps > 0.3  # the proposal is close to the conditional


def test_phi_step_without_its_acceptance_test_fails() -> None:
    """The invariance test has power: the proposal alone (Dir(α + tables + fractions), always
    accepted) does not leave p(φ | n) invariant when the fractions matter (small δ φ)."""
    counts, delta, alpha = np.array([[0.9, 0.1], [0.8, 0.95], [0.7, 0.6]]), 0.5, 1.0
    chains, steps = 4000, 60
    rng = np.random.default_rng(4)
    n = np.broadcast_to(counts[:, None, :], (counts.shape[0], chains, 2)).copy()
    log_phi = np.log(rng.dirichlet([alpha, alpha], size=chains))
    for _ in range(steps):
        tables, frac, _ = HierarchicalMultinomial.table_parts(n, log_phi, delta, rng)
        log_phi = HierarchicalMultinomial.sample_shared(tables + frac, alpha, rng)
    u, cdf = grid_cdf(lambda p: log_phi_posterior(p, counts, alpha, delta))
    assert stats.kstest(logit(np.exp(log_phi[:, 0])), lambda x: np.interp(x, u, cdf)).pvalue < 1e-6


def test_whole_counts_give_the_crt_step_bit_for_bit() -> None:
    """With whole counts the φ step is the CRT step: the same numbers from the same generator."""
    rng = np.random.default_rng(5)
    n = rng.integers(0, 30, size=(3, 4, 6))
    log_phi = np.log(rng.dirichlet(np.ones(6), size=4))
    a, b = np.random.default_rng(9), np.random.default_rng(9)
    tables = HierarchicalMultinomial.sample_tables(n, log_phi, 7.0, a)
    expected = HierarchicalMultinomial.sample_shared(tables, 0.5, a)
    got = HierarchicalMultinomial.sample_shared_given_counts(n, log_phi, 7.0, 0.5, b)
    assert np.array_equal(expected, got)
    assert a.random() == b.random()


# ----------------------------------------------------------------------------- (d) label swaps


def test_label_swap_ratio_is_the_tempered_marginal_ratio(monkeypatch: pytest.MonkeyPatch) -> None:
    """Home e, concepts a and b: the log acceptance ratio the compiled pass uses equals
    log p(C', G_e', data | φ, G_0) − log p(C, G_e, data | φ, G_0), θ^v integrated numerically over
    the tempered likelihood Π_t Mult(v_t | θ)^{s_t} (D = 2, no words)."""
    rng = np.random.default_rng(6)
    L, gamma, delta = 3, 2.5, 4.0
    views = rng.integers(0, 40, size=(5, 2))
    powers = np.minimum(1.0, 6.0 / views.sum(1))
    concepts = np.array([0, 0, 1, 2, 1])
    log_g = np.log(rng.dirichlet(np.ones(L)))[None]
    log_g0 = np.log(rng.dirichlet(np.full(L, 2.0)))
    log_phi_v = np.log(rng.dirichlet(np.full(2, 2.0), size=L))
    n_v = np.zeros((1, L, 2))
    np.add.at(n_v, (np.zeros(5, dtype=np.int64), concepts), powers[:, None] * views)
    captured: dict = {}
    real_pass = moves._matching_pass

    def capture(*args):
        captured["args"] = args
        return real_pass(*args)

    monkeypatch.setattr(moves, "_matching_pass", capture)
    moves.concept_swap_step(n_v, log_phi_v, delta, np.zeros((1, L, 1)), np.zeros((L, 1)), 1.0, log_g, log_g0,
                            gamma, np.ones(1, dtype=bool), rng)
    alpha_v, counts_v, alpha_w, counts_w, g_term, log_g_, _, _ = captured["args"]

    def log_marginal(c: np.ndarray, lg: np.ndarray) -> float:
        total = stats.dirichlet.logpdf(np.exp(lg), gamma * np.exp(log_g0)) + lg[c].sum()
        for concept in range(L):
            mine = c == concept
            phi1 = np.exp(log_phi_v[concept, 0])
            total += log_integral(lambda p, mine=mine, phi1=phi1: (
                stats.beta.logpdf(p, delta * phi1, delta * (1.0 - phi1))
                + tempered_log_likelihood(p, views[mine], powers[mine])))
        return total

    for a, b in itertools.combinations(range(L), 2):
        perm = np.arange(L)
        perm[[a, b]] = [b, a]
        exact = log_marginal(perm[concepts], log_g[0][perm]) - log_marginal(concepts, log_g[0])

        def accepted(log_u: float, a: int = a, b: int = b) -> bool:
            out = real_pass(alpha_v, counts_v, alpha_w, counts_w, g_term, log_g_, np.array([[[a, b]]]),
                            np.array([[log_u]]))[0]
            return bool(out[a] == b)

        low, high = -1e4, 1e4
        while high - low > 1e-10:
            mid = 0.5 * (low + high)
            low, high = (mid, high) if accepted(mid) else (low, mid)
        assert 0.5 * (low + high) == pytest.approx(exact, abs=1e-6), (a, b)


# ----------------------------------------------------------------------------- (e) the chain


CHAIN_VIEWS = np.array([[31, 9], [26, 14], [6, 14]])
CHAIN_HYPER = TransferHyperparameters(n_concepts=2, n_regions=1, alpha_visual=1.0, delta_visual=3.0,
                                      alpha_word=1.0, delta_word=1.0, gamma=1.5, gamma0=1.0, beta=1.0)


def partition_of(concepts: np.ndarray) -> int:
    """0: all together; 1: {0,1}{2}; 2: {0,2}{1}; 3: {1,2}{0} (labels do not matter)."""
    if concepts[0] == concepts[1] == concepts[2]:
        return 0
    if concepts[0] == concepts[1]:
        return 1
    return 2 if concepts[0] == concepts[2] else 3


def exact_partition_probabilities(powers: np.ndarray) -> np.ndarray:
    """p(partition | views) of one home, L = 2 concepts, one region (positions say nothing about
    concepts), every parameter integrated out: G_0 ~ Dir(γ0/L), G_e ~ Dir(γ G_0), C_t ~ Cat(G_e);
    φ_l ~ Dir(α), θ_l ~ Dir(δ φ_l), views Mult(v_t | θ_{C_t})^{s_t}. Integrals over G_0 and each φ_l
    on a grid, over G_e and θ in closed form (Dirichlet–multinomial, real counts)."""
    h = CHAIN_HYPER
    log_p = np.full(4, -np.inf)
    for c in itertools.product(range(2), repeat=3):
        c = np.array(c)
        m = np.bincount(c, minlength=2)

        def concept_prior(p: np.ndarray, m: np.ndarray = m) -> np.ndarray:
            g0 = np.stack([p, 1.0 - p], -1)
            a = h.gamma * g0
            return (stats.beta.logpdf(p, h.gamma0 / 2, h.gamma0 / 2) + gammaln(h.gamma) - gammaln(h.gamma + 3)
                    + (gammaln(a + m) - gammaln(a)).sum(-1))

        total = log_integral(concept_prior)
        for concept in range(2):
            n = (powers[c == concept, None] * CHAIN_VIEWS[c == concept]).sum(0)

            def visual(p: np.ndarray, n: np.ndarray = n) -> np.ndarray:
                a = h.delta_visual * np.stack([p, 1.0 - p], -1)
                return (stats.beta.logpdf(p, h.alpha_visual, h.alpha_visual) + gammaln(h.delta_visual)
                        - gammaln(h.delta_visual + n.sum()) + (gammaln(a + n) - gammaln(a)).sum(-1))

            total += log_integral(visual)
        k = partition_of(c)
        log_p[k] = np.logaddexp(log_p[k], total)
    return np.exp(log_p - logsumexp(log_p))


def test_chain_targets_the_tempered_posterior() -> None:
    """The exact sampler with the power target and w = 4 on one home of three views: the partition's
    distribution over 6,000 sweeps (thinned by 3) matches the exact tempered posterior (χ²), and
    that posterior is far from the untempered model's (the test could fail)."""
    w = 4.0
    powers = np.minimum(1.0, w / CHAIN_VIEWS.sum(1))
    exact = exact_partition_probabilities(powers)
    untempered = exact_partition_probabilities(np.ones(3))
    assert np.abs(exact - untempered).max() > 0.15
    data = prepared(CHAIN_VIEWS, np.zeros(3, dtype=np.int64))
    settings = gibbs.SamplerSettings.create("exact", prune=False, view_counts=w, power=True)
    rng = np.random.default_rng(7)
    state = gibbs.GibbsState(
        concepts=np.array([0, 1, 0]), regions=np.zeros(3, dtype=np.int64), log_g=np.log([[0.5, 0.5]]),
        log_g0=np.log([0.5, 0.5]), log_pi=np.zeros((1, 2, 1)), means=np.zeros((1, 1, 4)),
        covariances=np.eye(4)[None, None].copy(), log_theta_v=np.log(np.full((1, 2, 2), 0.5)),
        log_theta_w=np.zeros((1, 2, 1)), log_phi_v=np.log(np.full((2, 2), 0.5)), log_phi_w=np.zeros((2, 1)),
        word_mask=np.ones(1, dtype=bool))
    seen = np.zeros(4)
    for i in range(6_300):
        gibbs.sweep(data, state, CHAIN_HYPER, settings, rng, swaps=False)
        if i >= 300 and i % 3 == 0:
            seen[partition_of(state.concepts)] += 1
    result = stats.chisquare(seen, exact * seen.sum())
    assert result.pvalue > P_MIN, (seen / seen.sum(), exact)
    assert stats.chisquare(seen, untempered * seen.sum()).pvalue < 1e-6
