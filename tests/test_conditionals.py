"""Every conditional of the Gibbs sampler against brute force on tiny problems.

(a) the joint (C_t, R_t) draw of the local step against enumeration of the model's joint density;
(b) the reference variant's R | C and C | R blocks;
(c) φ and G_0 by CRT table counts: the auxiliary-variable chain leaves the exact posterior
    (computed on a grid) invariant;
(d) θ | φ, n, G_e | G_0, n and π | n: Dirichlet posterior moments;
(e) the NIW posterior draws of the region Gaussians;
(f) the collapsed label-swap Metropolis–Hastings move: its log acceptance ratio is the exact log
    ratio of the marginal p(C, G_e, π_e, data | φ, G_0) with θ integrated out;
(g) word pruning scores against brute-force mutual information and KL tables.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from conftest import chisquare_p, csr
from numpy.testing import assert_allclose
from scipy import stats
from scipy.special import expit, gammaln, logit, logsumexp, softmax

from spco.model import allocation, assignments, gibbs, moves, sweep_statistics
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.observations import GaussianRegions, HierarchicalMultinomial, NIWPrior
from spco.model.pruning import (
    bernoulli_kl_scores,
    concept_word_mutual_information,
    word_concept_mutual_information,
    words_to_keep,
)

P_MIN = 1e-3
Z_MAX = 4.0


# tiny problems call the compiled kernels thousands of times: one thread (conftest.py)
pytestmark = pytest.mark.usefixtures("single_numba_thread")


# ----------------------------------------------------------------------------- tiny problems


def random_spd(rng: np.random.Generator, d: int, scale: float) -> np.ndarray:
    a = rng.normal(size=(d, d))
    return scale * (a @ a.T / d + 0.3 * np.eye(d))


def make_problem(seed: int, sizes: tuple[int, ...] = (2, 2), L: int = 2, K: int = 2, D: int = 3, V: int = 3,
                 copies: int = 1) -> tuple[gibbs.PreparedData, gibbs.GibbsState, dict[str, np.ndarray]]:
    """A tiny random problem: data (each distinct sample repeated ``copies`` times, copies
    consecutive) and a state with moderately informative parameters.

    Returns the data, the state and the distinct samples (positions, visual, words, homes).
    """
    rng = np.random.default_rng(seed)
    E = len(sizes)
    homes_distinct = np.repeat(np.arange(E), sizes)
    n = homes_distinct.size
    means = rng.normal(size=(E, K, 4))
    covs = np.stack([[random_spd(rng, 4, 0.6) for _ in range(K)] for _ in range(E)])
    positions = means[homes_distinct, rng.integers(0, K, n)] + rng.normal(size=(n, 4)) * 0.7
    visual = rng.integers(0, 3, size=(n, D))
    words = rng.integers(0, 2, size=(n, V))
    words[-1] = 0  # an untaught sample
    distinct = {"positions": positions, "visual": visual, "words": words, "homes": homes_distinct}
    homes = np.repeat(homes_distinct, copies)
    sizes_rep = np.bincount(homes, minlength=E)
    data = gibbs.PreparedData(
        positions=np.repeat(positions, copies, axis=0), homes=homes,
        visual=csr(np.repeat(visual, copies, axis=0)), words=csr(np.repeat(words, copies, axis=0)),
        n_homes=E, offsets=np.concatenate([[0], np.cumsum(sizes_rep)]), position_scale=1.0,
        map_centres=np.zeros((E, 4)),
    )
    log_phi_v = np.log(rng.dirichlet(np.full(D, 3.0), size=L))
    log_phi_w = np.log(rng.dirichlet(np.full(V, 3.0), size=L))
    state = gibbs.GibbsState(
        concepts=rng.integers(0, L, size=homes.size), regions=rng.integers(0, K, size=homes.size),
        log_g=np.log(rng.dirichlet(np.full(L, 3.0), size=E)), log_g0=np.log(rng.dirichlet(np.full(L, 3.0))),
        log_pi=np.log(rng.dirichlet(np.full(K, 2.0), size=(E, L))), means=means, covariances=covs,
        log_theta_v=np.log(rng.dirichlet(np.full(D, 2.0), size=(E, L))),
        log_theta_w=np.log(rng.dirichlet(np.full(V, 2.0), size=(E, L))),
        log_phi_v=log_phi_v, log_phi_w=log_phi_w, word_mask=np.ones(V, dtype=bool),
    )
    return data, state, distinct


def assignment_table(state: gibbs.GibbsState, distinct: dict[str, np.ndarray]) -> np.ndarray:
    """Brute force log p(C_t = l, R_t = m, x_t, v_t, w_t | parameters) of every distinct sample,
    written from the model's definition with SciPy: (n, L, K)."""
    n = distinct["homes"].size
    L, K = state.log_pi.shape[1:]
    out = np.empty((n, L, K))
    for t in range(n):
        e = distinct["homes"][t]
        gauss = np.array([stats.multivariate_normal.logpdf(distinct["positions"][t], state.means[e, m],
                                                           state.covariances[e, m]) for m in range(K)])
        concept = (distinct["visual"][t] @ state.log_theta_v[e].T
                   + distinct["words"][t] @ state.log_theta_w[e].T)
        out[t] = state.log_g[e][:, None] + state.log_pi[e] + gauss[None, :] + concept[:, None]
    return out


EXACT = gibbs.SamplerSettings.create("exact", prune=False)
REFERENCE = gibbs.SamplerSettings.create("reference", prune=False)


# ----------------------------------------------------------------------------- (a) joint (C, R)


def test_joint_assignment_marginals_match_enumeration() -> None:
    copies = 6000
    data, state, distinct = make_problem(1, sizes=(2, 2), L=3, K=2, D=4, V=3, copies=copies)
    table = assignment_table(state, distinct)
    assignments.local_step(data, state, EXACT, np.random.default_rng(2))
    flat = (state.concepts * 2 + state.regions).reshape(-1, copies)
    for t in range(table.shape[0]):
        probs = softmax(table[t].ravel())
        assert probs.max() < 0.95  # the problem is not degenerate
        assert chisquare_p(np.bincount(flat[t], minlength=6), probs) > P_MIN, t


def test_joint_assignment_whole_configuration_matches_enumeration() -> None:
    """p(C, R | rest) over all (L·K)^N configurations of N = 4 samples, enumerated from the
    joint density; the local step draws every sample at once, 4,000 repetitions."""
    data, state, distinct = make_problem(3, sizes=(2, 2), L=2, K=2, D=3, V=3)
    table = assignment_table(state, distinct)
    n = table.shape[0]
    configs = np.array(list(itertools.product(range(4), repeat=n)))  # flat l·K + m per sample
    log_joint = np.array([sum(table[t].ravel()[c[t]] for t in range(n)) for c in configs])
    probs = softmax(log_joint)
    # the library's log joint agrees with the brute force up to a constant (multinomial coefficients)
    lib = []
    for c in configs[:: 17]:
        state.concepts, state.regions = c // 2, c % 2
        lib.append(gibbs.log_joint(data, state, TransferHyperparameters(n_concepts=2, n_regions=2), EXACT))
    assert_allclose(np.array(lib) - log_joint[:: 17], lib[0] - log_joint[0], atol=1e-8)
    rng = np.random.default_rng(4)
    index = np.empty(4000, dtype=np.int64)
    for i in range(index.size):
        assignments.local_step(data, state, EXACT, rng)
        flat = state.concepts * 2 + state.regions
        index[i] = int(np.ravel_multi_index(tuple(flat), (4,) * n))
    assert chisquare_p(np.bincount(index, minlength=4**n), probs) > P_MIN


def test_joint_assignment_with_peaked_likelihoods() -> None:
    """S^w-like word counts (thousands) and ~7,000 visual counts: probabilities are still exact."""
    copies = 5000
    data, state, distinct = make_problem(5, sizes=(2, 1), L=3, K=2, D=4, V=3, copies=copies)
    rng = np.random.default_rng(6)
    # equalise concepts 0 and 1 up to a known log-odds of 0.7 for the first sample
    big_v = rng.integers(1000, 2500, size=(3, 4))
    big_w = np.array([[5000, 0, 5000], [0, 5000, 0], [0, 0, 0]])
    state.log_theta_v[:, 1] = state.log_theta_v[:, 0]
    state.log_theta_w[:, 1] = state.log_theta_w[:, 0]
    state.log_g[0, :2] = np.log([0.3, 0.3 * np.exp(0.7)])
    state.log_g[0] -= logsumexp(state.log_g[0])
    distinct["visual"], distinct["words"] = big_v, big_w
    data = gibbs.PreparedData(
        positions=data.positions, homes=data.homes, visual=csr(np.repeat(big_v, copies, axis=0)),
        words=csr(np.repeat(big_w, copies, axis=0)), n_homes=2, offsets=data.offsets, position_scale=1.0,
        map_centres=data.map_centres)
    table = assignment_table(state, distinct)
    assert np.ptp(table[0]) > 1000  # thousands of nats between the best and the worst
    assignments.local_step(data, state, EXACT, rng)
    flat = (state.concepts * 2 + state.regions).reshape(-1, copies)
    for t in range(3):
        assert chisquare_p(np.bincount(flat[t], minlength=6), softmax(table[t].ravel())) > P_MIN


# ----------------------------------------------------------------------------- (b) reference blocks


def test_reference_blocks_r_given_c_then_c_given_r() -> None:
    copies = 6000
    data, state, distinct = make_problem(7, sizes=(2, 2), L=3, K=3, D=3, V=3, copies=copies)
    table = assignment_table(state, distinct)
    old = np.array([0, 2, 1, 2])  # C of each distinct sample before the step
    state.concepts = np.repeat(old, copies)
    assignments.local_step(data, state, REFERENCE, np.random.default_rng(8))
    regions = state.regions.reshape(-1, copies)
    concepts = state.concepts.reshape(-1, copies)
    for t in range(4):
        p_r = softmax(table[t, old[t]])  # p(R | C_old) ∝ π_{C_old, m} N(x | m)
        assert chisquare_p(np.bincount(regions[t], minlength=3), p_r) > P_MIN
        p_c_given_r = softmax(table[t], axis=0)  # p(C = l | R = m) ∝ G_l π_{l,m} p(v, w | θ_l)
        pair = p_r[None, :] * p_c_given_r  # (L, K): R first, then C | R
        observed = np.zeros((3, 3))
        np.add.at(observed, (concepts[t], regions[t]), 1)
        assert chisquare_p(observed, pair) > P_MIN


def test_block_functions_match_brute_force() -> None:
    copies = 5000
    data, state, distinct = make_problem(9, sizes=(1, 2), L=2, K=3, D=3, V=2, copies=copies)
    table = assignment_table(state, distinct)
    rng = np.random.default_rng(10)
    region_ll = GaussianRegions.log_likelihood(data.positions, data.homes, state.means, state.covariances)
    concept_ll = assignments.concept_loglik(data, state)
    fixed = np.repeat(np.array([1, 0, 2]), copies)
    c_given = np.repeat(np.array([0, 1, 1]), copies)
    r = allocation.sample_regions_given_concepts(state.log_pi, data.homes, c_given, region_ll, rng)
    c = allocation.sample_concepts_given_regions(state.log_g, state.log_pi, data.homes, fixed, concept_ll,
                                                 rng)
    for t in range(3):
        block = slice(t * copies, (t + 1) * copies)
        assert chisquare_p(np.bincount(r[block], minlength=3), softmax(table[t, c_given[block][0]])) > P_MIN
        assert chisquare_p(np.bincount(c[block], minlength=2), softmax(table[t, :, fixed[block][0]])) > P_MIN


# ----------------------------------------------------------------------------- (c) CRT auxiliary variables


def grid_cdf(log_density_p: callable) -> tuple[np.ndarray, np.ndarray]:
    """CDF on a logit grid of a density on (0, 1) given by its unnormalised log."""
    u = np.linspace(-30.0, 30.0, 300_001)
    p = expit(u)
    log_dens_u = log_density_p(p) + np.log(p) + np.log1p(-p)  # Jacobian dp/du = p(1 − p)
    assert np.isfinite(log_dens_u).all()
    dens = np.exp(log_dens_u - log_dens_u.max())
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(u))])
    return u, cdf / cdf[-1]


def log_dm_posterior(p: np.ndarray, counts: np.ndarray, prior: float, concentration: float) -> np.ndarray:
    """log [Dir(φ | prior) Π_e DM(n_e | concentration · φ)] for φ = (p, 1 − p), up to a constant."""
    phi = np.stack([p, 1.0 - p], axis=-1)
    a = concentration * phi
    out = (prior - 1.0) * np.log(phi).sum(-1)
    for n_e in counts:
        out += (gammaln(a + n_e) - gammaln(a)).sum(-1)
    return out


@pytest.mark.parametrize(("counts", "delta", "alpha"), [
    (np.array([[3, 7], [10, 2]]), 5.0, 1.0),  # exact Bernoulli sums
    (np.array([[0, 4], [1, 0], [6, 6]]), 2.0, 0.5),  # empty cells, a Dir(0.5) prior
    (np.array([[60, 140], [90, 35]]), 30.0, 1.0),  # the moment-matched tail (n > 40)
])
def test_phi_table_chain_leaves_exact_posterior_invariant(counts: np.ndarray, delta: float,
                                                          alpha: float) -> None:
    """Alternate (tables | φ, n) and (φ | tables) in 4,000 independent chains (the concept axis
    of HierarchicalMultinomial); after 150 steps the chains' φ are draws from p(φ | n)."""
    chains, steps = 4000, 150
    rng = np.random.default_rng(101)
    n = np.broadcast_to(counts[:, None, :], (counts.shape[0], chains, 2)).copy()
    log_phi = np.log(rng.dirichlet([alpha, alpha], size=chains))
    for _ in range(steps):
        tables = HierarchicalMultinomial.sample_tables(n, log_phi, delta, rng)
        assert tables.shape == (chains, 2)
        log_phi = HierarchicalMultinomial.sample_shared(tables, alpha, rng)
    u, cdf = grid_cdf(lambda p: log_dm_posterior(p, counts, alpha, delta))
    draws = logit(np.exp(log_phi[:, 0]))
    result = stats.kstest(draws, lambda x: np.interp(x, u, cdf))
    assert result.pvalue > P_MIN, result


def test_phi_table_chain_detects_a_wrong_posterior() -> None:
    """The invariance test has power: the pooled-count update of the reference variant (φ ~ Dir(α +
    Σ_e n), the δ → ∞ limit) does not pass it on the same counts."""
    counts, delta, alpha = np.array([[3, 7], [10, 2]]), 5.0, 1.0
    rng = np.random.default_rng(12)
    pooled = np.exp(HierarchicalMultinomial.sample_shared(np.tile(counts.sum(0), (4000, 1)).astype(float),
                                                          alpha, rng))
    u, cdf = grid_cdf(lambda p: log_dm_posterior(p, counts, alpha, delta))
    assert stats.kstest(logit(pooled[:, 0]), lambda x: np.interp(x, u, cdf)).pvalue < 1e-6


def test_global_concept_weights_chain_leaves_exact_posterior_invariant() -> None:
    """G_0 | concept counts (L = 2) through allocation.sample_global_concept_weights: one long chain
    (the function draws one G_0), thinned so that successive kept draws are nearly independent."""
    n_el = np.array([[4, 1], [2, 5], [0, 3]])
    gamma, gamma0 = 2.0, 1.0
    rng = np.random.default_rng(13)
    log_g0 = np.log(np.array([0.5, 0.5]))
    kept = []
    for i in range(24_000):
        log_g0 = allocation.sample_global_concept_weights(n_el, log_g0, gamma, gamma0, rng)
        if i >= 1000 and i % 6 == 0:
            kept.append(np.exp(log_g0[0]))
    draws = np.array(kept)
    assert abs(np.corrcoef(draws[:-1], draws[1:])[0, 1]) < 0.1  # thinning makes the KS test valid
    u, cdf = grid_cdf(lambda p: log_dm_posterior(p, n_el, gamma0 / 2, gamma))
    result = stats.kstest(logit(draws), lambda x: np.interp(x, u, cdf))
    assert result.pvalue > P_MIN, result


# ----------------------------------------------------------------------------- (d) Dirichlet posteriors


def dirichlet_z(log_p: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """z-scores of the sample mean and variance of Dirichlet draws (batch axis 0) vs exact."""
    p = np.exp(log_p)
    n = p.shape[0]
    a0 = alpha.sum(-1, keepdims=True)
    mean = alpha / a0
    var = alpha * (a0 - alpha) / (a0**2 * (a0 + 1))
    z_m = (p.mean(0) - mean) / np.sqrt(var / n)
    centred = p - p.mean(0)
    se_var = np.sqrt(np.maximum((centred**4).mean(0) - (centred**2).mean(0) ** 2, 1e-300) / n)
    z_v = (p.var(0, ddof=1) - var) / se_var
    return z_m, z_v


def test_theta_given_phi_and_counts() -> None:
    rng = np.random.default_rng(14)
    L, D, reps = 2, 4, 20_000
    log_phi = np.log(rng.dirichlet(np.ones(D), size=L))
    counts = np.array([[0, 3, 1, 0], [5, 0, 0, 2]])
    delta = 6.0
    log_theta = HierarchicalMultinomial.sample_specific(np.broadcast_to(counts, (reps, L, D)), log_phi, delta,
                                                        rng)
    assert log_theta.shape == (reps, L, D)
    z_m, z_v = dirichlet_z(log_theta, delta * np.exp(log_phi) + counts)
    assert np.abs(z_m).max() < Z_MAX and np.abs(z_v).max() < Z_MAX


def test_home_concept_weights_and_region_weights() -> None:
    rng = np.random.default_rng(15)
    reps = 20_000
    n_el = np.array([3, 0, 8])
    log_g0 = np.log(np.array([0.2, 0.5, 0.3]))
    gamma = 4.0
    log_g = allocation.sample_home_concept_weights(np.broadcast_to(n_el, (reps, 3)), log_g0, gamma, rng)
    z_m, z_v = dirichlet_z(log_g, gamma * np.exp(log_g0) + n_el)
    assert np.abs(z_m).max() < Z_MAX and np.abs(z_v).max() < Z_MAX
    # the authors' extra pseudo-count (reference variant) is added to every entry
    log_g = allocation.sample_home_concept_weights(np.broadcast_to(n_el, (reps, 3)), log_g0, gamma, rng,
                                                   extra=50.0)
    assert np.abs(dirichlet_z(log_g, gamma * np.exp(log_g0) + n_el + 50.0)[0]).max() < Z_MAX
    n_elm = np.array([[[2, 0, 1, 0], [0, 0, 0, 0]]])
    beta_over_k = 0.25
    log_pi = allocation.sample_region_weights(np.broadcast_to(n_elm, (reps, 2, 4)), beta_over_k, rng)
    z_m, z_v = dirichlet_z(log_pi, beta_over_k + n_elm[0])
    assert np.abs(z_m).max() < Z_MAX
    assert np.abs(z_v[0]).max() < Z_MAX  # the empty concept's π ~ Dir(0.25): heavy fourth moments


def test_count_statistics_match_brute_force() -> None:
    data, state, distinct = make_problem(16, sizes=(3, 2), L=3, K=2, D=4, V=3)
    hyper = TransferHyperparameters(n_concepts=3, n_regions=2)
    stats_ = sweep_statistics.sufficient_statistics(data, state, hyper, None)
    E, L, K = 2, 3, 2
    n_el = np.zeros((E, L), dtype=int)
    n_elm = np.zeros((E, L, K), dtype=int)
    vis = np.zeros((E, L, 4))
    for t, e in enumerate(distinct["homes"]):
        n_el[e, state.concepts[t]] += 1
        n_elm[e, state.concepts[t], state.regions[t]] += 1
        vis[e, state.concepts[t]] += distinct["visual"][t]
    assert_allclose(stats_.concepts, n_el)
    assert_allclose(stats_.regions_by_concept, n_elm)
    assert_allclose(stats_.visual, vis)
    for e in range(E):
        for m in range(K):
            pts = distinct["positions"][(distinct["homes"] == e) & (state.regions == m)]
            assert stats_.region_count[e, m] == len(pts)
            assert_allclose(stats_.region_total[e, m], pts.sum(0), atol=1e-12)
            assert_allclose(stats_.region_scatter[e, m], pts.T @ pts, atol=1e-12)


# ----------------------------------------------------------------------------- (e) NIW posterior draws


def test_region_gaussians_posterior_moments() -> None:
    rng = np.random.default_rng(17)
    d, K, reps = 4, 3, 20_000
    points = [rng.normal(loc=[1.0, -1.0, 0.0, 0.5], scale=0.5, size=(n, d)) for n in (6, 1, 0)]
    mu0 = np.array([0.5, 0.0, 0.0, 0.0])
    prior = NIWPrior(mu0=np.tile(mu0, (reps, 1)), kappa0=0.5, psi0=np.diag([0.2, 0.3, 0.1, 0.1]), nu0=8.0)
    positions = np.concatenate(points)
    regions = np.repeat(np.arange(K), [len(p) for p in points])
    homes = np.zeros(len(positions), dtype=int)
    count, total, scatter = GaussianRegions.statistics(positions, homes, regions, 1, K)
    tile = lambda a: np.broadcast_to(a, (reps, *a.shape[1:]))  # noqa: E731
    mu, sigma = GaussianRegions.sample_posterior(tile(count), tile(total), tile(scatter), prior, rng)
    assert mu.shape == (reps, K, d) and sigma.shape == (reps, K, d, d)
    for m, x in enumerate(points):
        n = len(x)
        kappa_n, nu_n = prior.kappa0 + n, prior.nu0 + n
        if n:
            xbar = x.mean(0)
            s = (x - xbar).T @ (x - xbar)
            mu_n = (prior.kappa0 * mu0 + n * xbar) / kappa_n
            psi_n = prior.psi0 + s + prior.kappa0 * n / kappa_n * np.outer(xbar - mu0, xbar - mu0)
        else:
            mu_n, psi_n = mu0, prior.psi0
        mean_sigma = psi_n / (nu_n - d - 1)
        entries = sigma[:, m].reshape(reps, -1)
        z = (entries.mean(0) - mean_sigma.ravel()) / (entries.std(0) / np.sqrt(reps))
        assert np.abs(z).max() < Z_MAX, m
        z_mu = (mu[:, m].mean(0) - mu_n) / (mu[:, m].std(0) / np.sqrt(reps))
        assert np.abs(z_mu).max() < Z_MAX, m
        # Var[μ_i] = E[Σ_ii]/κ_n
        centred = mu[:, m] - mu[:, m].mean(0)
        se = np.sqrt(((centred**4).mean(0) - (centred**2).mean(0) ** 2) / reps)
        z_var = (mu[:, m].var(0, ddof=1) - np.diag(mean_sigma) / kappa_n) / se
        assert np.abs(z_var).max() < Z_MAX, m


# ----------------------------------------------------------------------------- (f) label-swap moves


def log_dm(counts: np.ndarray, a: np.ndarray) -> float:
    """log Dirichlet–multinomial of a bag of counts (without the multinomial coefficient)."""
    return float(gammaln(a.sum()) - gammaln(a.sum() + counts.sum())
                 + (gammaln(a + counts) - gammaln(a)).sum())


def collapsed_home_log_marginal(concepts: np.ndarray, regions: np.ndarray, log_g: np.ndarray,
                                log_pi: np.ndarray, visual: np.ndarray, words: np.ndarray,
                                log_phi_v: np.ndarray, log_phi_w: np.ndarray, log_g0: np.ndarray,
                                hyper: TransferHyperparameters, word_mask: np.ndarray) -> float:
    """log p(C, G_e, π_e, data | φ, G_0) of one home with θ^v, θ^w integrated out, by brute force
    (Gaussian terms left out: they do not involve concepts)."""
    L, K = log_pi.shape
    g_prior = stats.dirichlet.logpdf(np.exp(log_g), hyper.gamma * np.exp(log_g0))
    pi_prior = sum(stats.dirichlet.logpdf(np.exp(log_pi[c]), np.full(K, hyper.beta / K)) for c in range(L))
    assignments = float((log_g[concepts] + log_pi[concepts, regions]).sum())
    kept = log_phi_w[:, word_mask]
    phi_w = np.exp(kept - logsumexp(kept, axis=1, keepdims=True))  # φ^w renormalised over kept words
    likelihood = 0.0
    for c in range(L):
        mine = concepts == c
        likelihood += log_dm(visual[mine].sum(0), hyper.delta_visual * np.exp(log_phi_v[c]))
        likelihood += log_dm(words[mine][:, word_mask].sum(0), hyper.delta_word * phi_w[c])
    return float(g_prior + pi_prior + assignments + likelihood)


def swapped(a: int, b: int, concepts: np.ndarray, log_g: np.ndarray,
            log_pi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The state with concept labels a and b exchanged (samples, G_e and π_e together)."""
    perm = np.arange(log_g.size)
    perm[[a, b]] = [b, a]
    return perm[concepts], log_g[perm], log_pi[perm]


def acceptance_threshold(args: dict, e: int, a: int, b: int) -> float:
    """The log acceptance ratio Δ the compiled pass uses for proposing to swap slots a, b of home
    e, found by bisection on the uniform (accepted iff log u < Δ); ±inf if always / never accepted."""
    homes = slice(e, e + 1)
    pairs = np.array([[[a, b]]], dtype=np.int64)

    def accepted(log_u: float) -> bool:
        perm = args["compiled_pass"](args["alpha_v"], args["counts_v"][homes], args["alpha_w"],
                                     args["counts_w"][homes], args["g_term"], args["log_g"][homes], pairs,
                                     np.array([[log_u]]))[0]
        return bool(perm[a] == b and perm[b] == a)

    low, high = -1e6, 1e6
    if not accepted(low):
        return -np.inf
    if accepted(high):
        return np.inf
    while high - low > 1e-9 * max(1.0, abs(low)):
        mid = 0.5 * (low + high)
        if accepted(mid):
            low = mid
        else:
            high = mid
    return 0.5 * (low + high)


def capture_pass_arguments(monkeypatch: pytest.MonkeyPatch) -> dict:
    """Record the arguments concept_swap_step hands to the compiled pass."""
    real_pass = moves._matching_pass
    captured: dict = {"compiled_pass": real_pass}

    def capture(alpha_v, counts_v, alpha_w, counts_w, g_term, log_g, pairs, log_u):
        captured.update(alpha_v=alpha_v, counts_v=counts_v, alpha_w=alpha_w, counts_w=counts_w, g_term=g_term,
                        log_g=log_g)
        return real_pass(alpha_v, counts_v, alpha_w, counts_w, g_term, log_g, pairs, log_u)

    monkeypatch.setattr(moves, "_matching_pass", capture)
    return captured


def swap_problem(seed: int) -> dict:
    """Two homes, three concepts (one of them empty in home 1), a few samples with counts."""
    rng = np.random.default_rng(seed)
    E, L, K, D, V = 2, 3, 2, 4, 3
    n = 9
    homes = np.repeat([0, 1], [5, 4])
    visual = rng.integers(0, 6, size=(n, D))
    words = rng.integers(0, 3, size=(n, V))
    concepts = np.array([0, 0, 1, 2, 1, 2, 2, 0, 0])  # home 1 leaves concept 1 empty
    n_v = np.zeros((E, L, D), dtype=np.int64)
    n_w = np.zeros((E, L, V), dtype=np.int64)
    np.add.at(n_v, (homes, concepts), visual)
    np.add.at(n_w, (homes, concepts), words)
    return dict(
        hyper=TransferHyperparameters(n_concepts=L, n_regions=K, alpha_visual=1.0, alpha_word=1.0,
                                      delta_visual=4.0, delta_word=3.0, gamma=2.5, gamma0=1.0, beta=1.5),
        homes=homes, visual=visual, words=words, concepts=concepts, regions=rng.integers(0, K, size=n),
        log_g=np.log(rng.dirichlet(np.ones(L), size=E)), log_g0=np.log(rng.dirichlet(np.full(L, 2.0))),
        log_pi=np.log(rng.dirichlet(np.ones(K), size=(E, L))),
        log_phi_v=np.log(rng.dirichlet(np.full(D, 2.0), size=L)),
        log_phi_w=np.log(rng.dirichlet(np.full(V, 2.0), size=L)), n_v=n_v, n_w=n_w, rng=rng,
    )


def check_swap_ratios(problem: dict, word_mask: np.ndarray, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every proposal's log acceptance ratio equals the brute-force collapsed log ratio."""
    P = problem
    hyper = P["hyper"]
    args = capture_pass_arguments(monkeypatch)
    moves.concept_swap_step(P["n_v"], P["log_phi_v"], hyper.delta_visual, P["n_w"], P["log_phi_w"],
                            hyper.delta_word, P["log_g"], P["log_g0"], hyper.gamma, word_mask, P["rng"])
    L = hyper.n_concepts
    for e in range(2):
        mine = P["homes"] == e
        common = dict(visual=P["visual"][mine], words=P["words"][mine], log_phi_v=P["log_phi_v"],
                      log_phi_w=P["log_phi_w"], log_g0=P["log_g0"], hyper=hyper, word_mask=word_mask)
        c_e, r_e = P["concepts"][mine], P["regions"][mine]
        base = collapsed_home_log_marginal(c_e, r_e, P["log_g"][e], P["log_pi"][e], **common)
        for a, b in itertools.combinations(range(L), 2):
            c2, g2, pi2 = swapped(a, b, c_e, P["log_g"][e], P["log_pi"][e])
            exact = collapsed_home_log_marginal(c2, r_e, g2, pi2, **common) - base
            assert np.isfinite(exact)
            used = acceptance_threshold(args, e, a, b)
            assert used == pytest.approx(exact, abs=1e-6), (e, a, b)


@pytest.mark.parametrize("prune_word", [False, True])
def test_label_swap_log_ratio_equals_collapsed_marginal_ratio(monkeypatch: pytest.MonkeyPatch,
                                                              prune_word: bool) -> None:
    problem = swap_problem(18)
    mask = np.array([True, False, True]) if prune_word else np.ones(3, dtype=bool)
    check_swap_ratios(problem, mask, monkeypatch)


def test_label_swap_with_shared_word_mass_on_a_pruned_word(monkeypatch: pytest.MonkeyPatch) -> None:
    """A concept whose φ^w puts (nearly) all its mass on pruned words — an unused concept's draw from
    Dir(α^w = 0.01) often does — still has a well-defined distribution over the kept words (renormalised
    in log space); its swap proposals must use it, not NaN."""
    problem = swap_problem(18)
    problem["log_phi_w"][2] = [-900.0, 0.0, -903.0]  # mass on word 1, which is pruned
    check_swap_ratios(problem, np.array([True, False, True]), monkeypatch)


def test_label_swap_acceptance_rate_is_metropolis() -> None:
    """With L = 2 there is one proposal per home; it is accepted with probability min(1, e^Δ)."""
    rng = np.random.default_rng(19)
    hyper = TransferHyperparameters(n_concepts=2, n_regions=1, delta_visual=3.0, delta_word=2.0, gamma=2.0)
    n_v = np.array([[[1, 1, 0], [0, 1, 1]], [[1, 1, 1], [0, 0, 2]]], dtype=np.int64)
    n_w = np.array([[[1, 0], [0, 1]], [[0, 0], [1, 0]]], dtype=np.int64)
    log_phi_v = np.log(np.array([[0.45, 0.35, 0.2], [0.2, 0.35, 0.45]]))
    log_phi_w = np.log(np.array([[0.6, 0.4], [0.45, 0.55]]))
    log_g = np.log(np.array([[0.3, 0.7], [0.5, 0.5]]))
    log_g0 = np.log(np.array([0.4, 0.6]))
    mask = np.ones(2, dtype=bool)
    expected = []
    for e in range(2):
        # the assignments' terms are unchanged by a swap; the concepts' counts enter as bags
        base = sum(log_dm(n_v[e, c], hyper.delta_visual * np.exp(log_phi_v[c]))
                   + log_dm(n_w[e, c], hyper.delta_word * np.exp(log_phi_w[c])) for c in range(2))
        swap = sum(log_dm(n_v[e, 1 - c], hyper.delta_visual * np.exp(log_phi_v[c]))
                   + log_dm(n_w[e, 1 - c], hyper.delta_word * np.exp(log_phi_w[c])) for c in range(2))
        g_prior = lambda lg: stats.dirichlet.logpdf(np.exp(lg), hyper.gamma * np.exp(log_g0))  # noqa: E731
        delta = swap - base + g_prior(log_g[e][::-1]) - g_prior(log_g[e])
        expected.append(min(1.0, np.exp(delta)))
    reps = 10_000
    accepted = np.zeros(2)
    for _ in range(reps):
        perms = moves.concept_swap_step(n_v, log_phi_v, hyper.delta_visual, n_w, log_phi_w, hyper.delta_word,
                                        log_g, log_g0, hyper.gamma, mask, rng)
        accepted += perms[:, 0] == 1
    for e in range(2):
        p = expected[e]
        assert 0.05 < p < 0.95  # a non-trivial acceptance probability
        z = (accepted[e] / reps - p) / np.sqrt(p * (1 - p) / reps)
        assert abs(z) < Z_MAX, (e, accepted[e] / reps, p)


# ----------------------------------------------------------------------------- (g) pruning scores


def mi_table(table: np.ndarray) -> float:
    """Mutual information of a 2-D joint probability table, brute force."""
    rows = table.sum(1, keepdims=True)
    cols = table.sum(0, keepdims=True)
    total = 0.0
    for i, j in np.ndindex(table.shape):
        if table[i, j] > 0:
            total += table[i, j] * np.log(table[i, j] / (rows[i, 0] * cols[0, j]))
    return total


def test_concept_word_mutual_information_brute_force() -> None:
    rng = np.random.default_rng(20)
    L, V = 4, 6
    phi = np.zeros((L, V))
    phi[:, :5] = rng.dirichlet(np.full(5, 0.5), size=L)
    phi[0, 2] = 0.0  # a word concept 0 never says
    phi[:, :5] *= 0.9 / phi[:, :5].sum(1, keepdims=True)
    phi[:, 5] = 0.1  # a word every concept says alike
    g = rng.dirichlet(np.ones(L))
    mi = concept_word_mutual_information(phi, g)
    for c, k in np.ndindex(L, V):
        others = np.arange(L) != c
        table = np.array([
            [phi[c, k] * g[c], (phi[others, k] * g[others]).sum()],
            [(1 - phi[c, k]) * g[c], ((1 - phi[others, k]) * g[others]).sum()],
        ])
        assert mi[c, k] == pytest.approx(mi_table(table), abs=1e-12), (c, k)
    # word-level MI with the whole concept variable: a 2 × L table
    word_mi = word_concept_mutual_information(phi, g)
    for k in range(V):
        table = np.stack([phi[:, k] * g, (1 - phi[:, k]) * g])
        assert word_mi[k] == pytest.approx(mi_table(table), abs=1e-12)
    assert word_mi[5] == pytest.approx(0.0, abs=1e-12)
    keep = words_to_keep(phi, g, threshold=0.05, score="mi")
    assert_allclose(keep, mi.max(0) >= 0.05)


def test_bernoulli_kl_scores_formula() -> None:
    rng = np.random.default_rng(21)
    L, V = 3, 5
    phi = rng.dirichlet(np.ones(V), size=L)
    phi[1, 0] = 0.0
    g = rng.dirichlet(np.ones(L))
    kl = bernoulli_kl_scores(phi, g)
    for c, k in np.ndindex(L, V):
        p, q = phi[c, k], g @ phi[:, k]
        expected = (p * np.log(p / q) if p > 0 else 0.0) + (1 - p) * np.log((1 - p) / (1 - q))
        assert kl[c, k] == pytest.approx(expected, abs=1e-12)
    assert_allclose(words_to_keep(phi, g, threshold=0.1, score="kl"), kl.max(0) >= 0.1)
