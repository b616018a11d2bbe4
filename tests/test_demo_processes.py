"""``spco demo``'s two-process layout (the robot's files made in a second process while the first
fits and draws) gives what one process gives: the same scores and the same knowledge and home
files, array for array."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spco.errors import SpcoError
from spco.synthetic_transfer import run_demo


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as archive:
        return {name: archive[name] for name in archive.files if name != "header"}


def _header(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as archive:
        header = json.loads(bytes(archive["header"]).decode())
    for key in ("checksum", "provenance", "knowledge_provenance"):  # time stamps and seconds
        header.pop(key, None)
    return header


def test_two_processes_give_what_one_gives(tmp_path: Path) -> None:
    one = run_demo(seed=3, out=tmp_path / "one", n_experienced=3, n_iterations=6, progress=False)
    two = run_demo(seed=3, out=tmp_path / "two", n_experienced=3, n_iterations=6, progress=False, processes=2)
    assert one.transfer.summary() == two.transfer.summary()
    assert one.baseline.summary() == two.baseline.summary()
    assert [p.name for p in one.files] == [p.name for p in two.files]
    assert two.knowledge_file is not None and two.home_file is not None and two.robot_seconds > 0
    for name in ("knowledge.spco", "home.spco"):
        a, b = _arrays(tmp_path / "one" / name), _arrays(tmp_path / "two" / name)
        assert a.keys() == b.keys()
        for key in a:
            assert np.array_equal(a[key], b[key], equal_nan=True), (name, key)
        assert _header(tmp_path / "one" / name) == _header(tmp_path / "two" / name)


def test_an_error_in_the_second_process_reaches_the_caller(tmp_path: Path) -> None:
    """The second process cannot write its files (their folder is a file): the demo raises its
    error instead of waiting for it."""
    out = tmp_path / "demo"
    out.mkdir()
    (out / "knowledge.spco").mkdir()  # the knowledge file's path is taken by a folder
    with pytest.raises(SpcoError, match=r"knowledge\.spco"):
        run_demo(seed=0, out=out, n_experienced=2, n_iterations=3, progress=False, processes=2)
