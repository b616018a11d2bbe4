"""How long a Gibbs sweep takes: spco's sampler against a sweep written the way the authors wrote theirs.

This module backs ``spco bench`` and ``benchmarks/run_scaling.py``. It measures, on one corpus:

- **spco's sweep** (:func:`spco.model.gibbs.sweep`), per sampler step, for the ``exact`` sampler
  and for the ``reference`` variant (spco's vectorised version of the authors' conditionals);
- a **reference sweep** (:func:`reference_sweep`): the authors' per-sweep work re-implemented
  here in the style of their published ``gibbs_spco_transfer20.py`` — one ``choice`` call per
  data point for R and C, ``scipy.stats.multivariate_normal.logpdf`` per region, the members of
  each region and concept gathered by Python loops over the samples, per-point outer products
  for the Gaussian statistics, an inverse-Wishart draw built element by element, one
  ``dirichlet`` call per concept and home (θ^v, θ^w, π), per home (G_e) and per concept (φ^v,
  φ^w), dense visual and word arrays. It is deliberately loopy: it is the baseline that spco's
  speed-up is measured against, on the same data, in the same process, on the same machine;
- the **peak memory** of a whole ``SpCoTransfer(...).fit(corpus)`` process (resident set size,
  as the authors' 300 MB figure is), measured in a child process.

Timings exclude compilation (Numba compiles on the first call): a few warm-up sweeps run first,
and the mean over the timed sweeps (the slowest tenth dropped) is reported; spco's sweeps follow
the steady state of a fit (label swaps on every tenth sweep). The timed sweeps of the three
samplers are interleaved (:func:`interleaved_schedule`), so that the ratios compare timings taken
in the same minutes of the machine's life.

The paper's largest configuration is :data:`PAPER_EXPERIENCED_HOMES` (16 SIGVerse homes, 2,660
samples, all taught) plus one new home (:data:`PAPER_NEW_HOME`, nothing taught), D = 4096,
L = 15, K = 20; :func:`paper_corpus` loads it and :func:`synthetic_corpus` makes synthetic homes of
the same size.
"""

from __future__ import annotations

import contextlib
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
from typing import Any

import numpy as np
from scipy.cluster.vq import kmeans2

from spco.data.environment import Corpus
from spco.model import gibbs
from spco.model.hyperparameters import TransferHyperparameters

__all__ = [
    "PAPER_EXPERIENCED_HOMES",
    "PAPER_NEW_HOME",
    "ReferenceData",
    "ReferenceState",
    "SweepTimings",
    "configuration",
    "inverse_wishart_loop",
    "machine_info",
    "measure_peak_memory",
    "paper_corpus",
    "peak_rss_mb",
    "reference_concept_probabilities",
    "reference_initialize",
    "reference_region_posterior",
    "reference_region_probabilities",
    "reference_sweep",
    "run_benchmark",
    "synthetic_corpus",
    "time_reference",
    "time_spco",
]

#: The 16 experienced SIGVerse homes of the paper's largest run, in the authors' order.
PAPER_EXPERIENCED_HOMES: tuple[str, ...] = (
    "3LDK_1", "1LDK_8", "2LDK_8", "1LDK_7", "2LDK_7", "1LDK_6", "2LDK_6", "1LDK_5", "2LDK_5",
    "1LDK_4", "2LDK_4", "1LDK_3", "2LDK_3", "1LDK_2", "2LDK_2", "1LDK_1",
)
#: The new home of the benchmark (nothing taught).
PAPER_NEW_HOME = "1LDK_9"

#: The authors' positions are in centimetres.
_CM = np.array([100.0, 100.0, 1.0, 1.0])
#: The authors' initial (and re-seed) covariance, 100·I.
_SIGMA_INIT = 100.0
#: Half-widths of the box an empty region's mean is re-seeded in (the authors draw within the map
#: bounds, stored in metres, while their positions are in centimetres: ±6 "cm" in x and y).
_RESEED_BOX = np.array([6.0, 6.0, 1.0, 1.0])
#: What the authors add to every drawn probability vector.
_TINY = 1e-100

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

    def add(self, total: float, steps: dict[str, float]) -> None:
        """Record one sweep."""
        self.totals.append(total)
        self.steps.append(dict(steps))

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
                "all_sweep_seconds": [round(t, 6) for t in self.totals], "steps": self.per_step()}


class SpcoRunner:
    """spco's sampler on ``corpus``, initialised and warmed up, timed one sweep at a time
    (:meth:`sweep`) into :attr:`timings`. No word pruning. The sweeps follow the steady state of a
    fit: label swaps on every :data:`~spco.model.gibbs.SWAP_EVERY`-th sweep."""

    def __init__(self, corpus: Corpus, variant: str = "exact", warmup: int = 2, seed: int = 0,
                 hyper: TransferHyperparameters | None = None, log: Log = _quiet) -> None:
        from spco.model.transfer import SpCoTransfer

        self.variant = variant
        self.hyper = hyper or TransferHyperparameters()
        self.settings = gibbs.SamplerSettings.create(variant, prune=False)
        self.data = SpCoTransfer._prepare(corpus, gibbs.CM_PER_M if variant == "reference" else 1.0)
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
        t0 = time.perf_counter()
        gibbs.sweep(self.data, self.state, self.hyper, self.settings, self.rng, timer=timer, swaps=swaps)
        elapsed = time.perf_counter() - t0
        self.timings.add(elapsed, timer.seconds)
        return elapsed


class ReferenceRunner:
    """:func:`reference_sweep` on ``corpus`` (the same training data spco learns from),
    initialised and warmed up, timed one sweep at a time (:meth:`sweep`) into :attr:`timings`."""

    def __init__(self, corpus: Corpus, warmup: int = 1, seed: int = 0,
                 hyper: TransferHyperparameters | None = None, log: Log = _quiet) -> None:
        from spco.model.transfer import SpCoTransfer

        self.hyper = hyper or TransferHyperparameters()
        self.data = ReferenceData.from_prepared(SpCoTransfer._prepare(corpus, 1.0))
        self.random_state = np.random.RandomState(seed)
        self.state = reference_initialize(self.data, self.hyper, self.random_state)
        for i in range(warmup):
            t0 = time.perf_counter()
            reference_sweep(self.data, self.state, self.hyper, self.random_state)
            milliseconds = (time.perf_counter() - t0) * 1e3
            log(f"  authors'-style sweep (warm-up {i + 1}/{warmup}): {milliseconds:.0f} ms")
        self.timings = SweepTimings()

    def sweep(self) -> float:
        """Run and record one timed sweep; returns its wall time in seconds."""
        timer = gibbs.StepTimer()
        t0 = time.perf_counter()
        reference_sweep(self.data, self.state, self.hyper, self.random_state, timer=timer)
        elapsed = time.perf_counter() - t0
        self.timings.add(elapsed, timer.seconds)
        return elapsed


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


def time_reference(corpus: Corpus, sweeps: int = 3, warmup: int = 1, seed: int = 0,
                   hyper: TransferHyperparameters | None = None, log: Log = _quiet) -> SweepTimings:
    """Time :func:`reference_sweep` on ``corpus`` (the same training data spco learns from)."""
    runner = ReferenceRunner(corpus, warmup, seed, hyper, log)
    for i in range(sweeps):
        elapsed = runner.sweep()
        log(f"  authors'-style sweep {i + 1}/{sweeps}: {elapsed * 1e3:.0f} ms")
    return runner.timings


def interleaved_schedule(spco_sweeps: int, reference_sweeps: int) -> list[str]:
    """The order of the timed sweeps in :func:`run_benchmark`: ``reference_sweeps`` rounds, each
    with its share of spco's exact and reference-variant sweeps and then one authors'-style sweep,
    so that all three samplers are timed in the same minutes (the speed of a shared or virtual
    machine drifts over minutes, and a ratio of timings taken minutes apart would carry that drift).
    Entries are ``"exact"``, ``"reference"`` (spco's variant) and ``"authors"``."""
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


def run_benchmark(corpus: Corpus, source: str, sweeps: int = 20, reference_sweeps: int = 3, warmup: int = 2,
                  seed: int = 0, memory: bool = True, memory_sweeps: int = 3,
                  hyper: TransferHyperparameters | None = None, log: Log = _quiet) -> dict[str, Any]:
    """Everything ``spco bench --json`` prints (see the command's help for the keys)."""
    hyper = hyper or TransferHyperparameters()
    config = configuration(corpus, hyper, source)
    log(f"benchmarking on {config['homes']} homes, {config['samples']} samples, D = {config['D']}, "
        f"L = {config['L']}, K = {config['K']}")
    machine = machine_info()
    log(f"preparing spco's exact and reference samplers ({warmup} warm-up sweeps each) and the "
        "authors'-style sweep (1 warm-up)")
    runners: dict[str, SpcoRunner | ReferenceRunner] = {
        variant: SpcoRunner(corpus, variant, warmup, seed, hyper, log) for variant in ("exact", "reference")}
    runners["authors"] = ReferenceRunner(corpus, warmup=1, seed=seed, hyper=hyper, log=log)
    log(f"timing {sweeps} sweeps of each spco sampler and {reference_sweeps} authors'-style sweeps, "
        "interleaved")
    for name in interleaved_schedule(sweeps, reference_sweeps):
        elapsed = runners[name].sweep()
        if name == "authors":
            done = len(runners["authors"].timings.totals)
            log(f"  authors'-style sweep {done}/{reference_sweeps}: {elapsed * 1e3:.0f} ms; spco exact so "
                f"far {runners['exact'].timings.per_sweep * 1e3:.0f} ms per sweep")
    variants = {variant: runners[variant].timings.summary() for variant in ("exact", "reference")}
    reference = runners["authors"].timings.summary()
    del runners
    peak = None
    if memory:
        log(f"measuring the peak memory of an exact fit ({memory_sweeps} sweeps) in a child process")
        peak = measure_peak_memory(corpus, "exact", memory_sweeps, seed)
    machine["load_average_after"] = machine_info()["load_average"]
    machine["numba_threading_layer"] = _threading_layer()
    exact = variants["exact"]["sweep_seconds"]
    ref = reference["sweep_seconds"]
    return {
        "sweep_seconds": exact,
        "reference_sweep_seconds": ref,
        "speedup": ref / exact,
        "peak_memory_mb": None if peak is None else peak["peak_mb"],
        "steps": variants["exact"]["steps"],
        "configuration": config,
        "machine": machine,
        "spco": variants,
        "reference": reference,
        "speedup_same_algorithm": ref / variants["reference"]["sweep_seconds"],
        "memory": peak,
        "warmup_sweeps": warmup,
        "seed": seed,
    }


# ----------------------------------------------------------------------------- the reference sweep


@dataclass
class ReferenceData:
    """The training data as the authors held it: per home, positions in centimetres and dense
    float visual and word count arrays; μ0 = 0 for every home (their map centre, computed in
    metres, is ≈ 0 in centimetres)."""

    positions: list[np.ndarray]
    vision: list[np.ndarray]
    names: list[np.ndarray]
    mu0: np.ndarray

    @classmethod
    def from_prepared(cls, data: gibbs.PreparedData) -> ReferenceData:
        """Split spco's stacked data per home, densify it and convert positions to centimetres."""
        scale = np.array([1.0 / data.position_scale] * 2 + [1.0, 1.0]) * _CM
        positions, vision, names = [], [], []
        for e in range(data.n_homes):
            rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
            positions.append(data.positions[rows] * scale)
            vision.append(data.visual[rows].toarray().astype(np.float64))
            names.append(data.words[rows].toarray().astype(np.float64))
        return cls(positions=positions, vision=vision, names=names, mu0=np.zeros((data.n_homes, 4)))

    @property
    def n_homes(self) -> int:
        """E."""
        return len(self.positions)


@dataclass
class ReferenceState:
    """The authors' sampler state: assignments as Python lists, parameters as probabilities.

    concepts, regions: per home, a list of the samples' C_t and R_t; G (E, L), G0 (L,),
    pi (E, L, K), mu (E, K, 4), sigma (E, K, 4, 4), theta_v (E, L, D), theta_w (E, L, V),
    phi_v (L, D), phi_w (L, V).
    """

    concepts: list[list[int]]
    regions: list[list[int]]
    G: np.ndarray
    G0: np.ndarray
    pi: np.ndarray
    mu: np.ndarray
    sigma: np.ndarray
    theta_v: np.ndarray
    theta_w: np.ndarray
    phi_v: np.ndarray
    phi_w: np.ndarray


def _stick_breaking(concentration: float, size: int, rs: np.random.RandomState) -> np.ndarray:
    """Truncated stick breaking, the last stick taking what is left."""
    weights = np.empty(size)
    rest = 1.0
    for i in range(size - 1):
        b = rs.beta(1.0, concentration)
        weights[i] = rest * b
        rest *= 1.0 - b
    weights[-1] = rest
    return weights


def reference_initialize(data: ReferenceData, hyper: TransferHyperparameters,
                         rs: np.random.RandomState) -> ReferenceState:
    """The authors' starting state: G_0 by stick breaking, G_e ~ Dir(G_0 + γ), π by stick
    breaking, region means at k-means centres with Σ = 100·I, uniform θ and φ, C uniform."""
    L, K, E = hyper.n_concepts, hyper.n_regions, data.n_homes
    D, V = data.vision[0].shape[1], data.names[0].shape[1]
    g0 = _stick_breaking(hyper.gamma0, L, rs) + _TINY
    mu = np.empty((E, K, 4))
    for e, x in enumerate(data.positions):
        k = min(K, x.shape[0])
        centres, _ = kmeans2(x, k, minit="++", seed=int(rs.randint(0, 2**31 - 1)))
        mu[e, :k] = centres
        mu[e, k:] = centres[rs.randint(0, k, size=K - k)]
    return ReferenceState(
        concepts=[list(rs.randint(0, L, size=x.shape[0])) for x in data.positions],
        regions=[[0] * x.shape[0] for x in data.positions],
        G=np.array([rs.dirichlet(g0 + hyper.gamma) for _ in range(E)]),
        G0=g0,
        pi=np.array([[_stick_breaking(hyper.beta, K, rs) + _TINY for _ in range(L)] for _ in range(E)]),
        mu=mu,
        sigma=np.tile(_SIGMA_INIT * np.eye(4), (E, K, 1, 1)),
        theta_v=np.full((E, L, D), 1.0 / D),
        theta_w=np.full((E, L, V), 1.0 / V) if V else np.zeros((E, L, 0)),
        phi_v=np.full((L, D), 1.0 / D),
        phi_w=np.full((L, V), 1.0 / V) if V else np.zeros((L, 0)),
    )


def _normalise_log_rows(log_p: np.ndarray) -> np.ndarray:
    """Rows of log-probabilities → probabilities (max subtracted before exponentiating)."""
    p = np.exp(log_p - log_p.max(axis=1, keepdims=True))
    return p / p.sum(axis=1, keepdims=True)


def reference_region_probabilities(positions: np.ndarray, concepts: Sequence[int], pi: np.ndarray,
                                   mu: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """p(R_t = m | C_t, x_t) ∝ π_{C_t, m} N(x_t | μ_m, Σ_m) for one home, shape (n, K).

    π (L, K), μ (K, 4), Σ (K, 4, 4). The authors' way: π gathered per sample in Python, one
    ``multivariate_normal.logpdf`` call per region."""
    from scipy.stats import multivariate_normal  # here: a fit (the memory child) does not import it

    n, K = positions.shape[0], mu.shape[0]
    log_pi_data = np.log(np.array([pi[concepts[d]] for d in range(n)]).reshape(n, K))
    log_p = np.zeros((K, n))
    for m in range(K):
        log_p[m] += multivariate_normal.logpdf(positions, mu[m], sigma[m]) + log_pi_data[:, m]
    return _normalise_log_rows(log_p.T)


def reference_concept_probabilities(vision: np.ndarray, names: np.ndarray, regions: Sequence[int],
                                    theta_v: np.ndarray, theta_w: np.ndarray, pi: np.ndarray,
                                    G: np.ndarray) -> np.ndarray:
    """p(C_t = l | R_t, v_t, w_t) ∝ G_l π_{l, R_t} Π_k θ^v_{l,k}^{v_tk} Π_k θ^w_{l,k}^{w_tk} for one
    home, shape (n, L). θ^v (L, D), θ^w (L, V), π (L, K), G (L,). One dense product per concept."""
    n, L = vision.shape[0], G.shape[0]
    log_theta_v, log_theta_w, log_g = np.log(theta_v), np.log(theta_w), np.log(G)
    log_pi_data = np.log(np.array([pi.T[regions[d]] for d in range(n)]).reshape(n, L))
    log_p = np.zeros((L, n))
    for c in range(L):
        log_p[c] += vision.dot(log_theta_v[c]) + names.dot(log_theta_w[c]) + log_pi_data[:, c] + log_g[c]
    return _normalise_log_rows(log_p.T)


def _bag_of_features(rows: list[np.ndarray], dim: int) -> np.ndarray:
    """Sum a list of count vectors, one vector at a time."""
    total = np.zeros(dim)
    for row in rows:
        total += row
    return total


def reference_region_posterior(positions: np.ndarray, regions: Sequence[int], region: int, mu0: np.ndarray,
                               kappa0: float, psi0: np.ndarray,
                               nu0: float) -> tuple[np.ndarray, float, np.ndarray, float, int]:
    """NIW posterior (μ_n, κ_n, Ψ_n, ν_n, n) of one region, the authors' way: the region's points
    gathered by a loop over the home's samples, sums and per-point outer products in Python."""
    dim = positions.shape[1]
    points = [positions[d] for d in range(len(regions)) if regions[d] == region]
    n = len(points)
    total = np.zeros(dim)
    for x in points:
        total += x
    mean = total / n if n else np.zeros(dim)
    scatter = np.zeros((dim, dim))
    for x in points:
        diff = x - mean
        scatter += np.outer(diff, diff)
    kappa_n, nu_n = kappa0 + n, nu0 + n
    mu_n = (kappa0 * mu0 + n * mean) / kappa_n
    dev = mean - mu0
    psi_n = psi0 + scatter + (kappa0 * n / kappa_n) * np.outer(dev, dev)
    return mu_n, kappa_n, psi_n, nu_n, n


def inverse_wishart_loop(nu: float, psi: np.ndarray, rs: np.random.RandomState) -> np.ndarray:
    """Σ ~ IW(Ψ, ν): a Wishart(Ψ^{-1}, ν) draw by the Bartlett decomposition, filled element by
    element, then inverted."""
    dim = psi.shape[0]
    chol = np.linalg.cholesky(np.linalg.inv(psi))
    a = np.zeros((dim, dim))
    for i in range(dim):
        a[i, i] = np.sqrt(rs.chisquare(nu - i))
        for j in range(i):
            a[i, j] = rs.normal()
    factor = chol @ a
    return np.linalg.inv(factor @ factor.T)


def _draw_each(p: np.ndarray, rs: np.random.RandomState) -> list[int]:
    """One categorical draw per row of ``p``, one ``choice`` call each."""
    choices = list(range(p.shape[1]))
    return [rs.choice(choices, p=p[d]) for d in range(p.shape[0])]


def _step(timer: gibbs.StepTimer | None, name: str) -> contextlib.AbstractContextManager[None]:
    return timer(name) if timer is not None else contextlib.nullcontext()


def reference_sweep(data: ReferenceData, state: ReferenceState, hyper: TransferHyperparameters,
                    rs: np.random.RandomState, timer: gibbs.StepTimer | None = None) -> None:
    """One sweep of the authors' sampler, written as they wrote it (in place).

    Per home: R block, C block, NIW per region (empty regions re-seeded), θ^v, θ^w and π per
    concept, G_e; then φ^v, φ^w per concept (pooled counts, uniform for an empty concept) and
    G_0 ~ Dir(γ0 + Σ_e n_e). No word pruning (``gibbs_spco_transfer20.py`` has none).
    ``timer`` accumulates the time of the steps ``R (regions)``, ``C (concepts)``,
    ``NIW (region Gaussians)``, ``θ, π, G (home)`` and ``φ, G0 (shared)``.
    """
    L, K = hyper.n_concepts, hyper.n_regions
    psi0 = hyper.psi0_matrix_m2() * np.outer(_CM, _CM)
    D, V = state.phi_v.shape[1], state.phi_w.shape[1]
    concept_totals = []
    for e in range(data.n_homes):
        x, vision, names = data.positions[e], data.vision[e], data.names[e]
        n = x.shape[0]
        with _step(timer, "R (regions)"):
            p = reference_region_probabilities(x, state.concepts[e], state.pi[e], state.mu[e], state.sigma[e])
            state.regions[e] = _draw_each(p, rs)
        with _step(timer, "C (concepts)"):
            p = reference_concept_probabilities(vision, names, state.regions[e], state.theta_v[e],
                                                state.theta_w[e], state.pi[e], state.G[e])
            state.concepts[e] = _draw_each(p, rs)
            concept_count = np.zeros(L)
            concept_region_count = np.zeros((L, K))
            for d in range(n):
                concept_count[state.concepts[e][d]] += 1.0
                concept_region_count[state.concepts[e][d]][state.regions[e][d]] += 1.0
        with _step(timer, "NIW (region Gaussians)"):
            for r in range(K):
                mu_n, kappa_n, psi_n, nu_n, count = reference_region_posterior(
                    x, state.regions[e], r, data.mu0[e], hyper.kappa0, psi0, hyper.nu0)
                state.sigma[e, r] = inverse_wishart_loop(nu_n, psi_n, rs)
                state.mu[e, r] = rs.multivariate_normal(mu_n, state.sigma[e, r] / kappa_n)
                if count == 0:
                    state.mu[e, r] = rs.uniform(-_RESEED_BOX, _RESEED_BOX)
                    state.sigma[e, r] = _SIGMA_INIT * np.eye(4)
        with _step(timer, "θ, π, G (home)"):
            for c in range(L):
                members = [d for d in range(n) if state.concepts[e][d] == c]
                counts_v = _bag_of_features([vision[d] for d in members], D)
                state.theta_v[e, c] = rs.dirichlet(counts_v + hyper.delta_visual * state.phi_v[c]) + _TINY
                if V:
                    counts_w = _bag_of_features([names[d] for d in members], V)
                    state.theta_w[e, c] = rs.dirichlet(counts_w + hyper.delta_word * state.phi_w[c]) + _TINY
                state.pi[e, c] = rs.dirichlet(concept_region_count[c] + hyper.beta)
            state.G[e] = rs.dirichlet(concept_count + hyper.gamma * state.G0 + 50.0) + _TINY
            concept_totals.append(concept_count)
    with _step(timer, "φ, G0 (shared)"):
        for c in range(L):
            rows_v, rows_w = [], []
            for e in range(data.n_homes):
                for d in range(data.positions[e].shape[0]):
                    if state.concepts[e][d] == c:
                        rows_v.append(data.vision[e][d])
                        rows_w.append(data.names[e][d])
            if not rows_v:
                state.phi_v[c] = 1.0 / D
                if V:
                    state.phi_w[c] = 1.0 / V
                continue
            state.phi_v[c] = rs.dirichlet(_bag_of_features(rows_v, D) + hyper.alpha_visual) + _TINY
            if V:
                state.phi_w[c] = rs.dirichlet(_bag_of_features(rows_w, V) + hyper.alpha_word) + _TINY
        state.G0 = rs.dirichlet(np.sum(concept_totals, axis=0) + hyper.gamma0)


def iter_steps(result: dict[str, Any]) -> Iterator[tuple[str, float, float | None]]:
    """(step, exact seconds, reference-variant seconds or None) for every step of spco's sweeps."""
    exact = result["spco"]["exact"]["steps"]
    ref = result["spco"].get("reference", {}).get("steps", {})
    for name in [*exact, *(n for n in ref if n not in exact)]:
        yield name, exact.get(name, float("nan")), ref.get(name)
