"""A map labels a place where ``where`` goes for it (issue 29, "one predictor"): the page of ``spco
serve``, the ROS markers and Foxglove read :func:`spco.service.answers.regions_answer`'s ``places``,
which is ``where``'s answer for every name, and a region's ``names`` are what ``what`` answers at its
centre. Before, a name labelled the region where p(name | region) was highest (a second predictor),
and on the tour home each of its three rooms was labelled in another region than ``where`` answers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from spco import knowledge as kn
from spco.data.lexicon import lexicon
from spco.ros.messages import marker_array
from spco.service.answers import regions_answer


def _labels(answer: dict) -> dict[str, int]:
    """name -> the region a map labels it at (each region's ``places``)."""
    found: dict[str, int] = {}
    for region in answer["regions"]:
        for place in region["places"]:
            assert place["name"] not in found, f"{place['name']} labelled twice"
            found[place["name"]] = region["region"]
    return found


def _check_labels_are_where(home: kn.HomeModel) -> dict[str, int]:
    answer = regions_answer(home)
    labels = _labels(answer)
    assert [p["name"] for p in answer["places"]] == home.known_names
    for place in answer["places"]:
        pred = kn.where(home, place["name"], n=10, random_state=3)
        assert place["region"] == pred.region == int(np.argmax(pred.region_probabilities))
        assert place["p"] == float(pred.region_probabilities[pred.region])
        assert place["learnt"] == pred.learnt
        # a learnt place is labelled at where's region, with where's p; a name not learnt is no label
        assert labels.get(place["name"]) == (pred.region if pred.learnt else None)
    drawn = {r["region"] for r in answer["regions"]}
    assert set(labels.values()) <= drawn
    # a region's names: what `what` answers at its centre (the pose alone)
    said = kn.names_at_regions(home, [r["region"] for r in answer["regions"]], top_k=3)
    for row, region in enumerate(answer["regions"]):
        assert [n["name"] for n in region["names"]] == [str(w) for w in said.words[row]]
        centre = home.parameters.region_means[0, region["region"]]
        theta = float(np.arctan2(centre[2], centre[3]))
        at = kn.what(home, float(centre[0]), float(centre[1]), theta) if kn.pose_outside_map(
            home, float(centre[0]), float(centre[1])) is None else None
        if at is not None:
            assert at.words[0][0] == region["names"][0]["name"]
    # the ROS markers write the same labels
    markers = marker_array(answer["regions"], home.knowledge.n_concepts)["markers"]
    texts = {m["id"]: m["text"] for m in markers[1:] if m["ns"] == "spco/names"}
    for name, region in labels.items():
        assert name in texts[region].split("\n")[0] or name in texts[region]
    return labels


def test_the_tour_home_labels_each_room_where_where_goes(tour_home_file: Path) -> None:
    home = kn.load_home_model(tour_home_file)
    labels = _check_labels_are_where(home)
    assert set(labels) == {"kitchen", "living room", "bedroom"}  # the three rooms, each learnt


def test_a_taught_name_is_labelled_where_where_goes(tour_home_file: Path) -> None:
    home = kn.load_home_model(tour_home_file)
    far = int(np.argmax(home.positions[:, 0]))  # a sample at one end of the tour
    taught = kn.teach(home, {int(home.ids[far]): "this is the pantry"}, random_state=0)
    labels = _check_labels_are_where(taught)
    assert "pantry" in taught.known_names
    assert labels.get("pantry") == kn.where(taught, "pantry").region


def test_the_robot_s_where_reads_the_lexicon_s_answer_as_the_experiments_do(tour_home_file: Path,
                                                                           monkeypatch) -> None:
    """A name nobody said that the lexicon answers by its own words (``SAID_WORDS``: "spare room" by
    "room") is looked up in the robot's ``where`` as those words only, as ``predict_positions`` (the
    experiments' A_p) reads the lexicon's answer (``query_forms`` with ``alone=False``: not every term
    that holds the word); a name answered by a relation (a synonym) as a name asked alone."""
    from spco.model import position_prediction
    from spco.model.unheard import SAID_WORDS, ResolvedName

    home = kn.load_home_model(tour_home_file)
    real = position_prediction.predict_positions
    seen: list[bool] = []

    def spy(*args, **kwargs):
        seen.append(kwargs.get("alone", True))
        return real(*args, **kwargs)

    monkeypatch.setattr(position_prediction, "predict_positions", spy)
    for how, alone in ((SAID_WORDS, False), ("synonym", True)):
        found = ResolvedName(asked="cooking room", name="kitchen", how=how, score=1.0)
        monkeypatch.setattr(position_prediction, "resolve_name", lambda *args, found=found, **kwargs: found)
        seen.clear()
        pred = kn.where(home, "cooking room", n=3, random_state=0)
        assert (pred.asked, pred.name, pred.via) == ("cooking room", "kitchen", how)
        assert seen == [True, alone], (how, seen)  # the name asked, then the lexicon's answer


@pytest.mark.skipif(lexicon() is None, reason="WordNet is not installed")
def test_the_robot_s_where_of_a_name_nobody_said_is_the_scored_predictor_s(tour_home_file: Path) -> None:
    """One look-up of a name nobody said: the robot's ``where`` answers a never-heard name (a synonym,
    a gloss, a head word) with exactly the positions of ``predict_positions(unheard=True)`` — what the
    experiments score — called as they call it, on the answer's parameters and rooms with the fit's
    word mask; before, the robot resolved the name with its own inputs and then asked for the known
    name without the look-up."""
    from spco.knowledge.queries import answer_inputs
    from spco.model.position_prediction import predict_positions

    home = kn.load_home_model(tour_home_file)
    params, rooms = answer_inputs(home)
    for name in ("galley", "bedchamber", "spare bedroom", "lounge"):
        assert name not in home.vocabulary
        robot = kn.where(home, name, n=5, random_state=4)
        scored = predict_positions(params, 0, home.vocabulary, name, n=5, rng=np.random.default_rng(4),
                                   mode="answer", unheard=True, rooms=rooms,
                                   view_counts=home.hyperparameters.view_weight(),
                                   lookup=home.parameters.word_mask)
        assert robot.via is not None and robot.name in home.known_names, name  # the lexicon answered
        assert (robot.asked, robot.name, robot.via) == (scored.asked, scored.name, scored.via)
        np.testing.assert_array_equal(robot.samples, scored.samples)
        np.testing.assert_array_equal(robot.region_probabilities, scored.region_probabilities)
