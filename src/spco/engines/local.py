"""The local engine: home shards in this process (:mod:`spco.model.driver`, where the driver loop
every engine shares lives with it: the estimators of :mod:`spco.model` run on it)."""

from spco.model.driver import LocalEngine, LocalRun, ShardedRun

__all__ = ["LocalEngine", "LocalRun", "ShardedRun"]
