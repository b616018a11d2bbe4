"""How the new home's samples cluster in cached natural-speech fits (issue 29; development only).

Reads the fits ``benchmarks/speech_errors.py --leave-one-out --cache C`` kept (keyed by its ``--set`` and
``--sweeps``) and prints, per configuration and seed, the adjusted Rand index of the new home's labelled
training samples' concepts (the chain's last sweep) against their places, and how many concepts they use.
A diagnostic of the power target's lump (benchmarks/README.md, "Issue 29: the power target with a φ^v step
that mixes, on every development configuration"). Development configurations only (natural_speech.py's
development side); it fits nothing.

    python benchmarks/speech_lump.py --cache C_cut --seeds 0 1 2 3 4 --json J
    python benchmarks/speech_lump.py --cache C_power --set target=power visual_prior=estimate
"""

from __future__ import annotations

import argparse
import json
import pickle
import sys
from pathlib import Path

import numpy as np
from sklearn.metrics import adjusted_rand_score

sys.path.insert(0, str(Path(__file__).resolve().parent))

from data_paths import SIGVERSE
from free_speech import read_names
from natural_speech import cache_path, configurations

HERE = Path(__file__).resolve().parent


def new_home_clusters(model, env) -> dict[str, float | int]:
    """The new home's (the corpus's last) labelled training samples: ARI against their places, the
    concepts they use and the number of places."""
    labels = np.asarray(env.ground_truth.labels, dtype=object)[~np.asarray(env.is_test, dtype=bool)]
    labels = np.asarray([str(x) for x in labels])
    concepts = model.state_.concepts[model.data_.homes == model.data_.n_homes - 1]
    if concepts.shape[0] != labels.shape[0]:
        raise SystemExit(f"the fit's new home has {concepts.shape[0]} samples, its labels {labels.shape[0]}")
    ok = labels != "None"
    return {"ari": float(adjusted_rand_score(labels[ok], concepts[ok])),
            "concepts_used": len(set(concepts[ok].tolist())), "places": len(set(labels[ok].tolist()))}


def main(argv: list[str] | None = None) -> int:
    """Command line: read the cached fits, print the table, write ``--json``."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sigverse", type=Path, default=SIGVERSE)
    p.add_argument("--accepted", type=Path, default=HERE / "development" / "accepted_names_dev.json")
    p.add_argument("--cache", type=Path, required=True, help="speech_errors.py's --cache")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    p.add_argument("--sweeps", type=int, default=60, help="the fits' --sweeps (part of the cache key)")
    p.add_argument("--set", nargs="+", action="extend", default=[], metavar="NAME=VALUE",
                   help="the fits' --set, all after one --set (the cache key)")
    p.add_argument("--json", type=Path, default=None)
    a = p.parse_args(argv)
    _, configs = configurations(a.sigverse, read_names(a.accepted), leave_one_out=True)
    out: dict[str, dict[int, dict]] = {}
    for label, _, env in configs:
        for seed in a.seeds:
            path = cache_path(a.cache, a.set, a.sweeps, label, seed)
            if not path.exists():
                print(f"{label} seed {seed}: no cached fit {path.name}", file=sys.stderr)
                continue
            with open(path, "rb") as fh:
                out.setdefault(label, {})[seed] = new_home_clusters(pickle.load(fh), env)
    print("| configuration | places | ARI per seed (concepts used) | mean ARI |\n|---|---|---|---|")
    for label, runs in out.items():
        cells = " ".join(f"{r['ari']:.2f} ({r['concepts_used']})" for _, r in sorted(runs.items()))
        places = next(iter(runs.values()))["places"]
        print(f"| {label} | {places} | {cells} | {np.mean([r['ari'] for r in runs.values()]):.2f} |")
    every = [r["ari"] for runs in out.values() for r in runs.values()]
    if every:
        print(f"\nmean ARI over {len(every)} fits: {np.mean(every):.3f}")
    if a.json is not None:
        a.json.write_text(json.dumps(out, indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
