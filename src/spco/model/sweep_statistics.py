"""The statistics of a sweep's assignments (:class:`Statistics`): the counts the global and home
steps (:mod:`spco.model.parameter_steps`) draw the parameters from, counted after the local step
(:mod:`spco.model.assignments`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spco.model import allocation
from spco.model.assignments import sentence_words, view_weights
from spco.model.home_place import home_place_statistics
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.observations import GaussianRegions, HierarchicalMultinomial
from spco.model.state import GibbsState, PreparedData, VisualCountCache
from spco.model.word_channels import (
    ChannelCounts,
    channel_counts,
    name_tokens,
    place_token_counts,
    token_scales,
)


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


def sufficient_statistics(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters,
                          view_counts: float | None) -> Statistics:
    """The statistics of the assignments; the visual counts weighted by the views' powers at
    ``view_counts`` (:func:`~spco.model.assignments.view_weights`; ``None``: every count whole), as
    the likelihood the assignments were drawn with weighs them."""
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

