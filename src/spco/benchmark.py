"""How long a Gibbs sweep of spco's sampler takes, per step, and the peak memory of a fit.

This module backs ``spco bench`` and ``benchmarks/run_scaling.py``. It measures, on one corpus:

- **spco's sweep** (:func:`spco.model.gibbs.sweep`), per sampler step, for the ``exact`` sampler
  and for the ``reference`` variant (spco's vectorised version of the authors' conditionals);
- optionally a **baseline** sampler timed beside them (:func:`run_benchmark`'s ``baseline``:
  ``benchmarks/reference_sampler.py`` passes the authors' sweep re-implemented loop for loop, and
  so measures spco's speed-up);
- the **peak memory** of a whole ``SpCoTransfer(...).fit(corpus)`` process (resident set size,
  as the authors' 300 MB figure is), measured in a child process.

Timings exclude compilation (Numba compiles on the first call): a few warm-up sweeps run first,
and the mean over the timed sweeps (the slowest tenth dropped) is reported; spco's sweeps follow
the steady state of a fit (label swaps on every tenth sweep). The timed sweeps of the samplers are
interleaved (:func:`interleaved_schedule`), so that the ratios compare timings taken in the same
minutes of the machine's life.

The paper's largest configuration is :data:`PAPER_EXPERIENCED_HOMES` (16 SIGVerse homes, 2,660
samples, all taught) plus one new home (:data:`PAPER_NEW_HOME`, nothing taught), D = 4096,
L = 15, K = 20; :func:`paper_corpus` loads it and :func:`synthetic_corpus` makes synthetic homes of
the same size.
"""

from __future__ import annotations

import json
import os
import pickle
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from spco.data.environment import Corpus
from spco.model import gibbs
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.state import PreparedData

__all__ = [
    "PAPER_EXPERIENCED_HOMES",
    "PAPER_NEW_HOME",
    "SpcoRunner",
    "SweepRunner",
    "SweepTimings",
    "configuration",
    "interleaved_schedule",
    "machine_info",
    "measure_peak_memory",
    "paper_corpus",
    "peak_rss_mb",
    "run_benchmark",
    "synthetic_corpus",
    "time_spco",
]

#: The 16 experienced SIGVerse homes of the paper's largest run, in the authors' order.
PAPER_EXPERIENCED_HOMES: tuple[str, ...] = (
    "3LDK_1", "1LDK_8", "2LDK_8", "1LDK_7", "2LDK_7", "1LDK_6", "2LDK_6", "1LDK_5", "2LDK_5",
    "1LDK_4", "2LDK_4", "1LDK_3", "2LDK_3", "1LDK_2", "2LDK_2", "1LDK_1",
)
#: The new home of the benchmark (nothing taught).
PAPER_NEW_HOME = "1LDK_9"

Log = Callable[[str], None]


def _quiet(_: str) -> None:
    """A logger that discards its message."""


# ----------------------------------------------------------------------------- corpora


def paper_corpus(path: str | os.PathLike[str], experienced: Sequence[str] = PAPER_EXPERIENCED_HOMES,
                 new_homes: Sequence[str] = (PAPER_NEW_HOME,)) -> Corpus:
    """The paper's largest configuration from a SIGVerse folder (or an spco cache).

    The ``experienced`` homes are taught at 100 %, the ``new_homes`` at 0 % (nothing taught); the
    vocabulary is built from the training sentences, as :class:`Corpus` does.
    """
    from spco.data.loading import load_homes

    envs = load_homes(path, names=list(experienced), teaching_rate=100)
    if new_homes:
        envs += load_homes(path, names=list(new_homes), teaching_rate=0)
    return Corpus(envs)


def synthetic_corpus(n_experienced: int = 16, n_new: int = 1, n_features: int = 4096,
                     seed: int = 0) -> Corpus:
    """Synthetic homes of the paper's size: ``n_experienced`` fully taught homes, then ``n_new``
    new homes with nothing taught, ``n_features`` visual dimensions (no home-specific rooms)."""
    from spco.data.synthetic import SyntheticConfig, generate_homes

    return generate_homes(n_experienced + n_new, seed=seed, config=SyntheticConfig(n_features=n_features),
                          new_homes=n_new, specific_rooms=False)


def configuration(corpus: Corpus, hyper: TransferHyperparameters, source: str) -> dict[str, Any]:
    """What is being benchmarked: homes, samples (training samples learnt from), D, V, L, K."""
    training = corpus.training_set()
    taught = [t.n_taught for t in training]
    return {
        "data": source,
        "homes": len(corpus),
        "experienced_homes": sum(t > 0 for t in taught),
        "new_homes": [t.name for t, n in zip(training, taught, strict=True) if n == 0],
        "samples": sum(t.n_samples for t in training),
        "taught_samples": sum(taught),
        "D": corpus.n_features,
        "V": len(corpus.vocabulary),
        "L": hyper.n_concepts,
        "K": hyper.n_regions,
    }


def machine_info() -> dict[str, Any]:
    """Cores, library versions and the load average (the machine may be shared)."""
    import numba
    import scipy

    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        usable = os.cpu_count()
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        load = None
    return {
        "cores": os.cpu_count(),
        "usable_cores": usable,
        "numba_threads": numba.get_num_threads(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
        "load_average": load,
        "threading_environment": {k: os.environ[k] for k in _THREADING_VARIABLES if k in os.environ},
    }


#: Environment variables that change how the compiled kernels and BLAS use the cores.
_THREADING_VARIABLES = ("NUMBA_NUM_THREADS", "NUMBA_THREADING_LAYER", "OMP_NUM_THREADS", "OMP_WAIT_POLICY",
                        "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def _threading_layer() -> str | None:
    """The threading layer Numba's parallel kernels ran on (``None`` before any ran)."""
    import numba

    try:
        return str(numba.threading_layer())
    except ValueError:
        return None


# ----------------------------------------------------------------------------- timings


@dataclass
class SweepTimings:
    """Wall time of every timed sweep (seconds) and of every step within it."""

    totals: list[float] = field(default_factory=list)
    steps: list[dict[str, float]] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)

    def add(self, total: float, steps: dict[str, float], cpu: float | None = None) -> None:
        """Record one sweep (``cpu``: its CPU seconds, every thread of this process)."""
        self.totals.append(total)
        self.steps.append(dict(steps))
        if cpu is not None:
            self.cpu.append(cpu)

    @property
    def per_sweep(self) -> float:
        """Seconds per sweep: the mean over the timed sweeps (a step that runs on some sweeps only,
        like the label swaps, counts with its frequency), robust to load spikes by dropping the
        slowest tenth of the sweeps."""
        kept = np.sort(self.totals)[: max(1, int(np.ceil(0.9 * len(self.totals))))]
        return float(np.mean(kept))

    def per_step(self) -> dict[str, float]:
        """Mean seconds per sweep of each step (steps that did not run count as 0), in the order
        the steps ran."""
        names: list[str] = []
        for s in self.steps:
            names += [n for n in s if n not in names]
        return {n: float(np.mean([s.get(n, 0.0) for s in self.steps])) for n in names}

    def summary(self) -> dict[str, Any]:
        """JSON-ready: seconds per sweep, every sweep, seconds per step."""
        return {"sweep_seconds": self.per_sweep, "sweeps": len(self.totals),
                "cpu_seconds": float(np.median(self.cpu)) if self.cpu else None,
                "all_sweep_seconds": [round(t, 6) for t in self.totals], "steps": self.per_step()}


class SpcoRunner:
    """spco's sampler on ``corpus``, initialised and warmed up, timed one sweep at a time
    (:meth:`sweep`) into :attr:`timings`. No word pruning; the hyperparameters' view weight and target
    (the defaults': w = 16, the cut sampler). The sweeps follow the steady state of a
    fit: label swaps on every :data:`~spco.model.gibbs.SWAP_EVERY`-th sweep."""

    def __init__(self, corpus: Corpus, variant: str = "exact", warmup: int = 2, seed: int = 0,
                 hyper: TransferHyperparameters | None = None, log: Log = _quiet) -> None:
        self.variant = variant
        self.hyper = hyper or TransferHyperparameters()
        self.settings = gibbs.SamplerSettings.create(variant, prune=False,
                                                     view_counts=self.hyper.view_weight(),
                                                     power=self.hyper.target == "power")
        self.data = PreparedData.from_corpus(corpus, gibbs.CM_PER_M if variant == "reference" else 1.0)
        self.rng = np.random.default_rng(seed)
        start = time.perf_counter()
        from spco.model.driver import start_run

        run = start_run(None, self.data, len(corpus.vocabulary), self.hyper, self.settings, self.rng)
        self.state = run.state()  # the fit's start (spco.model.shard_init), then sweeps in one process
        run.close()
        for _ in range(warmup):
            gibbs.sweep(self.data, self.state, self.hyper, self.settings, self.rng)
        seconds = time.perf_counter() - start
        log(f"  spco {variant}: initialised and {warmup} warm-up sweeps in {seconds:.1f} s")
        self.timings = SweepTimings()

    def sweep(self) -> float:
        """Run and record one timed sweep; returns its wall time in seconds."""
        timer = gibbs.StepTimer()
        swaps = gibbs.swaps_due(gibbs.SWAP_BURN_IN + len(self.timings.totals))
        c0, t0 = time.process_time(), time.perf_counter()
        gibbs.sweep(self.data, self.state, self.hyper, self.settings, self.rng, timer=timer, swaps=swaps)
        elapsed = time.perf_counter() - t0
        self.timings.add(elapsed, timer.seconds, time.process_time() - c0)
        return elapsed


class FitSweepRunner:
    """The sweep a fit runs (``SpCoTransfer(...).fit``: :func:`spco.model.driver.start_run` on the
    local engine, every home a shard of its own drawing from its own random stream, the shards'
    statistics reduced for the global step), on ``corpus``, timed whole into :attr:`timings`
    after ``warmup`` untimed sweeps. Exact sampler, no word pruning, as :class:`SpcoRunner`; its
    sweep numbers continue from :data:`~spco.model.gibbs.SWAP_BURN_IN` (label swaps on every
    :data:`~spco.model.gibbs.SWAP_EVERY`-th, as a fit's steady state)."""

    def __init__(self, corpus: Corpus, warmup: int = 2, seed: int = 0,
                 hyper: TransferHyperparameters | None = None, log: Log = _quiet) -> None:
        from spco.model.driver import start_run

        hyper = hyper or TransferHyperparameters()
        settings = gibbs.SamplerSettings.create("exact", prune=False, view_counts=hyper.view_weight(),
                                                power=hyper.target == "power")
        data = PreparedData.from_corpus(corpus, 1.0)
        start = time.perf_counter()
        self.run = start_run(None, data, len(corpus.vocabulary), hyper, settings, np.random.default_rng(seed))
        self.iteration = max(0, gibbs.SWAP_BURN_IN - warmup)
        for _ in range(warmup):
            self.run.sweep(self.iteration)
            self.iteration += 1
        log(f"  a fit's sweep (per-home shards): started and {warmup} warm-up sweeps in "
            f"{time.perf_counter() - start:.1f} s")
        self.timings = SweepTimings()

    def sweep(self) -> float:
        """Run and record one timed sweep; returns its wall time in seconds."""
        c0, t0 = time.process_time(), time.perf_counter()
        self.run.sweep(self.iteration)
        elapsed = time.perf_counter() - t0
        self.iteration += 1
        self.timings.add(elapsed, {}, time.process_time() - c0)
        return elapsed

    def summary(self) -> dict[str, Any]:
        """JSON-ready: :meth:`SweepTimings.summary` without steps."""
        summary = self.timings.summary()
        del summary["steps"]
        return summary


def time_spco(corpus: Corpus, variant: str = "exact", sweeps: int = 20, warmup: int = 2, seed: int = 0,
              hyper: TransferHyperparameters | None = None, log: Log = _quiet) -> SweepTimings:
    """Time spco's sweeps on ``corpus``: initialise, ``warmup`` untimed sweeps, then ``sweeps``
    timed ones, each with a :class:`~spco.model.gibbs.StepTimer`. No word pruning."""
    runner = SpcoRunner(corpus, variant, warmup, seed, hyper, log)
    for i in range(sweeps):
        runner.sweep()
        if (i + 1) % 10 == 0 or i + 1 == sweeps:
            per_sweep = runner.timings.per_sweep * 1e3
            log(f"  spco {variant}: {i + 1}/{sweeps} sweeps, {per_sweep:.0f} ms per sweep")
    return runner.timings


def interleaved_schedule(spco_sweeps: int, reference_sweeps: int) -> list[str]:
    """The order of the timed sweeps in :func:`run_benchmark`: ``reference_sweeps`` rounds (at least
    one), each with its share of spco's exact and reference-variant sweeps and then one baseline
    sweep, so that all the samplers are timed in the same minutes (the speed of a shared or virtual
    machine drifts over minutes, and a ratio of timings taken minutes apart would carry that drift).
    Entries are ``"exact"``, ``"reference"`` (spco's variant) and ``"authors"`` (the baseline)."""
    rounds = max(reference_sweeps, 1)
    order: list[str] = []
    done = 0
    for r in range(rounds):
        share = (spco_sweeps * (r + 1)) // rounds - done
        done += share
        order += ["exact", "reference"] * share
        if r < reference_sweeps:
            order.append("authors")
    return order


# ----------------------------------------------------------------------------- peak memory

#: The child process that fits a pickled corpus and reports its peak memory. Self-contained (it
#: imports only what a user's fit imports): argv = corpus pickle, variant, sweeps, seed.
_MEMORY_CHILD = """
import json, pickle, sys, time
from spco.model.transfer import SpCoTransfer
from spco.benchmark import peak_rss_mb
with open(sys.argv[1], "rb") as fh:
    corpus = pickle.load(fh)
before, _ = peak_rss_mb()
start = time.perf_counter()
SpCoTransfer(variant=sys.argv[2], n_iterations=int(sys.argv[3]), random_state=int(sys.argv[4])).fit(corpus)
seconds = time.perf_counter() - start
peak, how = peak_rss_mb()
print(json.dumps({"peak_mb": peak, "before_fit_mb": before, "fit_seconds": seconds, "measured_by": how}))
"""


def peak_rss_mb() -> tuple[float, str]:
    """This process's peak resident set size in MB, and how it was measured.

    On Linux, ``VmHWM`` of ``/proc/self/status``: the high-water mark of this program's own memory.
    Not ``getrusage(...).ru_maxrss``, because Linux carries it across ``execve``: a child started
    by ``subprocess`` reports at least the RSS its parent had when it forked (so would
    ``RUSAGE_CHILDREN`` in the parent). Elsewhere ``ru_maxrss`` (kB, bytes on macOS) is all there is.
    """
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024, "VmHWM"
    except OSError:
        pass
    import resource

    value = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return (value / 2**20 if sys.platform == "darwin" else value / 2**10), "ru_maxrss"


def measure_peak_memory(corpus: Corpus, variant: str = "exact", sweeps: int = 3,
                        seed: int = 0) -> dict[str, Any]:
    """Peak RSS of a fresh process that fits ``corpus`` (``SpCoTransfer(...).fit``, ``sweeps``
    sweeps, log joint recorded as by default).

    What is counted is the whole process, as in the authors' 300 MB: the interpreter, NumPy,
    SciPy, Numba (with its compiled kernels), the corpus and everything the fit allocates. The
    corpus reaches the child pickled, so no loader's transient memory is counted. Returns
    ``peak_mb``, ``before_fit_mb`` (peak RSS with spco imported and the corpus loaded, before
    fitting), ``fit_seconds``, ``measured_by`` (see :func:`peak_rss_mb`) and ``sweeps``.
    """
    import spco

    env = dict(os.environ)
    package_root = str(Path(spco.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH")) if p)
    with tempfile.TemporaryDirectory(prefix="spco-bench-") as tmp:
        path = Path(tmp) / "corpus.pickle"
        with open(path, "wb") as fh:
            pickle.dump(corpus, fh, protocol=pickle.HIGHEST_PROTOCOL)
        command = [sys.executable, "-c", _MEMORY_CHILD, str(path), variant, str(sweeps), str(seed)]
        proc = subprocess.run(command, capture_output=True, text=True, env=env, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"the memory-measuring child process failed (status {proc.returncode}):\n"
                           f"{proc.stderr.strip()[-2000:]}")
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    report["sweeps"] = sweeps
    return report


# ----------------------------------------------------------------------------- the whole benchmark


class SweepRunner(Protocol):
    """A sampler ready to be timed one sweep at a time (:class:`SpcoRunner`, or a baseline)."""

    timings: SweepTimings

    def sweep(self) -> float:
        """Run and record one timed sweep; returns its wall time in seconds."""
        ...


#: Builds a baseline sampler for :func:`run_benchmark`: (corpus, hyperparameters, seed, log) -> runner.
BaselineFactory = Callable[[Corpus, TransferHyperparameters, int, Log], SweepRunner]


def run_benchmark(corpus: Corpus, source: str, sweeps: int = 20, warmup: int = 2, seed: int = 0,
                  memory: bool = True, memory_sweeps: int = 3, hyper: TransferHyperparameters | None = None,
                  log: Log = _quiet, baseline: BaselineFactory | None = None,
                  baseline_sweeps: int = 3) -> dict[str, Any]:
    """Everything ``spco bench --json`` prints (see the command's help for the keys).

    With a ``baseline`` (a factory of a :class:`SweepRunner`), its ``baseline_sweeps`` timed sweeps
    are interleaved with spco's (:func:`interleaved_schedule`) and the result also has
    ``reference_sweep_seconds``, ``speedup`` (baseline over spco's exact sweep),
    ``speedup_same_algorithm`` (over spco's reference variant) and ``reference`` (its steps)."""
    hyper = hyper or TransferHyperparameters()
    config = configuration(corpus, hyper, source)
    log(f"benchmarking on {config['homes']} homes, {config['samples']} samples, D = {config['D']}, "
        f"L = {config['L']}, K = {config['K']}")
    machine = machine_info()
    log(f"preparing spco's exact and reference samplers ({warmup} warm-up sweeps each)")
    runners: dict[str, SweepRunner] = {
        variant: SpcoRunner(corpus, variant, warmup, seed, hyper, log) for variant in ("exact", "reference")}
    log(f"preparing a fit's sweep ({warmup} warm-up sweeps)")
    fit_runner = FitSweepRunner(corpus, warmup, seed, hyper, log)
    if baseline is not None:
        runners["authors"] = baseline(corpus, hyper, seed, log)
    rounds = baseline_sweeps if baseline is not None else 0
    log(f"timing {sweeps} sweeps of each spco sampler" + (f" and {rounds} baseline sweeps, interleaved"
                                                            if rounds else ""))
    for name in interleaved_schedule(sweeps, rounds):
        elapsed = runners[name].sweep()
        if name == "exact":  # a fit's sweep beside each of the exact sampler's, in the same minutes
            fit_runner.sweep()
        if name == "authors":
            done = len(runners["authors"].timings.totals)
            log(f"  baseline sweep {done}/{rounds}: {elapsed * 1e3:.0f} ms; spco exact so "
                f"far {runners['exact'].timings.per_sweep * 1e3:.0f} ms per sweep")
    variants = {variant: runners[variant].timings.summary() for variant in ("exact", "reference")}
    reference = runners["authors"].timings.summary() if baseline is not None else None
    fit_sweep = fit_runner.summary()
    del runners, fit_runner
    peak = None
    if memory:
        log(f"measuring the peak memory of an exact fit ({memory_sweeps} sweeps) in a child process")
        peak = measure_peak_memory(corpus, "exact", memory_sweeps, seed)
    machine["load_average_after"] = machine_info()["load_average"]
    machine["numba_threading_layer"] = _threading_layer()
    exact = variants["exact"]["sweep_seconds"]
    result: dict[str, Any] = {
        "sweep_seconds": exact,
        "fit_sweep_seconds": fit_sweep["sweep_seconds"],
        "fit_sweep": fit_sweep,
        "peak_memory_mb": None if peak is None else peak["peak_mb"],
        "steps": variants["exact"]["steps"],
        "configuration": config,
        "machine": machine,
        "spco": variants,
        "memory": peak,
        "warmup_sweeps": warmup,
        "seed": seed,
    }
    if reference is not None:
        ref = reference["sweep_seconds"]
        result.update(reference_sweep_seconds=ref, speedup=ref / exact, reference=reference,
                      speedup_same_algorithm=ref / variants["reference"]["sweep_seconds"])
    return result


def iter_steps(result: dict[str, Any]) -> Iterator[tuple[str, float, float | None]]:
    """(step, exact seconds, reference-variant seconds or None) for every step of spco's sweeps."""
    exact = result["spco"]["exact"]["steps"]
    ref = result["spco"].get("reference", {}).get("steps", {})
    for name in [*exact, *(n for n in ref if n not in exact)]:
        yield name, exact.get(name, float("nan")), ref.get(name)
