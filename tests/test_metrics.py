"""A_n, A_p and chance levels on hand-made cases, and evaluate_home on a hand-built home."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spco.data.environment import Environment, make_ground_truth
from spco.data.language import Vocabulary
from spco.data.regions import PlaceRegions
from spco.errors import ConfigurationError, DataFormatError
from spco.evaluation import (
    HomeScores,
    evaluate_home,
    mean_over_places,
    name_accuracy,
    name_chance,
    position_accuracy,
    position_chance,
)
from spco.model.answer_settings import AnswerSettings
from spco.model.parameters import ConceptParameters
from spco.model.position_prediction import predict_positions

REGIONS = PlaceRegions({
    "kitchen": ((0.0, 1.0, 0.0, 1.0),),
    "bath": ((2.0, 3.0, 0.0, 1.0), (2.0, 2.5, 1.0, 2.0)),  # an L-shaped union
    "Emma's room": ((5.0, 6.0, 5.0, 6.0),),
})


# ------------------------------------------------------------------------- A_n
def test_name_accuracy_per_place() -> None:
    predicted = ["kitchen", "bath", "kitchen", "bath", None, "kitchen"]
    labels = ["kitchen", "kitchen", "bath", "bath", "bath", None]
    acc = name_accuracy(predicted, labels)
    assert list(acc) == ["kitchen", "bath"]
    assert acc["kitchen"] == pytest.approx(0.5)
    assert acc["bath"] == pytest.approx(1 / 3)  # None prediction counts as wrong
    assert mean_over_places(acc) == pytest.approx((0.5 + 1 / 3) / 2)


def test_place_without_test_samples_is_nan_and_left_out_of_the_mean() -> None:
    acc = name_accuracy(["kitchen", "kitchen"], ["kitchen", "kitchen"], places=["kitchen", "Toilet"])
    assert acc["kitchen"] == 1.0
    assert math.isnan(acc["toilet"])
    assert mean_over_places(acc) == 1.0
    assert math.isnan(mean_over_places({"a": math.nan}))
    assert math.isnan(mean_over_places({}))


def test_accepted_names_count_as_right() -> None:
    predicted = ["bathroom", "shower", "toilet", "Bath", "living-room", "room"]
    labels = ["bath", "bath", "bath", "bath", "living room", "living room"]
    acc = name_accuracy(predicted, labels, accepted={"Bath": ["Bathroom", "shower"]})
    assert acc == {"bath": 0.75, "living room": 0.5}
    assert name_accuracy(predicted, labels)["bath"] == 0.25  # without synonyms: the label only


def test_name_accuracy_normalises_names() -> None:
    acc = name_accuracy(["Emma's room", "living-room"], ["emma's room", "Living Room"])
    assert acc == {"emma's room": 1.0, "living room": 1.0}
    with pytest.raises(ConfigurationError):
        name_accuracy(["a"], ["a", "b"])


# ------------------------------------------------------------------------- A_p
def test_point_on_an_edge_is_inside() -> None:
    corners = np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.5], [0.5, 0.0]])
    assert position_accuracy({"kitchen": corners}, REGIONS) == {"kitchen": 1.0}
    outside = np.array([[1.0 + 1e-9, 0.5], [0.5, -1e-9], [np.nan, 0.5], [0.5, 0.5]])
    assert position_accuracy({"kitchen": outside}, REGIONS)["kitchen"] == pytest.approx(0.25)


def test_union_of_rectangles() -> None:
    pts = np.array([
        [2.5, 0.5, 0.0],   # first rectangle
        [2.2, 1.8, 1.0],   # second rectangle only
        [2.8, 1.8, 2.0],   # in the bounding box, in neither rectangle
        [2.5, 2.0, 0.0],   # corner of the second rectangle
    ])
    acc = position_accuracy({"bath": pts, "Emma's room": np.array([[5.5, 5.5]])}, REGIONS)
    assert acc["bath"] == pytest.approx(0.75)
    assert acc["emma's room"] == 1.0
    assert math.isnan(position_accuracy({"bath": np.empty((0, 2))}, REGIONS)["bath"])
    with pytest.raises(ConfigurationError, match="garage"):
        position_accuracy({"garage": pts}, REGIONS)


def test_chance_levels() -> None:
    assert name_chance(20) == pytest.approx(0.05)
    assert position_chance(8) == pytest.approx(0.125)
    with pytest.raises(ConfigurationError):
        name_chance(0)
    with pytest.raises(ConfigurationError):
        position_chance(0)


# ------------------------------------------------------------------------- evaluate_home
WORDS = ("this", "is", "kitchen", "bath", "emma's room")


def home_params() -> ConceptParameters:
    """Concept l ↔ region l ↔ word 2 + l; region means at the centres of the REGIONS rectangles."""
    theta_w = np.array([
        [0.4, 0.3, 0.3, 0.0, 0.0],
        [0.4, 0.3, 0.0, 0.3, 0.0],
        [0.4, 0.3, 0.0, 0.0, 0.3],
    ])
    g = np.array([0.4, 0.4, 0.2])
    pi = np.full((3, 3), 0.02) + np.eye(3) * 0.94
    means = np.array([[0.5, 0.5, 0.0, 1.0], [2.5, 0.5, 0.0, 1.0], [5.5, 5.5, 0.0, 1.0]])
    covs = np.tile(np.diag([0.004, 0.004, 0.1, 0.1]), (3, 1, 1))
    theta_v = np.array([[0.7, 0.1, 0.1, 0.1], [0.1, 0.7, 0.1, 0.1], [0.1, 0.1, 0.7, 0.1]])
    return ConceptParameters(g[None], pi[None], means[None], covs[None], theta_w[None], theta_v[None],
                             theta_w, theta_v, g, np.ones(5, dtype=bool), np.array([[10, 10, 10]]))


def home() -> Environment:
    # 0-1 kitchen, 2-3 bath, 4-5 emma's room (train); 6-8 kitchen, 9-10 bath, 11 in bath but labelled
    # toilet (train), 12-13 emma's room (test, specific)
    rows = [(0.5, 0.5, 0), (0.4, 0.6, 0), (2.5, 0.5, 1), (2.4, 0.4, 1), (5.5, 5.5, 2), (5.6, 5.4, 2),
            (0.5, 0.5, 0), (0.6, 0.5, 0), (2.5, 0.5, 1),  # test: kitchen, kitchen, bath (wrong label)
            (2.5, 0.6, 1), (2.45, 0.5, 1), (2.5, 0.5, 1), (5.5, 5.5, 2), (5.5, 5.6, 2)]
    positions = np.array([[x, y, 0.0, 1.0] for x, y, _ in rows])
    visual = np.zeros((len(rows), 4), dtype=np.int64)
    visual[np.arange(len(rows)), [c for _, _, c in rows]] = 30
    labels = ["kitchen", "kitchen", "bath", "bath", "bedroom", "bedroom",
              "kitchen", "kitchen", "kitchen", "bath", "bath", "toilet", "bedroom", "bedroom"]
    specific = [lab if lab != "bedroom" else "Emma's-room" for lab in labels]
    is_test = np.zeros(len(rows), dtype=bool)
    is_test[[6, 7, 8, 9, 10, 12, 13]] = True
    specific_test = np.zeros(len(rows), dtype=bool)
    specific_test[[12, 13]] = True
    regions = PlaceRegions({**REGIONS.places, "toilet": ((8.0, 9.0, 8.0, 9.0),)})
    return Environment(
        name="toy", ids=np.arange(len(rows)), positions=positions, visual=visual,
        sentences=[None] * len(rows), is_test=is_test, extent=(-1.0, 7.0, -1.0, 7.0),
        ground_truth=make_ground_truth(labels, specific, specific_test, regions),
    )


def test_evaluate_home_general() -> None:
    scores = evaluate_home(home_params(), 0, home(), Vocabulary(WORDS), n_positions=50, rng=0)
    assert isinstance(scores, HomeScores)
    assert scores.places == ("kitchen", "bath", "bedroom", "toilet")
    assert scores.name_accuracy["kitchen"] == pytest.approx(2 / 3)  # sample 8 is labelled kitchen
    assert scores.name_accuracy["bath"] == 1.0
    assert scores.name_accuracy["bedroom"] == 0.0  # only the specific name was taught
    assert math.isnan(scores.name_accuracy["toilet"])  # no test sample
    assert scores.mean_name_accuracy == pytest.approx((2 / 3 + 1 + 0) / 3)
    assert scores.position_accuracy["kitchen"] == 1.0
    assert scores.position_accuracy["bath"] == 1.0
    assert math.isnan(scores.position_accuracy["bedroom"])  # no ground-truth area for "bedroom"
    assert scores.position_accuracy["toilet"] == 0.0  # never taught: cannot be predicted
    assert scores.mean_position_accuracy == pytest.approx(2 / 3)
    assert scores.name_chance == pytest.approx(1 / 5)
    assert scores.position_chance == pytest.approx(1 / 4)
    assert scores.predicted_names == ("kitchen", "kitchen", "bath", "bath", "bath", "emma's room",
                                      "emma's room")
    assert set(scores.predicted_positions) == {"kitchen", "bath"}
    assert scores.predicted_positions["bath"].shape == (50, 3)
    assert scores.summary()["name_accuracy"]["toilet"] is None


def test_one_rounding_of_the_scores_the_summary_and_the_experiments_records() -> None:
    """The scores as measured, NaN and None written as None (metrics.json_score): the summary keeps
    2/3 unrounded, and an experiment's record takes its score fields from the summary."""
    from spco.evaluation import runs
    from spco.evaluation.metrics import json_score

    assert json_score(float("nan")) is None and json_score(None) is None
    assert json_score(np.float64(0.5)) == 0.5
    scores = evaluate_home(home_params(), 0, home(), Vocabulary(WORDS), n_positions=50, rng=0)
    summary = scores.summary()
    assert summary["name_accuracy"]["kitchen"] == scores.name_accuracy["kitchen"] == 2 / 3
    assert summary["mean_name_accuracy"] == scores.mean_name_accuracy
    assert "summary" in runs.execute_run.__code__.co_names  # the records' scores are the summary's


def test_position_accuracy_both_ways() -> None:
    """A_p from the most probable region (the authors' code) against A_p sampled from the whole
    mixture p(x | name) (the paper's text): a name whose region probability is split 0.55 / 0.45
    between its place and another scores 1 the first way and about 0.55 the second."""
    params = home_params()
    pi = params.region_weights.copy()
    pi[0, 0] = [0.55, 0.45, 0.0]  # concept "kitchen": 55 % in the kitchen's region, 45 % in the bath's
    split = ConceptParameters(params.concept_weights, pi, params.region_means, params.region_covariances,
                              params.word_probabilities, params.visual_probabilities,
                              params.shared_word_probabilities, params.shared_visual_probabilities,
                              params.global_concept_weights, params.word_mask, params.concept_counts)
    scores = evaluate_home(split, 0, home(), Vocabulary(WORDS), n_positions=400, rng=3)
    assert scores.position_accuracy["kitchen"] == 1.0
    assert 0.45 < scores.position_accuracy_mixture["kitchen"] < 0.65
    assert scores.position_accuracy_mixture["bath"] > 0.9  # bath: 0.94 of its mass in its region
    assert math.isnan(scores.position_accuracy_mixture["bedroom"])
    assert scores.summary()["mean_position_accuracy_mixture"] < scores.summary()["mean_position_accuracy"]
    # the mixture draws come from a child stream: the most-probable-region draws are those of the
    # seed's own stream, place after place, as before A_p was measured both ways
    gen = np.random.default_rng(3)
    predict_positions(split, 0, Vocabulary(WORDS), "kitchen", n=400, rng=gen)
    bath = predict_positions(split, 0, Vocabulary(WORDS), "bath", n=400, rng=gen)
    assert np.array_equal(bath.samples, scores.predicted_positions["bath"])


def test_evaluate_home_specific() -> None:
    scores = evaluate_home(home_params(), 0, home(), Vocabulary(WORDS), specific=True, n_positions=20,
                           rng=1, weighting="reference")
    assert scores.places == ("emma's room",)
    assert scores.labels == ("emma's room", "emma's room")
    assert scores.name_accuracy == {"emma's room": 1.0}
    assert scores.position_accuracy == {"emma's room": 1.0}
    assert scores.position_chance == 1.0


def test_evaluate_home_without_ground_truth() -> None:
    env = home()
    bare = Environment(name="bare", ids=env.ids, positions=env.positions, visual=env.visual,
                       sentences=env.sentences, is_test=env.is_test)
    with pytest.raises(DataFormatError):
        evaluate_home(home_params(), 0, bare, Vocabulary(WORDS))


def test_evaluate_answers_scores_what_the_robot_answers(small_corpus) -> None:
    """The experiments' and benchmarks' scoring (evaluate_answers) gives each test view the name the
    robot answers there (SpCoTransfer.predict_names: the answer's parameters, rooms, weighting and view
    weight), and A_p from the robot's where."""
    from spco.evaluation import evaluate_answers
    from spco.model.transfer import SpCoTransfer

    model = SpCoTransfer(variant="exact", prune_words=True, n_iterations=5, random_state=0).fit(small_corpus)
    e = len(small_corpus) - 1
    env = small_corpus[e]
    scores = evaluate_answers(model, e, env, rng=0)
    test = env.is_test
    robot = model.predict_names(e, env.positions[test], env.visual[test])
    assert list(scores.predicted_names) == list(robot.best)
    assert model.name_weighting() == model.answer_inputs(e)[2]


def test_evaluate_answers_view_in_room_is_the_robots_answer_with_the_view_in_its_room(small_corpus,
                                                                                       monkeypatch) -> None:
    """The override ``settings=AnswerSettings(view_in_room=True)`` (opt-in) scores the names
    ``answer_names(…, settings=…)`` gives with the model's own answer inputs and view weight; without
    it evaluate_answers passes the model's settings (the defaults here) and scores the robot's answer;
    positions (A_p) are the same either way (``where`` reads no view)."""
    from spco.evaluation import evaluate_answers, metrics
    from spco.model.confidence import answer_names
    from spco.model.transfer import SpCoTransfer

    model = SpCoTransfer(variant="exact", prune_words=True, n_iterations=5, random_state=0).fit(small_corpus)
    e = len(small_corpus) - 1
    env = small_corpus[e]
    test = env.is_test
    params, rooms, weighting = model.answer_inputs(e)
    assert rooms is not None
    expected = answer_names(params, e, model.vocabulary_, env.positions[test], env.visual[test], top_k=3,
                            weighting=weighting, name_prior=model.hyperparameters_.name_prior,
                            view_counts=model.settings_.view_counts, rooms=rooms,
                            settings=AnswerSettings(view_in_room=True))
    seen: list[AnswerSettings] = []

    def spy(*args, **kwargs):
        seen.append(kwargs["settings"])
        return answer_names(*args, **kwargs)

    monkeypatch.setattr(metrics, "answer_names", spy)
    in_room = evaluate_answers(model, e, env, rng=0, settings=AnswerSettings(view_in_room=True))
    plain = evaluate_answers(model, e, env, rng=0)
    assert seen == [AnswerSettings(view_in_room=True), AnswerSettings()]
    assert list(in_room.predicted_names) == list(expected.best)
    robot = model.predict_names(e, env.positions[test], env.visual[test])
    assert list(plain.predicted_names) == list(robot.best)
    assert in_room.position_accuracy == plain.position_accuracy


def test_evaluate_home_view_in_room_needs_rooms() -> None:
    with pytest.raises(ConfigurationError, match="view_in_room"):
        evaluate_home(home_params(), 0, home(), Vocabulary(WORDS), settings=AnswerSettings(view_in_room=True))
