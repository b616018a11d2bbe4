"""Whether the chain leaves its start (issue 28, class c of ``speech_errors.py``): the concept of every
taught sample of the knowledge homes, per home and place, after a few sweeps and after many.

Development side only (``benchmarks/SPLIT.md``, "Natural speech"): one configuration of
``natural_speech.py --leave-one-out`` (``--home``: 3LDK_9, or a development home held out), fitted
with the trial seed of ``speech_errors.py`` for each number of sweeps in ``--sweeps``. Printed per
knowledge home and place: ``concept x samples`` (``N``: the samples whose sentence says a name of the
place, ``accepted_names_dev.json``), then how many taught samples changed concept between the first
and the last fit. On main ``eabbb08`` (1LDK_5 held out, seed 0, ``--sweeps 1 60``): 179 of 1,140, and
the rooms that share a concept after the first sweep (2LDK_5's dining area and living room,
2LDK_1's dining area and nameless living-room samples) still share it at the 60th
(benchmarks/README.md, "Natural speech: concepts that hold two rooms, and the start").

    python benchmarks/start_places.py --home 1LDK_5 --seed 0 --sweeps 1 60
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from data_paths import SIGVERSE
from free_speech import fit_speech, read_names
from natural_speech import configurations
from speech_errors import training_places
from split_seeds import refuse_other_seeds

from spco.data import Corpus
from spco.evaluation.experiments import trial_seed


def _parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sigverse", type=Path, default=SIGVERSE)
    parser.add_argument("--accepted", type=Path,
                        default=Path(__file__).resolve().parent / "development" / "accepted_names_dev.json")
    parser.add_argument("--home", default="1LDK_5", help="the configuration: 3LDK_9, or a development home "
                        "held out")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sweeps", type=int, nargs="+", default=[1, 60])
    return parser


def main() -> None:
    """Fit the configuration once per number of sweeps; print the taught samples' concepts."""
    parser = _parser()
    args = parser.parse_args()
    refuse_other_seeds(parser, [args.seed])
    accepted = read_names(args.accepted)
    _, configs = configurations(args.sigverse, accepted, leave_one_out=True)
    labels = [c[0] for c in configs]
    found = [c for c in configs if c[0].split()[0] == args.home]
    if not found:
        parser.error(f"--home must be one of {', '.join(label.split()[0] for label in labels)}")
    label, homes, env = found[0]
    corpus = Corpus([*homes, env])
    fits = {sweeps: fit_speech(corpus, None, sweeps, trial_seed(args.seed, labels.index(label)))
            for sweeps in args.sweeps}
    places = [training_places(corpus[e], corpus.vocabulary, accepted) for e in range(len(corpus) - 1)]
    for sweeps, model in fits.items():
        print(f"\n{label}, seed {args.seed}, {sweeps} sweeps: concept x samples (N: naming the place)")
        for e in range(len(corpus) - 1):
            held: dict[str, Counter] = defaultdict(Counter)
            for c, (place, said) in zip(model.concepts_[e], places[e], strict=True):
                if place is not None:
                    held[place][f"{int(c)}{'N' if said else ''}"] += 1
            rows = [f"{p}: " + " ".join(f"{k}x{n}" for k, n in sorted(c.items()))
                    for p, c in sorted(held.items())]
            print(f"  {corpus.names[e]}: " + "; ".join(rows))
    first, last = fits[args.sweeps[0]], fits[args.sweeps[-1]]
    taught = [np.array([p is not None for p, _ in home]) for home in places]
    changed = sum(int((first.concepts_[e][t] != last.concepts_[e][t]).sum()) for e, t in enumerate(taught))
    total = sum(int(t.sum()) for t in taught)
    print(f"\ntaught samples whose concept differs between {args.sweeps[0]} and {args.sweeps[-1]} sweeps: "
          f"{changed} of {total}")


if __name__ == "__main__":
    main()
