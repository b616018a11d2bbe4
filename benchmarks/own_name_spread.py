"""Why a name first heard in a new home can take over the home: the model's posterior or the sampler?

Fits a knowledge on synthetic homes, adapts a new home, teaches "this is the study room" at one
sample (``teach``'s defaults) and then compares assignments of the home's samples to concepts by a
collapsed score of the model with the knowledge fixed:

- views: a concept of the knowledge explains a sample's views by its φ^v (θ^v ≈ φ^v: δ^v = 3·10^5
  pseudo-counts against a few thousand counts of a home); a free concept (one the knowledge does
  not use, learnt from this home) by the Dirichlet-multinomial marginal of its samples' counts under
  Dir(α^v), φ and θ integrated out (the same δ^v → ∞ approximation);
- G_e ~ Dir(γ G_0) and each concept's region weights π_l ~ Dir(β/K) integrated out.

Assignments scored: "taught as is" (what ``teach`` returns), "the name at its room only" (the taught
room's samples in the taught concept, every other sample as adapted), and "own concepts" (the taught
room in the taught concept, the other rooms each in another free concept while free concepts last,
the rest as adapted); then 30 sweeps of the adapt sampler from "own concepts" show whether the
sampler keeps it. ``what`` is asked at five samples of each ground-truth room. Run::

    python benchmarks/own_name_spread.py --homes 3 --iterations 12
    python benchmarks/own_name_spread.py --homes 16 --iterations 100
"""

from __future__ import annotations

import argparse
import warnings
from dataclasses import replace

import numpy as np
from scipy.special import gammaln

from spco import knowledge as kn
from spco.data.environment import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.knowledge.home import _copy_state
from spco.model import gibbs, home_shard


def collapsed_score(concepts: np.ndarray, regions: np.ndarray, visual: np.ndarray,
                    knowledge: kn.Knowledge) -> float:
    """log p(views, concepts | regions, knowledge) up to terms equal for every assignment (see the
    module docstring); ``visual`` (n, D) dense counts."""
    hyper = knowledge.hyperparameters
    g0 = np.exp(knowledge.log_g0)
    free = g0 < kn.FREE_CONCEPT_WEIGHT
    alpha = np.full(visual.shape[1], hyper.alpha_visual)
    total = 0.0
    K, b = hyper.n_regions, hyper.beta / hyper.n_regions
    for concept in np.unique(concepts):
        counts = visual[concepts == concept]
        if free[concept]:
            n = counts.sum(axis=0)
            total += (gammaln(alpha.sum()) - gammaln(alpha.sum() + n.sum())
                      + (gammaln(alpha + n) - gammaln(alpha)).sum())
        else:
            total += float((counts @ knowledge.log_phi_visual[concept]).sum())
        by_region = np.bincount(regions[concepts == concept], minlength=K)
        total += (gammaln(b * K) - gammaln(b * K + by_region.sum())
                  + (gammaln(b + by_region) - gammaln(b)).sum())
    n_l = np.bincount(concepts, minlength=g0.size)
    a = hyper.gamma * g0
    total += gammaln(a.sum()) - gammaln(a.sum() + n_l.sum()) + (gammaln(a + n_l) - gammaln(a)).sum()
    return float(total)


def _composition(labels: np.ndarray, rows: np.ndarray) -> dict[str, int]:
    names, counts = np.unique(labels[rows], return_counts=True)
    return dict(zip(names.tolist(), counts.tolist(), strict=True))


def _what_report(home: kn.HomeModel, labels: np.ndarray, name: str) -> dict[str, str]:
    report = {}
    for room in np.unique(labels):
        answers = []
        for i in np.flatnonzero(labels == room)[:5]:
            x, y = home.positions[i, :2]
            theta = float(np.arctan2(home.positions[i, 2], home.positions[i, 3]))
            answers.append(kn.what(home, float(x), float(y), theta, visual=home.visual[[i]]).best[0])
        report[str(room)] = (f"{sum(a == room for a in answers)}/5 right, "
                             f"{sum(a == name for a in answers)}/5 {name!r}")
    return report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--homes", type=int, default=3, help="experienced homes of the knowledge")
    parser.add_argument("--iterations", type=int, default=12, help="sweeps of fit_knowledge")
    parser.add_argument("--sample", type=int, default=7, help="index of the taught sample")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    corpus = list(generate_homes(args.homes + 1, seed=3, config=SyntheticConfig(n_features=128), new_homes=1,
                                 specific_rooms=False))
    knowledge = kn.fit_knowledge(Corpus(corpus[:args.homes]), n_iterations=args.iterations, random_state=1)
    new = corpus[args.homes]
    home = kn.adapt(knowledge, new, n_iterations=15, random_state=args.seed)
    labels = np.asarray(new.ground_truth.labels, dtype=object)[~new.is_test]
    name = "study room"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", kn.OwnNamesSpreadWarning)
        taught = kn.teach(home, {int(home.ids[args.sample]): f"this is the {name}"}, random_state=args.seed)
    visual = taught.visual.toarray().astype(np.float64)
    extended = taught.knowledge
    free = np.flatnonzero(np.exp(extended.log_g0) < kn.FREE_CONCEPT_WEIGHT)
    concepts, regions = taught.state.concepts, taught.state.regions
    named, room = int(concepts[args.sample]), labels[args.sample]
    print(f"knowledge of {args.homes} homes, {args.iterations} sweeps; {free.size} free concepts; "
          f"taught at a sample of the {room}")

    used = np.exp(extended.log_g0) >= kn.FREE_CONCEPT_WEIGHT
    gaps = {}
    for other_room in np.unique(labels):
        counts = visual[labels == other_room]
        own_views = np.log((counts.sum(axis=0) + extended.hyperparameters.alpha_visual)
                           / (counts.sum() + extended.hyperparameters.alpha_visual * counts.shape[1]))
        best = (counts @ extended.log_phi_visual[used].T).sum(axis=0).max()
        gaps[str(other_room)] = round(float(((counts @ own_views).sum() - best) / counts.shape[0]), 1)
    print(f"  per sample, the room's own smoothed view counts minus the best transferred φ^v (nats): {gaps}")

    at_room = home.state.concepts.copy()
    at_room[labels == room] = named
    own = at_room.copy()
    others = [r for r in np.unique(labels) if r != room]
    for other_room, concept in zip(others, [c for c in free if c != named], strict=False):
        own[labels == other_room] = concept
    for label, assignment in (("taught as is", concepts), ("the name at its room only", at_room),
                              ("own concepts", own)):
        print(f"  {label:26s} score {collapsed_score(assignment, regions, visual, extended):11.1f}  "
              f"taught concept {_composition(labels, assignment == named)}")

    state = _copy_state(taught.state)
    state.concepts = own.copy()
    hyper = extended.hyperparameters
    settings = gibbs.SamplerSettings.create(extended.variant, extended.prune_words, learn_shared=False)
    rng = np.random.default_rng(args.seed)
    home_shard.learn_free_concepts(taught.data, state, hyper, settings, rng)
    for _ in range(30):
        home_shard.sweep_home(taught.data, state, hyper, settings, rng, None, taught.n_knowledge_words)
    print(f"  from own concepts, 30 sweeps: score "
          f"{collapsed_score(state.concepts, state.regions, visual, extended):.1f}, taught concept "
          f"{_composition(labels, state.concepts == state.concepts[args.sample])}")
    print("  what, taught as is:        ", _what_report(taught, labels, name))
    kept = replace(taught, state=state, posterior=None)
    print("  what, from own concepts:   ", _what_report(kept, labels, name))


if __name__ == "__main__":
    main()
