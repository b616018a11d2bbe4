"""Sweep time against the number of homes: does a sweep of spco's sampler grow linearly?

For each size N (default 16, 64, 256) this generates N fully taught synthetic homes plus one new
home (nothing taught) at the paper's visual dimension (D = 4096 unless ``--features``), runs spco's
sampler for a few warm-up sweeps, times ``--sweeps`` more (mean, per step), and finally fits
``seconds per sweep = a + b · homes`` by least squares and prints b (time per home) and R².

    python benchmarks/run_scaling.py                      # 16, 64, 256 homes, D = 4096
    python benchmarks/run_scaling.py --homes 8 16 32 --features 1024 --json

Progress goes to stderr, the table (or JSON) to stdout.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

import numpy as np
from reference_sampler import time_reference

from spco import benchmark
from spco.model.hyperparameters import TransferHyperparameters


def log(message: str) -> None:
    """Progress on stderr."""
    print(message, file=sys.stderr, flush=True)


def linear_fit(x: np.ndarray, y: np.ndarray) -> dict[str, float]:
    """Least-squares line y = intercept + slope · x and its coefficient of determination R²."""
    slope, intercept = np.polyfit(x, y, 1)
    residual = y - (intercept + slope * x)
    total = ((y - y.mean()) ** 2).sum()
    r2 = 1.0 - (residual ** 2).sum() / total if total > 0 else 1.0
    return {"slope": float(slope), "intercept": float(intercept), "r2": float(r2)}


def measure(n_homes: int, args: argparse.Namespace) -> dict[str, Any]:
    """Time one size: ``n_homes`` experienced synthetic homes + one new home."""
    start = time.perf_counter()
    corpus = benchmark.synthetic_corpus(n_homes, 1, n_features=args.features, seed=args.seed)
    log(f"{n_homes} + 1 homes: generated in {time.perf_counter() - start:.0f} s")
    config = benchmark.configuration(corpus, TransferHyperparameters(), "synthetic")
    timings = benchmark.time_spco(corpus, args.variant, args.sweeps, args.warmup, args.seed, log=log)
    row: dict[str, Any] = {"homes": config["homes"], "samples": config["samples"],
                           "sweep_seconds": timings.per_sweep, "steps": timings.per_step(),
                           "all_sweep_seconds": timings.totals}
    if args.with_reference:
        ref = time_reference(corpus, args.reference_sweeps, warmup=1, seed=args.seed, log=log)
        row["reference_sweep_seconds"] = ref.per_sweep
    return row


def main(argv: list[str] | None = None) -> int:
    """Run the scaling benchmark and print the table (or JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--homes", type=int, nargs="+", default=[16, 64, 256],
                        help="numbers of experienced homes (one new home is added to each)")
    parser.add_argument("--features", type=int, default=4096, help="visual dimension D")
    parser.add_argument("--sweeps", type=int, default=5, help="timed sweeps per size (mean)")
    parser.add_argument("--warmup", type=int, default=2, help="untimed sweeps first")
    parser.add_argument("--variant", default="exact", choices=["exact", "reference"], help="spco sampler")
    parser.add_argument("--with-reference", action="store_true",
                        help="also time the authors'-style reference sweep")
    parser.add_argument("--reference-sweeps", type=int, default=1, help="timed reference sweeps per size")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    args = parser.parse_args(argv)

    machine = benchmark.machine_info()
    rows = [measure(n, args) for n in args.homes]
    homes = np.array([r["homes"] for r in rows], dtype=float)
    seconds = np.array([r["sweep_seconds"] for r in rows])
    fit = linear_fit(homes, seconds) if len(rows) >= 2 else None
    machine["load_average_after"] = benchmark.machine_info()["load_average"]
    if args.json:
        print(json.dumps({"variant": args.variant, "D": args.features, "rows": rows, "fit": fit,
                          "machine": machine}, indent=1, ensure_ascii=False))
        return 0

    step_names: list[str] = []
    for r in rows:
        step_names += [s for s in r["steps"] if s not in step_names]
    header = ["homes", "samples", "ms/sweep", "ms/home", *step_names]
    if args.with_reference:
        header.append("reference ms")
    table = []
    for r in rows:
        line = [str(r["homes"]), f"{r['samples']:,}", f"{r['sweep_seconds'] * 1e3:,.0f}",
                f"{r['sweep_seconds'] * 1e3 / r['homes']:.1f}",
                *(f"{r['steps'].get(s, 0.0) * 1e3:,.0f}" for s in step_names)]
        if args.with_reference:
            line.append(f"{r['reference_sweep_seconds'] * 1e3:,.0f}")
        table.append(line)
    widths = [max(len(h), *(len(t[i]) for t in table)) for i, h in enumerate(header)]
    print(f"spco {args.variant} sampler, synthetic homes, D = {args.features}, L = 15, K = 20; "
          f"mean of {args.sweeps} sweeps (step columns in ms per sweep)")
    print(f"machine: {machine['cores']} cores, numpy {machine['numpy']}, numba {machine['numba']}, "
          f"load average {machine['load_average']} before, {machine['load_average_after']} after")
    print("  ".join(h.rjust(w) for h, w in zip(header, widths, strict=True)))
    for t in table:
        print("  ".join(c.rjust(w) for c, w in zip(t, widths, strict=True)))
    if fit is not None:
        print(f"linear fit: sweep time = {fit['intercept'] * 1e3:.0f} ms + {fit['slope'] * 1e3:.1f} ms "
              f"× homes, R² = {fit['r2']:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
