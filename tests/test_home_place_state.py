"""The homes' own place words ψ_{e,l} (``place_channel="home"``, :mod:`spco.model.home_place`) are part
of a home's state as θ^w_{e,l} is: kept by engine checkpoints (a resumed fit continues the same chain),
by a teaching's local update (ψ_{e,l} of the concepts it updates redrawn, the others kept; the same home,
teaching and seed give the same home) and by home files (format version 5; a file written before loads
with none held). An undo gives the state back byte for byte, ψ_{e,l} included. With the default
``place_channel="shared"`` nothing changes (no ψ_{e,l} anywhere, the files' versions as before)."""

from __future__ import annotations

import hashlib
import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.special import logsumexp

from spco import knowledge as kn
from spco.data.environment import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.engines import LocalEngine, checkpoints
from spco.knowledge.requests import Teach, Undo
from spco.model.home_place import draw_home_place_of, grown_home_place, home_place_mean
from spco.model.hyperparameters import DELTA_PLACE, TransferHyperparameters
from spco.model.sources import SyntheticHomes
from spco.model.transfer import SpatialConceptModel
from spco.model.word_channels import WordChannels

HOME = TransferHyperparameters().with_settings(["place_channel=home"])
CONFIG = SyntheticConfig(n_features=32, n_train=12, language="free")


def _state_digest(home: kn.HomeModel) -> str:
    """SHA-256 of every array of the home's state, its switches and ψ_{e,l} (the channels' arrays),
    and of its posterior: the state an undo must give back."""
    digest = hashlib.sha256()
    s = home.state
    for name, value in sorted(vars(s).items()):
        if isinstance(value, np.ndarray):
            digest.update(name.encode() + np.ascontiguousarray(value).tobytes())
    channels = s.channels
    for name in ("log_place", "log_background", "log_shares", "log_evidence", "log_place_home"):
        value = None if channels is None else getattr(channels, name)
        digest.update(name.encode() + (b"none" if value is None else np.ascontiguousarray(value).tobytes()))
    if home.posterior is not None:
        for name, value in sorted(home.posterior.arrays().items()):
            digest.update(name.encode() + np.ascontiguousarray(value).tobytes())
    return digest.hexdigest()


def _teach(model: kn.HomeModel, sentences: dict, **options) -> kn.HomeModel:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return kn.teach(model, sentences, **options)


@pytest.fixture(scope="module")
def homes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One new home adapted from two experienced homes' knowledge, with the home level and with the
    default, saved."""
    folder = tmp_path_factory.mktemp("psi_state")
    corpus = generate_homes(3, seed=5, config=CONFIG, new_homes=1, specific_rooms=False)
    envs = list(corpus)
    out = {}
    for label, hyper in (("home", HOME), ("shared", TransferHyperparameters())):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            knowledge = kn.fit_knowledge(Corpus(envs[:2]), n_iterations=6, random_state=0,
                                         hyperparameters=hyper)
            home = kn.adapt(knowledge, envs[2], n_iterations=4, random_state=0)
        out[label] = home.save(folder / f"{label}.spco")
    return out


# ----------------------------------------------------------------------------- the functions
def test_drawing_the_place_words_of_some_concepts_keeps_the_others() -> None:
    """ψ_{e,l} of the concepts asked for ~ Dir(δ^p ψ_l + n_{e,l}) (mean and variance against the
    Dirichlet's, V = 3), the others' arrays bit for bit; a state holding none reads ψ_l for them."""
    rng = np.random.default_rng(0)
    L, V = 3, 3
    log_place = np.log(np.array([[0.5, 0.3, 0.2], [0.1, 0.1, 0.8], [0.3, 0.3, 0.4]]))
    held = np.log(rng.dirichlet(np.ones(V), size=(1, L)))
    channels = WordChannels(log_place, np.full(V, -np.log(V)), np.zeros(3), np.zeros((V, 3)),
                            log_place_home=held)
    counts = np.array([[[3, 0, 1], [0, 5, 0], [2, 2, 2]]])
    delta = 4.0
    draws = []
    for _ in range(4000):
        drawn = draw_home_place_of(channels, counts, delta, np.array([1]), rng).log_place_home
        np.testing.assert_array_equal(drawn[0, [0, 2]], held[0, [0, 2]])
        draws.append(np.exp(drawn[0, 1]))
    a = delta * np.exp(log_place[1]) + counts[0, 1]
    mean, total = a / a.sum(), a.sum()
    draws = np.array(draws)
    assert (np.abs(draws.mean(0) - mean) < 4 * np.sqrt(mean * (1 - mean) / (total + 1) / 4000)).all()
    assert_allclose(draws.var(0), mean * (1 - mean) / (total + 1), rtol=0.15)
    assert channels.log_place_home is held  # (a new array: the channels are not changed)
    none_held = WordChannels(log_place, np.full(V, -np.log(V)), np.zeros(3), np.zeros((V, 3)))
    drawn = draw_home_place_of(none_held, counts, delta, np.array([0]), rng).log_place_home
    np.testing.assert_array_equal(drawn[0, 1:], log_place[1:])
    assert_allclose(home_place_mean(counts, log_place, delta)[0, 1], np.log(mean))


def test_a_grown_vocabulary_gives_new_words_the_shared_place_words() -> None:
    """A word first heard in a teaching: ψ_{e,l} takes ψ_l's value for it (its prior mean) and the old
    words keep their proportions; rows sum to one."""
    rng = np.random.default_rng(1)
    home = np.log(rng.dirichlet(np.ones(4), size=(1, 2)))
    grown = np.log(rng.dirichlet(np.ones(6), size=2))
    out = grown_home_place(home, grown)
    assert out.shape == (1, 2, 6)
    assert_allclose(logsumexp(out, axis=-1), 0.0, atol=1e-12)
    np.testing.assert_array_equal(out[0, :, 4:], grown[:, 4:])
    assert_allclose(out[0, :, :4] - logsumexp(out[0, :, :4], axis=-1, keepdims=True), home[0], atol=1e-12)
    assert grown_home_place(None, grown) is None and grown_home_place(out, grown) is out


# ----------------------------------------------------------------------------- checkpoints
def _channels_run(engine, source, hyper, settings):
    """A run of ``engine`` from the sharded start (seed 5) learning its words with the word channels
    (every word's name evidence 0.5), as a fit gives them after its start."""
    run = engine.start_source(source, hyper, settings, np.random.default_rng(5))
    run.use_word_channels(WordChannels.initial(np.full(len(source.vocabulary), 0.5), hyper.n_concepts))
    return run


def test_a_shard_checkpoint_keeps_the_homes_place_words(tmp_path) -> None:
    """A shard's file holds its homes' ψ_{e,l} (version 4) and reads it back bit for bit; without the
    home level the file is as before (version 3, no such array)."""
    source = SyntheticHomes.create(3, seed=2, config=CONFIG, new_homes=1)
    for hyper, version in ((HOME, 4), (TransferHyperparameters(), 3)):
        model = SpatialConceptModel(hyper, random_state=0, prune_words=True)
        run = _channels_run(LocalEngine(1), source, model.checked_hyperparameters(), model.sampler_settings())
        for i in range(3):
            run.sweep(i)
        shard = run.shards[0]
        path = tmp_path / f"s{version}.npz"
        checkpoints.save_shard(path, shard.state, shard.rng_states())
        with np.load(path) as f:
            assert json.loads(str(f["meta"]))["version"] == version
            assert ("channels.log_place_home" in f.files) == (version == 4)
        state, _ = checkpoints.load_shard(path)
        held = shard.state.channels.log_place_home
        if version == 4:
            assert held is not None and held.shape[0] == source.n_homes
            np.testing.assert_array_equal(state.channels.log_place_home, held)
        else:
            assert held is None and state.channels.log_place_home is None
        run.close()


@pytest.mark.parametrize("on_disk", [True, False])
def test_ray_resumes_the_home_level_chain_from_its_checkpoint(tmp_path, ray_session, on_disk: bool) -> None:
    """place_channel="home", checkpoints in a directory (each actor's file) or in memory: killing an
    actor after sweep 7 restarts the shards from the checkpoint of sweep 5, and the fit ends where the
    fault-free local fit ends — its trace, concepts, regions, θ^w, ψ_l and every home's ψ_{e,l} hashed."""
    from spco.engines.ray import RayEngine

    source = SyntheticHomes.create(3, seed=2, config=CONFIG, new_homes=1)
    model = SpatialConceptModel(HOME, random_state=0, prune_words=True)
    hyper, settings = model.checked_hyperparameters(), model.sampler_settings()
    engine = RayEngine(2, checkpoint_every=5, checkpoint_dir=tmp_path if on_disk else None)
    run = _channels_run(engine, source, hyper, settings)
    killed = []

    def kill_once(iteration: int, _: float) -> None:
        if iteration == 7 and not killed:
            killed.append(True)
            ray_session.kill(run.actors[1])

    trace = run.fit(10, kill_once)
    state = run.state()
    run.close()
    assert run.restarts == 1
    local = _channels_run(LocalEngine(2), source, hyper, settings)
    expected_trace = local.fit(10)
    expected = local.state()
    local.close()

    def digest(t, s) -> str:
        parts = (t, s.concepts, s.regions, s.log_theta_w, s.channels.log_place, s.channels.log_place_home)
        return hashlib.sha256(b"".join(np.ascontiguousarray(p).tobytes() for p in parts)).hexdigest()

    assert state.channels.log_place_home is not None
    assert digest(trace, state) == digest(expected_trace, expected)


# ----------------------------------------------------------------------------- teaching and files
def test_a_teaching_updates_the_taught_concepts_place_words_and_keeps_the_others(homes) -> None:
    """The local update redraws ψ_{e,l} of the concepts whose θ^w it redraws and keeps the rest bit for
    bit; the same teaching and seed give the same state; ``where`` reads the home's own place words
    (their conditional mean given its tokens), not the knowledge's ψ_l."""
    home = kn.load_home_model(homes["home"])
    before = home.state.channels.log_place_home
    assert before is not None and before.shape == (1, *home.state.channels.log_place.shape)
    known = [w for w in home.vocabulary.words[: home.n_knowledge_words] if " " not in w][:3]
    sentence = " ".join(known)
    taught = _teach(home, {int(home.ids[3]): sentence}, random_state=1)
    again = _teach(home, {int(home.ids[3]): sentence}, random_state=1)
    assert _state_digest(taught) == _state_digest(again)
    after = taught.state.channels.log_place_home
    assert after.shape == before.shape  # (no new word)
    theta_changed = ~np.all(taught.state.log_theta_w[0] == home.state.log_theta_w[0], axis=1)
    psi_changed = ~np.all(after[0] == before[0], axis=1)
    assert theta_changed.any() and not theta_changed.all()
    np.testing.assert_array_equal(psi_changed, theta_changed)
    params = taught.parameters
    expected = np.exp(taught._place_mean())
    np.testing.assert_array_equal(params.place_word_probabilities, expected)
    assert not np.allclose(expected, np.exp(taught.knowledge.channels.channels.log_place))
    assert_allclose(expected.sum(axis=-1), 1.0)


def test_a_new_word_grows_the_homes_place_words(homes) -> None:
    home = kn.load_home_model(homes["home"])
    taught = _teach(home, {int(home.ids[2]): "this is the quokka room"}, random_state=2)
    psi = taught.state.channels.log_place_home
    assert psi.shape == (1, *taught.state.channels.log_place.shape) and psi.shape[2] > home.knowledge.n_words
    assert_allclose(logsumexp(psi, axis=-1), 0.0, atol=1e-9)


def test_the_home_file_keeps_the_place_words_and_an_older_file_loads(homes, tmp_path) -> None:
    """A home file holds ψ_{e,l} (version 5) and reads it back: teaching the loaded home gives the
    home the original's teaching gives, byte for byte. A file written before (version 4, no ψ_{e,l})
    loads with none held (ψ_l read) and can be taught; the default's file is version 4 without it."""
    path = homes["home"]
    home = kn.load_home_model(path)
    with np.load(path) as f:
        header = json.loads(bytes(f["header"]).decode())
        assert header["format_version"] == 5 and "state.log_place_home" in f.files
    assert home.hyperparameters.place_channel == "home" and home.hyperparameters.delta_place == DELTA_PLACE
    copy = home.save(tmp_path / "copy.spco")
    again = kn.load_home_model(copy)
    assert _state_digest(again) == _state_digest(home)
    sentence = {int(home.ids[5]): "this is the quokka room"}
    assert _state_digest(_teach(again, sentence, random_state=3)) == _state_digest(
        _teach(home, sentence, random_state=3))
    # a file of the home level written before ψ_{e,l} was kept: version 4, no array
    older = kn.HomeModel(**{**{f: getattr(home, f) for f in home.__dataclass_fields__},
                            "state": _without_place_words(home.state)})
    old_path = older.save(tmp_path / "older.spco")
    with np.load(old_path) as f:
        assert json.loads(bytes(f["header"]).decode())["format_version"] == 4
    loaded = kn.load_home_model(old_path)
    assert loaded.state.channels.log_place_home is None
    taught = _teach(loaded, sentence, random_state=3)
    assert taught.state.channels.log_place_home is not None
    shared = kn.load_home_model(homes["shared"])
    with np.load(homes["shared"]) as f:
        assert json.loads(bytes(f["header"]).decode())["format_version"] == 4
        assert "state.log_place_home" not in f.files
    assert shared.state.channels.log_place_home is None
    np.testing.assert_array_equal(shared.parameters.place_word_probabilities,
                                  np.exp(shared.knowledge.channels.channels.log_place))


def _without_place_words(state):
    from dataclasses import replace

    from spco.knowledge.home import _copy_state

    copy = _copy_state(state)
    copy.channels = replace(state.channels, log_place_home=None)
    return copy


def test_a_home_file_with_bad_place_words_is_refused(homes, tmp_path) -> None:
    """A ψ_{e,l} of the wrong shape is refused naming ``state.log_place_home``."""
    from dataclasses import replace

    from spco.errors import ModelFileError
    from spco.knowledge.home import _copy_state

    home = kn.load_home_model(homes["home"])
    state = _copy_state(home.state)
    state.channels = replace(state.channels, log_place_home=state.channels.log_place_home[:, :-1])
    bad = kn.HomeModel(**{**{f: getattr(home, f) for f in home.__dataclass_fields__}, "state": state})
    path = bad.save(tmp_path / "bad.spco")
    with pytest.raises(ModelFileError, match=r"state\.log_place_home"):
        kn.load_home_model(path)


def test_teach_then_undo_gives_the_state_back_byte_for_byte(homes, tmp_path) -> None:
    """The service's writer with the home level: a teaching then its undo gives the home's state back,
    ψ_{e,l} included, byte for byte; so does undoing a teaching in the middle (the later ones
    replayed) against teaching the others in the library; and a restart from the files."""
    import shutil

    from spco.service.writer import HomeWriter

    path = tmp_path / "served.spco"
    shutil.copyfile(homes["home"], path)
    original = kn.load_home_model(path)
    ids = [int(i) for i in original.ids[:4]]
    writer = HomeWriter(path, seed=5, compact_records=2, compact_idle=3600)
    before = writer.snapshot()
    assert writer.handle([Teach(sentence="this is the quokka room", id=ids[0])])[0]["ok"]
    assert _state_digest(writer.snapshot()) != _state_digest(before)
    assert writer.handle([Undo(1)])[0]["ok"]
    assert _state_digest(writer.snapshot()) == _state_digest(before)
    assert writer.snapshot().state.channels.log_place_home is not None
    for sentence, i in (("the sofa room", ids[1]), ("this is the den", ids[2]), ("the marimba room", ids[3])):
        assert writer.handle([Teach(sentence=sentence, id=i)])[0]["ok"]
    assert writer.handle([Undo(4)])[0]["ok"]  # the den, in the middle
    expected = original
    for seq in (3, 5):
        record = writer.history[seq]["record"]
        expected = _teach(expected, {int(record["id"]): record["sentence"]}, n_sweeps=int(record["sweeps"]),
                          random_state=int(record["seed"]))
    after_undo = writer.snapshot()
    assert _state_digest(after_undo) == _state_digest(expected)
    writer.close()
    restarted = HomeWriter(path, seed=5)
    assert _state_digest(restarted.snapshot()) == _state_digest(after_undo)
    restarted.close()
