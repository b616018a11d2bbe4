"""Every figure of issue 22, points 1–4, held-out beside development, in one command.

    python benchmarks/heldout_report.py [--quick] [--data ../shared/datasets/sigverse] [--out DIR]

The split is ``benchmarks/SPLIT.md``. Each part is run by its own command, whose outputs stay in
``--out/<part>`` (a re-run reuses what is there: every part resumes or reuses its models), then this
script prints one table of the headline figures, followed by each part's own tables:

1. **home-specific** (point 1): ``spco experiment specific --config`` on
   ``benchmarks/heldout/specific_heldout.json`` (held-out: 9 rooms in 4 homes, seeds 100–119) and on
   ``benchmarks/development/specific_dev.json`` (development: 19 rooms, seeds 0–9), rates 20/40/100,
   SpCoTransfer+MI and SpCoA; A_n per room with 95 % bootstrap intervals over test samples, A_p
   both ways. Targets at 40 %: mean A_n ≥ 0.9, every room above the paper's 0.45 / 0.68 / 0.50.
2. **general** (point 1, "unchanged"): ``spco experiment general`` with 16 experienced homes,
   held-out new homes 1DK_8 and 2LDK_9 (seed 100) and development new home 3LDK_9 (seed 0).
   Target ≥ 0.99 / 0.97.
3. **free speech and unheard names** (points 2–3): ``benchmarks/free_speech.py`` with the
   development and held-out speech sets (``benchmarks/development``, ``benchmarks/heldout``), when
   that script is on this branch.
4. **calibration** (point 4): ``benchmarks/calibration.py`` (its own split,
   ``benchmarks/calibration/SPLIT.md``), when that script is on this branch.

``--quick`` runs fewer seeds (home-specific: 10 held-out, 5 development, rate 40 only; general: 3
trials; the other parts their development/held-out sets as they define them) — still ≥ 10 seeds for
the held-out home-specific headline. ``--parts`` picks parts (``specific,general,speech,calibration``).
Runs use ``--jobs`` worker processes (default 1) at the lowest priority the machine allows for
this process (``nice``).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"
HELDOUT_CONFIG = BENCH / "heldout" / "specific_heldout.json"
DEV_CONFIG = BENCH / "development" / "specific_dev.json"
#: The paper's A_n at 40 % per room (Emma's, mother's, father's), the bar every room must clear.
PAPER_ROOM_BAR = 0.68
PAPER_ROOM_FIGURES = (0.45, 0.68, 0.50)
SPECIFIC_TARGET = 0.9
GENERAL_TARGET = (0.99, 0.97)
PARTS = ("specific", "general", "speech", "calibration")


def _run(cmd: Sequence[str], log: Path) -> int:
    """Run ``cmd`` (stdout and stderr to ``log``); returns its exit status."""
    log.parent.mkdir(parents=True, exist_ok=True)
    print("$ " + " ".join(shlex.quote(c) for c in cmd), flush=True)
    with log.open("w", encoding="utf-8") as fh:
        return subprocess.call(list(cmd), stdout=fh, stderr=subprocess.STDOUT, cwd=ROOT)


def _spco() -> list[str]:
    return [sys.executable, "-m", "spco"]


def _fmt(value: float | None) -> str:
    return "–" if value is None else f"{value:.3f}"


def _interval(row: dict[str, Any]) -> str:
    lo, hi = row["interval"]
    return f"{row['mean_name_accuracy']:.3f} [{lo:.3f}, {hi:.3f}]"


# ------------------------------------------------------------------------------------ parts
def specific(args: argparse.Namespace, rows: list[list[str]], tables: list[str]) -> None:
    """Home-specific names: held-out and development configuration files."""
    rates = "40" if args.quick else "20,40,100"
    runs = (("held-out", HELDOUT_CONFIG, 10 if args.quick else 20),
            ("development", DEV_CONFIG, 5 if args.quick else 10))
    results: dict[str, dict[str, Any]] = {}
    for side, config, trials in runs:
        out = args.out / f"specific_{side}"
        cmd = [*_spco(), "experiment", "specific", "--config", str(config), "--data", str(args.data),
               "--rates", rates, "--trials", str(trials), "--models", "spcotransfer+mi,spcoa",
               "--jobs", str(args.jobs), "--out", str(out), "--quiet"]
        if (out / "config.json").is_file():
            cmd.append("--resume")
        status = _run(cmd, args.out / "logs" / f"specific_{side}.log")
        path = out / "results.json"
        if status != 0 or not path.is_file():
            rows.append([f"home-specific ({side})", "failed", f"see {args.out}/logs/specific_{side}.log",
                         "", ""])
            continue
        results[side] = json.loads(path.read_text(encoding="utf-8"))
        tables.append(f"## Home-specific, {side} ({config.relative_to(ROOT)})\n\n"
                      + (out / "tables.md").read_text(encoding="utf-8"))
    for rate in (20, 40, 100):
        for model in ("spcotransfer+mi", "spcoa"):
            cells = {}
            for side, res in results.items():
                found = [r for r in res["overall"] if r["rate"] == rate and r["model"] == model]
                if found:
                    row = found[0]
                    cells[side] = (f"{_interval(row)}; worst room {row['min_room_name_accuracy']:.2f}; "
                                   f"A_p {_fmt(row['mean_position_accuracy']['argmax'])} / "
                                   f"{_fmt(row['mean_position_accuracy']['mixture'])}")
            if not cells:
                continue
            target = ""
            if rate == 40 and model == "spcotransfer+mi":
                held = [r for r in results.get("held-out", {}).get("overall", [])
                        if r["rate"] == 40 and r["model"] == model]
                if held:
                    ok = held[0]["mean_name_accuracy"] >= SPECIFIC_TARGET and \
                        held[0]["min_room_name_accuracy"] > PAPER_ROOM_BAR
                    target = (f"mean ≥ {SPECIFIC_TARGET}, every room > {PAPER_ROOM_BAR}: "
                              f"{'met' if ok else 'NOT met'}")
            rows.append([f"home-specific A_n, {rate} %, {model}", cells.get("held-out", "–"),
                         cells.get("development", "–"), target, "mean over rooms [95 % bootstrap over "
                         "test samples]; A_p most probable region / mixture"])


def general(args: argparse.Namespace, rows: list[list[str]], tables: list[str]) -> None:
    """General places with 16 experienced homes: held-out and development new homes."""
    trials = "3" if args.quick else "10"
    runs = (("held-out", "1DK_8,2LDK_9", "100"), ("development", "3LDK_9", "0"))
    for side, homes, seed in runs:
        out = args.out / f"general_{side}"
        cmd = [*_spco(), "experiment", "general", "--data", str(args.data), "--regions", str(args.regions),
               "--envs", "16", "--new-homes", homes, "--trials", trials, "--seed", seed,
               "--models", "spcotransfer+mi", "--jobs", str(args.jobs), "--out", str(out), "--quiet"]
        if (out / "config.json").is_file():
            cmd.append("--resume")
        status = _run(cmd, args.out / "logs" / f"general_{side}.log")
        path = out / "results.json"
        if status != 0 or not path.is_file():
            rows.append([f"general ({side})", "failed", f"see {args.out}/logs/general_{side}.log", "", ""])
            continue
        res = json.loads(path.read_text(encoding="utf-8"))
        mean = next(s for s in res["summary"] if s["place"] == "mean" and s["setting"] == 16)
        cell = (f"A_n {_fmt(mean['name_accuracy_mean'])}, A_p {_fmt(mean['position_accuracy_mean'])} / "
                f"{_fmt(mean.get('position_accuracy_mixture_mean'))} ({mean['n']} runs, {homes})")
        ok = (mean["name_accuracy_mean"] or 0) >= GENERAL_TARGET[0] and \
            (mean["position_accuracy_mean"] or 0) >= GENERAL_TARGET[1]
        rows.append([f"general, 16 homes ({side})", cell if side == "held-out" else "–",
                     cell if side == "development" else "–",
                     f"≥ {GENERAL_TARGET[0]} / {GENERAL_TARGET[1]}: {'met' if ok else 'NOT met'}",
                     "A_p most probable region / mixture"])
        tables.append(f"## General, {side} ({homes}, seed {seed})\n\n"
                      + (out / "tables.md").read_text(encoding="utf-8"))


def speech(args: argparse.Namespace, rows: list[list[str]], tables: list[str]) -> None:
    """Free speech and unheard names (the ``names`` work): its script, both speech sets."""
    script = BENCH / "free_speech.py"
    if not script.is_file():
        rows.append(["free speech / unheard names", "not on this branch yet", "", "A_n, A_p ≥ 0.9 (dev), "
                     "≥ 0.85 (held-out); unheard A_p ≥ 0.8", "benchmarks/free_speech.py"])
        return
    seeds = ["100", "101"] if args.quick else ["100", "101", "102"]
    dev_seeds = ["0"] if args.quick else ["0", "1", "2"]
    for side, folder, sd, suffix in (("held-out", "heldout", seeds, "heldout"),
                                     ("development", "development", dev_seeds, "dev")):
        out = args.out / f"speech_{side}.json"
        cmd = [sys.executable, str(script), "--sigverse", str(args.data), "--regions", str(args.regions),
               "--speech", str(BENCH / folder / f"speech_{suffix}.csv"),
               "--accepted", str(BENCH / folder / f"accepted_names_{suffix}.json"),
               "--unheard", str(BENCH / folder / f"unheard_names_{suffix}.json"),
               "--seeds", *sd, "--json", str(out)]
        status = _run(cmd, args.out / "logs" / f"speech_{side}.log")
        log = (args.out / "logs" / f"speech_{side}.log").read_text(encoding="utf-8")
        rows.append([f"free speech ({side})", "see below" if side == "held-out" and status == 0 else
                     ("–" if side != "held-out" else "failed"),
                     "see below" if side == "development" and status == 0 else
                     ("–" if side != "development" else "failed"), "", f"exit {status}"])
        tables.append(f"## Free speech, {side}\n\n```\n{log[-6000:]}\n```\n")


def calibration(args: argparse.Namespace, rows: list[list[str]], tables: list[str]) -> None:
    """Calibration of `what` (the ``calib`` work): its script and split."""
    script = BENCH / "calibration.py"
    if not script.is_file():
        rows.append(["calibration of what", "not on this branch yet", "", "ECE ≤ 0.05, ≤ 10 % of wrong "
                     "answers at p ≥ 0.99", "benchmarks/calibration.py"])
        return
    out = args.out / "calibration"
    cmd = [sys.executable, str(script), "--data", str(args.data), "--out", str(out), "--jobs", str(args.jobs)]
    if args.images is not None:
        cmd += ["--images", str(args.images)]
    if args.quick:
        cmd += ["--features", "fc7"]
    status = _run(cmd, args.out / "logs" / "calibration.log")
    tables_md = out / "tables.md"
    rows.append(["calibration of what", "see below" if status == 0 else "failed", "see below", "ECE ≤ 0.05, "
                 "≤ 10 % wrong at p ≥ 0.99", "benchmarks/calibration/SPLIT.md"])
    if tables_md.is_file():
        tables.append("## Calibration\n\n" + tables_md.read_text(encoding="utf-8"))


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    default_data = ROOT.parent.parent / "shared" / "datasets"
    if not default_data.is_dir():
        default_data = Path("/work/shared/datasets")
    parser.add_argument("--data", type=Path, default=default_data / "sigverse", help="the SIGVerse homes")
    parser.add_argument("--regions", type=Path, default=default_data / "sigverse_regions.json")
    parser.add_argument("--images", type=Path, default=None, help="camera images (sigverse_images/)")
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "heldout_report")
    parser.add_argument("--quick", action="store_true", help="fewer seeds and rates (see the docstring)")
    parser.add_argument("--parts", default=",".join(PARTS))
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args(argv)
    parts = [p.strip() for p in args.parts.split(",") if p.strip()]
    unknown = [p for p in parts if p not in PARTS]
    if unknown:
        parser.error(f"unknown part(s) {', '.join(unknown)}; parts: {', '.join(PARTS)}")
    if not args.data.is_dir():
        parser.error(f"{args.data}: no such data folder (--data)")
    with_nice = getattr(os, "nice", None)
    if with_nice is not None:
        with_nice(10)
    rows: list[list[str]] = []
    tables: list[str] = []
    functions = {"specific": specific, "general": general, "speech": speech, "calibration": calibration}
    for part in parts:
        functions[part](args, rows, tables)
    header = ["figure", "held-out (headline)", "development", "target", "note"]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    report = "# Held-out report (issue 22, points 1–4)\n\n" + "\n".join(lines) + "\n\n" + "\n".join(tables)
    args.out.mkdir(parents=True, exist_ok=True)
    tmp = args.out / ".report.md.tmp"
    tmp.write_text(report, encoding="utf-8")
    os.replace(tmp, args.out / "report.md")
    print(report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
