"""Where a fit's home shards run: :mod:`spco.model.driver` (in this process, the default) or
:mod:`spco.engines.ray` (Ray actors, on this machine or a cluster; ``pip install "spco[ray]"``).

An engine starts a :class:`~spco.model.driver.ShardedRun` from a
:class:`~spco.model.sources.HomeSource` whose homes every shard prepares and starts itself
(``engine.start_source``; :func:`start_run` for homes prepared in the driver):
``run.sweep(iteration)`` is one sweep of :func:`spco.model.shard.sweep` and ``run.state()`` joins
the shards' states. Every home draws from its own random stream, so the same seed gives the same
chain for any number of shards and on every engine.
"""

from __future__ import annotations

import numpy as np

from spco.model import driver
from spco.model.driver import LocalEngine, ShardedRun
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


def _resolve(engine):
    """An engine object for ``engine``: a name (:func:`make_engine`), an engine, or ``None``."""
    return make_engine(engine) if isinstance(engine, str) else engine


def start_run(engine, data: PreparedData, n_words: int, hyper: TransferHyperparameters,
              settings: SamplerSettings, rng: np.random.Generator) -> ShardedRun:
    """:func:`spco.model.driver.start_run` with ``engine`` also given by name (``"local"``, ``"ray"``)."""
    return driver.start_run(_resolve(engine), data, n_words, hyper, settings, rng)


def start_source_run(engine, source, hyper: TransferHyperparameters, settings: SamplerSettings,
                     rng: np.random.Generator) -> ShardedRun:
    """:func:`spco.model.driver.start_source_run` with ``engine`` also given by name."""
    return driver.start_source_run(_resolve(engine), source, hyper, settings, rng)


__all__ = ["ENGINES", "LocalEngine", "ShardedRun", "make_engine", "start_run", "start_source_run"]
