"""``name_answer="looks"``: the pragmatic speaker of ``name_answer="listener"`` with a listener that takes
concepts that look alike as one referent, S(w | x, v) ∝ Σ_l P(l | x, v) θ^w_{l,w} Σ_l' s(l, l') L(l' | w),
s(l, l') = BC(φ^v_l, φ^v_l')^n — against brute force on hand-built parameters, and the setting's plumbing."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from test_listener_answer import brute_listener, params

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.model.confidence import answer_weighting
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.prediction import looks_kernel, predict_names

WORDS = ("this", "kitchen", "washroom", "bathroom", "bath")
VOCAB = Vocabulary(WORDS)


def brute_kernel(phi: np.ndarray, n: float) -> np.ndarray:
    """s(l, l') by loops: (Σ_d sqrt(φ_{l,d} φ_{l',d}))^n."""
    L, D = phi.shape
    out = np.zeros((L, L))
    for a in range(L):
        for b in range(L):
            out[a, b] = sum(math.sqrt(phi[a, d] * phi[b, d]) for d in range(D)) ** n
    return out


def with_looks(theta: np.ndarray, g: np.ndarray, phi: np.ndarray):
    return replace(params(theta, g), shared_visual_probabilities=phi)


def test_the_kernel_against_loops() -> None:
    rng = np.random.default_rng(0)
    for n in (None, 1.0, 16.0, 0.5):
        phi = rng.dirichlet(np.full(6, 0.7), size=4)
        phi[1, 2] = 0.0  # a feature one concept never shows
        phi[1] /= phi[1].sum()
        got = looks_kernel(phi, n)
        want = brute_kernel(phi, 1.0 if n is None else n)
        assert np.allclose(got, want, rtol=1e-10, atol=1e-300)
        assert np.allclose(np.diag(got), 1.0) and np.allclose(got, got.T)
        assert np.all(got > 0) and np.all(got <= 1.0)
    far = np.array([[1.0 - 1e-12, 1e-12], [1e-12, 1.0 - 1e-12]])  # log space: a tiny coefficient, not 0/0
    assert 0.0 < looks_kernel(far, 1.0)[0, 1] < 1e-5
    with pytest.raises(ConfigurationError, match="view_counts"):
        looks_kernel(phi, 0.0)
    with pytest.raises(ConfigurationError, match="shared_visual"):
        looks_kernel(phi[0], 1.0)


def test_looks_scores_against_brute_force() -> None:
    """predict_names' scores with weighting="looks" are Σ_l P(l | obs) θ_{l,w} Σ_l' s(l, l') L(l' | w), by
    loops, for any concept posterior; the probabilities stay p(w | obs)."""
    rng = np.random.default_rng(1)
    for view_counts in (1.0, 16.0):
        theta = rng.dirichlet(np.ones(5), size=3)
        g = np.array([0.5, 0.3, 0.2])
        phi = rng.dirichlet(np.full(4, 2.0), size=3)
        p = with_looks(theta, g, phi)
        concepts = rng.dirichlet(np.ones(3), size=6)
        kw = {"top_k": 5, "use_vision": False, "concepts": concepts, "view_counts": view_counts}
        pred = predict_names(p, 0, VOCAB, np.zeros((6, 4)), None, weighting="looks", **kw)
        said = predict_names(p, 0, VOCAB, np.zeros((6, 4)), None, weighting="none", **kw)
        lis = brute_listener(theta, g)
        s = brute_kernel(phi, view_counts)
        for i in range(6):
            want = [sum(concepts[i, c] * theta[c, w] * sum(s[c, m] * lis[m, w] for m in range(3))
                        for c in range(3)) for w in range(5)]
            assert list(pred.indices[i]) == list(np.argsort(-np.asarray(want), kind="stable"))
            assert np.allclose(pred.scores[i], np.asarray(want)[pred.indices[i]])
            assert np.allclose(pred.word_probabilities[i], said.word_probabilities[i])
        assert pred.weighting == "looks"


def test_the_limits_are_the_listener_and_the_said_answer() -> None:
    """Concepts that look nothing alike: the listener's scores; concepts that look the same: s = 1, so
    Σ_l' L(l' | w) = 1 for every word said and the answer is the said one."""
    rng = np.random.default_rng(2)
    theta = rng.dirichlet(np.ones(5), size=3)
    g = np.array([0.2, 0.3, 0.5])
    concepts = rng.dirichlet(np.ones(3), size=4)
    kw = {"top_k": 5, "use_vision": False, "concepts": concepts}
    apart = with_looks(theta, g, np.eye(3, 4) * (1 - 3e-12) + 1e-12)
    lis = predict_names(apart, 0, VOCAB, np.zeros((4, 4)), None, weighting="listener", **kw)
    looks = predict_names(apart, 0, VOCAB, np.zeros((4, 4)), None, weighting="looks", view_counts=16.0, **kw)
    assert np.array_equal(lis.indices, looks.indices) and np.allclose(lis.scores, looks.scores)
    same = with_looks(theta, g, np.full((3, 4), 0.25))
    said = predict_names(same, 0, VOCAB, np.zeros((4, 4)), None, weighting="none", **kw)
    looks = predict_names(same, 0, VOCAB, np.zeros((4, 4)), None, weighting="looks", view_counts=16.0, **kw)
    assert np.array_equal(said.indices, looks.indices) and np.allclose(said.scores, looks.scores)


def test_a_name_two_alike_concepts_share_is_not_anothers() -> None:
    """Two bedroom concepts (alike views) share "bedroom" (index 3 here), a bath concept (other views)
    says "bath". At a view mostly in one bedroom concept with some weight on the bath's, the listener
    answers "bath" ("bedroom" is split between the two bedrooms); "looks" answers "bedroom". The washroom
    case stays the listener's: a washroom that does not look like the kitchen answers "washroom"."""
    theta = np.array([[0.0, 0.0, 0.0, 1.0, 0.0],     # bedroom, one kind
                      [0.0, 0.0, 0.0, 1.0, 0.0],     # bedroom, another kind
                      [0.0, 0.0, 0.0, 0.0, 1.0]])    # bath
    g = np.array([1 / 3, 1 / 3, 1 / 3])
    phi = np.array([[0.5, 0.5, 1e-9, 1e-9], [0.45, 0.55, 1e-9, 1e-9], [1e-9, 1e-9, 0.5, 0.5]])
    p = with_looks(theta, g, phi / phi.sum(axis=1, keepdims=True))
    kw = {"top_k": 1, "use_vision": False, "concepts": np.array([[0.6, 0.0, 0.4]]), "view_counts": 16.0}
    lis = predict_names(p, 0, VOCAB, np.zeros((1, 4)), None, weighting="listener", **kw)
    looks = predict_names(p, 0, VOCAB, np.zeros((1, 4)), None, weighting="looks", **kw)
    assert lis.words[0, 0] == "bath" and looks.words[0, 0] == "bathroom"
    theta = np.array([[0.0, 0.9, 0.0, 0.0, 0.1],     # kitchen concept
                      [0.05, 0.4, 0.3, 0.25, 0.0]])  # washroom concept, its people say "kitchen" most
    phi = np.array([[0.5, 0.5, 1e-9, 1e-9], [1e-9, 1e-9, 0.5, 0.5]])
    p = with_looks(theta, np.array([0.5, 0.5]), phi / phi.sum(axis=1, keepdims=True))
    kw = {"top_k": 1, "use_vision": False, "concepts": np.array([[0.02, 0.98]]), "view_counts": 16.0}
    said = predict_names(p, 0, VOCAB, np.zeros((1, 4)), None, weighting="none", **kw)
    looks = predict_names(p, 0, VOCAB, np.zeros((1, 4)), None, weighting="looks", **kw)
    assert said.words[0, 0] == "kitchen" and looks.words[0, 0] == "washroom"


def test_the_setting() -> None:
    hyper = TransferHyperparameters()
    looks = hyper.with_settings(["name_answer=looks"])
    assert looks.name_answer == "looks" and looks.to_dict()["name_answer"] == "looks"
    assert TransferHyperparameters.from_dict(looks.to_dict()) == looks
    assert "name_answer" not in hyper.to_dict()
    assert answer_weighting("exact", True, "looks") == "looks"
    assert answer_weighting("exact", False, "looks") == "mi"
    assert answer_weighting("reference", True, "looks") == "reference"
    with pytest.raises(ConfigurationError, match="weighting"):
        predict_names(with_looks(np.full((2, 5), 0.2), np.array([0.5, 0.5]), np.full((2, 4), 0.25)), 0, VOCAB,
                      np.zeros((1, 4)), None, weighting="alike", use_vision=False)  # type: ignore[arg-type]


def test_a_fit_answers_with_looks() -> None:
    """The fit does not read the setting (the same seed, the same parameters as ``"said"``); the model
    answers with the weighting ``"looks"``, its probabilities those of ``"said"``."""
    import warnings

    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.model import SpCoTransfer

    corpus = generate_homes(3, seed=4, new_homes=1, specific_rooms=False,
                            config=SyntheticConfig(n_features=64, n_train=5, n_test=2))
    fits = []
    for setting in ("said", "looks"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fits.append(SpCoTransfer(TransferHyperparameters(name_answer=setting), variant="exact",
                                     prune_words=True, n_iterations=3, random_state=0).fit(corpus))
    assert [f.name_weighting() for f in fits] == ["none", "looks"]
    assert np.array_equal(fits[0].parameters_.word_probabilities, fits[1].parameters_.word_probabilities)
    env = list(corpus)[-1]
    rows = np.flatnonzero(env.is_test)
    names = [f.predict_names(len(corpus) - 1, env.positions[rows], env.visual[rows], top_k=3) for f in fits]
    assert names[1].weighting == "looks"
    assert np.allclose(names[0].word_probabilities, names[1].word_probabilities)


def test_a_home_adapted_from_a_knowledge_answers_with_looks() -> None:
    """A knowledge keeps φ^v and the setting, so its adapted home answers ``what`` with ``"looks"``; the
    probabilities are those of the same home answering ``"said"``."""
    from conftest import fit_twice_and_adapt

    import spco.knowledge as kn

    _, fits, home = fit_twice_and_adapt(TransferHyperparameters(name_answer="looks"))
    assert fits[0].hyperparameters.name_answer == "looks" and home.weighting == "looks"
    x, y = map(float, home.positions[0, :2])
    looks = kn.what(home, x, y, 0.0, top_k=3)
    assert looks.weighting == "looks"
    params = home.parameters
    kernel = looks_kernel(params.shared_visual_probabilities, home.knowledge.hyperparameters.view_counts)
    assert kernel.shape == (params.n_concepts,) * 2 and np.allclose(np.diag(kernel), 1.0)
