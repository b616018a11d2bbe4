"""``benchmarks/heldout_report.py``: its plan (every README headline, held-out seeds on the held-out
side only), its time estimate, its intervals over seeds and its table — on output files written
here, so nothing is fitted or scored."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def report():
    spec = importlib.util.spec_from_file_location("heldout_report", ROOT / "benchmarks" / "heldout_report.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["heldout_report"] = module
    spec.loader.exec_module(module)
    return module


def _seeds_of(argv: list[str]) -> list[int]:
    out = []
    for flag in ("--seeds", "--seed"):
        if flag in argv:
            i = argv.index(flag) + 1
            while i < len(argv) and argv[i].isdigit():
                out.append(int(argv[i]))
                i += 1
    return out


def test_every_part_has_both_sides_and_each_side_its_own_seeds(report, tmp_path: Path,
                                                               capsys: pytest.CaptureFixture) -> None:
    assert report.main(["--dry-run", "--budget", "--data", str(tmp_path), "--out", str(tmp_path / "o")]) == 0
    text = capsys.readouterr().out
    args = report.parse_args(["--budget", "--data", str(tmp_path), "--out", str(tmp_path / "o")])
    steps = report.plan(args).steps
    assert {(s.part, s.side) for s in steps} == {(p, s) for p in report.PARTS for s in report.SIDES}
    for step in steps:
        assert step.command in text and step.cpu_estimate > 0
        seeds = _seeds_of(step.argv)
        if step.part == "calibration":  # seeds from the script's own split, by set
            expected = "held-out" if step.side == "heldout" else step.side
            assert step.argv[step.argv.index("--sets") + 1] == expected
            continue
        if "--trials" in step.argv and not seeds:
            continue  # seeds from the configuration file (specific_heldout.json: 100–119)
        held = [s for s in seeds if 100 <= s <= 119]
        if step.side == "heldout":
            assert seeds and held == seeds, step.command
        else:
            assert seeds and not held, step.command
    natural = next(s for s in steps if s.part == "natural" and s.side == "heldout")
    assert len(_seeds_of(natural.argv)) >= 10 and "--side" in natural.argv
    asking = next(s for s in steps if s.part == "asking" and s.side == "heldout")
    assert asking.argv[asking.argv.index("--homes") + 1] == ""  # no general places of spent homes
    assert "estimated CPU" in text


def test_wall_estimate_puts_the_longest_step_first(report) -> None:
    steps = [report.Step("a", "heldout", [], Path("x"), c, "") for c in (10.0, 6.0, 4.0, 3.0)]
    assert report.estimate_wall(steps, 1) == 23.0
    assert report.estimate_wall(steps, 2) == 13.0  # 10 + 3 | 6 + 4


def test_seed_interval_is_over_seeds(report) -> None:
    fig = report.seed_interval([0.5, 0.7, 0.9, float("nan")])
    assert fig["n"] == 3 and fig["mean"] == pytest.approx(0.7)
    assert fig["low"] == pytest.approx(0.7 - 4.302653 * 0.2 / 3 ** 0.5, abs=1e-4)  # t(0.975, 2)
    assert fig["high"] == 1.0  # clipped
    assert report.seed_interval([]) is None
    assert report.seed_interval([0.4])["low"] == 0.4


def test_summaries_and_table_from_output_files(report, tmp_path: Path) -> None:
    runs = [{"seed": s, "home": h, "A_n": a, "A_p": a - 0.1} for s, a in ((100, 0.6), (101, 0.8))
            for h in ("1LDK_9", "2LDK_9")]
    (tmp_path / "natural_heldout.json").write_text(json.dumps({"runs": runs}))
    (tmp_path / "speech2_heldout.json").write_text(json.dumps({"runs": runs, "homes": ["1LDK_9", "2LDK_9"],
                                                             "unheard_A_p_seeds": {"100": 0.5, "101": 0.7}}))
    folder = tmp_path / "specific_heldout"
    folder.mkdir()
    rec = {"model": "spcotransfer+mi", "rate": 40, "home": "2LDK_10"}
    no_region = {"argmax": None}
    rows = [dict(rec, seed=s, rooms={"office": {"name_accuracy": v, "position_accuracy": no_region},
                                     "grandma": {"name_accuracy": 1.0, "position_accuracy": no_region}})
            for s, v in ((100, 0.0), (101, 1.0))]
    (folder / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    natural = report.summarise_natural(tmp_path)["heldout"]
    assert natural["A_n"]["values"] == [0.6, 0.8] and natural["A_p"]["mean"] == pytest.approx(0.6)
    speech = report.summarise_speech2(tmp_path)["heldout"]
    assert speech["unheard_A_p"]["mean"] == pytest.approx(0.6)
    specific = report.summarise_specific(tmp_path)["heldout"]
    assert specific["A_n"]["values"] == [0.5, 1.0]  # a seed at 0 in one room widens the interval
    assert specific["worst_room"] == {"room": "2LDK_10 office", "A_n": 0.5} and specific["A_p"] is None
    _, md = report.table({"natural": report.summarise_natural(tmp_path),
                          "specific": report.summarise_specific(tmp_path)}, budget=True)
    lines = md.splitlines()
    assert lines[0].startswith("| experiment | held-out A_n | held-out A_p | development (labelled)")
    assert "--budget --parts natural" in lines[2] and "0.700 [" in lines[2] and "2 seeds" in lines[2]
    assert "worst room 0.50" in lines[3]


def test_held_out_side_refuses_uncommitted_changes(report, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(report, "git_state", lambda: {"commit": "x", "subject": "s", "dirty": True})
    with pytest.raises(SystemExit) as exc:
        report.main(["--data", str(tmp_path), "--out", str(tmp_path / "o"), "--parts", "natural"])
    assert exc.value.code == 2
