"""Joint-distribution test ("getting it right", Geweke 2004) of the whole exact Gibbs sampler.

Two ways of drawing (parameters, assignments, data) must agree in distribution:

- the *marginal-conditional* simulator draws everything from the prior and the model;
- the *successive-conditional* simulator alternates "data | parameters, assignments" (from the
  model) with one sweep of the exact sampler (local step, statistics, shared step, home step,
  label swaps — the order of :func:`spco.model.gibbs.sweep`), started from a prior draw.

If every conditional of the sweep is right, the chain leaves the joint distribution invariant and
both simulators give the same expectations of any statistic; a wrong conditional (a missing
pseudo-count, a wrong table count, the wrong update order of the partially collapsed steps, a
biased label swap) shifts some of them by many standard errors. Expectations are compared by
z-tests with batch-means standard errors for the chain.

The model is tiny and well-behaved: E = 2 homes, L = 2 concepts, K = 2 regions, D = 3 visual
features (4 counts per sample), V = 3 words (S^w = 1, every sample taught), 5 samples per home,
α = 1, δ^v = δ^w = 5, γ = 2, γ0 = 1, β = 1, positions in sampler units with a small Ψ0.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy import stats
from scipy.special import logsumexp

from spco.model import assignments, gibbs, parameter_steps, sweep_statistics
from spco.model.hyperparameters import TransferHyperparameters

E, L, K, D, V = 2, 2, 2, 3, 3
PER_HOME = 5
N = E * PER_HOME
HOMES = np.repeat(np.arange(E), PER_HOME)
VISUAL_COUNTS = 4
WORD_COUNTS = 1

HYPER = TransferHyperparameters(
    n_concepts=L, n_regions=K, alpha_visual=1.0, alpha_word=1.0, delta_visual=5.0, delta_word=5.0, gamma=2.0,
    gamma0=1.0, beta=1.0, kappa0=1.0, nu0=10.0, psi0=(1.0, 1.0, 1.0, 1.0), psi0_in_cm2=False,
    mu0=(0.0, 0.0, 0.0, 0.0),
)
SETTINGS = gibbs.SamplerSettings.create("exact", prune=False)

N_PRIOR = 30_000
N_CHAIN = 5_000
BATCH = 100
Z_MAX = 4.0


# tiny problems call the compiled kernels thousands of times: one thread (conftest.py)
pytestmark = pytest.mark.usefixtures("single_numba_thread")


# ----------------------------------------------------------------------------- the model, written out


def log_dirichlet_draws(alpha: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Dirichlet draws along the last axis as logs, by Gamma(a) = Gamma(a + 1) · U^{1/a}
    (exact for the tiny concentrations γ G_0 and δ φ can reach)."""
    log_g = np.log(rng.standard_gamma(alpha + 1.0)) + np.log(rng.random(alpha.shape)) / alpha
    return log_g - logsumexp(log_g, axis=-1, keepdims=True)


def categorical(probs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One draw per row of ``probs`` (..., J)."""
    cdf = np.cumsum(probs, axis=-1)
    u = rng.random((*probs.shape[:-1], 1)) * cdf[..., -1:]
    return np.minimum((u > cdf).sum(-1), probs.shape[-1] - 1)


def draw_parameters(rng: np.random.Generator, m: int) -> dict[str, np.ndarray]:
    """m independent draws of every parameter from the prior (probabilities as logs)."""
    log_g0 = log_dirichlet_draws(np.full((m, L), HYPER.gamma0 / L), rng)
    log_g = log_dirichlet_draws(HYPER.gamma * np.exp(log_g0)[:, None, :] * np.ones((1, E, 1)), rng)
    log_phi_v = log_dirichlet_draws(np.full((m, L, D), HYPER.alpha_visual), rng)
    log_phi_w = log_dirichlet_draws(np.full((m, L, V), HYPER.alpha_word), rng)
    log_theta_v = log_dirichlet_draws(HYPER.delta_visual * np.exp(log_phi_v)[:, None] * np.ones((1, E, 1, 1)),
                                      rng)
    log_theta_w = log_dirichlet_draws(HYPER.delta_word * np.exp(log_phi_w)[:, None] * np.ones((1, E, 1, 1)),
                                      rng)
    log_pi = log_dirichlet_draws(np.full((m, E, L, K), HYPER.beta / K), rng)
    psi0 = np.diag(np.asarray(HYPER.psi0, dtype=float))
    sigma = np.asarray(stats.invwishart.rvs(df=HYPER.nu0, scale=psi0, size=m * E * K, random_state=rng))
    sigma = sigma.reshape(m, E, K, 4, 4)
    chol = np.linalg.cholesky(sigma / HYPER.kappa0)
    mu = np.asarray(HYPER.mu0) + np.einsum("...ij,...j->...i", chol, rng.standard_normal((m, E, K, 4)))
    return dict(log_g0=log_g0, log_g=log_g, log_phi_v=log_phi_v, log_phi_w=log_phi_w, log_theta_v=log_theta_v,
                log_theta_w=log_theta_w, log_pi=log_pi, means=mu, covariances=sigma)


def draw_assignments(params: dict[str, np.ndarray],
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """C_t ~ G_e, R_t ~ π_{e,C_t} for the N samples of every draw: (m, N) each."""
    m = params["log_g"].shape[0]
    concepts = categorical(np.exp(params["log_g"][:, HOMES]), rng)  # (m, N)
    pi = np.exp(params["log_pi"][np.arange(m)[:, None], HOMES[None, :], concepts])  # (m, N, K)
    return concepts, categorical(pi, rng)


def draw_data(params: dict[str, np.ndarray], concepts: np.ndarray, regions: np.ndarray,
              rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Positions, visual and word counts of every sample given the parameters and assignments."""
    m = concepts.shape[0]
    rows = np.arange(m)[:, None]
    mu = params["means"][rows, HOMES[None, :], regions]  # (m, N, 4)
    chol = np.linalg.cholesky(params["covariances"][rows, HOMES[None, :], regions])
    x = mu + np.einsum("...ij,...j->...i", chol, rng.standard_normal((m, N, 4)))
    theta_v = np.exp(params["log_theta_v"][rows, HOMES[None, :], concepts])  # (m, N, D)
    theta_w = np.exp(params["log_theta_w"][rows, HOMES[None, :], concepts])
    visual = rng.multinomial(VISUAL_COUNTS, theta_v / theta_v.sum(-1, keepdims=True))
    words = rng.multinomial(WORD_COUNTS, theta_w / theta_w.sum(-1, keepdims=True))
    return dict(positions=x, visual=visual, words=words)


# ----------------------------------------------------------------------------- statistics


STATISTICS = (
    # label-specific: the chain must also move between labellings
    "phi_v[0,0]", "G0[0]", "G[0,0]", "theta_w[0,0,0]", "pi[0,0,0]", "mu[0,0,0]", "frac C=0",
    # label-invariant: concentrations and couplings of the hierarchy
    "sum G0^2", "G0 . G[1]", "sum phi_v^2", "sum phi_w^2", "phi_v . theta_v[0]", "phi_w . theta_w[1]",
    "sum pi[0]^2", "trace Sigma[0,0]", "mu[1,1,1]^2",
    # fit of parameters to the data and assignments drawn with them
    "phi_v fit", "phi_w fit", "theta_v fit", "theta_w fit", "pi fit", "G fit", "G0 fit", "gauss fit",
    "C0==C1 (home 0)", "C(home 0)==C(home 1)", "x[0,0]^2", "w0*v0",
)


def statistics(params: dict[str, np.ndarray], concepts: np.ndarray, regions: np.ndarray,
               data: dict[str, np.ndarray]) -> np.ndarray:
    """The compared statistics of m draws: (m, len(STATISTICS))."""
    phi_v, phi_w = np.exp(params["log_phi_v"]), np.exp(params["log_phi_w"])
    g0, g = np.exp(params["log_g0"]), np.exp(params["log_g"])
    theta_v, theta_w = np.exp(params["log_theta_v"]), np.exp(params["log_theta_w"])
    pi, sigma, mu = np.exp(params["log_pi"]), params["covariances"], params["means"]
    x, v, w = data["positions"], data["visual"], data["words"]
    m = concepts.shape[0]
    rows = np.arange(m)[:, None]
    homes = HOMES[None, :]

    def fit(table: np.ndarray, counts: np.ndarray, total: int) -> np.ndarray:
        return (table * counts).sum(-1).mean(1) / total

    columns = [
        phi_v[:, 0, 0], g0[:, 0], g[:, 0, 0], theta_w[:, 0, 0, 0], pi[:, 0, 0, 0], mu[:, 0, 0, 0],
        (concepts == 0).mean(1),
        (g0**2).sum(1), (g0 * g[:, 1]).sum(1), (phi_v**2).sum((1, 2)) / L, (phi_w**2).sum((1, 2)) / L,
        (phi_v * theta_v[:, 0]).sum((1, 2)), (phi_w * theta_w[:, 1]).sum((1, 2)), (pi[:, 0] ** 2).sum((1, 2)),
        np.trace(sigma[:, 0, 0], axis1=-2, axis2=-1), mu[:, 1, 1, 1] ** 2,
        fit(phi_v[rows, concepts], v, VISUAL_COUNTS), fit(phi_w[rows, concepts], w, WORD_COUNTS),
        fit(theta_v[rows, homes, concepts], v, VISUAL_COUNTS),
        fit(theta_w[rows, homes, concepts], w, WORD_COUNTS),
        pi[rows, homes, concepts, regions].mean(1), g[rows, homes, concepts].mean(1),
        g0[rows, concepts].mean(1),
        ((x - mu[rows, homes, regions]) ** 2).sum(-1).mean(1),
        (concepts[:, 0] == concepts[:, 1]).astype(float),
        (concepts[:, 0] == concepts[:, PER_HOME]).astype(float),
        x[:, 0, 0] ** 2, (w[:, :, 0] * v[:, :, 0]).mean(1),
    ]
    return np.column_stack(columns)


# ----------------------------------------------------------------------------- the two simulators


def prepared(data: dict[str, np.ndarray]) -> gibbs.PreparedData:
    """PreparedData of one draw (index 0), in the sampler's layout and units (metres, scale 1)."""

    def csr(dense: np.ndarray) -> sp.csr_array:
        rows, cols = np.nonzero(dense)
        indptr = np.zeros(N + 1, dtype=np.int64)
        np.cumsum(np.bincount(rows, minlength=N), out=indptr[1:])
        out = sp.csr_array((dense[rows, cols].astype(np.float64), cols, indptr), shape=dense.shape)
        out.indices = out.indices.astype(np.int64)  # the layout of the sampler's counts
        out.indptr = out.indptr.astype(np.int64)
        return out

    return gibbs.PreparedData(
        positions=np.ascontiguousarray(data["positions"][0]), homes=HOMES, visual=csr(data["visual"][0]),
        words=csr(data["words"][0]), n_homes=E, offsets=np.arange(0, N + 1, PER_HOME), position_scale=1.0,
        map_centres=np.zeros((E, 4)),
    )


PARAMETER_NAMES = ("log_g0", "log_g", "log_phi_v", "log_phi_w", "log_theta_v", "log_theta_w", "log_pi",
                   "means", "covariances")


def marginal_conditional(rng: np.random.Generator) -> np.ndarray:
    params = draw_parameters(rng, N_PRIOR)
    concepts, regions = draw_assignments(params, rng)
    data = draw_data(params, concepts, regions, rng)
    return statistics(params, concepts, regions, data)


def successive_conditional(rng: np.random.Generator) -> np.ndarray:
    params = draw_parameters(rng, 1)
    concepts, regions = draw_assignments(params, rng)
    state = gibbs.GibbsState(
        concepts=concepts[0], regions=regions[0], word_mask=np.ones(V, dtype=bool),
        **{name: params[name][0] for name in PARAMETER_NAMES},
    )
    out = np.empty((N_CHAIN, len(STATISTICS)))
    for i in range(N_CHAIN):
        params = {name: getattr(state, name)[None] for name in PARAMETER_NAMES}
        c, r = state.concepts[None], state.regions[None]
        data = draw_data(params, c, r, rng)  # data | parameters, assignments
        prep = prepared(data)
        # one sweep of the exact sampler, in the order of gibbs.sweep
        assignments.local_step(prep, state, SETTINGS, rng)
        suff = sweep_statistics.sufficient_statistics(prep, state, HYPER, SETTINGS.learning_view_counts())
        parameter_steps.global_step(suff, state, HYPER, rng)
        parameter_steps.home_step(prep, state, suff, HYPER, SETTINGS, rng)
        parameter_steps.swap_labels(prep, state, suff, HYPER, SETTINGS, rng)
        params = {name: getattr(state, name)[None] for name in PARAMETER_NAMES}
        # (new parameters, data they were drawn from) is a draw from the joint distribution
        out[i] = statistics(params, state.concepts[None], state.regions[None], data)[0]
    return out


def batch_means_se(values: np.ndarray, batch: int) -> np.ndarray:
    """Standard error of the mean of a chain by non-overlapping batch means, per column."""
    n = values.shape[0] // batch
    means = values[: n * batch].reshape(n, batch, -1).mean(1)
    return means.std(0, ddof=1) / np.sqrt(n)


def test_geweke_joint_distribution_exact_sampler() -> None:
    rng = np.random.default_rng(2024)
    prior = marginal_conditional(rng)
    chain = successive_conditional(rng)
    assert np.isfinite(prior).all() and np.isfinite(chain).all()
    se_prior = prior.std(0, ddof=1) / np.sqrt(prior.shape[0])
    se_chain = batch_means_se(chain, BATCH)
    z = (chain.mean(0) - prior.mean(0)) / np.sqrt(se_prior**2 + se_chain**2)
    report = "\n".join(f"{name:28s} prior {p:9.4f}  chain {c:9.4f}  z {zz:6.2f}"
                       for name, p, c, zz in zip(STATISTICS, prior.mean(0), chain.mean(0), z, strict=True))
    assert np.abs(z).max() < Z_MAX, report
    # the chain moves: every statistic varies along it (a stuck chain would pass the means by luck)
    assert (chain.std(0) > 0.2 * prior.std(0)).all(), report
