"""The home-specific experiment on a configuration file (``spco experiment specific --config``):
the file's checks, its teaching draw, name normalisation, the bootstrap interval, the summaries,
and one SIGVerse run on a held-out configuration."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from spco.cli.experiment import experiment
from spco.data.language import normalize_name
from spco.errors import DataFormatError
from spco.evaluation.specific_config import (
    ConfiguredData,
    ConfiguredRun,
    bootstrap_interval,
    execute_configured_run,
    load_specific_config,
    normalize_phrase,
    summarise,
    taught_count,
    teaching_sentences,
)

ROOT = Path(__file__).resolve().parents[1]
HELDOUT = ROOT / "benchmarks" / "heldout" / "specific_heldout.json"
DEVELOPMENT = ROOT / "benchmarks" / "development" / "specific_dev.json"
#: the harder development configurations (renamed rooms sharing a concept, names holding the general name)
DEVELOPMENT_HARD = ROOT / "benchmarks" / "development" / "specific_dev_hard.json"


def _small(tmp_path: Path, **changes: object) -> Path:
    """A one-configuration file in the format, with ``changes`` applied to the top level."""
    room = {"name": "the study", "form": "single-word", "owner": None, "replaces": "bedroom",
            "accepted": ["study"], "train_ids": list(range(10)), "test_ids": [10, 11],
            "taught_count": {"20": 2, "40": 4, "100": 10}, "region": [[0, 1, 0, 1]]}
    owner = dict(room, name="kim's room", owner="kim", accepted=["kim's room", "kim"],
                 train_ids=list(range(20, 30)), test_ids=[30], region=None)
    data = {"_format": "heldout-specific/1", "templates": ["this is {name}", "{name}"],
            "possessive_templates": ["{owner} sleeps here"], "teaching_rates": [20, 40, 100],
            "seeds": [5, 6], "experienced_homes": ["a", "b"],
            "configs": [{"id": "c1", "home": "h", "test_source": "defined-here", "rooms": [room, owner]}]}
    data.update(changes)
    path = tmp_path / "config.json"
    path.write_text(json.dumps(data))
    return path


def test_the_project_files_read_and_keep_the_split() -> None:
    held = load_specific_config(HELDOUT)
    dev = load_specific_config(DEVELOPMENT)
    assert len(held.configurations) == 4 and sum(len(c.rooms) for c in held.configurations) == 9
    assert held.seeds == tuple(range(100, 120)) and set(dev.seeds) <= set(range(100))
    held_homes = {c.home for c in held.configurations}
    dev_homes = {c.home for c in dev.configurations}
    assert not held_homes & dev_homes  # no home is on both sides of benchmarks/SPLIT.md
    assert not {"3LDK_9", "3LDK_9_original", "3LDK_9_100data"} & held_homes
    hard = load_specific_config(DEVELOPMENT_HARD)
    assert set(hard.seeds) <= set(range(100)) and len(hard.configurations) == 7
    # development or knowledge homes only: none held out, nor the calibration's held-out 1LDK_9
    assert not {c.home for c in hard.configurations} & (held_homes | {"1LDK_9"})


def test_teaching_draw_follows_the_files_rule(tmp_path: Path) -> None:
    file = load_specific_config(_small(tmp_path))
    conf = file.configurations[0]
    taught = teaching_sentences(file, conf, 40, 5)
    assert taught == teaching_sentences(file, conf, 40, 5)  # same seed, same draw
    assert taught != teaching_sentences(file, conf, 40, 6)
    study = [i for i in taught if i < 10]
    kim = [i for i in taught if 20 <= i < 30]
    assert len(study) == 4 and len(kim) == 4  # the file's counts at 40 %
    # the rule: rng.choice per room in order, then a template index per drawn id
    rng = np.random.default_rng(5)
    drawn = rng.choice(np.arange(10), size=4, replace=False)
    assert list(taught)[:4] == [int(i) for i in drawn]
    assert all(taught[i] in ("this is the study", "the study") for i in study)
    assert all(taught[i] in ("this is kim's room", "kim's room", "kim sleeps here") for i in kim)
    assert taught_count(40, 14) == 6 and taught_count(20, 14) == 3 and taught_count(0, 20) == 0


@pytest.mark.parametrize(("changes", "message"), [
    ({"_format": "x/1"}, "_format: expected"),
    ({"seeds": [1, 1]}, "seeds: must be a non-empty list of distinct"),
    ({"templates": ["no placeholder"]}, "holds neither"),
    ({"teaching_rates": [40, 150]}, "teaching_rates"),
])
def test_bad_files_give_one_clear_error(tmp_path: Path, changes: dict, message: str) -> None:
    with pytest.raises(DataFormatError, match=message):
        load_specific_config(_small(tmp_path, **changes))


def test_bad_rooms_name_the_field(tmp_path: Path) -> None:
    raw = json.loads(_small(tmp_path).read_text())
    raw["configs"][0]["rooms"][0]["taught_count"]["40"] = 5  # the rule gives 4 of 10
    (tmp_path / "b.json").write_text(json.dumps(raw))
    with pytest.raises(DataFormatError, match=r"configs\[0\]\.rooms\[0\]\.taught_count: rate 40"):
        load_specific_config(tmp_path / "b.json")
    raw["configs"][0]["rooms"][0]["taught_count"]["40"] = 4
    raw["configs"][0]["rooms"][1]["train_ids"] = [5, *range(21, 30)]  # sample 5 is the study's
    (tmp_path / "b.json").write_text(json.dumps(raw))
    with pytest.raises(DataFormatError, match="sample 5 belongs to 'the study' and \"kim's room\""):
        load_specific_config(tmp_path / "b.json")
    with pytest.raises(DataFormatError, match="cannot read"):
        load_specific_config(tmp_path / "missing.json")


def test_names_are_compared_as_the_files_say() -> None:
    assert normalize_phrase("The Nursery") == "nursery"
    assert normalize_phrase("my  Kim's_room") == "kim's room"
    assert normalize_phrase("the") == "the"  # a lone article stays (and names nothing)
    assert normalize_phrase("piano-room") == "piano room"
    # a plural possessive as the tokenizer writes it: the robot's "kids bedroom" is "the kids' bedroom"
    assert normalize_phrase("the kids' bedroom") == normalize_phrase("Kids\u2019 bedroom") == "kids bedroom"
    assert normalize_phrase("the kids' bedroom") == normalize_name("the kids' bedroom").removeprefix("the ")
    assert normalize_phrase("grandpa's study") == "grandpa's study"  # a singular possessive keeps its 's


def test_bootstrap_interval_covers_the_mean_and_narrows_with_samples() -> None:
    rng = np.random.default_rng(0)
    small = [rng.random(10) < 0.7, rng.random(6) < 0.4]
    large = [np.repeat(s, 20) for s in small]
    lo, hi = bootstrap_interval([s.astype(float) for s in small])
    mean = np.mean([s.mean() for s in small])
    assert lo <= mean <= hi and hi - lo > 0.1
    lo2, hi2 = bootstrap_interval([s.astype(float) for s in large])
    assert lo2 <= mean <= hi2 and hi2 - lo2 < (hi - lo) / 2
    assert bootstrap_interval([np.ones(5)]) == (1.0, 1.0)


def test_bootstrap_interval_resamples_seeds() -> None:
    """A room right at every test sample in 9 seeds and wrong everywhere in one: the interval over
    seeds and samples reaches well below the mean (averaging the seeds first gave [0.9, 0.9]), and
    resampling rooms widens the interval of a mean over unlike rooms."""
    one_bad_seed = np.ones((10, 20))
    one_bad_seed[3] = 0.0
    lo, hi = bootstrap_interval([one_bad_seed])
    assert lo <= 0.75 and hi == 1.0
    assert np.allclose(bootstrap_interval([one_bad_seed.mean(axis=0)]), 0.9)  # one row: seeds averaged
    unlike = [np.ones((3, 10)), np.zeros((3, 10)), np.ones((3, 10))]
    fixed = bootstrap_interval(unlike)
    assert fixed[0] == fixed[1]
    lo_r, hi_r = bootstrap_interval(unlike, rooms=True)
    assert lo_r < 0.5 and hi_r == 1.0


def test_summary_pools_seeds_per_test_sample(tmp_path: Path) -> None:
    file = load_specific_config(_small(tmp_path))
    unscored = {"argmax": None, "mixture": None}
    records = [{"configuration": "c1", "rate": 40, "model": "m", "seed": s,
                "rooms": {"the study": {"correct": c, "position_accuracy": {"argmax": 1.0, "mixture": 0.5}},
                          "kim's room": {"correct": [k], "position_accuracy": unscored}}}
               for s, c, k in ((5, [1, 0], 1), (6, [1, 1], 0))]
    result = summarise(records, file)
    (group,) = result["summary"]
    study, kim = group["rooms"]
    assert study["name_accuracy"] == 0.75 and kim["name_accuracy"] == 0.5
    assert study["seed_min"] == 0.5 and group["mean_name_accuracy"] == 0.625
    assert study["position_accuracy"] == {"argmax": 1.0, "mixture": 0.5}
    assert kim["position_accuracy"] == {"argmax": None, "mixture": None}
    (overall,) = result["overall"]
    assert overall["rooms"] == 2 and overall["min_room_name_accuracy"] == 0.5


def test_cli_refuses_options_that_do_not_apply(tmp_path: Path) -> None:
    res = CliRunner().invoke(experiment, ["specific", "--config", str(HELDOUT), "--data", str(tmp_path),
                                          "--seed", "3", "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "--seed cannot be used with --config" in res.output
    res = CliRunner().invoke(experiment, ["specific", "--seeds", "1", "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "only apply with --config" in res.output
    res = CliRunner().invoke(experiment, ["specific", "--set", "target=power", "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "--set" in res.output and "only apply with --config" in res.output
    res = CliRunner().invoke(experiment, ["specific", "--config", str(HELDOUT), "--data", str(tmp_path),
                                          "--set", "visual_prior=sometimes", "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "visual_prior" in res.output


def test_set_reaches_the_models_and_the_identity(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--set`` gives every run the hyperparameters on top of the paper's, and the experiment's
    identity (config.json) records them: a resume at other settings is refused."""
    import spco.evaluation.specific_config as sc

    seen = []

    class Stop(Exception):
        pass

    def fake_run(data, key, iterations, n_positions, fingerprint="", hyperparameters=None):
        seen.append(hyperparameters)
        raise Stop

    monkeypatch.setattr(sc, "ConfiguredData", lambda *args, **kwargs: None)
    monkeypatch.setattr(sc, "execute_configured_run", fake_run)
    out = tmp_path / "o"
    res = CliRunner().invoke(experiment, ["specific", "--config", str(_small(tmp_path)),
                                          "--data", str(tmp_path), "--set", "target=power",
                                          "--set", "visual_prior=estimate", "--out", str(out)])
    assert isinstance(res.exception, Stop), res.output
    assert seen[0].target == "power" and seen[0].visual_prior == "estimate" and seen[0].delta_word == 1e4
    identity = json.loads((out / "config.json").read_text())["identity"]
    assert identity["hyperparameters"]["visual_prior"] == "estimate"


# ------------------------------------------------------------------------------------ SIGVerse
@pytest.mark.sigverse
def test_development_rooms_are_named_at_40_percent(sigverse_dir: Path) -> None:
    """One trial of the first development configuration (3LDK_9: Emma's, mother's and father's
    rooms), development seed 0, 40 % taught, the protocol's 200 sweeps: the run is complete and its
    rooms are named far above chance. A floor, not a figure (the figures are `spco experiment
    specific`'s, over seeds); a unit test scores no held-out configuration (benchmarks/SPLIT.md) —
    this test scored the held-out 2LDK_9 configuration (seed 100) before issue 29."""
    file = load_specific_config(DEVELOPMENT)
    conf = file.configurations[0]
    data = ConfiguredData(file, str(sigverse_dir), (conf,))
    record = execute_configured_run(data, ConfiguredRun(conf.id, 40, 0, "spcotransfer+mi"), 200, 10)
    accuracy = {room: r["name_accuracy"] for room, r in record["rooms"].items()}
    assert record["taught"] > 0 and record["vocabulary_size"] > 18
    assert set(accuracy) == {room.name for room in conf.rooms}
    assert np.mean(list(accuracy.values())) >= 0.5, accuracy
