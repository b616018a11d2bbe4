"""Names never heard on development: where each query of the unheard list goes, and why it fails.

Development only (benchmarks/SPLIT.md): the written development speech (``--speech``, default
``benchmarks/development/speech_dev.csv``) taught to the paper's 16 experienced homes, the new home
``3LDK_9`` untaught, fitted exactly as ``benchmarks/free_speech.py`` fits it (its
:func:`taught_homes`, :func:`new_home`, SpCoTransfer+MI, trial seed), and ``where`` asked for every
name of the unheard list (``--unheard``) that the speech never says. The A_p of each query is
``free_speech.py``'s (10 positions in the argmax region, the share inside the place's region; a
refused query counts 0), so the figure is the same as its ``unheard_A_p`` on the same seeds.

Each query is put in one class:

- **right**: A_p ≥ 0.5;
- **refused**: no known name, none of the name's words known (``UnknownNameError``);
- **words**: the lexicon found nothing, and the name's own known words said together answered
  ("spare + room", "room"), wrongly;
- **other place**: the known name used is not an accepted name of the place (the lexicon related
  the name to another place's name: "rec room" → "kitchen");
- **misplaced**: the known name used is an accepted name of the place, but the model places that
  name elsewhere in this home (a weakly bound synonym: "hall").

``--own-names`` also asks, for each failed query, ``where`` for the place's own accepted names that the
vocabulary holds as one usable token (as said, ``unheard=False``), and counts the failures whose place
has one placed right (the look-up's answer lost them, not ``where`` given a right word) and those with one
among the look-up's candidates (the lexicon had the place's own name to find).

The fitted parameters are kept in ``--cache`` (default ``$SPCO_CACHE_DIR/unheard_errors``), keyed by
the speech file's content, the seed, the home and the sweeps, so that the look-up
(:mod:`spco.model.unheard`, the lexicon) can be changed and measured again without fitting::

    nice -n 5 python benchmarks/unheard_errors.py --seeds 0 1 2 --sweeps 200
    nice -n 5 python benchmarks/unheard_errors.py --speech benchmarks/development/speech_dev_words.csv

The cache holds fits only: change the code of the fit (the sampler, the word model) and the cache is
stale (``--refit`` fits again).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import pickle
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from data_paths import SIGVERSE
from free_speech import never_heard, new_home, read_names, read_speech, taught_homes
from split_seeds import refuse_other_seeds

from spco.data import Corpus
from spco.evaluation.experiments import trial_seed
from spco.evaluation.metrics import position_accuracy
from spco.model import SpCoTransfer
from spco.model.position_prediction import predict_positions
from spco.model.prediction import UnknownNameError

DEV = Path(__file__).resolve().parent / "development"
CLASSES = ("right", "refused", "words", "other place", "misplaced")


def cache_path(args: argparse.Namespace, speech_path: Path, seed: int, home: str) -> Path:
    """The cache file of a fit: keyed by the speech file's content, ``--set`` (only when given: the
    default's key is unchanged), the home, the seed and the sweeps."""
    key = hashlib.sha256(speech_path.read_bytes()).hexdigest()[:16]
    if args.set:  # a fit with other hyperparameters is another fit
        key += "-" + hashlib.sha256(" ".join(sorted(args.set)).encode()).hexdigest()[:8]
    return args.cache / f"{key}-{home}-s{seed}-w{args.sweeps}.pkl"


def fitted(args: argparse.Namespace, speech_path: Path, seed: int, home: str, index: int,
           accepted: dict[str, tuple[str, ...]]) -> tuple[object, int, object, object]:
    """(parameters, home index, vocabulary, new home) of the fit, from the cache when there."""
    path = cache_path(args, speech_path, seed, home)
    env = new_home(args.sigverse, args.sigverse.parent / "sigverse_regions.json", home, accepted)
    if path.exists() and not args.refit:
        with open(path, "rb") as fh:
            params, e, vocabulary = pickle.load(fh)
        return params, e, vocabulary, env
    experienced = taught_homes(args.sigverse, read_speech(speech_path), seed)
    corpus = Corpus([*experienced, env])
    started = time.process_time()
    model = SpCoTransfer(args.hyper, variant="exact", prune_words=True, n_iterations=args.sweeps,
                         random_state=trial_seed(seed, index)).fit(corpus)
    print(f"fitted seed {seed} {home}: {time.process_time() - started:.0f} s CPU", flush=True)
    e = len(corpus) - 1
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as fh:
        pickle.dump((model.parameters_, e, corpus.vocabulary), fh)
    os.replace(tmp, path)
    return model.parameters_, e, corpus.vocabulary, env


def classify(params, e, vocabulary, env, place: str, name: str, seed: int,
             accepted: tuple[str, ...]) -> tuple[str, float, str, str]:
    """(class, A_p, the known name used, how) of ``where name`` in the new home."""
    regions = env.ground_truth.regions
    try:
        pred = predict_positions(params, e, vocabulary, name, n=10, rng=seed, unheard=True)
    except UnknownNameError:
        return "refused", 0.0, "(none)", ""
    value = float(position_accuracy({place: pred.samples}, regions)[place])
    if value >= 0.5:
        kind = "right"
    elif pred.via is None:
        kind = "words"
    elif pred.name in accepted:
        kind = "misplaced"
    else:
        kind = "other place"
    return kind, value, pred.name, pred.via or ""


def own_names_placed(params, e, vocabulary, env, place: str, seed: int,
                     accepted: tuple[str, ...]) -> tuple[int, int, int]:
    """(placed right, candidates, asked): the place's accepted names that the vocabulary holds as one
    usable token, asked with ``where`` as said (``unheard=False``, the same draws as :func:`classify`);
    how many of them land in the place (A_p ≥ 0.5: whether ``where`` given a right word finds the
    place), and how many are among the look-up's candidates (:func:`spco.model.unheard.candidate_names`
    with the information :func:`spco.model.position_prediction.resolve_unheard` gives it: whether the
    lexicon had the place's own name to relate the name asked to)."""
    from spco.data.lexicon import lexicon
    from spco.model.prediction import mutual_information_weights
    from spco.model.unheard import candidate_names

    mask = np.asarray(params.word_mask, dtype=bool)
    candidates = set(candidate_names(vocabulary, mask, params.name_prior, lexicon(),
                                     mutual_information_weights(params, e)))
    right = asked = among = 0
    for name in accepted:
        k = vocabulary.index(name)
        if k is None or not mask[k]:
            continue
        asked += 1
        among += vocabulary.words[k] in candidates
        try:
            pred = predict_positions(params, e, vocabulary, name, n=10, rng=seed, unheard=False)
        except UnknownNameError:
            continue
        right += float(position_accuracy({place: pred.samples}, env.ground_truth.regions)[place]) >= 0.5
    return right, among, asked


def _arguments() -> argparse.Namespace:
    """The command line, checked (development seeds and sets only)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sigverse", type=Path, default=SIGVERSE)
    parser.add_argument("--speech", type=Path, default=DEV / "speech_dev.csv")
    parser.add_argument("--accepted", type=Path, default=DEV / "accepted_names_dev.json")
    parser.add_argument("--unheard", type=Path, default=DEV / "unheard_names_dev.json")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--sweeps", type=int, default=200)
    parser.add_argument("--homes", nargs="+", default=["3LDK_9"])
    parser.add_argument("--cache", type=Path,
                        default=Path(os.environ.get("SPCO_CACHE_DIR", ".")) / "unheard_errors")
    parser.add_argument("--refit", action="store_true", help="fit again even when the cache holds the fit")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--own-names", action="store_true",
                        help="for each failed query, also ask where the place's own names are")
    parser.add_argument("--set", nargs="+", action="extend", default=[], metavar="NAME=VALUE",
                        help="transfer hyperparameters of the fit (as spco fit --set), e.g. "
                             "place_channel=home")
    args = parser.parse_args()
    from spco.errors import ConfigurationError
    from spco.model.hyperparameters import TransferHyperparameters

    try:
        args.hyper = TransferHyperparameters().with_settings(list(args.set)) if args.set else None
    except ConfigurationError as exc:
        parser.error(f"--set: {exc}")
    refuse_other_seeds(parser, args.seeds)
    if "heldout" in str(args.speech) + str(args.unheard):
        parser.error("development only: development sets, not held-out ones (benchmarks/SPLIT.md)")
    return args


def main() -> None:
    """Fit (or load) each seed's model, ask for every unheard name, print the classes and the figure."""
    args = _arguments()
    accepted = read_names(args.accepted)
    unheard, left_out = never_heard(read_names(args.unheard), read_speech(args.speech))
    if left_out:
        print(f"left out (said by {args.speech.name}): {', '.join(left_out)}")
    scores: dict[tuple, list[float]] = defaultdict(list)
    classes: Counter = Counter()
    rows: dict[tuple[str, str], list[str]] = defaultdict(list)
    per_seed: dict[int, float] = {}
    own: Counter = Counter()  # failed queries, and those whose place has an own known name placed right
    for seed in args.seeds:
        seed_scores: dict[tuple, list[float]] = defaultdict(list)
        for index, home in enumerate(args.homes):
            params, e, vocabulary, env = fitted(args, args.speech, seed, home, index, accepted)
            for place, names in unheard.items():
                if place not in env.ground_truth.regions.places:
                    continue
                for name in names:
                    kind, value, used, how = classify(params, e, vocabulary, env, place, name, seed,
                                                      accepted.get(place, ()))
                    seed_scores[(home, place)].append(value)
                    classes[kind] += 1
                    rows[(place, name)].append(f"{used} ({how or '-'}) {value:.1f} {kind}")
                    if args.own_names and kind != "right":
                        placed, among, _ = own_names_placed(params, e, vocabulary, env, place, seed,
                                                            accepted.get(place, ()))
                        own["failed"] += 1
                        own["an own name placed right"] += placed > 0
                        own["an own name among the candidates"] += among > 0
        for k, v in seed_scores.items():
            scores[k].extend(v)
        per_seed[seed] = float(np.mean([np.mean(v) for v in seed_scores.values()]))
    a_p = float(np.mean([np.mean(v) for v in scores.values()]))
    for (place, name), outcomes in rows.items():
        print(f"{place:12s} {name:18s} " + " | ".join(outcomes))
    total = sum(classes.values())
    print(f"classes of {total} queries: " + ", ".join(f"{c} {classes[c]}" for c in CLASSES))
    print(f"never heard A_p {a_p:.3f} (per seed " + ", ".join(f"{v:.3f}" for v in per_seed.values())
          + f"), refused {classes['refused']} of {total}")
    if args.own_names:
        print(f"failed queries whose place has an own known name that where places right: "
              f"{own['an own name placed right']} of {own['failed']}; one among the look-up's candidates: "
              f"{own['an own name among the candidates']} of {own['failed']}")
    if args.json:
        table = {f"{p}/{n}": o for (p, n), o in rows.items()}
        out = {"A_p": a_p, "per_seed": per_seed, "classes": dict(classes), "queries": total, "rows": table}
        if args.own_names:
            out["own_names"] = dict(own)
        args.json.write_text(json.dumps(out, indent=1), encoding="utf-8")


if __name__ == "__main__":
    main()
