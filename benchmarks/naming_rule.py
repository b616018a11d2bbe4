"""Measure the naming rule's statistic (``spco.model.pruning.colocation``) on real and synthetic homes.

For each data set this runs the exact sampler *without* pruning (so the measurement does not depend
on the rule it is used to choose) for ``--sweeps`` sweeps, then prints, for every word, its pairs of
uses said in the same home, the share of those pairs that fall in the same region, the share expected
for random pairs of taught samples, their ratio (the lift), the excess (chance-corrected share), the
Bayes factor of "name" against "said like any sentence" and the verdict. The thresholds of
``spco.model.pruning`` were chosen from this table (docs/model.md, "What counts as a name").

    python benchmarks/naming_rule.py --data synthetic --rate 20
    python benchmarks/naming_rule.py --data ../shared/datasets/sigverse \
        --regions ../shared/datasets/sigverse_regions.json --rate 40
    python benchmarks/naming_rule.py --data synthetic --language free
"""

from __future__ import annotations

import argparse

import numpy as np

from spco.evaluation.experiments import ExperimentConfig, load_experiment_data
from spco.model.pruning import colocation, judge_names
from spco.model.state import PreparedData
from spco.model.transfer import SpCoTransfer


def main() -> None:
    """Print the colocation table of every word after a short unpruned fit."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default="synthetic")
    parser.add_argument("--regions", default=None)
    parser.add_argument("--rate", type=int, default=40, help="teaching rate of the home-specific rooms")
    parser.add_argument("--experienced-rate", type=float, default=100.0,
                        help="synthetic only: teaching rate of the experienced homes")
    parser.add_argument("--language", default="templates", choices=("templates", "free"),
                        help="synthetic only: the sentences")
    parser.add_argument("--sweeps", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.data == "synthetic" and (args.experienced_rate < 100 or args.language != "templates"):
        from spco.data.synthetic import SyntheticConfig, generate_homes

        corpus = generate_homes(17, seed=args.seed, new_homes=1, teaching_rate=args.experienced_rate,
                                config=SyntheticConfig(language=args.language))
    else:
        config = ExperimentConfig(experiment="specific", settings=(args.rate,), data=args.data,
                                  regions=args.regions, trials=1, seed=args.seed)
        data = load_experiment_data(config)
        from spco.data.environment import Corpus

        homes = data.homes_for(args.rate, data.specific_home)
        corpus = Corpus(homes)
    model = SpCoTransfer(prune_words=False, n_iterations=args.sweeps, random_state=args.seed,
                         record_log_joint=False)
    model.fit(corpus)
    prepared = PreparedData.from_corpus(corpus, 1.0)
    state = model.state_
    stats = colocation(prepared.words, prepared.homes, state.regions, prepared.n_homes,
                       model.hyperparameters_.n_regions)
    verdict = judge_names(stats)
    bayes = np.exp(stats.log_bayes_factor())
    print(f"{'word':>18} {'pairs':>8} {'same':>7} {'share':>6} {'random':>6} {'lift':>6} {'excess':>6} "
          f"{'bayes':>8} verdict")
    for k in np.argsort(-stats.log_bayes_factor()):
        share = stats.same[k] / stats.pairs[k] if stats.pairs[k] else float("nan")
        rand = stats.expected[k] / stats.pairs[k] if stats.pairs[k] else float("nan")
        print(f"{corpus.vocabulary.words[k]:>18} {stats.pairs[k]:8.0f} {stats.same[k]:7.0f} {share:6.3f} "
              f"{rand:6.3f} {stats.lift[k]:6.2f} {stats.excess[k]:6.3f} {bayes[k]:8.3g} "
              f"{('not', 'undecided', 'NAME')[verdict[k]]}")


if __name__ == "__main__":
    main()
