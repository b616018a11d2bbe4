"""The learnt parameters of the spatial-concept model: a posterior summary, all homes stacked.

This is the interface between learning (:mod:`spco.model`) and use (:mod:`spco.model.prediction`,
:mod:`spco.evaluation`, model files): every model — the transfer model and the SpCoA baselines —
produces a :class:`ConceptParameters`, and prediction needs nothing else. Positions are in metres
whatever units the sampler used internally.

Shapes use E homes, L concepts, K regions, V words, D visual features.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np


@dataclass(frozen=True, eq=False)
class ConceptParameters:
    """A summary of the model's parameters (an average over thinned sweeps, see
    :mod:`spco.model.posterior`) or one sample of them.

    Attributes
    ----------
    concept_weights: (E, L) G_e, the concept distribution of each home.
    region_weights: (E, L, K) π_{e,l}, the region distribution of each concept in each home.
    region_means: (E, K, 4) μ_{e,m} in metres (x, y, sin θ, cos θ).
    region_covariances: (E, K, 4, 4) Σ_{e,m} in metres².
    word_probabilities: (E, L, V) θ^w_{e,l}; pruned words have probability 0.
    visual_probabilities: (E, L, D) θ^v_{e,l}, strictly positive.
    shared_word_probabilities: (L, V) φ^w_l, home-independent.
    shared_visual_probabilities: (L, D) φ^v_l, home-independent.
    global_concept_weights: (L,) G_0.
    word_mask: (V,) bool, False for words removed by mutual-information pruning.
    region_counts: (E, K) int, training samples assigned to each region (0 = unused region).
    concept_counts: (E, L) float, mean number of training samples assigned to each concept over
        the averaged sweeps (< 1: the concept holds no sample of the home), or ``None`` (model
        files written before it existed: no concept is then known to be empty).
    name_prior: (V,) float in (0, 1), P(name | how the word was said and what it is)
        (:func:`spco.model.name_evidence.name_prior`): which known words may stand for a name
        nobody said (:mod:`spco.model.unheard`), and, only when asked for
        (``predict_names(..., name_prior="wordnet")``), the order of each concept's words; or
        ``None`` (models without the naming rule, and files written before it existed: every word
        alike).
    place_word_probabilities: (L, V) ψ_l, the words said at each concept's place that are not its
        names (objects, activities, people: the word channels, :mod:`spco.model.word_channels`), or
        ``None`` (models without the channels). ``word_probabilities`` is then the names channel.
    word_channel_prior: (V, 3) p(z = name, place, background | word), the switch's prior of every
        word with the learnt shares, or ``None``.
    """

    concept_weights: np.ndarray
    region_weights: np.ndarray
    region_means: np.ndarray
    region_covariances: np.ndarray
    word_probabilities: np.ndarray
    visual_probabilities: np.ndarray
    shared_word_probabilities: np.ndarray
    shared_visual_probabilities: np.ndarray
    global_concept_weights: np.ndarray
    word_mask: np.ndarray
    region_counts: np.ndarray
    concept_counts: np.ndarray | None = None
    name_prior: np.ndarray | None = None
    place_word_probabilities: np.ndarray | None = None
    word_channel_prior: np.ndarray | None = None

    @property
    def n_environments(self) -> int:
        """Number of homes E."""
        return int(self.concept_weights.shape[0])

    @property
    def n_concepts(self) -> int:
        """Number of concepts L."""
        return int(self.concept_weights.shape[1])

    @property
    def n_regions(self) -> int:
        """Number of regions K."""
        return int(self.region_means.shape[1])

    def arrays(self) -> dict[str, np.ndarray]:
        """All fields as a name -> array mapping (for saving)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}
