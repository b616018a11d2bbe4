"""The blocked Gibbs sampler: prepared data, sampler state, initialisation, sweeps, log joint.

One sweep follows bnpy's cycle: a **local step** (per-sample assignments C_t, R_t, all homes at
once) → **sufficient statistics** → a **global step** (shared φ^v, φ^w, G_0) → the **home step**
(θ, G_e, π, μ, Σ of every home). The conditionals themselves live in
:mod:`spco.model.allocation` (concepts and regions) and :mod:`spco.model.observations`
(positions, words, vision).

Three samplers share this machinery:

``exact`` — the generative model as written (``../docs/model.md`` of the project):
    joint (C, R) draw; φ | table counts (CRT auxiliary variables) then θ | φ (partially collapsed
    Gibbs, in that order); G_0 | concept table counts; G_e ~ Dir(γ G_0 + n); π ~ Dir(β/K + n);
    NIW regions; positions in metres with μ0 = map centre; pruning score = true mutual information.
``reference`` — what the authors' published code does, to reproduce their numbers:
    R block then C block; θ given the previous φ, then φ ~ Dir(α + counts pooled over homes);
    G_0 ~ Dir(γ0 + Σ_e n_e); G_e ~ Dir(n + γ G_0 + 50); π ~ Dir(n + β); positions in centimetres
    with μ0 = 0; k-means initialisation with Σ = 100·I; empty regions re-seeded uniformly in a
    ±6 cm box around the origin with Σ = 100·I; pruning score = Bernoulli KL with threshold 0.1
    (pruned words get probability 1e-100 in their code, i.e. they are ignored, as here).
``spcoa`` — the SpCoA baseline: no environment plate, θ_l ~ Dir(α + n) directly, G ~ Dir(γ/L + n).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.cluster.vq import kmeans2
from scipy.optimize import linear_sum_assignment

from spco.model import allocation
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.moves import concept_swap_step
from spco.model.numba_cache import announce_compilation
from spco.model.observations import GaussianRegions, HierarchicalMultinomial, NIWPrior
from spco.model.pruning import words_to_keep
from spco.model.random import DimensionMajorCounts, dimension_major, dirichlet_log_density, log_dirichlet

VARIANTS = ("exact", "reference", "spcoa")

#: Reference variant: positions in centimetres.
CM_PER_M = 100.0


@dataclass(frozen=True, eq=False)
class PreparedData:
    """All homes' training samples stacked, in the sampler's units.

    positions (N, 4), homes (N,) home index of each sample, visual (N, D) CSR int64 counts,
    words (N, V) CSR int64 counts (empty rows for untaught samples), n_homes E, offsets (E+1,)
    so that home e holds rows offsets[e]:offsets[e+1], position_scale (1 for metres, 100 for cm).
    """

    positions: np.ndarray
    homes: np.ndarray
    visual: sp.csr_array
    words: sp.csr_array
    n_homes: int
    offsets: np.ndarray
    position_scale: float
    map_centres: np.ndarray  # (E, 4) in sampler units

    @property
    def n_samples(self) -> int:
        """N."""
        return int(self.homes.size)

    @cached_property
    def visual_by_dimension(self) -> DimensionMajorCounts:
        """The visual counts by home and dimension (:func:`~spco.model.random.dimension_major`),
        built at the first sweep: the layout of the visual likelihood's kernel."""
        return dimension_major(self.visual, self.offsets)

    @cached_property
    def niw_priors(self) -> dict:
        """The NIW priors already built for this data (:func:`niw_prior`), by hyperparameters and
        variant: built once per fit instead of once per sweep."""
        return {}


@dataclass
class GibbsState:
    """Assignments and parameters after a sweep (log-probabilities, sampler units).

    concepts (N,), regions (N,); log_g (E, L) G_e; log_g0 (L,) G_0; log_pi (E, L, K) π;
    means (E, K, 4), covariances (E, K, 4, 4); log_theta_v (E, L, D), log_theta_w (E, L, V);
    log_phi_v (L, D), log_phi_w (L, V); word_mask (V,) words kept by pruning; candidate_words
    (V,) words that pruning may keep at all (``None``: every word), see :func:`warm_start`;
    home_specific_words (V,) candidates said in one home only, never pruned (see :func:`_prune`).
    """

    concepts: np.ndarray
    regions: np.ndarray
    log_g: np.ndarray
    log_g0: np.ndarray
    log_pi: np.ndarray
    means: np.ndarray
    covariances: np.ndarray
    log_theta_v: np.ndarray
    log_theta_w: np.ndarray
    log_phi_v: np.ndarray
    log_phi_w: np.ndarray
    word_mask: np.ndarray
    region_counts: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=np.int64))
    candidate_words: np.ndarray | None = None
    home_specific_words: np.ndarray | None = None
    visual_cache: VisualCountCache | None = field(default=None, repr=False)


@dataclass
class VisualCountCache:
    """n^v_{e,l,·} of the last sweep and the assignments they were counted for, so that the next
    sweep only moves the rows of the samples whose concept changed (exact integer updates: the
    counts are identical to a recount). Valid only for the same ``visual`` matrix object."""

    visual: sp.csr_array
    concepts: np.ndarray
    counts: np.ndarray


@dataclass(frozen=True)
class SamplerSettings:
    """What distinguishes the samplers (derived from the variant name)."""

    variant: str
    prune: bool
    hierarchical: bool
    joint_assignment: bool
    pruning_score: str
    learn_shared: bool = True

    @classmethod
    def create(cls, variant: str, prune: bool, learn_shared: bool = True) -> SamplerSettings:
        """Settings of ``variant`` (``exact``, ``reference`` or ``spcoa``).

        ``learn_shared=False`` keeps φ^v, φ^w and G_0 fixed (adapting to a new home with
        knowledge learnt elsewhere): sweeps then update only the homes' own variables."""
        if variant not in VARIANTS:
            raise ValueError(f"unknown sampler variant {variant!r}; choose one of {VARIANTS}")
        return cls(variant=variant, prune=prune, hierarchical=variant != "spcoa",
                   joint_assignment=variant != "reference",
                   pruning_score="kl" if variant == "reference" else "mi", learn_shared=learn_shared)


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
    """A starting state, then the first sweep starts with the local step.

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
    log_phi_v = np.full((L, D), -np.log(D))
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
        # θ only in the state, not in local names too: when the first sweep (or warm_start)
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
    if settings.variant == "exact":
        warm_start(data, state, hyper, settings, rng)
    return state


def warm_start(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters,
               settings: SamplerSettings, rng: np.random.Generator, n_sweeps: int = 3) -> None:
    """Start the hierarchical sampler from homes whose concept labels agree.

    Each home is first learnt on its own for ``n_sweeps`` sweeps (θ_{e,l} ~ Dir(α + n), the SpCoA
    conditionals), which makes its concepts place-pure within the home; then the homes' labels
    are aligned progressively — taught homes first — by matching each home's concepts to the
    pooled word and visual counts of the homes aligned before it (Hungarian algorithm); finally
    φ and G_0 are set from the aligned counts of the homes taught at least half of their samples,
    and θ, G_e, π, μ, Σ drawn given them — for the other homes (a new home) from the priors given
    φ and G_0, so that their samples are first assigned by the transferred knowledge.

    This is only an initialisation (the chain is valid MCMC from its end on, whatever state it
    starts from); it matters because label switching between homes is the sampler's hardest move:
    see :mod:`spco.model.moves`.
    """
    independent = SamplerSettings(variant="spcoa", prune=False, hierarchical=False, joint_assignment=True,
                                  pruning_score="mi")
    for sweep_index in range(n_sweeps):
        _local_step(data, state, independent, rng)
        stats = _statistics(data, state, hyper)
        if sweep_index == 0 and settings.prune:
            state.candidate_words = place_words(data, state.regions)
            state.home_specific_words = state.candidate_words & words_of_one_home(data)
            state.word_mask = state.candidate_words.copy()
        _home_step(data, state, stats, hyper, independent, rng)
    stats = _statistics(data, state, hyper)
    perms = align_homes(stats.visual, stats.words, hyper.alpha_visual, hyper.alpha_word)
    _apply_permutations(data, state, perms)
    stats = _statistics(data, state, hyper)
    # Homes taught little (a new home) start from the transferred knowledge instead: their
    # concept statistics are dropped, so their θ, G_e and π are drawn from the priors given the
    # φ and G_0 of the taught homes, and the next local step assigns their samples by it.
    taught = np.bincount(data.homes, weights=np.diff(data.words.indptr) > 0, minlength=data.n_homes)
    sizes = np.diff(data.offsets)
    reset = taught < 0.5 * sizes
    if reset.any() and not reset.all():
        for name in ("visual", "words", "concepts", "regions_by_concept"):
            dropped = getattr(stats, name).copy()  # (the visual counts are the sampler's cache)
            dropped[reset] = 0
            setattr(stats, name, dropped)
    state.log_phi_v = log_dirichlet(hyper.alpha_visual + stats.visual.sum(0), rng)
    state.log_phi_w = log_dirichlet(hyper.alpha_word + stats.words.sum(0), rng)
    state.log_g0 = log_dirichlet(hyper.gamma0 / hyper.n_concepts + stats.concepts.sum(0), rng)
    _home_step(data, state, stats, hyper, settings, rng)


def place_words(data: PreparedData, groups: np.ndarray, p_value: float = 1e-3) -> np.ndarray:
    """Words whose occurrence depends on where they were said: a G-test pooled over homes, (V,) bool.

    ``groups`` is a spatial partition of each home's samples (the regions at the start of the
    run). A word of the sentence templates ("this", "is", "here") occurs in every part of a home at
    the same rate; a place name only in the parts that cover its room. For each home, the
    sentences' word presence × group table gives G_e = 2 Σ O log(O / E); under independence
    Σ_e G_e ~ χ²(Σ_e (m_e − 1)) over the homes where the word was said (m_e: groups with taught
    samples), so a name said in one home only ("Emma's-room") is judged on that home. Words with
    p ≥ ``p_value`` are removed from the candidates of mutual-information pruning for the whole
    run.

    Why not the paper's rule at this point: the mutual information of a place name depends on how
    finely the partition splits its room (0.01–0.03 nats), while the templates' sampling noise
    reaches 0.006; a significance test separates them cleanly. Why not later, on the concepts:
    with S^w = 5000 the sampler soon splits a place into one concept per sentence template, which
    makes the template words look informative too.
    """
    n_words = data.words.shape[1]
    # A new matrix: ``sp.csr_array(data.words, dtype=float64)`` would share the data array of the
    # (already float64) word counts, and setting it to 1 would replace S^w by 1 for the whole run.
    present = sp.csr_array(data.words > 0, dtype=np.float64)
    taught = np.diff(data.words.indptr) > 0
    g_stat = np.zeros(n_words)
    dof = np.zeros(n_words)
    for e in range(data.n_homes):  # a loop over homes; each step is one sparse product
        rows = np.flatnonzero(taught & (data.homes == e))
        if rows.size == 0:
            continue
        labels, index = np.unique(groups[rows], return_inverse=True)
        if labels.size < 2:
            continue
        onehot = sp.csr_array((np.ones(rows.size), (index, np.arange(rows.size))),
                              shape=(labels.size, rows.size))
        with_word = np.asarray((onehot @ present[rows]).todense())  # (L_e, V)
        sizes = np.bincount(index).astype(float)[:, None]
        observed = np.stack([with_word, sizes - with_word])  # present / absent
        expected = sizes * np.stack([with_word.sum(0), (sizes - with_word).sum(0)])[:, None, :] / rows.size
        with np.errstate(divide="ignore", invalid="ignore"):
            terms = np.where(observed > 0, observed * np.log(observed / expected), 0.0)
        g_stat += 2.0 * terms.sum(axis=(0, 1))
        dof += (labels.size - 1) * (with_word.sum(0) > 0)  # only homes where the word was said
    if not dof.any():
        return np.ones(n_words, dtype=bool)
    from scipy.stats import chi2  # here, not at the top: scipy.stats adds ~24 MB to every fit

    keep = (dof > 0) & (chi2.sf(g_stat, np.maximum(dof, 1)) < p_value)
    if not keep.any():
        keep[:] = True
    return keep


def words_of_one_home(data: PreparedData) -> np.ndarray:
    """(V,) bool: words taught in exactly one home while at least two homes were taught.

    Such a word ("Emma's-room") names a place of its own home; its mutual information with the
    concepts of all homes is small by construction (its concept has a small G_0 weight), so the
    shared-model pruning rule would remove it before its concept forms."""
    taught = np.diff(data.words.indptr) > 0
    per_home = np.zeros((data.n_homes, data.words.shape[1]), dtype=bool)
    rows = np.flatnonzero(taught)
    coo = data.words[rows].tocoo()
    per_home[data.homes[rows][coo.row], coo.col] = True
    n_taught_homes = int(per_home.any(axis=1).sum())
    return (per_home.sum(axis=0) == 1) & (n_taught_homes >= 2)


def align_homes(visual: np.ndarray, words: np.ndarray, alpha_visual: float, alpha_word: float) -> np.ndarray:
    """Permutations that make the homes' concept labels agree.

    Parameters
    ----------
    visual: (E, L, D) visual counts per home and concept; words: (E, L, V) word counts.

    Returns
    -------
    perms: (E, L); slot j of home e should hold its current concept perms[e, j]. Homes are
    aligned in order of decreasing word counts; each is matched to the pooled counts of those
    aligned before it by maximising Σ_j log p(counts of its concept perms[e, j] | pooled profile j).
    """
    n_homes, n_concepts, _ = visual.shape
    order = np.argsort(-words.sum(axis=(1, 2)), kind="stable")
    perms = np.tile(np.arange(n_concepts), (n_homes, 1))
    pooled_v = visual[order[0]].astype(float)
    pooled_w = words[order[0]].astype(float)
    for e in order[1:]:
        log_pv = np.log(pooled_v + alpha_visual) - np.log((pooled_v + alpha_visual).sum(1, keepdims=True))
        score = visual[e] @ log_pv.T  # (own concept, label)
        if words.shape[2]:
            log_pw = np.log(pooled_w + alpha_word) - np.log((pooled_w + alpha_word).sum(1, keepdims=True))
            score = score + words[e] @ log_pw.T
        own, label = linear_sum_assignment(score, maximize=True)
        perms[e, label] = own
        pooled_v += visual[e][perms[e]]
        pooled_w += words[e][perms[e]]
    return perms


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


def _statistics(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters) -> Statistics:
    E, L, K = data.n_homes, hyper.n_concepts, hyper.n_regions
    count, total, scatter = GaussianRegions.statistics(data.positions, data.homes, state.regions, E, K)
    return Statistics(
        concepts=allocation.concept_counts(data.homes, state.concepts, E, L),
        regions_by_concept=allocation.region_counts(data.homes, state.concepts, state.regions, E, L, K),
        region_count=count, region_total=total, region_scatter=scatter,
        visual=_visual_counts(data, state, E, L),
        words=HierarchicalMultinomial.statistics(data.words, data.homes, state.concepts, E, L),
    )


def _visual_counts(data: PreparedData, state: GibbsState, n_homes: int, n_concepts: int) -> np.ndarray:
    """n^v (E, L, D), updated from the previous sweep's counts when few samples changed concept
    (after burn-in most do not), recounted otherwise. Read-only for callers."""
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


def _concept_loglik(data: PreparedData, state: GibbsState) -> np.ndarray:
    """Visual + word log-likelihood of every sample under every concept of its home: (N, L)."""
    loglik = HierarchicalMultinomial.log_likelihood(data.visual, data.homes, state.log_theta_v,
                                                    by_dimension=data.visual_by_dimension)
    if data.words.nnz:
        log_theta_w = kept_word_log_theta(state.log_theta_w, state.word_mask)
        loglik += HierarchicalMultinomial.log_likelihood(data.words, data.homes, log_theta_w)
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
    kept = log_theta_w[..., mask]
    top = kept.max(axis=-1, keepdims=True)
    log_norm = np.log(np.exp(kept - top).sum(axis=-1, keepdims=True)) + top
    return np.where(mask, log_theta_w - log_norm, 0.0)


def _local_step(data: PreparedData, state: GibbsState, settings: SamplerSettings,
                rng: np.random.Generator) -> float:
    """Draw the assignments; returns log p(data, C, R | parameters) of the state it started from
    (computed from the likelihoods the draw needs anyway)."""
    concept_ll = _concept_loglik(data, state)
    region_ll = GaussianRegions.log_likelihood(data.positions, data.homes, state.means, state.covariances)
    before = _conditional_log_joint(data, state, concept_ll, region_ll)
    if settings.joint_assignment:
        state.concepts, state.regions = allocation.sample_assignments_joint(
            state.log_g, state.log_pi, data.homes, concept_ll, region_ll, rng)
    else:  # the authors' two blocks: R | C, then C | R
        state.regions = allocation.sample_regions_given_concepts(state.log_pi, data.homes, state.concepts,
                                                                 region_ll, rng)
        state.concepts = allocation.sample_concepts_given_regions(state.log_g, state.log_pi, data.homes,
                                                                  state.regions, concept_ll, rng)
    return before


def _conditional_log_joint(data: PreparedData, state: GibbsState, concept_ll: np.ndarray,
                           region_ll: np.ndarray) -> float:
    """Σ_t log G_{e,C_t} + log π_{e,C_t,R_t} + log N(x_t | R_t) + log p(v_t, w_t | C_t)."""
    homes, c, r = data.homes, state.concepts, state.regions
    rows = np.arange(data.n_samples)
    return float((state.log_g[homes, c] + state.log_pi[homes, c, r] + region_ll[rows, r]
                  + concept_ll[rows, c]).sum())


def _global_step(stats: Statistics, state: GibbsState, hyper: TransferHyperparameters,
                 rng: np.random.Generator) -> None:
    """Exact: φ^v, φ^w and G_0 given CRT table counts (θ and G_e integrated out)."""
    tables_v = HierarchicalMultinomial.sample_tables(stats.visual, state.log_phi_v, hyper.delta_visual, rng)
    state.log_phi_v = HierarchicalMultinomial.sample_shared(tables_v, hyper.alpha_visual, rng)
    tables_w = HierarchicalMultinomial.sample_tables(stats.words, state.log_phi_w, hyper.delta_word, rng)
    state.log_phi_w = HierarchicalMultinomial.sample_shared(tables_w, hyper.alpha_word, rng)
    state.log_g0 = allocation.sample_global_concept_weights(stats.concepts, state.log_g0, hyper.gamma,
                                                            hyper.gamma0, rng)


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
    state.log_pi = allocation.sample_region_weights(stats.regions_by_concept, hyper.beta / K, rng)
    state.means, state.covariances = GaussianRegions.sample_posterior(
        stats.region_count, stats.region_total, stats.region_scatter, niw_prior(data, hyper, settings), rng)
    state.region_counts = stats.region_count.astype(np.int64)


def _swap_labels(data: PreparedData, state: GibbsState, stats: Statistics, hyper: TransferHyperparameters,
                 settings: SamplerSettings, rng: np.random.Generator) -> None:
    """Metropolis–Hastings label swaps within each home, θ marginalised (see
    :mod:`spco.model.moves`), then θ of the homes that changed redrawn from its conditional."""
    perms = concept_swap_step(stats.visual, state.log_phi_v, hyper.delta_visual, stats.words,
                              state.log_phi_w, hyper.delta_word, state.log_g, state.log_g0, hyper.gamma,
                              state.word_mask, rng)
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


def _prune(state: GibbsState, hyper: TransferHyperparameters, settings: SamplerSettings) -> None:
    """Recompute which words are informative enough to keep (``state.word_mask``).

    Exact variant: a word is kept if it passed :func:`place_words` and either its mutual
    information with some concept of the shared model (φ^w, G_0) reaches ε or it was taught in one
    home only (:func:`words_of_one_home`); reference variant: the authors' rule (KL score on φ^w,
    G_0).

    Pruned words are left out of the word likelihood of the next sweep and get probability 0 in
    the exported θ^w, φ^w (rows renormalised), as in the paper. The sampler itself keeps their
    φ^w and θ^w, so the pruning is re-decided after every sweep: a word pruned while concepts are
    still forming can come back once they separate (with φ^w set to 0, its table counts and hence
    its φ^w would stay 0 for ever).
    """
    if state.log_phi_w.shape[1] == 0:
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


class StepTimer:
    """Accumulates wall time per sampler step (for ``spco bench``): ``timer.seconds[name]``."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    def __call__(self, name: str):
        return _Timed(self, name)


class _Timed:
    def __init__(self, timer: StepTimer | None, name: str) -> None:
        self.timer, self.name = timer, name

    def __enter__(self) -> None:
        self.start = time.perf_counter()

    def __exit__(self, *exc: object) -> None:
        if self.timer is not None:
            elapsed = time.perf_counter() - self.start
            self.timer.seconds[self.name] = self.timer.seconds.get(self.name, 0.0) + elapsed


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
        previous_log_joint = _local_step(data, state, settings, rng)
    with _Timed(timer, "statistics"):
        stats = _statistics(data, state, hyper)
    if settings.variant == "reference":
        with _Timed(timer, "home parameters"):
            _home_step_reference(data, state, stats, hyper, settings, rng)
        if settings.learn_shared:
            with _Timed(timer, "shared parameters"):
                _global_step_reference(stats, state, hyper, rng)
    else:
        if settings.hierarchical and settings.learn_shared:
            with _Timed(timer, "shared parameters"):
                _global_step(stats, state, hyper, rng)
        with _Timed(timer, "home parameters"):
            _home_step(data, state, stats, hyper, settings, rng)
        if swaps and settings.hierarchical and data.n_homes > 1:
            with _Timed(timer, "label swaps"):
                _swap_labels(data, state, stats, hyper, settings, rng)
    if settings.prune and settings.learn_shared:
        with _Timed(timer, "word pruning"):
            _prune(state, hyper, settings)
    return previous_log_joint


# ----------------------------------------------------------------------------- log joint


def log_joint(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters,
              settings: SamplerSettings, include_parameter_priors: bool = False) -> float:
    """log p(data, C, R | parameters), or with ``include_parameter_priors`` the full
    log p(data, C, R, parameters), in the sampler's units, up to the multinomial coefficients
    (which do not depend on the state). With word pruning, pruned words are left out.

    The default leaves out the parameters' prior densities because, with α^w = 0.01 and
    δ^w φ^w ≪ 1, the Dirichlet density of a word distribution with near-zero entries reaches
    1e100 and more, which swamps every change of fit; the conditional log joint is the
    trace to watch for convergence."""
    E, L, K = data.n_homes, hyper.n_concepts, hyper.n_regions
    region_ll = GaussianRegions.log_likelihood(data.positions, data.homes, state.means, state.covariances)
    total = _conditional_log_joint(data, state, _concept_loglik(data, state), region_ll)
    if not include_parameter_priors:
        return total
    mask = state.word_mask
    if settings.hierarchical:
        total += HierarchicalMultinomial.log_prior_specific(state.log_theta_v, state.log_phi_v,
                                                            hyper.delta_visual)
        if mask.any():
            total += HierarchicalMultinomial.log_prior_specific(state.log_theta_w, state.log_phi_w,
                                                                hyper.delta_word, mask)
            total += HierarchicalMultinomial.log_prior_shared(state.log_phi_w, hyper.alpha_word, mask)
        total += HierarchicalMultinomial.log_prior_shared(state.log_phi_v, hyper.alpha_visual)
        total += float(dirichlet_log_density(state.log_g, hyper.gamma * np.exp(state.log_g0)).sum())
        total += float(dirichlet_log_density(state.log_g0, np.full(L, hyper.gamma0 / L)))
    else:
        total += HierarchicalMultinomial.log_prior_shared(state.log_theta_v.reshape(E * L, -1),
                                                          hyper.alpha_visual)
        if mask.any():
            total += HierarchicalMultinomial.log_prior_shared(state.log_theta_w.reshape(E * L, -1),
                                                              hyper.alpha_word, mask)
        total += float(dirichlet_log_density(state.log_g, np.full(L, hyper.gamma / L)).sum())
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
