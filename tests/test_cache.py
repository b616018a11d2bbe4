"""The single-file cache: round trips, teaching rates, damaged files, speed."""

from __future__ import annotations

import json
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_plain_format import assert_same_home, tiny_env

from spco.data import load
from spco.data.cache import is_cache_file, read_cache, read_cache_records, write_records
from spco.data.environment import Environment, make_ground_truth
from spco.data.loading import load_homes, write_cache
from spco.data.plain import write_corpus
from spco.data.records import HomeRecord
from spco.data.regions import PlaceRegions
from spco.errors import ConfigurationError, DataFormatError


# ----------------------------------------------------------------------------- property tests
@st.composite
def homes(draw: st.DrawFn, name: str, dim: int) -> Environment:
    n = draw(st.integers(1, 12))
    ids = draw(st.lists(st.integers(-10**12, 10**12), min_size=n, max_size=n, unique=True))
    xy = draw(st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=2 * n, max_size=2 * n))
    theta = np.asarray(draw(st.lists(st.floats(-4, 4), min_size=n, max_size=n)))
    dense = np.asarray(draw(st.lists(st.integers(0, 70000), min_size=n * dim, max_size=n * dim)))
    mask = np.asarray(draw(st.lists(st.booleans(), min_size=n * dim, max_size=n * dim)))
    text = st.one_of(st.none(), st.text(min_size=1, max_size=30))
    sentences = draw(st.lists(text, min_size=n, max_size=n))
    labels = draw(st.one_of(st.none(), st.lists(st.one_of(st.none(), st.sampled_from(
        ["kitchen", "Emma's room", "living-room", "ダイニング"])), min_size=n, max_size=n)))
    regions = draw(st.one_of(st.none(), st.just(PlaceRegions({"kitchen": ((0.0, 1.5, -2.0, 2.0),)}))))
    specific_test = draw(st.one_of(st.none(), st.lists(st.booleans(), min_size=n, max_size=n)))
    extent = draw(st.one_of(st.none(), st.tuples(*[st.floats(-50, 50)] * 4)))
    gt = None
    if labels is not None or regions is not None or specific_test is not None:
        chosen = None if specific_test is None else np.array(specific_test)
        gt = make_ground_truth(labels, None, chosen, regions)
    return Environment(
        name=name, ids=np.asarray(ids, dtype=np.int64),
        positions=np.column_stack([np.reshape(xy, (n, 2)), np.sin(theta), np.cos(theta)]),
        visual=sp.csr_array((dense * mask).reshape(n, dim)), sentences=tuple(sentences),
        is_test=np.asarray(draw(st.lists(st.booleans(), min_size=n, max_size=n))), extent=extent,
        ground_truth=gt, source=None)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                   HealthCheck.too_slow])
@given(st.lists(st.integers(0, 2), min_size=1, max_size=3), st.data())
def test_cache_round_trip(tmp_path: Path, kinds: list[int], data: st.DataObject) -> None:
    dim = data.draw(st.integers(1, 40))
    envs = [data.draw(homes(f"home{k}", dim)) for k in range(len(kinds))]
    records = []
    for env, kind in zip(envs, kinds, strict=True):
        if kind == 0:  # plain home: one set of sentences, subsampled on reading
            records.append(HomeRecord(env, None, "x"))
        elif kind == 1:  # SIGVerse home taught at several rates
            records.append(HomeRecord(env, {100: env.sentences, 20: (None,) * env.n_samples}, "x"))
        else:  # SIGVerse home never taught
            records.append(HomeRecord(env.with_sentences((None,) * env.n_samples), {}, "x"))
    out = tmp_path / "c.npz"
    write_records(records, out)
    back = read_cache_records(out)
    assert [r.environment.name for r in back] == [e.name for e in envs]
    for rec, got in zip(records, back, strict=True):
        assert_same_home(rec.environment, got.environment, atol=0)
        assert got.rates == rec.rates
        for rate in (0, 100):
            assert got.at_rate(rate).sentences == rec.at_rate(rate).sentences


# ----------------------------------------------------------------------------- behaviour
def test_write_and_read_plain_homes(tmp_path: Path) -> None:
    write_corpus([tiny_env("a", seed=1), tiny_env("b", seed=2, truth=False)], tmp_path / "homes")
    summary = write_cache(tmp_path / "homes", tmp_path / "cache.npz")
    assert "2 homes" in summary and "16 samples" in summary and "cache.npz" in summary
    assert is_cache_file(tmp_path / "cache.npz")
    direct, cached = load(tmp_path / "homes"), load(tmp_path / "cache.npz")
    assert cached.names == direct.names == ["a", "b"]
    for a, b in zip(direct, cached, strict=True):
        assert_same_home(a, b, atol=0)
    assert [e.n_taught for e in read_cache(tmp_path / "cache.npz", 50)] == [
        e.with_teaching_rate(50).n_taught for e in direct]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cache.npz", "homes"]  # no temporary files


def test_every_rate_or_one_rate(tmp_path: Path, make_sigverse_home) -> None:
    make_sigverse_home("sig", root=tmp_path / "src", rates={20: (0,), 100: (0, 1, 2, 3)})
    write_cache(tmp_path / "src", tmp_path / "all.npz")
    assert [read_cache(tmp_path / "all.npz", r)[0].n_taught for r in (0, 20, 100)] == [0, 1, 4]
    with pytest.raises(DataFormatError, match="available rates: 20, 100"):
        read_cache(tmp_path / "all.npz", 40)
    summary = write_cache(tmp_path / "src", tmp_path / "one.npz", teaching_rate=20)
    assert "teaching rate 20%" in summary
    assert read_cache(tmp_path / "one.npz", 20)[0].n_taught == 1
    with pytest.raises(DataFormatError, match=r"available rates: 20$"):
        read_cache(tmp_path / "one.npz", 100)
    # a cache can be read back into a cache
    write_cache(tmp_path / "all.npz", tmp_path / "copy.npz")
    copied = read_cache(tmp_path / "copy.npz", 20)[0]
    assert copied.sentences == read_cache(tmp_path / "all.npz", 20)[0].sentences


def test_refuses_to_overwrite(tmp_path: Path) -> None:
    write_corpus([tiny_env("a")], tmp_path / "homes")
    write_cache(tmp_path / "homes", tmp_path / "c.npz")
    with pytest.raises(ConfigurationError, match="--force"):
        write_cache(tmp_path / "homes", tmp_path / "c.npz")
    write_cache(tmp_path / "homes", tmp_path / "c.npz", overwrite=True)
    with pytest.raises(ConfigurationError, match="teaching rate"):
        write_cache(tmp_path / "homes", tmp_path / "d.npz", teaching_rate=120)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.npz", "homes"]


@pytest.fixture
def cache_file(tmp_path: Path) -> Path:
    write_corpus([tiny_env("a", seed=1), tiny_env("b", seed=2)], tmp_path / "homes")
    write_cache(tmp_path / "homes", tmp_path / "cache.npz")
    return tmp_path / "cache.npz"


def _rewrite(path: Path, change) -> None:
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    change(arrays)
    np.savez(path, **arrays)


def test_truncated_cache(cache_file: Path) -> None:
    data = cache_file.read_bytes()
    cache_file.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataFormatError) as err:
        read_cache(cache_file)
    assert "cache.npz" in str(err.value)


def test_flipped_byte(cache_file: Path) -> None:
    data = bytearray(cache_file.read_bytes())
    with zipfile.ZipFile(cache_file) as zf:
        info = zf.getinfo("positions.npy")
    data[info.header_offset + 60 + info.compress_size // 2] ^= 0xFF
    cache_file.write_bytes(bytes(data))
    with pytest.raises(DataFormatError, match=r"cache\.npz"):
        read_cache(cache_file)


@pytest.mark.parametrize("edit", [
    lambda a: a.update(sample_offsets=a["sample_offsets"][:-1]),
    lambda a: a.update(visual_indices=a["visual_indices"][:-3]),
    lambda a: a.update(positions=np.full_like(a["positions"], np.nan)),
    lambda a: a.pop("ids"),
    lambda a: a.update(header=np.frombuffer(b"{not json", dtype=np.uint8)),
    lambda a: a.update(header=np.frombuffer(json.dumps({
        **json.loads(a["header"].tobytes()), "homes": [{"name": "a"}]}).encode(), dtype=np.uint8)),
    lambda a: a.update(visual_indices=a["visual_indices"] + 100),
])
def test_edited_cache(cache_file: Path, edit) -> None:
    _rewrite(cache_file, edit)
    with pytest.raises(DataFormatError) as err:
        read_cache(cache_file)
    assert "cache.npz" in str(err.value)


def test_foreign_and_newer_files(tmp_path: Path, cache_file: Path) -> None:
    np.savez(tmp_path / "other.npz", x=np.arange(3))
    (tmp_path / "text.npz").write_text("hello")
    for path in (tmp_path / "other.npz", tmp_path / "text.npz"):
        assert not is_cache_file(path)
        with pytest.raises(DataFormatError, match="not an spco cache") as err:
            load(path)
        assert path.name in str(err.value)
    _rewrite(cache_file, lambda a: a.update(header=np.frombuffer(json.dumps({
        **json.loads(a["header"].tobytes()), "format_version": 99}).encode(), dtype=np.uint8)))
    with pytest.raises(DataFormatError, match="newer spco"):
        read_cache(cache_file)


@pytest.mark.sigverse
def test_sigverse_cache_is_identical_and_fast(sigverse_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "sigverse.npz"
    summary = write_cache(sigverse_dir, out)
    assert "25 homes" in summary and "5080 samples" in summary and "20, 40, 60, 80, 100" in summary
    assert out.stat().st_size < 12e6
    start = time.perf_counter()
    cached = load(out)
    elapsed = time.perf_counter() - start
    assert elapsed < 1.5  # typically ~0.2 s
    direct = load(sigverse_dir)
    for a, b in zip(direct, cached, strict=True):
        assert_same_home(a, b, atol=0)
    for rate in (20, 60):
        (home,) = load_homes(out, names=["3LDK_9"], teaching_rate=rate)
        assert home.sentences == load(sigverse_dir / "3LDK_9", teaching_rate=rate)["3LDK_9"].sentences
    with pytest.raises(DataFormatError, match="available rates: 100"):  # the experienced homes
        load(out, teaching_rate=20)
