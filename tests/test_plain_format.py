"""The plain per-home format: reading, writing, round trips, real-valued features."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from spco.data import features_to_counts, load
from spco.data.environment import Corpus, Environment, make_ground_truth
from spco.data.loading import load_home
from spco.data.plain import read_home, write_corpus, write_home
from spco.data.regions import PlaceRegions
from spco.data.sigverse import load_sigverse_home
from spco.errors import ConfigurationError, DataFormatError

SENTENCES = ["this is the kitchen", None, 'well, this is "emma\'s room"', "ここは台所です",
             "line one\nline two", None, "the living-room is here", None]


def tiny_env(name: str = "flat", n: int = 8, dim: int = 12, seed: int = 0, truth: bool = True) -> Environment:
    rng = np.random.default_rng(seed)
    theta = rng.uniform(-np.pi, np.pi, n)
    positions = np.column_stack([rng.normal(0, 2, n), rng.normal(0, 2, n), np.sin(theta), np.cos(theta)])
    visual = sp.random_array((n, dim), density=0.3, rng=rng,
                             data_sampler=lambda size: rng.integers(1, 50, size))
    gt = None
    if truth:
        labels = [("kitchen", "living room", None, "emma's room")[i % 4] for i in range(n)]
        gt = make_ground_truth(labels, [f"Room {i % 3}" for i in range(n)], np.arange(n) % 3 == 0,
                               PlaceRegions({"kitchen": ((0.0, 1.0, 0.0, 2.0), (1.0, 2.0, 0.0, 1.0))}))
    return Environment(name=name, ids=np.arange(100, 100 + n), positions=positions,
                       visual=sp.csr_array(visual, dtype=np.int64),
                       sentences=tuple((SENTENCES * (n // len(SENTENCES) + 1))[:n]),
                       is_test=np.arange(n) >= n - 2, extent=(-5.0, 5.0, -4.0, 4.5), ground_truth=gt)


def assert_same_home(a: Environment, b: Environment, atol: float = 1e-12) -> None:
    assert a.name == b.name
    assert np.array_equal(a.ids, b.ids)
    np.testing.assert_allclose(a.positions, b.positions, atol=atol, rtol=0)
    assert a.visual.shape == b.visual.shape and (a.visual != b.visual).nnz == 0
    assert a.sentences == b.sentences
    assert np.array_equal(a.is_test, b.is_test)
    assert a.extent == b.extent
    ga, gb = a.ground_truth, b.ground_truth
    assert (ga is None) == (gb is None)
    if ga is not None and gb is not None:
        assert ga.labels == gb.labels and ga.specific_labels == gb.specific_labels
        assert (ga.specific_test is None) == (gb.specific_test is None)
        if ga.specific_test is not None:
            assert np.array_equal(ga.specific_test, gb.specific_test)
        assert (ga.regions is None) == (gb.regions is None)
        if ga.regions is not None:
            assert ga.regions.to_json() == gb.regions.to_json()


def test_round_trip(tmp_path: Path) -> None:
    env = tiny_env()
    folder = write_home(env, tmp_path / "flat")
    assert sorted(p.name for p in folder.iterdir()) == [
        "home.json", "labels.csv", "regions.json", "samples.csv", "specific_test.txt", "test.txt",
        "visual.npz"]
    assert_same_home(env, read_home(folder))
    assert_same_home(env, load_home(folder))
    bare = tiny_env(truth=False)
    assert_same_home(bare, read_home(write_home(bare, tmp_path / "bare")))
    assert not (tmp_path / "bare" / "labels.csv").exists()


def test_accepted_names_round_trip(tmp_path: Path) -> None:
    from spco.data.synthetic import SyntheticConfig, generate_home

    env = generate_home(0, layout="1LDK", config=SyntheticConfig(n_features=64, language="free"))
    back = read_home(write_home(env, tmp_path / "h"))
    assert back.ground_truth.accepted_names == env.ground_truth.accepted_names
    assert "bathroom" in back.ground_truth.accepted("bath")
    (tmp_path / "h" / "accepted_names.json").write_text('{"bath": "bathroom"}')
    with pytest.raises(DataFormatError, match=r"accepted_names\.json"):
        read_home(tmp_path / "h")


def test_written_csv_is_documented_format(tmp_path: Path) -> None:
    folder = write_home(tiny_env(), tmp_path / "flat")
    lines = (folder / "samples.csv").read_text(encoding="utf-8").splitlines()
    assert lines[0] == "id,x,y,theta,sentence"
    assert lines[1].startswith("100,") and lines[1].endswith(',"this is the kitchen"')
    assert json.loads((folder / "home.json").read_text())["extent"] == [-5.0, 5.0, -4.0, 4.5]
    assert (folder / "test.txt").read_text() == "106, 107\n"


def test_hand_written_home_csv_and_jsonl(tmp_path: Path) -> None:
    home = tmp_path / "mine"
    home.mkdir()
    (home / "samples.csv").write_text(
        "sentence,theta,y,x,id,timestamp\n"
        'this is the kitchen,0,0.5,1.5,7,12:00\n'
        ',1.5707963267948966,-1,2,3,12:01\n'
        '"well, the hall",3.141592653589793,0,0,11,12:02\n', encoding="utf-8")
    np.save(home / "visual.npy", np.array([[1, 0, 2], [0, 0, 5], [3, 3, 3]]))
    (home / "test.txt").write_text("11,\n")
    env = read_home(home)
    assert env.name == "mine" and env.ids.tolist() == [7, 3, 11]
    np.testing.assert_allclose(env.positions[1], [2, -1, 1, 0], atol=1e-15)
    assert env.sentences == ("this is the kitchen", None, "well, the hall")
    assert env.is_test.tolist() == [False, False, True] and env.n_taught == 1
    assert env.visual.toarray().tolist() == [[1, 0, 2], [0, 0, 5], [3, 3, 3]]

    (home / "samples.csv").unlink()
    rows = [{"id": 7, "x": 1.5, "y": 0.5, "theta": 0, "sentence": "this is the kitchen"},
            {"id": 3, "x": 2, "y": -1, "theta": 1.5707963267948966},
            {"id": 11, "x": 0, "y": 0, "theta": 3.141592653589793, "sentence": None}]
    (home / "samples.jsonl").write_text("\n".join(json.dumps(r) for r in rows) + "\n\n")
    other = read_home(home)
    assert other.ids.tolist() == [7, 3, 11] and other.sentences == ("this is the kitchen", None, None)
    np.testing.assert_allclose(other.positions, env.positions)


def test_visual_file_kinds(tmp_path: Path) -> None:
    home = write_home(tiny_env(truth=False), tmp_path / "flat")
    dense = read_home(home).visual.toarray()
    (home / "visual.npz").unlink()
    np.savez(home / "visual.npz", features=dense.astype(np.float32))  # dense, integer-valued floats
    assert np.array_equal(read_home(home).visual.toarray(), dense)
    (home / "visual.npz").unlink()
    np.save(home / "visual.npy", dense.astype(np.uint16))
    assert np.array_equal(read_home(home).visual.toarray(), dense)


def test_real_valued_features_need_visual_scale(tmp_path: Path) -> None:
    home = write_home(tiny_env(truth=False), tmp_path / "flat")
    rng = np.random.default_rng(1)
    features = rng.normal(0.5, 1.0, (8, 12))
    (home / "visual.npz").unlink()
    np.save(home / "visual.npy", features)
    with pytest.raises(DataFormatError, match="visual_scale") as err:
        read_home(home)
    assert "visual.npy" in str(err.value)
    meta = json.loads((home / "home.json").read_text())
    (home / "home.json").write_text(json.dumps({**meta, "visual_scale": 5.0}))
    env = read_home(home)
    assert np.array_equal(env.visual.toarray(), np.floor(np.maximum(features, 0) * 5.0))
    sp.save_npz(home / "visual.npz", sp.csr_array(features))  # sparse real-valued works too
    (home / "visual.npy").unlink()
    assert np.array_equal(read_home(home).visual.toarray(), env.visual.toarray())


def test_features_to_counts() -> None:
    f = np.array([[0.19, 1.0, -3.0], [0.0, 2.5, 0.41]])
    assert features_to_counts(f).tolist() == [[0, 5, 0], [0, 12, 2]]
    assert features_to_counts(f, scale=10).tolist() == [[1, 10, 0], [0, 25, 4]]
    sparse = features_to_counts(sp.csr_array(f))
    assert sp.issparse(sparse) and sparse.toarray().tolist() == [[0, 5, 0], [0, 12, 2]]
    with pytest.raises(ConfigurationError):
        features_to_counts(f, scale=0)
    with pytest.raises(DataFormatError):
        features_to_counts(np.array([[np.nan]]))


def test_home_json(tmp_path: Path) -> None:
    home = write_home(tiny_env(truth=False), tmp_path / "folder_name")
    (home / "home.json").unlink()
    env = read_home(home)
    assert env.name == "folder_name" and env.extent is None
    (home / "home.json").write_text('{"name": "Kitchen flat", "extnt": [0, 1, 0, 1]}')
    with pytest.raises(DataFormatError, match="extnt") as err:
        read_home(home)
    assert "home.json" in str(err.value)


def test_teaching_rate_subsamples_taught_training_samples(tmp_path: Path) -> None:
    env = tiny_env(n=40, truth=False)
    home = write_home(env, tmp_path / "flat")
    full = read_home(home)
    half = read_home(home, teaching_rate=50)
    assert half.n_taught == round(full.n_taught * 0.5)
    assert half.sentences == env.with_teaching_rate(50, seed=0).sentences
    assert read_home(home, teaching_rate=0).n_taught == 0


def test_refuses_to_overwrite_unless_forced(tmp_path: Path) -> None:
    folder = write_home(tiny_env(), tmp_path / "flat")
    (folder / "my_notes.txt").write_text("keep me")
    with pytest.raises(ConfigurationError, match="--force"):
        write_home(tiny_env(seed=3), folder)
    other = tiny_env(name="other", seed=3, truth=False)
    write_home(other, folder, overwrite=True)
    assert_same_home(other, read_home(folder))
    assert (folder / "my_notes.txt").read_text() == "keep me"
    assert not (folder / "labels.csv").exists()  # stale ground truth of the old home removed
    assert [p.name for p in tmp_path.iterdir()] == ["flat"]  # no temporary folders left


def test_write_corpus_and_load_folder(tmp_path: Path) -> None:
    corpus = Corpus([tiny_env("b_home", seed=1), tiny_env("a_home", seed=2)])
    folders = write_corpus(corpus, tmp_path / "homes")
    assert [f.name for f in folders] == ["b_home", "a_home"]
    loaded = load(tmp_path / "homes")
    assert loaded.names == ["a_home", "b_home"]  # sorted by folder name
    assert_same_home(corpus["a_home"], loaded["a_home"])
    with pytest.raises(ConfigurationError, match="--force"):
        write_corpus(corpus, tmp_path / "homes")
    write_corpus(corpus, tmp_path / "homes", overwrite=True)
    with pytest.raises(ConfigurationError, match="folder name"):
        write_corpus([tiny_env("../evil")], tmp_path / "homes")


def test_mixed_folder(tmp_path: Path, make_sigverse_home) -> None:
    make_sigverse_home("sig", root=tmp_path / "mixed", dim=12)
    with pytest.raises(DataFormatError, match="holds 12 values, expected 4096"):
        load(tmp_path / "mixed")
    make_sigverse_home("sig2", root=tmp_path / "mixed2")
    write_home(tiny_env("plain", dim=4096, truth=False), tmp_path / "mixed2" / "plain")
    corpus = load(tmp_path / "mixed2")
    assert corpus.names == ["plain", "sig2"]


@pytest.mark.sigverse
def test_sigverse_home_round_trips_through_plain_format(sigverse_dir: Path, tmp_path: Path) -> None:
    env = load_sigverse_home(sigverse_dir / "3LDK_9", teaching_rate=40)
    back = read_home(write_home(env, tmp_path / "3LDK_9"))
    # headings are stored as theta, so they come back as exact unit vectors
    assert_same_home(env, back, atol=2e-4)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.one_of(st.none(), st.text(min_size=1, max_size=25),
                         st.text(alphabet=' ab,;"\'\r\n\t\u2028\x85é', min_size=1, max_size=12)),
                min_size=1, max_size=6),
       st.booleans())
def test_any_sentence_round_trips(tmp_path_factory: pytest.TempPathFactory, sentences: list[str | None],
                                  jsonl: bool) -> None:
    n = len(sentences)
    env = tiny_env(n=n, truth=False).with_sentences(sentences)
    folder = write_home(env, tmp_path_factory.mktemp("home") / "h")
    if jsonl:  # the same home as JSON lines
        rows = [{"id": int(i), "x": x, "y": y, "theta": float(np.arctan2(s, c)), "sentence": t}
                for i, (x, y, s, c), t in zip(env.ids, env.positions.tolist(), env.sentences, strict=True)]
        (folder / "samples.csv").unlink()
        lines = [json.dumps(r, ensure_ascii=k % 2 == 0) for k, r in enumerate(rows)]
        (folder / "samples.jsonl").write_text("\n".join(lines), encoding="utf-8", newline="")
    assert read_home(folder).sentences == env.sentences
