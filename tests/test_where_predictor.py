"""One p(pose | name) (issue 29): the robot's `where` and the experiments' A_p answer from the same
function, :func:`spco.model.position_prediction.region_posterior_for_name`, with the same parameters
(the names `what` answers) and the same rooms (the room account); its formula checked by hand."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose
from serve_helpers import build_home

from spco import knowledge as kn
from spco.evaluation import evaluate_home
from spco.model import SpCoTransfer, position_prediction
from spco.model.confidence import model_answer_parameters
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.position_prediction import said_word_matrix
from spco.model.rooms import model_rooms, room_concepts

SMALL = TransferHyperparameters(n_concepts=6, n_regions=8)


@pytest.fixture(scope="module")
def home(tmp_path_factory: pytest.TempPathFactory) -> kn.HomeModel:
    return kn.load_home_model(build_home(tmp_path_factory.mktemp("where_predictor")))


@pytest.fixture(scope="module")
def joint(small_corpus):
    return SpCoTransfer(SMALL, prune_words=True, n_iterations=10, random_state=2).fit(small_corpus)


class _Spy:
    """Wraps ``region_posterior_for_name``: records whether each call had the home's rooms."""

    def __init__(self) -> None:
        self.original = position_prediction.region_posterior_for_name
        self.calls: list[tuple[object, object, np.ndarray]] = []

    def __call__(self, params, e, vocabulary, name, **options):
        result = self.original(params, e, vocabulary, name, **options)
        self.calls.append((params, options.get("rooms"), result))
        return result


def _by_hand(params, rooms, view_counts, vocabulary, name, lookup, e: int = 0) -> np.ndarray:
    """p(m | w) ∝ Σ_k n_k [r(k) = m] Σ_l p(l | room k) p(w | l), worked out room by room."""
    K = int(np.shape(params.region_means)[1])
    counts, posterior = room_concepts(params, e, rooms, view_counts)
    _, region_of = rooms.membership(K)
    columns = position_prediction.query_indices(params, vocabulary, name, lookup)
    likelihood = np.prod(said_word_matrix(params, e)[:, columns], axis=1)
    out = np.zeros(K)
    for k in range(counts.size):
        out[region_of[k]] += counts[k] * float(posterior[k] @ likelihood)
    return out / out.sum()


def test_where_answers_from_the_one_function_with_the_rooms_and_names_of_what(
        home: kn.HomeModel, monkeypatch: pytest.MonkeyPatch) -> None:
    spy = _Spy()
    monkeypatch.setattr(position_prediction, "region_posterior_for_name", spy)
    params, rooms = kn.queries.answer_inputs(home)  # what `what` reads
    assert home.known_names
    for name in home.known_names:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            answer = kn.where(home, name, n=4, random_state=0)
        called_params, called_rooms, result = spy.calls[-1]
        assert called_params is params and called_rooms is rooms  # the answer's parameters and rooms
        assert_allclose(answer.region_probabilities, result)
        expected = _by_hand(params, rooms, home.hyperparameters.view_weight(), home.vocabulary, name,
                            home.parameters.word_mask)
        assert_allclose(answer.region_probabilities, expected, atol=1e-12)
        assert answer.region == int(np.argmax(expected))


def test_the_experiments_a_p_draws_from_what_where_answers(joint, small_corpus,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """evaluate_home's positions come from the same function as `where`, with the robot's answer
    parameters and rooms: a scorer with an account of its own fails here."""
    e = len(small_corpus) - 1
    env = small_corpus[e]
    answer, rooms = model_answer_parameters(joint, e), model_rooms(joint, e)
    w = joint.settings_.view_counts
    spy = _Spy()
    monkeypatch.setattr(position_prediction, "region_posterior_for_name", spy)
    scores = evaluate_home(joint.parameters_, e, env, joint.vocabulary_, rng=0, view_counts=w,
                           answer_params=answer, answer_rooms=rooms)
    assert scores.position_predictions, "no place's name was predicted"
    assert spy.calls and all(p is answer and r is rooms for p, r, _ in spy.calls)
    for place, pred in scores.position_predictions.items():
        expected = _by_hand(answer, rooms, w, joint.vocabulary_, pred.name, joint.parameters_.word_mask, e)
        assert_allclose(pred.region_probabilities, expected, atol=1e-12, err_msg=place)
        direct = position_prediction.predict_positions(answer, e, joint.vocabulary_, pred.name, n=3, rng=0,
                                                       unheard=False, rooms=rooms, view_counts=w,
                                                       lookup=joint.parameters_.word_mask)
        assert_allclose(direct.region_probabilities, pred.region_probabilities)


def test_answer_regions_draw_the_regions_at_least_half_as_probable_as_the_best() -> None:
    regions = position_prediction.answer_regions(np.array([0.1, 0.45, 0.05, 0.4]), 10)
    assert regions[0] == 1 and set(regions.tolist()) == {1, 3}
    assert (regions == 1).sum() == 5 and (regions == 3).sum() == 5
    assert position_prediction.answer_regions(np.array([0.2, 0.8]), 0).size == 0
    assert set(position_prediction.answer_regions(np.array([0.5, 0.5]), 1).tolist()) <= {0, 1}


def test_a_taught_room_is_found_by_its_name_through_the_rooms(home: kn.HomeModel) -> None:
    """The home's teachings enter through the room account (its taught names decide the room's concept)
    and the answer's θ^w, with no weight of their own: a new name taught at one sample is found in
    that sample's region, learnt."""
    row = 3
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        taught = kn.teach(home, {int(home.ids[row]): "this is the quokka room"}, random_state=0)
        answer = kn.where(taught, "quokka room", n=6, random_state=0)
    assert answer.learnt
    assert int(taught.state.regions[row]) in answer.regions.tolist() or \
        kn.queries.answered_at_region(taught, answer.region) == "quokka room"
    assert not hasattr(kn, "WHERE_MODEL_WEIGHT") and not hasattr(kn.queries, "WHERE_ANYWHERE_WEIGHT")
