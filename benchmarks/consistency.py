"""Cross-home consistency of the learnt concepts: is one place carried by one concept in every home?

For each seed this generates synthetic homes (``spco synth``'s generator, every sample taught),
fits SpCoTransfer+MI and reports, for every place name said in at least two homes, whether the
concept that carries it (the concept holding most of the samples that say it) is the same in every
home. The consistency is the share of names that are. Issue 13 measured 2–3 of 8 names split
across concept labels after 200 sweeps on main.

    python benchmarks/consistency.py --seeds 0 1 2 --sweeps 200
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from spco.data.synthetic import generate_homes
from spco.model.transfer import SpCoTransfer


def consistency(corpus, concepts: list[np.ndarray], words: list[str]) -> dict[str, list[int]]:
    """name -> the concept carrying it in each home where it is said."""
    carriers: dict[str, list[int]] = {}
    for env, conc in zip(corpus.training_set(), concepts, strict=True):
        for word in words:
            said = np.array([s is not None and word in s.lower().split() for s in env.sentences])
            if said.any():
                carriers.setdefault(word, []).append(int(np.bincount(conc[said]).argmax()))
    return {w: c for w, c in carriers.items() if len(c) >= 2}


def main() -> None:
    """Fit per seed and print the consistency (JSON lines)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--homes", type=int, default=16)
    parser.add_argument("--sweeps", type=int, default=200)
    args = parser.parse_args()
    for seed in args.seeds:
        corpus = generate_homes(args.homes, seed=seed, specific_rooms=False)
        model = SpCoTransfer(prune_words=True, n_iterations=args.sweeps, random_state=seed,
                             record_log_joint=False).fit(corpus)
        names = sorted({lab for env in corpus for lab in env.labels() if lab is not None})
        carriers = consistency(corpus, list(model.concepts_), names)
        split = {w: sorted(set(c)) for w, c in carriers.items() if len(set(c)) > 1}
        print(json.dumps({"seed": seed, "names": len(carriers), "consistent": len(carriers) - len(split),
                          "share": round((len(carriers) - len(split)) / max(len(carriers), 1), 3),
                          "split": split}), flush=True)


if __name__ == "__main__":
    main()
