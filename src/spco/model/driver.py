"""The driver of a fit: a sweep maps the home shards' local steps, reduces their statistics and
runs the global step (:class:`ShardedRun`); shards in this process (:class:`LocalEngine`), and how
a fit starts on an engine (:func:`start_run`, :func:`start_source_run`).

Where else shards may run — Ray actors — is :mod:`spco.engines`, whose engines subclass
:class:`ShardedRun`; the estimators and :func:`spco.knowledge.fit_knowledge` take an engine object
(``None``: :class:`LocalEngine`).
"""

from __future__ import annotations

import dataclasses
import itertools
from abc import ABC, abstractmethod
from collections.abc import Iterator

import numpy as np

from spco.errors import ConfigurationError
from spco.model import shard as shards_api
from spco.model import shard_init
from spco.model.cut_start import cut_phase, cut_sweeps
from spco.model.hyperparameters import ESTIMATE, VIEW_COUNTS, TransferHyperparameters
from spco.model.shard import GlobalStep
from spco.model.shard_group import ShardGroup
from spco.model.sources import HomeSource
from spco.model.state import GibbsState, PreparedData, SamplerSettings
from spco.model.view_fit import VIEW_WEIGHT_GRID, estimate_view_weight
from spco.model.visual_prior import estimate_visual_prior
from spco.model.word_prior import estimate_word_prior, given_delta_word


class ShardedRun(ABC):
    """A fit in progress: the driver's shared parameters and global step, and the workers.

    Every fit starts the same way: the homes of a :class:`~spco.model.sources.HomeSource` are cut
    into ``n_shards`` consecutive parts, each worker prepares its part and starts every home of it
    on its own (a :class:`~spco.model.shard_group.ShardGroup` of one-home shards, each drawing
    from its home's generator, :func:`~spco.model.shard.home_generator`), and the workers finish
    the start together through the driver (:func:`spco.model.shard_init.initialise`). Subclasses
    say where the workers live (:meth:`_start` and :meth:`call`). The chain depends on the seed
    only: the same for any number of workers and any engine."""

    def __init__(self, source: HomeSource, hyper: TransferHyperparameters, settings: SamplerSettings,
                 rng: np.random.Generator, n_shards: int) -> None:
        if not settings.hierarchical and source.n_homes > 1:
            raise ValueError("the SpCoA sampler learns one home: it has no shared part to reduce")
        #: what the kept sweeps target; with a cut start (:mod:`spco.model.cut_start`) the first
        #: ``cut_start`` sweeps run as the cut sampler (``hyper``, ``settings`` until then)
        self.target_hyper, self.target_settings = hyper, settings
        self.cut_start = cut_sweeps(hyper)
        self.cutting = self.cut_start > 0
        if self.cutting:
            hyper, settings = cut_phase(hyper, settings)
        self.hyper, self.settings, self.rng = hyper, settings, rng
        self.n_shards = n_shards
        self.n_homes = source.n_homes
        self.global_step = GlobalStep(hyper, settings, rng)
        self.bytes_sent = 0
        self.n_words = source.n_words
        parts = source.parts(n_shards)
        edges = np.cumsum([0, *[p.n_homes for p in parts]])
        self.bounds = [(int(a), int(b)) for a, b in itertools.pairwise(edges)]
        self.entropy = shards_api.home_entropy(rng)
        self._start(parts)
        self.shared, self.initialisation = shard_init.initialise(
            self.call, self.call_each, self.bounds, self.n_words, hyper, settings, rng)
        #: the view-weight estimate's record (``None``: w was given, not estimated)
        self.view_weight: dict | None = None
        if hyper.view_counts == ESTIMATE and settings.variant == "exact":
            self._estimate_view_weight()
        #: the visual prior's estimate (``None``: δ^v and α^v were given)
        self.visual_prior: dict | None = None
        #: the word prior's estimate (``None``: δ^w and α^w were given; made when the channels start)
        self.word_prior: dict | None = None
        if self.target_hyper.visual_prior == "estimate" and settings.variant == "exact" and self.n_homes > 1:
            self._estimate_visual_prior()

    def _estimate_visual_prior(self) -> None:
        """Estimate δ^v and α^v from the homes' views on the concepts of the start
        (:func:`spco.model.visual_prior.estimate_visual_prior`) and make every worker, the global
        step and this run's ``hyper`` use them from the first sweep of the chain on; a value that
        cannot be estimated stays as given."""
        parts = [home for part in self.call("visual_prior_moments") for home in part]  # home order
        m, s, q = (np.concatenate(arrays, axis=0) for arrays in zip(*parts, strict=True))
        delta, alpha = estimate_visual_prior(m, s, q)
        self.visual_prior = self._use_prior("visual", delta, alpha, self.hyper.delta_visual,
                                            self.hyper.alpha_visual)

    def _use_prior(self, kind: str, delta: float | None, alpha: float | None, given_delta: float,
                   given_alpha: float) -> dict:
        """Use the estimated δ and α of the ``kind`` prior ("visual", "word"; ``None``: not estimated,
        ``given_delta`` or ``given_alpha`` stays) in the target's hyperparameters and, unless the cut
        still runs (then the power target's, from its first sweep: :meth:`_start_power`), in this run's
        ``hyper``, the global step's and every worker's (``set_<kind>_prior``). Returns the record of
        the estimate: which were estimated, and the values used."""
        record = {f"delta_{kind}_estimated": delta is not None, f"alpha_{kind}_estimated": alpha is not None}
        values = {f"delta_{kind}": float(given_delta if delta is None else delta),
                  f"alpha_{kind}": float(given_alpha if alpha is None else alpha)}
        record.update(values)
        self.target_hyper = dataclasses.replace(self.target_hyper, **values)
        if not self.cutting:
            self.hyper = dataclasses.replace(self.hyper, **values)
            self.global_step.hyper = self.hyper
            self.call(f"set_{kind}_prior", *values.values())
        return record

    def _estimate_view_weight(self) -> None:
        """Learn the view weight w from the homes (:func:`spco.model.view_fit.estimate_view_weight`,
        on the concepts of the start) and make every worker, the global step and this run's
        ``hyper`` and ``settings`` use it from the first sweep of the chain on. Without a taught view
        in two homes there is nothing to estimate from: w stays the start's
        :data:`~spco.model.hyperparameters.VIEW_COUNTS`."""
        totals, taught, words = (sum(parts) for parts in zip(*self.call("view_weight_totals"), strict=True))
        losses, used, homes = np.zeros(len(VIEW_WEIGHT_GRID)), 0, 0
        for part in self.call("view_weight_losses", totals, taught, words):
            for home_losses, home_used in part:  # in home order
                losses, used, homes = losses + home_losses, used + home_used, homes + (home_used > 0)
        w = estimate_view_weight(losses, used) if homes > 1 else None
        self.view_weight = {"estimated": w is not None, "views": int(used),
                            "grid": [float(g) for g in VIEW_WEIGHT_GRID],
                            "mean_log_loss": [float(x) / max(used, 1) for x in losses]}
        w = VIEW_COUNTS if w is None else w
        self.view_weight["view_counts"] = w
        self.hyper = dataclasses.replace(self.hyper, view_counts=w)
        self.settings = dataclasses.replace(self.settings, view_counts=w)
        self.target_hyper = dataclasses.replace(self.target_hyper, view_counts=w)
        self.target_settings = dataclasses.replace(self.target_settings, view_counts=w)
        self.global_step.hyper, self.global_step.settings = self.hyper, self.settings
        self.call("set_view_weight", w)

    @abstractmethod
    def _start(self, parts: list) -> None:
        """Start one worker per part (a :class:`~spco.model.sources.HomesPart`, homes
        ``self.bounds[i]`` of the fit): it prepares its homes and starts each on its own
        (:meth:`ShardGroup.from_part <spco.model.shard_group.ShardGroup.from_part>` with
        ``self.entropy``)."""

    @abstractmethod
    def call(self, method: str, *args) -> list:
        """Run the :class:`~spco.model.shard_group.ShardGroup` method on every worker; results in
        worker (hence home) order."""

    @abstractmethod
    def call_each(self, method: str, args: list[tuple]) -> list:
        """Run the :class:`~spco.model.shard_group.ShardGroup` method on worker i with ``args[i]``;
        results in worker order."""

    def sweep(self, iteration: int) -> float:
        """Sweep number ``iteration`` (0-based); returns the log joint of the state it started from.
        With a cut start, the power target's chain takes over before sweep ``cut_start``
        (:meth:`_start_power`)."""
        if self.cutting and iteration >= self.cut_start:
            self._start_power()
        log_joint, self.shared = shards_api.sweep(self.call, self.global_step, self.shared, iteration,
                                                  self.shared.word_mask, self.shared.name_words)
        return log_joint

    def _start_power(self) -> None:
        """The cut start's end (:mod:`spco.model.cut_start`): the assignments, regions and switches
        kept, every worker recounts its statistics as the power target weighs views and tokens, and
        every parameter is drawn from the power target's conditionals — the shared ones from the
        homes' tables (:class:`~spco.model.shard.GlobalStep`), then each home's θ, G_e, π, μ, Σ — before
        the power target's first sweep."""
        self._cut_phase = (self.hyper, self.settings)  # (what rewind_cut_start restores)
        hyper, settings = self.target_hyper, self.target_settings
        channels = self.shared.channels
        if channels is not None:
            channels = dataclasses.replace(channels, power=True)
        self.hyper, self.settings, self.cutting = hyper, settings, False
        self.global_step.hyper, self.global_step.settings = hyper, settings
        self.call("start_power", hyper, settings, channels)
        shared = dataclasses.replace(self.shared, channels=channels)
        if settings.learn_shared and settings.hierarchical:
            shared = self.global_step.run(self.call, shared)
        self.call("home_step", shared, False, False)
        self.shared = shared

    def rewind_cut_start(self, iteration: int) -> None:
        """Back to the cut start's sweeps when a restarted engine resumes at sweep ``iteration``
        (0-based) before the power target's first sweep (:meth:`_start_power` runs again then)."""
        if self.cut_start and not self.cutting and iteration <= self.cut_start:
            self.hyper, self.settings = self._cut_phase
            self.global_step.hyper, self.global_step.settings = self.hyper, self.settings
            self.cutting = True

    def fit(self, n_iterations: int, after_sweep=None) -> np.ndarray:
        """Run sweeps 0..n_iterations − 1; returns their log joints (entry i: the state sweep i
        started from). ``after_sweep(iteration, log_joint)`` (optional) is called after each sweep
        (a restarted engine calls it again for the sweeps it repeats)."""
        trace = np.empty(n_iterations)
        for iteration in range(n_iterations):
            trace[iteration] = self.sweep(iteration)
            if after_sweep is not None:
                after_sweep(iteration, trace[iteration])
        return trace

    @abstractmethod
    def states(self) -> list[GibbsState]:
        """Every worker's state (copies where the workers live elsewhere)."""

    def home_states(self) -> list[GibbsState]:
        """States whose homes, in order, are every home of the fit: the workers' own states where
        they live in this process (no copies), else :meth:`states`."""
        return self.states()

    def home_visual(self) -> Iterator[np.ndarray]:
        """Every home's log θ^v (L, D), in home order, without joining them (views where the
        workers live in this process)."""
        for state in self.home_states():
            yield from state.log_theta_v

    def state(self, visual: bool = True) -> GibbsState:
        """The workers' states joined: the state of every home, with the word mask of the last
        sweep's pruning (the homes receive it with the next local step). ``visual=False``: without
        log θ^v (``None``; read it per home with :meth:`home_visual`), the largest field, which
        joining copies."""
        if visual:
            state = shards_api.join_states(self.states())
        else:
            state = shards_api.join_states(self.home_states(), without=("log_theta_v",))
        state.word_mask = self.shared.word_mask
        state.name_words = self.shared.name_words
        joined, state.channels = state.channels, self.shared.channels
        if joined is not None and joined.log_place_home is not None and state.channels is not None:
            # the place channel's home level: the shared part with every home's own ψ_{e,l}
            state.channels = dataclasses.replace(state.channels, log_place_home=joined.log_place_home)
        return state

    def use_word_channels(self, channels) -> None:
        """From the next sweep on, words follow the word channels ``channels``
        (:class:`~spco.model.word_channels.WordChannels`) instead of the naming rule: no word is
        pruned, and every token's switch is drawn from the next local step on. Called after the
        start (which places the homes by the naming rule's names: a start, valid for any target)."""
        self.shared = dataclasses.replace(self.shared, word_mask=np.ones_like(self.shared.word_mask),
                                          name_words=None, channels=channels)
        if (self.target_hyper.word_prior == "estimate" and self.settings.variant == "exact"
                and self.n_homes > 1 and self.word_prior is None):
            # (with a cut start: weighed as the power target's channels, used from its first sweep)
            self._estimate_word_prior(dataclasses.replace(channels, power=True) if self.cutting else channels)

    def _estimate_word_prior(self, channels) -> None:
        """Estimate δ^w and α^w from the homes' name tokens on the concepts of the start, each token
        weighed by the switch's prior p(z = name | word) of ``channels``
        (:func:`spco.model.word_prior.estimate_word_prior`), and make every worker, the global step
        and this run's ``hyper`` use them from the next sweep on. Where the homes' names do not spread
        beyond their sampling noise (homes that name alike: template speech) the moments give no
        finite δ^w, and the given δ^w is put in the units θ^w counts a token in
        (:func:`spco.model.word_prior.given_delta_word`: times W^w / S^w under the power target); an α^w
        that cannot be estimated stays as given."""
        parts = [home for part in self.call("word_prior_moments", channels.name_prior()) for home in part]
        m, s, q = (np.concatenate(arrays, axis=0) for arrays in zip(*parts, strict=True))
        delta, alpha = estimate_word_prior(m, s, q)
        self.word_prior = self._use_prior("word", delta, alpha,
                                          given_delta_word(self.target_hyper.delta_word, channels),
                                          self.target_hyper.alpha_word)

    @abstractmethod
    def close(self) -> None:
        """Free the workers."""


class LocalRun(ShardedRun):
    """Workers as :class:`~spco.model.shard_group.ShardGroup` objects in this process."""

    def _start(self, parts) -> None:
        self.shards = [ShardGroup.from_part(p, first, self.entropy, self.n_words, self.n_homes, self.hyper,
                                            self.settings)
                       for p, (first, _) in zip(parts, self.bounds, strict=True)]

    def call(self, method: str, *args) -> list:
        return [getattr(s, method)(*args) for s in self.shards]

    def call_each(self, method: str, args: list[tuple]) -> list:
        return [getattr(s, method)(*a) for s, a in zip(self.shards, args, strict=True)]

    def states(self) -> list[GibbsState]:
        return [s.state for s in self.shards]

    def home_states(self) -> list[GibbsState]:
        return [h.state for s in self.shards for h in s.homes]

    def close(self) -> None:
        """Drop the workers (this process's objects: their data views, caches and states), so that
        what follows a fit does not hold them beside the joined state."""
        self.shards = []


class LocalEngine:
    """Workers in this process: ``LocalEngine(shards)`` cuts the homes into ``shards`` groups
    (default 1, the default fit); any number gives the same chain, as the Ray engine does."""

    name = "local"

    def __init__(self, shards: int = 1) -> None:
        if shards < 1:
            raise ValueError(f"shards must be at least 1, got {shards}")
        self.shards = shards

    def start_source(self, source: HomeSource, hyper: TransferHyperparameters, settings: SamplerSettings,
                     rng: np.random.Generator) -> ShardedRun:
        """Start the workers from ``source``: each prepares and starts its own homes
        (:mod:`spco.model.shard_init`)."""
        return LocalRun(source, hyper, settings, rng, min(self.shards, source.n_homes))


def _engine(engine) -> object:
    """``engine`` as an engine object: ``None`` or ``"local"`` is :class:`LocalEngine`; other names
    are resolved by :func:`spco.engines.make_engine`, which the layers above call."""
    if engine is None or engine == "local":
        return LocalEngine()
    if isinstance(engine, str):
        raise ConfigurationError(f"engine {engine!r}: pass an engine object, e.g. "
                                 f"spco.engines.make_engine({engine!r})")
    return engine


def start_run(engine, data: PreparedData, n_words: int, hyper: TransferHyperparameters,
              settings: SamplerSettings, rng: np.random.Generator) -> ShardedRun:
    """Start a fit of ``data`` (``n_words`` words) on ``engine`` (an engine object, or ``None``:
    ``LocalEngine()``): :func:`start_source_run` of the homes of ``data``."""
    from spco.model.sources import PreparedHomes

    return start_source_run(engine, PreparedHomes(data, n_words), hyper, settings, rng)


def start_source_run(engine, source: HomeSource, hyper: TransferHyperparameters, settings: SamplerSettings,
                     rng: np.random.Generator) -> ShardedRun:
    """Start a fit of the homes of ``source`` (a :class:`~spco.model.sources.HomeSource`, e.g.
    :class:`~spco.model.sources.FolderHomes`) on ``engine`` (an engine object, or ``None``:
    ``LocalEngine()``): every worker prepares and starts its own homes, and the driver never holds
    them (:class:`ShardedRun`)."""
    return _engine(engine).start_source(source, hyper, settings, rng)
