"""The authors' sampler, re-implemented loop for loop, and spco's speed-up over it.

:func:`reference_sweep` is the authors' per-sweep work written here in the style of their published
``gibbs_spco_transfer20.py``: one ``choice`` call per data point for R and C,
``scipy.stats.multivariate_normal.logpdf`` per region, the members of each region and concept
gathered by Python loops over the samples, per-point outer products for the Gaussian statistics, an
inverse-Wishart draw built element by element, one ``dirichlet`` call per concept and home (θ^v,
θ^w, π), per home (G_e) and per concept (φ^v, φ^w), dense visual and word arrays. It is
deliberately loopy: it is the baseline that spco's speed-up is measured against, on the same data,
in the same process, on the same machine. It is not part of the package: nothing but this
benchmark, ``run_scaling.py --with-reference`` and ``tests/test_benchmark.py`` runs it.

Run as a script, it is ``spco bench`` with the authors'-style sweep timed beside spco's two samplers
(interleaved, :func:`spco.benchmark.interleaved_schedule`), and reports the speed-ups::

    python benchmarks/reference_sampler.py --data /path/to/sigverse      # the paper's largest run
    python benchmarks/reference_sampler.py --json                       # synthetic homes, JSON

Progress goes to stderr, the result to stdout.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.cluster.vq import kmeans2

from spco import benchmark
from spco.data.environment import Corpus
from spco.model import gibbs
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.state import PreparedData

Log = benchmark.Log


def _quiet(_: str) -> None:
    """A logger that discards its message."""

#: The authors' positions are in centimetres.
_CM = np.array([100.0, 100.0, 1.0, 1.0])
#: The authors' initial (and re-seed) covariance, 100·I.
_SIGMA_INIT = 100.0
#: Half-widths of the box an empty region's mean is re-seeded in (the authors draw within the map
#: bounds, stored in metres, while their positions are in centimetres: ±6 "cm" in x and y).
_RESEED_BOX = np.array([6.0, 6.0, 1.0, 1.0])
#: What the authors add to every drawn probability vector.
_TINY = 1e-100


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


class ReferenceRunner:
    """:func:`reference_sweep` on ``corpus`` (the same training data spco learns from),
    initialised and warmed up, timed one sweep at a time (:meth:`sweep`) into :attr:`timings`."""

    def __init__(self, corpus: Corpus, warmup: int = 1, seed: int = 0,
                 hyper: TransferHyperparameters | None = None, log: Log = _quiet) -> None:

        self.hyper = hyper or TransferHyperparameters()
        self.data = ReferenceData.from_prepared(PreparedData.from_corpus(corpus, 1.0))
        self.random_state = np.random.RandomState(seed)
        self.state = reference_initialize(self.data, self.hyper, self.random_state)
        for i in range(warmup):
            t0 = time.perf_counter()
            reference_sweep(self.data, self.state, self.hyper, self.random_state)
            milliseconds = (time.perf_counter() - t0) * 1e3
            log(f"  authors'-style sweep (warm-up {i + 1}/{warmup}): {milliseconds:.0f} ms")
        self.timings = benchmark.SweepTimings()

    def sweep(self) -> float:
        """Run and record one timed sweep; returns its wall time in seconds."""
        timer = gibbs.StepTimer()
        t0 = time.perf_counter()
        reference_sweep(self.data, self.state, self.hyper, self.random_state, timer=timer)
        elapsed = time.perf_counter() - t0
        self.timings.add(elapsed, timer.seconds)
        return elapsed


def time_reference(corpus: Corpus, sweeps: int = 3, warmup: int = 1, seed: int = 0,
                   hyper: TransferHyperparameters | None = None,
                   log: Log = _quiet) -> benchmark.SweepTimings:
    """Time :func:`reference_sweep` on ``corpus`` (the same training data spco learns from)."""
    runner = ReferenceRunner(corpus, warmup, seed, hyper, log)
    for i in range(sweeps):
        elapsed = runner.sweep()
        log(f"  authors'-style sweep {i + 1}/{sweeps}: {elapsed * 1e3:.0f} ms")
    return runner.timings


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Time spco's samplers and the authors'-style sweep, interleaved; print the result with the
    speed-ups (``speedup``: the authors'-style sweep over spco's exact sweep;
    ``speedup_same_algorithm``: over spco's reference variant, the same conditionals)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=None,
                        help="the SIGVerse data set (or an spco cache); default: synthetic homes")
    parser.add_argument("--sweeps", type=int, default=20, help="timed sweeps of spco's samplers")
    parser.add_argument("--reference-sweeps", type=int, default=3, help="timed authors'-style sweeps")
    parser.add_argument("--warmup", type=int, default=2, help="untimed sweeps of spco's samplers first")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--new-home", default=benchmark.PAPER_NEW_HOME, help="the new home with --data")
    parser.add_argument("--homes", type=int, default=16, help="experienced homes")
    parser.add_argument("--features", type=int, default=4096, help="visual dimension D of synthetic homes")
    parser.add_argument("--no-memory", action="store_true", help="do not measure a fit's peak memory")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    args = parser.parse_args(argv)

    if args.data is None:
        corpus = benchmark.synthetic_corpus(args.homes, 1, n_features=args.features, seed=args.seed)
        source = "synthetic"
    else:
        corpus = benchmark.paper_corpus(args.data, benchmark.PAPER_EXPERIENCED_HOMES[:args.homes],
                                        (args.new_home,))
        source = str(args.data)

    def authors(corpus: Corpus, hyper: TransferHyperparameters, seed: int, log: Log) -> ReferenceRunner:
        return ReferenceRunner(corpus, warmup=1, seed=seed, hyper=hyper, log=log)

    result = benchmark.run_benchmark(corpus, source, sweeps=args.sweeps, warmup=args.warmup, seed=args.seed,
                                     memory=not args.no_memory, log=_log, baseline=authors,
                                     baseline_sweeps=args.reference_sweeps)
    if args.json:
        print(json.dumps(result, indent=1, ensure_ascii=False))
    else:
        from spco.cli.bench import format_result

        print(format_result(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
