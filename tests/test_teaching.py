"""Teaching a live home: a local update, an exact undo, and the limits of what a teaching brings."""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from serve_helpers import build_home

from spco import knowledge as kn
from spco.errors import TeachingLimitError, TeachingRateError
from spco.knowledge.requests import Pose, Teach, Undo
from spco.model.local_update import splice_posterior
from spco.service.teaching import ConflictError, undo_base_path
from spco.service.writer import HomeWriter


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_home(tmp_path_factory.mktemp("teaching"))


@pytest.fixture
def home(built: Path, tmp_path: Path) -> Path:
    target = tmp_path / "home.spco"
    shutil.copyfile(built, target)
    return target


def _arrays(home: kn.HomeModel) -> dict[str, np.ndarray]:
    out = {"state." + k: np.asarray(v) for k, v in vars(home.state).items() if isinstance(v, np.ndarray)}
    out.update({"posterior." + k: v for k, v in home.posterior.arrays().items()})
    return out


def _answers(home: kn.HomeModel) -> dict[str, object]:
    """Every answer an undo must give back: what at every sample (pose and view), where of every name."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prediction = kn.name_prediction(home, home.positions, home.visual, top_k=5)
        out: dict[str, object] = {"vocabulary": tuple(home.vocabulary.words),
                                  "what": (prediction.words, np.asarray(prediction.probabilities))}
        for name in home.known_names:
            out[name] = np.asarray(kn.where(home, name, n=5, random_state=0).region_probabilities)
    return out


def _assert_same_answers(a: kn.HomeModel, b: kn.HomeModel) -> None:
    x, y = _answers(a), _answers(b)
    assert x.keys() == y.keys()
    assert x["vocabulary"] == y["vocabulary"]
    words = [np.asarray(answers["what"][0], dtype=object) for answers in (x, y)]
    np.testing.assert_array_equal(*words)
    np.testing.assert_array_equal(x["what"][1], y["what"][1])
    for name in x:
        if name not in ("vocabulary", "what"):
            np.testing.assert_array_equal(x[name], y[name])


def _teach(model: kn.HomeModel, sentences: dict | None = None, observations: list | tuple = (),
           **options: object) -> kn.HomeModel:
    """:func:`spco.knowledge.teach` without its warnings (a new name spreading: said, not tested here)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return kn.teach(model, sentences, observations, **options)  # type: ignore[arg-type]


# ----------------------------------------------------------------------------- a local update
def test_a_teaching_changes_the_taught_place_and_leaves_the_rest_as_it_was(home: Path) -> None:
    model = kn.load_home_model(home)
    row = 7
    taught = _teach(model, {int(model.ids[row]): "this is the quokka room"}, random_state=4)
    again = _teach(model, {int(model.ids[row]): "this is the quokka room"}, random_state=4)
    for name, value in _arrays(taught).items():  # the same seed: the same home, bit for bit
        np.testing.assert_array_equal(value, _arrays(again)[name], err_msg=name)
    before, after = model.posterior, taught.posterior
    region = int(taught.state.regions[row])
    # the samples outside the taught sample's region keep their concept and region
    outside = model.state.regions != model.state.regions[row]
    assert (taught.state.regions[:model.n_samples][outside] == model.state.regions[outside]).all()
    assert (taught.state.concepts[:model.n_samples][outside] == model.state.concepts[outside]).all()
    # every region the teaching did not touch answers exactly as before
    named = taught.state.regions[taught.state.concepts == taught.state.concepts[row]]
    untouched = [k for k in range(before.n_regions) if k != region
                 and not (taught.state.regions == k).any() ^ (model.state.regions == k).any()
                 and not np.isin(k, named)]
    assert len(untouched) >= before.n_regions // 2
    for k in untouched:
        np.testing.assert_array_equal(after.region_means[0, k], before.region_means[0, k])
    # and most concepts keep their views and words
    same = [c for c in range(before.n_concepts)
            if np.array_equal(after.visual_probabilities[0, c], before.visual_probabilities[0, c])]
    assert len(same) >= before.n_concepts // 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        answer = kn.where(taught, "quokka room", n=10, random_state=0)
    assert answer.learnt and int(answer.region) == region


def test_a_teaching_regroups_only_its_own_names_not_the_homes_other_new_names(home: Path) -> None:
    import copy
    from dataclasses import replace

    model = kn.load_home_model(home)
    row_a = 7
    named = _teach(model, {int(model.ids[row_a]): "this is the quokka room"}, random_state=1)
    concept_a = int(named.state.concepts[row_a])
    of_a = np.flatnonzero(named.state.concepts == concept_a)
    # a posterior in which the name's samples are not all in one concept: one of them elsewhere
    spread = copy.deepcopy(named.state)
    other = int(np.flatnonzero(np.arange(named.posterior.n_concepts) != concept_a)[0])
    spread.concepts[row_a] = other
    spread_home = replace(named, state=spread)
    far = np.flatnonzero(~np.isin(named.state.regions, named.state.regions[of_a]))
    row_b = int(far[len(far) // 2])
    taught = _teach(spread_home, {int(model.ids[row_b]): "this is the zephyr room"}, random_state=2)
    # the teaching of "zephyr room" gave its own name a concept, and left "quokka room"'s samples as the
    # home's posterior had them (not regrouped into a concept of their own)
    assert taught.state.concepts[row_b] not in set(spread.concepts[of_a].tolist())
    np.testing.assert_array_equal(taught.state.concepts[of_a], spread.concepts[of_a])


def test_a_new_name_stands_for_its_place_not_for_another_concepts_samples_of_the_region(home: Path) -> None:
    """A region that spans two places (two concepts): a name taught at one of them takes that place's
    untaught samples with it, and leaves the other concept's samples of the region as they were."""
    import copy
    from dataclasses import replace

    model = kn.load_home_model(home)
    row = 7
    region, concept = int(model.state.regions[row]), int(model.state.concepts[row])
    mates = np.flatnonzero((model.state.regions == region) & (np.arange(model.n_samples) != row))
    assert mates.size >= 4
    # half of the region's other samples made another concept's: the region spans two places
    mixed = copy.deepcopy(model.state)
    other = int(np.flatnonzero(np.arange(model.posterior.n_concepts) != concept)[0])
    elsewhere, own = mates[: mates.size // 2], mates[mates.size // 2:]
    mixed.concepts[elsewhere] = other
    # no sweeps: what the name stands for, before the sampler weighs the (made-up) other concept
    taught = _teach(replace(model, state=mixed), {int(model.ids[row]): "this is the quokka room"},
                    n_sweeps=0, random_state=3)
    named = int(taught.state.concepts[row])
    assert named not in (concept, other)
    assert (taught.state.concepts[own] == named).any()  # its place's untaught samples come with the name
    assert (taught.state.concepts[elsewhere] == other).all()  # the other place's stay


def test_a_teaching_answers_with_the_posterior_mean_of_its_regions_gaussians(home: Path) -> None:
    """The taught regions' Gaussians in the answers are their posterior mean given the sweeps'
    assignments (the NIW posterior predictive's moments), not the average of two draws: with one
    sweep, exactly those of the samples the state holds in each affected region."""
    from spco.model import parameter_steps
    from spco.model.local_update import expected_gaussians

    model = kn.load_home_model(home)
    row = 7
    taught = _teach(model, {int(model.ids[row]): "this is the quokka room"}, n_sweeps=1, random_state=4)
    data, state = taught.data, taught.state
    shared = taught.knowledge.shared_part()
    prior = parameter_steps.niw_prior(data, shared.hyperparameters, shared.sampler_settings())
    region = int(state.regions[row])
    x = data.positions[state.regions == region]
    count = np.array([float(x.shape[0])])
    means, covariances = expected_gaussians(count, x.sum(axis=0)[None], (x.T @ x)[None], prior)
    scale = np.array([model.position_scale, model.position_scale, 1.0, 1.0])
    after = taught.posterior
    np.testing.assert_allclose(after.region_means[0, region], means[0] / scale, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(after.region_covariances[0, region], covariances[0] / np.outer(scale, scale),
                               rtol=1e-9, atol=1e-12)
    # the state keeps the chain's draw (the next teaching goes on from it)
    assert not np.allclose(state.means[0, region], means[0])


def test_a_new_observation_is_placed_where_it_is_not_in_region_0(home: Path) -> None:
    model = kn.load_home_model(home)
    nonzero = np.flatnonzero(model.state.regions != 0)
    row = int(nonzero[len(nonzero) // 2])
    x, y = (float(v) for v in model.positions[row, :2])
    theta = float(np.arctan2(model.positions[row, 2], model.positions[row, 3]))
    taught = _teach(model, observations=[kn.Observation(x=x, y=y, theta=theta, sentence="the zephyr")],
                    random_state=0)
    assert taught.state.regions[-1] == taught.state.regions[row]


def test_splice_keeps_untouched_concepts_and_regions_and_the_concept_weights_sum_to_one(home: Path) -> None:
    model = kn.load_home_model(home)
    previous = model.posterior
    rng = np.random.default_rng(0)
    updated = type(previous)(**{k: (v * rng.uniform(0.5, 1.5, size=v.shape) if v.dtype.kind == "f" else v)
                                for k, v in previous.arrays().items()})
    spliced = splice_posterior(previous, updated, np.array([1, 2]), np.array([0]))
    np.testing.assert_array_equal(spliced.visual_probabilities[0, 3], previous.visual_probabilities[0, 3])
    np.testing.assert_array_equal(spliced.visual_probabilities[0, 1], updated.visual_probabilities[0, 1])
    np.testing.assert_array_equal(spliced.region_means[0, 1], previous.region_means[0, 1])
    np.testing.assert_array_equal(spliced.region_means[0, 0], updated.region_means[0, 0])
    np.testing.assert_array_equal(spliced.concept_weights[0, 3:], previous.concept_weights[0, 3:])
    assert spliced.concept_weights.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(spliced.word_probabilities.sum(axis=-1), 1.0)


# ----------------------------------------------------------------------------- undo restores
def _teach_library(model: kn.HomeModel, record: dict) -> kn.HomeModel:
    options = {"n_sweeps": int(record["sweeps"]), "random_state": int(record["seed"])}
    if record["op"] == "sentence":
        return _teach(model, {int(record["id"]): record["sentence"]}, **options)
    obs = kn.Observation(x=record["x"], y=record["y"], theta=record["theta"], sentence=record["sentence"],
                         id=int(record["id"]))
    return _teach(model, observations=[obs], **options)


def test_undo_gives_every_answer_back_exactly_through_compaction_and_a_restart(home: Path) -> None:
    original = kn.load_home_model(home)
    # the home learns its words with the word channels: the undo gives their switches back too
    assert original.knowledge.channels is not None and original.state.switches is not None
    ids = [int(i) for i in original.ids[:6]]
    writer = HomeWriter(home, seed=5, compact_records=2, compact_idle=3600)
    requests = [Teach(sentence="this is the quokka room", id=ids[0]),
                Teach(sentence="the zephyr hall", pose=Pose(0.2, -0.3, 0.1)),
                Teach(sentence="this is the marimba room", id=ids[1]),
                Teach(sentence="this is the tundra", id=ids[0]),
                Teach(sentence="this is the quokka room", id=ids[2])]
    snapshots = []
    for request in requests:
        snapshots.append(writer.snapshot())
        assert writer.handle([request])[0]["ok"]
    # the last teaching undone: the home as it was before it
    assert writer.handle([Undo(5)])[0]["ok"]
    _assert_same_answers(writer.snapshot(), snapshots[4])
    # a teaching in the middle undone: the later ones replayed, as if it had never been made
    assert writer.handle([Undo(2)])[0]["ok"]
    expected = original
    for seq in (1, 3, 4):
        expected = _teach_library(expected, writer.history[seq]["record"])
    words = writer.home.vocabulary.words
    assert "zephyr hall" not in words and "zephyr" not in words and "marimba room" in words
    _assert_same_answers(writer.snapshot(), expected)
    np.testing.assert_array_equal(writer.snapshot().state.switches, expected.state.switches)
    after_undo = writer.snapshot()
    writer.close()
    assert undo_base_path(home).exists()
    restarted = HomeWriter(home, seed=5)
    _assert_same_answers(restarted.snapshot(), after_undo)
    with pytest.raises(ConflictError, match="undone already"):
        raise ConflictError(restarted.handle([Undo(2)])[0]["error"])
    restarted.close()


def test_undo_of_an_old_teaching_is_refused_saying_why(home: Path) -> None:
    model = kn.load_home_model(home)
    writer = HomeWriter(home, seed=1, undo_limit=2, compact_idle=3600)
    for k in range(4):
        request = Teach(sentence="this is the den", id=int(model.ids[k]))
        assert writer.handle([request])[0]["ok"]
    refused = writer.handle([Undo(1)])[0]
    assert not refused["ok"] and refused["kind"] == "ConflictError"
    assert "not among the last 2 teachings" in refused["error"] and "--undo-limit" in refused["error"]
    assert writer.handle([Undo(3)])[0]["ok"]
    # an observation whose sample a later teaching named: that one first
    added = writer.handle([Teach(sentence="the den", pose=Pose(0.1, 0.1, 0.0))])[0]
    assert writer.handle([Teach(sentence="this is the hall", id=added["id"])])[0]["ok"]
    refused = writer.handle([Undo(added["seq"])])[0]
    assert not refused["ok"] and "undo that one first" in refused["error"]
    writer.close()


# ----------------------------------------------------------------------------- limits
def test_limits_refuse_a_teaching_whole_naming_the_limit(home: Path) -> None:
    model = kn.load_home_model(home)
    sample = int(model.ids[0])
    limits = kn.TeachingLimits(max_sentence_words=6, max_new_words=2, max_home_words=3)
    with pytest.raises(TeachingLimitError, match="max_sentence_words") as error:
        kn.teach(model, {sample: "this is the room where we keep the old piano"}, limits=limits)
    assert error.value.limit == "max_sentence_words" and error.value.allowed == 6
    with pytest.raises(TeachingLimitError, match="max_new_words"):
        kn.teach(model, {sample: "zork the blip the quux"}, limits=limits)  # three new words
    grown = _teach(model, {sample: "zork the blip"}, limits=limits, n_sweeps=1)
    with pytest.raises(TeachingLimitError, match="max_home_words"):
        kn.teach(grown, {sample: "quux the frob"}, limits=limits)
    kn.TeachingLimits(max_home_words=None)  # no limit of that kind
    with pytest.raises(Exception, match="max_new_words: expected an integer"):
        kn.TeachingLimits(max_new_words=-1)


def test_the_writer_limits_observations_a_minute_and_words_across_a_batch(home: Path) -> None:
    limits = kn.TeachingLimits(max_observations_per_minute=2, max_new_words=2, max_home_words=3)
    writer = HomeWriter(home, seed=0, limits=limits, compact_idle=3600)
    results = writer.handle([Teach(sentence=None, pose=Pose(0.1, 0.1, 0.0))
                             for _ in range(3)])
    assert [r["ok"] for r in results] == [True, True, False]
    assert results[2]["kind"] == TeachingRateError.__name__
    assert results[2]["limit"] == "max_observations_per_minute"
    sample = int(writer.home.ids[0])
    results = writer.handle([Teach(sentence="zork the blip", id=sample),
                             Teach(sentence="quux the frob", id=int(writer.home.ids[1]))])
    assert results[0]["ok"] and not results[1]["ok"] and results[1]["limit"] == "max_home_words"
    writer.close()
