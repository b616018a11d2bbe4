"""The Ray engine: home shards as Ray actors that keep their homes' data and state between sweeps.

Only statistics (table or pooled counts, (L, D) + (L, V) + (L,) per shard and step) and the shared
parameters travel; the driver adds the statistics up and takes the global step
(:mod:`spco.model.shard`). Every ``checkpoint_every`` sweeps the driver keeps a checkpoint (the
shards' states and random generators, its own generator and the shared parameters; in its memory,
or on disk with ``checkpoint_dir``: :mod:`spco.engines.checkpoints`); when an actor
dies, every shard is restarted from the last checkpoint and the sweeps since are run again, so
the fit ends where a fault-free fit ends.

Needs Ray (``pip install "spco[ray]"``); ``address`` joins a running cluster (``ray start``),
otherwise a local Ray instance is started.
"""

from __future__ import annotations

import copy
import os
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import scipy.sparse as sp

from spco.engines import checkpoints
from spco.model.driver import ShardedRun
from spco.model.gibbs import GibbsState, PreparedData, SamplerSettings
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.shard_group import ShardGroup
from spco.model.sources import HomeSource, HomesPart
from spco.model.state import SharedParameters


def _require_ray():
    try:
        import ray
    except ImportError as error:  # pragma: no cover - depends on the installation
        raise ImportError('the Ray engine needs Ray: pip install "spco[ray]"') from error
    return ray


class _WritablePart(HomesPart):
    """A part whose prepared arrays are made writable (arrays from Ray's object store are not)."""

    def __init__(self, part: HomesPart) -> None:
        self.part, self.n_homes = part, part.n_homes

    def prepare(self) -> PreparedData:
        return _writable_data(self.part.prepare())


class _ShardActor:
    """A worker's homes (a :class:`~spco.model.shard_group.ShardGroup`) in a Ray actor: their data
    and state stay there.

    ``part`` is the worker's :class:`~spco.model.sources.HomesPart` (homes ``first``.. of the
    fit), which it prepares itself; ``state`` is ``None`` (start the homes, each with its own
    generator from ``entropy``), the homes' joined state and ``rng_states`` (a checkpoint in
    memory), or the path of a checkpoint file (:func:`spco.engines.checkpoints.save_shard`, which
    also holds the generators' states)."""

    def __init__(self, part: HomesPart, first: int, state, rng_states: list[dict] | None, entropy: list[int],
                 n_words: int, n_fit_homes: int, hyper: TransferHyperparameters, settings: SamplerSettings,
                 threads: int) -> None:
        import numba

        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))  # results do not change
        if isinstance(state, str):
            state, rng_states = checkpoints.load_shard(state)
        if state is None:
            self.shard = ShardGroup.from_part(_WritablePart(part), first, entropy, n_words, n_fit_homes,
                                              hyper, settings)
            return
        self.shard = ShardGroup.restore(_writable_data(part.prepare()), _writable_state(state), rng_states,
                                        first, n_fit_homes, hyper, settings)

    def call(self, method: str, *args) -> Any:
        # arrays from Ray's object store are read-only: the kernels write into the state's
        # arrays, and a read-only argument would compile another specialisation of each kernel
        args = tuple(_writable_shared(a) if isinstance(a, SharedParameters) else a for a in args)
        return getattr(self.shard, method)(*args)

    def snapshot(self) -> tuple[GibbsState, list[dict]]:
        """The homes' joined state (without the count cache, which is rebuilt exactly) and their
        generators' states."""
        state = copy.copy(self.shard.state)
        state.visual_cache = None
        return state, self.shard.rng_states()

    def save(self, path: str) -> int:
        """Write the worker's checkpoint to ``path`` (atomically); returns the bytes written."""
        return checkpoints.save_shard(path, self.shard.state, self.shard.rng_states())

    def setup_seconds(self) -> dict[str, float]:
        """Seconds the shard took to prepare and to start its homes (empty if given its state)."""
        return self.shard.setup_seconds

    def memory(self) -> int:
        """Peak resident memory of the actor's process, bytes."""
        import resource
        import sys

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return int(peak if sys.platform == "darwin" else peak * 1024)


def _writable(value):
    if isinstance(value, np.ndarray) and not value.flags.writeable:
        return value.copy()
    return value


def _writable_data(data: PreparedData) -> PreparedData:
    def csr(m: sp.csr_array) -> sp.csr_array:
        return sp.csr_array((_writable(m.data), _writable(m.indices), _writable(m.indptr)), shape=m.shape)

    return PreparedData(positions=_writable(data.positions), homes=_writable(data.homes),
                        visual=csr(data.visual), words=csr(data.words), n_homes=data.n_homes,
                        offsets=_writable(data.offsets), position_scale=data.position_scale,
                        map_centres=_writable(data.map_centres), view_missing=_writable(data.view_missing))


def _writable_state(state: GibbsState) -> GibbsState:
    for f in fields(state):
        setattr(state, f.name, _writable(getattr(state, f.name)))
    return state


def _writable_shared(shared: SharedParameters) -> SharedParameters:
    return SharedParameters(*(_writable(getattr(shared, f.name)) for f in fields(shared)))


@dataclass
class _Checkpoint:
    iteration: int
    shards: list[tuple[GibbsState, list[dict]]] | None  # None: on disk
    driver_rng: dict | None = None
    shared: SharedParameters | None = None
    trace: np.ndarray | None = None


class RayRun(ShardedRun):
    """A fit whose shards are Ray actors.

    Checkpoints (every ``checkpoint_every`` sweeps) are kept in the driver's memory, or, with
    ``checkpoint_dir``, on disk (:mod:`spco.engines.checkpoints`): each actor writes its own
    state there, so the driver never holds the shards' states; on a cluster the directory must be
    reachable from every node (shared storage)."""

    def __init__(self, *args, checkpoint_every: int = 10, checkpoint_dir: str | os.PathLike | None = None,
                 **kwargs) -> None:
        self.checkpoint_every = max(1, int(checkpoint_every))
        self.checkpoint_dir = None if checkpoint_dir is None else os.fspath(checkpoint_dir)
        self.restarts = 0
        super().__init__(*args, **kwargs)

    def _start(self, parts) -> None:
        self.ray = _require_ray()
        self._parts = parts
        self._launch([(None, None)] * len(parts))

    def _launch(self, snapshots: list[tuple[GibbsState | str | None, list[dict] | None]]) -> None:
        ray = self.ray
        cpus = ray.cluster_resources().get("CPU", 1.0)
        actor = ray.remote(num_cpus=min(1.0, cpus / len(snapshots)), max_restarts=0)(_ShardActor)
        hyper, settings = ray.put(self.hyper), ray.put(self.settings)
        if not hasattr(self, "part_refs"):  # the homes' parts are put in the object store once
            self.part_refs = [ray.put(p) for p in self._parts]
            del self._parts
        threads = max(1, int(cpus // len(snapshots)))  # Numba threads per worker
        self.actors = []
        for part, (first, _), (state, rng_states) in zip(self.part_refs, self.bounds, snapshots, strict=True):
            self.actors.append(actor.remote(part, first, state, rng_states, self.entropy, self.n_words,
                                            self.n_homes, hyper, settings, threads))

    def call(self, method: str, *args) -> list:
        ray = self.ray
        sent = [ray.put(a) if isinstance(a, SharedParameters) else a for a in args]
        self.bytes_sent += sum(a.nbytes for a in args if isinstance(a, SharedParameters)) * len(self.actors)
        return ray.get([a.call.remote(method, *sent) for a in self.actors])

    def call_each(self, method: str, args: list[tuple]) -> list:
        return self.ray.get([a.call.remote(method, *x) for a, x in zip(self.actors, args, strict=True)])

    def states(self) -> list[GibbsState]:
        return [s for s, _ in self.ray.get([a.snapshot.remote() for a in self.actors])]

    def memory(self) -> list[int]:
        """Peak resident memory of every shard's process, bytes."""
        return self.ray.get([a.memory.remote() for a in self.actors])

    def setup_seconds(self) -> list[dict[str, float]]:
        """Every shard's seconds to prepare and start its homes."""
        return self.ray.get([a.setup_seconds.remote() for a in self.actors])

    def _checkpoint(self, iteration: int, trace: np.ndarray) -> _Checkpoint:
        if self.checkpoint_dir is None:
            return _Checkpoint(iteration, self.ray.get([a.snapshot.remote() for a in self.actors]),
                               copy.deepcopy(self.rng.bit_generator.state), self.shared,
                               trace[:iteration].copy())
        directory = self.checkpoint_dir
        paths = [os.fspath(checkpoints.shard_path(directory, s, iteration)) for s in range(len(self.actors))]
        self.ray.get([a.save.remote(p) for a, p in zip(self.actors, paths, strict=True)])
        checkpoints.save_driver(directory, iteration, self.rng.bit_generator.state, self.shared,
                                trace[:iteration], len(self.actors))
        checkpoints.remove_older(directory, iteration)
        return _Checkpoint(iteration, None)

    def _restore(self, checkpoint: _Checkpoint, trace: np.ndarray) -> int:
        for a in self.actors:
            try:
                self.ray.kill(a)
            except Exception:  # already dead
                pass
        self.restarts += 1
        if checkpoint.shards is None:  # on disk: the actors read their own files
            iteration, driver_rng, shared, saved, paths = checkpoints.load_driver(self.checkpoint_dir)
            snapshots = [(os.fspath(p), None) for p in paths]
        else:
            iteration, driver_rng, shared, saved = (checkpoint.iteration, checkpoint.driver_rng,
                                                    checkpoint.shared, checkpoint.trace)
            snapshots = checkpoint.shards
        self.rng.bit_generator.state = copy.deepcopy(driver_rng)
        self.shared = shared
        self.rewind_cut_start(iteration)  # (a checkpoint from before the power target's first sweep)
        trace[:iteration] = saved
        self._launch(snapshots)
        return iteration

    def fit(self, n_iterations: int, after_sweep=None) -> np.ndarray:
        """As :meth:`ShardedRun.fit`, restarting every shard from the last checkpoint when an actor
        dies (at most 3 restarts without progress past a checkpoint)."""
        errors = (self.ray.exceptions.RayActorError, self.ray.exceptions.ActorUnavailableError)
        trace = np.empty(n_iterations)
        iteration, checkpoint, failures = 0, None, 0
        while iteration < n_iterations:
            try:
                if iteration % self.checkpoint_every == 0 and (checkpoint is None
                                                               or checkpoint.iteration != iteration):
                    checkpoint = self._checkpoint(iteration, trace)
                    failures = 0
                trace[iteration] = self.sweep(iteration)
            except errors:
                failures += 1
                if checkpoint is None or failures > 3:
                    raise
                iteration = self._restore(checkpoint, trace)
                continue
            if after_sweep is not None:
                after_sweep(iteration, trace[iteration])
            iteration += 1
        return trace

    def close(self) -> None:
        for a in self.actors:
            self.ray.kill(a)


class RayEngine:
    """Shards as Ray actors: ``RayEngine(shards=2, address=None, checkpoint_every=10)``."""

    name = "ray"

    def __init__(self, shards: int = 2, address: str | None = None, checkpoint_every: int = 10,
                 checkpoint_dir: str | os.PathLike | None = None) -> None:
        if shards < 1:
            raise ValueError(f"shards must be at least 1, got {shards}")
        self.shards, self.address, self.checkpoint_every = shards, address, checkpoint_every
        self.checkpoint_dir = checkpoint_dir

    def _init_ray(self):
        ray = _require_ray()
        if not ray.is_initialized():
            ray.init(address=self.address, log_to_driver=False)
        return ray

    def start_source(self, source: HomeSource, hyper: TransferHyperparameters, settings: SamplerSettings,
                     rng: np.random.Generator) -> RayRun:
        """Start Ray if needed and the actors from ``source``: each actor prepares and starts its
        own homes (:mod:`spco.model.shard_init`); the same chain as ``LocalEngine`` with any number
        of shards, given the same seed."""
        self._init_ray()
        return RayRun(source, hyper, settings, rng, min(self.shards, source.n_homes),
                      checkpoint_every=self.checkpoint_every, checkpoint_dir=self.checkpoint_dir)
