"""Where 3LDK_9's missed ``where`` land, and why (issue 28, branch words13): a diagnosis of the development
configuration of ``benchmarks/natural_speech.py`` (3LDK_9 the new home; its three bedrooms untaught).

For each seed the fit of ``benchmarks/speech_errors.py`` (same trial seed, sweeps, ``--set``,
``--cache``) is read for: every missed ``where`` (score below 0.5) whose answer lands in one of the untaught
bedrooms, with the concept answered and the asked place's own concept: G_e (the concept's weight in 3LDK_9),
θ^w_e(name) (the answer's parameters) and their product; and, over the seeds, how many of the bedrooms'
training samples sit outside a bedroom concept (less than half of its knowledge samples bedrooms), and how
many of those in a concept whose top name in 3LDK_9 is an accepted name of one of its other places.
``--start-part`` keeps only one of the two things the words' start (``--set warm_start=words``) does
(:func:`spco.model.word_channels.warm_start_settings`):
``weight`` (the start's token weight W^w / S^w, no ``start_not_names``) or ``objects`` (``start_not_names``,
token weight 1) — an ablation for the diagnosis, not a setting. Development seeds only (0–99).

Run (development)::

    python benchmarks/where_landings.py --seeds 0 1 2 --set warm_start=words --cache /tmp/fits
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from free_speech import read_names
from natural_speech import configurations, fit_arguments, fitted
from speech_errors import place_of_samples
from split_seeds import refuse_other_seeds

import spco.model.transfer as transfer
from spco.data import Corpus
from spco.data.language import normalize_name
from spco.evaluation import evaluate_answers
from spco.evaluation.metrics import position_accuracy
from spco.model.position_prediction import predict_positions
from spco.model.prediction import UnknownNameError

#: 3LDK_9's untaught bedrooms (its drawn regions).
BEDROOMS = ("emma's room", "father's room", "mother's room")

#: 3LDK_9's taught places whose ``where`` is scored.
PLACES = ("toilet", "bath", "washroom", "dining", "kitchen", "living room", "entrance")


def only_part(part: str):
    """:func:`~spco.model.word_channels.warm_start_settings` keeping only ``part`` of the words' start:
    ``"weight"`` (no ``start_not_names``) or ``"objects"`` (token weight 1)."""
    original = transfer.warm_start_settings

    def settings(start, hyper, evidence, vocabulary, word_increment, lexicon=None):
        out = original(start, hyper, evidence, vocabulary, word_increment, lexicon)
        if out is start:
            return out
        if part == "weight":
            return replace(out, start_not_names=start.start_not_names)
        return replace(out, word_weight=start.word_weight)

    return settings


def _parser() -> argparse.ArgumentParser:
    """The command line: speech_errors.py's fit options (the same fits, the same cache) and --start-part."""
    parser = fit_arguments(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--start-part", choices=("both", "weight", "objects"), default="both",
                        help="with --set warm_start=words: keep only one part of the words' start (a part "
                        "other than both needs a --cache directory of its own)")
    return parser


def _labels(env) -> np.ndarray:
    """The place label of each training sample of a knowledge home."""
    train = ~env.is_test
    return np.array([normalize_name(lab) if lab else None
                     for lab, t in zip(env.ground_truth.labels, train, strict=True) if t], dtype=object)


class Home:
    """3LDK_9's configuration: the corpus, the places of its training samples, the knowledge homes' labels."""

    def __init__(self, args: argparse.Namespace, accepted: dict) -> None:
        # natural_speech.py's labels with the homes held out: 3LDK_9's trial seed index is 0 either way
        _, configs = configurations(args.sigverse, accepted, leave_one_out=True)
        self.labels = [c[0] for c in configs]
        self.label, homes, self.env = configs[0]
        self.corpus = Corpus([*homes, self.env])
        self.e = len(self.corpus) - 1
        self.words = list(self.corpus.vocabulary.words)
        areas = self.env.ground_truth.regions
        self.places = place_of_samples(areas, [normalize_name(p) for p in areas.places],
                                       self.env.training_data().positions[:, :2])
        self.beds = np.isin(self.places, BEDROOMS)
        self.other_names = {n for p in PLACES for n in accepted[p]}
        self.known = [_labels(self.corpus[h]) for h in range(self.e)]

    def knowledge(self, model, c: int) -> Counter:
        """The knowledge homes' place labels of concept ``c``'s samples."""
        know: Counter = Counter()
        for h in range(self.e):
            know.update(self.known[h][model.concepts_[h] == c].tolist())
        return know

    def concept(self, model, params, k: int, c: int) -> str:
        """Concept ``c`` as the answer weighs it for word ``k``, and what it holds."""
        g, t = params.concept_weights[self.e, c], params.word_probabilities[self.e, c, k]
        here = Counter(self.places[model.concepts_[self.e] == c].tolist())
        return (f"c{c} θ^w {t:.3f} × G_e {g:.3f} = {t * g:.4f}; knowledge "
                f"{dict(self.knowledge(model, c).most_common(3))}; 3LDK_9 {dict(here)}")

    def landings(self, model, seed: int) -> None:
        """Print the missed ``where`` of one fit that land in an untaught bedroom."""
        params, rooms, _ = model.answer_inputs(self.e)
        vocab, areas, own = self.corpus.vocabulary, self.env.ground_truth.regions, model.concepts_[self.e]
        for place in PLACES:
            names = [n for i, n in enumerate(self.env.ground_truth.accepted(place))
                     if i == 0 or vocab.index(n) is not None]
            if len(names) > 1 and vocab.index(place) is None:
                names = names[1:]
            for name in names:
                try:
                    pred = predict_positions(params, self.e, vocab, name, n=10, rng=seed, unheard=False,
                                             rooms=rooms, view_counts=model.settings_.view_counts,
                                             lookup=model.parameters_.word_mask)
                except UnknownNameError:
                    continue
                if position_accuracy({place: pred.samples}, areas)[place] >= 0.5:
                    continue
                inside = rooms.regions == pred.region
                landed = Counter(self.places[inside].tolist()).most_common(1)[0][0]
                if landed not in BEDROOMS:
                    continue
                k = vocab.index(name)
                answered = Counter(rooms.concepts[inside].tolist()).most_common(1)[0][0]
                right = Counter(own[self.places == place].tolist()).most_common(1)[0][0]
                print(f"seed {seed}: where {name!r} ({place}) -> {landed}\n"
                      f"  answered {self.concept(model, params, k, answered)}\n"
                      f"  place's  {self.concept(model, params, k, right)}")

    def outside(self, model) -> tuple[int, int, list[float]]:
        """The bedroom samples outside a bedroom concept, those in a concept named for another place of
        3LDK_9, and such concepts' G_e."""
        params, _, _ = model.answer_inputs(self.e)
        out = hazard = 0
        weights: list[float] = []
        for c, n in Counter(model.concepts_[self.e][self.beds].tolist()).items():
            know = self.knowledge(model, c)
            total = sum(know.values())
            if total and know.get("bedroom", 0) / total >= 0.5:
                continue
            out += n
            if self.words[int(np.argmax(params.word_probabilities[self.e, c]))] in self.other_names:
                hazard += n
                weights.append(float(params.concept_weights[self.e, c]))
        return out, hazard, weights


def main() -> None:
    """Fit (or read) each seed's 3LDK_9 fit and print its A_n and A_p (as speech_errors.py), its bedroom
    landings and the seeds' bedroom concepts."""
    parser = _parser()
    args = parser.parse_args()
    refuse_other_seeds(parser, args.seeds)
    if args.start_part != "both":
        transfer.warm_start_settings = only_part(args.start_part)
    home = Home(args, read_names(args.accepted))
    outside = hazard = 0
    weights: list[float] = []
    for seed in args.seeds:
        model = fitted(home.corpus, seed, home.label, home.labels, settings=args.set, sweeps=args.sweeps,
                       cache=args.cache)
        scores = evaluate_answers(model, home.e, home.env, rng=seed)  # as speech_errors.py scores 3LDK_9
        print(f"seed {seed}: A_n {scores.mean_name_accuracy:.3f} A_p {scores.mean_position_accuracy:.3f}")
        home.landings(model, seed)
        o, h, w = home.outside(model)
        outside, hazard, weights = outside + o, hazard + h, weights + w
    asked = int(home.beds.sum()) * len(args.seeds)
    print(f"\nbedroom samples outside a bedroom concept: {outside} of {asked}; "
          f"in a concept named for another place: {hazard} ({len(weights)} concept-fits, G_e mean "
          f"{np.mean(weights) if weights else float('nan'):.3f})")


if __name__ == "__main__":
    main()
