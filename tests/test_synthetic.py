"""Tests of the synthetic home generator (spco.data.synthetic)."""

from __future__ import annotations

import itertools
import re
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spco.data.environment import Corpus, Environment
from spco.data.language import normalize_name, tokenize
from spco.data.synthetic import (
    DEFAULT_LAYOUTS,
    GENERAL_PLACES,
    SENTENCE_TEMPLATES,
    SPECIFIC_ROOM_NAMES,
    Layout,
    SyntheticConfig,
    floor_plan,
    generate_home,
    generate_homes,
    make_world,
    teach,
)
from spco.errors import ConfigurationError

SMALL = SyntheticConfig(n_features=128)  # fast, for tests that do not look at vision


@pytest.fixture(scope="module")
def corpus() -> Corpus:
    """Six experienced homes and two new ones; the last holds the home-specific bedrooms."""
    return generate_homes(8, seed=11, new_homes=2)


def _rooms(env: Environment) -> list[tuple[str, tuple[float, float, float, float]]]:
    """(general place, rectangle) of every room of a synthetic home."""
    regions = env.ground_truth.regions.places
    general = {normalize_name(p) for p in GENERAL_PLACES}
    return [(place, rect) for place, rects in regions.items() if place in general for rect in rects]


def _same(a: Environment, b: Environment) -> bool:
    return (a.name == b.name and np.array_equal(a.ids, b.ids)
            and np.array_equal(a.positions, b.positions)
            and np.array_equal(a.visual.indptr, b.visual.indptr)
            and np.array_equal(a.visual.indices, b.visual.indices)
            and np.array_equal(a.visual.data, b.visual.data)
            and a.sentences == b.sentences and np.array_equal(a.is_test, b.is_test)
            and a.extent == b.extent and a.ground_truth.labels == b.ground_truth.labels
            and a.ground_truth.specific_labels == b.ground_truth.specific_labels
            and a.ground_truth.regions == b.ground_truth.regions)


# ------------------------------------------------------------------------------ determinism
def test_same_seed_gives_identical_homes(corpus: Corpus) -> None:
    again = generate_homes(8, seed=11, new_homes=2)
    assert corpus.vocabulary == again.vocabulary
    assert all(_same(a, b) for a, b in zip(corpus, again, strict=True))


def test_different_seeds_give_different_homes() -> None:
    a = generate_homes(2, seed=0, config=SMALL)
    b = generate_homes(2, seed=1, config=SMALL)
    for x, y in zip(a, b, strict=True):
        assert x.positions.shape != y.positions.shape or not np.array_equal(x.positions, y.positions)


def test_world_is_shared_across_seeds_unless_asked() -> None:
    assert np.array_equal(make_world(SMALL, 1).topics, make_world(SMALL, 2).topics)
    free = replace(SMALL, world_seed=None)
    assert not np.array_equal(make_world(free, 1).topics, make_world(free, 2).topics)
    other = replace(SMALL, world_seed=5)
    assert not np.array_equal(make_world(SMALL).place_topics, make_world(other).place_topics)
    with pytest.raises(ConfigurationError):
        make_world(free)


def test_a_place_type_keeps_its_look_when_others_are_added() -> None:
    more = replace(SMALL, place_types=(*GENERAL_PLACES, "garage"))
    a, b = make_world(SMALL), make_world(more)
    assert np.array_equal(a.prototype("kitchen"), b.prototype("kitchen"))


def test_home_names_and_layouts(corpus: Corpus) -> None:
    layouts = {lay.name for lay in DEFAULT_LAYOUTS}
    for i, env in enumerate(corpus, start=1):
        match = re.fullmatch(r"synthetic_(\w+)_(\d+)", env.name)
        assert match and match.group(1) in layouts and int(match.group(2)) == i


# ------------------------------------------------------------------------------ geometry
def test_rooms_tile_the_house_without_overlap(corpus: Corpus) -> None:
    for env in corpus:
        x0, x1, y0, y1 = env.extent
        rooms = _rooms(env)
        rects = np.array([r for _, r in rooms])
        assert (rects[:, 0] >= x0 - 1e-9).all() and (rects[:, 1] <= x1 + 1e-9).all()
        assert (rects[:, 2] >= y0 - 1e-9).all() and (rects[:, 3] <= y1 + 1e-9).all()
        assert ((rects[:, 1] - rects[:, 0]) >= 0.99).all() and ((rects[:, 3] - rects[:, 2]) >= 0.99).all()
        for a, b in itertools.combinations(rects, 2):
            overlap = (max(0.0, min(a[1], b[1]) - max(a[0], b[0]))
                       * max(0.0, min(a[3], b[3]) - max(a[2], b[2])))
            assert overlap < 1e-9
        area = ((rects[:, 1] - rects[:, 0]) * (rects[:, 3] - rects[:, 2])).sum()
        assert area == pytest.approx((x1 - x0) * (y1 - y0))
        assert floor_plan(env) == (env.extent, dict(env.ground_truth.regions.places))


def test_every_position_lies_in_its_room(corpus: Corpus) -> None:
    for env in corpus:
        gt = env.ground_truth
        for kind in filter(None, (gt.labels, gt.specific_labels)):
            labels = np.array(kind)
            for place in set(kind):
                inside = gt.regions.contains(place, env.positions[labels == place, :2])
                assert inside.all(), (env.name, place)
        norm = env.positions[:, 2] ** 2 + env.positions[:, 3] ** 2
        assert np.allclose(norm, 1.0)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), layout=st.sampled_from(DEFAULT_LAYOUTS))
def test_any_home_is_consistent(seed: int, layout: Layout) -> None:
    env = generate_home(seed, layout=layout, config=SMALL, new=seed % 2 == 0)
    labels = np.array(env.ground_truth.labels)
    rooms = _rooms(env)
    for place in set(labels):
        assert env.ground_truth.regions.contains(place, env.positions[labels == place, :2]).all()
    assert len(rooms) * SMALL.n_train == env.n_train
    present = tuple(p for p in layout.optional if normalize_name(p) in labels)
    assert sorted(p for p, _ in rooms) == sorted(normalize_name(r) for r in layout.rooms + present)


# ------------------------------------------------------------------------------ samples
def test_blocks_split_and_sentences(corpus: Corpus) -> None:
    experienced, new = list(corpus)[:-2], list(corpus)[-2:]
    for env in experienced:
        assert env.n_test == 0 and env.n_taught == env.n_train
        labels = env.labels(specific=env.ground_truth.specific_labels is not None)
        for sentence, label in zip(env.sentences, labels, strict=True):
            assert normalize_name(sentence) in {normalize_name(t.format(the="the ", name=label))
                                                for t in SENTENCE_TEMPLATES}
            assert label in tokenize(sentence)
    for env in new:
        assert all(s is None for s in env.sentences) and env.n_taught == 0
        labels = np.array(env.ground_truth.labels)
        n_rooms = {p: len(r) for p, r in env.ground_truth.regions.places.items()}
        for place in set(labels):
            assert (labels[env.is_test] == place).sum() == 10 * n_rooms[place]
        # test blocks come after the training blocks of the general rooms
        first_test = int(np.argmax(env.is_test))
        assert not env.is_test[:first_test].any() and first_test == 20 * len(_rooms(env))
    for env in corpus:
        labels = np.array(env.ground_truth.labels)
        assert (labels[:20] == labels[0]).all()  # consecutive blocks of one room
        train = labels[~env.is_test]
        assert all((train[i:i + 20] == train[i]).all() for i in range(0, train.size, 20))


def test_home_specific_rooms_in_exactly_one_home(corpus: Corpus) -> None:
    with_specific = [env for env in corpus if env.ground_truth.specific_labels is not None]
    assert [env.name for env in with_specific] == [corpus[-1].name]
    env = with_specific[0]
    gt = env.ground_truth
    names = [normalize_name(n) for n in SPECIFIC_ROOM_NAMES]
    specific = np.array(gt.specific_labels)
    general = np.array(gt.labels)
    for name in names:
        rows = specific == name
        assert rows.sum() == 20 + 10 + 20  # training, test and extra training samples
        assert (general[rows] == "bedroom").all()
        assert name in gt.regions.places
    assert gt.specific_test.sum() == 30
    assert set(specific[gt.specific_test]) == set(names)
    assert (env.is_test[gt.specific_test]).all()
    assert env.n_samples == 10 * 20 + 10 * 10 + 3 * 20  # as 3LDK_9


def test_specific_rooms_can_be_renamed_or_left_out() -> None:
    plain = generate_homes(3, seed=2, config=SMALL, specific_rooms=False)
    assert all(env.ground_truth.specific_labels is None for env in plain)
    named = generate_homes(2, seed=2, config=SMALL, specific_rooms=["Kenji's-room", "study-room"])
    assert set(named[-1].ground_truth.specific_labels) >= {"kenji's room", "study room"}
    assert "kenji's room" in named.vocabulary  # experienced home: taught with the names
    with pytest.raises(ConfigurationError):
        generate_home(0, layout="1K", config=SMALL, specific_names=["a", "b"])


def test_teaching_rate_of_experienced_homes() -> None:
    corpus = generate_homes(3, seed=4, config=SMALL, teaching_rate=25, specific_rooms=False)
    for env in corpus:
        assert env.n_taught == round(env.n_train * 0.25)


def test_teach_reproduces_the_home_specific_experiment(corpus: Corpus) -> None:
    env = corpus[-1]
    taught = teach(env, 20, places=SPECIFIC_ROOM_NAMES, seed=3)
    specific = np.array(env.ground_truth.specific_labels)
    said = [(s, lab) for s, lab in zip(taught.sentences, specific, strict=True) if s is not None]
    assert len(said) == 3 * 8
    assert all(lab in tokenize(s) and lab.split(" ")[0].endswith("'s") for s, lab in said)
    assert all(not s.startswith("this is the") for s, _ in said)  # no article before a possessive
    assert not any(s for s, t in zip(taught.sentences, taught.is_test, strict=True) if t)
    full = teach(env, 100, specific=False)
    assert full.n_taught == env.n_train
    assert teach(env, 20, places=SPECIFIC_ROOM_NAMES, seed=3).sentences == taught.sentences


def test_free_form_and_wrong_names() -> None:
    cfg = replace(SMALL, free_form_rate=1.0)
    env = generate_home(1, layout="2LDK", config=cfg)
    templates = {t.format(the="the ", name=lab) for lab in set(env.ground_truth.labels)
                 for t in SENTENCE_TEMPLATES}
    for sentence, label in zip(env.sentences, env.ground_truth.labels, strict=True):
        assert sentence not in templates and label in tokenize(sentence)
    wrong = generate_home(1, layout="2LDK", config=replace(SMALL, wrong_name_rate=1.0))
    for sentence, label in zip(wrong.sentences, wrong.ground_truth.labels, strict=True):
        assert label not in tokenize(sentence)


def test_free_language_varies_as_people_speak() -> None:
    free = replace(SMALL, language="free")
    corpus = generate_homes(6, seed=0, config=free, specific_rooms=False)
    again = generate_homes(6, seed=0, config=free, specific_rooms=False)
    assert [e.sentences for e in corpus] == [e.sentences for e in again]  # same seed, same speech
    templates = generate_homes(6, seed=0, config=SMALL, specific_rooms=False)
    assert [e.positions.tolist() for e in corpus] == [e.positions.tolist() for e in templates]
    said = [(s, lab) for e in corpus for s, lab in zip(e.sentences, e.ground_truth.labels, strict=True) if s]
    assert len({s for s, _ in said}) > 0.4 * len(said)  # many phrasings
    vocab = corpus.vocabulary
    assert {"living room", "dining room", "front door"} <= set(vocab.terms)  # learnt multi-word names
    assert {"bathroom", "shower", "fridge"} <= set(vocab.words)  # synonyms and objects
    gt = corpus[0].ground_truth
    assert gt.accepted("bath")[:2] == ("bath", "bathroom") and "shower" in gt.accepted("bath")
    assert "living room" in gt.accepted("living-room")
    # most sentences name the place, or one of its synonyms, as a token
    named = sum(any(t in gt.accepted(lab) for t in vocab.tokenize(s)) for s, lab in said)
    assert 0.5 < named / len(said) < 0.95
    with pytest.raises(ConfigurationError, match="language"):
        SyntheticConfig(language="klingon")


# ------------------------------------------------------------------------------ vision
def test_visual_counts_look_like_the_real_ones(corpus: Corpus) -> None:
    cfg = SyntheticConfig()
    assert cfg.mean_counts == 1825
    for env in corpus:
        assert env.n_features == cfg.n_features and env.visual.dtype == np.int64
        totals = env.visual.sum(axis=1)
        nonzero = np.diff(env.visual.indptr) / env.n_features
        assert abs(totals.mean() / cfg.mean_counts - 1) < 0.05
        assert 0.05 < totals.std() / totals.mean() < 0.2
        assert 0.15 < nonzero.mean() < 0.25
        assert 5 <= np.median(env.visual.data) <= 10 and env.visual.data.max() < 200


def test_real_dimension_has_real_density() -> None:
    env = generate_home(0, layout="1K", config=SyntheticConfig(n_features=4096))
    totals = env.visual.sum(axis=1)
    assert abs(totals.mean() - 7300) < 300
    assert 0.15 < np.diff(env.visual.indptr).mean() / 4096 < 0.25


def test_vision_transfers_to_a_new_home_but_not_perfectly() -> None:
    corpus = generate_homes(12, seed=0, new_homes=4, specific_rooms=False)
    experienced, new = list(corpus)[:8], list(corpus)[8:]

    def normalised(env: Environment) -> np.ndarray:
        x = env.visual.toarray().astype(float)
        return x / x.sum(axis=1, keepdims=True)

    x = np.concatenate([normalised(env) for env in experienced])
    y = np.concatenate([env.ground_truth.labels for env in experienced])
    places = sorted(set(y))
    centroids = np.stack([x[y == p].mean(axis=0) for p in places])
    centroids /= np.linalg.norm(centroids, axis=1, keepdims=True)
    correct = total = 0
    for env in new:
        xt = normalised(env)[env.is_test]
        yt = np.array(env.ground_truth.labels)[env.is_test]
        predicted = np.array(places)[np.argmax(xt @ centroids.T, axis=1)]
        correct += int((predicted == yt).sum())
        total += yt.size
    chance = 1 / len(places)
    assert 0.5 < correct / total < 0.995 and correct / total > 3 * chance


# ------------------------------------------------------------------------------ arguments
@pytest.mark.parametrize("kwargs", [
    {"n_features": 0}, {"place_distinctness": 0.8, "group_similarity": 0.3}, {"view_mixing": 1.0},
    {"free_form_rate": 1.5}, {"place_types": ("kitchen", "kitchen")},
    {"layouts": (Layout("X", ("garage",)),)}, {"specific_names": ("kitchen",)},
    {"similar_places": (("bath", "moon"),)}, {"counts_per_image": 0},
])
def test_bad_config_is_refused(kwargs: dict) -> None:
    with pytest.raises(ConfigurationError):
        SyntheticConfig(**kwargs)


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ConfigurationError):
        generate_homes(0)
    with pytest.raises(ConfigurationError):
        generate_homes(2, new_homes=3)
    with pytest.raises(ConfigurationError):
        generate_homes(2, teaching_rate=101)
    with pytest.raises(ConfigurationError):
        generate_home(0, layout="5LDK")
    with pytest.raises(ConfigurationError):
        generate_home(0, config=SMALL, world=make_world())
    with pytest.raises(ConfigurationError):
        generate_home(-1, config=SMALL)
    with pytest.raises(ConfigurationError):
        generate_homes(2, seed=-3, config=SMALL)
    with pytest.raises(ConfigurationError):
        generate_home(0, layout="3LDK", config=SMALL, specific_names=["a-room", "A-room"])
    with pytest.raises(ConfigurationError):
        generate_home(0, layout="3LDK", config=SMALL, specific_names=["kitchen"])
    with pytest.raises(ConfigurationError):
        teach(generate_home(0, config=SMALL), 120)
