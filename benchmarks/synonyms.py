"""Measure the synonym rule's overlap (``spco.model.synonyms``) on synthetic homes.

Runs the exact sampler's start (+MI, one sweep) on the 16 experienced synthetic homes of the general
experiment and records the names and regions its warm start groups (``same_place_names``, called by each
shard of homes: :mod:`spco.model.shard_init`). For every
pair of names said in one home it computes their region overlap, per home and pooled over the homes
that say both, and prints how many pairs of synonyms (names of one place in the generator's lexicon,
:data:`spco.data.speech.PLACE_WORDS`, used here for the measurement only) and of names of different
places each rule would join. The threshold ``spco.model.synonyms.MIN_OVERLAP`` was chosen from this
table (docs/model.md, "Synonyms").

    python benchmarks/synonyms.py --language free --seed 0
    python benchmarks/synonyms.py --language templates
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

import spco.model.shard_init as shard_init
from spco.data.environment import Corpus
from spco.data.language import normalize_name
from spco.data.speech import PLACE_WORDS
from spco.evaluation.experiments import ExperimentConfig, load_experiment_data
from spco.model.synonyms import name_region_overlaps, pooled_overlaps
from spco.model.transfer import SpCoTransfer


def _place_of_words() -> dict[str, str]:
    """word or term -> its place type, from the generator's lexicon (names, then object words)."""
    place_of: dict[str, str] = {}
    for place, words in PLACE_WORDS.items():
        for name in words.names:
            place_of[normalize_name(name)] = place
        for thing in words.objects:
            for word in normalize_name(thing).split():
                place_of.setdefault(word, place)
    return place_of


def _recorded_start(language: str, seed: int) -> tuple[dict[str, Any], list[str]]:
    """The names, regions and home offsets the warm start groups, and the vocabulary's words."""
    config = ExperimentConfig(experiment="general", data="synthetic", language=language, settings=(16,),
                              trials=1, seed=seed, iterations=1).validated()
    data = load_experiment_data(config)
    calls: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    seen: dict[str, Any] = {}
    original = shard_init.same_place_names

    def record(names: np.ndarray, regions: np.ndarray, offsets: np.ndarray, n_regions: int,
               n_words: int, *rest: Any, **options: Any) -> np.ndarray:
        calls.append((names.copy(), regions.copy(), offsets.copy()))
        seen.update(n_regions=n_regions, n_words=n_words)
        return original(names, regions, offsets, n_regions, n_words, *rest, **options)

    shard_init.same_place_names = record  # each shard's warm start calls it through the module
    try:
        homes = data.homes_for(16, data.new_homes[0])
        SpCoTransfer(n_iterations=1, random_state=seed, prune_words=True).fit(
            Corpus(homes, vocabulary=data.vocabulary))
    finally:
        shard_init.same_place_names = original
    # the shards' homes in one layout: names and regions end to end, offsets shifted
    starts = np.cumsum([0] + [names.size for names, _, _ in calls])
    shifted = [offsets[1:] + start for (_, _, offsets), start in zip(calls, starts, strict=False)]
    seen.update(names=np.concatenate([c[0] for c in calls]), regions=np.concatenate([c[1] for c in calls]),
                offsets=np.concatenate([[0], *shifted]))
    return seen, list(data.vocabulary.words)


def main() -> None:
    """Print the share of synonym pairs and of different-place pairs each overlap rule joins."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--language", default="free", choices=("free", "templates"))
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    seen, words = _recorded_start(args.language, args.seed)
    place_of = _place_of_words()
    per_home = name_region_overlaps(seen["names"], seen["regions"], seen["offsets"], seen["n_regions"])
    pooled = pooled_overlaps(per_home, seen["n_words"]).toarray()
    home_pairs: dict[bool, list[float]] = {True: [], False: []}
    pooled_pairs: dict[bool, dict[tuple[int, int], float]] = {True: {}, False: {}}
    for used, _, overlap in per_home:
        for i, j in zip(*np.triu_indices(used.size, k=1), strict=True):
            a, b = words[used[i]], words[used[j]]
            if a not in place_of or b not in place_of:
                continue  # not in the lexicon (frame words, terms with a filler): not measured
            same = place_of[a] == place_of[b]
            home_pairs[same].append(float(overlap[i, j]))
            key = (min(used[i], used[j]), max(used[i], used[j]))
            pooled_pairs[same][key] = float(pooled[key])
    print(f"{args.language} sentences, seed {args.seed}: pairs of names said in one home "
          f"({len(home_pairs[True])} synonym pairs, {len(home_pairs[False])} of different places)")
    print("| rule | synonym pairs joined | pairs of different places joined |")
    print("|---|---|---|")
    for threshold in (0.3, 0.4, 0.5, 0.6):
        same, other = np.asarray(home_pairs[True]), np.asarray(home_pairs[False])
        share = f"{(same > threshold).mean():.0%}" if same.size else "-"
        print(f"| per home, overlap > {threshold} | {share} of {same.size} | "
              f"{int((other > threshold).sum())} of {other.size} |")
    for threshold in (0.3, 0.4, 0.5):
        same = np.asarray(list(pooled_pairs[True].values()))
        other = np.asarray(list(pooled_pairs[False].values()))
        print(f"| pooled, overlap > {threshold} | {int((same > threshold).sum())} of {same.size} | "
              f"{int((other > threshold).sum())} of {other.size} |")
    other_pairs = sorted(pooled_pairs[False].items(), key=lambda kv: -kv[1])[:5]
    print("largest pooled overlaps of different places:",
          ", ".join(f"{words[a]} / {words[b]} {v:.2f}" for (a, b), v in other_pairs))


if __name__ == "__main__":
    main()
