"""The local step of a sweep: every sample's concept and region drawn given the parameters, and the
likelihoods they are drawn with (:func:`concept_loglik`, the visual and word log-likelihood of every
sample under every concept of its home). The statistics of the assignments are counted in
:mod:`spco.model.sweep_statistics`, the parameters drawn from them in :mod:`spco.model.parameter_steps`;
:func:`spco.model.gibbs.sweep` runs the three in turn."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from spco.model import allocation
from spco.model.blocks import region_block_step
from spco.model.hyperparameters import TransferHyperparameters, view_powers
from spco.model.observations import GaussianRegions, HierarchicalMultinomial
from spco.model.state import GibbsState, PreparedData, SamplerSettings
from spco.model.word_channels import mixture_log_likelihood, sample_switches, token_rows


def view_weights(data: PreparedData, view_counts: float | None) -> np.ndarray | None:
    """(N,) the weight of each sample's visual log-likelihood, ``min(1, view_counts / Σ_d v_d)``:
    a view scored as ``view_counts`` draws (``None``: every count a draw, no weights)."""
    if view_counts is None:
        return None
    return view_powers(data.view_totals, float(view_counts))


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


def concept_loglik(data: PreparedData, state: GibbsState, view_counts: float | None = None,
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


def home_concept_concentration(state: GibbsState, hyper: TransferHyperparameters,
                               settings: SamplerSettings) -> np.ndarray:
    """The Dirichlet concentration of every home's concept weights G_e (L,): γ G_0 (transfer model),
    γ/L (SpCoA) — G_e's prior in the log joint, integrated over by the block moves."""
    n_concepts = state.log_g.shape[1]
    if settings.hierarchical:
        return hyper.gamma * np.exp(state.log_g0)
    return np.full(n_concepts, hyper.gamma / n_concepts)


def conditional_log_joint(data: PreparedData, state: GibbsState, concept_ll: np.ndarray,
                          region_ll: np.ndarray) -> float:
    """Σ_t log G_{e,C_t} + log π_{e,C_t,R_t} + log N(x_t | R_t) + log p(v_t, w_t | C_t)."""
    homes, c, r = data.homes, state.concepts, state.regions
    rows = np.arange(data.n_samples)
    return float((state.log_g[homes, c] + state.log_pi[homes, c, r] + region_ll[rows, r]
                  + concept_ll[rows, c]).sum())


def local_step(data: PreparedData, state: GibbsState, settings: SamplerSettings,
               rng: np.random.Generator, hyper: TransferHyperparameters | None = None) -> float:
    """Draw the assignments; returns log p(data, C, R | parameters) of the state it started from
    (computed from the likelihoods the draw needs anyway).

    With ``settings.block_moves`` (exact sampler) and ``hyper`` given, the one-sample draws are
    followed by a pass of region block moves (:mod:`spco.model.blocks`: a region's samples of one
    concept change concept together, G_e and π integrated out), before the word switches are drawn;
    the caller's next home step redraws G_e and π given the result, as the move requires."""
    concept_ll = concept_loglik(data, state, settings.view_counts, settings.word_weight)
    region_ll = GaussianRegions.log_likelihood(data.positions, data.homes, state.means, state.covariances)
    before = conditional_log_joint(data, state, concept_ll, region_ll)
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

