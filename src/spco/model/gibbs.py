"""The blocked Gibbs sampler: initialisation, sweeps, word pruning, log joint.

One sweep (:func:`sweep`) follows bnpy's cycle, one module a step: a **local step** (per-sample
assignments C_t, R_t, all homes at once: :mod:`spco.model.assignments`) → **sufficient statistics**
(:mod:`spco.model.sweep_statistics`) → a **global step** (shared φ^v, φ^w, G_0) → the **home step**
(θ, G_e, π, μ, Σ of every home; both in :mod:`spco.model.parameter_steps`). The sampler's data and
state are in :mod:`spco.model.state`; the conditionals themselves in :mod:`spco.model.allocation`
(concepts and regions) and :mod:`spco.model.observations` (positions, words, vision).

Three samplers share this machinery:

``exact`` — the generative model as written (``../docs/model.md`` of the project), an MCMC for
    its posterior without word pruning (with pruning, see :func:`prune`: a heuristic, the chain
    then has no stated target); joint (C, R) draw; φ | table counts (CRT auxiliary variables)
    then θ | φ (partially collapsed Gibbs, in that order); G_0 | concept table counts;
    G_e ~ Dir(γ G_0 + n); π ~ Dir(β/K + n); NIW regions; positions in metres with μ0 = map
    centre; pruning score = true mutual information.
``reference`` — what the authors' published code does, to reproduce their numbers:
    R block then C block; θ given the previous φ, then φ ~ Dir(α + counts pooled over homes);
    G_0 ~ Dir(γ0 + Σ_e n_e); G_e ~ Dir(n + γ G_0 + 50); π ~ Dir(n + β); positions in centimetres
    with μ0 = 0; k-means initialisation with Σ = 100·I; empty regions re-seeded uniformly in a
    ±6 cm box around the origin with Σ = 100·I; pruning score = Bernoulli KL with threshold 0.1
    (pruned words get probability 1e-100 in their code, i.e. they are ignored, as here).
``spcoa`` — the SpCoA baseline: no environment plate, θ_l ~ Dir(α + n) directly, G ~ Dir(γ/L + n).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.cluster.vq import kmeans2

from spco.model import allocation
from spco.model.alignment import HomeCounts, align_in_order
from spco.model.assignments import (
    concept_loglik,
    conditional_log_joint,
    home_concept_concentration,
    local_step,
)
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.kernels.dirichlet import dirichlet_log_density, log_dirichlet
from spco.model.numba_cache import announce_compilation
from spco.model.observations import GaussianRegions, HierarchicalMultinomial
from spco.model.parameter_steps import (
    global_step,
    global_step_reference,
    home_step,
    home_step_reference,
    niw_prior,
    swap_labels,
)
from spco.model.phi_moves import phi_block_step
from spco.model.pruning import NAME, NOT_A_NAME, Colocation, colocation, judge_names, words_to_keep
from spco.model.state import (  # noqa: F401  (the sampler's data and state, re-exported)
    CM_PER_M,
    VARIANTS,
    GibbsState,
    PreparedData,
    SamplerSettings,
    VisualCountCache,
)
from spco.model.sweep_statistics import sufficient_statistics
from spco.model.timing import StepTimer, _Timed

# ----------------------------------------------------------------------------- initialisation


def initialize(data: PreparedData, n_words: int, hyper: TransferHyperparameters,
               settings: SamplerSettings, rng: np.random.Generator) -> GibbsState:
    """Each home's start on its own (a fit's shards start their homes with it, then finish the
    start together: :mod:`spco.model.shard_init`); the first sweep starts with the local step.

    Regions are assigned by k-means on each home's positions and their Gaussians drawn given that
    assignment (the reference variant sets the k-means centres as means with Σ = 100·I, as the
    authors do); π is drawn from its prior; concepts are uniform at random; the word and visual
    distributions θ, φ start uniform, as in the authors' code, and so do G_0 and G_e (the
    reference variant draws those as the authors do).

    Why uniform θ: with ~7,000 visual and S^w = 5000 word counts per sample the likelihood is so
    peaked that the chain keeps whatever partition its first sweep makes. With uniform θ that
    first partition follows the regions (p(C, R) ∝ G π N(x | R)), i.e. concepts start as groups of
    nearby samples, which words and vision then refine. Drawing θ from the prior or from counts of
    random concepts instead starts from a random partition that the chain does not leave.

    The exact variant's warm start — homes learnt on their own for a few sweeps, their labels
    aligned across homes, the shared part set from the aligned counts — runs across the shards:
    :func:`spco.model.shard_init.initialise`.
    """
    announce_compilation()
    L, K, E = hyper.n_concepts, hyper.n_regions, data.n_homes
    D, V = data.visual.shape[1], n_words
    concepts = rng.integers(0, L, size=data.n_samples)
    regions = np.zeros(data.n_samples, dtype=np.int64)
    means = np.empty((E, K, 4))
    for e in range(E):
        rows = slice(data.offsets[e], data.offsets[e + 1])
        x = data.positions[rows]
        k = min(K, x.shape[0])
        restarts = 10 if settings.variant == "reference" else 1  # the authors keep the best of 10
        best = np.inf
        for _ in range(restarts):
            centres, labels = kmeans2(x, k, minit="++", seed=int(rng.integers(0, 2**31 - 1)))
            cost = ((x - centres[labels]) ** 2).sum()
            if cost < best:
                best, best_centres, best_labels = cost, centres, labels
        regions[rows] = best_labels
        means[e, :k] = best_centres
        means[e, k:] = best_centres[rng.integers(0, k, size=K - k)]
    reference = settings.variant == "reference"
    # Word and visual distributions start uniform (as in the authors' code), so the first local
    # step groups samples by region: concepts start spatially coherent within each home.
    log_phi_v = np.full((L, D), -np.log(max(D, 1)))  # D = 0: no home has a view
    log_phi_w = np.full((L, V), -np.log(V)) if V else np.zeros((L, 0))
    if reference:  # the authors: G_0 by stick breaking, G_e ~ Dir(G_0 + γ)
        log_g0 = log_dirichlet(np.full(L, hyper.gamma0), rng)
        log_g = log_dirichlet(np.exp(log_g0)[None, :] + hyper.gamma + np.zeros((E, L)), rng)
    else:  # uniform: the sparse prior draws of G_0 would put every sample in one or two concepts
        log_g0 = np.full(L, -np.log(L))
        log_g = np.full((E, L), -np.log(L))
    region_prior = hyper.beta if reference else hyper.beta / K
    log_pi = allocation.sample_region_weights(np.zeros((E, L, K)), region_prior, rng)
    state = GibbsState(
        concepts=concepts, regions=regions, log_g=log_g, log_g0=log_g0, log_pi=log_pi, means=means,
        covariances=np.tile(100.0 * np.eye(4), (E, K, 1, 1)),
        # θ only in the state, not in local names too: when the first sweep (or the warm start)
        # replaces the uniform (E, L, D) θ^v, it is freed at once
        log_theta_v=np.broadcast_to(log_phi_v, (E, L, D)).copy(),
        log_theta_w=np.broadcast_to(log_phi_w, (E, L, V)).copy(), log_phi_v=log_phi_v, log_phi_w=log_phi_w,
        word_mask=np.ones(V, dtype=bool),
    )
    count, total, scatter = GaussianRegions.statistics(data.positions, data.homes, regions, E, K)
    state.region_counts = count.astype(np.int64)
    if not reference:
        state.means, state.covariances = GaussianRegions.sample_posterior(
            count, total, scatter, niw_prior(data, hyper, settings), rng)
    return state


#: Smoothing of :func:`initial_home_weights` (a taught fraction): keeps the weights continuous
#: when no home is taught.
TAUGHT_SMOOTHING = 0.02


def initial_home_weights(taught_fraction: np.ndarray) -> np.ndarray:
    """Weight of each home's statistics in the initial shared part: (E,) in (0, 1].

    ``taught_fraction`` (E,) is the share of each home's samples with a sentence; the weight is
    (f_e + ε) / (max_e f_e + ε) with ε = :data:`TAUGHT_SMOOTHING`: the most taught homes count
    fully, the others in proportion (a home taught nothing among fully taught homes ≈ 0.02, i.e.
    it starts from the knowledge of the others), every home fully when all are taught alike
    (also when none is). Continuous in every fraction: no threshold decides the first partition.
    """
    f = np.clip(np.asarray(taught_fraction, dtype=np.float64), 0.0, 1.0)
    return (f + TAUGHT_SMOOTHING) / (f.max() + TAUGHT_SMOOTHING)


def sample_names(data: PreparedData, regions: np.ndarray, hyper: TransferHyperparameters,
                 named: np.ndarray | None = None, stats: Colocation | None = None) -> np.ndarray:
    """The place name each sample stands for, (N,) vocabulary column or −1.

    A taught sample whose sentence holds a name (``named``, (V,) bool; default: the words
    :func:`naming_verdicts` finds to be names on ``regions``) stands for that name (of its names,
    the one most bound to one place: the largest lift); any other sample for the name most of the
    named samples of its region stand for, or none (−1). ``stats``: the naming rule's statistics to
    judge by (default: those of ``data``'s homes; a shard of a fleet passes those of all homes)."""
    if stats is None:
        stats = colocation(data.words, data.homes, regions, data.n_homes, hyper.n_regions)
    if named is None:
        named = judge_names(stats) == NAME
    n_words, n_regions = data.words.shape[1], hyper.n_regions
    score = np.where(named, np.nan_to_num(stats.lift, nan=0.0) + 1.0, 0.0)  # (V,) > 0 for names
    best = (sp.csr_array(data.words > 0, dtype=np.float64) @ sp.diags_array(score)).tocsr()
    has_name = np.asarray(best.max(axis=1).todense()).ravel() > 0
    name_of = np.asarray(best.argmax(axis=1)).ravel()
    cell = data.homes * n_regions + regions
    votes = sp.csr_array((np.ones(int(has_name.sum())), (cell[has_name], name_of[has_name])),
                         shape=(data.n_homes * n_regions, n_words))
    voted = np.asarray(votes.sum(axis=1)).ravel() > 0
    majority = np.asarray(votes.argmax(axis=1)).ravel()
    return np.where(has_name, name_of, np.where(voted[cell], majority[cell], -1)).astype(np.int64)


def concepts_by_name(data: PreparedData, regions: np.ndarray, hyper: TransferHyperparameters,
                     names: np.ndarray | None = None) -> np.ndarray:
    """Starting concepts (N,) that follow the homes' place names, per home: one concept per name
    (:func:`sample_names`, or ``names`` if given) and, for the samples that stand for none, one per
    region. Names and regions of a home get distinct concepts, up to L (then they share, in
    order). Labels differ between homes until :func:`align_homes` matches them."""
    if names is None:
        names = sample_names(data, regions, hyper)
    key = np.where(names >= 0, names, data.words.shape[1] + regions)
    concepts = np.empty(data.n_samples, dtype=np.int64)
    for e in range(data.n_homes):  # a loop over homes; each step is vectorised
        rows = slice(data.offsets[e], data.offsets[e + 1])
        _, label = np.unique(key[rows], return_inverse=True)
        concepts[rows] = label % hyper.n_concepts
    return concepts


def naming_verdicts(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters) -> np.ndarray:
    """The naming rule's verdict on every word (:func:`spco.model.pruning.judge_names`), judged on
    the samples' current regions: (V,) int8, NAME / UNDECIDED / NOT_A_NAME.

    Regions, not concepts: with S^w = 5000 the sampler may split one place into one concept per
    sentence template, which would make the template words look place-bound; the regions are
    drawn mostly by position and do not split by sentence. Re-evaluated after every sweep."""
    return judge_names(colocation(data.words, data.homes, state.regions, data.n_homes, hyper.n_regions))


def align_homes(visual: np.ndarray, words: np.ndarray, alpha_visual: float, alpha_word: float,
                name_counts: np.ndarray | None = None) -> np.ndarray:
    """Permutations that make the homes' concept labels agree.

    Parameters
    ----------
    visual: (E, L, D) visual counts per home and concept; words: (E, L, V) word counts.

    Returns
    -------
    perms: (E, L); slot j of home e should hold its current concept perms[e, j]. Homes are
    aligned in order of decreasing word counts; each is matched to the pooled counts of those
    aligned before it by maximising Σ_j log p(counts of its concept perms[e, j] | pooled profile j),
    the word counts of a concept that has words, the visual counts of one that has none.

    ``name_counts`` (E, L, V), optional: how many samples of each concept stand for each place name
    (:func:`sample_names`). A concept most of whose samples stand for names that none of the homes
    aligned before it says, but another home does — a synonym ("front door" where the others said
    "entrance") — is matched by its views instead: its words cannot tell which place it is, and
    matched by them it would take a label at random and split the place in two across homes. A
    name said in this home only (Emma's room) still goes by its words (to a free label).
    """
    n_homes, n_concepts, _ = visual.shape

    def fetch(homes: np.ndarray) -> list[HomeCounts]:
        return [HomeCounts(sp.csr_array(visual[e]), words[e], None if name_counts is None else name_counts[e])
                for e in homes]

    names_said = None if name_counts is None else name_counts.sum(axis=1) > 0
    return align_in_order(fetch, words.sum(axis=(1, 2)), names_said, alpha_visual, alpha_word, n_concepts,
                          batch=max(n_homes, 1))


# ----------------------------------------------------------------------------- the sweep


def prune(state: GibbsState, hyper: TransferHyperparameters, settings: SamplerSettings,
          data: PreparedData | None = None) -> None:
    """Recompute which words are informative enough to keep (``state.word_mask``).

    Exact variant (given ``data``): the naming rule (:func:`naming_verdicts`): a word is pruned
    only when enough pairs of its uses show that it is said alike everywhere in its homes; a word
    said mostly at one place, and a word heard too rarely to judge, are kept. Reference variant:
    the authors' rule (KL score on φ^w, G_0); SpCoA+MI: the mutual information on θ^w, G.

    Pruned words are left out of the word likelihood of the next sweep and get probability 0 in
    the exported θ^w, φ^w (rows renormalised), as in the paper. The sampler itself keeps their
    φ^w and θ^w, so the pruning is re-decided after every sweep: a word pruned while concepts are
    still forming can come back once they separate (with φ^w set to 0, its table counts and hence
    its φ^w would stay 0 for ever).

    This makes pruning a heuristic outside the model: θ^w and φ^w are drawn from counts that
    include the pruned words while the likelihood renormalises θ^w over the kept ones, and the
    mask changes between sweeps, so a chain with pruning ("+MI") has no stated stationary
    distribution and its log joint jumps when the mask changes. Without pruning the exact
    sampler is an MCMC for the model's posterior.
    """
    if state.log_phi_w.shape[1] == 0 or state.channels is not None:  # channels: no pruning
        return
    if settings.variant == "exact" and data is not None:
        verdicts = naming_verdicts(data, state, hyper)
        state.word_mask = verdicts != NOT_A_NAME
        state.name_words = verdicts == NAME
        return
    if settings.hierarchical:
        phi_w, weights = np.exp(state.log_phi_w), np.exp(state.log_g0)
    else:  # SpCoA+MI: the single home's θ^w and G
        phi_w, weights = np.exp(state.log_theta_w[0]), np.exp(state.log_g[0])
    score = settings.pruning_score
    threshold = hyper.pruning_threshold(score)
    keep = words_to_keep(phi_w, weights, threshold, score)
    if state.home_specific_words is not None:
        keep |= state.home_specific_words
    if state.candidate_words is not None:
        keep &= state.candidate_words
    if not keep.any():  # never remove every word: keep the most informative one
        keep[np.argmax(phi_w.max(0))] = True
    state.word_mask = keep


#: Label swaps run on every one of the first sweeps, then on every SWAP_EVERY-th sweep.
SWAP_BURN_IN = 20
SWAP_EVERY = 10


def swaps_due(iteration: int) -> bool:
    """Whether sweep number ``iteration`` (0-based) includes the label-swap moves.

    The moves are exact Metropolis–Hastings steps, so any fixed schedule keeps the chain valid;
    they matter most while the homes' labellings settle, and cost about as much as a sweep."""
    return iteration < SWAP_BURN_IN or iteration % SWAP_EVERY == 0


def sweep(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters, settings: SamplerSettings,
          rng: np.random.Generator, timer: StepTimer | None = None, swaps: bool = True) -> float:
    """One Gibbs sweep, in place. ``timer`` (optional) accumulates the time of each step;
    ``swaps`` includes the label-swap moves (see :func:`swaps_due`).

    Returns log p(data, C, R | parameters) of the state the sweep started from (the previous
    sweep's result), which costs nothing extra: the assignment step needs those likelihoods."""
    with _Timed(timer, "assignments"):
        previous_log_joint = local_step(data, state, settings, rng, hyper)
    with _Timed(timer, "statistics"):
        stats = sufficient_statistics(data, state, hyper, settings.learning_view_counts())
    if settings.variant == "reference":
        with _Timed(timer, "home parameters"):
            home_step_reference(data, state, stats, hyper, settings, rng)
        if settings.learn_shared:
            with _Timed(timer, "shared parameters"):
                global_step_reference(stats, state, hyper, rng)
    else:
        if settings.hierarchical and settings.learn_shared:
            moved = None
            if settings.phi_moves and data.n_homes > 1:  # power target (spco.model.phi_moves)
                with _Timed(timer, "phi block moves"):
                    stats, moved = phi_block_step(data, state, stats, hyper, settings, rng)
            with _Timed(timer, "shared parameters"):
                global_step(stats, state, hyper, rng, moved)
        with _Timed(timer, "home parameters"):
            home_step(data, state, stats, hyper, settings, rng)
        if swaps and settings.hierarchical and data.n_homes > 1:
            with _Timed(timer, "label swaps"):
                swap_labels(data, state, stats, hyper, settings, rng)
    if settings.prune and settings.learn_shared:
        with _Timed(timer, "word pruning"):
            prune(state, hyper, settings, data)
    return previous_log_joint


# ----------------------------------------------------------------------------- log joint


def log_joint(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters,
              settings: SamplerSettings, include_parameter_priors: bool = False) -> float:
    """log p(data, C, R | parameters), or with ``include_parameter_priors`` the full
    log p(data, C, R, parameters), in the sampler's units, up to the multinomial coefficients
    (which do not depend on the state). With word pruning, pruned words are left out, so the
    value jumps when the mask changes between sweeps (the "+MI" chain has no stated target; see
    :func:`prune`).

    The default leaves out the parameters' prior densities because, with α^w = 0.01 and
    δ^w φ^w ≪ 1, the Dirichlet density of a word distribution with near-zero entries reaches
    1e100 and more, which swamps every change of fit; the conditional log joint is the
    trace to watch for convergence."""
    E, L, K = data.n_homes, hyper.n_concepts, hyper.n_regions
    region_ll = GaussianRegions.log_likelihood(data.positions, data.homes, state.means, state.covariances)
    total = conditional_log_joint(data, state, concept_loglik(data, state, settings.view_counts), region_ll)
    if not include_parameter_priors:
        return total
    mask = state.word_mask
    concentration_g = home_concept_concentration(state, hyper, settings)
    if settings.hierarchical:
        total += HierarchicalMultinomial.log_prior_specific(state.log_theta_v, state.log_phi_v,
                                                            hyper.delta_visual)
        if mask.any():
            total += HierarchicalMultinomial.log_prior_specific(state.log_theta_w, state.log_phi_w,
                                                                hyper.delta_word, mask)
            total += HierarchicalMultinomial.log_prior_shared(state.log_phi_w, hyper.alpha_word, mask)
        total += HierarchicalMultinomial.log_prior_shared(state.log_phi_v, hyper.alpha_visual)
        total += float(dirichlet_log_density(state.log_g, concentration_g).sum())
        total += float(dirichlet_log_density(state.log_g0, np.full(L, hyper.gamma0 / L)))
    else:
        total += HierarchicalMultinomial.log_prior_shared(state.log_theta_v.reshape(E * L, -1),
                                                          hyper.alpha_visual)
        if mask.any():
            total += HierarchicalMultinomial.log_prior_shared(state.log_theta_w.reshape(E * L, -1),
                                                              hyper.alpha_word, mask)
        total += float(dirichlet_log_density(state.log_g, concentration_g).sum())
    total += float(dirichlet_log_density(state.log_pi, np.full(K, hyper.beta / K)).sum())
    total += GaussianRegions.log_prior(state.means, state.covariances, niw_prior(data, hyper, settings))
    return total
