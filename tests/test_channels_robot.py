"""One word model on the robot's path: knowledge and home files carry the word channels, and `adapt`,
`teach` (the local update, its undo) and the answers of `what`, `where` and `ask` use them — never the
naming rule, which stays only for speech without English function words."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from spco import knowledge as kn
from spco.data.environment import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.errors import ModelFileError
from spco.model import gibbs, home_shard
from spco.model.word_channels import switch_probabilities

CONFIG = SyntheticConfig(n_features=128)


@pytest.fixture(scope="module")
def world() -> dict:
    """A knowledge of 5 synthetic homes (30 sweeps) and a new home adapted to it (untaught)."""
    corpus = generate_homes(6, seed=4, config=CONFIG, new_homes=1, specific_rooms=False)
    homes = list(corpus)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        knowledge = kn.fit_knowledge(Corpus(homes[:5]), n_iterations=30, random_state=4)
        home = kn.adapt(knowledge, homes[5], n_iterations=20, random_state=4)
    return {"knowledge": knowledge, "home": home, "new": homes[5]}


def _quiet(function, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function(*args, **kwargs)


def test_a_knowledge_is_learnt_with_the_channels_and_says_so(world: dict) -> None:
    knowledge = world["knowledge"]
    assert knowledge.hyperparameters.word_model == "channels"
    channels = knowledge.channels
    assert channels is not None
    L, V = knowledge.n_concepts, knowledge.n_words
    assert channels.channels.log_place.shape == (L, V) and channels.tokens.shape == (V, 3)
    np.testing.assert_allclose(np.exp(channels.channels.log_place).sum(axis=1), 1.0)
    np.testing.assert_allclose(np.exp(channels.channels.log_background).sum(), 1.0)
    # the names said by each concept's samples and at their places (averaged over the kept sweeps)
    assert channels.place_names is not None and channels.place_names.shape == (L, V)
    assert (channels.place_names >= 0).all()
    used = np.exp(knowledge.log_g0) > 0.01
    assert (channels.place_names[used].sum(axis=1) > 0).all()
    names = {knowledge.vocabulary.words[k] for k in np.argmax(channels.place_names[used], axis=1)}
    assert names <= set(knowledge.known_names), names
    # the template's frame words are background, the places' names names
    for word in ("this", "is", "the"):
        assert word not in knowledge.known_names
    assert {"kitchen", "toilet"} <= set(knowledge.known_names)


def test_a_knowledge_exports_the_place_words_as_the_kept_sweeps_conditional_means(monkeypatch) -> None:
    """The knowledge's ψ is the average over the kept sweeps of E[ψ | the sweep's place tokens]
    (Dir(α^p + n)'s mean, relabelled like φ), not of the sweeps' draws: a concept that holds no place
    token in any kept sweep gets the prior's mean 1/V exactly (an average of a few Dir(0.1) draws is a
    spike), and the exported ψ is the mean of the draws the chain makes from the same counts."""
    from spco.knowledge import fit as fit_module
    from spco.model import shard
    from spco.model.word_channels import ALPHA_PLACE, sample_channels

    counts_by_sweep: list = []
    original_mean = shard.place_mean

    def recording_mean(counts, *args, **kwargs):
        counts_by_sweep.append(counts)
        return original_mean(counts, *args, **kwargs)

    seen: dict = {}
    original_average = fit_module._averaged_channels

    def recording_average(samples, perms, *args, **kwargs):
        seen["samples"], seen["perms"] = samples, perms
        return original_average(samples, perms, *args, **kwargs)

    monkeypatch.setattr(shard, "place_mean", recording_mean)
    monkeypatch.setattr(fit_module, "_averaged_channels", recording_average)
    corpus = generate_homes(4, seed=7, config=CONFIG, new_homes=0, specific_rooms=False)
    n_iterations = 12
    knowledge = _quiet(kn.fit_knowledge, Corpus(list(corpus)), n_iterations=n_iterations, random_state=7)
    assert len(counts_by_sweep) == n_iterations  # one global step per sweep
    kept = knowledge.provenance["summary"]["iterations"]
    assert len(kept) >= 2 and len(seen["samples"]) == len(kept)
    psi = np.exp(knowledge.channels.channels.log_place)
    L, V = psi.shape
    expected = np.zeros((L, V))
    empty = np.ones(L, dtype=bool)  # no place token in any kept sweep (after relabelling)
    for sample, perm, sweep in zip(seen["samples"], seen["perms"], kept, strict=True):
        place = np.asarray(counts_by_sweep[sweep].place, dtype=np.float64)
        mean = (ALPHA_PLACE + place) / (ALPHA_PLACE + place).sum(axis=1, keepdims=True)
        np.testing.assert_allclose(np.exp(sample.log_place), mean, rtol=1e-12)
        expected += mean[perm] / len(kept)
        empty &= place[perm].sum(axis=1) == 0
    np.testing.assert_allclose(psi, expected, rtol=1e-10)
    assert empty.any() and (~empty).any()
    np.testing.assert_allclose(psi[empty], 1.0 / V, rtol=1e-12)  # the prior's mean, exactly
    assert (psi[~empty].max(axis=1) > 1.5 / V).all()  # the held concepts keep their words
    # the mean of the chain's draws from the last kept sweep's counts is that sweep's exported ψ
    last = counts_by_sweep[kept[-1]]
    rng = np.random.default_rng(0)
    draws = np.mean([np.exp(sample_channels(last, seen["samples"][-1], rng).log_place)
                     for _ in range(2000)], axis=0)
    np.testing.assert_allclose(draws, np.exp(seen["samples"][-1].log_place), atol=0.03)
    # a single draw of an empty concept is a spike, which the export no longer is
    assert draws.shape == (L, V) and np.exp(sample_channels(last, seen["samples"][-1], rng).log_place)[
        np.flatnonzero(empty)].max() > 2.0 / V


def test_knowledge_and_home_files_round_trip_the_channels(world: dict, tmp_path: Path) -> None:
    knowledge, home = world["knowledge"], world["home"]
    knowledge.save(tmp_path / "k.spco")
    again = kn.load_knowledge(tmp_path / "k.spco")
    assert again.checksum == knowledge.checksum and again.hyperparameters.word_model == "channels"
    for name in ("log_place", "log_background", "log_shares", "log_evidence"):
        np.testing.assert_array_equal(getattr(again.channels.channels, name),
                                      getattr(knowledge.channels.channels, name))
    np.testing.assert_array_equal(again.channels.tokens, knowledge.channels.tokens)
    np.testing.assert_array_equal(again.channels.place_names, knowledge.channels.place_names)
    home.save(tmp_path / "h.spco")
    loaded = kn.load_home_model(tmp_path / "h.spco")
    np.testing.assert_array_equal(loaded.state.switches, home.state.switches)
    assert loaded.state.channels is not None
    np.testing.assert_array_equal(loaded.name_mask, home.name_mask)
    with np.load(tmp_path / "h.spco", allow_pickle=False) as archive:
        header = json.loads(archive["header"].tobytes().decode())
    assert header["format_version"] == 4 and header["hyperparameters"]["word_model"] == "channels"


def _rewrite_header(src: Path, dst: Path, change) -> Path:
    """``src`` with its header changed and its content checksum sealed again (a file as an older
    spco wrote it, not an edited one)."""
    from spco.knowledge.files import _content_checksum

    with np.load(src, allow_pickle=False) as archive:
        arrays = {k: archive[k] for k in archive.files}
    header = json.loads(arrays.pop("header").tobytes().decode())
    change(header, arrays)
    from spco.model.archive import checksum

    header["array_checksums"] = {n: checksum(a) for n, a in arrays.items()}
    header["checksum"] = _content_checksum(header)
    raw = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    with open(dst, "wb") as handle:
        np.savez(handle, header=raw, **arrays)
    return dst


def test_a_file_written_before_the_channels_is_refused_saying_what_to_do(world: dict, tmp_path: Path) -> None:
    world["knowledge"].save(tmp_path / "k.spco")
    world["home"].save(tmp_path / "h.spco")

    def as_version_3(header: dict, arrays: dict) -> None:
        header["format_version"] = 3
        header["hyperparameters"]["word_model"] = "naming-rule"
        for name in [n for n in arrays if "channels." in n or n == "state.switches"]:
            del arrays[name]

    old_k = _rewrite_header(tmp_path / "k.spco", tmp_path / "old_k.spco", as_version_3)
    with pytest.raises(ModelFileError, match=r"format version 3.*naming rule.*spco fit"):
        kn.load_knowledge(old_k)
    old_h = _rewrite_header(tmp_path / "h.spco", tmp_path / "old_h.spco", as_version_3)
    with pytest.raises(ModelFileError, match=r"format version 3.*naming rule.*spco adapt"):
        kn.load_home_model(old_h)

    def without_channels(header: dict, arrays: dict) -> None:  # a version-4 file missing its channels
        for name in [n for n in arrays if "channels." in n]:
            del arrays[name]

    broken = _rewrite_header(tmp_path / "k.spco", tmp_path / "broken.spco", without_channels)
    with pytest.raises(ModelFileError, match="word_model 'channels' but the knowledge holds none"):
        kn.load_knowledge(broken)


def test_the_home_path_never_runs_the_naming_rule_with_the_channels(world: dict,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """adapt, teach (a new name, a new observation), what, where and ask on a home learnt with the
    channels: the naming rule's verdicts are never asked for."""

    def refuse(*args, **kwargs):
        raise AssertionError("the naming rule ran on a home learnt with the word channels")

    monkeypatch.setattr(gibbs, "naming_verdicts", refuse)
    monkeypatch.setattr(home_shard.gibbs, "naming_verdicts", refuse)
    home = _quiet(kn.adapt, world["knowledge"], world["new"], n_iterations=5, random_state=1)
    taught = _quiet(kn.teach, home, {int(home.ids[3]): "this is emma's room"}, random_state=1)
    observed = _quiet(kn.teach, taught, observations=[kn.Observation(0.1, 0.2, 0.0, sentence="the kitchen")],
                      random_state=2)
    _quiet(kn.what, observed, *observed.positions[3, :2], 0.0)
    _quiet(kn.where, observed, "kitchen", random_state=0)
    _quiet(kn.ask, observed, n=2)


def test_what_answers_from_the_channels_names_not_the_naming_rule(world: dict) -> None:
    """The names `what` may answer are the words the switches make names (the fit's name tokens and
    the home's expected ones, recomputed here from the switch probabilities), not the naming rule's
    kept words."""
    home = world["home"]
    data, state = home.data, home.state
    p = switch_probabilities(data.words, data.homes, state.concepts, state.log_theta_w, state.channels)
    tokens = home.knowledge.channels.tokens.copy()
    np.add.at(tokens, data.words.indices, p)
    names = tokens[:, 0]
    expected = (names >= home_shard.NAME_TOKENS) & (names >= home_shard.NAME_SHARE * tokens.sum(axis=1))
    np.testing.assert_array_equal(home.name_mask, expected)
    params = kn.answer_parameters(home)
    np.testing.assert_array_equal(params.word_mask, home.name_mask)
    prediction = kn.name_prediction(home, home.positions, home.visual, top_k=3)
    answered = {w for row in prediction.words for w in row if w is not None}
    assert answered and answered <= set(home.known_names)
    assert not answered & {"this", "is", "the", "here"}


def _teach_two(home: kn.HomeModel, name_sentence: str) -> tuple[kn.HomeModel, int, int]:
    """``name_sentence`` taught at sample 7, "the fridge is over here" at the sample farthest from it."""
    dist = np.linalg.norm(home.positions[:, :2] - home.positions[7, :2], axis=1)
    far = int(np.argmax(dist))
    taught = _quiet(kn.teach, home, {int(home.ids[7]): name_sentence,
                                     int(home.ids[far]): "the fridge is over here"}, random_state=0)
    return taught, 7, far


def test_a_name_said_once_is_answerable_there_and_an_object_is_not(world: dict) -> None:
    """"this is the study room" said once at a pose makes "study room" answerable there; "the fridge is
    over here" said at another does not make "fridge" a place name (it is a word of that place, which
    `where` still finds). A word first heard in the home is a name as its evidence says (its switch's
    prior: with no other use, that is its posterior)."""
    taught, at, far = _teach_two(world["home"], "this is the study room")
    assert "study room" in taught.known_names
    assert "fridge" not in taught.known_names
    pose = taught.positions[at]
    answer = _quiet(kn.what, taught, pose[0], pose[1], float(np.arctan2(pose[2], pose[3])),
                    visual=taught.visual[[at]])
    assert answer.words[0][0] == "study room"
    assert _quiet(kn.where, taught, "study room", random_state=0).region == int(taught.state.regions[at])
    assert _quiet(kn.where, taught, "fridge", random_state=0).region == int(taught.state.regions[far])
    # every answer at every sample: never the fridge, never a function word
    prediction = kn.name_prediction(taught, taught.positions, taught.visual, top_k=3)
    answered = {w for row in prediction.words for w in row if w is not None}
    assert not answered & {"fridge", "over here", "over", "here", "the", "is", "this"}


@pytest.mark.parametrize("sentence, name", [("this is emma's room", "emma's room"),
                                            ("we call it mum and dad's room", "mum and dad's room")])
def test_a_possessive_name_said_once_is_answerable(world: dict, sentence: str, name: str) -> None:
    """A possessive name said once in a naming frame is a name of the home: the possessive inside the
    term is read as a determiner (``name_evidence.holds_determiner``), so its switch's prior makes it
    a name, and `what` answers it at the taught pose; "fridge", said once beside it, is not."""
    taught, at, _ = _teach_two(world["home"], sentence)
    assert name in taught.known_names
    assert "fridge" not in taught.known_names
    pose = taught.positions[at]
    answer = _quiet(kn.what, taught, pose[0], pose[1], float(np.arctan2(pose[2], pose[3])),
                    visual=taught.visual[[at]])
    assert answer.words[0][0] == name
    assert _quiet(kn.where, taught, name, random_state=0).region == int(taught.state.regions[at])


@pytest.mark.parametrize("sentence, words", [("i cook here", {"cook", "i cook"}),
                                             ("don't touch the oven", {"oven", "don't", "don't touch"}),
                                             ("the fridge is over here", {"fridge", "over"})])
def test_an_object_or_activity_said_once_beside_a_place_is_no_name(world: dict, sentence: str,
                                                                    words: set[str]) -> None:
    """Objects, activities and function words said once at a place ("i cook here", "don't touch the
    oven", "the fridge is over here") are not names of the home: none is among its names, none is
    answered anywhere, while "emma's room" taught at the same time is."""
    home = world["home"]
    dist = np.linalg.norm(home.positions[:, :2] - home.positions[7, :2], axis=1)
    far = int(np.argmax(dist))
    taught = _quiet(kn.teach, home, {int(home.ids[7]): "this is emma's room", int(home.ids[far]): sentence},
                    random_state=0)
    assert "emma's room" in taught.known_names
    assert not words & set(taught.known_names)
    prediction = kn.name_prediction(taught, taught.positions, taught.visual, top_k=3)
    answered = {w for row in prediction.words for w in row if w is not None}
    assert "emma's room" in answered and not words & answered


def test_a_teaching_then_its_replay_from_the_file_give_the_same_home(world: dict, tmp_path: Path) -> None:
    """The undo replays teachings from a saved home: teaching the home in memory and teaching it read
    back from its file give the same switches and answers, bit for bit."""
    home = world["home"]
    home.save(tmp_path / "h.spco")
    loaded = kn.load_home_model(tmp_path / "h.spco")
    teaching = {int(home.ids[5]): "this is the quokka room", int(home.ids[9]): "we cook here"}
    a = _quiet(kn.teach, home, teaching, random_state=7)
    b = _quiet(kn.teach, loaded, teaching, random_state=7)
    np.testing.assert_array_equal(a.state.switches, b.state.switches)
    np.testing.assert_array_equal(a.state.concepts, b.state.concepts)
    assert a.known_names == b.known_names
    pa = kn.name_prediction(a, a.positions, a.visual, top_k=3)
    pb = kn.name_prediction(b, b.positions, b.visual, top_k=3)
    np.testing.assert_array_equal(np.asarray(pa.probabilities), np.asarray(pb.probabilities))
    # the untouched sentences keep their tokens' switches
    untouched = [k for k in range(home.n_samples) if k not in (5, 9)]
    old = home.data.words
    for k in untouched:
        s, e = old.indptr[k], old.indptr[k + 1]
        ns, ne = a.data.words.indptr[k], a.data.words.indptr[k + 1]
        np.testing.assert_array_equal(a.state.switches[ns:ne], home.state.switches[s:e])


def test_speech_without_english_function_words_keeps_the_naming_rule() -> None:
    """Japanese speech (no English function word): the knowledge is learnt with the naming rule and
    says so; its files carry no channels and its homes answer the naming rule's names."""
    corpus = generate_homes(3, seed=2, config=CONFIG, new_homes=1, specific_rooms=False)
    homes = list(corpus)
    words = {"this": "これ", "is": "は", "the": "その", "here": "ここ"}

    def japanese(env):
        sentences = tuple(None if s is None else " ".join(words.get(w, w) for w in s.split())
                          for s in env.sentences)
        from dataclasses import replace

        return replace(env, sentences=sentences)

    knowledge = _quiet(kn.fit_knowledge, Corpus([japanese(h) for h in homes[:2]]), n_iterations=6,
                       random_state=0)
    assert knowledge.hyperparameters.word_model == "naming-rule" and knowledge.channels is None
    home = _quiet(kn.adapt, knowledge, homes[2], n_iterations=4, random_state=0)
    assert home.state.channels is None and home.state.switches is None
    np.testing.assert_array_equal(home.name_mask, home.state.word_mask)


def test_a_concept_named_with_a_word_the_home_does_not_answer_is_answered_unsure(world: dict) -> None:
    """The SIGVerse "dining" case (benchmarks/README.md, "Issue 29: dining views answered
    'entrance'"): a word whose uses are mostly drawn as place words is no name of the home
    (``name_mask``), yet it is the whole names channel of its concept. Masked, the concept's other
    names hold ~10^-6 each; renormalised, `what` answered one of them at p ≈ 1. The concept must
    answer unsure (p ≈ 1 / number of names), and a concept named with a kept name is unchanged."""
    from dataclasses import replace

    home = world["home"]
    vocabulary = list(home.vocabulary.words)
    plain = kn.answer_parameters(home)
    theta = np.asarray(plain.word_probabilities)[0]
    prediction = kn.name_prediction(home, home.positions, home.visual, top_k=1)
    concepts = home.state.concepts
    best = np.asarray(prediction.best, dtype=object)
    answers, counts = np.unique(best.astype(str), return_counts=True)
    name = str(answers[np.argmax(counts)])  # the name answered most in this home
    column = vocabulary.index(name)
    rows = np.flatnonzero((best == name) & (np.asarray(prediction.confidence) > 0.9))
    assert rows.size  # views answered that name, sure
    # drop that name from the home's names the way the fit dropped "dining": most uses place words
    tokens = home.knowledge.channels.tokens.copy()
    tokens[column] = [1.0, 20.0 * max(1.0, tokens[column].sum()), 0.0]
    knowledge = replace(home.knowledge, channels=replace(home.knowledge.channels, tokens=tokens))
    masked = replace(home, knowledge=knowledge)
    assert name not in masked.known_names and len(masked.known_names) >= 3
    params = kn.answer_parameters(masked)
    answered = kn.name_prediction(masked, home.positions[rows], home.visual[rows], top_k=1)
    n_names = len(masked.known_names)
    assert answered.confidence.max() < 2.0 / n_names  # was 0.998 (the concept's leftovers)
    assert answered.unsure.all()
    # rows sum to one over the names; a concept whose θ^w is on kept names keeps its distribution
    theta_masked = np.asarray(params.word_probabilities)[0]
    np.testing.assert_allclose(theta_masked.sum(axis=1), 1.0)
    assert not theta_masked[:, ~masked.name_mask].any()
    kept = np.asarray(masked.name_mask)
    for concept in np.unique(concepts):
        on_kept = theta[concept, kept]
        if on_kept.sum() > 1 - 1e-9:
            np.testing.assert_allclose(theta_masked[concept, kept], on_kept / on_kept.sum(), atol=1e-9)


def test_a_knowledge_without_place_names_answers_from_its_names_channels(world: dict, tmp_path: Path) -> None:
    """A knowledge file written before the place names (no ``channels.place_names``) reads, and a home
    of it answers each concept's names around φ^w as before; with them, a concept the knowledge uses
    and the untaught home names nothing in answers the name said most by its samples and at their
    places."""
    from dataclasses import replace

    from spco.knowledge.queries import answer_parameters

    knowledge, home = world["knowledge"], world["home"]
    knowledge.save(tmp_path / "k.spco")
    old = _rewrite_header(tmp_path / "k.spco", tmp_path / "old.spco",
                          lambda header, arrays: arrays.pop("channels.place_names"))
    before = kn.load_knowledge(old)
    assert before.channels is not None and before.channels.place_names is None
    at_places = home.knowledge.channels.place_names
    answer = np.asarray(answer_parameters(home).word_probabilities)[0]
    assert at_places is not None and at_places.shape == answer.shape
    mask = np.asarray(home.name_mask, dtype=bool)
    checked = 0
    for concept in np.flatnonzero(at_places[:, mask].sum(axis=1) > 0):
        assert np.argmax(answer[concept] * mask) == np.argmax(at_places[concept] * mask)
        checked += 1
    assert checked >= 5
    # the same home with the knowledge's channels without place names: the names channels answer
    plain = replace(home, knowledge=replace(home.knowledge, channels=replace(home.knowledge.channels,
                                                                               place_names=None)))
    theta = np.asarray(home.parameters.word_probabilities)[0]
    unchanged = np.asarray(answer_parameters(plain).word_probabilities)[0]
    used = np.exp(home.knowledge.log_g0) >= 1e-3  # (a free concept answers its posterior mean: uniform)
    for concept in np.flatnonzero(used & (theta[:, mask].sum(axis=1) > 0.5)):
        assert np.argmax(unchanged[concept] * mask) == np.argmax(theta[concept] * mask)
