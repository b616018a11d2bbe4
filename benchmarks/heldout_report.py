"""Every headline of README.md's Results table, re-measured on the checked-out code, held-out beside
development, in one command.

    python benchmarks/heldout_report.py --dry-run --budget    # the commands and the estimated time
    python benchmarks/heldout_report.py --budget --jobs 2     # about 25 minutes on 2 quiet cores
    python benchmarks/heldout_report.py --jobs 2              # the full configurations

The split is ``benchmarks/SPLIT.md`` (read it before running). Each part runs its own script or
``spco`` command (printed before it runs, and beside its figure) on its **held-out** side, and on its
**development** side for the figure printed beside it, labelled:

=============  ================================================================================
part           held-out side (development side)
=============  ================================================================================
natural        people's own sentences (``sigverse_subject``) of the 8 held-out homes; new homes
               1LDK_9, 2LDK_9, 3LDK_9 taught nothing; ``benchmarks/natural_speech.py --side
               heldout``, seeds 100–109, 60 sweeps (development: the 8 development homes' sentences,
               new home 3LDK_9, seeds 0–4)
speech2        the independent writer's set ``benchmarks/heldout/speech2/`` taught to the paper's 16
               homes; new homes 1LDK_9, 2LDK_9, 3LDK_9 taught nothing; names nobody said
               (``unheard_names.json``); ``benchmarks/free_speech.py``, seeds 100–109, 200 sweeps
               (development: ``benchmarks/development/speech_dev.csv`` on 3LDK_9, seeds 0–2)
specific       home-specific rooms taught at 40 %: ``benchmarks/heldout/specific_heldout.json``
               (9 rooms, 4 homes), seeds 100–109 (development: ``specific_dev.json``, 19 rooms)
general        general places on new homes taught nothing: 2LDK_10, 1LDK_10 (held-out from
               2026-12-06; A_n only, they have no rectangles), ``benchmarks/general_places.py``,
               seeds 100–109 (development: 3LDK_9, seeds 0–2)
asking         ``spco experiment active``, default criterion (``errors``) and random questions:
               home-specific A_n of ``2LDK_9-kenta-nursery-piano`` after 6 answers, master seeds
               100–109, one trial each (development: 3LDK_9's bedrooms, master seeds 0–4)
calibration    ``benchmarks/calibration.py --sets held-out``: ECE and wrong answers at p ≥ 0.99 of
               ``what`` on the test views of 1LDK_9, 2LDK_9, seeds 100–109, 4/6/8/16 experienced
               homes, colour-hog and fc7 (development: 1DK_8, 3LDK_9, seeds 0–2, 4 and 8 homes)
=============  ================================================================================

Every figure is the mean over seeds with a 95 % Student-t interval over seeds (for ``asking`` each
master seed is the whole pipeline: the knowledge's fit, adapt and the questions, one trial).
``--budget`` (the lead's end-of-session run) keeps every held-out headline at 10 seeds (the full
run: natural speech, home-specific rooms and asking at 20) and the development sides smaller.
``--dry-run`` prints every command with its estimated CPU time (from development runs, never
held-out ones, ``COSTS``) and the estimated wall time on ``--jobs`` quiet cores (a machine shared
with other work takes longer in proportion). Steps run as separate processes, ``--jobs`` at a time (longest
first), each single-threaded; a step whose outputs are in ``--out`` from the same commit and command
is reused (so an interrupted run continues).

The held-out side runs only on a committed tree: the runner refuses when ``src/``, ``benchmarks/`` or
``pyproject.toml`` have uncommitted changes, and records the commit with every figure. That run is
the "once per frozen method" of SPLIT.md: a held-out figure that leads to a change of the method
makes its data spent.

Writes ``--out``/``report.json`` (format ``spco-heldout-report/2``: every figure, its seeds, its
command, the commit) and ``--out``/``report.md``: the table of README.md's Results section (paste
it there and in docs/results.md), then each part's details.
"""

from __future__ import annotations

import argparse
import datetime as dt
import heapq
import json
import math
import os
import shlex
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"
FORMAT = "spco-heldout-report/2"
PARTS = ("natural", "speech2", "specific", "general", "asking", "calibration")
SIDES = ("heldout", "development")
HELDOUT_SEEDS = tuple(range(100, 110))

#: Estimated CPU seconds (one core) of each kind of unit of work, measured on DEVELOPMENT runs only
#: (2026-12-06 06:22–06:40 UTC, this 2-core machine at a load of 9–18 from other sessions: CPU time of
#: the process and its children, user + sys; a quiet machine may be faster). ``start``: a process's
#: imports and data loading; the others one fit, run, question or task. Measured:
#: ``natural_speech.py --seeds 0 --sweeps 60`` 8.4 s (one fit of 8 + 1 homes);
#: ``free_speech.py --speech …speech_dev.csv … --seeds 0 --homes 3LDK_9`` 28.0 s (16 + 1 homes, 200
#: sweeps); ``general_places.py --seeds 0`` 18.5 s; ``spco experiment specific --config
#: …specific_dev.json --rates 40 --trials 1`` 102 s for its 6 runs; ``spco experiment active --homes
#: 3LDK_9 --strategies errors --questions 6 --rates '' --trials 1`` 19.5 s (the knowledge's fit and one
#: trial); ``calibration.py --sets development --first-seeds 1 --sizes 4`` 13.1 s and ``--sizes 8``
#: 17.9 s (colour-hog and fc7: two tasks each).
COSTS: dict[str, float] = {
    "start": 5.0,
    "natural_fit_60": 3.0,          # one fit of 8 + 1 homes, 60 sweeps, and its scoring
    "free_fit_200": 23.0,           # 16 + 1 homes, 200 sweeps, scoring and unheard names
    "general_fit_200": 13.5,        # 16 + 1 homes, 200 sweeps, scoring
    "specific_run_200": 16.0,       # 16 + 1 homes, 200 sweeps, a configuration's rooms scored
    "active_knowledge": 12.0,       # the 16 homes' knowledge, 200 sweeps (once per master seed)
    "active_question": 0.3,         # one question of one strategy: ranking, teach, scoring (+ adapt)
    "calibration_task": 1.5,        # one (views, homes, seed) task: adapting 2 new homes, answering
    "calibration_per_home": 0.6,    # fit_knowledge per experienced home of the task
}


# ------------------------------------------------------------------------------------ figures
def seed_interval(values: Sequence[float]) -> dict[str, Any] | None:
    """Mean and 95 % Student-t interval of the mean over ``values`` (one per seed or trial, NaN
    dropped), clipped to [0, 1]; ``None`` without a value."""
    finite = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    if not finite:
        return None
    n = len(finite)
    mean = sum(finite) / n
    if n < 2:
        return {"mean": mean, "low": mean, "high": mean, "n": n, "values": finite}
    from scipy import stats

    sd = math.sqrt(sum((v - mean) ** 2 for v in finite) / (n - 1))
    half = float(stats.t.ppf(0.975, n - 1)) * sd / math.sqrt(n)
    return {"mean": mean, "low": max(0.0, mean - half), "high": min(1.0, mean + half), "n": n,
            "values": finite}


def cell(fig: dict[str, Any] | None, digits: int = 3) -> str:
    """``mean [low, high]`` or ``–``."""
    if fig is None:
        return "–"
    if fig["n"] < 2:  # no interval from one seed
        return f"{fig['mean']:.{digits}f}"
    return f"{fig['mean']:.{digits}f} [{fig['low']:.{digits}f}, {fig['high']:.{digits}f}]"


# ------------------------------------------------------------------------------------ steps
@dataclass
class Step:
    """One process of the report: a part's side, its command, its outputs and its estimated cost."""

    part: str
    side: str
    argv: list[str]
    output: Path
    cpu_estimate: float
    what: str
    tag: str = ""  # tells apart the steps of one part and side (logs, markers)

    @property
    def command(self) -> str:
        """The command as typed in the repository: ``python``, paths inside it relative to it."""
        def show(word: str) -> str:
            if word == sys.executable:
                return "python"
            if word.startswith("/"):
                try:
                    return shlex.quote(str(Path(word).relative_to(ROOT)))
                except ValueError:
                    pass
            return shlex.quote(word)
        return " ".join(show(w) for w in self.argv)


@dataclass
class Plan:
    """Every step of a report and where its figures go."""

    steps: list[Step] = field(default_factory=list)


def _py(script: str) -> list[str]:
    return [sys.executable, str(BENCH / script)]


def _spco() -> list[str]:
    return [sys.executable, "-m", "spco"]


def _seeds(seeds: Sequence[int]) -> list[str]:
    return [str(s) for s in seeds]


def plan(args: argparse.Namespace) -> Plan:
    """The steps of ``args.parts`` and ``args.sides`` in the chosen mode (see the docstring)."""
    out, data, budget = args.out, args.data, args.budget
    regions = args.regions
    p = Plan()
    c = COSTS

    def add(part: str, side: str, argv: list[str], output: Path, cpu: float, what: str,
            tag: str = "") -> None:
        if part in args.parts and side in args.sides:
            p.steps.append(Step(part, side, argv, output, c["start"] + cpu, what, tag))

    # natural speech (issue 28): README's first row
    held = HELDOUT_SEEDS if budget else tuple(range(100, 120))
    add("natural", "heldout", [*_py("natural_speech.py"), "--sigverse", str(data), "--side", "heldout",
                               "--seeds", *_seeds(held), "--sweeps", "60", "--i-know-the-method-is-frozen",
                               "--json", str(out / "natural_heldout.json")],
        out / "natural_heldout.json", len(held) * 3 * c["natural_fit_60"],
        f"{len(held)} seeds × 3 new homes, 60 sweeps")
    dev = range(0, 5) if budget else range(0, 10)
    add("natural", "development", [*_py("natural_speech.py"), "--sigverse", str(data), "--seeds",
                                   *_seeds(dev), "--sweeps", "60", "--json", str(out / "natural_dev.json")],
        out / "natural_dev.json", len(dev) * c["natural_fit_60"], f"{len(dev)} seeds × 3LDK_9, 60 sweeps")

    # the independent writer's set (issue 28, held-out) and names never heard
    s2 = BENCH / "heldout" / "speech2"
    add("speech2", "heldout", [*_py("free_speech.py"), "--sigverse", str(data), "--regions", str(regions),
                               "--speech", str(s2 / "speech.csv"),
                               "--accepted", str(s2 / "accepted_names.json"),
                               "--unheard", str(s2 / "unheard_names.json"), "--seeds", *_seeds(HELDOUT_SEEDS),
                               "--json", str(out / "speech2_heldout.json")],
        out / "speech2_heldout.json", len(HELDOUT_SEEDS) * 3 * c["free_fit_200"],
        "10 seeds × 3 new homes, 200 sweeps")
    dv = BENCH / "development"
    dev = range(0, 3) if budget else range(0, 5)
    add("speech2", "development", [*_py("free_speech.py"), "--sigverse", str(data), "--regions", str(regions),
                                   "--speech", str(dv / "speech_dev.csv"),
                                   "--accepted", str(dv / "accepted_names_dev.json"),
                                   "--unheard", str(dv / "unheard_names_dev.json"), "--homes", "3LDK_9",
                                   "--seeds", *_seeds(dev), "--json", str(out / "speech2_dev.json")],
        out / "speech2_dev.json", len(dev) * c["free_fit_200"], f"{len(dev)} seeds × 3LDK_9, 200 sweeps")

    # home-specific rooms at 40 %
    for side, config, trials, rooms_configs in (
            ("heldout", BENCH / "heldout" / "specific_heldout.json", 10 if budget else 20, 4),
            ("development", BENCH / "development" / "specific_dev.json", 3 if budget else 5, 6)):
        folder = out / f"specific_{side}"
        add("specific", side, [*_spco(), "experiment", "specific", "--config", str(config),
                               "--data", str(data), "--rates", "40", "--trials", str(trials),
                               "--models", "spcotransfer+mi",
                               "--jobs", "1", "--out", str(folder), "--quiet"],
            folder / "results.json", trials * rooms_configs * c["specific_run_200"],
            f"{trials} seeds × {rooms_configs} configurations, 200 sweeps")

    # general places on new homes taught nothing
    dev = range(0, 3) if budget else range(0, 5)
    for side, seeds, homes in (("heldout", HELDOUT_SEEDS, 2), ("development", dev, 1)):
        name = f"general_{'heldout' if side == 'heldout' else 'dev'}.json"
        add("general", side, [*_py("general_places.py"), "--sigverse", str(data), "--regions", str(regions),
                              "--side", side, "--seeds", *_seeds(seeds), "--answers", "rooms",
                              "--json", str(out / name)],
            out / name, len(seeds) * homes * c["general_fit_200"],
            f"{len(seeds)} seeds × {homes} new home(s), 200 sweeps")

    # a robot that asks: the default criterion and random questions, 6 answers; one trial per master
    # seed, so that each seed is the whole pipeline (the knowledge's fit, adapt, questions)
    held = HELDOUT_SEEDS if budget else tuple(range(100, 120))
    for side, seeds, extra in (
            ("heldout", held, ["--homes", "", "--heldout", str(BENCH / "heldout" / "specific_heldout.json"),
                               "--heldout-config", "2LDK_9-kenta-nursery-piano"]),
            ("development", range(0, 5) if budget else range(0, 10), ["--homes", "3LDK_9"])):
        for seed in seeds:
            folder = out / f"asking_{side}" / f"seed{seed}"
            add("asking", side, [*_spco(), "experiment", "active", "--data", str(data),
                                 "--regions", str(regions),
                                 *extra, "--strategies", "errors,random", "--questions", "6", "--rates", "",
                                 "--trials", "1", "--seed", str(seed), "--jobs", "1", "--out", str(folder),
                                 "--quiet"],
                folder / "runs.jsonl", c["active_knowledge"] + 2 * 6 * c["active_question"],
                f"master seed {seed}: the knowledge's fit, 1 trial × 2 strategies × 6 questions",
                tag=f"_{seed}")

    # how sure `what` is, on held-out views (issue 29's configurations)
    images = ["--images", str(args.images)] if args.images else []
    feats = "colour-hog,fc7" if args.images else "fc7"
    for side, sizes, seeds in (("heldout", (4, 6, 8, 16), 10), ("development", (4, 8), 3 if budget else 5)):
        folder = out / f"calibration_{side}"
        add("calibration", side, [*_py("calibration.py"), "--data", str(data), *images,
                                  "--sets", "held-out" if side == "heldout" else "development",
                                  "--features", feats, "--sizes", ",".join(map(str, sizes)),
                                  *(["--first-seeds", str(seeds)] if side == "development" else []),
                                  "--jobs", "1", "--out", str(folder)],
            folder / "predictions.jsonl",
            len(feats.split(",")) * seeds * sum(c["calibration_task"] + s * c["calibration_per_home"]
                                                for s in sizes),
            f"{feats} × {','.join(map(str, sizes))} homes × {seeds} seeds × 2 new homes")
    return p


# ------------------------------------------------------------------------------------ running
def estimate_wall(steps: Sequence[Step], jobs: int) -> float:
    """Wall seconds of ``steps`` on ``jobs`` cores, longest first onto the first free core."""
    cores = [0.0] * max(1, jobs)
    heapq.heapify(cores)
    for step in sorted(steps, key=lambda s: -s.cpu_estimate):
        heapq.heappush(cores, heapq.heappop(cores) + step.cpu_estimate)
    return max(cores)


def git_state() -> dict[str, Any]:
    """The checked-out commit and whether the method's files have uncommitted changes."""
    def git(*a: str) -> str:
        done = subprocess.run(["git", *a], capture_output=True, text=True, check=True, cwd=ROOT)
        return done.stdout.strip()
    try:
        return {"commit": git("rev-parse", "HEAD"), "subject": git("log", "-1", "--format=%s"),
                "dirty": bool(git("status", "--porcelain", "--", "src", "benchmarks", "pyproject.toml"))}
    except (OSError, subprocess.CalledProcessError):
        return {"commit": None, "subject": None, "dirty": True}


def _marker(step: Step) -> Path:
    return step.output.parent / f".{step.part}_{step.side}{step.tag}.done.json"


def run_step(step: Step, state: dict[str, Any], logs: Path, lock: threading.Lock) -> dict[str, Any]:
    """Run one step (or reuse its outputs from the same commit and command); returns its record."""
    marker = _marker(step)
    record = {"part": step.part, "side": step.side, "command": step.command, "argv": step.argv,
              "commit": state["commit"], "cpu_estimate": round(step.cpu_estimate, 1)}
    if marker.is_file() and step.output.exists():
        old = json.loads(marker.read_text(encoding="utf-8"))
        if old.get("argv") == step.argv and old.get("commit") == state["commit"]:
            with lock:
                print(f"[reuse] {step.part} ({step.side}): {step.output}", flush=True)
            return old
    step.output.parent.mkdir(parents=True, exist_ok=True)
    log = logs / f"{step.part}_{step.side}{step.tag}.log"
    log.parent.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               MKL_NUM_THREADS="1", PYTHONUNBUFFERED="1")
    with lock:
        print(f"$ {step.command}", flush=True)
    started = time.perf_counter()
    with log.open("w", encoding="utf-8") as fh:
        proc = subprocess.Popen(step.argv, stdout=fh, stderr=subprocess.STDOUT, cwd=ROOT, env=env)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
    record.update({"exit": proc.returncode, "wall_seconds": round(time.perf_counter() - started, 1),
                   "cpu_seconds": round(usage.ru_utime + usage.ru_stime, 1), "log": str(log),
                   "finished": dt.datetime.now(dt.UTC).isoformat(timespec="seconds")})
    if proc.returncode == 0 and step.output.exists():
        tmp = marker.with_name(marker.name + ".tmp")
        tmp.write_text(json.dumps(record, indent=1), encoding="utf-8")
        os.replace(tmp, marker)
    with lock:
        print(f"[{'done' if proc.returncode == 0 else 'FAILED'}] {step.part} ({step.side}): "
              f"{record['wall_seconds']:.0f} s wall, {record['cpu_seconds']:.0f} s CPU "
              f"(estimated {step.cpu_estimate:.0f}); log {log}", flush=True)
    return record


def run_all(steps: list[Step], jobs: int, state: dict[str, Any], logs: Path) -> list[dict[str, Any]]:
    """Run ``steps`` ``jobs`` at a time, longest estimated first."""
    queue = sorted(steps, key=lambda s: -s.cpu_estimate)
    records: list[dict[str, Any]] = []
    lock = threading.Lock()

    def worker() -> None:
        while True:
            with lock:
                if not queue:
                    return
                step = queue.pop(0)
            rec = run_step(step, state, logs, lock)
            with lock:
                records.append(rec)

    threads = [threading.Thread(target=worker) for _ in range(max(1, jobs))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return records


# ------------------------------------------------------------------------------------ summaries
def _load_json(path: Path) -> Any | None:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _jsonl(path: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]


def _per_seed(runs: list[dict[str, Any]], key: str, seed_key: str = "seed",
              keep: Callable[[dict[str, Any]], bool] = lambda r: True) -> list[float]:
    """Each seed's mean of ``key`` over its runs (new homes)."""
    by: dict[Any, list[float]] = {}
    for r in runs:
        v = r.get(key)
        if keep(r) and v is not None and math.isfinite(float(v)):
            by.setdefault(r[seed_key], []).append(float(v))
    return [sum(v) / len(v) for _, v in sorted(by.items())]


def summarise_natural(out: Path) -> dict[str, Any]:
    """Natural speech: A_n, A_p per seed (mean over the new homes) on each side."""
    res: dict[str, Any] = {}
    for side, name in (("heldout", "natural_heldout.json"), ("development", "natural_dev.json")):
        d = _load_json(out / name)
        if d is not None:
            runs = [r for r in d.get("runs", []) if not str(r["home"]).endswith("(out)")]
            res[side] = {"A_n": seed_interval(_per_seed(runs, "A_n")),
                         "A_p": seed_interval(_per_seed(runs, "A_p")),
                         "homes": sorted({r["home"] for r in runs})}
    return res


def summarise_speech2(out: Path) -> dict[str, Any]:
    """Free speech with a speech set: A_n, A_p per seed; names never heard: A_p per seed."""
    res: dict[str, Any] = {}
    for side, name in (("heldout", "speech2_heldout.json"), ("development", "speech2_dev.json")):
        d = _load_json(out / name)
        if d is None:
            continue
        runs = d.get("runs", [])
        unheard = d.get("unheard_A_p_seeds")
        res[side] = {"A_n": seed_interval(_per_seed(runs, "A_n")),
                     "A_p": seed_interval(_per_seed(runs, "A_p")),
                     "unheard_A_p": seed_interval(list(unheard.values())) if unheard else None,
                     "homes": d.get("homes")}
    return res


def summarise_specific(out: Path) -> dict[str, Any]:
    """Home-specific rooms: per seed, the mean over every room of the file of its A_n (and A_p,
    most probable region); the worst room's mean over seeds."""
    res: dict[str, Any] = {}
    for side in SIDES:
        folder = out / f"specific_{side}"
        runs_file = folder / "runs.jsonl"
        if not runs_file.is_file():
            continue
        runs = _jsonl(runs_file)
        runs = [r for r in runs if r.get("model") == "spcotransfer+mi" and int(r.get("rate", 0)) == 40]
        seeds = sorted({r["seed"] for r in runs})
        a_n, a_p = [], []
        rooms: dict[str, list[float]] = {}
        for s in seeds:
            mine = [room for r in runs if r["seed"] == s for room in r["rooms"].values()]
            a_n.append(sum(room["name_accuracy"] for room in mine) / len(mine))
            ps = [room["position_accuracy"]["argmax"] for room in mine
                  if room["position_accuracy"].get("argmax") is not None]
            a_p.append(sum(ps) / len(ps) if ps else math.nan)
        for r in runs:
            for name, room in r["rooms"].items():
                rooms.setdefault(f"{r['home']} {name}", []).append(room["name_accuracy"])
        worst = min(((sum(v) / len(v), k) for k, v in rooms.items()), default=None)
        res[side] = {"A_n": seed_interval(a_n), "A_p": seed_interval(a_p), "rooms": len(rooms),
                     "worst_room": None if worst is None else {"room": worst[1], "A_n": worst[0]},
                     "per_room": {k: sum(v) / len(v) for k, v in sorted(rooms.items())}}
    return res


def summarise_general(out: Path) -> dict[str, Any]:
    """General places: the script's own figures (intervals over seeds)."""
    res: dict[str, Any] = {}
    for side, name in (("heldout", "general_heldout.json"), ("development", "general_dev.json")):
        d = _load_json(out / name)
        if d is not None:
            res[side] = {"A_n": seed_interval(d["A_n"]["seeds"]) if d.get("A_n") else None,
                         "A_p": seed_interval(d["A_p"]["seeds"]) if d.get("A_p") else None,
                         # what the robot answers (the room account, one predictor), from the same fits
                         "A_n_answer": seed_interval(d["A_n_rooms"]["seeds"]) if d.get("A_n_rooms") else None,
                         "A_p_answer": seed_interval(d["A_p_rooms"]["seeds"]) if d.get("A_p_rooms") else None,
                         "homes": d.get("homes"), "per_place": d.get("A_n_per_place")}
    return res


def summarise_asking(out: Path, k: int = 6) -> dict[str, Any]:
    """A robot that asks: home-specific A_n after ``k`` answers, by strategy, per master seed (the
    mean of its trials), with the interval over master seeds."""
    res: dict[str, Any] = {}
    for side in SIDES:
        paths = sorted((out / f"asking_{side}").glob("seed*/runs.jsonl"))
        if not paths:
            continue
        figs: dict[str, Any] = {}
        homes: set[str] = set()
        for strategy in ("errors", "random"):
            per_seed = []
            for path in paths:
                values = []
                for r in _jsonl(path):
                    homes.add(r["home"])
                    steps = [s for s in r.get("curves", {}).get(strategy, []) if s["k"] == k]
                    if steps and steps[0].get("specific_n") is not None:
                        values.append(steps[0]["specific_n"])
                if values:
                    per_seed.append(sum(values) / len(values))
            figs[strategy] = seed_interval(per_seed)
        res[side] = {"A_n": figs.get("errors"), "A_n_random": figs.get("random"), "k": k,
                     "homes": sorted(homes)}
    return res


def summarise_calibration(out: Path) -> dict[str, Any]:
    """Calibration: per configuration (views × experienced homes), pooled ECE and the share of
    wrong answers at p ≥ 0.99 over every seed, and the per-seed ECE with an interval over seeds."""
    sys.path.insert(0, str(BENCH))
    import numpy as np
    from calibration import SURE, ece

    res: dict[str, Any] = {}
    for side, folder in (("heldout", "calibration_heldout"), ("development", "calibration_development")):
        path = out / folder / "predictions.jsonl"
        if not path.is_file():
            continue
        rows = _jsonl(path)
        configs = []
        for key in sorted({(r["features"], int(r["size"])) for r in rows}):
            mine = [r for r in rows if (r["features"], int(r["size"])) == key]
            conf = np.array([r["p_after"] for r in mine])
            right = np.array([r["after"] == r["label"] for r in mine])
            wrong = ~right
            per_seed, accuracy = [], []
            for s in sorted({r["seed"] for r in mine}):
                idx = np.array([r["seed"] == s for r in mine])
                per_seed.append(ece(conf[idx], right[idx]))
                accuracy.append(float(right[idx].mean()))
            pooled = ece(conf, right)
            sure = float((conf[wrong] >= SURE).mean()) if wrong.any() else 0.0
            configs.append({"features": key[0], "size": key[1], "ece_pooled": pooled,
                            "ece_seeds": seed_interval(per_seed), "wrong": int(wrong.sum()),
                            "wrong_sure": int((conf[wrong] >= SURE).sum()), "wrong_sure_share": sure,
                            "accuracy": seed_interval(accuracy),
                            "met": pooled <= 0.05 and sure <= 0.10})
        res[side] = {"configurations": configs, "met": sum(c["met"] for c in configs), "of": len(configs)}
    return res


SUMMARIES: dict[str, Callable[[Path], dict[str, Any]]] = {
    "natural": summarise_natural, "speech2": summarise_speech2, "specific": summarise_specific,
    "general": summarise_general, "asking": summarise_asking, "calibration": summarise_calibration}


# ------------------------------------------------------------------------------------ the table
LABELS = {
    "natural": ("natural speech: people's own sentences for the 8 held-out homes "
                "(`sigverse_subject`); new `1LDK_9`, `2LDK_9`, `3LDK_9` taught nothing; 60 sweeps", "–"),
    "speech2": ("the independent writer's speech (`benchmarks/heldout/speech2/`) taught to the 16 homes; "
                "new `1LDK_9`, `2LDK_9`, `3LDK_9` taught nothing; A_p of names never heard beside", "–"),
    "specific": ("home-specific rooms taught at 40 %: 9 rooms in 4 held-out homes "
                 "(`specific_heldout.json`)", "0.54 / 0.78"),
    "general": ("general places: new homes `2LDK_10`, `1LDK_10` taught nothing (A_n only: no rectangles)",
                "0.88 / 0.86"),
    "asking": ("a robot that asks (`spco experiment active`, default criterion): home-specific rooms of "
               "`2LDK_9` after 6 answered questions", "–"),
    "calibration": ("how sure `what` is: ECE on the held-out test views of `1LDK_9`, `2LDK_9` "
                    "(4, 6, 8, 16 homes; colour-hog and fc7)", "–"),
}


def _seeds_text(fig: dict[str, Any] | None, unit: str = "seeds") -> str:
    return "" if fig is None else f", {fig['n']} {unit if fig['n'] != 1 else unit.rstrip('s')}"


def table(figures: dict[str, Any], budget: bool = False) -> tuple[list[str], str]:
    """The README Results table (one row per part, with the command that re-measures it) and its
    Markdown."""
    header = ["experiment", "held-out A_n", "held-out A_p", "development (labelled)", "paper A_n / A_p",
              "command"]
    rows = []
    for part in PARTS:
        if part not in figures:
            continue
        f = figures[part]
        h, d = f.get("heldout") or {}, f.get("development") or {}
        label, paper = LABELS[part]
        cmd = f"`python benchmarks/heldout_report.py {'--budget ' if budget else ''}--parts {part}`"
        if part == "calibration":
            confs = h.get("configurations", [])
            worst = max(confs, key=lambda c: c["ece_pooled"], default=None)
            held_n = ("–" if not confs else f"{h['met']} of {h['of']} configurations meet ECE ≤ 0.05 and "
                      f"≤ 10 % wrong at p ≥ 0.99; worst ECE {worst['ece_pooled']:.3f} ({worst['features']}, "
                      f"{worst['size']} homes)")
            held_p = "–"
            dconfs = d.get("configurations", [])
            dev = ("–" if not dconfs else "development (1DK_8, 3LDK_9): " + "; ".join(
                f"{c['features']} {c['size']}: ECE {c['ece_pooled']:.3f}" for c in dconfs))
        elif part == "asking":
            held_n = (f"**{cell(h.get('A_n'))}**{_seeds_text(h.get('A_n'))} "
                      f"(random questions {cell(h.get('A_n_random'))})") if h else "–"
            held_p = "–"
            dev = (f"development (3LDK_9's bedrooms): {cell(d.get('A_n'))}"
                   f"{_seeds_text(d.get('A_n'))}" if d else "–")
        else:
            held_n = f"**{cell(h.get('A_n'))}**{_seeds_text(h.get('A_n'))}" if h.get("A_n") else "–"
            held_p = f"**{cell(h.get('A_p'))}**" if h.get("A_p") else "–"
            if part == "speech2" and h.get("unheard_A_p"):
                held_p += f"; never heard: {cell(h['unheard_A_p'])}"
            if part == "specific" and h.get("worst_room"):
                held_n += f"; worst room {h['worst_room']['A_n']:.2f}"
            if part == "general" and h.get("A_n_answer"):
                held_n += f"; the robot's answer (room account) {cell(h['A_n_answer'])}"
            where = {"natural": "8 development homes' sentences, 3LDK_9", "speech2": "speech_dev.csv, 3LDK_9",
                     "specific": f"{d.get('rooms', 19)} development rooms", "general": "3LDK_9"}[part]
            dev = (f"development ({where}): A_n {cell(d.get('A_n'))}, A_p {cell(d.get('A_p'))}"
                   f"{_seeds_text(d.get('A_n'))}" if d else "–")
        rows.append([label, held_n, held_p, dev, paper, cmd])
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return header, "\n".join(lines)


def details(figures: dict[str, Any], records: list[dict[str, Any]]) -> str:
    """Each part's commands and its further figures, as Markdown."""
    parts = []
    for part in PARTS:
        mine = [r for r in records if r["part"] == part]
        if not mine and part not in figures:
            continue
        text = [f"### {part}", ""]
        for r in sorted(mine, key=lambda r: r["side"] != "heldout"):
            status = ("" if r.get("exit", 0) == 0 else " — not run here" if r.get("exit") is None
                      else f" — **failed** (exit {r.get('exit')}, see {r.get('log')})")
            timing = (f" ({r['wall_seconds']:.0f} s wall, {r['cpu_seconds']:.0f} s CPU)"
                      if "wall_seconds" in r else "")
            text.append(f"- {r['side']}{timing}{status}: `{r['command']}`")
        f = figures.get(part, {})
        if part == "calibration":
            for side in SIDES:
                confs = (f.get(side) or {}).get("configurations", [])
                if confs:
                    text += ["", f"| {side}: views | homes | ECE (pooled) | ECE per seed [95 % over seeds] | "
                             "accuracy [95 % over seeds] | wrong at p ≥ 0.99 | target met |",
                             "|---|---:|---:|---|---|---|---|"]
                    text += [f"| {c['features']} | {c['size']} | {c['ece_pooled']:.3f} | "
                             f"{cell(c['ece_seeds'])} | {cell(c['accuracy'])} | "
                             f"{c['wrong_sure']} of {c['wrong']} | "
                             f"{'yes' if c['met'] else 'no'} |" for c in confs]
        elif part in ("specific", "general"):
            unit = "room" if part == "specific" else "place"
            for side in SIDES:
                scores = (f.get(side) or {}).get(f"per_{unit}")
                if scores:
                    text += ["", f"{side} A_n per {unit} (mean over seeds): "
                             + ", ".join(f"{k} {v:.2f}" for k, v in scores.items())]
        parts.append("\n".join(text))
    return "\n\n".join(parts)


# ------------------------------------------------------------------------------------ main
def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The command line, checked; ``parts`` and ``sides`` as lists, the default paths filled in."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    default_data = ROOT.parent.parent / "shared" / "datasets"
    if not default_data.is_dir():
        default_data = Path("/work/shared/datasets")
    parser.add_argument("--data", type=Path, default=default_data / "sigverse", help="the SIGVerse homes")
    parser.add_argument("--regions", type=Path, default=None,
                        help="sigverse_regions.json (default: beside --data)")
    parser.add_argument("--images", type=Path, default=None,
                        help="camera images (default: sigverse_images beside --data, when there)")
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "heldout_report")
    parser.add_argument("--budget", "--quick", dest="budget", action="store_true",
                        help="the end-of-session configuration (about 25 minutes on 2 cores)")
    parser.add_argument("--parts", default=",".join(PARTS), help=f"comma-separated, of {', '.join(PARTS)}")
    parser.add_argument("--sides", default=",".join(SIDES), help="heldout, development or both")
    parser.add_argument("--jobs", type=int, default=2, help="processes at a time (each single-threaded)")
    parser.add_argument("--dry-run", action="store_true", help="print the commands and the estimated time")
    parser.add_argument("--summarise-only", action="store_true",
                        help="only read the outputs in --out and write the report")
    args = parser.parse_args(argv)
    args.parts = [p.strip() for p in args.parts.split(",") if p.strip()]
    args.sides = [s.strip() for s in args.sides.split(",") if s.strip()]
    unknown = [p for p in args.parts if p not in PARTS] + [s for s in args.sides if s not in SIDES]
    if unknown:
        parser.error(f"unknown part(s) or side(s) {', '.join(unknown)}; parts: {', '.join(PARTS)}; "
                     f"sides: {', '.join(SIDES)}")
    if args.jobs < 1:
        parser.error("--jobs: at least 1")
    args.regions = args.regions or args.data.parent / "sigverse_regions.json"
    if args.images is None and (args.data.parent / "sigverse_images").is_dir():
        args.images = args.data.parent / "sigverse_images"
    args.parser = parser
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Plan, (dry-)run, summarise, write ``report.json`` and ``report.md``."""
    args = parse_args(argv)
    parser = args.parser
    the_plan = plan(args)
    total_cpu = sum(s.cpu_estimate for s in the_plan.steps)
    wall = estimate_wall(the_plan.steps, args.jobs)
    if args.dry_run:
        print(f"{len(the_plan.steps)} steps; estimated CPU {total_cpu / 60:.1f} min, "
              f"wall {wall / 60:.1f} min on {args.jobs} quiet core(s) (estimates from development runs: "
              "COSTS in this file)\n")
        for s in the_plan.steps:
            print(f"# {s.part} ({s.side}): {s.what}; ~{s.cpu_estimate / 60:.1f} min CPU\n{s.command}\n")
        return 0
    if not args.data.is_dir():
        parser.error(f"--data {args.data}: no such folder")
    state = git_state()
    if "heldout" in args.sides and not args.summarise_only and state["dirty"]:
        parser.error("src/, benchmarks/ or pyproject.toml have uncommitted changes: a held-out figure "
                     "must be of a commit (commit first, or run --sides development)")
    args.out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    records: list[dict[str, Any]] = []
    if not args.summarise_only:
        print(f"commit {state['commit']} ({state['subject']}); {len(the_plan.steps)} steps, estimated "
              f"{wall / 60:.0f} min wall on {args.jobs} cores", flush=True)
        records = run_all(the_plan.steps, args.jobs, state, args.out / "logs")
    else:
        for s in the_plan.steps:
            m = _marker(s)
            records.append(json.loads(m.read_text(encoding="utf-8")) if m.is_file() else
                           {"part": s.part, "side": s.side, "command": s.command, "exit": None})
    figures = {part: SUMMARIES[part](args.out) for part in args.parts}
    _, md_table = table(figures, args.budget)
    report = {"format": FORMAT, "created": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
              "commit": state["commit"], "commit_subject": state["subject"], "dirty": state["dirty"],
              "budget": args.budget, "jobs": args.jobs, "split": "benchmarks/SPLIT.md",
              "wall_seconds": round(time.perf_counter() - started, 1), "steps": records, "figures": figures,
              "table": md_table}
    md = (f"# Results, re-measured (commit {str(state['commit'])[:7]}, "
          f"{report['created']})\n\nHeld-out figures: mean over seeds [95 % Student-t interval over seeds]; "
          f"development beside, labelled. Split: benchmarks/SPLIT.md.\n\n{md_table}\n\n"
          f"## Commands and details\n\n{details(figures, records)}\n")
    for name, text in (("report.json", json.dumps(report, indent=1, default=str)), ("report.md", md)):
        tmp = args.out / f".{name}.tmp"
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, args.out / name)
    print("\n" + md)
    failed = [r for r in records if r.get("exit") not in (0, None)]
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
