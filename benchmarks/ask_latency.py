"""How long ``spco.knowledge.ask`` takes to rank a home's samples (issue 23: at most 1 s).

Adapts a SIGVerse home taught nothing to a knowledge file (or loads a home file), then times
``ask(home, n=5)`` — the whole ranking: concept posterior and names of every sample, rooms, the
own-name prior, the view fits, the gain, the order and the reasons — ``--repeats`` times, in wall
time and in this process's CPU time (which the other processes of a busy machine do not inflate).
Prints one JSON object with the percentiles and the load average.

    python benchmarks/ask_latency.py --knowledge K.spco --data ../shared/datasets/sigverse --home 3LDK_9
    python benchmarks/ask_latency.py --home-file H.spco
"""

from __future__ import annotations

import argparse
import json
import os
import time
import warnings

import numpy as np

from spco import knowledge as kn


def main() -> None:
    """Time the ranking and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--knowledge", help="a knowledge file (with --data and --home)")
    parser.add_argument("--data", help="the folder of SIGVerse homes")
    parser.add_argument("--home", default="3LDK_9", help="the new home to adapt (taught nothing)")
    parser.add_argument("--home-file", help="a home file to rank instead")
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.home_file:
        home = kn.load_home_model(args.home_file)
    else:
        if not (args.knowledge and args.data):
            parser.error("give --home-file, or --knowledge and --data")
        from spco.data.loading import load_homes

        env = load_homes(args.data, names=[args.home], teaching_rate=0)[0]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            home = kn.adapt(kn.load_knowledge(args.knowledge), env, random_state=args.seed)
    kn.ask(home, n=5)  # the first call imports what it needs
    wall, cpu = [], []
    for _ in range(args.repeats):
        w, c = time.perf_counter(), time.process_time()
        kn.ask(home, n=5)
        wall.append(time.perf_counter() - w)
        cpu.append(time.process_time() - c)

    def stats(values: list[float]) -> dict[str, float]:
        return {"median_ms": round(1000 * float(np.median(values)), 1),
                "p95_ms": round(1000 * float(np.percentile(values, 95)), 1),
                "max_ms": round(1000 * float(np.max(values)), 1)}

    print(json.dumps({"home": home.name, "samples": home.n_samples, "repeats": args.repeats,
                      "wall": stats(wall), "cpu": stats(cpu), "load_average": list(os.getloadavg())}))


if __name__ == "__main__":
    main()
