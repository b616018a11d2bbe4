"""Where the written development sets' errors come from (issue 28): every wrong ``what`` and every
missed ``where`` of ``benchmarks/free_speech.py`` on a written speech set, classified, view by view.

The fits and scores are ``free_speech.py``'s (the paper's 16 experienced homes taught with sentences of
``--speech`` drawn by seed, the new home untaught, SpCoTransfer+MI, the trial seed of
:func:`~spco.evaluation.experiments.trial_seed`, the robot's answers
:func:`~spco.evaluation.evaluate_answers`); the classes are ``speech_errors.py``'s
(:func:`speech_errors.classify_answer`, :func:`speech_errors.where_miss_class`), with "said here"
read from the taught sentences of this set. Development only: the new home is 3LDK_9 by default
(1LDK_9 and 2LDK_9 are held out, benchmarks/SPLIT.md) and seeds outside the development seeds
(0–99 and 200–399) are refused.

Each wrong answer is printed with the view's top three names and their probabilities, the concept the view
is drawn to, and the places of that concept's taught samples; each missed ``where`` with the place its
positions landed in.

Run (development)::

    nice -n 5 python benchmarks/written_errors.py --speech benchmarks/development/speech_dev_words.csv \\
        --seeds 0 1 2 3 4 --sweeps 60 --json /tmp/written_errors.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from data_paths import SIGVERSE
from free_speech import (
    fit_new_home,
    new_home,
    read_names,
    read_speech,
    settings_hyperparameters,
    taught_homes,
)
from natural_speech import place_speech
from speech_errors import _answers, _misses
from split_seeds import refuse_other_seeds

from spco.data import Corpus
from spco.data.language import normalize_name
from spco.evaluation import evaluate_answers
from spco.model.confidence import answer_names
from spco.model.prediction import concept_posterior


def _views(model, corpus: Corpus, e: int, env, accepted: dict, out: list[dict], seed: int) -> None:
    """Every wrong test view of home ``e``: its place, the top three answers, its concept and the
    places of the concept's taught samples, into ``out``."""
    rows = np.flatnonzero(env.is_test)
    answer, rooms, weighting = model.answer_inputs(e)
    pred = answer_names(answer, e, corpus.vocabulary, env.positions[rows], env.visual[rows], top_k=3,
                        weighting=weighting, view_counts=model.settings_.view_counts, rooms=rooms,
                        settings=model.hyperparameters_.answer_settings())
    post = concept_posterior(model.parameters_, e, env.positions[rows], env.visual[rows], True, True,
                             view_counts=model.settings_.view_counts)
    labels = [env.ground_truth.labels[i] for i in rows]
    for i, label in enumerate(labels):
        if label is None:
            continue
        top = [str(w) for w in pred.words[i]]
        if top[0] in env.ground_truth.accepted(label):
            continue
        k = int(np.argmax(post[i]))
        places: Counter = Counter()
        for h, home in enumerate(corpus):
            if h == e:
                continue
            train = [lab for lab, t in zip(home.ground_truth.labels, home.is_test, strict=True) if not t]
            for c, lab in zip(model.concepts_[h], train, strict=True):
                if c == k and lab is not None:
                    places[normalize_name(lab)] += 1
        out.append({"seed": seed, "place": normalize_name(label), "top": top,
                    "p": [round(float(x), 3) for x in pred.probabilities[i]],
                    "concept": k, "p_concept": round(float(post[i, k]), 3),
                    "concept_places": dict(places.most_common(4))})


def main() -> None:
    """Fit, score, classify; print the classes and every wrong view."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sigverse", type=Path, default=SIGVERSE)
    parser.add_argument("--speech", type=Path, required=True)
    parser.add_argument("--accepted", type=Path,
                        default=Path(__file__).resolve().parent / "development" / "accepted_names_dev.json")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--sweeps", type=int, default=60)
    parser.add_argument("--home", default="3LDK_9")
    parser.add_argument("--set", nargs="+", action="extend", default=[], metavar="NAME=VALUE")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    refuse_other_seeds(parser, args.seeds)
    if args.home in ("1LDK_9", "2LDK_9") or "heldout" in str(args.speech):
        parser.error("held-out homes and sets are not scored here (benchmarks/SPLIT.md)")
    hyper = settings_hyperparameters(args.set)
    speech = read_speech(args.speech)
    accepted = read_names(args.accepted)
    regions_file = args.sigverse.parent / "sigverse_regions.json"
    table: Counter = Counter()
    words: dict[str, Counter] = defaultdict(Counter)
    views: list[dict] = []
    runs = []
    started = time.perf_counter()
    for seed in args.seeds:
        experienced = taught_homes(args.sigverse, speech, seed)
        env = new_home(args.sigverse, regions_file, args.home, accepted)
        model, corpus = fit_new_home(experienced, env, hyper, args.sweeps, seed, 0)
        e = len(corpus) - 1
        scores = evaluate_answers(model, e, env, rng=seed)
        said = place_speech(experienced, corpus)
        _answers(model, corpus, e, env, env, scores, accepted, said, table, words, args.home)
        _misses(model, corpus, e, env, scores, said, seed, table, words, args.home, accepted)
        _views(model, corpus, e, env, accepted, views, seed)
        runs.append({"seed": seed, "A_n": scores.mean_name_accuracy, "A_p": scores.mean_position_accuracy,
                     "A_n_places": scores.name_accuracy, "A_p_places": scores.position_accuracy})
        print(f"seed {seed}: A_n {scores.mean_name_accuracy:.3f} A_p {scores.mean_position_accuracy:.3f} "
              f"({time.perf_counter() - started:.0f} s)", flush=True)
    print(json.dumps(dict(table), indent=None))
    for cls, c in words.items():
        print(f"{cls}: {dict(c.most_common(30))}")
    for v in views:
        print(v)
    if args.json:
        errors = {k: dict(v) for k, v in words.items()}
        args.json.write_text(json.dumps({"seeds": args.seeds, "sweeps": args.sweeps, "runs": runs,
                                         "table": dict(table), "errors": errors, "views": views}, indent=1),
                             encoding="utf-8")


if __name__ == "__main__":
    main()
