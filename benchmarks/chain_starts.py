"""Do chains from different starts reach the same concepts? And does a chain leave its start?

Development data only: the paper's home-specific experiment (the 16 experienced homes + 3LDK_9, its
bedrooms taught at ``--rate`` % with the data set's own sentences). For each seed, SpCoTransfer+MI
(the exact sampler with the naming rule) runs ``--sweeps`` sweeps from three starts:

- ``names`` — the default start (each home from the places its names mark, homes aligned, the new
  home's own names in free concepts: ``spco.model.shard_init``/``gibbs.initialize``);
- ``regions`` — no warm start: uniform θ, so the first sweep groups each home's samples by region;
- ``random`` — concepts uniform at random and θ, G, π drawn from their counts before the first sweep;

and the authors' sampler (``spcotransfer-ref+mi``) from a fit's start (for it: random concepts, uniform
θ, k-means regions, as the authors' code).
Printed per chain: A_n on the 30 home-specific test samples (the paper's measure; SpCoTransfer
predicts with its view weight, the authors' sampler with their KL weighting), the ARI between the
partition after the first sweep and the final one (1: the chain kept its start), and the ARI of
the final partition with the places (pooled over homes: a sample's label is (home, place), the new
home's bedrooms by their own names; a partition's is (home, concept));
then, per seed, the pooled ARI between the final partitions of every pair of starts.

    python benchmarks/chain_starts.py --data ../shared/datasets/sigverse --seeds 0 1
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import numpy as np
from data_paths import SIGVERSE
from sklearn.metrics import adjusted_rand_score

from spco.data.environment import Corpus
from spco.evaluation.config import trial_seed
from spco.evaluation.experiments import ExperimentConfig, load_experiment_data
from spco.evaluation.metrics import evaluate_home
from spco.model import gibbs, parameter_steps, sweep_statistics
from spco.model.driver import start_run
from spco.model.posterior import ParameterAverage, thinned_sweeps, untaught_concepts_name_nothing
from spco.model.state import PreparedData
from spco.model.transfer import SpCoTransfer

STARTS = ("names", "regions", "random")


def _chain(corpus: Corpus, variant: str, start: str, seed: int, sweeps: int) -> dict:
    """Run one chain by hand (the one-process sampler) and return its partitions and parameters."""
    model = SpCoTransfer(variant=variant, prune_words=True, n_iterations=sweeps, random_state=seed)
    hyper = model.checked_hyperparameters()
    settings = model.sampler_settings()
    data = PreparedData.from_corpus(corpus, gibbs.CM_PER_M if variant == "reference" else 1.0)
    rng = np.random.default_rng(seed)
    average = ParameterAverage(data.homes, data.position_scale)
    averaged = set(thinned_sweeps(sweeps))
    first = None
    if start == "names":  # the default start and chain of a fit (spco.model.shard_init, one worker)
        run = start_run(None, data, len(corpus.vocabulary), hyper, settings, rng)
        for it in range(sweeps):
            run.sweep(it)
            if it == 0:
                first = run.state().concepts.copy()
            if it in averaged:
                average.add(run.state())
        state = run.state()
        run.close()
    else:  # the one-process sampler from a start of its own
        state = gibbs.initialize(data, len(corpus.vocabulary), hyper, settings, rng)
        if start == "random":  # θ, G, π from the counts of a random partition
            state.concepts = rng.integers(0, hyper.n_concepts, size=data.n_samples)
            stats = sweep_statistics.sufficient_statistics(data, state, hyper,
                                                           settings.learning_view_counts())
            parameter_steps.home_step(data, state, stats, hyper, settings, rng)
        for it in range(sweeps):
            gibbs.sweep(data, state, hyper, settings, rng, swaps=gibbs.swaps_due(it))
            if it == 0:
                first = state.concepts.copy()
            if it in averaged:
                average.add(state)
    params = average.result(state)
    if variant == "exact":
        taught = np.zeros(hyper.n_concepts, dtype=bool)
        taught[np.unique(state.concepts[np.diff(data.words.indptr) > 0])] = True
        params = untaught_concepts_name_nothing(params, taught)
    return {"first": first, "final": state.concepts.copy(), "homes": data.homes.copy(), "params": params,
            "view_counts": settings.view_counts, "L": hyper.n_concepts}


def _pooled(homes: np.ndarray, concepts: np.ndarray, n_concepts: int) -> np.ndarray:
    return homes * n_concepts + concepts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=SIGVERSE)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--rate", type=int, default=40)
    parser.add_argument("--sweeps", type=int, default=200)
    parser.add_argument("--json", type=Path, default=None, help="write the figures to this file")
    args = parser.parse_args()
    config = ExperimentConfig("specific", settings=(args.rate,), data=args.data,
                              regions=args.data.parent / "sigverse_regions.json", trials=1)
    data = load_experiment_data(config)
    homes = data.homes_for(args.rate, data.specific_home)
    corpus = Corpus(homes, vocabulary=data.vocabulary_for(args.rate))
    # the places of the training samples, per home (a label is (home, place), as a partition's is
    # (home, concept)); the new home's bedrooms by their home-specific names
    labels = np.concatenate([np.array([f"{e}:{lab}" for lab, test in zip(
        env.labels(specific=e == len(homes) - 1), env.is_test, strict=True) if not test], dtype=object)
        for e, env in enumerate(homes)])
    rows = []
    for seed in args.seeds:
        chains = {}
        for variant, start in [("exact", s) for s in STARTS] + [("reference", "names")]:
            t0 = time.perf_counter()
            chain = _chain(corpus, variant, start, trial_seed(seed, 0), args.sweeps)
            e = len(homes) - 1
            scores = evaluate_home(chain["params"], e, homes[-1], corpus.vocabulary, specific=True, rng=0,
                                   weighting="reference" if variant == "reference" else "mi",
                                   view_counts=chain["view_counts"])
            pooled_first = _pooled(chain["homes"], chain["first"], chain["L"])
            pooled_final = _pooled(chain["homes"], chain["final"], chain["L"])
            row = {"seed": seed, "sampler": variant, "start": start,
                   "name_accuracy": scores.mean_name_accuracy,
                   "per_room": {k: round(v, 3) for k, v in scores.name_accuracy.items()},
                   "ari_first_final": adjusted_rand_score(pooled_first, pooled_final),
                   "ari_places": adjusted_rand_score(labels, pooled_final),
                   "seconds": round(time.perf_counter() - t0, 1)}
            rows.append(row)
            chains[start if variant == "exact" else f"authors' sampler ({start})"] = pooled_final
            print(json.dumps(row), flush=True)
        for a, b in itertools.combinations(chains, 2):
            ari = adjusted_rand_score(chains[a], chains[b])
            rows.append({"seed": seed, "pair": f"{a} vs {b}", "ari": ari})
            print(json.dumps(rows[-1]), flush=True)
    print("\n| seed | sampler | start | A_n (Emma / mother / father) | ARI first sweep vs final | "
          "ARI final vs places |\n|---:|---|---|---|---:|---:|")
    for r in rows:
        if "start" in r:
            rooms = " / ".join(f"{v:.2f}" for v in r["per_room"].values())
            print(f"| {r['seed']} | {r['sampler']} | {r['start']} | {r['name_accuracy']:.3f} ({rooms}) | "
                  f"{r['ari_first_final']:.3f} | {r['ari_places']:.3f} |")
    print("\n| seed | starts | pooled ARI of the final partitions |\n|---:|---|---:|")
    for r in rows:
        if "pair" in r:
            print(f"| {r['seed']} | {r['pair']} | {r['ari']:.3f} |")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
