"""The sampler's data and state: all homes' samples stacked in the sampler's units
(:class:`PreparedData`, made from a corpus by :meth:`PreparedData.from_corpus`), the assignments and
parameters after a sweep (:class:`GibbsState`), the part of them every home shares
(:class:`SharedParameters`, what the driver sends the shards) and what distinguishes the samplers
(:class:`SamplerSettings`). The sweeps are in :mod:`spco.model.gibbs`."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from spco.data.environment import Corpus
from spco.errors import ConfigurationError
from spco.model.hyperparameters import ESTIMATE, VIEW_COUNTS
from spco.model.kernels.counts import stack_counts
from spco.model.kernels.likelihood import DimensionMajorCounts, dimension_major
from spco.model.word_channels import WordChannels

VARIANTS = ("exact", "reference", "spcoa")

#: Reference variant: positions in centimetres.
CM_PER_M = 100.0


@dataclass(frozen=True, eq=False)
class PreparedData:
    """All homes' training samples stacked, in the sampler's units.

    positions (N, 4), homes (N,) home index of each sample, visual (N, D) CSR int64 counts,
    words (N, V) CSR int64 counts (empty rows for untaught samples), n_homes E, offsets (E+1,)
    so that home e holds rows offsets[e]:offsets[e+1], position_scale (1 for metres, 100 for cm),
    view_missing (N,) bool: the samples without a view (their rows of ``visual`` are empty, so
    their visual likelihood — a product over no counts — is 1: it is left out, marginalised, not
    imputed; and an empty row adds nothing to any visual statistic). ``D`` is 0 when no sample
    of any home has a view.
    """

    positions: np.ndarray
    homes: np.ndarray
    visual: sp.csr_array
    words: sp.csr_array
    n_homes: int
    offsets: np.ndarray
    position_scale: float
    map_centres: np.ndarray  # (E, 4) in sampler units
    view_missing: np.ndarray | None = None  # (N,) bool; None: every sample has a view

    def __post_init__(self) -> None:
        n = int(np.asarray(self.homes).size)
        missing = np.zeros(n, dtype=bool) if self.view_missing is None \
            else np.asarray(self.view_missing, dtype=bool)
        if missing.shape != (n,):
            raise ValueError(f"view_missing must have shape ({n},), got {missing.shape}")
        if missing.any() and self.visual[np.flatnonzero(missing)].nnz:
            raise ValueError("a sample without a view must have an empty visual row")
        object.__setattr__(self, "view_missing", missing)

    @classmethod
    def from_corpus(cls, corpus: Corpus, position_scale: float) -> PreparedData:
        """The training samples of every home of ``corpus`` stacked as the sampler reads them, positions
        multiplied by ``position_scale`` (1 for metres, :data:`CM_PER_M` for the reference variant's
        centimetres: :attr:`spco.model.transfer.SpatialConceptModel.position_scale`); raises
        :class:`~spco.errors.ConfigurationError` for a home without training samples."""
        if not isinstance(corpus, Corpus):
            raise ConfigurationError("fit() expects a spco.data.Corpus")
        training = corpus.training_set()
        for env, train in zip(corpus, training, strict=True):
            if train.n_samples == 0:
                raise ConfigurationError(
                    f"home {env.name!r} has no training samples: all {env.n_samples} samples are in its "
                    "test split, and test samples are never used for training")
        positions = np.concatenate([t.positions for t in training]) * np.array(
            [position_scale, position_scale, 1.0, 1.0])
        sizes = np.array([t.n_samples for t in training])
        offsets = np.concatenate([[0], np.cumsum(sizes)])
        homes = np.repeat(np.arange(len(training)), sizes)
        visual = stack_counts(*(t.visual for t in training))  # stacked once, in the kernels' layout
        words = stack_counts(corpus.word_counts([s for t in training for s in t.sentences]))
        centres = np.zeros((len(training), 4))
        for e, t in enumerate(training):
            if t.extent is not None:
                x0, x1, y0, y1 = t.extent
                centres[e, :2] = ((x0 + x1) / 2, (y0 + y1) / 2)
            else:
                centres[e, :2] = t.positions[:, :2].mean(0)
        centres[:, :2] *= position_scale
        missing = np.concatenate([t.view_missing for t in training])
        return cls(positions=positions, homes=homes, visual=visual, view_missing=missing, words=words,
                   n_homes=len(training), offsets=offsets, position_scale=position_scale, map_centres=centres)

    @property
    def n_views(self) -> np.ndarray:
        """(E,) samples with a view in each home."""
        return np.add.reduceat(~self.view_missing, self.offsets[:-1]) if self.n_samples \
            else np.zeros(self.n_homes, dtype=np.int64)

    @property
    def n_samples(self) -> int:
        """N."""
        return int(self.homes.size)

    @cached_property
    def visual_by_dimension(self) -> DimensionMajorCounts:
        """The visual counts by home and dimension (:func:`~spco.model.kernels.likelihood.dimension_major`),
        built at the first sweep: the layout of the visual likelihood's kernel."""
        return dimension_major(self.visual, self.offsets)

    @cached_property
    def view_totals(self) -> np.ndarray:
        """(N,) float: the visual counts of each sample (``Σ_d v_d``), for a view's weight."""
        return np.asarray(self.visual.sum(axis=1), dtype=np.float64).ravel()

    @cached_property
    def niw_priors(self) -> dict:
        """The NIW priors already built for this data (:func:`spco.model.parameter_steps.niw_prior`), by
        hyperparameters and variant: built once per fit instead of once per sweep."""
        return {}


@dataclass
class GibbsState:
    """Assignments and parameters after a sweep (log-probabilities, sampler units).

    concepts (N,), regions (N,); log_g (E, L) G_e; log_g0 (L,) G_0; log_pi (E, L, K) π;
    means (E, K, 4), covariances (E, K, 4, 4); log_theta_v (E, L, D), log_theta_w (E, L, V);
    log_phi_v (L, D), log_phi_w (L, V); word_mask (V,) words kept by pruning; candidate_words
    (V,) words that the mutual-information pruning may keep at all (``None``: every word);
    home_specific_words (V,) candidates it never prunes (the exact variant uses neither: see
    :func:`naming_verdicts`); name_words (V,) the words the naming rule judges names (exact variant
    with pruning; ``None``: none judged yet): a taught sample whose sentence holds one is scored by
    its name words only (:func:`spco.model.assignments.sentence_words`); channels and switches: the word
    channels (:mod:`spco.model.word_channels`), which replace the naming rule where set.
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
    name_words: np.ndarray | None = None
    #: the words matrix :func:`spco.model.assignments.sentence_words` last built: (data.words, name_words
    #: bytes, matrix)
    words_cache: tuple | None = field(default=None, repr=False)
    #: the word channels' parameters (:class:`spco.model.word_channels.WordChannels`, shared by all
    #: homes; ``None``: the naming rule's word model)
    channels: object | None = None
    #: every token's switch (:mod:`spco.model.word_channels`): (nnz of ``data.words``,) int8, drawn in
    #: the local step after the concepts (``None`` before the first draw or without channels)
    switches: np.ndarray | None = field(default=None, repr=False)


@dataclass
class SharedParameters:
    """The parameters every home shares (log-probabilities): φ^v (L, D), φ^w (L, V), G_0 (L,), the
    word-pruning mask (V,) bool and the words judged names (V,) bool or ``None``
    (:func:`spco.model.assignments.sentence_words`)."""

    log_phi_v: np.ndarray
    log_phi_w: np.ndarray
    log_g0: np.ndarray
    word_mask: np.ndarray
    name_words: np.ndarray | None = None
    #: the word channels (:mod:`spco.model.word_channels`; ``None``: the naming rule's word model)
    channels: WordChannels | None = None

    @classmethod
    def of(cls, state: GibbsState) -> SharedParameters:
        """The shared parameters held in ``state``."""
        return cls(state.log_phi_v, state.log_phi_w, state.log_g0, state.word_mask, state.name_words,
                   state.channels)

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays (what a broadcast sends)."""
        arrays = (self.log_phi_v, self.log_phi_w, self.log_g0, self.word_mask, self.name_words)
        if self.channels is not None:
            c = self.channels
            arrays += (c.log_place, c.log_background, c.log_shares, c.log_evidence)
        return sum(a.nbytes for a in arrays if a is not None)


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
    view_counts: float | None = None
    #: region block moves after each one-sample assignment draw (:mod:`spco.model.blocks`; exact
    #: sampler only)
    block_moves: bool = False
    #: the φ^v-marginal block moves of the power target after each sweep's statistics
    #: (:mod:`spco.model.phi_moves`; ``TransferHyperparameters.block_moves == "phi"``, exact sampler,
    #: :func:`spco.model.gibbs.sweep`)
    phi_moves: bool = False
    #: the power likelihood in every step (``TransferHyperparameters.target == "power"``; exact
    #: sampler only): θ^v and φ^v learn from the views' weighted counts as the assignments weigh them
    power: bool = False
    #: the evidence of one word token in a sample's concept draw when the state has no word channels,
    #: as a share of the token's S^w counts (1: S^w per token; or one per sample, (N,)). A fit with
    #: the word channels and ``TransferHyperparameters.warm_start="words"`` sets W^w / S^w for its warm
    #: start's independent sweeps (:mod:`spco.model.shard_init`), so that the start weighs a token as
    #: the chain does; the chain weighs tokens through the channels and does not read this
    word_weight: float | np.ndarray = 1.0
    #: vocabulary columns that mark no place at the warm start although the naming rule may judge them
    #: names (:func:`spco.model.word_channels.warm_start_settings`); the chain does not read this
    start_not_names: tuple[int, ...] = ()

    @classmethod
    def create(cls, variant: str, prune: bool, learn_shared: bool = True,
               view_counts: float | str | None = None, block_moves: bool = False,
               power: bool = False, phi_moves: bool = False) -> SamplerSettings:
        """Settings of ``variant`` (``exact``, ``reference`` or ``spcoa``).

        ``learn_shared=False`` keeps φ^v, φ^w and G_0 fixed (adapting to a new home with
        knowledge learnt elsewhere): sweeps then update only the homes' own variables.
        ``view_counts``: the evidence of one view in counts
        (:attr:`~spco.model.hyperparameters.TransferHyperparameters.view_counts`; ``"estimate"``:
        the start's :data:`~spco.model.hyperparameters.VIEW_COUNTS` until the driver sets the
        estimate); the exact variant only — the authors' sampler and SpCoA score every count, as
        published. ``block_moves``: after each sweep's one-sample assignments, move every region's
        samples of one concept together (:mod:`spco.model.blocks`); the exact variant only. ``power``:
        the chain targets the power likelihood (``TransferHyperparameters.target``); exact variant.
        ``phi_moves``: the power target's φ^v-marginal block moves (:mod:`spco.model.phi_moves`); exact
        variant with ``power`` only."""
        if view_counts == ESTIMATE:
            view_counts = VIEW_COUNTS
        if variant not in VARIANTS:
            raise ValueError(f"unknown sampler variant {variant!r}; choose one of {VARIANTS}")
        return cls(variant=variant, prune=prune, hierarchical=variant != "spcoa",
                   joint_assignment=variant != "reference",
                   pruning_score="kl" if variant == "reference" else "mi", learn_shared=learn_shared,
                   view_counts=view_counts if variant == "exact" else None,
                   block_moves=bool(block_moves) and variant == "exact",
                   power=bool(power) and variant == "exact",
                   phi_moves=bool(phi_moves) and bool(power) and variant == "exact")

    def learning_view_counts(self) -> float | None:
        """The view weight with which θ^v, φ^v and the label swaps count a view: the assignments'
        :attr:`view_counts` when the chain targets the power likelihood (:attr:`power`), ``None``
        (every count) in the cut sampler."""
        return self.view_counts if self.power else None
