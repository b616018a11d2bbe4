"""Sentences written by hand, as people speak, for two SIGVerse homes: the method is not tuned to
the sentences of its own generator (:mod:`spco.data.speech`).

``tests/data/handwritten_sigverse.csv`` gives 34 sentences for ``1LDK_9`` and 36 for ``2LDK_9``
(four or five per place, said at training samples; the test samples stay untaught), written freely
by a person: multi-word names ("living room", "front door", "dining room") next to one-word ones,
synonyms ("loo", "bathroom"), objects and activities, punctuation and capitals.
"""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from spco.data import Corpus, Environment
from spco.data.language import normalize_name
from spco.data.loading import load
from spco.evaluation import evaluate_answers
from spco.model import SpCoTransfer
from spco.model.position_prediction import predict_positions, region_posterior_for_name

SENTENCES = Path(__file__).parent / "data" / "handwritten_sigverse.csv"
#: Names the writer used for each place besides the place's own (accepted as right answers).
ACCEPTED = {"entrance": ("front door",), "toilet": ("loo", "restroom"), "bath": ("bathroom", "bathtub"),
            "dining": ("dining room",), "bedroom": ("master bedroom", "kids bedroom")}


def handwritten_homes(sigverse_dir: Path) -> list[Environment]:
    """1LDK_9 and 2LDK_9 taught the hand-written sentences (nothing else), with accepted names."""
    with open(SENTENCES, encoding="utf-8", newline="") as fh:
        rows = list(csv.DictReader(fh))
    homes = []
    for name in ("1LDK_9", "2LDK_9"):
        env = load(sigverse_dir / name)[name]
        said = {int(r["id"]): r["sentence"] for r in rows if r["home"] == name}
        assert not any(env.is_test[env.index_of(i)] for i in said)
        gt = env.ground_truth
        assert gt is not None
        accepted = {normalize_name(p): tuple(map(normalize_name, names)) for p, names in ACCEPTED.items()}
        homes.append(replace(env.with_sentences([said.get(int(i)) for i in env.ids]),
                             ground_truth=replace(gt, accepted_names=accepted)))
    return homes


def handwritten_development_homes(sigverse_dir: Path, sources: tuple[str, ...] = ("1LDK_9", "2LDK_9")
                                  ) -> list[Environment]:
    """The hand-written sentences said at the same places of the **development** home 3LDK_9: two
    copies of it, one taught 1LDK_9's sentences, one 2LDK_9's (``sources``), each sentence at a
    training sample of 3LDK_9 with the label of the sample it was written for (1LDK_9 and 2LDK_9 are held out:
    benchmarks/SPLIT.md; their labels are read only to place the sentences, nothing is scored on
    them). ``benchmarks/handwritten.py`` scores the sentences in their own homes."""
    with open(SENTENCES, encoding="utf-8", newline="") as fh:
        rows = list(csv.DictReader(fh))
    dev = load(sigverse_dir / "3LDK_9")["3LDK_9"]
    free: dict[str | None, list[int]] = {}
    for i, (label, test) in enumerate(zip(dev.labels(), dev.is_test, strict=True)):
        if not test:
            free.setdefault(label, []).append(int(dev.ids[i]))
    gt = dev.ground_truth
    assert gt is not None
    accepted = {normalize_name(p): tuple(map(normalize_name, names)) for p, names in ACCEPTED.items()}
    homes = []
    for source in sources:
        written_for = load(sigverse_dir / source)[source]
        labels = written_for.labels()
        places = {label: list(ids) for label, ids in free.items()}
        said = {}
        for r in rows:
            if r["home"] == source:
                label = labels[written_for.index_of(int(r["id"]))]
                if places.get(label):
                    said[places[label].pop(0)] = r["sentence"]
        homes.append(replace(dev.with_sentences([said.get(int(i)) for i in dev.ids]), name=f"3LDK_9_{source}",
                             ground_truth=replace(gt, accepted_names=accepted)))
    return homes


@pytest.mark.sigverse
def test_handwritten_sentences_name_and_find_the_places(sigverse_dir: Path) -> None:
    """Scored on the development home 3LDK_9 only (a unit test scores no held-out home), two copies
    taught 1LDK_9's and 2LDK_9's hand-written sentences."""
    corpus = Corpus(handwritten_development_homes(sigverse_dir))
    vocab = corpus.vocabulary
    assert {"living room", "front door", "dining room"} <= set(vocab.terms)  # learnt, not listed
    model = SpCoTransfer(n_iterations=40, random_state=0, prune_words=True).fit(corpus)
    params = model.parameters_
    accuracy = []
    for e, env in enumerate(corpus):
        # one place however the name is written
        same = [region_posterior_for_name(params, e, vocab, n) for n in ("living room", "Living Room",
                                                                          "living-room")]
        assert all(np.array_equal(same[0], s) for s in same[1:])
        regions = env.ground_truth.regions  # type: ignore[union-attr]
        where = predict_positions(params, e, vocab, "Living Room", n=50, rng=0)
        assert where.name == "living room"
        assert regions.contains("living room", where.samples[:, :2]).mean() >= 0.8
        # names as the robot answers them (evaluate_answers, the experiments' one scoring): the fit's own
        # parameters ranked by MI are no answer, and their best word at a view is an object in some
        # chains (seed 0 of this fit: "fridge" at the kitchen once "bathroom" and "toilet" kept their
        # name evidence; main's at seeds 3 and 4: "i", "hot"), where the robot's answers name places
        # at seeds 0-4 before and after
        scores = evaluate_answers(model, e, env, rng=0)
        # the living room's test samples are named "living room" (the term), never "room"
        living = [p for p, lab in zip(scores.predicted_names, scores.labels, strict=True)
                  if lab == "living room"]
        assert "room" not in living
        # no test sample is named by a word that names no place: not the pronoun "we" said at six places
        # of seven uses, nor "is", "our" (the naming rule judges them spread; before it, the model
        # answered "we" at four bath views of 1LDK_9)
        gt = env.ground_truth
        assert gt is not None
        place_names = {name for place in gt.places for name in gt.accepted(place)}
        assert set(scores.predicted_names) <= place_names, scores.predicted_names
        # a floor on the mean of the two copies, not a figure (figures: benchmarks/handwritten.py, over
        # seeds); 3LDK_9 has more rooms than the sentences name (its other bedrooms and second toilet
        # are answered by the one taught place)
        print(f"{env.name}: A_n {scores.mean_name_accuracy:.3f}, A_p {scores.mean_position_accuracy:.3f}")
        accuracy.append((scores.mean_name_accuracy, scores.mean_position_accuracy))
    a_n, a_p = np.mean(accuracy, axis=0)
    assert a_n >= 0.7 and a_p >= 0.7, accuracy
