"""A robot that asks: the criterion (spco.model.question_scores), ``spco.knowledge.ask``, ``spco ask`` and
``GET /ask``.

The criterion's tests build the home's beliefs by hand (concept posteriors, names, regions), so that
each property is checked on a case whose answer is known; the library, CLI and HTTP tests run on
small synthetic homes (128 visual features, tens of sweeps): they check the workflow and the two
cases the issue names — a home whose every place is known asks little anywhere, a place that looks
like nothing the experienced homes had is asked first.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from click.testing import CliRunner

from spco import knowledge as kn
from spco.cli.ask import ask as ask_command
from spco.data.environment import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.errors import ConfigurationError
from spco.model.confidence import UNSURE_BELOW
from spco.model.question_scores import (
    group_rooms,
    name_entropy,
    question_scores,
    rank_questions,
    room_novelty,
)
from spco.service.answers import ask_answer

CONFIG = SyntheticConfig(n_features=128)


# ----------------------------------------------------------------------------- the criterion
def _home_beliefs(n_per_room: int = 10) -> dict[str, np.ndarray]:
    """Three rooms of 10 samples, 3 m apart: room 0 kind 0 (kitchen), rooms 1 and 2 kind 1 (two
    bedrooms); concept 2 is one the knowledge does not use. Eight usable names: 0 kitchen, 1 bedroom,
    2 a name first heard in this home, and five others."""
    n = 3 * n_per_room
    rooms = np.repeat(np.arange(3), n_per_room)
    rng = np.random.default_rng(0)
    xy = np.column_stack([rooms * 3.0 + rng.uniform(0, 1, n), rng.uniform(0, 1, n)])
    concepts = np.zeros((n, 3))
    concepts[np.arange(n), np.where(rooms == 0, 0, 1)] = 1.0
    names = np.zeros((3, 8))
    names[[0, 1, 2], [0, 1, 2]] = 1.0
    return {"concepts": concepts, "name_matrix": names, "unnamed": np.array([False, False, True]),
            "kinds": np.where(rooms == 0, 0, 1), "regions": rooms.copy(), "xy": xy,
            "taught_names": np.zeros((n, 8)), "taught_own": np.zeros(n, dtype=bool)}


def _teach(beliefs: dict[str, np.ndarray], row: int, name: int, own: bool = False) -> None:
    beliefs["taught_names"][row] = 0.0
    beliefs["taught_names"][row, name] = 1.0
    beliefs["taught_own"][row] = own


def test_group_rooms_joins_touching_regions_of_one_kind_only() -> None:
    xy = np.array([[0.0, 0], [0.2, 0], [0.4, 0], [0.6, 0], [5.0, 0], [5.2, 0]])
    regions = np.array([0, 0, 1, 1, 2, 2])
    same_kind = group_rooms(regions, np.zeros(6, dtype=int), xy)
    assert same_kind.tolist() == [0, 0, 0, 0, 1, 1]  # regions 0 and 1 touch; region 2 is 4.4 m away
    other_kind = group_rooms(regions, np.array([0, 0, 1, 1, 0, 0]), xy)
    assert other_kind.tolist() == [0, 0, 1, 1, 2, 2]
    with pytest.raises(ConfigurationError, match="same samples"):
        group_rooms(regions, np.zeros(5, dtype=int), xy)


def test_name_entropy_counts_a_name_never_learnt() -> None:
    h = name_entropy(np.array([[1.0, 0.0], [0.0, 0.0], [0.5, 0.5]]), np.array([0.0, 1.0, 0.0]), 2)
    assert h == pytest.approx([0.0, np.log(3), np.log(2)])


@pytest.mark.parametrize("criterion", ["errors", "information"])
def test_a_home_whose_every_place_is_known_has_low_gains_everywhere(criterion: str) -> None:
    beliefs = _home_beliefs()
    untaught = question_scores(**beliefs, criterion=criterion)
    _teach(beliefs, 0, 0)  # the kitchen, "kitchen"
    _teach(beliefs, 10, 1)  # both bedrooms, "bedroom"
    _teach(beliefs, 20, 1)
    known = question_scores(**beliefs, criterion=criterion)
    assert known.gain.max() < 1e-9  # the model and every room's answer agree: nothing to learn
    assert untaught.gain.max() > 2.0


@pytest.mark.parametrize("criterion", ["errors", "information"])
def test_a_place_nobody_named_ranks_first(criterion: str) -> None:
    beliefs = _home_beliefs()
    beliefs["concepts"][:10] = [0.0, 0.0, 1.0]  # room 0's samples sit in the unused concept
    scores = question_scores(**beliefs, criterion=criterion)
    rows, gains = rank_questions(scores)
    assert scores.rooms[rows[0]] == 0 and gains[0] == pytest.approx(scores.gain[0])
    assert scores.unknown[:10] == pytest.approx(1.0)
    assert gains[0] > gains[1]


def test_a_room_whose_views_are_unlike_the_experienced_homes_is_asked_first() -> None:
    assert room_novelty(np.array([1.2, 0.6, 0.45, 0.2, np.nan]), (0.6, 0.3)) == pytest.approx(
        [0.0, 0.0, 0.5, 1.0, 0.0])
    assert room_novelty(np.array([0.1]), None) == pytest.approx([0.0])
    with pytest.raises(ConfigurationError, match="fit_range"):
        room_novelty(np.array([0.1]), (0.3, 0.6))
    beliefs = _home_beliefs()
    fits = np.full(30, 1.1)
    fits[:10] = 0.1  # the kitchen's views: worse than any experienced home's
    scores = question_scores(**beliefs, view_fits=fits, fit_range=(0.6, 0.3))
    assert scores.novelty[:10] == pytest.approx(1.0) and scores.novelty[10:] == pytest.approx(0.0)
    assert scores.own_name[:10] == pytest.approx(1.0)
    rows, gains = rank_questions(scores)
    assert scores.rooms[rows[0]] == 0 and gains[0] > gains[1]
    plain = question_scores(**beliefs, view_fits=np.full(30, 1.1), fit_range=(0.6, 0.3))
    assert plain.rooms[rank_questions(plain)[0][0]] != 0


def test_rooms_of_a_shared_kind_may_have_names_of_their_own_and_answers_teach_it() -> None:
    beliefs = _home_beliefs()
    scores = question_scores(**beliefs)
    assert scores.own_name[:10] == pytest.approx(0.1)  # the only kitchen
    assert scores.own_name[10:] == pytest.approx(0.5)  # one of two bedrooms
    rows, _ = rank_questions(scores)
    assert scores.rooms[rows[0]] in (1, 2)
    _teach(beliefs, 10, 2, own=True)  # one bedroom is "Emma's room": the other may be someone's too
    own = question_scores(**beliefs)
    assert own.own_name[20:] == pytest.approx((2 * 0.5 + 1) / 3)
    assert own.own_name[10:20] == pytest.approx(0.0)  # a taught room's name is known
    _teach(beliefs, 10, 1, own=False)  # ... or it is "bedroom": the other is less likely to differ
    transferred = question_scores(**beliefs)
    assert transferred.own_name[20:] == pytest.approx(1.0 / 3)


def test_a_sample_contradicting_its_rooms_answer_is_worth_asking() -> None:
    beliefs = _home_beliefs()
    _teach(beliefs, 10, 2, own=True)
    beliefs["concepts"][11:20] = 0.0
    beliefs["concepts"][11:20, 2] = 1.0  # most of the room follows the new name ...
    beliefs["concepts"][11:20, 1] = 0.0
    beliefs["unnamed"] = np.zeros(3, dtype=bool)
    beliefs["concepts"][18:20] = [0.0, 1.0, 0.0]  # ... two samples are still "bedroom"
    scores = question_scores(**beliefs, criterion="errors")
    assert scores.errors[18:20] == pytest.approx(0.5)
    assert scores.errors[11:18] == pytest.approx(0.0)
    rows, gains = rank_questions(scores)
    first = {int(scores.rooms[r]): g for r, g in zip(rows, gains, strict=True) if r in rows[:3]}
    assert first[1] == pytest.approx(1.0)  # two wrong answers, each even odds


def test_one_question_per_room_comes_first() -> None:
    scores = question_scores(**_home_beliefs())
    rows, gains = rank_questions(scores)
    assert len({int(scores.rooms[r]) for r in rows[:3]}) == 3
    assert np.all(np.diff(gains) <= 1e-12)
    rows, _ = rank_questions(scores, candidates=np.array([5, 25]))
    assert sorted(rows.tolist()) == [5, 25]


@pytest.mark.parametrize(("change", "message"), [
    (lambda b: b.update(kinds=np.full(30, 7)), "kinds must be concepts"),
    (lambda b: b.update(unnamed=np.zeros(2, dtype=bool)), "unnamed has shape"),
    (lambda b: b.update(concepts=-b["concepts"]), "finite and >= 0"),
    (lambda b: b.update(name_matrix=np.ones((4, 8))), "do not fit"),
])
def test_bad_beliefs_are_refused(change, message: str) -> None:
    beliefs = _home_beliefs()
    change(beliefs)
    with pytest.raises(ConfigurationError, match=message):
        question_scores(**beliefs)


def test_bad_criterion_and_candidates_are_refused() -> None:
    with pytest.raises(ConfigurationError, match="criterion"):
        question_scores(**_home_beliefs(), criterion="entropy")
    with pytest.raises(ConfigurationError, match="candidates"):
        rank_questions(question_scores(**_home_beliefs()), candidates=np.array([99]))


# ----------------------------------------------------------------------------- on learnt homes
@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """A knowledge of 8 synthetic homes (40 sweeps) and a new home of the same world (9 places),
    untaught; and the same home with one room's views replaced by views unlike any place."""
    corpus = generate_homes(9, seed=3, config=CONFIG, new_homes=1, specific_rooms=False)
    homes = list(corpus)
    knowledge = kn.fit_knowledge(Corpus(homes[:8]), n_iterations=40, random_state=3)
    new = homes[8]
    labels = np.array([label or "" for label in new.ground_truth.labels])
    rows = np.flatnonzero(labels == "bath")
    rng = np.random.default_rng(0)
    views = new.visual.toarray().astype(np.int64)
    profile = np.zeros(views.shape[1])
    support = rng.choice(views.shape[1], 12, replace=False)
    profile[support] = rng.dirichlet(np.ones(12))
    for r in rows:
        views[r] = rng.multinomial(int(views[r].sum()), profile)
    novel = replace(new, visual=sp.csr_array(views))
    folder = tmp_path_factory.mktemp("asking")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        home = kn.adapt(knowledge, new, n_iterations=50, random_state=3)
        odd = kn.adapt(knowledge, novel, n_iterations=50, random_state=3)
    path = folder / "home.spco"
    home.save(path)
    return {"knowledge": knowledge, "new": new, "labels": dict(zip(new.ids.tolist(), labels, strict=True)),
            "home": home, "odd": odd, "path": path, "folder": folder}


def test_a_place_that_looks_like_nothing_experienced_is_asked_first(world: dict) -> None:
    questions = kn.ask(world["odd"], n=3)
    first = questions[0]
    assert world["labels"][first.id] == "bath"
    assert "no experienced home has a place that looks like this" in first.reason
    assert first.unknown > 0.5 and first.gain > questions[1].gain
    plain = kn.ask(world["home"], n=1)[0]  # the same home with its own views: the bath is not special
    assert "no experienced home" not in plain.reason or world["labels"][plain.id] != "bath"


def test_a_home_whose_every_place_is_taught_asks_little(world: dict) -> None:
    """Every second training sample taught its place's name: every room is known, and what is left
    to ask is where the model's own answers still disagree with the room's (a weak knowledge of 8
    synthetic homes confuses a few views), well under a quarter of any room's samples."""
    from spco.knowledge.asking import home_question_scores

    new = world["new"]
    labels = world["labels"]
    sentences = [f"this is the {labels[i]}" if labels[i] and not new.is_test[k] and k % 2 == 0 else None
                 for k, i in enumerate(new.ids.tolist())]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        known = kn.adapt(world["knowledge"], new.with_sentences(sentences), n_iterations=50, random_state=3)
    untaught = home_question_scores(world["home"])
    scores = home_question_scores(known)
    # every room has a taught name
    assert scores.own_name.max() < 0.2 and np.mean(scores.own_name > 0) < 0.02
    size = np.bincount(scores.rooms)
    assert (scores.room_gain / size).max() < 0.35
    assert np.mean(scores.room_gain / size < 0.25) >= 0.8
    assert scores.room_gain.sum() < 0.4 * untaught.room_gain.sum()
    assert kn.ask(known, n=1)[0].gain < 0.7 * kn.ask(world["home"], n=1)[0].gain


def test_json_cli_and_library_agree(world: dict) -> None:
    path = world["path"]
    home = kn.load_home_model(path)
    library = [q.to_dict() for q in kn.ask(home, n=4)]
    answer = ask_answer(home, 4)
    assert answer["questions"] == library and answer["home"] == home.name
    result = CliRunner().invoke(ask_command, [str(path), "--n", "4", "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.output) == answer
    text = CliRunner().invoke(ask_command, [str(path), "-n", "4"])
    assert text.exit_code == 0
    shown = [int(line.split("sample ")[1].split()[0]) for line in text.output.splitlines()
             if ". sample " in line]
    assert shown == [q["id"] for q in library]
    assert f"--id {library[0]['id']}" in text.output
    q = library[0]
    assert set(q) >= {"id", "x", "y", "theta", "gain", "reason"}
    row = home.ids.tolist().index(q["id"])
    assert (q["x"], q["y"]) == pytest.approx(tuple(home.positions[row, :2]))


def test_asking_ranks_a_home_within_a_second(world: dict) -> None:
    import time

    home = world["home"]
    kn.ask(home, n=5)
    start = time.perf_counter()
    kn.ask(home, n=5)
    assert time.perf_counter() - start < 1.0


def test_bad_input_gets_clear_errors(world: dict, tmp_path: Path) -> None:
    home = world["home"]
    for n in (0, -1, 2.5, True):
        with pytest.raises(ConfigurationError, match="number of questions"):
            kn.ask(home, n=n)  # type: ignore[arg-type]
    with pytest.raises(ConfigurationError, match="HomeModel"):
        kn.ask(world["knowledge"])  # type: ignore[arg-type]
    with pytest.raises(ConfigurationError, match="criterion"):
        kn.ask(home, criterion="loudest")
    knowledge_file = tmp_path / "knowledge.spco"
    world["knowledge"].save(knowledge_file)
    for args, message in (([str(tmp_path / "missing.spco")], "error:"), ([str(knowledge_file)], "error:"),
                          ([str(world["path"]), "--n", "0"], "0 is not in the range")):
        result = CliRunner().invoke(ask_command, args)
        assert result.exit_code == 2 and message in result.output, result.output


def test_ask_only_when_unsure(world: dict) -> None:
    home = world["home"]
    every = kn.ask(home, n=1000)
    unsure = kn.ask(home, n=1000, unsure_only=True)
    assert [q.id for q in unsure] == [q.id for q in every if q.worth_asking]
    assert all(q.confidence < UNSURE_BELOW for q in unsure)
    assert all(q.worth_asking == (q.confidence < UNSURE_BELOW) for q in every)
    assert kn.ask(home, n=5, unsure_only=True, unsure_below=0.0) == []
    # the same call as JSON (same n: a batch of another size may differ in the last bit of a p)
    assert ask_answer(home, 5, unsure_only=True)["questions"] == [
        q.to_dict() for q in kn.ask(home, n=5, unsure_only=True)]
    assert [q["id"] for q in ask_answer(home, 5, unsure_only=True)["questions"]] == [q.id for q in unsure[:5]]
    for bad in (-0.1, 1.5, "high"):
        with pytest.raises(ConfigurationError, match="unsure_below"):
            kn.ask(home, unsure_below=bad)  # type: ignore[arg-type]
    result = CliRunner().invoke(ask_command, [str(world["path"]), "--unsure-only", "--json"])
    assert result.exit_code == 0 and all(q["worth_asking"] for q in json.loads(result.output)["questions"])


def test_a_fully_taught_home_has_nothing_to_ask(world: dict) -> None:
    home = world["home"]
    sentences = {int(i): "this is the kitchen" for i in home.ids}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        taught = kn.teach(home, sentences, n_sweeps=0, random_state=0)
    assert kn.ask(taught, n=3) == []
    assert ask_answer(taught, 3)["questions"] == []


def test_http_ask_answers_as_the_library(world: dict, tmp_path: Path) -> None:
    pytest.importorskip("fastapi", reason="spco serve needs its extra: pip install -e '.[serve]'")
    from fastapi.testclient import TestClient

    from spco.service import LiveHome
    from spco.service.app import create_app

    path = tmp_path / "home.spco"
    path.write_bytes(world["path"].read_bytes())
    with LiveHome(path, writer="thread") as live, TestClient(create_app(live),
                                                               base_url="http://127.0.0.1") as client:
        response = client.get("/ask", params={"n": 3})
        assert response.status_code == 200
        assert response.json() == ask_answer(live.home, 3)
        unsure = client.get("/ask", params={"n": 3, "unsure_only": "true"})
        assert unsure.json() == ask_answer(live.home, 3, unsure_only=True)
        assert live.ask(3) == response.json()
        for n in (0, 10**9, "many"):
            bad = client.get("/ask", params={"n": n})
            assert bad.status_code == 422 and "n" in bad.json()["error"]
        with pytest.raises(ConfigurationError, match="number of questions"):
            live.ask(0)


def test_the_http_question_is_the_library_question_as_json() -> None:
    """One definition of a question: the HTTP schema (``QuestionJSON``, in the OpenAPI document) has
    exactly the keys of :meth:`spco.knowledge.Question.to_dict` and takes its values."""
    pytest.importorskip("fastapi", reason="spco serve needs its extra: pip install -e '.[serve]'")
    from spco.service.schemas import QuestionJSON

    question = kn.Question(id=4, x=1.0, y=-2.0, theta=0.5, gain=0.3, reason="two concepts compete",
                           names=(("kitchen", 0.6), ("bath", 0.3)), unknown=0.1, confidence=0.6)
    assert set(QuestionJSON.model_fields) == set(question.to_dict())
    assert QuestionJSON.model_validate(question.to_dict()).model_dump() == question.to_dict()


def test_what_and_ask_answer_with_one_predictor(world: dict) -> None:
    """`what` (name_prediction), its one-pose form and `ask`'s question scores all read P(l | pose, view)
    from spco.model.confidence.answer_concepts with the home's rooms (the room account): the same
    numbers, and not the view-by-view posterior of the home's π and θ^v."""
    from spco.knowledge.asking import home_question_scores, name_columns
    from spco.knowledge.queries import answer_parameters, home_rooms
    from spco.model.confidence import answer_concepts
    from spco.model.prediction import concept_posterior
    from spco.model.rooms import concepts_by_room

    home = world["home"]
    w = home.hyperparameters.view_weight()
    params = answer_parameters(home)
    concepts = answer_concepts(params, 0, home.positions, home.visual, view_counts=w, rooms=home_rooms(home),
                               settings=home.hyperparameters.answer_settings())
    np.testing.assert_allclose(concepts, concepts_by_room(params, 0, home.positions, home.visual,
                                                          home_rooms(home), w))
    view_by_view = concept_posterior(params, 0, home.positions, home.visual, view_counts=w)
    assert np.abs(concepts - view_by_view).max() > 1e-3  # a different account, not a relabelling
    said = kn.name_prediction(home, home.positions, home.visual, top_k=len(home.vocabulary))
    theta = np.asarray(params.word_probabilities[0], dtype=float) * np.asarray(params.word_mask, bool)
    expected = concepts @ theta
    np.testing.assert_allclose(said.word_probabilities, expected / expected.sum(axis=1, keepdims=True),
                               atol=1e-12)
    columns = name_columns(home)
    model = home_question_scores(home).model_probabilities
    mine = said.word_probabilities[:, columns]
    # (the scores leave out the concepts they count unnamed: here a share of at most ~1e-5)
    np.testing.assert_allclose(model, mine / mine.sum(axis=1, keepdims=True), atol=1e-4)
    assert np.abs(model - concept_posterior_names(view_by_view, theta, columns)).max() > 1e-3
    i = 7
    x, y, s, c = (float(v) for v in home.positions[i])  # `what` at one pose: the same answer
    one = kn.what(home, x, y, float(np.arctan2(s, c)), visual=home.visual[[i]].toarray()[0], top_k=1)
    assert one.best[0] == said.best[i] and one.confidence[0] == pytest.approx(said.confidence[i])


def concept_posterior_names(concepts: np.ndarray, theta: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """p(name | x, v) over the name ``columns`` from a concept posterior, renormalised."""
    p = (concepts @ theta)[:, columns]
    return p / p.sum(axis=1, keepdims=True)
