"""A_n and A_p of the hand-written sentences (``tests/data/handwritten_sigverse.csv``) over seeds.

Fits 1LDK_9 and 2LDK_9 from their hand-written sentences alone, as ``tests/test_handwritten.py``
does (SpCoTransfer+MI, 40 sweeps), once per seed, and prints each home's A_n, A_p and the test
samples named wrong (place -> predicted name: count)::

    python benchmarks/handwritten.py --sigverse ../shared/datasets/sigverse --seeds 0 1 2 3 4 5

``--name-prior wordnet`` predicts names with the opt-in ordering by the name prior, ``both`` scores
each fit both ways (``off``, the default, passes no option: the script also runs on older code).
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from data_paths import SIGVERSE
from test_handwritten import handwritten_homes

from spco.data import Corpus
from spco.evaluation import evaluate_home
from spco.model import SpCoTransfer


def main() -> None:
    """Print A_n, A_p and the wrong names per seed and home, then the means."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sigverse", type=Path, default=SIGVERSE)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4, 5])
    parser.add_argument("--sweeps", type=int, default=40)
    parser.add_argument("--weighting", default="mi", choices=("mi", "none", "reference"))
    parser.add_argument("--name-prior", default="off", choices=("off", "wordnet", "both"))
    args = parser.parse_args()
    settings = ["off", "wordnet"] if args.name_prior == "both" else [args.name_prior]
    corpus = Corpus(handwritten_homes(Path(args.sigverse)))
    scores = {(env.name, s): [] for env in corpus for s in settings}
    for seed in args.seeds:
        model = SpCoTransfer(n_iterations=args.sweeps, random_state=seed, prune_words=True).fit(corpus)
        for e, env in enumerate(corpus):
            for setting in settings:
                option = {} if setting == "off" else {"name_prior": setting}
                view_counts = getattr(getattr(model, "settings_", None), "view_counts", None)
                if view_counts is not None:  # as the model learnt (and as tests/test_handwritten.py)
                    option["view_counts"] = view_counts
                home = evaluate_home(model.parameters_, e, env, corpus.vocabulary, rng=0,
                                     weighting=args.weighting, **option)
                gt = env.ground_truth
                assert gt is not None
                wrong = Counter(f"{place} -> {name}" for place, name in zip(home.labels, home.predicted_names,
                                                                             strict=True)
                                if name not in gt.accepted(place))
                scores[(env.name, setting)].append((home.mean_name_accuracy, home.mean_position_accuracy))
                print(f"seed {seed} {env.name} name prior {setting}: A_n {home.mean_name_accuracy:.3f} A_p "
                      f"{home.mean_position_accuracy:.3f} wrong {dict(wrong)}", flush=True)
    for (name, setting), values in scores.items():
        mean = np.mean(values, axis=0)
        print(f"{name} name prior {setting}: mean A_n {mean[0]:.3f}, mean A_p {mean[1]:.3f} "
              f"over seeds {args.seeds}")


if __name__ == "__main__":
    main()
