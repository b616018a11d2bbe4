"""``spco experiment active``: configuration, the held-out file, the summaries (intervals, first k,
"ask only when unsure"), and a tiny run on the SIGVerse data with its resume."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from spco.cli.active import active as active_command
from spco.errors import ConfigurationError, DataFormatError
from spco.evaluation.active import (
    ActiveConfig,
    first_k,
    load_active_homes,
    stop_rule_summary,
    summarise,
)

HELDOUT = Path(__file__).resolve().parents[1] / "benchmarks" / "heldout" / "specific_heldout.json"


def _record(home: str, trial: int, specific: list[float], confidence: list[float]) -> dict:
    steps = []
    for k, value in enumerate(specific):
        step = {"k": k, "specific_n": value, "specific_p": value, "general_n": 1.0, "general_p": 1.0,
                "all_n": (value + 1) / 2, "all_p": 1.0, "name": {}, "position": {}}
        if k < len(specific) - 1:
            step.update({"next": k, "next_place": "bedroom", "gain": 1.0, "confidence": confidence[k],
                         "what_confidence": 1.0, "rank_seconds": 0.01})
        steps.append(step)
    return {"home": home, "trial": trial, "curves": {"errors": steps, "random": steps},
            "references": [{"rate": 20, "k": 24, **{m: 0.9 for m in ("specific_n", "specific_p", "general_n",
                                                                       "general_p", "all_n", "all_p")}}],
            "wall_seconds": 1.0}


def test_summaries_intervals_first_k_and_stop_rule() -> None:
    records = [_record("h", 0, [0.0, 0.5, 0.9, 1.0], [0.2, 0.4, 0.95]),
               _record("h", 1, [0.0, 0.7, 0.9, 0.9], [0.3, 0.97, 0.99])]
    summary = summarise(records, ["errors", "random"])
    row = next(r for r in summary if r["strategy"] == "errors" and r["k"] == 1)
    assert row["specific_n"]["mean"] == pytest.approx(0.6)
    assert row["specific_n"]["low"] <= 0.6 <= row["specific_n"]["high"]
    assert row["specific_n"]["low"] >= 0.5 and row["specific_n"]["high"] <= 0.7
    reference = next(r for r in summary if r["strategy"].startswith("paper"))
    assert reference["k"] == 24 and reference["specific_n"]["mean"] == pytest.approx(0.9)
    assert first_k(summary)["h"] == {"errors": 2, "random": 2}
    stop = stop_rule_summary(records, "errors", thresholds=[0.9])
    # trial 0 stops before question 3 (confidence 0.95), trial 1 before question 2 (0.97)
    assert stop[0]["questions"] == pytest.approx(1.5) and stop[0]["saved"] == pytest.approx(1.5)
    assert stop[0]["specific_n_at_stop"] == pytest.approx((0.9 + 0.7) / 2)
    assert stop[0]["specific_n_all_questions"] == pytest.approx(0.95)


@pytest.mark.parametrize(("change", "message"), [
    ({"strategies": ("loudest",)}, "strategies"),
    ({"strategies": ("random", "random")}, "strategies"),
    ({"trials": 0}, "trials must be"),
    ({"questions": -1}, "questions must be"),
    ({"rates": (0,)}, "rates"),
    ({"homes": (), "heldout_configs": None}, "no new home"),
    ({"heldout_configs": ("x",)}, "--heldout"),
    ({"homes": ("1LDK_1",)}, "experienced homes too"),
])
def test_bad_configurations_name_the_option(change: dict, message: str) -> None:
    with pytest.raises(ConfigurationError, match=message):
        ActiveConfig(data="d", regions="r", **change).validated()


def test_the_heldout_file_is_read_with_clear_errors(tmp_path: Path, sigverse_dir: Path) -> None:
    regions = sigverse_dir.parent / "sigverse_regions.json"
    config = ActiveConfig(data=str(sigverse_dir), regions=str(regions), homes=(), heldout=str(HELDOUT),
                          heldout_configs=("no-such-config",), knowledge="unused")
    with pytest.raises(DataFormatError, match="no configuration 'no-such-config'"):
        load_active_homes(config)
    bogus = tmp_path / "bogus.json"
    bogus.write_text(json.dumps({"configs": []}))
    with pytest.raises(DataFormatError, match="heldout-specific"):
        load_active_homes(ActiveConfig(data=str(sigverse_dir), regions=str(regions), homes=(),
                                       heldout=str(bogus), heldout_configs=("x",), knowledge="unused"))
    _, (home,) = load_active_homes(ActiveConfig(data=str(sigverse_dir), regions=str(regions), homes=(),
                                                heldout=str(HELDOUT),
                                                heldout_configs=("2LDK_9-kenta-nursery-piano",),
                                                knowledge="unused"))
    assert home.specific == ("kenta's room", "the nursery", "the piano room")
    assert "bedroom" not in home.general and "living room" not in home.general
    oracle = home.oracle_of(3)
    assert "kenta" in oracle[20] and oracle == home.oracle_of(3)  # a trial's draw is stable
    taught = home.references[20](0)
    assert len(taught) == 12 and all(i in oracle for i in taught)


def test_3ldk9_oracle_says_the_bedrooms_own_names(sigverse_dir: Path) -> None:
    regions = sigverse_dir.parent / "sigverse_regions.json"
    _, (home,) = load_active_homes(ActiveConfig(data=str(sigverse_dir), regions=str(regions),
                                                homes=("3LDK_9",), knowledge="unused"))
    assert set(home.specific) == {"emma's room", "mother's room", "father's room"}
    assert "emma's" in home.oracle[20].lower() and home.oracle[0] == "this is the entrance"
    assert all(int(i) in home.oracle for i in home.home.ids[~home.home.is_test])
    assert len(home.test_labels) == 100 and home.label_of(20) == "emma's room"
    assert sorted(home.references) == [20, 40] and len(home.references[20](0)) == 24


def test_a_tiny_run_writes_its_results_and_resumes(tmp_path: Path, sigverse_dir: Path) -> None:
    from spco import knowledge as kn
    from spco.data.environment import Corpus
    from spco.data.loading import load_homes

    knowledge_file = tmp_path / "k.spco"
    homes = load_homes(sigverse_dir, names=["3LDK_1", "1LDK_8"])
    kn.fit_knowledge(Corpus(homes), n_iterations=4,
                     random_state=0).save(knowledge_file)
    regions = sigverse_dir.parent / "sigverse_regions.json"
    out = tmp_path / "out"
    args = ["--data", sigverse_dir, "--regions", regions, "--homes", "3LDK_9",
            "--strategies", "errors,random", "--questions", "1", "--trials", "1", "--adapt-iterations", "2",
            "--teach-sweeps", "1", "--rates", "", "--knowledge", knowledge_file, "--out", out, "-q"]
    result = CliRunner().invoke(active_command, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    results = json.loads((out / "results.json").read_text())
    assert results["format"] == "spco-active-results" and results["timing"]["runs"] == 1
    steps = [r for r in results["summary"] if r["strategy"] == "errors"]
    assert [r["k"] for r in steps] == [0, 1] and steps[0]["specific_n"] is not None  # 3LDK_9's bedrooms
    assert steps[0]["general_n"] is not None
    assert (out / "tables.md").is_file() and (out / "active_3LDK_9.png").is_file()
    assert results["ranking_seconds"]["max"] < 1.0
    again = CliRunner().invoke(active_command, [str(a) for a in args])
    assert again.exit_code == 2 and "--resume" in again.output
    more = CliRunner().invoke(active_command, [str(a) for a in [*args, "--resume", "--trials", "2"]])
    assert more.exit_code == 0, more.output
    lines = (out / "runs.jsonl").read_text().splitlines()
    assert len(lines) == 2 and json.loads(lines[0]) == json.loads(lines[0])
    first = json.loads(lines[0])
    assert first["curves"]["errors"][1]["k"] == 1 and np.isfinite(first["curves"]["errors"][0]["gain"])
