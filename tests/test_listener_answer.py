"""``name_answer="listener"``: the robot answers the name a listener takes to mean the concept it is in,
S(w | x, v) ∝ Σ_l P(l | x, v) θ^w_{l,w} L(l | w), L(l | w) ∝ G_l θ^w_{l,w} — against brute force on
hand-built parameters, and the setting's plumbing (hyperparameters, answer weighting, a fit)."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.model.confidence import answer_weighting
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.parameters import ConceptParameters
from spco.model.prediction import listener_weights, predict_names

WORDS = ("this", "kitchen", "washroom", "bathroom", "bath")
VOCAB = Vocabulary(WORDS)


def params(theta_w: np.ndarray, g: np.ndarray) -> ConceptParameters:
    """One home, L concepts each in its own region, V = 5 words, D = 4."""
    L = theta_w.shape[0]
    means = np.zeros((L, 4))
    means[:, 0] = 3.0 * np.arange(L)
    means[:, 3] = 1.0
    covs = np.broadcast_to(np.eye(4) * 0.2, (L, L, 4, 4)).copy()[0]
    theta_v = np.full((L, 4), 0.25)
    return ConceptParameters(
        concept_weights=g[None], region_weights=(np.full((L, L), 0.05) + np.eye(L))[None] / (1 + 0.05 * L),
        region_means=means[None], region_covariances=covs[None], word_probabilities=theta_w[None],
        visual_probabilities=theta_v[None], shared_word_probabilities=theta_w,
        shared_visual_probabilities=theta_v, global_concept_weights=g, word_mask=np.ones(5, dtype=bool),
        region_counts=np.full((1, L), 20))


def brute_listener(theta: np.ndarray, g: np.ndarray) -> np.ndarray:
    """L(l | w) by loops."""
    L, V = theta.shape
    out = np.zeros((L, V))
    for w in range(V):
        total = sum(g[m] * theta[m, w] for m in range(L))
        for c in range(L):
            out[c, w] = g[c] * theta[c, w] / total if total > 0 else 0.0
    return out


def test_the_listener_against_loops() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        theta = rng.dirichlet(np.full(5, 0.5), size=3)
        theta[:, 4] = 0.0  # a word no concept says
        theta /= theta.sum(axis=1, keepdims=True)
        g = rng.dirichlet(np.ones(3))
        got = listener_weights(theta, g)
        assert np.allclose(got, brute_listener(theta, g), atol=1e-12)
        assert np.allclose(got[:, :4].sum(axis=0), 1.0) and not got[:, 4].any()
    tiny = np.array([[1e-300, 0.5], [1e-300, 0.5]])  # log space: no underflow to 0/0
    assert np.allclose(listener_weights(tiny, np.array([0.25, 0.75]))[:, 0], [0.25, 0.75])


def test_listener_scores_against_brute_force() -> None:
    """predict_names' scores with weighting="listener" are Σ_l P(l | obs) θ_{l,w} L(l | w), by loops, for
    any concept posterior given; the probabilities stay p(w | obs)."""
    rng = np.random.default_rng(1)
    theta = rng.dirichlet(np.ones(5), size=3)
    g = np.array([0.5, 0.3, 0.2])
    p = params(theta, g)
    concepts = rng.dirichlet(np.ones(3), size=6)
    pred = predict_names(p, 0, VOCAB, np.zeros((6, 4)), None, top_k=5, weighting="listener",
                         use_vision=False, concepts=concepts)
    said = predict_names(p, 0, VOCAB, np.zeros((6, 4)), None, top_k=5, weighting="none",
                         use_vision=False, concepts=concepts)
    lis = brute_listener(theta, g)
    for i in range(6):
        want = [sum(concepts[i, c] * theta[c, w] * lis[c, w] for c in range(3)) for w in range(5)]
        assert list(pred.indices[i]) == list(np.argsort(-np.asarray(want), kind="stable"))
        assert np.allclose(pred.scores[i], np.asarray(want)[pred.indices[i]])
        assert np.allclose(pred.word_probabilities[i], said.word_probabilities[i])
    assert pred.weighting == "listener"


def test_a_name_mostly_anothers_comes_behind_the_concepts_own() -> None:
    """The washroom's people say "kitchen" more than "washroom" (as in the development homes); the
    kitchen concept says "kitchen" only. At the washroom "said" answers "kitchen", "listener" answers
    "washroom"; at the kitchen both answer "kitchen"; with one concept the two agree."""
    theta = np.array([[0.0, 0.9, 0.0, 0.0, 0.1],     # kitchen concept
                      [0.05, 0.4, 0.3, 0.25, 0.0]])  # washroom concept
    g = np.array([0.5, 0.5])
    p = params(theta, g)
    at = np.array([[0.02, 0.98], [0.98, 0.02]])  # at the washroom, at the kitchen
    kw = {"top_k": 1, "use_vision": False, "concepts": at}
    said = predict_names(p, 0, VOCAB, np.zeros((2, 4)), None, weighting="none", **kw)
    heard = predict_names(p, 0, VOCAB, np.zeros((2, 4)), None, weighting="listener", **kw)
    assert list(said.words[:, 0]) == ["kitchen", "kitchen"]
    assert list(heard.words[:, 0]) == ["washroom", "kitchen"]
    one = params(theta[1:], np.array([1.0]))
    kw1 = {"top_k": 5, "use_vision": False, "concepts": np.ones((1, 1))}
    assert list(predict_names(one, 0, VOCAB, np.zeros((1, 4)), None, weighting="none", **kw1).indices[0]) \
        == list(predict_names(one, 0, VOCAB, np.zeros((1, 4)), None, weighting="listener", **kw1).indices[0])


def test_the_setting() -> None:
    hyper = TransferHyperparameters()
    assert hyper.name_answer == "said" and "name_answer" not in hyper.to_dict()
    listener = hyper.with_settings(["name_answer=listener"])
    assert listener.name_answer == "listener" and listener.to_dict()["name_answer"] == "listener"
    assert TransferHyperparameters.from_dict(listener.to_dict()) == listener
    with pytest.raises(ConfigurationError, match="name_answer"):
        hyper.with_settings(["name_answer=heard"])
    with pytest.raises(ConfigurationError, match="name_answer"):
        replace(hyper, name_answer="loudest")
    assert answer_weighting("exact", True) == "none"
    assert answer_weighting("exact", True, "listener") == "listener"
    assert answer_weighting("exact", False, "listener") == "mi"  # without pruning: MI, as before
    assert answer_weighting("reference", True, "listener") == "reference"


def test_a_fit_answers_as_its_setting_says() -> None:
    """The same seed gives the same fit with either setting (the fit does not read it); only the
    answers' ranking differs, by the weighting the model reports."""
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.model import SpCoTransfer

    corpus = generate_homes(3, seed=4, new_homes=1, specific_rooms=False,
                            config=SyntheticConfig(n_features=64, n_train=5, n_test=2))
    fits = []
    for setting in ("said", "listener"):
        hyper = TransferHyperparameters(name_answer=setting)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fits.append(SpCoTransfer(hyper, variant="exact", prune_words=True, n_iterations=3,
                                     random_state=0).fit(corpus))
    assert [f.name_weighting() for f in fits] == ["none", "listener"]
    a, b = (f.parameters_ for f in fits)
    assert np.array_equal(a.word_probabilities, b.word_probabilities)
    assert np.array_equal(a.region_means, b.region_means)
    env = list(corpus)[-1]
    rows = np.flatnonzero(env.is_test)
    names = [f.predict_names(len(corpus) - 1, env.positions[rows], env.visual[rows], top_k=1) for f in fits]
    assert names[1].weighting == "listener" and names[0].weighting == "none"
