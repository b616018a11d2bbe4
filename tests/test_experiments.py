"""The experiment runner: a short general experiment on synthetic homes (CLI and library), resume,
refusal to mix configurations, bad input, the specific experiment, and a SIGVerse smoke test."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from spco.cli.experiment import _MODEL_NAMES, experiment
from spco.errors import ConfigurationError, DataFormatError, SpcoError
from spco.evaluation.experiments import (
    MODELS,
    PAPER_EXPERIENCED_HOMES,
    ExperimentConfig,
    load_experiment_data,
    parse_int_list,
    parse_models,
    read_runs,
    run_experiment,
    trial_seed,
)
from spco.evaluation.report import format_cell, summarize

SMALL = {"experiment": "general", "settings": (0, 2), "trials": 2, "iterations": 10,
         "models": ("spcotransfer+mi", "spcoa")}
RUN_KEYS = {"experiment", "model", "setting", "home", "trial", "place", "name_accuracy",
            "position_accuracy", "position_accuracy_mixture",
            "seed", "iterations", "wall_seconds", "reused_from_setting"}
SUMMARY_KEYS = {"experiment", "model", "setting", "place", "name_accuracy_mean", "name_accuracy_std",
                "position_accuracy_mean", "position_accuracy_std", "position_accuracy_mixture_mean",
                "position_accuracy_mixture_std", "n"}


@pytest.fixture(scope="module")
def new_home() -> str:
    """One synthetic new home (seed 0), to keep the experiments short."""
    return load_experiment_data(ExperimentConfig(**SMALL)).new_homes[0]


@pytest.fixture(scope="module")
def general_out(tmp_path_factory: pytest.TempPathFactory, new_home: str) -> Path:
    """A short general experiment on synthetic homes, run through the command line."""
    out = tmp_path_factory.mktemp("general") / "out"
    result = CliRunner().invoke(experiment, [
        "general", "--envs", "0,2", "--trials", "2", "--iterations", "10",
        "--models", "spcotransfer+mi,spcoa", "--new-homes", new_home, "--out", str(out), "--quiet",
    ])
    assert result.exit_code == 0, result.output
    assert "8 runs" in result.output
    return out


def _stable(results: dict[str, Any]) -> dict[str, Any]:
    """results.json without timings (everything else must be reproducible)."""
    runs = [{k: v for k, v in row.items() if k != "wall_seconds"} for row in results["runs"]]
    config = {k: v for k, v in results["config"].items()}
    return {"runs": runs, "summary": results["summary"], "summary_by_home": results["summary_by_home"],
            "chance": results["chance"], "config": config}


# ------------------------------------------------------------------------------------ outputs
def test_results_schema(general_out: Path, new_home: str) -> None:
    results = json.loads((general_out / "results.json").read_text())
    assert {"runs", "summary", "config", "chance", "timing"} <= set(results)
    runs = results["runs"]
    assert all(set(row) == RUN_KEYS for row in runs)
    per_run = {(r["model"], r["setting"], r["trial"]) for r in runs}
    assert len(per_run) == 2 * 2 * 2
    assert {r["home"] for r in runs} == {new_home}
    means = [r for r in runs if r["place"] == "mean"]
    assert len(means) == 8
    for m in means:  # a run's mean is the mean of its places
        places = [r["name_accuracy"] for r in runs if r["place"] != "mean" and
                  (r["model"], r["setting"], r["trial"]) == (m["model"], m["setting"], m["trial"])]
        assert m["name_accuracy"] == pytest.approx(sum(places) / len(places))
    assert all(set(row) == SUMMARY_KEYS for row in results["summary"])
    mean_rows = [s for s in results["summary"] if s["place"] == "mean"]
    assert {(s["model"], s["setting"]) for s in mean_rows} == {(m, s) for m in SMALL["models"]
                                                              for s in (0, 2)}
    assert all(s["n"] == 2 for s in mean_rows)
    # transfer from 2 experienced homes names the new home's places better than from none and than
    # chance, with the model the robot ships (spcotransfer+mi) and its answers (the room account).
    # The bound has a margin: over 10 runs of this configuration (this new home, 2 homes, 10 sweeps,
    # trials 0-9; benchmarks/rooms_synthetic.py, benchmarks/README "Issue 29: the room account the
    # default") every run scored >= 0.667, mean 0.850 [0.772, 0.928] with the room account and 0.850
    # [0.768, 0.932] with the view-by-view answer of main 445a282; this test's two runs (trials 0, 1)
    # average 0.883 (room account) and 0.875 (view by view). From 0 homes it names nothing (0.000),
    # chance is 0.067. (Plain spcotransfer, without the naming rule, scored 0.000-1.000 per run, mean
    # 0.36, and this test's two runs exactly its old bound of 0.25: too noisy for a 2-run bound.)
    # SpCoA learns the new home alone, which is taught nothing: it never says a place's name there.
    mean_of = {(s["model"], s["setting"]): s["name_accuracy_mean"] for s in mean_rows}
    chance = results["chance"]["name_accuracy"]
    assert mean_of[("spcotransfer+mi", 2)] >= max(mean_of[("spcotransfer+mi", 0)] + 0.5, 6 * chance)
    assert mean_of[("spcoa", 0)] == mean_of[("spcoa", 2)] == 0.0
    # seeds: one per trial, shared by models and settings
    assert {r["seed"] for r in runs} == {trial_seed(0, 0), trial_seed(0, 1)}
    assert results["timing"]["runs"] == 8 and results["timing"]["run_wall_seconds_total"] > 0
    # SpCoA learns the new home alone: computed at 2 experienced homes, recorded for 0 as well
    assert results["timing"]["runs_reused"] == 2
    for r in runs:
        reused = r["model"] == "spcoa" and r["setting"] == 0
        assert r["reused_from_setting"] == (2 if reused else None)
        assert (r["wall_seconds"] == 0) == reused
    vocabulary = results["config"]["data"]["vocabulary"]
    assert results["chance"]["name_accuracy"] == pytest.approx(1 / len(vocabulary))
    config = json.loads((general_out / "config.json").read_text())
    assert config["fingerprint"] == results["config"]["fingerprint"]


def test_tables_and_figures(general_out: Path) -> None:
    tables = (general_out / "tables.md").read_text()
    assert "## spcotransfer+mi: name accuracy A_n" in tables and "| chance |" in tables
    assert "| experienced homes |" in tables
    pngs = ["general_name_accuracy.png", "general_position_accuracy.png",
            "general_log_joint_spcotransfer_mi.png", "general_log_joint_spcoa.png"]
    for name in pngs:
        assert (general_out / name).stat().st_size > 1000, name
    maps = sorted((general_out / "maps").glob("*.png"))
    assert len(maps) == 2 and all(p.stat().st_size > 1000 for p in maps)
    assert sum(1 for _ in (general_out / "runs.jsonl").open()) == 8


# ------------------------------------------------------------------------------------ resume
def test_resume_after_interruption_gives_the_same_results(general_out: Path, tmp_path: Path,
                                                          new_home: str) -> None:
    out = tmp_path / "out"
    shutil.copytree(general_out, out)
    full = json.loads((out / "results.json").read_text())
    lines = (out / "runs.jsonl").read_text().splitlines(keepends=True)
    # killed: six runs recorded, the seventh line half-written, no results yet
    (out / "runs.jsonl").write_text("".join(lines[:6]) + lines[6][: len(lines[6]) // 2])
    (out / "results.json").unlink()
    config = ExperimentConfig(**SMALL, new_homes=(new_home,), jobs=2)  # workers must agree, too
    result = run_experiment(config, out, resume=True)
    assert result.results["timing"]["runs_this_session"] == sum(
        r.get("reused_from_setting") is None for r in [json.loads(line) for line in lines[6:]])
    assert _stable(result.results) == _stable(full)
    assert len(read_runs(out)) == 8


def test_a_reused_run_is_the_run_itself(general_out: Path, new_home: str) -> None:
    """The copy of SpCoA's run at 0 experienced homes equals that run computed at 0 homes."""
    from spco.evaluation.experiments import RunKey, _RunContext, execute_run

    config = ExperimentConfig(**SMALL, new_homes=(new_home,)).validated()
    data = load_experiment_data(config)
    ctx = _RunContext(config.experiment, config.iterations, config.seed, config.n_positions,
                      config.hyperparameters, "no fingerprint", str(general_out), None,
                      map_setting=max(SMALL["settings"]))
    computed = execute_run(data, ctx, RunKey(0, 1, new_home, "spcoa"))
    recorded = next(r for r in read_runs(general_out)
                    if (r["model"], r["setting"], r["trial"]) == ("spcoa", 0, 1))
    assert recorded["reused_from_setting"] == 2
    for field in ("name_accuracy", "position_accuracy", "seed"):
        assert recorded[field] == computed[field]


def test_resume_with_more_trials_keeps_finished_runs(general_out: Path, tmp_path: Path,
                                                     new_home: str) -> None:
    out = tmp_path / "out"
    shutil.copytree(general_out, out)
    config = ExperimentConfig(**{**SMALL, "trials": 1}, new_homes=(new_home,))
    result = run_experiment(config, out, resume=True)  # fewer trials: nothing to run
    assert result.results["timing"]["runs_this_session"] == 0
    assert {r["trial"] for r in result.runs} == {0}


def test_mixing_configurations_is_refused(general_out: Path, tmp_path: Path, new_home: str) -> None:
    out = tmp_path / "out"
    shutil.copytree(general_out, out)
    other = ExperimentConfig(**{**SMALL, "iterations": 5}, new_homes=(new_home,))
    with pytest.raises(ConfigurationError, match=r"another configuration.*iterations: 10 -> 5"):
        run_experiment(other, out, resume=True)
    with pytest.raises(ConfigurationError, match="--resume"):
        run_experiment(other, out)  # not empty, no --resume
    runner = CliRunner()
    res = runner.invoke(experiment, ["general", "--envs", "0,2", "--trials", "2", "--iterations", "10",
                                     "--models", "spcotransfer+mi", "--new-homes", new_home,
                                     "--out", str(out), "--resume", "-q"])
    assert res.exit_code == 2 and "models" in res.output and "Traceback" not in res.output
    # the opt-in name prior is another configuration too (the default's identity is the one from before)
    res = runner.invoke(experiment, ["general", "--envs", "0,2", "--trials", "2", "--iterations", "10",
                                     "--models", "spcotransfer+mi,spcoa", "--new-homes", new_home,
                                     "--out", str(out), "--resume", "-q", "--name-prior", "wordnet"])
    assert res.exit_code == 2 and "name_prior" in res.output and "Traceback" not in res.output
    # --force starts over
    result = run_experiment(other, out, force=True, max_runs=1)  # trial 0, 0 homes: no map
    assert result.results["timing"]["runs"] == 1
    assert all(r["iterations"] == 5 for r in result.runs)


def test_foreign_runs_are_refused(general_out: Path, tmp_path: Path, new_home: str) -> None:
    out = tmp_path / "out"
    shutil.copytree(general_out, out)
    with (out / "runs.jsonl").open("a") as fh:
        fh.write(json.dumps({"fingerprint": "x", "model": "spcoa", "setting": 0, "trial": 5,
                             "home": new_home}) + "\n")
    with pytest.raises(ConfigurationError, match="another configuration"):
        run_experiment(ExperimentConfig(**SMALL, new_homes=(new_home,)), out, resume=True)


# ------------------------------------------------------------------------------------ specific
def test_specific_experiment_on_synthetic_homes(tmp_path: Path) -> None:
    config = ExperimentConfig("specific", settings=(0, 100), trials=1, iterations=5, models=("spcoa",))
    result = run_experiment(config, tmp_path / "out")
    places = {r["place"] for r in result.runs} - {"mean"}
    assert places == {"emma's room", "mother's room", "father's room"}
    untaught = [r for r in result.runs if r["setting"] == 0 and r["place"] != "mean"]
    # rate 0: the word list is the rate's own, so it has no column for a name never taught: the
    # names can be neither predicted nor looked for (before, the list was the highest rate's and
    # SpCoA answered them from prior draws of θ^w)
    assert len(untaught) == 3
    assert all(r["name_accuracy"] == 0.0 and r["position_accuracy"] == 0.0 for r in untaught)
    by_rate = result.results["config"]["data"]["vocabulary_by_rate"]
    names = {"emma's room", "mother's room", "father's room"}
    assert not names & set(by_rate["0"]) and names <= set(by_rate["100"])
    # rate 100: every bedroom taught; SpCoA names them far above chance (1/|V| ~ 0.06): seed 0 gave
    # 0.967 with one random stream for all homes, 0.733 with one per home (5 sweeps only)
    taught = [r for r in result.runs if r["setting"] == 100 and r["place"] == "mean"]
    assert taught[0]["name_accuracy"] >= 0.6
    assert (tmp_path / "out" / "specific_name_accuracy.png").stat().st_size > 1000
    assert "teaching rate [%]" in result.tables


# ------------------------------------------------------------------------------------ free sentences
def test_general_experiment_on_free_sentences(tmp_path: Path, new_home: str) -> None:
    config = ExperimentConfig("general", settings=(2,), trials=1, iterations=5, models=("spcotransfer+mi",),
                              new_homes=(new_home,), language="free")
    result = run_experiment(config, tmp_path / "out")
    data = result.results["config"]["data"]
    assert data["language"] == "free" and data["source"] == "synthetic"
    assert {"living room", "bathroom"} <= set(data["vocabulary"])  # a term and a synonym
    places = {r["place"] for r in result.runs} - {"mean"}
    assert "living room" in places or "dining" in places
    # the same with the opt-in name prior (--name-prior wordnet): recorded in the configuration
    res = CliRunner().invoke(experiment, ["general", "--envs", "2", "--trials", "1", "--iterations", "5",
                                          "--models", "spcotransfer+mi", "--new-homes", new_home,
                                          "--language", "free", "--name-prior", "wordnet",
                                          "--out", str(tmp_path / "opt-in"), "-q"])
    assert res.exit_code == 0, res.output
    opt_in = json.loads((tmp_path / "opt-in" / "results.json").read_text())
    assert opt_in["config"]["hyperparameters"]["spcotransfer+mi"]["name_prior"] == "wordnet"
    assert "name_prior" not in result.results["config"]["hyperparameters"]["spcotransfer+mi"]
    with pytest.raises(ConfigurationError, match="synthetic homes only"):
        load_experiment_data(ExperimentConfig(**SMALL, data=tmp_path, language="free"))


# ------------------------------------------------------------------------------------ bad input
@pytest.mark.parametrize(("args", "message"), [
    (["--models", "spcotransfer,nope"], "unknown model"),
    (["--envs", "0,x"], "--envs must be a comma-separated list"),
    (["--envs", "1,1"], "repeated"),
    (["--envs", "-1"], "out of range"),
    (["--data", "/no/such/folder"], "no such data folder"),
    (["--regions", "/no/such/regions.json"], "region file not found"),
])
def test_bad_input_gives_a_clear_error(tmp_path: Path, args: list[str], message: str) -> None:
    res = CliRunner().invoke(experiment, ["general", "--out", str(tmp_path / "o"), "-q", *args])
    assert res.exit_code == 2, res.output
    assert message in res.output and "Traceback" not in res.output


def test_regions_file_must_cover_the_new_homes(tmp_path: Path) -> None:
    regions = tmp_path / "regions.json"
    regions.write_text(json.dumps({"homes": {"elsewhere": {"kitchen": [[0, 1, 0, 1]]}}}))
    config = ExperimentConfig(**SMALL, regions=regions)
    with pytest.raises(DataFormatError, match="no regions for new home"):
        run_experiment(config, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_parsers_and_registry() -> None:
    assert parse_int_list("16, 0,2", "--envs", 0) == (0, 2, 16)
    assert parse_models(None) == tuple(MODELS) == parse_models("all")
    assert _MODEL_NAMES == tuple(MODELS)  # the --help text lists the registry
    with pytest.raises(SpcoError):
        parse_int_list("", "--envs", 0)
    with pytest.raises(ConfigurationError, match="listed twice"):
        parse_models("spcoa,spcoa")
    assert trial_seed(3, 1) == trial_seed(3, 1) != trial_seed(3, 2)
    assert format_cell(0.5, None) == "0.500" and format_cell(None, None) == "-"
    rows = [{"k": 1, "name_accuracy": 0.5, "position_accuracy": None},
            {"k": 1, "name_accuracy": 1.0, "position_accuracy": 0.25}]
    (summary,) = summarize(rows, ("k",))
    assert summary["name_accuracy_mean"] == 0.75 and summary["n"] == 2
    assert summary["name_accuracy_std"] == pytest.approx(0.3535534)
    assert summary["position_accuracy_mean"] == 0.25 and summary["position_accuracy_std"] is None


# ------------------------------------------------------------------------------------ SIGVerse
@pytest.mark.sigverse
def test_sigverse_smoke(sigverse_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    regions = sigverse_dir.parent / "sigverse_regions.json"
    if not regions.is_file():
        pytest.skip(f"region file {regions} not found")
    out = tmp_path / "out"
    monkeypatch.chdir(sigverse_dir.parent)  # paths as a user types them, relative
    res = CliRunner().invoke(experiment, [
        "general", "--data", sigverse_dir.name, "--regions", regions.name, "--envs", "1",
        "--trials", "1", "--iterations", "3", "--models", "spcotransfer", "--new-homes", "3LDK_9",
        "--out", str(out), "-q",
    ])
    assert res.exit_code == 0, res.output
    results = json.loads((out / "results.json").read_text())
    assert results["config"]["data"]["experienced_homes"] == list(PAPER_EXPERIENCED_HOMES)
    # result files name the data as given, never as an absolute path of this machine
    assert results["config"]["data"]["source"] == sigverse_dir.name
    assert results["config"]["data"]["regions"] == regions.name
    assert f"data: {sigverse_dir.name}." in (out / "tables.md").read_text()
    assert str(sigverse_dir.parent) not in (out / "results.json").read_text()
    places = {r["place"] for r in results["runs"]} - {"mean"}
    assert len(places) == 8
    assert (out / "maps" / "general_spcotransfer_1_3LDK_9.png").stat().st_size > 1000
