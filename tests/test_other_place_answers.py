"""``benchmarks/other_place_answers.py`` (why a view answers another place's name): the causes on hand-made
shares, and the room account's terms it reports put back together against the robot's own concept
posterior (``answer_concepts``) on a small synthetic fit."""

from __future__ import annotations

import sys
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from scipy.special import logsumexp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from other_place_answers import CAUSES, HOLDS, _room_terms, cause, concept_holdings, summary


def test_each_wrong_answer_gets_one_cause_in_order() -> None:
    assert cause(0.4, 0.4, 1.0) == "i merge"  # both places in the concept, whatever the room
    assert cause(HOLDS, HOLDS, 0.0) == "i merge"
    assert cause(0.8, 0.1, 0.0) == "iv name share"  # the right kind of concept
    assert cause(0.1, 0.9, 0.2) == "ii region"  # another room's concept, the pose in another room
    assert cause(0.1, 0.9, 0.9) == "iii view"  # another room's concept, the pose in this place's room
    assert cause(0.49, 0.0, 0.5) == "iii view"
    assert set(CAUSES) == {"i merge", "iv name share", "ii region", "iii view"}


def test_summary_counts_views_per_class_and_cause() -> None:
    rows = [{"class": "b", "cause": "i merge", "said": True, "named": 1, "terms": {}},
            {"class": "c", "cause": "iii view", "said": False, "named": 2,
             "terms": {"prior": 1.0, "room views": 5.0, "view": -2.0}},
            {"class": "c", "cause": "iii view", "said": False, "named": None,
             "terms": {"prior": 0.0, "room views": 0.0, "view": 0.0}}]
    out = summary(rows)
    assert out["causes"]["b"]["i merge"] == 1 and out["causes"]["c"]["iii view"] == 2
    assert out["v said"] == {"b": 1, "c": 0}
    assert out["iii leading term"] == {"room views": 1}
    assert out["no naming concept"] == 1


@pytest.fixture(scope="module")
def fitted():
    """A joint fit of three taught synthetic homes and an untaught one (D = 64, 6 sweeps, seed 0)."""
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.model import SpCoTransfer

    corpus = generate_homes(4, seed=2, config=SyntheticConfig(n_features=64), new_homes=1,
                            specific_rooms=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = SpCoTransfer(variant="exact", prune_words=True, n_iterations=6, random_state=0).fit(corpus)
    return corpus, model


def test_the_terms_put_back_together_are_the_robots_concept_posterior(fitted) -> None:
    """P(l | x, v) ∝ Σ_k p(k | x) p(l | room k) p(v | l), with p(l | room k) ∝ G_0 · the room's pooled
    views: the script's pieces give ``answer_concepts`` back (a wrong prior, room term or view term
    would not)."""
    from spco.model.confidence import answer_concepts

    corpus, model = fitted
    e = len(corpus) - 1
    env = list(corpus)[e]
    answer, rooms, _ = model.answer_inputs(e)
    rows = np.flatnonzero(env.is_test)
    positions, visual = env.positions[rows], env.visual[rows]
    view_counts = model.settings_.view_counts
    want = answer_concepts(answer, e, positions, visual, view_counts=view_counts, rooms=rooms,
                           settings=model.hyperparameters_.answer_settings())
    log_k, region_of, room_views, view, prior = _room_terms(answer, rooms, e, positions, visual, view_counts)
    assert np.allclose(logsumexp(log_k, axis=1), 0.0)
    assert region_of.size == room_views.shape[0] == log_k.shape[1]
    room = prior[None, :] + room_views
    room = room - logsumexp(room, axis=1, keepdims=True)
    joint = logsumexp(log_k[:, :, None] + room[None, :, :], axis=1) + view
    got = np.exp(joint - logsumexp(joint, axis=1, keepdims=True))
    assert np.allclose(got, want, atol=1e-10)
    flat = np.exp((joint - view) - logsumexp(joint - view, axis=1, keepdims=True))  # the view left out
    assert not np.allclose(flat, want, atol=1e-3)


def test_concept_holdings_count_the_other_homes_taught_samples(fitted) -> None:
    """Each concept's places over the other homes, against a count by hand."""
    from spco.data.language import normalize_name

    corpus, model = fitted
    e = len(corpus) - 1
    held = concept_holdings(model, corpus, e)
    want = [Counter() for _ in held]
    for h, env in enumerate(corpus):
        if h == e:
            continue
        train = [i for i, test in enumerate(env.is_test) if not test]
        sentences = env.training_data().sentences
        for j, i in enumerate(train):
            label = env.ground_truth.labels[i]
            if label is not None and sentences[j] is not None:
                want[int(model.concepts_[h][j])][normalize_name(label)] += 1
    assert held == want
    assert sum(sum(c.values()) for c in held) > 0
