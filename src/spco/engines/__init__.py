"""Where a fit's home shards run: :mod:`spco.engines.local` (in this process, the default) or
:mod:`spco.engines.ray` (Ray actors, on this machine or a cluster; ``pip install "spco[ray]"``).

An engine starts a :class:`~spco.engines.local.ShardedRun` from the initialised data and state
(``engine.start``), or from a :class:`~spco.model.sources.HomeSource` whose homes every shard
prepares and initialises itself (``engine.start_source``; :func:`start_run` picks the path):
``run.sweep(iteration)`` is one sweep of :func:`spco.model.shard.sweep` and ``run.state()`` joins
the shards' states. The same seed and number of shards give the same chain on every engine.
"""

from __future__ import annotations

import numpy as np

from spco.engines.local import LocalEngine, ShardedRun
from spco.model.gibbs import PreparedData, SamplerSettings
from spco.model.hyperparameters import TransferHyperparameters

ENGINES = ("local", "ray")


def make_engine(name: str = "local", shards: int | None = None, address: str | None = None,
                checkpoint_every: int = 10, checkpoint_dir: str | None = None):
    """The engine called ``name`` (``local`` or ``ray``) with ``shards`` shards (default 1 local,
    2 on Ray); ``address`` is the Ray cluster to join (default: start a local Ray instance);
    ``checkpoint_every`` sweeps between the Ray engine's checkpoints, kept in ``checkpoint_dir``
    (default: in the driver's memory)."""
    if name == "local":
        return LocalEngine(shards or 1)
    if name == "ray":
        from spco.engines.ray import RayEngine

        return RayEngine(shards or 2, address=address, checkpoint_every=checkpoint_every,
                         checkpoint_dir=checkpoint_dir)
    raise ValueError(f"unknown engine {name!r}; choose one of {ENGINES}")


def start_run(engine, data: PreparedData, n_words: int, hyper: TransferHyperparameters,
              settings: SamplerSettings, rng: np.random.Generator) -> ShardedRun:
    """Start a fit of ``data`` (``n_words`` words) on ``engine`` (a name, an engine, or ``None``:
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

    engine = make_engine(engine) if isinstance(engine, str) else (engine or LocalEngine())
    if getattr(engine, "share_rng", False) or not hasattr(engine, "start_source"):
        state = gibbs.initialize(data, n_words, hyper, settings, rng)
        return engine.start(data, state, hyper, settings, rng)
    return engine.start_source(PreparedHomes(data, n_words), hyper, settings, rng)


def start_source_run(engine, source, hyper: TransferHyperparameters, settings: SamplerSettings,
                     rng: np.random.Generator) -> tuple[ShardedRun, PreparedData | None]:
    """Start a fit of the homes of ``source`` (a :class:`~spco.model.sources.HomeSource`, e.g.
    :class:`~spco.model.sources.FolderHomes`) on ``engine`` (as :func:`start_run`); returns the
    run and the data the driver prepared: ``None`` where the shards prepare their own homes (Ray,
    or local with several shards), so the driver never holds them; all homes for the default
    one-process engine, which initialises in the driver. The same chain as :func:`start_run`
    given the same homes prepared in the driver."""
    engine = make_engine(engine) if isinstance(engine, str) else (engine or LocalEngine())
    if getattr(engine, "share_rng", False) or not hasattr(engine, "start_source"):
        data = source.parts(1)[0].prepare()
        return start_run(engine, data, source.n_words, hyper, settings, rng), data
    return engine.start_source(source, hyper, settings, rng), None


__all__ = ["ENGINES", "LocalEngine", "ShardedRun", "make_engine", "start_run", "start_source_run"]
