"""`spco bench` and the authors'-style reference sweep that benchmarks/reference_sampler.py
measures it against (fast tests, no timing assertions)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from spco import benchmark
from spco.cli.bench import bench, format_result
from spco.model import gibbs
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.kernels.niw import niw_posterior
from spco.model.state import PreparedData

# the authors' sampler re-implemented: a benchmark, not part of the package
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import reference_sampler as reference

HYPER = TransferHyperparameters()


@pytest.fixture(scope="module")
def corpus():
    """Two taught synthetic homes and one new home, D = 32."""
    return benchmark.synthetic_corpus(2, 1, n_features=32, seed=0)


@pytest.fixture(scope="module")
def bench_json() -> dict:
    """`spco bench --json` on a tiny synthetic configuration."""
    result = CliRunner().invoke(bench, ["--homes", "2", "--features", "32", "--json", "--sweeps", "2",
                                        "--warmup", "1"])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def _softmax_rows(log_p: np.ndarray) -> np.ndarray:
    p = np.exp(log_p - log_p.max(axis=1, keepdims=True))
    return p / p.sum(axis=1, keepdims=True)


def _random_covariances(rng: np.random.Generator, k: int, scale: float = 1.0) -> np.ndarray:
    a = rng.normal(size=(k, 4, 4))
    return scale * (a @ np.swapaxes(a, 1, 2) + 4 * np.eye(4))


# ----------------------------------------------------------------------------- the reference sweep


def test_reference_sweep_keeps_a_valid_state(corpus) -> None:
    data = reference.ReferenceData.from_prepared(PreparedData.from_corpus(corpus, 1.0))
    sizes = [t.n_samples for t in corpus.training_set()]
    assert [x.shape[0] for x in data.positions] == sizes
    assert data.vision[0].shape[1] == 32 and data.names[0].shape[1] == len(corpus.vocabulary)
    # positions are in centimetres, as in the authors' code
    np.testing.assert_allclose(data.positions[0][:, :2], corpus[0].training_data().positions[:, :2] * 100)
    rs = np.random.RandomState(0)
    state = reference.reference_initialize(data, HYPER, rs)
    timer = gibbs.StepTimer()
    for _ in range(2):
        reference.reference_sweep(data, state, HYPER, rs, timer=timer)
    assert list(timer.seconds) == ["R (regions)", "C (concepts)", "NIW (region Gaussians)", "θ, π, G (home)",
                                   "φ, G0 (shared)"]
    E, L, K = 3, HYPER.n_concepts, HYPER.n_regions
    for e, n in enumerate(sizes):
        assert len(state.concepts[e]) == len(state.regions[e]) == n
        assert 0 <= min(state.concepts[e]) and max(state.concepts[e]) < L
        assert 0 <= min(state.regions[e]) and max(state.regions[e]) < K
    for probabilities, shape in ((state.theta_v, (E, L, 32)), (state.theta_w, (E, L, len(corpus.vocabulary))),
                                 (state.pi, (E, L, K)), (state.G, (E, L)), (state.G0, (L,)),
                                 (state.phi_v, (L, 32))):
        assert probabilities.shape == shape
        assert np.isfinite(probabilities).all() and (probabilities >= 0).all()
        np.testing.assert_allclose(probabilities.sum(-1), 1.0, rtol=1e-9)
    assert state.mu.shape == (E, K, 4) and np.isfinite(state.mu).all()
    np.testing.assert_allclose(state.sigma, np.swapaxes(state.sigma, -1, -2), rtol=1e-8, atol=1e-8)
    assert (np.linalg.eigvalsh(state.sigma) > 0).all()


def test_region_probabilities_match_the_conditional() -> None:
    rng = np.random.default_rng(1)
    n, L, K = 30, 4, 5
    x = rng.normal(scale=50, size=(n, 4))
    concepts = list(rng.integers(0, L, n))
    pi = rng.dirichlet(np.ones(K), size=L)
    mu = rng.normal(scale=50, size=(K, 4))
    sigma = _random_covariances(rng, K, 100.0)
    p = reference.reference_region_probabilities(x, concepts, pi, mu, sigma)
    # log N(x | μ, Σ) through the Cholesky factor, vectorised over samples and regions
    chol = np.linalg.cholesky(sigma)
    z = np.linalg.solve(chol[None], (x[:, None, :] - mu[None])[..., None])[..., 0]
    log_det = 2 * np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(-1)
    log_norm = -0.5 * (z ** 2).sum(-1) - 0.5 * log_det - 2 * np.log(2 * np.pi)
    expected = _softmax_rows(log_norm + np.log(pi[concepts]))
    np.testing.assert_allclose(p, expected, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(p.sum(1), 1.0)


def test_concept_probabilities_match_the_conditional() -> None:
    rng = np.random.default_rng(2)
    n, L, K, D, V = 25, 6, 4, 40, 7
    vision = rng.poisson(3.0, size=(n, D)).astype(float)
    names = np.zeros((n, V))
    names[np.arange(n), rng.integers(0, V, n)] = 5.0
    regions = list(rng.integers(0, K, n))
    theta_v, theta_w = rng.dirichlet(np.ones(D), size=L), rng.dirichlet(np.ones(V), size=L)
    pi, g = rng.dirichlet(np.ones(K), size=L), rng.dirichlet(np.ones(L))
    p = reference.reference_concept_probabilities(vision, names, regions, theta_v, theta_w, pi, g)
    log_p = vision @ np.log(theta_v).T + names @ np.log(theta_w).T + np.log(pi[:, regions]).T + np.log(g)
    np.testing.assert_allclose(p, _softmax_rows(log_p), rtol=1e-8, atol=1e-12)


def test_region_posterior_matches_the_batched_niw_posterior() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(scale=80, size=(40, 4))
    regions = list(rng.integers(0, 3, 40))  # region 3 stays empty
    mu0, psi0 = np.array([5.0, -3.0, 0.0, 0.0]), np.diag([10.0, 10.0, 0.5, 0.5])
    for r in range(4):
        mu_n, kappa_n, psi_n, nu_n, n = reference.reference_region_posterior(x, regions, r, mu0, 0.05, psi0,
                                                                             10.0)
        members = x[np.asarray(regions) == r]
        assert n == len(members)
        expected = niw_posterior(np.array(n), members.sum(0), members.T @ members, mu0, 0.05, psi0, 10.0)
        np.testing.assert_allclose(mu_n, expected[0], rtol=1e-10, atol=1e-10)
        assert kappa_n == pytest.approx(float(expected[1])) and nu_n == pytest.approx(float(expected[3]))
        np.testing.assert_allclose(psi_n, expected[2], rtol=1e-8, atol=1e-8)


def test_inverse_wishart_draws_have_the_right_mean() -> None:
    rs = np.random.RandomState(4)
    psi = np.array([[4.0, 1.0, 0.0, 0.5], [1.0, 3.0, 0.2, 0.0], [0.0, 0.2, 2.0, 0.3], [0.5, 0.0, 0.3, 1.0]])
    nu = 30.0
    draws = np.array([reference.inverse_wishart_loop(nu, psi, rs) for _ in range(4000)])
    np.testing.assert_allclose(draws.mean(0), psi / (nu - 4 - 1), rtol=0.05, atol=0.004)


def test_draw_each_is_one_categorical_draw_per_row() -> None:
    p = np.eye(5)[[3, 0, 4, 4, 1]]
    assert [int(c) for c in reference._draw_each(p, np.random.RandomState(0))] == [3, 0, 4, 4, 1]


# ----------------------------------------------------------------------------- timings and memory


def test_time_spco_and_reference_record_every_sweep(corpus) -> None:
    exact = benchmark.time_spco(corpus, "exact", sweeps=2, warmup=0)
    assert len(exact.totals) == 2 and {"assignments", "home parameters"} <= set(exact.per_step())
    assert exact.per_sweep > 0
    ref = reference.time_reference(corpus, sweeps=1, warmup=0)
    assert len(ref.totals) == 1 and len(ref.per_step()) == 5


def test_interleaved_schedule_spreads_every_sampler_over_the_run() -> None:
    order = benchmark.interleaved_schedule(20, 5)
    assert order.count("exact") == order.count("reference") == 20 and order.count("authors") == 5
    # one authors'-style sweep per round, each after that round's four sweeps of each spco sampler
    rounds = " ".join(order).split("authors")
    assert [r.split().count("exact") for r in rounds[:5]] == [4, 4, 4, 4, 4]
    assert order[-1] == "authors"
    few = benchmark.interleaved_schedule(3, 5)
    assert few.count("exact") == 3 and few.count("authors") == 5


def test_configuration_counts_homes_and_samples(corpus) -> None:
    config = benchmark.configuration(corpus, HYPER, "synthetic")
    assert config["homes"] == 3 and config["experienced_homes"] == 2
    assert config["new_homes"] == [corpus[2].name]
    assert config["samples"] == sum(e.n_train for e in corpus)
    assert (config["D"], config["L"], config["K"]) == (32, 15, 20)


def test_peak_rss_is_positive() -> None:
    mb, how = benchmark.peak_rss_mb()
    assert mb > 1 and how in ("VmHWM", "ru_maxrss")


# ----------------------------------------------------------------------------- the command


def test_bench_json_has_the_documented_keys(bench_json: dict) -> None:
    for key in ("sweep_seconds", "peak_memory_mb", "steps", "configuration", "machine", "spco", "memory"):
        assert key in bench_json
    assert "speedup" not in bench_json and "reference" not in bench_json  # no baseline timed
    assert bench_json["peak_memory_mb"] > 0
    assert {"homes", "samples", "D", "L", "K"} <= set(bench_json["configuration"])
    assert bench_json["configuration"]["homes"] == 3 and bench_json["configuration"]["D"] == 32
    assert {"cores", "numpy", "numba"} <= set(bench_json["machine"])
    assert "assignments" in bench_json["steps"]
    assert bench_json["spco"]["exact"]["sweeps"] == 2 and bench_json["spco"]["reference"]["sweeps"] == 2


def test_bench_table_lists_steps_totals_and_memory(bench_json: dict) -> None:
    text = format_result(bench_json)
    assert "assignments" in text and "total (mean of 2 sweeps)" in text and "peak memory" in text
    assert "speedup" not in text


def test_reference_benchmark_times_the_authors_sweep_beside_spco(capsys: pytest.CaptureFixture[str]) -> None:
    """benchmarks/reference_sampler.py: spco bench with the authors'-style sweep interleaved, and the
    speed-ups computed from the same timings."""
    assert reference.main(["--homes", "2", "--features", "32", "--sweeps", "2", "--reference-sweeps", "1",
                           "--warmup", "0", "--no-memory", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["reference"]["sweeps"] == 1 and out["spco"]["exact"]["sweeps"] == 2
    assert out["speedup"] == pytest.approx(out["reference_sweep_seconds"] / out["sweep_seconds"])
    assert out["speedup_same_algorithm"] == pytest.approx(out["reference_sweep_seconds"]
                                                          / out["spco"]["reference"]["sweep_seconds"])
    text = format_result(out)
    assert "authors'-style reference sweep (mean of 1)" in text and "speedup:" in text


def test_bench_on_sigverse_layout_homes(tmp_path: Path, make_sigverse_home) -> None:
    root = tmp_path / "homes"
    for name in ("3LDK_1", "1LDK_8", "1LDK_9"):
        make_sigverse_home(name, n=8, test=(6, 7), root=root)
    corpus = benchmark.paper_corpus(root, ["3LDK_1", "1LDK_8"], ["1LDK_9"])
    assert [e.n_taught for e in corpus] == [6, 6, 0]
    result = CliRunner().invoke(bench, ["--data", str(root), "--homes", "2", "--json", "--sweeps", "1",
                                        "--warmup", "0", "--no-memory"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["configuration"]["new_homes"] == ["1LDK_9"] and out["configuration"]["samples"] == 18
    assert out["peak_memory_mb"] is None


def test_bench_reports_bad_input_in_one_line(tmp_path: Path) -> None:
    result = CliRunner().invoke(bench, ["--data", str(tmp_path / "nowhere"), "--homes", "2"])
    assert result.exit_code == 2 and result.output.splitlines()[-1].startswith("error:")
    result = CliRunner().invoke(bench, ["--data", str(tmp_path), "--new-home", "3LDK_1"])
    assert result.exit_code == 2 and "experienced" in result.output


def test_bench_is_a_spco_command() -> None:
    from spco.cli import main

    result = CliRunner().invoke(main, ["bench", "--help"])
    assert result.exit_code == 0 and "--sweeps" in result.output and "--reference-sweeps" not in result.output
