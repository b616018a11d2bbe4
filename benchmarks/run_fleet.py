"""Fleet benchmark: sweep time, peak memory and bytes sent, by number of homes and engine.

Each measurement runs in a fresh process (``one``), so that its peak memory is its own: it
makes N fully taught synthetic homes plus one new home (D visual dimensions) and starts the engine
(local, or Ray with S shards as actors): every shard generates and starts its own homes
(:mod:`spco.model.shard_init`: the driver holds only the shared parameters). It then runs
``--warmup`` untimed and ``--sweeps`` timed sweeps (steady state: sweeps 21.., label swaps on
every 10th) and prints one JSON row: seconds per sweep, peak resident memory of the driver and
of every shard's process, bytes sent per sweep (shared parameters to the shards, statistics
back), and the time to generate and to initialise.

``table`` runs ``one`` for every size, interleaving the engines within each size (the machine is
shared, so timings drift with its load; interleaving keeps the comparison fair) and prints a
Markdown table (``--json FILE`` keeps the rows):

    python benchmarks/run_fleet.py table --homes 16 256 1024 --features 4096
    python benchmarks/run_fleet.py one --homes 1024 --engine ray --shards 2

Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from typing import Any

import numpy as np

ENGINES = (("local", 1), ("ray", 1), ("ray", 2))


def log(message: str) -> None:
    """Progress on stderr."""
    print(message, file=sys.stderr, flush=True)


def peak_rss() -> int:
    """Peak resident memory of this process, bytes (Linux: ru_maxrss in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """One configuration, in this process."""
    from spco.engines import make_engine
    from spco.model import gibbs
    from spco.model.hyperparameters import TransferHyperparameters

    hyper = TransferHyperparameters()
    settings = gibbs.SamplerSettings.create("exact", prune=False)
    rng = np.random.default_rng(args.seed)
    engine = make_engine(args.engine, args.shards)
    if args.engine == "ray":
        import ray

        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    generated = initialised = None
    # every shard generates and starts its own homes (spco.model.shard_init)
    from spco.data.synthetic import SyntheticConfig
    from spco.model.sources import SyntheticHomes

    t0 = time.perf_counter()
    source = SyntheticHomes.create(args.homes + 1, args.seed, SyntheticConfig(n_features=args.features),
                                   new_homes=1)
    vocabulary_seconds = time.perf_counter() - t0
    t0 = time.perf_counter()
    run = engine.start_source(source, hyper, settings, rng)
    started = time.perf_counter() - t0
    log(f"  started in {started:.1f} s")
    first = gibbs.SWAP_BURN_IN + 1
    for i in range(args.warmup):
        run.sweep(first + i)
    sent, received = run.bytes_sent, run.global_step.bytes_received
    times = []
    for i in range(args.sweeps):
        t0 = time.perf_counter()
        run.sweep(first + args.warmup + i)
        times.append(time.perf_counter() - t0)
    shard_memory = run.memory() if hasattr(run, "memory") else []
    row = {"homes": run.bounds[-1][1], "D": args.features, "engine": args.engine,
           "shards": run.n_shards, "sweep_seconds": float(np.median(times)), "all_sweep_seconds": times,
           "driver_peak_bytes": peak_rss(), "shard_peak_bytes": shard_memory,
           "bytes_sent_per_sweep": (run.bytes_sent - sent) / args.sweeps,
           "bytes_received_per_sweep": (run.global_step.bytes_received - received) / args.sweeps,
           "generate_seconds": generated, "initialise_seconds": initialised, "start_seconds": started,
           "finished_at": time.strftime("%H:%M:%S", time.gmtime())}
    setup = (run.setup_seconds() if hasattr(run, "setup_seconds")
             else [shard.setup_seconds for shard in run.shards])
    row.update(vocabulary_seconds=vocabulary_seconds, shard_setup_seconds=setup,
               initialisation_bytes_received=run.initialisation.bytes_received,
               initialisation_bytes_sent=run.initialisation.bytes_sent,
               warm_start_seconds=run.initialisation.seconds,
               alignment_seconds=run.initialisation.alignment_seconds)
    run.close()
    return row


def table(rows: list[dict[str, Any]]) -> str:
    """The Markdown table of the rows."""
    lines = ["| homes | D | engine | sweep s | ms / home / sweep | driver peak MB | shard peaks MB | "
             "MB / home (largest process) | KB sent / sweep | KB received / sweep |",
             "|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        engine = r["engine"] if r["engine"] == "local" else f"ray × {r['shards']}"
        shards = " / ".join(f"{b / 2**20:.0f}" for b in r["shard_peak_bytes"]) or "–"
        largest = max([r["driver_peak_bytes"], *r["shard_peak_bytes"]])
        lines.append(f"| {r['homes']} | {r['D']} | {engine} | {r['sweep_seconds']:.3f} | "
                     f"{r['sweep_seconds'] / r['homes'] * 1e3:.2f} | {r['driver_peak_bytes'] / 2**20:.0f} | "
                     f"{shards} | {largest / r['homes'] / 2**20:.2f} | "
                     f"{r['bytes_sent_per_sweep'] / 1e3:.0f} | "
                     f"{r['bytes_received_per_sweep'] / 1e3:.0f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``one`` configuration, or the whole ``table``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=("one", "table"))
    parser.add_argument("--homes", type=int, nargs="+", default=[16, 256, 1024])
    parser.add_argument("--features", type=int, default=4096)
    parser.add_argument("--engine", choices=("local", "ray"), default="local")
    parser.add_argument("--shards", type=int, default=1)
    parser.add_argument("--engines", nargs="+", default=[f"{e}:{s}" for e, s in ENGINES],
                        help="table: engine:shards pairs to run for every size")
    parser.add_argument("--sweeps", type=int, default=3)
    parser.add_argument("--warmup", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=None, help="table: append the rows to this JSON-lines file")
    args = parser.parse_args(argv)
    if args.mode == "one":
        args.homes = args.homes[0]
        print(json.dumps(measure(args)))
        return 0
    rows = []
    for homes in args.homes:
        for pair in args.engines:
            engine, shards = pair.split(":")
            command = [sys.executable, __file__, "one", "--homes", str(homes),
                       "--features", str(args.features),
                       "--engine", engine, "--shards", shards, "--sweeps", str(args.sweeps),
                       "--warmup", str(args.warmup), "--seed", str(args.seed)]
            log(f"{homes} homes, D = {args.features}, {engine} × {shards} ...")
            done = subprocess.run(command, capture_output=True, text=True)
            if done.returncode != 0:
                last = done.stderr.strip().splitlines()[-1] if done.stderr.strip() else done.returncode
                log(f"  failed: {last}")
                continue
            row = json.loads(done.stdout.strip().splitlines()[-1])
            log(f"  {row['sweep_seconds']:.3f} s per sweep, "
                f"driver {row['driver_peak_bytes'] / 2**20:.0f} MB, "
                f"shards {[round(b / 2**20) for b in row['shard_peak_bytes']]} MB")
            rows.append(row)
            if args.json:
                with open(args.json, "a") as f:
                    f.write(json.dumps(row) + "\n")
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
