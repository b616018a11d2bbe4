"""The home-specific experiment through the knowledge workflow: fit once, adapt, teach.

Fits the knowledge on the 16 experienced SIGVerse homes (once per seed), then for each teaching
rate scores 3LDK_9's three bedrooms (the 30 home-specific test samples, as ``spco experiment
specific``) two ways: ``adapt`` given the home at that rate (everything at once), and ``adapt`` of
the untaught home followed by one ``teach`` call per taught sample (random order). Names are ranked
as ``spco what`` ranks them on a home file.

    python benchmarks/specific_workflow.py --data ../shared/datasets/sigverse \
        --regions ../shared/datasets/sigverse_regions.json --rates 20,40,100 --seeds 1 2 3
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from spco import knowledge as kn
from spco.data.environment import Corpus
from spco.evaluation import evaluate_home
from spco.evaluation.experiments import ExperimentConfig, load_experiment_data


def score(home: kn.HomeModel, env, seed: int) -> dict:
    """A_n and A_p per bedroom of the home model on the home-specific test samples."""
    s = evaluate_home(home.parameters, 0, env, home.vocabulary, specific=True, rng=seed,
                      weighting=home.weighting)  # type: ignore[arg-type]
    return {"A_n": {k: round(v, 3) for k, v in s.name_accuracy.items()},
            "A_p": {k: round(v, 3) for k, v in s.position_accuracy.items()},
            "mean_A_n": round(s.mean_name_accuracy, 3), "mean_A_p": round(s.mean_position_accuracy, 3)}


def main() -> None:
    """Print one JSON line per seed, rate and way."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True)
    parser.add_argument("--regions", required=True)
    parser.add_argument("--rates", default="20,40,100")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1])
    args = parser.parse_args()
    rates = [int(r) for r in args.rates.split(",")]
    config = ExperimentConfig(experiment="specific", settings=tuple(rates), data=args.data,
                              regions=args.regions, trials=1)
    data = load_experiment_data(config)
    experienced = Corpus([data.experienced_home(n) for n in data.experienced])
    for seed in args.seeds:
        knowledge = kn.fit_knowledge(experienced, random_state=seed)  # its own vocabulary, as `spco fit`
        untaught = data.new_home(data.specific_home, 0)
        base = kn.adapt(knowledge, untaught, random_state=seed)
        for rate in rates:
            env = data.new_home(data.specific_home, rate)
            at_once = kn.adapt(knowledge, env, random_state=seed)
            print(json.dumps({"seed": seed, "rate": rate, "way": "adapt", **score(at_once, env, seed)}),
                  flush=True)
            home = base
            rng = np.random.default_rng(seed)
            train = env.training_data()
            for j in rng.permutation(np.flatnonzero([s is not None for s in train.sentences])):
                home = kn.teach(home, {int(train.ids[j]): train.sentences[j]}, random_state=rng)
            print(json.dumps({"seed": seed, "rate": rate, "way": "teach one by one",
                              **score(home, env, seed)}), flush=True)


if __name__ == "__main__":
    main()
