"""A first run and a warm one of ``spco demo``, and a fit's sweep time per home, for one or more
source trees side by side (this code against a previous release's).

    python benchmarks/first_run.py --code this=src --code previous=/tmp/spco-previous/src
    python benchmarks/first_run.py --code this=src --repeats 3 --skip-sweeps
    python benchmarks/first_run.py --code this=src --code previous=OLD/src --skip-demo --homes 1 16 4096

A previous release's tree: ``git archive 8119f5b | tar -x -C /tmp/spco-previous``.

**Demo.** For each repeat and each tree in turn (A B A B …): ``python -m spco demo`` with an empty
``SPCO_CACHE_DIR`` (the first run: compiling the kernels included), then again with the same
cache (the warm run). Each run is a fresh process; its wall time and its CPU time (user + system
of the process and of every process it started and waited for, such as the second compiling
process) are read from the operating system (``os.wait4``), with the load average (1 min) before
it. The machine may be shared: compare CPU times, and trees within one repeat.

**Sweeps.** For each number of experienced homes (``--homes``, one new home added to each, as in
``run_scaling.py``) one synthetic corpus (``spco.benchmark.synthetic_corpus``, D ``--features``)
is generated and pickled once; for each tree a fresh process loads it, starts a fit as
``SpCoTransfer`` does (``spco.model.driver.start_run``, word pruning on: the "+MI" model of the
demo and the experiments), runs ``--warmup`` sweeps, then times ``--sweeps`` (wall and process CPU,
all threads). Reported per home: the median sweep over the number of homes.

Progress on stderr; the tables (or ``--json``) on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]

#: What a tree's process runs to time sweeps (argv: corpus pickle, warm-up sweeps, timed sweeps, seed).
_SWEEP_CHILD = """
import json, pickle, sys, time
import numpy as np
from spco.model import gibbs
from spco.model.driver import start_run
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.transfer import SpCoTransfer
with open(sys.argv[1], "rb") as fh:
    corpus = pickle.load(fh)
warmup, sweeps, seed = int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
import os
hyper = TransferHyperparameters(**json.loads(os.environ.get("SPCO_SWEEP_HYPER") or "{}"))
settings = gibbs.SamplerSettings.create("exact", prune=True)
prepare = (getattr(gibbs.PreparedData, "from_corpus", None)  # (before: SpCoTransfer.prepare_data,
           or getattr(SpCoTransfer, "prepare_data", None) or SpCoTransfer._prepare)  # 8119f5b: _prepare)
data = prepare(corpus, 1.0)
run = start_run(None, data, len(corpus.vocabulary), hyper, settings, np.random.default_rng(seed))
for i in range(warmup):
    run.sweep(i)
wall, cpu = [], []
for i in range(warmup, warmup + sweeps):
    c, t = time.process_time(), time.perf_counter()
    run.sweep(i)
    wall.append(time.perf_counter() - t)
    cpu.append(time.process_time() - c)
run.close()
print(json.dumps({"wall": wall, "cpu": cpu}))
"""


def log(message: str) -> None:
    """Progress on stderr."""
    print(message, file=sys.stderr, flush=True)


def run_process(command: list[str], env: dict[str, str]) -> dict[str, Any]:
    """Run ``command`` to its end; its wall seconds, CPU seconds (user + system, waited-for
    descendants included), exit status, load average before, and stdout."""
    load = os.getloadavg()[0]
    start = time.perf_counter()
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen(command, env=env, stdout=out, stderr=subprocess.DEVNULL)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        stdout = out.read().decode(errors="replace")
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime, "user": usage.ru_utime,
            "status": proc.returncode, "load": load, "stdout": stdout}


def tree_env(src: Path, cache: Path | None = None, hyper: str | None = None) -> dict[str, str]:
    """The environment of a process running the sources in ``src`` (``hyper``: JSON of the sweep
    child's :class:`TransferHyperparameters` fields)."""
    env = dict(os.environ)
    env.pop("SPCO_SWEEP_HYPER", None)
    if hyper:
        env["SPCO_SWEEP_HYPER"] = hyper
    env["PYTHONPATH"] = str(src)
    env.pop("NUMBA_CACHE_DIR", None)
    if cache is not None:
        env["SPCO_CACHE_DIR"] = str(cache)
    return env


def demo_runs(trees: dict[str, Path], repeats: int) -> list[dict[str, Any]]:
    """First and warm ``spco demo`` of every tree, ``repeats`` rounds, trees alternating."""
    rows = []
    for r in range(repeats):
        for name, src in trees.items():
            with tempfile.TemporaryDirectory(prefix="spco-first-run-") as tmp:
                cache, out = Path(tmp) / "cache", Path(tmp) / "out"
                command = [sys.executable, "-m", "spco", "demo", "--out", str(out)]
                first = run_process(command, tree_env(src, cache))
                warm = run_process(command, tree_env(src, cache))
            for kind, result in (("first", first), ("warm", warm)):
                if result["status"] != 0:
                    raise RuntimeError(f"spco demo ({name}, {kind}) exited with status {result['status']}")
            log(f"round {r + 1}, {name}: first {first['wall']:.1f} s wall / {first['cpu']:.1f} s CPU "
                f"(load {first['load']:.1f}), warm {warm['wall']:.1f} s / {warm['cpu']:.1f} s "
                f"(load {warm['load']:.1f})")
            rows.append({"round": r + 1, "tree": name, "first": _strip(first), "warm": _strip(warm)})
    return rows


def _strip(result: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in result.items() if k != "stdout"}


def sweep_runs(trees: dict[str, Path], homes: list[int], features: int, warmup: int, sweeps: int,
               seed: int, corpora: Path | None = None,
               hypers: dict[str, str] | None = None) -> list[dict[str, Any]]:
    """Sweep time per home of every tree for each number of experienced homes. With ``corpora`` (a
    folder) the generated corpora are kept there and read back when present (the 4,096-home corpus
    takes minutes to generate). ``hypers``: per tree, JSON of the sweep's hyperparameters."""
    hypers = hypers or {}
    sys.path.insert(0, str(next(iter(trees.values()))))
    from spco import benchmark

    rows = []
    with tempfile.TemporaryDirectory(prefix="spco-sweeps-") as tmp:
        for n in homes:
            start = time.perf_counter()
            folder = corpora if corpora is not None else Path(tmp)
            folder.mkdir(parents=True, exist_ok=True)
            path = folder / f"corpus-{n}-d{features}-seed{seed}.pickle"
            if path.is_file():
                n_fit = n + 1
                log(f"{n} + 1 homes (D = {features}): read from {path}")
            else:
                corpus = benchmark.synthetic_corpus(n, 1, n_features=features, seed=seed)
                partial = path.with_suffix(".partial")
                with open(partial, "wb") as fh:
                    pickle.dump(corpus, fh, protocol=pickle.HIGHEST_PROTOCOL)
                partial.replace(path)
                n_fit = len(corpus)
                del corpus
                log(f"{n} + 1 homes (D = {features}): generated in {time.perf_counter() - start:.0f} s")
            for name, src in trees.items():
                command = [sys.executable, "-c", _SWEEP_CHILD, str(path), str(warmup), str(sweeps), str(seed)]
                cache = Path(tmp) / f"cache-{name}"  # compiled by the first size's warm-up sweeps
                result = run_process(command, tree_env(src, cache, hypers.get(name)))
                if result["status"] != 0:
                    raise RuntimeError(f"the sweep process of {name} ({n} homes) exited with status "
                                       f"{result['status']}")
                timed = json.loads(result["stdout"].strip().splitlines()[-1])
                row = {"tree": name, "experienced": n, "homes": n_fit, "load": result["load"],
                       "wall_per_home": statistics.median(timed["wall"]) / n_fit,
                       "cpu_per_home": statistics.median(timed["cpu"]) / n_fit,
                       "wall": timed["wall"], "cpu": timed["cpu"]}
                log(f"  {name}: {row['wall_per_home'] * 1e3:.2f} ms wall, {row['cpu_per_home'] * 1e3:.2f} ms "
                    f"CPU per home and sweep (load {row['load']:.1f})")
                rows.append(row)
    return rows


def demo_table(rows: list[dict[str, Any]], trees: list[str]) -> str:
    """Markdown: per tree the median first and warm wall and CPU, and per round the ratios."""
    lines = ["| tree | runs | first: wall | first: CPU | warm: wall | warm: CPU | load before (range) |",
             "|---|---|---|---|---|---|---|"]
    for name in trees:
        mine = [r for r in rows if r["tree"] == name]
        loads = [r[k]["load"] for r in mine for k in ("first", "warm")]
        med = {f"{k}_{m}": statistics.median(r[k][m] for r in mine) for k in ("first", "warm")
               for m in ("wall", "cpu")}
        lines.append(f"| {name} | {len(mine)} | {med['first_wall']:.1f} s | {med['first_cpu']:.1f} s | "
                     f"{med['warm_wall']:.1f} s | {med['warm_cpu']:.1f} s | "
                     f"{min(loads):.1f}–{max(loads):.1f} |")
    if len(trees) >= 2:
        a, b = trees[1], trees[0]
        lines += ["", f"Ratios {a} / {b}, round by round (CPU): "
                  + "; ".join(f"first {_ratio(rows, r, a, b, 'first')}, warm {_ratio(rows, r, a, b, 'warm')}"
                              for r in sorted({x['round'] for x in rows}))]
    return "\n".join(lines)


def _ratio(rows: list[dict[str, Any]], round_: int, a: str, b: str, kind: str) -> str:
    ra = next(r for r in rows if r["round"] == round_ and r["tree"] == a)
    rb = next(r for r in rows if r["round"] == round_ and r["tree"] == b)
    return f"{ra[kind]['cpu'] / rb[kind]['cpu']:.2f}"


def sweep_table(rows: list[dict[str, Any]], trees: list[str]) -> str:
    """Markdown: per number of homes, each tree's ms per home and sweep (wall, CPU)."""
    header = "| experienced homes (+1 new) | " + " | ".join(
        f"{t}: wall | {t}: CPU" for t in trees) + (f" | CPU {trees[0]} / {trees[1]}" if len(trees) >= 2 else
                                                   " | –") + " | load |"
    lines = [header, "|" + "---|" * (2 + 2 * len(trees) + 1)]
    for n in sorted({r["experienced"] for r in rows}):
        mine = {r["tree"]: r for r in rows if r["experienced"] == n}
        cells = " | ".join(f"{mine[t]['wall_per_home'] * 1e3:.2f} ms | {mine[t]['cpu_per_home'] * 1e3:.2f} ms"
                           for t in trees)
        ratio = (f"{mine[trees[0]]['cpu_per_home'] / mine[trees[1]]['cpu_per_home']:.2f}"
                 if len(trees) >= 2 else "–")
        loads = "–".join(f"{mine[t]['load']:.1f}" for t in trees)
        lines.append(f"| {n} | {cells} | {ratio} | {loads} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print its tables (or JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--code", action="append", default=[], metavar="NAME=SRC",
                        help="a source tree to run (its src folder); repeat to compare (default: this=src)")
    parser.add_argument("--repeats", type=int, default=2, help="rounds of first + warm demo runs per tree")
    parser.add_argument("--homes", type=int, nargs="+", default=[1, 16, 4096],
                        help="numbers of experienced homes for the sweep times (one new home added)")
    parser.add_argument("--features", type=int, default=256, help="visual dimension D of the sweep corpora")
    parser.add_argument("--warmup", type=int, default=2, help="untimed sweeps before the timed ones")
    parser.add_argument("--sweeps", type=int, default=5, help="timed sweeps (median)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--skip-demo", action="store_true")
    parser.add_argument("--skip-sweeps", action="store_true")
    parser.add_argument("--corpora", type=Path, default=None, metavar="DIR",
                        help="keep the sweep corpora in DIR and reuse them when present")
    parser.add_argument("--hyper", action="append", default=[], metavar="NAME=JSON",
                        help="the sweeps of tree NAME with these TransferHyperparameters fields, e.g. "
                             "'rule={\"word_model\": \"naming-rule\"}' (NAME may name a --code tree twice)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the tables")
    args = parser.parse_args(argv)
    hypers = dict(item.partition("=")[::2] for item in args.hyper)
    trees: dict[str, Path] = {}
    for item in args.code or ["this=src"]:
        name, _, src = item.partition("=")
        path = Path(src) if Path(src).is_absolute() else ROOT / src
        if not name or not (path / "spco" / "__init__.py").is_file():
            parser.error(f"--code {item!r}: expected NAME=SRC with SRC a folder holding spco/")
        trees[name] = path
    demo = [] if args.skip_demo else demo_runs(trees, args.repeats)
    sweeps = [] if args.skip_sweeps else sweep_runs(trees, args.homes, args.features, args.warmup,
                                                    args.sweeps, args.seed, args.corpora, hypers)
    if args.json:
        print(json.dumps({"demo": demo, "sweeps": sweeps, "cores": os.cpu_count(),
                          "trees": {k: str(v) for k, v in trees.items()}}, indent=1))
        return 0
    print(f"{os.cpu_count()} cores; load average now {os.getloadavg()[0]:.1f}")
    if demo:
        print("\nspco demo, first run (empty cache) and warm run (medians):\n")
        print(demo_table(demo, list(trees)))
    if sweeps:
        print(f"\nA fit's sweep (+MI), synthetic homes, D = {args.features}: ms per home and sweep, "
              f"median of {args.sweeps}:\n")
        print(sweep_table(sweeps, list(trees)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
