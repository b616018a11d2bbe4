"""Where a fit's home shards run: :mod:`spco.engines.local` (in this process, the default) or
:mod:`spco.engines.ray` (Ray actors, on this machine or a cluster; ``pip install "spco[ray]"``).

An engine starts a :class:`~spco.engines.local.ShardedRun` from the initialised data and state:
``run.sweep(iteration)`` is one sweep of :func:`spco.model.shard.sweep` and ``run.state()`` joins
the shards' states. The same seed and number of shards give the same chain on every engine.
"""

from __future__ import annotations

from spco.engines.local import LocalEngine, ShardedRun

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


__all__ = ["ENGINES", "LocalEngine", "ShardedRun", "make_engine"]
