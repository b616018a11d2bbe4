"""benchmarks/rooms_specific.py's ``--diagnose`` (:func:`rooms_specific.diagnose`): where each room is in a
fit, read from the fit's own state and the robot's own answer functions.

A short synthetic fit (three homes, the new one with "emma's room" taught at half of its bedroom's
training samples): the taught and untaught training samples are told apart by the new home's sentences
(not by the fit's word rows the function reads), and each recorded concept and answer is the one the
library computes for those samples.
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import rooms_specific

from spco.data.environment import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.evaluation.specific_file import Room
from spco.model.answer_settings import AnswerSettings
from spco.model.confidence import answer_names
from spco.model.driver import LocalEngine
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.prediction import concept_posterior
from spco.model.transfer import SpCoTransfer


@pytest.fixture(scope="module")
def fitted():
    homes = list(generate_homes(3, seed=4, new_homes=1, config=SyntheticConfig(n_features=64, n_train=8),
                                specific_rooms=False))
    new = homes[-1]
    labels = np.asarray(new.ground_truth.labels)
    train = np.flatnonzero(~new.is_test & (labels == "bedroom"))
    taught = set(train[::2].tolist())
    new = new.with_sentences(["this is emma's room" if i in taught else s
                              for i, s in enumerate(new.sentences)])
    corpus = Corpus([*homes[:-1], new])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = SpCoTransfer(TransferHyperparameters(), n_iterations=12, random_state=5,
                             prune_words=True).fit(corpus, engine=LocalEngine(1))
    room = Room(name="emma's room", form="possessive", owner="emma", replaces="bedroom",
                accepted=("emma's room", "emma"), train_ids=tuple(int(new.ids[i]) for i in train),
                test_ids=tuple(int(new.ids[i]) for i in np.flatnonzero(new.is_test & (labels == "bedroom"))),
                taught={}, region=None)
    return model, len(corpus) - 1, new, room, train, taught


def test_diagnose_reads_the_fit_and_the_answers(fitted) -> None:
    model, e, new, room, train, taught = fitted
    out = rooms_specific.diagnose(model, e, new, [room], model.name_weighting())
    json.dumps(out)  # a record's part
    d = out[room.name]
    row = {int(i): r for r, i in enumerate(new.training_data().ids)}  # the fit's rows of the home
    concepts = np.asarray(model.concepts_[e])
    said = [concepts[row[int(new.ids[i])]] for i in train if int(i) in taught]
    unsaid = [concepts[row[int(new.ids[i])]] for i in train if int(i) not in taught]
    assert d["taught"] == [int(c) for c in said] and len(said) == len(taught)
    assert d["untaught"] == [int(c) for c in unsaid]
    assert d["untaught_with_taught"] == pytest.approx(np.mean(np.isin(unsaid, said)), abs=1e-4)
    params, rooms, weighting = model.answer_inputs(e)
    test = np.array([int(np.flatnonzero(new.ids == i)[0]) for i in room.test_ids])
    w = model.settings_.view_counts
    view = concept_posterior(params, e, new.positions[test], new.visual[test], view_counts=w)
    assert d["view_concepts"] == view.argmax(axis=1).tolist()
    in_room = answer_names(params, e, model.vocabulary_, new.positions[test], new.visual[test], top_k=1,
                           weighting=weighting, view_counts=w, rooms=rooms,
                           settings=AnswerSettings(view_in_room=True))
    assert d["view_in_room"] == [str(x) for x in in_room.words[:, 0]]
    assert d["view_in_room_correct"] == [int(room.is_accepted(str(x))) for x in in_room.words[:, 0]]
    assert set(d["theta_accepted"]) == set(np.unique(said).tolist())
