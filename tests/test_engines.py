"""Sharded sweeps: the local engine with several shards, the Ray engine, and its restarts.

The same seed gives the same chain (log-joint trace and concepts, bit for bit) for any number of
shards, in process and on Ray: every home draws from its own random stream; killing a Ray actor
mid-fit restarts the shards from the last checkpoint and ends where a fault-free fit ends. The Ray
tests share one local Ray instance (2 CPUs)."""

from __future__ import annotations

import numpy as np
import pytest

from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.engines import LocalEngine, start_run
from spco.model import gibbs, shard, sweep_statistics
from spco.model.additive import SUM_GRID
from spco.model.state import PreparedData
from spco.model.transfer import SpatialConceptModel

N_SWEEPS = 12


@pytest.fixture(scope="module")
def corpus():
    return generate_homes(5, seed=2, new_homes=1, config=SyntheticConfig(n_features=64, n_train=12))


def start(corpus, engine, variant: str = "exact", seed: int = 5):
    """A run of ``engine`` on ``corpus``, started as SpatialConceptModel.fit starts it."""
    model = SpatialConceptModel(variant=variant, random_state=seed, prune_words=True)
    hyper, settings = model.checked_hyperparameters(), model.sampler_settings()
    rng = np.random.default_rng(seed)
    data = PreparedData.from_corpus(corpus, gibbs.CM_PER_M if variant == "reference" else 1.0)
    return data, start_run(engine, data, len(corpus.vocabulary), hyper, settings, rng)


def chain(corpus, engine, variant: str = "exact", after_sweep=None):
    """(log-joint trace, concepts, regions) after N_SWEEPS sweeps."""
    _, run = start(corpus, engine, variant)
    trace = run.fit(N_SWEEPS, after_sweep)
    state = run.state()
    run.close()
    return trace, state.concepts, state.regions


def test_split_and_join_round_trip(corpus) -> None:
    """Cutting homes into shards and joining their states gives back every array unchanged."""
    model = SpatialConceptModel(random_state=0, prune_words=True)
    data = PreparedData.from_corpus(corpus, 1.0)
    state = gibbs.initialize(data, len(corpus.vocabulary), model.checked_hyperparameters(),
                             model.sampler_settings(), np.random.default_rng(0))
    bounds = shard.shard_bounds(data, 3)
    assert bounds[0][0] == 0 and bounds[-1][1] == data.n_homes
    assert all(a < b for a, b in bounds) and all(bounds[i][1] == bounds[i + 1][0] for i in range(2))
    parts = shard.split(data, state, 3)
    assert sum(d.n_samples for d, _ in parts) == data.n_samples
    joined = shard.join_states([s for _, s in parts])
    for name in shard.HOME_FIELDS + shard.SAMPLE_FIELDS:
        np.testing.assert_array_equal(getattr(joined, name), getattr(state, name))
    with pytest.raises(ValueError, match="shards"):
        shard.shard_bounds(data, data.n_homes + 1)


@pytest.mark.parametrize("variant", ["exact", "reference"])
def test_any_number_of_local_shards_gives_the_same_chain(corpus, variant: str) -> None:
    """One, two and four in-process shards: a finite log joint and the same chain, bit for bit
    (every home draws from its own stream, the driver sums exactly); another seed, another chain."""
    one = chain(corpus, LocalEngine(1), variant)
    assert np.isfinite(one[0]).all()
    for shards in (2, 4):
        other = chain(corpus, LocalEngine(shards), variant)
        for a, b in zip(one, other, strict=True):
            np.testing.assert_array_equal(a, b)
    _, run = start(corpus, LocalEngine(2), variant, seed=6)
    assert not np.array_equal(run.fit(N_SWEEPS), one[0])
    run.close()


def test_statistics_add_up_over_shards(corpus) -> None:
    """Pooled counts of two shards sum to the counts of all homes in one shard."""
    data, run = start(corpus, LocalEngine(2))
    run.call("local_step", None)
    parts = run.call("pooled_counts")
    total = parts[0] + parts[1]
    state = run.state()
    model = SpatialConceptModel(random_state=0)
    stats = sweep_statistics.sufficient_statistics(data, state, model.checked_hyperparameters(), None)
    np.testing.assert_array_equal(total.visual, stats.visual.sum(0))
    np.testing.assert_array_equal(total.concepts, stats.concepts.sum(0))


def test_naming_rule_adds_up_over_shards(corpus) -> None:
    """The naming rule's statistics of three shards sum to those of all homes, so the driver's
    verdicts are the ones one process would reach (gibbs.naming_verdicts)."""
    from spco.model.pruning import colocation, judge_names

    data, run = start(corpus, LocalEngine(3))
    run.call("local_step", None)
    parts = run.call("colocation")
    state = run.state()
    hyper = SpatialConceptModel(random_state=0).checked_hyperparameters()
    whole = colocation(data.words, data.homes, state.regions, data.n_homes, hyper.n_regions)
    fields = ("pairs", "same", "expected", "log_likelihood")
    for field in fields:  # (each home's floats are rounded to SUM_GRID, so that they add up exactly)
        np.testing.assert_allclose(sum(getattr(c, field) for c in parts), getattr(whole, field), rtol=0,
                                   atol=SUM_GRID * data.n_homes)
    summed = type(whole)(*(sum(getattr(c, f) for c in parts) for f in fields))
    np.testing.assert_array_equal(judge_names(summed), gibbs.naming_verdicts(data, state, hyper))
    assert (whole.pairs > 0).any()  # the corpus has words said twice in a home: the test has teeth


# ----------------------------------------------------------------------------- Ray


def test_ray_gives_the_local_engines_chain(corpus, ray_session) -> None:
    """Two shards as Ray actors: the same log-joint trace and concepts as one in-process shard."""
    from spco.engines.ray import RayEngine

    local = chain(corpus, LocalEngine(1))
    remote = chain(corpus, RayEngine(2, checkpoint_every=5))
    np.testing.assert_array_equal(remote[0], local[0])
    np.testing.assert_array_equal(remote[1], local[1])
    np.testing.assert_array_equal(remote[2], local[2])


def test_ray_restarts_a_killed_actor_from_the_checkpoint(corpus, ray_session) -> None:
    """Killing a shard's actor after sweep 7 (checkpoints every 5): the fit restarts from sweep 5
    and ends where the fault-free fit ends."""
    from spco.engines.ray import RayEngine

    _, run = start(corpus, RayEngine(2, checkpoint_every=5))
    killed = []

    def kill_once(iteration: int, _: float) -> None:
        if iteration == 7 and not killed:
            killed.append(True)
            ray_session.kill(run.actors[1])

    trace = run.fit(N_SWEEPS, kill_once)
    state = run.state()
    run.close()
    assert run.restarts == 1
    local = chain(corpus, LocalEngine(2))
    np.testing.assert_array_equal(trace, local[0])
    np.testing.assert_array_equal(state.concepts, local[1])


def test_fit_takes_the_ray_engine(corpus, ray_session) -> None:
    """SpatialConceptModel.fit(corpus, engine=...) runs on Ray and exports every home."""
    from spco.engines.ray import RayEngine

    model = SpatialConceptModel(n_iterations=4, random_state=1).fit(corpus, engine=RayEngine(2))
    assert len(model.concepts_) == len(corpus) and np.isfinite(model.log_joint_).all()


def test_experiment_runs_as_ray_tasks_and_resumes(tmp_path, ray_session) -> None:
    """`spco experiment … --engine ray`: an interrupted local experiment resumed on Ray gives the
    results of the uninterrupted one (runs are Ray tasks; the engine is not part of its identity)."""
    import json
    import shutil

    from spco.evaluation.experiments import ExperimentConfig, load_experiment_data, run_experiment

    small = {"experiment": "general", "settings": (0, 1), "trials": 2, "iterations": 5, "models": ("spcoa",)}
    new_home = load_experiment_data(ExperimentConfig(**small)).new_homes[0]
    full = run_experiment(ExperimentConfig(**small, new_homes=(new_home,)), tmp_path / "local")
    out = tmp_path / "ray"
    shutil.copytree(tmp_path / "local", out)
    lines = (out / "runs.jsonl").read_text().splitlines(keepends=True)
    (out / "runs.jsonl").write_text(lines[0])
    (out / "results.json").unlink()
    resumed = run_experiment(ExperimentConfig(**small, new_homes=(new_home,), engine="ray"), out, resume=True)
    assert resumed.results["timing"]["runs_this_session"] == sum(
        json.loads(line).get("reused_from_setting") is None for line in lines[1:])

    def stable(results):
        return json.dumps([{k: v for k, v in r.items() if k != "wall_seconds"} for r in results["runs"]],
                          sort_keys=True)

    assert stable(resumed.results) == stable(full.results)


def test_fit_command_refuses_an_address_without_ray(tmp_path) -> None:
    """`spco fit --address` belongs to `--engine ray`: a one-line usage error, exit 2."""
    from click.testing import CliRunner

    from spco.cli import main

    result = CliRunner().invoke(main, ["fit", "--data", str(tmp_path), "--out", str(tmp_path / "k.spco"),
                                       "--address", "auto"])
    assert result.exit_code == 2
    assert "--address is for --engine ray" in result.output


def test_fit_command_refuses_a_checkpoint_dir_without_ray(tmp_path) -> None:
    """`spco fit --checkpoint-dir` belongs to `--engine ray` too."""
    from click.testing import CliRunner

    from spco.cli import main

    result = CliRunner().invoke(main, ["fit", "--data", str(tmp_path), "--out", str(tmp_path / "k.spco"),
                                       "--checkpoint-dir", str(tmp_path / "c")])
    assert result.exit_code == 2
    assert "--checkpoint-dir is for --engine ray" in result.output
