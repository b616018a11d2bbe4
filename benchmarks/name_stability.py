"""Which words a knowledge counts as names, over seeds (issue 28: the name decision).

The same experienced homes fitted with several seeds should give the same names as far as the
posterior allows. This fits the knowledge of ``benchmarks/calibration.py``'s development set (the
first four of the paper's experienced homes, 3LDK_1, 1LDK_8, 2LDK_8, 1LDK_7, fc7 counts, every sample
taught, the default model and sweeps) once per seed and prints, per seed, the knowledge's names
(:attr:`spco.knowledge.Knowledge.name_mask`; with the word channels
:meth:`~spco.knowledge.knowledge.KnowledgeChannels.name_mask`),
each word's tokens per channel (name / place / background: ``KnowledgeChannels.tokens``) and its
switch prior for the words asked about, then the words whose verdict differs between seeds.
Development data only (no held-out home is read).

Run::

    nice -n 5 python benchmarks/name_stability.py --data $D/sigverse --seeds 0 1 2 3 4 5
    # the code before: the same command with PYTHONPATH at its src
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True, help="the SIGVerse data set folder")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--homes", type=int, default=4, help="how many of the paper's experienced homes")
    parser.add_argument("--words", nargs="+", default=["dining", "bath", "location", "place", "space"],
                        help="words whose tokens are printed")
    parser.add_argument("--json", type=Path, help="write every seed's names and tokens here")
    args = parser.parse_args(argv)

    import spco.knowledge as kn
    from spco.data.environment import Corpus
    from spco.data.loading import load_homes
    from spco.evaluation.config import PAPER_EXPERIENCED_HOMES

    if not args.data.is_dir():
        parser.error(f"--data {args.data}: no such folder")
    names = [h for h in PAPER_EXPERIENCED_HOMES[: args.homes] if h not in ("1DK_8", "3LDK_9")]
    homes = load_homes(args.data, names=names, teaching_rate=100)
    print(f"homes: {', '.join(names)}")
    results: dict[int, dict] = {}
    for seed in args.seeds:
        knowledge = kn.fit_knowledge(Corpus(homes), random_state=seed)
        words = list(knowledge.vocabulary.words)
        mask = np.asarray(knowledge.name_mask, dtype=bool)
        record: dict = {"names": [w for w, keep in zip(words, mask, strict=True) if keep]}
        if knowledge.channels is not None:
            tokens = knowledge.channels.tokens
            prior = np.exp(knowledge.channels.channels.log_prior())
            record["tokens"] = {w: [round(float(x), 3) for x in tokens[words.index(w)]]
                                for w in args.words if w in words}
            record["prior"] = {w: [round(float(x), 4) for x in prior[words.index(w)]]
                               for w in args.words if w in words}
        results[seed] = record
        shown = "; ".join(f"{w} {record['tokens'][w]} (prior {record['prior'][w]})"
                          for w in record.get("tokens", {}))
        print(f"seed {seed}: names {record['names']}\n  tokens name/place/background: {shown}", flush=True)
    every = set().union(*(set(r["names"]) for r in results.values()))
    counts = {w: sum(w in r["names"] for r in results.values()) for w in sorted(every)}
    flips = {w: c for w, c in counts.items() if c < len(results)}
    print(f"names in every seed: {[w for w, c in counts.items() if c == len(results)]}")
    print(f"names in some seeds only (seeds of {len(results)}): {flips or 'none'}")
    if args.json:
        args.json.write_text(json.dumps({"seeds": results, "flips": flips}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
