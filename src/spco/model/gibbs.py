"""The blocked Gibbs sampler: prepared data, sampler state, initialisation, sweeps, log joint.

One sweep follows bnpy's cycle: a **local step** (per-sample assignments C_t, R_t, all homes at
once) → **sufficient statistics** → a **global step** (shared φ^v, φ^w, G_0) → the **home step**
(θ, G_e, π, μ, Σ of every home). The conditionals themselves live in
:mod:`spco.model.allocation` (concepts and regions) and :mod:`spco.model.observations`
(positions, words, vision).

Three samplers share this machinery:

``exact`` — the generative model as written (``../docs/model.md`` of the project), an MCMC for
    its posterior without word pruning (with pruning, see :func:`_prune`: a heuristic, the chain
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

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.cluster.vq import kmeans2

from spco.model import allocation
from spco.model.alignment import HomeCounts, align_in_order
from spco.model.blocks import region_block_step
from spco.model.home_place import draw_home_place, home_place_statistics, shared_place_counts
from spco.model.hyperparameters import TransferHyperparameters, view_powers
from spco.model.kernels.dirichlet import dirichlet_log_density, log_dirichlet
from spco.model.moves import concept_swap_step
from spco.model.numba_cache import announce_compilation
from spco.model.observations import GaussianRegions, HierarchicalMultinomial, NIWPrior
from spco.model.phi_moves import phi_after_move, phi_block_step
from spco.model.pruning import NAME, NOT_A_NAME, Colocation, colocation, judge_names, words_to_keep
from spco.model.state import (  # noqa: F401  (the sampler's data and state, re-exported)
    CM_PER_M,
    VARIANTS,
    GibbsState,
    PreparedData,
    SamplerSettings,
    VisualCountCache,
)
from spco.model.timing import StepTimer, _Timed
from spco.model.word_channels import (
    ChannelCounts,
    channel_counts,
    mixture_log_likelihood,
    name_tokens,
    place_token_counts,
    sample_channels,
    sample_switches,
    token_rows,
    token_scales,
)


def niw_prior(data: PreparedData, hyper: TransferHyperparameters, settings: SamplerSettings) -> NIWPrior:
    """The NIW prior in the sampler's units (μ0 = map centre, or 0 in the reference variant);
    its arrays are read-only."""
    key = (hyper, settings.variant)
    try:
        prior = data.niw_priors.get(key)
    except TypeError:  # hyperparameters holding lists (unhashable): no cache
        return _build_niw_prior(data, hyper, settings)
    if prior is None:
        prior = data.niw_priors[key] = _build_niw_prior(data, hyper, settings)
    return prior


def _build_niw_prior(data: PreparedData, hyper: TransferHyperparameters,
                     settings: SamplerSettings) -> NIWPrior:
    scale = np.array([data.position_scale, data.position_scale, 1.0, 1.0])
    psi0 = hyper.psi0_matrix_m2() * np.outer(scale, scale)
    if settings.variant == "reference":
        mu0 = np.zeros((data.n_homes, 4))
    elif hyper.mu0 is not None:
        mu0 = np.tile(np.asarray(hyper.mu0, dtype=float) * scale, (data.n_homes, 1))
    else:
        mu0 = data.map_centres.copy()
    mu0.flags.writeable = False
    psi0.flags.writeable = False
    return NIWPrior(mu0=mu0, kappa0=hyper.kappa0, psi0=psi0, nu0=hyper.nu0)


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


def _apply_permutations(data: PreparedData, state: GibbsState, perms: np.ndarray, theta: bool = True) -> None:
    """Relabel concepts within each home: slot j of home e takes its old concept perms[e, j].
    ``theta=False`` leaves θ^v, θ^w as they are (for a caller that redraws them)."""
    if (perms == np.arange(perms.shape[1])).all():
        return
    homes = np.arange(perms.shape[0])[:, None]
    if theta:
        state.log_theta_v = state.log_theta_v[homes, perms]
        state.log_theta_w = state.log_theta_w[homes, perms]
    state.log_g = state.log_g[homes, perms]
    state.log_pi = state.log_pi[homes, perms]
    inverse = np.argsort(perms, axis=1)  # old concept -> new slot
    state.concepts = inverse[data.homes, state.concepts]


# ----------------------------------------------------------------------------- statistics


@dataclass
class Statistics:
    """Sufficient statistics of the assignments: concept counts (E, L), region-by-concept counts
    (E, L, K), Gaussian statistics per region, and visual/word counts per concept (E, L, D/V)."""

    concepts: np.ndarray
    regions_by_concept: np.ndarray
    region_count: np.ndarray
    region_total: np.ndarray
    region_scatter: np.ndarray
    visual: np.ndarray
    words: np.ndarray
    #: with word channels: the switches' counts (each token once) and the place tokens per home and
    #: concept with their counts (E, L, V), for the label swaps
    channel: ChannelCounts | None = None
    place_tokens: np.ndarray | None = None
    #: the place channel's home level: place tokens per home, concept and word in ψ's units (E, L, V)
    home_place: np.ndarray | None = None


def uses_channels(data: PreparedData, state: GibbsState) -> bool:
    """Whether ``state`` has word channels whose switches are drawn for ``data``'s tokens."""
    switches = state.switches
    return state.channels is not None and switches is not None and switches.shape == (data.words.nnz,)


def sentence_words(data: PreparedData, state: GibbsState) -> sp.csr_array:
    """The word counts (N, V) that the word likelihood and the word statistics count: one sentence
    names one place.

    A taught sentence whose words include one the naming rule judges a *name*
    (``state.name_words``) is counted by its name words only; its other words — a frame the home's
    people say around names ("look robot, this is …", "we call this …"), undecided because it was
    heard too rarely to judge — tell nothing about the place the name does not already tell. Left
    in, each would weigh S^w counts: a frame said in two sentences at two rooms would pull their
    samples into a concept of its own (one concept per sentence frame), and the room's name would
    be split over those concepts. A sentence without a judged name keeps all its words (a name
    taught once is undecided, and usable at once). The naming rule itself still judges every word
    on all its uses (``data.words``). Without judged names this is ``data.words`` itself.
    """
    names = getattr(state, "name_words", None)
    words = data.words
    if names is None or not words.nnz or not names[words.indices].any():
        return words
    key = names.tobytes()
    cache = state.words_cache
    if cache is not None and cache[0] is words and cache[1] == key:
        return cache[2]
    is_name = names[words.indices]
    rows = token_rows(words)
    named_row = np.bincount(rows, weights=is_name, minlength=words.shape[0]) > 0
    keep = is_name | ~named_row[rows]
    kept = sp.csr_array((words.data[keep], (rows[keep], words.indices[keep])), shape=words.shape)
    kept.sort_indices()
    state.words_cache = (words, key, kept)
    return kept


def _statistics(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters,
                view_counts: float | None) -> Statistics:
    """The statistics of the assignments; the visual counts weighted by the views' powers at
    ``view_counts`` (:func:`view_weights`; ``None``: every count whole), as the likelihood the
    assignments were drawn with weighs them."""
    E, L, K = data.n_homes, hyper.n_concepts, hyper.n_regions
    count, total, scatter = GaussianRegions.statistics(data.positions, data.homes, state.regions, E, K)
    channel = place_tokens = home_place = None
    if uses_channels(data, state):  # θ^w counts the name tokens only
        channels = state.channels
        power = channels.power  # the power likelihood: θ^w, ψ and β count a token W^w n times
        words = name_tokens(data.words, state.switches, channels.token_weight if power else 1.0)
        channel = channel_counts(data.words, state.concepts, state.switches, L,
                                 token_scales(data.words, channels) if power else None)
        place_tokens = place_token_counts(data.words, data.homes, state.concepts, state.switches, E, L,
                                          state.channels.token_weight)
        home_place = home_place_statistics(data, state, hyper, E, L)
    else:
        words = sentence_words(data, state)
    return Statistics(
        concepts=allocation.concept_counts(data.homes, state.concepts, E, L),
        regions_by_concept=allocation.region_counts(data.homes, state.concepts, state.regions, E, L, K),
        region_count=count, region_total=total, region_scatter=scatter,
        visual=_visual_counts(data, state, E, L, view_counts),
        words=HierarchicalMultinomial.statistics(words, data.homes, state.concepts, E, L),
        channel=channel, place_tokens=place_tokens, home_place=home_place,
    )


def _visual_counts(data: PreparedData, state: GibbsState, n_homes: int, n_concepts: int,
                   view_counts: float | None = None) -> np.ndarray:
    """n^v (E, L, D), updated from the previous sweep's counts when few samples changed concept
    (after burn-in most do not), recounted otherwise. Read-only for callers.

    With a view weight (``view_counts``) some view's power s_t is below 1 and n^v holds the
    weighted counts Σ_t s_t v_t (float64), recounted every sweep in row order (no running sums,
    which would round differently from a recount)."""
    weights = view_weights(data, view_counts)
    if weights is not None and not np.all(weights == 1.0):
        state.visual_cache = None
        counts = HierarchicalMultinomial.weighted_statistics(data.visual, weights, data.homes, state.concepts,
                                                             n_homes, n_concepts)
        counts.flags.writeable = False
        return counts
    cache = state.visual_cache
    usable = (cache is not None and cache.visual is data.visual
              and cache.concepts.shape == state.concepts.shape
              and cache.counts.shape == (n_homes, n_concepts, data.visual.shape[1]))
    if usable:
        changed = np.flatnonzero(cache.concepts != state.concepts)
        if changed.size <= data.n_samples // 4:
            counts = cache.counts
            counts.flags.writeable = True
            HierarchicalMultinomial.move_counts(counts, data.visual, changed, data.homes[changed],
                                                cache.concepts[changed], state.concepts[changed])
            counts.flags.writeable = False
            cache.concepts = state.concepts.copy()
            return counts
    counts = HierarchicalMultinomial.statistics(data.visual, data.homes, state.concepts, n_homes, n_concepts)
    counts.flags.writeable = False
    state.visual_cache = VisualCountCache(visual=data.visual, concepts=state.concepts.copy(), counts=counts)
    return counts


# ----------------------------------------------------------------------------- the steps


def view_weights(data: PreparedData, view_counts: float | None) -> np.ndarray | None:
    """(N,) the weight of each sample's visual log-likelihood, ``min(1, view_counts / Σ_d v_d)``:
    a view scored as ``view_counts`` draws (``None``: every count a draw, no weights)."""
    if view_counts is None:
        return None
    return view_powers(data.view_totals, float(view_counts))


def _concept_loglik(data: PreparedData, state: GibbsState, view_counts: float | None = None,
                    word_weight: float | np.ndarray = 1.0) -> np.ndarray:
    """Visual + word log-likelihood of every sample under every concept of its home: (N, L).

    ``view_counts``: the evidence of one view in counts (:func:`view_weights`; ``None``: the
    multinomial of every count); ``word_weight``: without channels, the words' times this (or (N,))."""
    loglik = HierarchicalMultinomial.log_likelihood(data.visual, data.homes, state.log_theta_v,
                                                    by_dimension=data.visual_by_dimension)
    weights = view_weights(data, view_counts)
    if weights is not None:
        loglik *= weights[:, None]
    channels = getattr(state, "channels", None)
    if data.words.nnz and channels is not None:  # the switches marginalised
        loglik += mixture_log_likelihood(data.words, data.homes, state.log_theta_w, channels)
    elif data.words.nnz:
        log_theta_w = kept_word_log_theta(state.log_theta_w, state.word_mask)
        words = HierarchicalMultinomial.log_likelihood(sentence_words(data, state), data.homes, log_theta_w)
        weight = np.asarray(word_weight, dtype=np.float64)
        loglik += words if np.all(weight == 1.0) else words * weight.reshape(-1, 1)
    return loglik


def kept_word_log_theta(log_theta_w: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """log θ^w with the pruned words removed: rows renormalised over the kept words, 0 (ignored)
    at the pruned ones; shape as ``log_theta_w`` (…, V).

    Pruning removes word k from every θ^w and renormalises the rows (``docs/model.md``, as in the
    exported parameters and the label-swap moves). Leaving the rows unnormalised instead would
    score a kept word by its share of *all* words: a place name holds ~0.2 of its concept's θ^w
    (the sentence templates hold the rest), while a concept empty in a home, whose θ^w is a draw
    around a sparse prior φ^w, can hold ~1.0 of it — with S^w = 5000 counts per word that is
    5000 · log 5 ≈ 8,000 nats in favour of the empty concept, so whole places jumped into empty
    concepts sweep after sweep and nothing stayed aligned across homes."""
    if mask.all():
        return log_theta_w
    if not mask.any():  # every word pruned (no word names a place): the words say nothing
        return np.zeros_like(log_theta_w)
    kept = log_theta_w[..., mask]
    top = kept.max(axis=-1, keepdims=True)
    log_norm = np.log(np.exp(kept - top).sum(axis=-1, keepdims=True)) + top
    return np.where(mask, log_theta_w - log_norm, 0.0)


def _local_step(data: PreparedData, state: GibbsState, settings: SamplerSettings,
                rng: np.random.Generator, hyper: TransferHyperparameters | None = None) -> float:
    """Draw the assignments; returns log p(data, C, R | parameters) of the state it started from
    (computed from the likelihoods the draw needs anyway).

    With ``settings.block_moves`` (exact sampler) and ``hyper`` given, the one-sample draws are
    followed by a pass of region block moves (:mod:`spco.model.blocks`: a region's samples of one
    concept change concept together, G_e and π integrated out), before the word switches are drawn;
    the caller's next home step redraws G_e and π given the result, as the move requires."""
    concept_ll = _concept_loglik(data, state, settings.view_counts, settings.word_weight)
    region_ll = GaussianRegions.log_likelihood(data.positions, data.homes, state.means, state.covariances)
    before = _conditional_log_joint(data, state, concept_ll, region_ll)
    if settings.joint_assignment:
        state.concepts, state.regions = allocation.sample_assignments_joint(
            state.log_g, state.log_pi, data.homes, concept_ll, region_ll, rng)
        if settings.block_moves and hyper is not None and settings.variant == "exact":
            prior = home_concept_concentration(state, hyper, settings)
            state.concepts = region_block_step(data.homes, state.concepts, state.regions, concept_ll, prior,
                                               hyper.beta, data.n_homes, state.log_pi.shape[2], rng)
    else:  # the authors' two blocks: R | C, then C | R
        state.regions = allocation.sample_regions_given_concepts(state.log_pi, data.homes, state.concepts,
                                                                 region_ll, rng)
        state.concepts = allocation.sample_concepts_given_regions(state.log_g, state.log_pi, data.homes,
                                                                  state.regions, concept_ll, rng)
    if state.channels is not None:  # each token's switch given its sample's new concept
        state.switches = sample_switches(data.words, data.homes, state.concepts, state.log_theta_w,
                                         state.channels, rng)
    return before


def home_concept_concentration(state: GibbsState, hyper: TransferHyperparameters,
                               settings: SamplerSettings) -> np.ndarray:
    """The Dirichlet concentration of every home's concept weights G_e (L,): γ G_0 (transfer model),
    γ/L (SpCoA) — G_e's prior in the log joint, integrated over by the block moves."""
    n_concepts = state.log_g.shape[1]
    if settings.hierarchical:
        return hyper.gamma * np.exp(state.log_g0)
    return np.full(n_concepts, hyper.gamma / n_concepts)


def _conditional_log_joint(data: PreparedData, state: GibbsState, concept_ll: np.ndarray,
                           region_ll: np.ndarray) -> float:
    """Σ_t log G_{e,C_t} + log π_{e,C_t,R_t} + log N(x_t | R_t) + log p(v_t, w_t | C_t)."""
    homes, c, r = data.homes, state.concepts, state.regions
    rows = np.arange(data.n_samples)
    return float((state.log_g[homes, c] + state.log_pi[homes, c, r] + region_ll[rows, r]
                  + concept_ll[rows, c]).sum())


def _global_step(stats: Statistics, state: GibbsState, hyper: TransferHyperparameters,
                 rng: np.random.Generator, moved: tuple | None = None) -> None:
    """Exact: φ^v, φ^w and G_0 given CRT table counts (θ and G_e integrated out); φ^v from the
    views' weighted counts (:meth:`HierarchicalMultinomial.sample_shared_given_counts`), or after a
    φ^v-marginal block move with the other homes' tables it drew (``moved``: :mod:`spco.model.phi_moves`)."""
    if moved is not None:
        state.log_phi_v = phi_after_move(stats.visual, state.log_phi_v, hyper.delta_visual,
                                         hyper.alpha_visual, moved, rng, passes=hyper.phi_passes)
    else:
        state.log_phi_v = HierarchicalMultinomial.sample_shared_given_counts(
            stats.visual, state.log_phi_v, hyper.delta_visual, hyper.alpha_visual, rng,
            passes=hyper.phi_passes)
    tables_w = HierarchicalMultinomial.sample_tables(stats.words, state.log_phi_w, hyper.delta_word, rng)
    state.log_phi_w = HierarchicalMultinomial.sample_shared(tables_w, hyper.alpha_word, rng)
    state.log_g0 = allocation.sample_global_concept_weights(stats.concepts, state.log_g0, hyper.gamma,
                                                            hyper.gamma0, rng)
    if stats.channel is not None and state.channels is not None:
        counts = shared_place_counts(stats, state.channels, hyper, rng)  # (the home level: ψ_l's tables)
        state.channels = sample_channels(counts, state.channels, rng)


def _home_step(data: PreparedData, state: GibbsState, stats: Statistics, hyper: TransferHyperparameters,
               settings: SamplerSettings, rng: np.random.Generator) -> None:
    """θ^v, θ^w, G_e, π and the region Gaussians of every home, given φ, G_0 and the assignments."""
    K, L = hyper.n_regions, hyper.n_concepts
    if settings.hierarchical:
        # drawn into the previous θ^v's memory: no new (E, L, D) array per sweep
        state.log_theta_v = HierarchicalMultinomial.sample_specific(
            stats.visual, state.log_phi_v, hyper.delta_visual, rng, out=state.log_theta_v)
        state.log_theta_w = HierarchicalMultinomial.sample_specific(stats.words, state.log_phi_w,
                                                                    hyper.delta_word, rng)
        state.log_g = allocation.sample_home_concept_weights(stats.concepts, state.log_g0, hyper.gamma, rng)
    else:  # SpCoA: θ_l ~ Dir(α + n), G ~ Dir(γ/L + n)
        state.log_theta_v = log_dirichlet(hyper.alpha_visual + stats.visual, rng)
        state.log_theta_w = log_dirichlet(hyper.alpha_word + stats.words, rng)
        state.log_g = log_dirichlet(hyper.gamma / L + stats.concepts, rng)
        state.log_phi_v = _log_mean(state.log_theta_v)  # exported as the shared part
        state.log_phi_w = _log_mean(state.log_theta_w)
        state.log_g0 = _log_mean(state.log_g)
    if stats.home_place is not None and state.channels is not None:  # ψ_{e,l} | ψ_l, tokens
        state.channels = draw_home_place(state.channels, stats.home_place, hyper.delta_place, rng)
    state.log_pi = allocation.sample_region_weights(stats.regions_by_concept, hyper.beta / K, rng)
    state.means, state.covariances = GaussianRegions.sample_posterior(
        stats.region_count, stats.region_total, stats.region_scatter, niw_prior(data, hyper, settings), rng)
    state.region_counts = stats.region_count.astype(np.int64)


def _swap_labels(data: PreparedData, state: GibbsState, stats: Statistics, hyper: TransferHyperparameters,
                 settings: SamplerSettings, rng: np.random.Generator) -> None:
    """Metropolis–Hastings label swaps within each home, θ marginalised (see
    :mod:`spco.model.moves`), then θ of the homes that changed redrawn from its conditional."""
    place = place_home = None
    if stats.home_place is not None and state.channels is not None:  # ψ_{e,l} integrated out
        place_home = (stats.home_place, state.channels.log_place, hyper.delta_place)
    elif stats.place_tokens is not None and state.channels is not None:
        place = (stats.place_tokens, state.channels.log_place)
    perms = concept_swap_step(stats.visual, state.log_phi_v, hyper.delta_visual, stats.words,
                              state.log_phi_w, hyper.delta_word, state.log_g, state.log_g0, hyper.gamma,
                              state.word_mask, rng, place=place, place_home=place_home)
    changed = np.flatnonzero((perms != np.arange(perms.shape[1])).any(axis=1))
    if changed.size == 0:
        return
    # θ of the homes that changed is redrawn below and the others keep theirs: no need to permute it
    _apply_permutations(data, state, perms, theta=False)
    slots = (changed[:, None], perms[changed])
    visual, words = stats.visual[slots], stats.words[slots]
    _relabel_visual_cache(data, state, perms, changed, visual)
    state.log_theta_v[changed] = HierarchicalMultinomial.sample_specific(visual, state.log_phi_v,
                                                                         hyper.delta_visual, rng)
    state.log_theta_w[changed] = HierarchicalMultinomial.sample_specific(words, state.log_phi_w,
                                                                         hyper.delta_word, rng)
    if place_home is not None:  # the changed homes' ψ_{e,l} redrawn, as θ^w (their tokens relabelled)
        relabelled = stats.home_place[np.arange(perms.shape[0])[:, None], perms]
        state.channels = draw_home_place(state.channels, relabelled, hyper.delta_place, rng, changed)


def _relabel_visual_cache(data: PreparedData, state: GibbsState, perms: np.ndarray, changed: np.ndarray,
                          visual: np.ndarray) -> None:
    """Carry the visual count cache through a relabelling (``visual``: the changed homes' counts in
    their new slot order), so that the next sweep moves only the rows of samples that change
    concept again instead of recounting the relabelled homes."""
    cache = state.visual_cache
    if cache is None or cache.visual is not data.visual or cache.concepts.shape != state.concepts.shape:
        return
    inverse = np.argsort(perms, axis=1)
    cache.concepts = inverse[data.homes, cache.concepts]
    cache.counts.flags.writeable = True
    cache.counts[changed] = visual
    cache.counts.flags.writeable = False


def _log_mean(log_p: np.ndarray) -> np.ndarray:
    """log of the mean over the first axis of exp(log_p)."""
    if log_p.shape[0] == 1:
        return log_p[0].copy()
    top = log_p.max(axis=0)
    return np.log(np.exp(log_p - top).mean(axis=0)) + top


def _home_step_reference(data: PreparedData, state: GibbsState, stats: Statistics,
                         hyper: TransferHyperparameters, settings: SamplerSettings,
                         rng: np.random.Generator, regions_too: bool = True) -> None:
    """The authors' per-home updates: NIW (empty regions re-seeded), θ | previous φ, π, G_e."""
    if regions_too:
        means, covs = GaussianRegions.sample_posterior(stats.region_count, stats.region_total,
                                                       stats.region_scatter, niw_prior(data, hyper, settings),
                                                       rng)
        empty = stats.region_count == 0
        n_empty = int(empty.sum())
        if n_empty:
            box = np.array([6.0, 6.0, 1.0, 1.0])
            means[empty] = rng.uniform(-box, box, size=(n_empty, 4))
            covs[empty] = 100.0 * np.eye(4)
        state.means, state.covariances = means, covs
    state.log_theta_v = HierarchicalMultinomial.sample_specific(
        stats.visual, state.log_phi_v, hyper.delta_visual, rng, out=state.log_theta_v)
    state.log_theta_w = HierarchicalMultinomial.sample_specific(stats.words, state.log_phi_w,
                                                                hyper.delta_word, rng)
    state.log_pi = allocation.sample_region_weights(stats.regions_by_concept, hyper.beta, rng)
    state.log_g = allocation.sample_home_concept_weights(stats.concepts, state.log_g0, hyper.gamma, rng,
                                                         extra=50.0)
    state.region_counts = stats.region_count.astype(np.int64)


def _global_step_reference(stats: Statistics, state: GibbsState, hyper: TransferHyperparameters,
                           rng: np.random.Generator) -> None:
    """The authors' shared updates: φ ~ Dir(α + pooled counts), G_0 ~ Dir(γ0 + Σ_e n_e)."""
    state.log_phi_v = log_dirichlet(hyper.alpha_visual + stats.visual.sum(0), rng)
    state.log_phi_w = log_dirichlet(hyper.alpha_word + stats.words.sum(0), rng)
    state.log_g0 = log_dirichlet(hyper.gamma0 + stats.concepts.sum(0), rng)


def _prune(state: GibbsState, hyper: TransferHyperparameters, settings: SamplerSettings,
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
        previous_log_joint = _local_step(data, state, settings, rng, hyper)
    with _Timed(timer, "statistics"):
        stats = _statistics(data, state, hyper, settings.learning_view_counts())
    if settings.variant == "reference":
        with _Timed(timer, "home parameters"):
            _home_step_reference(data, state, stats, hyper, settings, rng)
        if settings.learn_shared:
            with _Timed(timer, "shared parameters"):
                _global_step_reference(stats, state, hyper, rng)
    else:
        if settings.hierarchical and settings.learn_shared:
            moved = None
            if settings.phi_moves and data.n_homes > 1:  # power target (spco.model.phi_moves)
                with _Timed(timer, "phi block moves"):
                    stats, moved = phi_block_step(data, state, stats, hyper, settings, rng, _statistics)
            with _Timed(timer, "shared parameters"):
                _global_step(stats, state, hyper, rng, moved)
        with _Timed(timer, "home parameters"):
            _home_step(data, state, stats, hyper, settings, rng)
        if swaps and settings.hierarchical and data.n_homes > 1:
            with _Timed(timer, "label swaps"):
                _swap_labels(data, state, stats, hyper, settings, rng)
    if settings.prune and settings.learn_shared:
        with _Timed(timer, "word pruning"):
            _prune(state, hyper, settings, data)
    return previous_log_joint


# ----------------------------------------------------------------------------- log joint


def log_joint(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters,
              settings: SamplerSettings, include_parameter_priors: bool = False) -> float:
    """log p(data, C, R | parameters), or with ``include_parameter_priors`` the full
    log p(data, C, R, parameters), in the sampler's units, up to the multinomial coefficients
    (which do not depend on the state). With word pruning, pruned words are left out, so the
    value jumps when the mask changes between sweeps (the "+MI" chain has no stated target; see
    :func:`_prune`).

    The default leaves out the parameters' prior densities because, with α^w = 0.01 and
    δ^w φ^w ≪ 1, the Dirichlet density of a word distribution with near-zero entries reaches
    1e100 and more, which swamps every change of fit; the conditional log joint is the
    trace to watch for convergence."""
    E, L, K = data.n_homes, hyper.n_concepts, hyper.n_regions
    region_ll = GaussianRegions.log_likelihood(data.positions, data.homes, state.means, state.covariances)
    total = _conditional_log_joint(data, state, _concept_loglik(data, state, settings.view_counts), region_ll)
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


# ----------------------------------------------------------------------------- public step names
# The per-home steps under public names, for :mod:`spco.model.shard` and for the callers outside
# ``spco.model`` (adapting knowledge to a home): nothing outside the package calls a private one.

local_step = _local_step
sufficient_statistics = _statistics
global_step = _global_step
home_step = _home_step
home_step_reference = _home_step_reference
global_step_reference = _global_step_reference
prune = _prune
swap_labels = _swap_labels
