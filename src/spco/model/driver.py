"""The driver of a fit: a sweep maps the home shards' local steps, reduces their statistics and
runs the global step (:class:`ShardedRun`); shards in this process (:class:`LocalEngine`), and how
a fit starts on an engine (:func:`start_run`, :func:`start_source_run`).

Where else shards may run — Ray actors — is :mod:`spco.engines`, whose engines subclass
:class:`ShardedRun`; the estimators and :func:`spco.knowledge.fit_knowledge` take an engine object
(``None``: :class:`LocalEngine`).
"""

from __future__ import annotations

import itertools
from abc import ABC, abstractmethod

import numpy as np

from spco.errors import ConfigurationError
from spco.model import shard as shards_api
from spco.model import shard_init
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.shard import GlobalStep, HomeShard, SharedParameters
from spco.model.shard_init import InitialisationReport
from spco.model.sources import HomeSource
from spco.model.state import GibbsState, PreparedData, SamplerSettings


class ShardedRun(ABC):
    """A fit in progress: the driver's shared parameters and global step, and the shards.

    Subclasses say where the shards live (:meth:`_start` and :meth:`call`). With ``share_rng``
    (one in-process shard only) the shard draws from the driver's generator: the chain of
    :func:`spco.model.gibbs.sweep`. Otherwise shard i draws from its own generator seeded from
    the driver's (:func:`~spco.model.shard.shard_seeds`)."""

    def __init__(self, data: PreparedData | None, state: GibbsState | None, hyper: TransferHyperparameters,
                 settings: SamplerSettings, rng: np.random.Generator, n_shards: int,
                 share_rng: bool = False, source: HomeSource | None = None) -> None:
        if n_shards > 1 and not settings.hierarchical:
            raise ValueError("the SpCoA sampler has no shared part to reduce: run it with one shard")
        if share_rng and (n_shards != 1 or source is not None):
            raise ValueError("only one in-process shard started from the driver's state can share the "
                             "driver's random generator")
        self.hyper, self.settings, self.rng = hyper, settings, rng
        self.n_shards = n_shards
        self.global_step = GlobalStep(hyper, settings, rng)
        self.bytes_sent = 0
        self.initialisation: InitialisationReport | None = None
        parts: list
        if source is None:
            self.shared = SharedParameters.of(state)
            self.n_words = state.log_phi_w.shape[1]
            parts = shards_api.split(data, state, n_shards)
            sizes = [d.n_homes for d, _ in parts]
        else:
            self.n_words = source.n_words
            parts = source.parts(n_shards)
            sizes = [p.n_homes for p in parts]
        edges = np.cumsum([0, *sizes])
        self.bounds = [(int(a), int(b)) for a, b in itertools.pairwise(edges)]
        generators = ([rng] if share_rng
                      else [np.random.default_rng(s) for s in shards_api.shard_seeds(rng, n_shards)])
        self._start(parts, generators)
        if source is not None:
            self.shared, self.initialisation = shard_init.initialise(
                self.call, self.call_each, self.bounds, self.n_words, hyper, settings, rng)

    @abstractmethod
    def _start(self, parts: list, generators: list[np.random.Generator]) -> None:
        """Start one shard per part, drawing from its generator: a part is a ``(data, state)`` pair
        (initialised in the driver) or a :class:`~spco.model.sources.HomesPart` (the shard prepares
        and starts its homes, :meth:`HomeShard.from_part`)."""

    @abstractmethod
    def call(self, method: str, *args) -> list:
        """Run the :class:`~spco.model.shard.HomeShard` method on every shard; results in shard order."""

    @abstractmethod
    def call_each(self, method: str, args: list[tuple]) -> list:
        """Run the :class:`~spco.model.shard.HomeShard` method on shard i with ``args[i]``; results
        in shard order."""

    def sweep(self, iteration: int) -> float:
        """Sweep number ``iteration`` (0-based); returns the log joint of the state it started from."""
        log_joint, self.shared = shards_api.sweep(self.call, self.global_step, self.shared, iteration,
                                                  self.shared.word_mask)
        return log_joint

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
        """Every shard's state (copies where the shards live elsewhere)."""

    def state(self) -> GibbsState:
        """The shards' states joined: the state of every home, with the word mask of the last
        sweep's pruning (the shards receive it with the next local step)."""
        state = shards_api.join_states(self.states())
        state.word_mask = self.shared.word_mask
        return state

    @abstractmethod
    def close(self) -> None:
        """Free the shards."""


class LocalRun(ShardedRun):
    """Shards as :class:`~spco.model.shard.HomeShard` objects in this process."""

    def _start(self, parts, generators) -> None:
        self.shards = [HomeShard(*p, self.hyper, self.settings, g) if isinstance(p, tuple)
                       else HomeShard.from_part(p, self.n_words, self.hyper, self.settings, g)
                       for p, g in zip(parts, generators, strict=True)]

    def call(self, method: str, *args) -> list:
        return [getattr(s, method)(*args) for s in self.shards]

    def call_each(self, method: str, args: list[tuple]) -> list:
        return [getattr(s, method)(*a) for s, a in zip(self.shards, args, strict=True)]

    def states(self) -> list[GibbsState]:
        return [s.state for s in self.shards]

    def close(self) -> None:
        """Nothing to free: the shards are this process's objects, dropped with the run."""


class LocalEngine:
    """Shards in this process. ``LocalEngine(1)`` is the default fit: one shard sharing the
    driver's generator (``share_rng``), the chain of :func:`spco.model.gibbs.sweep`; more shards
    (or ``share_rng=False``) give the chain the Ray engine gives with as many shards."""

    name = "local"

    def __init__(self, shards: int = 1, share_rng: bool | None = None) -> None:
        if shards < 1:
            raise ValueError(f"shards must be at least 1, got {shards}")
        self.shards = shards
        self.share_rng = shards == 1 if share_rng is None else share_rng

    def start(self, data: PreparedData, state: GibbsState, hyper: TransferHyperparameters,
              settings: SamplerSettings, rng: np.random.Generator) -> ShardedRun:
        """Split ``data`` and ``state`` into the shards and return the run."""
        return LocalRun(data, state, hyper, settings, rng, min(self.shards, data.n_homes), self.share_rng)

    def start_source(self, source: HomeSource, hyper: TransferHyperparameters, settings: SamplerSettings,
                     rng: np.random.Generator) -> ShardedRun:
        """Start the shards from ``source``: each prepares and initialises its own homes
        (:mod:`spco.model.shard_init`; every shard draws from its own generator, also with one shard)."""
        return LocalRun(None, None, hyper, settings, rng, min(self.shards, source.n_homes), source=source)


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
    the default ``LocalEngine()``).

    The default engine, one in-process shard sharing the driver's generator, initialises in the
    driver (:func:`spco.model.gibbs.initialize`): the chain of :func:`spco.model.gibbs.sweep`. An
    engine whose shards draw from their own generators (Ray, or local with several shards) starts
    them from the data instead (``engine.start_source``): each shard initialises its own homes
    and the warm start's label alignment goes through the driver as per-home summaries
    (:mod:`spco.model.shard_init`), so the driver never holds every home's sampler state. The
    same seed and number of shards give the same chain on either engine."""
    from spco.model import gibbs
    from spco.model.sources import PreparedHomes

    engine = _engine(engine)
    if getattr(engine, "share_rng", False) or not hasattr(engine, "start_source"):
        state = gibbs.initialize(data, n_words, hyper, settings, rng)
        return engine.start(data, state, hyper, settings, rng)
    return engine.start_source(PreparedHomes(data, n_words), hyper, settings, rng)


def start_source_run(engine, source: HomeSource, hyper: TransferHyperparameters, settings: SamplerSettings,
                     rng: np.random.Generator) -> tuple[ShardedRun, PreparedData | None]:
    """Start a fit of the homes of ``source`` (a :class:`~spco.model.sources.HomeSource`, e.g.
    :class:`~spco.model.sources.FolderHomes`) on ``engine`` (as :func:`start_run`); returns the
    run and the data the driver prepared: ``None`` where the shards prepare their own homes (Ray,
    or local with several shards), so the driver never holds them; all homes for the default
    one-process engine, which initialises in the driver. The same chain as :func:`start_run`
    given the same homes prepared in the driver."""
    engine = _engine(engine)
    if getattr(engine, "share_rng", False) or not hasattr(engine, "start_source"):
        data = source.parts(1)[0].prepare()
        return start_run(engine, data, source.n_words, hyper, settings, rng), data
    return engine.start_source(source, hyper, settings, rng), None
