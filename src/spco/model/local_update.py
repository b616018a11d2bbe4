"""A teaching as a local update of one home: the taught place changes, the rest of the home stays.

A home that is served is taught one sentence or one observation at a time. Re-running Gibbs sweeps
of the whole home from its state after each teaching (what adapting does) redraws every concept's
and every region's parameters and lets every sample move: each teaching is then a fresh random
perturbation of the whole home — a room nobody talked about can change its name — and the answers
at places the teaching said nothing about change from one teaching to the next.

:func:`teach_locally` updates instead only the part of the home the new evidence is about, as a
blocked Gibbs sampler whose blocks are the *affected* variables, all others conditioned on at their
current values (a valid MCMC step of the same posterior, restricted to a block):

1. a new observation's concept and region are drawn from their joint conditional given the home's
   other samples (:func:`_draw_assignments`), over every concept and region — not placed in
   region 0 and concept 0. The regions' Gaussians (and π, G_e) are integrated out there: a
   position is scored by the posterior predictive of each region's samples (a Student t,
   :class:`_RegionStatistics`), not by the last draw of its Gaussian — one narrow draw of a small
   region made a pose beside its samples improbable there, and the observation joined the next
   room's broad region (measured on the synthetic home of ``benchmarks/teaching.py``: a pose
   without a view landed in the taught room in 94 % of teachings instead of 92 %);
2. the affected set: the regions of the taught samples (``R_A``) plus one empty region, the
   *movable* samples (the taught ones and every sample of ``R_A``), and the affected concepts
   ``C_A``: the movable samples' concepts, the concept that explains a taught sentence's words
   best, and the concept a name first heard in the home gets
   (:func:`~spco.model.home_shard.own_names_to_free_concepts`) — only the names the teaching says:
   the home's other own names keep the concepts its posterior gave them (regrouping them at every
   teaching changed 1.23 % of the other places' top names on SIGVerse 3LDK_9 adapted with seed 1,
   ``benchmarks/teaching.py``), and a new name stands only for the taught samples' *places* — the
   untaught samples of a taught sample's region that share its concept — not for another concept's
   samples in that region (another room a region spans: on synthetic seed 11 a kitchen teaching
   renamed the bedroom's samples of a bedroom + kitchen region; other rooms' top names changed 0.42 %
   → 0.08 %, max 11.1 % → 0.7 %);
3. ``n_sweeps`` sweeps of that block: the movable samples' (concept, region) pairs from their
   joint conditional restricted to ``C_A × R_A``, given the regions' current Gaussians (the
   current pair is in it, so the step keeps the posterior; with the word channels the switches
   marginalised; the Gaussians not integrated out here: with the model's prior the collapsed
   conditional drains small regions into large ones — a teaching at six regions merged three of
   them into one — the uncollapsed sampler's slow mixing between region configurations is what
   keeps a teaching local), with the word channels the switch of each of their word tokens given
   its new concept (the taught tokens' switches are first drawn given their sample's concept; every
   other token keeps its switch), then θ^v, θ^w and π of ``C_A`` (and with the place channel's home
   level the home's ψ_{e,l} of ``C_A``, right after θ^w as the home step draws it:
   :func:`~spco.model.home_place.draw_home_place_of`; the other concepts keep theirs), the
   Gaussians of ``R_A``, and
   G_e's share among ``C_A`` given the share of the other concepts (the conditional of a
   Dirichlet's sub-vector);
   φ of a free concept in ``C_A`` (one the knowledge does not use) as adapting learns it; in the
   first :data:`SPLIT_SWEEPS` sweeps, before the parameters, the region of each taught sample's
   *place* — its concept's samples of its region, as one block — is drawn from its conditional
   (:func:`place_conditional`): a region of its own (one empty before the teaching) or any region
   holding no sample of that concept, in proportion to the NIW marginal likelihoods (the Gaussians
   integrated out; π's term cancels), so that a place told apart from the rest of its region by a
   teaching gets a region of its own when the positions prefer it, and gives it back when not;
4. the home's answers come from the posterior average (:class:`~spco.model.posterior.ParameterAverage`)
   of those sweeps for ``C_A`` and ``R_A`` — the Gaussians of ``R_A``'s occupied regions averaged as
   their posterior mean given each averaged sweep's assignments (:func:`expected_gaussians`: the
   moments of the NIW posterior predictive, what infinitely many draws average to), not the two draws
   a teaching's sweeps leave (a Rao–Blackwellised estimate of the same average) — and from the
   home's previous average for every other concept and region (:func:`splice_posterior`): a
   concept or region the teaching did not touch answers exactly as before it; G_e moves only by
   the affected concepts' share.

Everything is drawn from the one generator given: the same home, teaching and seed give the same
home, bit for bit.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from scipy.special import multigammaln

from spco.model import assignments, parameter_steps, sweep_statistics
from spco.model.home_place import draw_home_place_of
from spco.model.home_shard import (
    FREE_CONCEPT_WEIGHT,
    SharedPart,
    draw_switches,
    judge_new_words,
    own_names_to_free_concepts,
    warn_if_own_names_spread,
)
from spco.model.kernels.dirichlet import log_dirichlet
from spco.model.kernels.niw import niw_posterior
from spco.model.observations import LOG_FLOOR, GaussianRegions, HierarchicalMultinomial
from spco.model.parameters import ConceptParameters
from spco.model.posterior import ParameterAverage, masked_rows, thinned_sweeps
from spco.model.state import GibbsState, PreparedData, SamplerSettings
from spco.model.word_channels import mixture_log_likelihood

__all__ = ["SPLIT_SWEEPS", "expected_gaussians", "place_conditional", "splice_posterior", "teach_locally"]

#: The first sweeps of a teaching that try to give the taught place a region of its own
#: or give a region it does not need back (:func:`_move_taught_places`).
SPLIT_SWEEPS = 3


def _sample_rows(logits: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One categorical draw per row of ``logits`` (n, m), by the inverse CDF of one uniform each."""
    top = logits.max(axis=1, keepdims=True)
    p = np.exp(logits - top)
    cdf = np.cumsum(p, axis=1)
    u = rng.random(logits.shape[0]) * cdf[:, -1]
    return np.minimum((cdf < u[:, None]).sum(axis=1), logits.shape[1] - 1)


def _likelihoods(
    data: PreparedData, state: GibbsState, settings: SamplerSettings, rows: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(concept log-likelihood (n, L) of their views and words, region log-likelihood (n, K) of
    their positions under the regions' current Gaussians) of the samples ``rows``: the sampler's
    (:func:`spco.model.assignments.concept_loglik`, :meth:`GaussianRegions.log_likelihood`) for these rows
    only — a teaching's few samples, not the home's hundreds."""
    visual = sp.csr_array(data.visual[rows], dtype=np.float64)
    concept_ll = visual @ np.maximum(state.log_theta_v[0], LOG_FLOOR).T
    weights = assignments.view_weights(data, settings.view_counts)
    if weights is not None:
        concept_ll *= weights[rows][:, None]
    if state.channels is not None:  # the word channels: the switches marginalised, as the sampler
        words = sp.csr_array(data.words[rows])
        if words.nnz:
            concept_ll = concept_ll + mixture_log_likelihood(words, data.homes[rows], state.log_theta_w,
                                                             state.channels)
    else:
        words = assignments.sentence_words(data, state)[rows]
        if words.nnz:
            log_theta_w = assignments.kept_word_log_theta(state.log_theta_w, state.word_mask)[0]
            theta = np.maximum(log_theta_w, LOG_FLOOR).T
            concept_ll = concept_ll + sp.csr_array(words, dtype=np.float64) @ theta
    chol = np.linalg.cholesky(state.covariances[0])  # (K, d, d)
    diff = data.positions[rows][:, None, :] - state.means[0][None]  # (n, K, d)
    z = np.linalg.solve(chol[None], diff[..., None])[..., 0]
    d = diff.shape[-1]
    log_det = 2.0 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(-1)
    region_ll = -0.5 * ((z**2).sum(-1) + log_det[None] + d * np.log(2 * np.pi))
    return np.asarray(concept_ll), region_ll


def _collapsed_logits(
    state: GibbsState,
    hyper,
    concept_counts: np.ndarray,
    pair_counts: np.ndarray,
    concepts: np.ndarray,
    regions: np.ndarray,
    concept_ll: np.ndarray,
    region_ll: np.ndarray,
) -> np.ndarray:
    """log p(C = c, R = r | the other samples, θ, the Gaussians) with G_e and π integrated out
    (their Dirichlet predictive), over ``concepts`` × ``regions``: (|C|, |R|)."""
    K = state.log_pi.shape[2]
    log_g = np.log(hyper.gamma * np.exp(state.log_g0[concepts]) + concept_counts[concepts])
    log_pi = (
        np.log(hyper.beta / K + pair_counts[np.ix_(concepts, regions)])
        - np.log(hyper.beta + concept_counts[concepts])[:, None]
    )
    return log_g[:, None] + log_pi + concept_ll[concepts][:, None] + region_ll[regions][None, :]


def _draw_assignments(
    data: PreparedData,
    state: GibbsState,
    shared: SharedPart,
    settings: SamplerSettings,
    rows: np.ndarray,
    concepts: np.ndarray,
    regions: np.ndarray,
    rng: np.random.Generator,
    collapsed: bool = False,
) -> None:
    """Draw the (concept, region) of the samples ``rows`` one after another from their joint
    conditional restricted to ``concepts`` × ``regions``, G_e and π integrated out (the counts of the
    other samples; π and G_e are drawn again given the assignments in :func:`_parameters`), in place.
    ``collapsed``: the regions' Gaussians integrated out too (each position scored by the posterior
    predictive of the region's other samples, :class:`_RegionStatistics`; they are drawn again given
    the assignments next: a partially collapsed Gibbs step) — for a new observation's first draw;
    else the regions' current Gaussians score it. A sample's current pair must be in the
    restriction (or the sample new, not yet counted)."""
    if rows.size == 0:
        return
    hyper = shared.hyperparameters
    L, K = state.log_pi.shape[1:]
    concept_ll, region_ll = _likelihoods(data, state, settings, rows)
    counted = np.ones(data.n_samples, dtype=bool)
    counted[rows] = False
    pair_counts = np.zeros((L, K))
    np.add.at(pair_counts, (state.concepts[counted], state.regions[counted]), 1.0)
    concept_counts = pair_counts.sum(axis=1)
    positions = (_RegionStatistics(data, state, counted, regions,
                                   parameter_steps.niw_prior(data, hyper, settings)) if collapsed else None)
    for k, row in enumerate(rows):  # a loop over the teaching's few movable samples
        if positions is not None:
            region_ll[k, regions] = positions.log_predictive(data.positions[row])
        logits = _collapsed_logits(
            state, hyper, concept_counts, pair_counts, concepts, regions, concept_ll[k], region_ll[k]
        )
        flat = int(_sample_rows(logits.reshape(1, -1), rng)[0])
        c, r = concepts[flat // regions.size], regions[flat % regions.size]
        state.concepts[row], state.regions[row] = c, r
        pair_counts[c, r] += 1.0
        concept_counts[c] += 1.0
        if positions is not None:
            positions.add(flat % regions.size, data.positions[row])


class _RegionStatistics:
    """The position statistics (n, Σx, Σxxᵀ) of the regions ``regions`` over the samples ``counted``,
    and the posterior predictive density of a position in each: the Gaussians integrated out under
    the NIW prior (a Student t), so that a sample is placed by what the regions' samples say, not by
    one draw of their Gaussians (a narrow draw of a small region can make a pose next to its samples
    improbable there)."""

    def __init__(self, data: PreparedData, state: GibbsState, counted: np.ndarray, regions: np.ndarray,
                 prior) -> None:
        x = data.positions
        d = x.shape[1]
        self.prior = prior
        self.count = np.zeros(regions.size)
        self.total = np.zeros((regions.size, d))
        self.scatter = np.zeros((regions.size, d, d))
        index = np.full(state.log_pi.shape[2], -1)
        index[regions] = np.arange(regions.size)
        rows = np.flatnonzero(counted & (index[state.regions] >= 0))
        at = index[state.regions[rows]]
        np.add.at(self.count, at, 1.0)
        np.add.at(self.total, at, x[rows])
        np.add.at(self.scatter, at, x[rows][:, :, None] * x[rows][:, None, :])

    def add(self, k: int, point: np.ndarray) -> None:
        """Count ``point`` in the ``k``-th region."""
        self.count[k] += 1.0
        self.total[k] += point
        self.scatter[k] += np.outer(point, point)

    def log_predictive(self, point: np.ndarray) -> np.ndarray:
        """log p(point | the region's samples) of each region, (|regions|,): the ratio of the
        regions' marginals with and without the point (:func:`_log_marginal`)."""
        with_point = _log_marginal(self.count + 1.0, self.total + point[None],
                                   self.scatter + np.outer(point, point)[None], self.prior)
        return with_point - _log_marginal(self.count, self.total, self.scatter, self.prior)


def _parameters(
    data: PreparedData,
    state: GibbsState,
    shared: SharedPart,
    settings: SamplerSettings,
    concepts: np.ndarray,
    regions: np.ndarray,
    rng: np.random.Generator,
) -> None:
    """The affected parameters given the assignments (module docstring, step 3), in place."""
    hyper = shared.hyperparameters
    K = state.log_pi.shape[2]
    stats = sweep_statistics.sufficient_statistics(data, state, hyper, settings.learning_view_counts())
    free = concepts[
        (np.exp(state.log_g0[concepts]) < FREE_CONCEPT_WEIGHT) & (stats.concepts[0, concepts] > 0)
    ]
    if free.size:  # φ of a concept the knowledge does not use is learnt from this home (as adapting)
        state.log_phi_v[free] = HierarchicalMultinomial.sample_shared_given_counts(
            stats.visual[:, free], state.log_phi_v[free], hyper.delta_visual, hyper.alpha_visual, rng,
            passes=hyper.phi_passes,
        )
        tables_w = HierarchicalMultinomial.sample_tables(
            stats.words[:, free], state.log_phi_w[free], hyper.delta_word, rng
        )
        state.log_phi_w[free] = HierarchicalMultinomial.sample_shared(tables_w, hyper.alpha_word, rng)
    state.log_theta_v[:, concepts] = HierarchicalMultinomial.sample_specific(
        stats.visual[:, concepts], state.log_phi_v[concepts], hyper.delta_visual, rng
    )
    state.log_theta_w[:, concepts] = HierarchicalMultinomial.sample_specific(
        stats.words[:, concepts], state.log_phi_w[concepts], hyper.delta_word, rng
    )
    if stats.home_place is not None and state.channels is not None:  # ψ_{e,l} of C_A, as θ^w's
        state.channels = draw_home_place_of(state.channels, stats.home_place, hyper.delta_place, concepts,
                                            rng)
    # G_e restricted to C_A: its share among them ~ Dir(γ G_0 + n), their total mass kept
    log_mass = np.logaddexp.reduce(state.log_g[0, concepts])
    alpha = hyper.gamma * np.exp(state.log_g0[concepts]) + stats.concepts[0, concepts]
    state.log_g[0, concepts] = log_mass + log_dirichlet(alpha, rng)
    state.log_pi[:, concepts] = log_dirichlet(hyper.beta / K + stats.regions_by_concept[:, concepts], rng)
    means, covariances = GaussianRegions.sample_posterior(
        stats.region_count[:, regions],
        stats.region_total[:, regions],
        stats.region_scatter[:, regions],
        parameter_steps.niw_prior(data, hyper, settings),
        rng,
    )
    state.means[:, regions], state.covariances[:, regions] = means, covariances
    state.region_counts = stats.region_count.astype(np.int64)


def expected_gaussians(count: np.ndarray, total: np.ndarray, scatter: np.ndarray, prior
                       ) -> tuple[np.ndarray, np.ndarray]:
    """The posterior mean of m regions' Gaussians given their points' statistics — ``count`` (m,),
    Σx ``total`` (m, d), Σxxᵀ ``scatter`` (m, d, d) — under the NIW prior, as the moments an average
    of infinitely many draws of (μ, Σ) gives: (E[μ] = μ_n, E[Σ] + Cov(μ) = Ψ_n (1 + 1/κ_n) / (ν_n − d − 1)),
    the mean and covariance of the posterior predictive (a Student t). ``(m, d)``, ``(m, d, d)``."""
    d = total.shape[-1]
    mu_n, kappa_n, psi_n, nu_n = niw_posterior(count, total, scatter, prior.mu0[0], prior.kappa0, prior.psi0,
                                               prior.nu0)
    factor = (1.0 + 1.0 / kappa_n) / (nu_n - d - 1.0)
    return mu_n, psi_n * factor[:, None, None]


def _add_expected_gaussians(average: ParameterAverage, data: PreparedData, state: GibbsState,
                            shared: SharedPart, settings: SamplerSettings, regions: np.ndarray) -> None:
    """Add ``state`` to ``average`` with the Gaussians of the occupied ``regions`` (the teaching's) at
    their posterior mean given the sweep's assignments (:func:`expected_gaussians`) instead of the
    sweep's draw: the same posterior average (a Rao–Blackwellised estimate of it), without the
    noise of the few draws a teaching averages — two draws of a 16-sample region's mean moved a
    taught bedroom's `where` poses 0.25 m towards the entrance (``benchmarks/teaching.py``, synthetic
    seed 3). The state keeps its draws (the chain goes on from them)."""
    prior = parameter_steps.niw_prior(data, shared.hyperparameters, settings)
    d = data.positions.shape[1]
    positions = _RegionStatistics(data, state, np.ones(data.n_samples, dtype=bool), regions, prior)
    keep = (positions.count > 0) & (prior.nu0 + positions.count > d + 1)
    occupied = regions[keep]
    if occupied.size == 0:
        average.add(state)
        return
    means, covariances = state.means[:, occupied].copy(), state.covariances[:, occupied].copy()
    state.means[0, occupied], state.covariances[0, occupied] = expected_gaussians(
        positions.count[keep], positions.total[keep], positions.scatter[keep], prior)
    try:
        average.add(state)
    finally:
        state.means[:, occupied], state.covariances[:, occupied] = means, covariances


def _log_marginal(count: np.ndarray, total: np.ndarray, scatter: np.ndarray, prior) -> np.ndarray:
    """log p(points) of each of m regions from their statistics — ``count`` (m,), Σx ``total`` (m, d),
    Σxxᵀ ``scatter`` (m, d, d) — the Gaussian integrated out under the NIW prior, (m,)."""
    d = total.shape[-1]
    _, kappa_n, psi_n, nu_n = niw_posterior(count, total, scatter, prior.mu0[0], prior.kappa0, prior.psi0,
                                            prior.nu0)
    _, logdet0 = np.linalg.slogdet(prior.psi0)
    _, logdet_n = np.linalg.slogdet(psi_n)
    return (
        -0.5 * count * d * np.log(np.pi)
        + multigammaln(0.5 * nu_n, d)
        - multigammaln(0.5 * prior.nu0, d)
        + 0.5 * prior.nu0 * logdet0
        - 0.5 * nu_n * logdet_n
        + 0.5 * d * (np.log(prior.kappa0) - np.log(kappa_n))
    )


def place_conditional(
    x: np.ndarray, regions: np.ndarray, concepts: np.ndarray, row: int, openable: np.ndarray, prior,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The conditional of the region of sample ``row``'s place, as one block: (candidate regions,
    their log probabilities), or ``None`` when the move does not apply.

    The block P is concept c's samples of region r (c, r: those of ``row``). Its candidates are the
    lowest-numbered region e that is empty without P among ``openable`` (the regions the move may
    open: a constant of the kernel — those empty before the teaching, so that it never moves P into
    a region the home had kept empty for later), and every region s that holds samples without P
    but none of c. The move applies when P's region is one of them (it holds other concepts' samples,
    or it is e) and e exists; then the same P, e and candidates are found from every state the move
    can reach (P in any candidate), so drawing P's region from

        p(R_P = k | the rest, C) ∝ exp(M(x_k ∪ x_P) − M(x_k))    (k = e: exp(M(x_P)))

    — M the NIW log marginal of a region's positions (:func:`_log_marginal`), the Gaussians
    integrated out — is a blocked Gibbs step of the joint posterior. The region weights π are
    integrated out too and cancel: only c's region counts change, and P moves between regions where
    c has no other sample (a relabelling of c's counts; the Dirichlet–multinomial is symmetric),
    unlike moving *part* of a concept's samples of a region, which π charges 3–13 nats in the homes
    of ``benchmarks/teaching.py``. G_e, θ and every other region cancel as well
    (``tests/test_place_move.py`` checks the probabilities and the kernel's invariance against brute
    force over every assignment of a tiny problem). The place is split off its region (P to e) when
    the positions prefer it, and taken back when they do not. ``prior``: the
    :class:`~spco.model.observations.NIWPrior`. The caller redraws π of c and the Gaussians of the
    regions touched from their conditionals after the step (a partially collapsed Gibbs sampler)."""
    n_regions = openable.size
    c, r = int(concepts[row]), int(regions[row])
    part = (regions == r) & (concepts == c)
    rest = regions[~part]
    count = np.bincount(rest, minlength=n_regions)
    empty = np.flatnonzero((count == 0) & openable)
    if empty.size == 0:
        return None
    has_c = np.bincount(rest[concepts[~part] == c], minlength=n_regions) > 0
    candidates = np.union1d(np.flatnonzero((count > 0) & ~has_c), empty[:1])
    if r not in candidates:
        return None
    xp = x[part]
    d = x.shape[1]
    total = np.zeros((n_regions, d))
    scatter = np.zeros((n_regions, d, d))
    np.add.at(total, rest, x[~part])
    np.add.at(scatter, rest, x[~part][:, :, None] * x[~part][:, None, :])
    n, t, ss = count[candidates].astype(float), total[candidates], scatter[candidates]
    with_p = _log_marginal(n + xp.shape[0], t + xp.sum(axis=0), ss + xp.T @ xp, prior)
    without = np.where(n > 0, _log_marginal(n, t, ss, prior), 0.0)
    logits = with_p - without
    return candidates, logits - np.logaddexp.reduce(logits)


def _move_taught_places(
    data: PreparedData, state: GibbsState, shared: SharedPart, settings: SamplerSettings, taught: np.ndarray,
    openable: np.ndarray, rng: np.random.Generator,
) -> np.ndarray:
    """The region of each taught sample's place drawn from :func:`place_conditional`, in place;
    ``openable``: the regions it may open. Returns the regions it touched (their Gaussians are
    redrawn next)."""
    prior = parameter_steps.niw_prior(data, shared.hyperparameters, settings)
    touched: list[int] = []
    for row in taught:
        u = rng.random()
        conditional = place_conditional(data.positions, state.regions, state.concepts, int(row), openable,
                                        prior)
        if conditional is None:
            continue
        candidates, log_p = conditional
        cdf = np.cumsum(np.exp(log_p))
        k = int(candidates[min(int(np.searchsorted(cdf, u * cdf[-1], side="right")), candidates.size - 1)])
        r = int(state.regions[row])
        if k != r:
            state.regions[(state.regions == r) & (state.concepts == state.concepts[row])] = k
            touched.extend((r, k))
    return np.asarray(sorted(set(touched)), dtype=np.int64)


def _named_own_concept(data: PreparedData, state: GibbsState, rows: np.ndarray, n_known: int) -> np.ndarray:
    """Which of ``rows`` say a word first heard in this home and hold a free concept (one the
    knowledge does not use): a new name that :func:`own_names_to_free_concepts` gave a concept of
    its own."""
    words = sp.csr_array(data.words[rows])
    new_word = np.asarray((words[:, n_known:] > 0).sum(axis=1)).ravel() > 0 if words.shape[1] > n_known \
        else np.zeros(rows.size, dtype=bool)
    return new_word & (np.exp(state.log_g0[state.concepts[rows]]) < FREE_CONCEPT_WEIGHT)


def _affected(
    data: PreparedData, state: GibbsState, taught: np.ndarray, moved: np.ndarray, settings: SamplerSettings,
    n_known: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(movable samples, affected concepts C_A, affected regions R_A): module docstring, step 2."""
    K = state.log_pi.shape[2]
    touched = np.union1d(taught, moved)
    regions = np.unique(state.regions[touched])
    empty = np.flatnonzero(np.bincount(state.regions, minlength=K) == 0)
    if empty.size:  # room for the taught place to become a region of its own
        regions = np.union1d(regions, empty[:1])
    movable = np.union1d(np.flatnonzero(np.isin(state.regions, regions)), touched)
    concepts = np.unique(state.concepts[movable])
    said = taught[np.diff(data.words.indptr)[taught] > 0]
    # a new name with a concept of its own is explained by that concept: the concept whose other words
    # ("this is the … room") explain the sentence best would be another name's (it held "this is the
    # quokka room", and "this is the zephyr room" moved there in 2 of 4 seeds, with Ψ0 from the places)
    said = said[~_named_own_concept(data, state, said, n_known)]
    if said.size:  # the concept whose words explain a taught sentence best
        if state.channels is not None:
            word_ll = mixture_log_likelihood(sp.csr_array(data.words[said]), data.homes[said],
                                             state.log_theta_w, state.channels)
        else:
            words = assignments.sentence_words(data, state)[said]
            log_theta_w = assignments.kept_word_log_theta(state.log_theta_w, state.word_mask)
            word_ll = HierarchicalMultinomial.log_likelihood(words, data.homes[said], log_theta_w)
        concepts = np.union1d(concepts, np.argmax(word_ll + state.log_g[0][None, :], axis=1))
    return movable.astype(np.int64), concepts.astype(np.int64), regions.astype(np.int64)


def splice_posterior(
    previous: ConceptParameters | None, updated: ConceptParameters, concepts: np.ndarray, regions: np.ndarray
) -> ConceptParameters:
    """The home's parameters after a local update: ``updated`` (the average of the update's sweeps)
    for the affected ``concepts`` and ``regions``, ``previous`` (the home's average before it) for
    every other one; G_e's affected entries take the share the others leave. Words first heard in
    the teaching (columns ``previous`` lacks) and words the mask newly keeps come from ``updated``;
    rows are renormalised over the mask. ``previous`` ``None``: ``updated``."""
    if previous is None:
        return updated
    L, K = updated.region_weights.shape[1:]
    keep_c = np.ones(L, dtype=bool)
    keep_c[concepts] = False
    keep_r = np.ones(K, dtype=bool)
    keep_r[regions] = False
    g = updated.concept_weights.copy()
    kept_mass = previous.concept_weights[0, keep_c].sum()
    g[0, keep_c] = previous.concept_weights[0, keep_c]
    share = updated.concept_weights[0, ~keep_c]
    g[0, ~keep_c] = max(1.0 - kept_mass, 0.0) * share / max(share.sum(), np.finfo(float).tiny)
    pi = updated.region_weights.copy()
    pi[:, keep_c] = previous.region_weights[:, keep_c]
    means, covariances = updated.region_means.copy(), updated.region_covariances.copy()
    means[:, keep_r], covariances[:, keep_r] = (
        previous.region_means[:, keep_r],
        previous.region_covariances[:, keep_r],
    )
    region_counts = updated.region_counts.copy()
    region_counts[:, keep_r] = previous.region_counts[:, keep_r]
    visual = updated.visual_probabilities.copy()
    visual[:, keep_c] = previous.visual_probabilities[:, keep_c]
    v_old = previous.word_probabilities.shape[2]
    with np.errstate(divide="ignore"):
        log_words = np.log(updated.word_probabilities)
        old = np.log(previous.word_probabilities[:, keep_c])
    kept_before = np.asarray(previous.word_mask, dtype=bool)
    rows = log_words[:, keep_c]
    rows[..., :v_old] = np.where(kept_before, old, rows[..., :v_old])
    log_words[:, keep_c] = rows
    mask = np.asarray(updated.word_mask, dtype=bool)
    counts = None
    if updated.concept_counts is not None:
        counts = updated.concept_counts.copy()
        if previous.concept_counts is not None:
            counts[:, keep_c] = previous.concept_counts[:, keep_c]
    return replace(
        updated,
        concept_weights=g,
        region_weights=pi,
        region_means=means,
        region_covariances=covariances,
        region_counts=region_counts,
        visual_probabilities=visual,
        word_probabilities=masked_rows(log_words, mask),
        concept_counts=counts,
    )


def teach_locally(
    data: PreparedData,
    state: GibbsState,
    shared: SharedPart,
    n_known: int,
    taught: np.ndarray,
    new: np.ndarray,
    n_sweeps: int,
    rng: np.random.Generator,
    previous: ConceptParameters | None,
    home_name: str,
) -> ConceptParameters:
    """Update ``state`` in place for a teaching (module docstring) and return the home's parameters.

    Parameters
    ----------
    data: the home's samples after the teaching; state: its state, the new samples' rows appended
    (their assignments are drawn here); shared: the shared part (fixed); n_known: the knowledge's
    words; taught: rows whose sentence changed or that are new; new: the new samples' rows;
    n_sweeps: sweeps of the affected block (their thinned average answers for it; 0: the
    state's values after the first draw of the affected parameters); rng: the
    generator; previous: the home's parameters before the teaching (``None``: none averaged);
    home_name: for the warning of :func:`~spco.model.home_shard.warn_if_own_names_spread`.
    """
    settings = shared.sampler_settings()
    taught = np.asarray(taught, dtype=np.int64)
    new = np.asarray(new, dtype=np.int64)
    judge_new_words(state, shared, n_known, data)  # a taught name counts at once
    L, K = state.log_pi.shape[1:]
    _draw_assignments(data, state, shared, settings, new, np.arange(L), np.arange(K), rng, collapsed=True)
    draw_switches(data, state, rng)  # (word channels: the switches of the taught tokens, given their concept)
    before = state.concepts.copy()
    # the names of this teaching only: the home's other names keep the concepts its posterior gave them
    said = np.unique(data.words[taught].indices) if taught.size else np.zeros(0, dtype=np.int64)
    # a name said at a sample stands for its place — the samples of its region *and its concept* — not
    # for the samples of another concept that share the region (another room the region spans)
    cells = np.unique(state.regions[taught] * L + state.concepts[taught])
    place = np.isin(state.regions * L + state.concepts, cells)
    own_names_to_free_concepts(data, state, shared, n_known, words=said[said >= n_known], movable=place)
    moved = np.flatnonzero(before != state.concepts)
    movable, concepts, regions = _affected(data, state, taught, moved, settings, n_known)
    concepts = np.union1d(concepts, before[moved]).astype(np.int64)
    _parameters(data, state, shared, settings, concepts, regions, rng)
    # the regions the move of a taught place may open: those empty before the sweeps
    openable = np.bincount(state.regions, minlength=K) == 0
    average = ParameterAverage(data.homes, data.position_scale)
    averaged = set(thinned_sweeps(int(n_sweeps))) if n_sweeps else set()
    for iteration in range(int(n_sweeps)):
        _draw_assignments(data, state, shared, settings, movable, concepts, regions, rng)
        draw_switches(data, state, rng, movable)  # (word channels: the movable samples' tokens)
        if iteration < SPLIT_SWEEPS:  # once the sweeps told the taught place's samples from the others'
            opened = _move_taught_places(data, state, shared, settings, taught, openable, rng)
            regions = np.union1d(regions, opened)
        _parameters(data, state, shared, settings, concepts, regions, rng)
        if iteration in averaged:
            _add_expected_gaussians(average, data, state, shared, settings, regions)
    judge_new_words(state, shared, n_known, data)
    warn_if_own_names_spread(data, state, shared, home_name, n_known, stacklevel=5)
    if not average.n_samples:
        average.add(state)
    return splice_posterior(previous, average.result(state), concepts, regions)
