"""A sweep as map → reduce → global step: home shards, the statistics they send, the global step.

A :class:`HomeShard` holds some homes' data and sampler state. One sweep is

1. **map** — every shard's :meth:`HomeShard.local_step` draws its samples' concepts and regions and
   counts their statistics (kept in the shard);
2. **reduce** — the shards send what the shared parameters need, summed over their homes:
   CRT table counts (:meth:`HomeShard.tables`, exact sampler) or pooled counts
   (:meth:`HomeShard.pooled_counts`, the authors' sampler), (L, D), (L, V) and (L,) arrays whose
   size does not grow with the homes; the driver adds them up;
3. **global step** — :class:`GlobalStep` draws φ^v, φ^w and G_0 from the sums
   (:class:`~spco.model.state.SharedParameters`), which every shard then receives in
   :meth:`HomeShard.home_step` (θ, G_e, π, μ, Σ of its homes, label swaps, and the word-pruning mask).
4. **naming rule** (exact sampler with pruning) — every shard counts how often pairs of each word's
   uses fall in the same region of its homes and the log-likelihood of their regions on a grid of
   excess values (:meth:`HomeShard.colocation`, three (V,) arrays and one (V, 50), all adding up
   over homes); the driver sums them and judges which words are names
   (:func:`spco.model.pruning.judge_names`): the mask sent with the next local step.

Only statistics and shared parameters travel, so shards can live in other processes or machines
(:mod:`spco.engines`). A :class:`HomeShard` of a fit holds one home and draws from that home's own
random generator (:func:`home_generator`: seeded from the fit's seed and the home's index); the
homes a worker runs are a :class:`~spco.model.shard_group.ShardGroup`, and the driver draws from
its own generator. The statistics that travel add up exactly (integer counts, and per-home float
statistics rounded to :data:`~spco.model.additive.SUM_GRID`), so the chain depends on the seed only:
the same for any number of workers and any engine.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from spco.model import assignments, gibbs, parameter_steps, sweep_statistics
from spco.model.additive import SUM_GRID, PooledCounts
from spco.model.gibbs import GibbsState, PreparedData, SamplerSettings
from spco.model.home_place import shared_place_counts, uses_home_place
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.kernels.counts import csr_rows
from spco.model.kernels.crt import sample_crt
from spco.model.kernels.dirichlet import log_dirichlet
from spco.model.observations import HierarchicalMultinomial
from spco.model.phi_moves import move_home, phi_moves_due, sharded_phi_move, taught_homes
from spco.model.pruning import NAME, NOT_A_NAME, Colocation, colocation, judge_names
from spco.model.shard_init import ShardInitialisation
from spco.model.state import SharedParameters
from spco.model.word_channels import (
    ChannelCounts,
    WordChannels,
    expected_tokens,
    place_mean,
    place_names,
    sample_channels,
)


def home_generator(entropy: list[int], home: int) -> np.random.Generator:
    """The random generator of home ``home`` (its index in the fit) of a fit whose homes draw from
    ``entropy`` (:func:`home_entropy`): ``SeedSequence(entropy, spawn_key=(home,))``, the stream
    ``SeedSequence(entropy).spawn(n)[home]`` would give, whatever shard the home is in."""
    return np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=(int(home),)))


def home_entropy(rng: np.random.Generator) -> list[int]:
    """The entropy of a fit's home generators, drawn from the driver's generator (128 bits)."""
    return [int(v) for v in rng.integers(0, 2**63 - 1, size=2, dtype=np.int64)]

#: What a shard's :meth:`HomeShard.tables` can count.
TABLE_KINDS = ("visual", "words", "concepts")


@dataclass
class HomeStepResult:
    """What a shard reports after its home step: the new word mask (V,) (``None`` without
    pruning) and, for the SpCoA sampler (one shard), the shared part it exports."""

    word_mask: np.ndarray | None
    shared: SharedParameters | None = None


class HomeShard(ShardInitialisation):
    """Some homes' data and sampler state, and the steps that touch only them.

    In a fit every home is a shard of its own, drawing from its home's generator, and the homes a
    worker runs are a :class:`~spco.model.shard_group.ShardGroup`. A shard starts its homes on
    their own (:meth:`start`) and finishes its initialisation with the others (the ``init_*`` steps of
    :class:`~spco.model.shard_init.ShardInitialisation`, run by
    :func:`spco.model.shard_init.initialise`).

    Parameters
    ----------
    data:
        The shard's homes (:class:`~spco.model.gibbs.PreparedData`, home indices 0..E_s − 1).
    state:
        Their state (:class:`~spco.model.gibbs.GibbsState`, arrays over the shard's homes and
        samples), holding a copy of the shared parameters it last received.
    hyper, settings:
        The model's hyperparameters and sampler settings.
    rng:
        The shard's random generator (a fit's shard holds one home and draws from its generator,
        :func:`home_generator`).
    n_fit_homes:
        Homes of the whole fit (default: the shard's); label swaps need more than one.
    """

    def __init__(self, data: PreparedData, state: GibbsState, hyper: TransferHyperparameters,
                 settings: SamplerSettings, rng: np.random.Generator, n_fit_homes: int | None = None) -> None:
        self.data, self.state, self.hyper, self.settings, self.rng = data, state, hyper, settings, rng
        self.n_fit_homes = data.n_homes if n_fit_homes is None else int(n_fit_homes)
        self.stats: sweep_statistics.Statistics | None = None
        self.setup_seconds: dict[str, float] = {}
        #: (the statistics, δ^v, φ^v's weight at them: :meth:`visual_log_weight`)
        self._weight: (tuple[sweep_statistics.Statistics, float, Callable[[np.ndarray], np.ndarray]]
                       | None) = None

    @classmethod
    def start(cls, data: PreparedData, n_words: int, hyper: TransferHyperparameters,
              settings: SamplerSettings, rng: np.random.Generator,
              n_fit_homes: int | None = None) -> HomeShard:
        """A shard of ``data`` whose homes start on their own (:func:`spco.model.gibbs.initialize`:
        k-means regions, their Gaussians, π); :func:`spco.model.shard_init.initialise` then
        finishes the start with the other shards."""
        state = gibbs.initialize(data, n_words, hyper, settings, rng)
        return cls(data, state, hyper, settings, rng, n_fit_homes)

    def candidate_words(self) -> np.ndarray | None:
        """The words the reference sampler found to depend on the place (V,) bool, or ``None``."""
        return self.state.candidate_words

    def concept_visual_totals(self) -> np.ndarray:
        """The shard's visual counts by concept, (L,) (:func:`spco.model.view_fit.concept_visual_totals`)."""
        from spco.model.view_fit import concept_visual_totals

        return concept_visual_totals(self.data, self.state.concepts, self.hyper.n_concepts)

    def held_out_view_fits(self, log_phi_v: np.ndarray, log_g0: np.ndarray,
                           totals: np.ndarray) -> list[float | None]:
        """The held-out view fit of each of the shard's homes (:func:`spco.model.view_fit.held_out_view_fits`;
        ``totals``: (L,) visual counts by concept over all homes)."""
        from spco.model.view_fit import held_out_view_fits

        return held_out_view_fits(log_phi_v, log_g0, totals, self.data, self.state.concepts)

    def view_weight_totals(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The shard's visual counts (L, D), taught views (L,) and taught words (L, V) by concept, for
        the view-weight estimate (:func:`spco.model.view_fit.home_concept_totals`)."""
        from spco.model.view_fit import home_concept_totals

        return home_concept_totals(self.data, self.state.concepts, self.hyper.n_concepts)

    def view_weight_losses(self, totals: np.ndarray, taught: np.ndarray, words: np.ndarray
                           ) -> tuple[np.ndarray, int]:
        """The leave-one-home-out log loss of the shard's taught views on the view-weight grid
        (:func:`spco.model.view_fit.view_weight_losses`; ``totals``, ``taught``, ``words``: all
        homes')."""
        from spco.model.view_fit import view_weight_losses

        return view_weight_losses(self.data, self.state.concepts, totals, taught, words,
                                  self.hyper.alpha_visual, self.hyper.alpha_word)

    def set_view_weight(self, view_counts: float | None) -> None:
        """From the next sweep on, a view weighs ``view_counts`` (the estimate of the driver)."""
        self.hyper = replace(self.hyper, view_counts=view_counts)
        self.settings = replace(self.settings, view_counts=view_counts)

    def visual_prior_moments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The shard's views by concept as proportions, for the visual prior's estimate
        (:func:`spco.model.visual_prior.home_view_moments`)."""
        from spco.model.visual_prior import home_view_moments

        return home_view_moments(self.data, self.state.concepts, self.hyper.n_concepts)

    def word_prior_moments(self, name_prior: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The shard's name tokens by concept, each weighed by ``name_prior`` (V,), for the word
        prior's estimate (:func:`spco.model.word_prior.home_name_moments`)."""
        from spco.model.word_prior import home_name_moments

        return home_name_moments(self.data, self.state.concepts, self.hyper.n_concepts, name_prior)

    def set_word_prior(self, delta_word: float, alpha_word: float) -> None:
        """From the next sweep on, θ^w ~ Dir(δ^w φ^w) and φ^w ~ Dir(α^w) at these values (the
        driver's estimate)."""
        self.hyper = replace(self.hyper, delta_word=float(delta_word), alpha_word=float(alpha_word))

    def visual_means(self) -> np.ndarray:
        """The shard's log θ^v summary for a fit's average (E, L, D): under the power target its
        conditional mean log((δ^v φ^v + n^v) / (δ^v + N^v)) given the sweep's counts (a Dirichlet with
        parameters far below one draws most coordinates near e^(−1/a): no estimate of its mean),
        otherwise the draw."""
        if self.hyper.target != "power" or self.stats is None:
            return self.state.log_theta_v
        a = self.hyper.delta_visual * np.exp(self.state.log_phi_v)[None] + self._stats().visual
        return np.log(a) - np.log(a.sum(axis=-1, keepdims=True))

    def set_visual_prior(self, delta_visual: float, alpha_visual: float) -> None:
        """From the next sweep on, θ^v ~ Dir(δ^v φ^v) and φ^v ~ Dir(α^v) at these values (the
        driver's estimate)."""
        self.hyper = replace(self.hyper, delta_visual=float(delta_visual), alpha_visual=float(alpha_visual))

    def shared_parameters(self) -> SharedParameters:
        """The shared parameters the shard holds."""
        return SharedParameters.of(self.state)

    @property
    def n_homes(self) -> int:
        """Homes in this shard."""
        return self.data.n_homes

    def n_views(self) -> np.ndarray:
        """(E,) samples with a view in each of the shard's homes (a sample without one has its
        visual likelihood left out: ``PreparedData.view_missing``)."""
        return self.data.n_views

    def local_step(self, word_mask: np.ndarray | None = None, name_words: np.ndarray | None = None,
                   channels: WordChannels | None = None) -> float:
        """Draw every sample's concept and region and count the statistics (kept in the shard).

        ``word_mask`` (V,) is the pruning decision of the previous sweep and ``name_words`` (V,) the
        words it judged names, ``channels`` the word channels (``None``: unchanged). Returns this
        shard's part of log p(data, C, R | parameters) for the state it started from."""
        if word_mask is not None:
            self.state.word_mask = word_mask
        if name_words is not None:
            self.state.name_words = name_words
        if channels is not None:
            if uses_home_place(self.hyper):  # the shared part received, the homes' own ψ_{e,l} kept
                held = self.state.channels
                channels = replace(channels, log_place_home=None if held is None else held.log_place_home)
            self.state.channels = channels
        log_joint = assignments.local_step(self.data, self.state, self.settings, self.rng, self.hyper)
        self.stats = sweep_statistics.sufficient_statistics(self.data, self.state, self.hyper,
                                                self.settings.learning_view_counts())
        return log_joint

    def start_power(self, hyper: TransferHyperparameters, settings: SamplerSettings,
                    channels: WordChannels | None) -> None:
        """The end of a cut start (:mod:`spco.model.cut_start`): from now on the power target's
        ``hyper``, ``settings`` and word ``channels`` (``None``: none); the statistics recounted from
        the kept assignments, regions and switches as the power target weighs views and tokens."""
        self.hyper, self.settings = hyper, settings
        if channels is not None:
            if uses_home_place(hyper):  # the shared part received, the homes' own ψ_{e,l} kept
                held = self.state.channels
                channels = replace(channels, log_place_home=None if held is None else held.log_place_home)
            self.state.channels = channels
        self.stats = sweep_statistics.sufficient_statistics(self.data, self.state, hyper,
                                                settings.learning_view_counts())

    def tables(self, kind: str) -> np.ndarray:
        """CRT table counts of ``kind`` (``visual`` (L, D), ``words`` (L, V), ``concepts`` (L,)),
        summed over the shard's homes, given the shared parameters the shard holds."""
        stats, state, hyper = self._stats(), self.state, self.hyper
        if kind == "visual":  # (3, L, D): HierarchicalMultinomial.table_parts
            parts = HierarchicalMultinomial.table_parts(stats.visual, state.log_phi_v, hyper.delta_visual,
                                                        self.rng)
            return np.stack(parts).astype(np.float64)
        if kind == "words":
            return HierarchicalMultinomial.sample_tables(stats.words, state.log_phi_w, hyper.delta_word,
                                                         self.rng)
        if kind == "concepts":
            concentration = hyper.gamma * np.exp(state.log_g0)[None, :]
            return sample_crt(stats.concepts, concentration, self.rng).sum(axis=0)
        raise ValueError(f"unknown table kind {kind!r}; choose one of {TABLE_KINDS}")

    def visual_counts(self) -> np.ndarray:
        """(E_s, L, D) the shard's homes' real view counts per concept (the views' weighted counts
        under the power target), the other homes of the φ^v-marginal move (:mod:`spco.model.phi_moves`)."""
        return np.asarray(self._stats().visual)

    def taught_homes(self) -> np.ndarray:
        """(E_s,) whether each of the shard's homes has a sample with a word."""
        return taught_homes(self.data)

    def phi_move(self, others: np.ndarray, tables) -> np.ndarray:
        """The φ^v-marginal block move's pass over the shard's one home
        (:func:`spco.model.phi_moves.move_home`, the shard's generator) given the other homes' real
        counts ``others`` (E − 1, L, D) and their tables (M, F, H) given the shard's φ^v; the statistics
        recounted. Returns the home's counts per concept after the pass (L, D)."""
        if self.data.n_homes != 1:
            raise RuntimeError(f"HomeShard.phi_move: a shard of one home moves, not {self.data.n_homes}")
        self.stats, _ = move_home(self.data, self.state, self._stats(), self.hyper, self.settings, 0, others,
                                  tables, self.rng)
        return np.asarray(self.stats.visual[0])

    def visual_log_weight(self, log_phi: np.ndarray) -> np.ndarray:
        """(L, D) the shard's part of φ^v's fractional weight per dimension (the views' weighted
        counts: :meth:`HierarchicalMultinomial.fractional_log_weight_terms`), what the blocked φ^v
        step's acceptance ratios are summed from."""
        stats, delta = self._stats(), self.hyper.delta_visual
        if self._weight is None or self._weight[0] is not stats or self._weight[1] != delta:
            # the same statistics in every evaluation of a sweep's φ^v step: their fractional
            # counts gathered once (a local step or a recount makes new statistics)
            weight = HierarchicalMultinomial.fractional_log_weight_evaluator(stats.visual, delta)
            self._weight = (stats, delta, weight)
        return self._weight[2](log_phi)

    def channel_counts(self) -> ChannelCounts:
        """The switches' counts of the shard's homes (word channels; each token once). With the place
        channel's home level (``place_channel="home"``) ``place`` holds the homes' CRT tables given ψ_l
        instead of their place tokens (:func:`spco.model.home_place.shared_place_counts`): what ψ_l's
        step needs, adding up over homes as the counts do."""
        stats = self._stats()
        if stats.channel is None:
            raise RuntimeError("HomeShard: no word channels in this state")
        return shared_place_counts(stats, self.state.channels, self.hyper, self.rng)

    def expected_channel_tokens(self) -> np.ndarray:
        """(V, 3) the shard's expected tokens of each word per channel given its state
        (:func:`spco.model.word_channels.expected_tokens`: the switch probabilities summed)."""
        state = self.state
        if state.channels is None:
            raise RuntimeError("HomeShard: no word channels in this state")
        return expected_tokens(self.data.words, self.data.homes, state.concepts, state.log_theta_w,
                               state.channels)

    def concept_place_names(self, stand_ins: np.ndarray | None = None) -> np.ndarray:
        """(L, V) the names said at each concept's places over the shard's homes
        (:func:`spco.model.word_channels.place_names`, each home's regions its own; ``stand_ins``: the
        name each object stands in for, −1 none)."""
        state = self.state
        if state.channels is None:
            raise RuntimeError("HomeShard: no word channels in this state")
        return place_names(self.data.words, self.data.homes, state.concepts, state.regions, state.log_theta_w,
                           state.channels, state.log_theta_w.shape[1], stand_ins=stand_ins)

    def pooled_counts(self) -> PooledCounts:
        """The shard's visual, word and concept counts summed over its homes (authors' sampler)."""
        stats = self._stats()
        return PooledCounts(stats.visual.sum(0), stats.words.sum(0), stats.concepts.sum(0))

    def home_step(self, shared: SharedParameters | None, swaps: bool = False,
                  prune: bool = False) -> HomeStepResult:
        """Receive the new shared parameters (``None``: keep them), then draw θ, G_e, π, μ, Σ of
        the shard's homes (and the label swaps if ``swaps``); with ``prune``, re-decide the
        word mask from the shared parameters and return it."""
        data, state, hyper, settings, rng = self.data, self.state, self.hyper, self.settings, self.rng
        stats = self._stats()
        if shared is not None:
            self.receive(shared)
        if settings.variant == "reference":
            parameter_steps.home_step_reference(data, state, stats, hyper, settings, rng)
        else:
            parameter_steps.home_step(data, state, stats, hyper, settings, rng)
            if swaps and settings.hierarchical and self.n_fit_homes > 1:
                parameter_steps.swap_labels(data, state, stats, hyper, settings, rng)
        if prune and not uses_naming_rule(settings):  # (the naming rule is judged over all shards)
            gibbs.prune(state, hyper, settings)
        exported = None if settings.hierarchical else SharedParameters.of(state)
        return HomeStepResult(state.word_mask if prune else None, exported)

    def receive(self, shared: SharedParameters, prune: bool = False) -> HomeStepResult:
        """Take the new shared parameters; with ``prune``, re-decide the word mask from them."""
        self.state.log_phi_v, self.state.log_phi_w = shared.log_phi_v, shared.log_phi_w
        self.state.log_g0, self.state.word_mask = shared.log_g0, shared.word_mask
        if shared.name_words is not None:
            self.state.name_words = shared.name_words
        if shared.channels is not None:
            self.state.channels = shared.channels
        if prune:
            gibbs.prune(self.state, self.hyper, self.settings)
        return HomeStepResult(self.state.word_mask if prune else None)

    def colocation(self) -> Colocation:
        """The naming rule's statistics of the shard's homes on their current regions: pairs of each
        word's uses in one home, those in one region, and those expected there by chance, (V,) each,
        and the log-likelihood of the uses' regions on the grid of excess values, (V, 50) (they add
        up over shards; the float ones rounded to :data:`SUM_GRID`, so that they add up exactly)."""
        data = self.data
        return colocation(data.words, data.homes, self.state.regions, data.n_homes, self.hyper.n_regions,
                          grid=SUM_GRID)

    def _stats(self) -> sweep_statistics.Statistics:
        if self.stats is None:
            raise RuntimeError("HomeShard: call local_step() before this step")
        return self.stats


class GlobalStep:
    """The driver's step: the shared parameters from the shards' summed statistics.

    ``call(method, *args)`` runs a :class:`HomeShard` method on every shard and returns the
    results in shard order (in process, or on Ray actors); the sums are taken in shard order, so
    the result does not depend on where the shards run."""

    def __init__(self, hyper: TransferHyperparameters, settings: SamplerSettings,
                 rng: np.random.Generator) -> None:
        self.hyper, self.settings, self.rng = hyper, settings, rng
        self.bytes_received = 0
        #: log E[φ^v | the last sweep's tables] (L, D) under the power target: the mean of the φ^v
        #: step's proposal Dir(α^v + M + F), what a knowledge averages instead of the draws (a
        #: Dirichlet with parameters far below one draws most of its coordinates near e^(−1/a), so an
        #: average of a few draws is no estimate of the mean); ``None`` otherwise
        self.visual_mean: np.ndarray | None = None
        #: log E[ψ | the last sweep's place tokens] (L, V) with the word channels: Dir(α^p + counts)'s
        #: mean, what a fit exports instead of the draw (a concept no taught home holds has no place
        #: token; Dir(α^p = 0.1) then draws a spike on one word, which ``where`` would read as that
        #: word's place); ``None`` without the channels
        self.place_mean: np.ndarray | None = None

    def run(self, call, shared: SharedParameters, moved: tuple | None = None) -> SharedParameters:
        """New shared parameters given the current ones and the shards' statistics; ``moved``: the
        visual tables (M, F, H) of every home drawn by a φ^v-marginal block move this sweep
        (:func:`spco.model.phi_moves.sharded_phi_move`), which the φ^v step then proposes from."""
        hyper, rng = self.hyper, self.rng
        if self.settings.variant == "reference":
            counts = self.reduce(call("pooled_counts"))
            return SharedParameters(log_dirichlet(hyper.alpha_visual + counts.visual, rng),
                                    log_dirichlet(hyper.alpha_word + counts.words, rng),
                                    log_dirichlet(hyper.gamma0 + counts.concepts, rng), shared.word_mask,
                                    shared.name_words, shared.channels)
        # φ^v: CRT tables of the whole parts of the views' weighted counts, Dirichlet proposals
        # with the fractional parts, blocks accepted with the exact remainder summed over the shards
        # (HierarchicalMultinomial.sample_shared_given_counts; whole counts: the CRT step itself)
        tables_v, frac_v, fractional = self.reduce(call("tables", "visual")) if moved is None else moved
        log_phi_v = HierarchicalMultinomial.accept_shared(
            lambda phi: self.reduce(call("visual_log_weight", phi)), shared.log_phi_v,
            hyper.alpha_visual, tables_v, frac_v, rng, fractional > 0, passes=hyper.phi_passes)
        if hyper.target == "power":
            pseudo = hyper.alpha_visual + tables_v + frac_v
            self.visual_mean = np.log(pseudo) - np.log(pseudo.sum(axis=-1, keepdims=True))
        log_phi_w = log_dirichlet(hyper.alpha_word + self.reduce(call("tables", "words")), rng)
        tables_g = self.reduce(call("tables", "concepts"))
        log_g0 = log_dirichlet(hyper.gamma0 / hyper.n_concepts + tables_g, rng)
        channels = shared.channels
        if channels is not None:  # ψ, β, λ from the switches' counts of every home
            counts = self.reduce(call("channel_counts"))
            channels = sample_channels(counts, channels, rng)
            self.place_mean = place_mean(counts)
        return SharedParameters(log_phi_v, log_phi_w, log_g0, shared.word_mask, shared.name_words, channels)

    def reduce(self, parts: list):
        """The shards' statistics added up in shard order (counting the bytes received)."""
        total = parts[0]
        for part in parts[1:]:
            total = total + part
        self.bytes_received += sum(_nbytes(p) for p in parts)
        return total


def _nbytes(value) -> int:
    if isinstance(value, PooledCounts):
        return value.visual.nbytes + value.words.nbytes + value.concepts.nbytes
    if isinstance(value, Colocation | ChannelCounts):
        return value.nbytes
    return int(np.asarray(value).nbytes)


def sweep(call, global_step: GlobalStep, shared: SharedParameters, iteration: int,
          word_mask: np.ndarray | None = None,
          name_words: np.ndarray | None = None) -> tuple[float, SharedParameters]:
    """One sweep over the shards reached through ``call`` (see :class:`GlobalStep`): map (local
    steps), reduce and global step, then every shard's home step.

    ``word_mask`` is the mask decided by the previous sweep's pruning and ``name_words`` the words
    it judged names, sent with the local step (``None`` when unchanged). Returns the log joint of
    the state the sweep started from (the homes' parts summed in home order) and the new shared
    parameters (with the new mask and names)."""
    settings = global_step.settings
    # every home's part, summed in home order (the same sum however the homes are grouped)
    log_joint = float(sum(value for part in call("local_step", word_mask, name_words, shared.channels)
                          for value in np.atleast_1d(part)))
    prune = settings.prune and settings.learn_shared and shared.channels is None  # channels: no rule
    swaps = gibbs.swaps_due(iteration)
    if settings.variant == "reference":
        results = call("home_step", None, swaps, False)
        if settings.learn_shared:  # the authors' order: the homes, then the shared part, then pruning
            shared = global_step.run(call, shared)
            results = call("receive", shared, prune)
    elif settings.hierarchical:
        if settings.learn_shared:
            moved = None
            if settings.phi_moves and phi_moves_due(iteration, global_step.hyper):  # power target
                moved = sharded_phi_move(call, shared.log_phi_v, global_step.hyper, global_step.rng)
            shared = global_step.run(call, shared, moved)
        results = call("home_step", shared, swaps, prune)
    else:  # SpCoA: no shared part; its one shard exports the mean of its homes' parameters
        results = call("home_step", None, swaps, prune)
        shared = results[0].shared
    if prune:
        names = shared.name_words
        if uses_naming_rule(settings):
            verdicts = judge_names(global_step.reduce(call("colocation")))
            mask, names = verdicts != NOT_A_NAME, verdicts == NAME
        else:
            mask = results[0].word_mask
        shared = SharedParameters(shared.log_phi_v, shared.log_phi_w, shared.log_g0, mask, names,
                                  shared.channels)
    return log_joint, shared


def uses_naming_rule(settings: SamplerSettings) -> bool:
    """Whether pruning follows the naming rule over all homes (exact sampler) rather than a score of
    the shared parameters every shard can compute alone (the authors' KL, SpCoA+MI)."""
    return settings.prune and settings.variant == "exact"


# ----------------------------------------------------------------------------- splitting homes


def shard_bounds(data: PreparedData, n_shards: int) -> list[tuple[int, int]]:
    """Contiguous home ranges [first, last) for ``n_shards`` shards of about equal samples."""
    if not 1 <= n_shards <= data.n_homes:
        raise ValueError(f"the number of shards must be within 1..{data.n_homes} (the homes), got {n_shards}")
    targets = data.offsets[-1] * np.arange(1, n_shards) / n_shards
    cuts = np.searchsorted(data.offsets, targets)
    cuts = np.clip(cuts, np.arange(1, n_shards), data.n_homes - n_shards + np.arange(1, n_shards))
    cuts = np.maximum.accumulate(cuts)
    edges = [0, *[int(c) for c in cuts], data.n_homes]
    for i in range(1, len(edges)):  # every shard at least one home
        edges[i] = max(edges[i], edges[i - 1] + 1)
    return list(itertools.pairwise(edges))


def data_of_homes(data: PreparedData, first: int, last: int) -> PreparedData:
    """The homes first..last − 1 of ``data`` as their own :class:`PreparedData` (homes renumbered;
    the sparse counts' values and column indices are views of ``data``'s, which nothing writes)."""
    rows = slice(int(data.offsets[first]), int(data.offsets[last]))
    return PreparedData(positions=data.positions[rows].copy(), homes=data.homes[rows] - first,
                        visual=_rows_of(data.visual, rows), words=_rows_of(data.words, rows),
                        n_homes=last - first, offsets=data.offsets[first:last + 1] - data.offsets[first],
                        position_scale=data.position_scale, map_centres=data.map_centres[first:last].copy(),
                        view_missing=data.view_missing[rows].copy())


def _rows_of(matrix, rows: slice) -> sp.csr_array:
    """Rows ``rows`` of a sparse matrix as CSR, views of its values and int32 column indices
    (:func:`csr_rows`)."""
    if not isinstance(matrix, sp.csr_array):
        matrix = sp.csr_array(matrix)
    return csr_rows(matrix, rows.start, rows.stop)


#: GibbsState fields indexed by home, by sample, and shared by all homes.
HOME_FIELDS = ("log_g", "log_pi", "means", "covariances", "log_theta_v", "log_theta_w", "region_counts")
SAMPLE_FIELDS = ("concepts", "regions")
SHARED_FIELDS = ("log_phi_v", "log_phi_w", "log_g0", "word_mask", "candidate_words", "home_specific_words",
                 "name_words", "channels")


def state_of_homes(data: PreparedData, state: GibbsState, first: int, last: int) -> GibbsState:
    """The part of ``state`` for homes first..last − 1 (copies; the shared part copied too)."""
    rows = slice(int(data.offsets[first]), int(data.offsets[last]))
    fields = {name: np.array(getattr(state, name)[first:last]) for name in HOME_FIELDS}
    fields.update({name: getattr(state, name)[rows].copy() for name in SAMPLE_FIELDS})
    fields.update({name: None if getattr(state, name) is None else getattr(state, name).copy()
                   for name in SHARED_FIELDS})
    channels = fields["channels"]
    if channels is not None and channels.log_place_home is not None and channels.log_place_home.shape[0] > 1:
        fields["channels"] = replace(channels, log_place_home=channels.log_place_home[first:last].copy())
    return GibbsState(**fields)


def join_states(states: list[GibbsState], without: tuple[str, ...] = ()) -> GibbsState:
    """The states of consecutive shards as one (the shared part taken from the first); the fields
    named in ``without`` are not joined (``None``, e.g. log θ^v for the average, which reads each
    home's own: :meth:`~spco.model.driver.ShardedRun.home_states`)."""
    if len(states) == 1:
        return states[0]
    fields = {name: None if name in without else np.concatenate([getattr(s, name) for s in states])
              for name in HOME_FIELDS + SAMPLE_FIELDS}
    fields.update({name: getattr(states[0], name) for name in SHARED_FIELDS})
    homes_place = [None if s.channels is None else s.channels.log_place_home for s in states]
    if all(h is not None for h in homes_place):  # the place channel's home level: every home's own
        fields["channels"] = replace(states[0].channels, log_place_home=np.concatenate(homes_place))
    return GibbsState(**fields)


def split(data: PreparedData, state: GibbsState, n_shards: int) -> list[tuple[PreparedData, GibbsState]]:
    """``data`` and ``state`` cut into ``n_shards`` consecutive groups of homes; one shard is the
    objects themselves (no copy)."""
    if n_shards == 1:
        return [(data, state)]
    return [(data_of_homes(data, a, b), state_of_homes(data, state, a, b))
            for a, b in shard_bounds(data, n_shards)]
