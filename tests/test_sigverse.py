"""The SIGVerse layout reader: facts of the published data set and every quirk on tiny homes."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spco.data.loading import load, load_homes
from spco.data.sigverse import (
    _parse_counts_fast,
    _parse_counts_slow,
    load_sigverse_folder,
    load_sigverse_home,
    sigverse_teaching_rates,
)
from spco.errors import DataFormatError

EXPERIENCED_16 = ["3LDK_1", "1LDK_8", "2LDK_8", "1LDK_7", "2LDK_7", "1LDK_6", "2LDK_6", "1LDK_5",
                  "2LDK_5", "1LDK_4", "2LDK_4", "1LDK_3", "2LDK_3", "1LDK_2", "2LDK_2", "1LDK_1"]


# ----------------------------------------------------------------------------- the published data set
@pytest.mark.sigverse
def test_new_home_1ldk_9(sigverse_dir: Path) -> None:
    env = load_sigverse_home(sigverse_dir / "1LDK_9")
    assert (env.name, env.n_samples, env.n_test, env.n_taught) == ("1LDK_9", 240, 80, 0)
    assert env.n_features == 4096
    assert env.ground_truth is not None and env.ground_truth.regions is not None  # sigverse_regions.json
    assert set(env.ground_truth.places) == {"entrance", "toilet", "bedroom", "bath", "living room",
                                           "dining", "kitchen", "washroom"}


@pytest.mark.sigverse
def test_3ldk_9_teaching_rates_and_ground_truth(sigverse_dir: Path) -> None:
    home = sigverse_dir / "3LDK_9"
    assert sigverse_teaching_rates(home) == [20, 40, 60, 80, 100]
    env = load_sigverse_home(home, teaching_rate=20)
    assert (env.n_samples, env.n_test, env.n_taught) == (360, 100, 24)
    assert [load_sigverse_home(home, r).n_taught for r in (0, 40, 100)] == [0, 48, 120]
    gt = env.ground_truth
    assert gt is not None and gt.labels is not None and gt.specific_labels is not None
    assert all(label is None for label in gt.labels[300:])  # no name_label files for 300..359
    assert gt.labels[0] == "entrance"
    assert gt.specific_test is not None and gt.specific_test.sum() == 30
    assert {gt.specific_labels[i] for i in np.flatnonzero(gt.specific_test)} == {
        "emma's room", "mother's room", "father's room"}
    with pytest.raises(DataFormatError, match=r"available rates: 20, 40, 60, 80, 100") as err:
        load_sigverse_home(home, teaching_rate=30)
    assert "sentence" in str(err.value)


@pytest.mark.sigverse
def test_sixteen_experienced_homes(sigverse_dir: Path) -> None:
    envs = load_homes(sigverse_dir, names=EXPERIENCED_16)
    assert [e.name for e in envs] == EXPERIENCED_16
    assert sum(e.n_samples for e in envs) == 2660
    assert all(e.n_test == 0 and e.n_taught == e.n_samples for e in envs)


@pytest.mark.sigverse
def test_whole_folder(sigverse_dir: Path) -> None:
    envs = load_sigverse_folder(sigverse_dir)
    names = [e.name for e in envs]
    assert names == sorted(names) and len(names) == 25  # 23 homes + two recordings of 3LDK_9
    for env in envs:
        assert np.isfinite(env.positions).all()
        assert np.allclose(np.hypot(env.positions[:, 2], env.positions[:, 3]), 1, atol=2e-4)
        x0, x1, y0, y1 = env.extent
        xy = env.positions[:, :2]
        assert ((xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)).all(), env.name
    counts = np.concatenate([e.visual.sum(axis=1) for e in envs])
    nnz = np.concatenate([np.diff(e.visual.indptr) for e in envs])
    assert 6000 < counts.mean() < 8500 and 700 < nnz.mean() < 1000  # ~7,300 counts, ~880 non-zeros


@pytest.mark.sigverse
def test_visual_counts_equal_a_plain_text_parse(sigverse_dir: Path) -> None:
    env = load_sigverse_home(sigverse_dir / "1LDK_1")
    for i in (0, 57, 119):
        expected = np.loadtxt(sigverse_dir / "1LDK_1" / "vision_fc7_normalized" / f"{i}.csv", dtype=np.int64)
        assert np.array_equal(env.visual[[i]].toarray()[0], expected)


@pytest.mark.sigverse
def test_damaged_cos_of_1ldk_7_is_recovered(sigverse_dir: Path) -> None:
    env = load_sigverse_home(sigverse_dir / "1LDK_7")
    x, y, s, c = env.positions[121]
    assert (x, y, s) == (0.662, 1.6088, 0.7351)  # file says cos = 0.625
    assert c == pytest.approx(np.sqrt(1 - 0.7351**2))


@pytest.mark.sigverse
def test_extents(sigverse_dir: Path) -> None:
    envs = {e.name: e for e in load_homes(sigverse_dir, names=["1DK_8", "3LDK_9", "1LDK_10"])}
    assert envs["1DK_8"].extent == (-5.0, 5.0, -3.0, 3.0)  # x and y swapped in the file
    assert envs["3LDK_9"].extent == (-6.0, 6.0, -4.75, 4.75)  # as written
    ext = envs["1LDK_10"].extent  # no parameter file: bounding box of the positions
    xy = envs["1LDK_10"].positions[:, :2]
    assert ext == (xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max())


@pytest.mark.sigverse
def test_copy_with_stray_files_loads_the_same(sigverse_dir: Path, tmp_path: Path) -> None:
    home = shutil.copytree(sigverse_dir / "1LDK_1", tmp_path / "1LDK_1")
    for folder in (home, home / "position", home / "vision_fc7_normalized", home / "sentence" / "per_100"):
        (folder / ".DS_Store").write_bytes(b"\x00\x00\x00\x01Bud1")
    (home / "position" / "notes.txt~").write_text("x")
    a, b = load_sigverse_home(sigverse_dir / "1LDK_1"), load_sigverse_home(home)
    assert np.array_equal(a.positions, b.positions) and a.sentences == b.sentences
    assert (a.visual != b.visual).nnz == 0


# ----------------------------------------------------------------------------- tiny homes
def test_tiny_home(make_sigverse_home) -> None:
    home = make_sigverse_home("flat", n=6, test=(4, 5))
    env = load_sigverse_home(home)
    assert (env.name, env.n_samples, env.n_test, env.n_taught, env.n_features) == ("flat", 6, 2, 4, 4096)
    assert env.extent == (-4.0, 4.0, -3.0, 3.0)
    assert env.ground_truth is not None and env.ground_truth.labels[1] == "kitchen"
    assert env.ground_truth.regions is None
    for i in range(6):
        expected = np.loadtxt(home / "vision_fc7_normalized" / f"{i}.csv", dtype=np.int64)
        assert np.array_equal(env.visual[[i]].toarray()[0], expected)


def test_missing_final_newlines_crlf_and_blanks(make_sigverse_home) -> None:
    home = make_sigverse_home(n=4, test=())
    reference = load_sigverse_home(home)
    vis = home / "vision_fc7_normalized"
    (vis / "0.csv").write_bytes((vis / "0.csv").read_bytes().rstrip(b"\n"))
    (vis / "1.csv").write_bytes((vis / "1.csv").read_bytes().replace(b"\n", b"\r\n"))
    (vis / "2.csv").write_bytes((vis / "2.csv").read_bytes() + b"\n\n")
    pos = home / "position" / "3.txt"
    pos.write_bytes(b"  " + pos.read_bytes().replace(b"\n", b"\r\n") + b"\r\n")
    env = load_sigverse_home(home)
    assert np.array_equal(env.positions, reference.positions)
    assert (env.visual != reference.visual).nnz == 0


def test_nothing_taught_and_rate_zero(make_sigverse_home) -> None:
    untaught = make_sigverse_home("new", rates={})
    assert sigverse_teaching_rates(untaught) == []
    for rate in (0, 20, 100):
        assert load_sigverse_home(untaught, rate).n_taught == 0
    taught = make_sigverse_home("old")
    assert load_sigverse_home(taught, 0).n_taught == 0
    with pytest.raises(DataFormatError, match="available rates: 100"):
        load_sigverse_home(taught, 50)


def test_no_test_samples_and_no_parameter_file(make_sigverse_home) -> None:
    home = make_sigverse_home(test=(), params=False)
    assert (home / "test_num.txt").read_text() == "999"
    env = load_sigverse_home(home)
    assert env.n_test == 0
    xy = env.positions[:, :2]
    assert env.extent == (xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max())
    (home / "test_num.txt").unlink()
    assert load_sigverse_home(home).n_test == 0


def test_swapped_extent_is_detected(make_sigverse_home) -> None:
    home = make_sigverse_home()
    (home / "Environment_parameter.txt").write_text(  # x positions reach ±3, y only ±2
        "Max_x_value_of_map 2.5\nMax_y_value_of_map 3.5\nMin_x_value_of_map -2.5\nMin_y_value_of_map -3.5\n")
    for i in range(6):
        (home / "position" / f"{i}.txt").write_text(f"{(-1) ** i * 3.2:.2f} 0.5\n0 1")
    assert load_sigverse_home(home).extent == (-3.5, 3.5, -2.5, 2.5)


@pytest.mark.parametrize(("cos_text", "expected_sign"), [
    ("0.6", 1.0),       # truncated
    ("-0.62", -1.0),    # mistyped digit
    ("0.62.5", 1.0),    # malformed, leading digits kept
    ("-", -1.0),        # only the sign survived
    ("-0.", -1.0),
])
def test_damaged_cos_is_recovered_from_sin(make_sigverse_home, cos_text: str, expected_sign: float) -> None:
    home = make_sigverse_home()
    (home / "position" / "2.txt").write_text(f"1.0 2.0\n0.7351 {cos_text}")
    env = load_sigverse_home(home)
    assert env.positions[2, 2] == 0.7351
    assert env.positions[2, 3] == pytest.approx(expected_sign * np.sqrt(1 - 0.7351**2))


def test_rounded_unit_cos_is_kept_as_written(make_sigverse_home) -> None:
    home = make_sigverse_home()
    (home / "position" / "1.txt").write_text("1.4426 3.6652\n-0.0019 1.000\n")
    assert tuple(load_sigverse_home(home).positions[1]) == (1.4426, 3.6652, -0.0019, 1.0)


def test_last_data_number_and_folder_names(make_sigverse_home, tmp_path: Path) -> None:
    make_sigverse_home("b_home", n=3, test=())
    make_sigverse_home("a_home", n=4, test=())
    (tmp_path / "maps").mkdir()
    (tmp_path / ".DS_Store").write_bytes(b"\x00")
    envs = load_sigverse_folder(tmp_path, progress=True)
    assert [e.name for e in envs] == ["a_home", "b_home"]
    assert [e.name for e in load_sigverse_folder(tmp_path, names=["b_home"])] == ["b_home"]
    corpus = load(tmp_path)
    assert corpus.names == ["a_home", "b_home"] and corpus.vocabulary.words


# ----------------------------------------------------------------------------- the count parser
@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(st.integers(0, 9_999_999), min_size=1, max_size=40), min_size=1, max_size=4))
def test_fast_count_parser_matches_python(rows: list[list[int]]) -> None:
    dim = len(rows[0])
    rows = [(r * dim)[:dim] for r in rows]
    blobs = [("\n".join(map(str, r)) + "\n").encode() for r in rows]
    lines, values = _parse_counts_fast(blobs, dim)
    dense = np.zeros(len(rows) * dim, dtype=np.int64)
    dense[lines] = values
    assert np.array_equal(dense, np.array(rows, dtype=np.int64).ravel())
    for blob, row in zip(blobs, rows, strict=True):
        assert np.array_equal(_parse_counts_slow(Path("x.csv"), blob), row)
