"""Saving and loading fitted models (spco.model.io): round trips, atomic writes, damaged files."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.errors import ConfigurationError, ModelFileError
from spco.model import SpCoA, SpCoAHyperparameters, SpCoTransfer, TransferHyperparameters, archive
from spco.model.io import FORMAT_VERSION, load, load_model
from spco.model.transfer import save_model

HYPER = TransferHyperparameters(n_concepts=6, n_regions=8)


@pytest.fixture(scope="module")
def corpus():
    config = SyntheticConfig(n_features=64, n_train=6, n_test=3)
    return generate_homes(3, seed=3, config=config, new_homes=1, specific_rooms=False)


@pytest.fixture(scope="module")
def fitted(corpus) -> SpCoTransfer:
    return SpCoTransfer(HYPER, n_iterations=3, random_state=5).fit(corpus)


@pytest.fixture(scope="module")
def saved(fitted, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("model") / "model.npz"
    save_model(fitted, path)
    return path


def assert_same_predictions(original, loaded, corpus) -> None:
    """SpCoA: a loaded model predicts identically. A transfer model answers as the robot does, from
    the home's rooms (its training samples), which the file does not keep: loaded, it refuses."""
    if not isinstance(original, SpCoA):
        positions, visual = corpus[0].positions[:2], corpus[0].visual[:2]
        for call in (lambda: loaded.predict_names(0, positions, visual),
                     lambda: loaded.predict_positions(0, original.vocabulary_.words[0])):
            with pytest.raises(ConfigurationError, match="loaded from a file, which keeps no training"):
                call()
        for name, array in original.parameters_.arrays().items():
            assert_array_equal(getattr(loaded.parameters_, name), array, err_msg=name)
        return
    for e, env in enumerate(corpus):
        positions, visual = env.positions[:7], env.visual[:7]
        a = original.predict_names(e, positions, visual, top_k=3)
        b = loaded.predict_names(env.name, positions, visual, top_k=3)
        assert_array_equal(a.words, b.words)
        assert_array_equal(a.scores, b.scores)
        assert_array_equal(a.word_probabilities, b.word_probabilities)
        word = original.vocabulary_.words[int(np.argmax(original.parameters_.word_probabilities[e].sum(0)))]
        pa = original.predict_positions(e, word, n=5, random_state=11)
        pb = loaded.predict_positions(e, word, n=5, random_state=11)
        assert_array_equal(pa.samples, pb.samples)
        assert pa.region == pb.region


# ----------------------------------------------------------------------------- round trips


def test_round_trip_keeps_the_model(fitted, saved, corpus) -> None:
    loaded = load_model(saved)
    assert type(loaded) is SpCoTransfer
    for name, array in fitted.parameters_.arrays().items():
        restored = getattr(loaded.parameters_, name)
        assert restored.dtype == array.dtype, name
        assert_array_equal(restored, array, err_msg=name)
    assert loaded.hyperparameters_ == fitted.hyperparameters_
    assert loaded.settings_ == fitted.settings_
    assert loaded.vocabulary_ == fitted.vocabulary_
    assert loaded.home_names_ == fitted.home_names_
    assert loaded.word_increment_ == fitted.word_increment_
    assert loaded.variant == fitted.variant and loaded.prune_words == fitted.prune_words
    assert loaded.n_iterations == fitted.n_iterations and loaded.n_iter_ == fitted.n_iter_
    assert loaded.random_state == 5
    assert_array_equal(loaded.log_joint_, fitted.log_joint_)
    for attr in ("concepts_", "regions_", "training_ids_"):
        assert len(getattr(loaded, attr)) == len(corpus)
        for a, b in zip(getattr(fitted, attr), getattr(loaded, attr), strict=True):
            assert_array_equal(a, b)
    assert_same_predictions(fitted, loaded, corpus)
    # a loaded model holds no sampler state to continue from (nor the rooms the robot answers from)
    assert not hasattr(loaded, "state_") and not hasattr(loaded, "data_")


def test_file_layout_header_and_no_pickle(saved, fitted) -> None:
    with np.load(saved, allow_pickle=False) as archive:
        assert all(archive[name].dtype != object for name in archive.files)
        header = json.loads(archive["header"].tobytes().decode("utf-8"))
        assert {f"param.{name}" for name in fitted.parameters_.arrays()} <= set(archive.files)
    # version 1: the vocabulary segments no text written without spaces (version 2 does)
    assert header["format"] == "spco-model" and header["format_version"] == 1 < FORMAT_VERSION
    assert header["model_class"] == "SpCoTransfer" and header["variant"] == "exact"
    assert TransferHyperparameters.from_dict(header["hyperparameters"]) == HYPER
    assert header["vocabulary"] == list(fitted.vocabulary_.words)
    assert header["home_names"] == fitted.home_names_
    assert set(header["array_checksums"]) == set(archive.files) - {"header"}
    for key in ("spco_version", "prune_words", "n_iterations", "random_state", "word_increment", "created"):
        assert key in header


def test_baselines_and_reference_variant_round_trip(corpus, tmp_path) -> None:
    spcoa = SpCoA(SpCoAHyperparameters(n_concepts=5, n_regions=6), prune_words=True, n_iterations=2,
                  random_state=np.random.default_rng(1)).fit(corpus, home=corpus.names[0])
    path = tmp_path / "spcoa.npz"
    spcoa.save(path)  # the estimator's own save() goes through save_model
    loaded = load(path)
    assert type(loaded) is SpCoA
    assert isinstance(loaded.hyperparameters_, SpCoAHyperparameters)
    assert loaded.hyperparameters_ == spcoa.hyperparameters_
    assert loaded.settings_.variant == "spcoa" and loaded.prune_words
    assert loaded.random_state is None  # a Generator cannot be written down
    assert_array_equal(loaded.parameters_.word_mask, spcoa.parameters_.word_mask)
    sub = corpus[:1]
    assert_same_predictions(spcoa, loaded, sub)

    reference = SpCoTransfer(HYPER, variant="reference", prune_words=True, n_iterations=2, random_state=2)
    reference.fit(corpus)
    save_model(reference, tmp_path / "reference.npz")
    loaded = load_model(tmp_path / "reference.npz")
    assert loaded.variant == "reference" and loaded.settings_ == reference.settings_
    assert_same_predictions(reference, loaded, corpus)


def test_save_refuses_unfitted_model(tmp_path) -> None:
    with pytest.raises(ConfigurationError, match="not fitted"):
        save_model(SpCoTransfer(), tmp_path / "m.npz")
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- atomic writes


def test_atomic_write_leaves_no_temporary_file(fitted, tmp_path) -> None:
    target = tmp_path / "m.npz"
    returned = save_model(fitted, target)
    assert returned == target
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]


def test_existing_file_is_not_overwritten_without_permission(fitted, tmp_path) -> None:
    target = tmp_path / "m.npz"
    target.write_bytes(b"precious")
    with pytest.raises(ModelFileError, match="overwrite=True") as info:
        save_model(fitted, target)
    assert str(target) in str(info.value)
    assert target.read_bytes() == b"precious"
    with pytest.raises(ModelFileError):
        fitted.save(target)
    assert target.read_bytes() == b"precious"
    save_model(fitted, target, overwrite=True)
    assert load_model(target).home_names_ == fitted.home_names_
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]


def test_failed_write_leaves_nothing_behind(fitted, tmp_path, monkeypatch) -> None:
    target = tmp_path / "m.npz"
    target.write_bytes(b"old model")

    def broken_savez(file, *args, **kwargs):
        file.write(b"PK\x03\x04 partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(archive.np, "savez", broken_savez)
    with pytest.raises(ModelFileError, match="No space left") as info:
        save_model(fitted, target, overwrite=True)
    assert str(target) in str(info.value)
    assert target.read_bytes() == b"old model"  # the old file is untouched
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]  # no temporary file is left

    def interrupted(file, *args, **kwargs):
        file.write(b"PK partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(archive.np, "savez", interrupted)
    with pytest.raises(KeyboardInterrupt):
        save_model(fitted, tmp_path / "other.npz")
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]


def test_save_into_missing_folder(fitted, tmp_path) -> None:
    target = tmp_path / "no" / "such" / "m.npz"
    with pytest.raises(ModelFileError, match="does not exist") as info:
        save_model(fitted, target)
    assert str(target) in str(info.value)


# ----------------------------------------------------------------------------- damaged and foreign files


def rewrite(source: Path, target: Path, header_changes: dict | None = None,
            array_changes: dict[str, np.ndarray] | None = None) -> Path:
    """Copy a model file with some header fields or arrays replaced (checksums kept as they were)."""
    with np.load(source, allow_pickle=False) as archive:
        arrays = {name: archive[name] for name in archive.files}
    header = json.loads(arrays.pop("header").tobytes().decode("utf-8"))
    header.update(header_changes or {})
    arrays.update(array_changes or {})
    with open(target, "wb") as handle:
        np.savez(handle, header=np.frombuffer(json.dumps(header).encode(), dtype=np.uint8), **arrays)
    return target


def test_missing_file(tmp_path) -> None:
    path = tmp_path / "nothing.npz"
    with pytest.raises(ModelFileError, match="no such model file") as info:
        load_model(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("fraction", [0.0, 0.1, 0.5, 0.97])
def test_truncated_file(saved, tmp_path, fraction: float) -> None:
    data = saved.read_bytes()
    path = tmp_path / "truncated.npz"
    path.write_bytes(data[: int(len(data) * fraction)])
    with pytest.raises(ModelFileError) as info:
        load_model(path)
    assert str(path) in str(info.value)


def test_flipped_bytes_in_an_array(saved, tmp_path) -> None:
    data = bytearray(saved.read_bytes())
    with zipfile.ZipFile(saved) as archive:
        member = archive.getinfo("param.visual_probabilities.npy")
    # the member's data start after its 30-byte local header, name and extra field; skip the .npy header
    offset = member.header_offset + 30 + len(member.filename.encode()) + len(member.extra) + 200
    for i in range(8):
        data[offset + i] ^= 0xFF
    path = tmp_path / "flipped.npz"
    path.write_bytes(bytes(data))
    with pytest.raises(ModelFileError) as info:
        load_model(path)
    assert str(path) in str(info.value)


def test_edited_array_fails_checksum(saved, tmp_path) -> None:
    with np.load(saved, allow_pickle=False) as archive:
        weights = archive["param.concept_weights"].copy()
    weights[0] = weights[0][::-1]
    path = rewrite(saved, tmp_path / "edited.npz", array_changes={"param.concept_weights": weights})
    with pytest.raises(ModelFileError, match=r"checksum mismatch for array 'param\.concept_weights'") as info:
        load_model(path)
    assert str(path) in str(info.value)
    # an array removed, or an array added
    with np.load(saved, allow_pickle=False) as archive:
        arrays = {n: archive[n] for n in archive.files if n != "param.word_mask"}
    missing = tmp_path / "missing.npz"
    with open(missing, "wb") as handle:
        np.savez(handle, **arrays)
    with pytest.raises(ModelFileError, match="missing"):
        load_model(missing)
    extra = rewrite(saved, tmp_path / "extra.npz", array_changes={"intruder": np.zeros(3)})
    with pytest.raises(ModelFileError, match="unexpected"):
        load_model(extra)


def test_newer_format_version(saved, tmp_path) -> None:
    changes = {"format_version": FORMAT_VERSION + 1, "spco_version": "9.0"}
    path = rewrite(saved, tmp_path / "future.npz", changes)
    with pytest.raises(ModelFileError, match="newer") as info:
        load_model(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("changes", [{"format": "something-else"}, {"format_version": "one"},
                                     {"format_version": 0}, {"model_class": "KMeans"}])
def test_wrong_format_fields(saved, tmp_path, changes: dict) -> None:
    path = rewrite(saved, tmp_path / "wrong.npz", changes)
    with pytest.raises(ModelFileError) as info:
        load_model(path)
    assert str(path) in str(info.value)


def test_foreign_files(tmp_path) -> None:
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, a=np.arange(3), b=np.eye(2))
    with pytest.raises(ModelFileError, match="not a spco model file") as info:
        load_model(foreign)
    assert str(foreign) in str(info.value)
    text = tmp_path / "notes.npz"
    text.write_text("this is not a model\n")
    with pytest.raises(ModelFileError, match=r"notes\.npz"):
        load_model(text)
    single = tmp_path / "array.npy"
    np.save(single, np.arange(4))
    with pytest.raises(ModelFileError, match=r"array\.npy"):
        load_model(single)
    header_only = tmp_path / "header.npz"
    np.savez(header_only, header=np.frombuffer(b"{not json", dtype=np.uint8))
    with pytest.raises(ModelFileError, match="JSON"):
        load_model(header_only)
    with pytest.raises(ModelFileError, match="folder"):
        load_model(tmp_path)
