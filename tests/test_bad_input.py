"""Bad input of every kind: each is a DataFormatError naming the file, and `spco inspect` exits 2."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from test_plain_format import tiny_env

from spco.cli import main
from spco.data import load
from spco.data.loading import write_cache
from spco.data.plain import write_home
from spco.errors import DataFormatError

Builder = Callable[[Path, Callable[..., Path]], Path]
SIGVERSE_CASES: dict[str, tuple[Builder, str]] = {}
PLAIN_CASES: dict[str, tuple[Builder, str]] = {}


def sigverse_case(name: str, culprit: str) -> Callable[[Callable[[Path], object]], Callable[[Path], object]]:
    """Register a corruption of a tiny SIGVerse home; ``culprit`` must appear in the error."""

    def register(edit: Callable[[Path], object]) -> Callable[[Path], object]:
        def build(tmp: Path, make: Callable[..., Path]) -> Path:
            home = make("home")
            edit(home)
            return home

        SIGVERSE_CASES[name] = (build, culprit)
        return edit

    return register


def plain_case(name: str, culprit: str) -> Callable[[Callable[[Path], object]], Callable[[Path], object]]:
    """Register a corruption of a tiny plain home; ``culprit`` must appear in the error."""

    def register(edit: Callable[[Path], object]) -> Callable[[Path], object]:
        def build(tmp: Path, make: Callable[..., Path]) -> Path:
            home = write_home(tiny_env("flat"), tmp / "flat")
            edit(home)
            return home

        PLAIN_CASES[name] = (build, culprit)
        return edit

    return register


def _edit_csv(home: Path, index: int, change: Callable[[list[str]], list[str]]) -> None:
    path = home / "vision_fc7_normalized" / f"{index}.csv"
    path.write_text("\n".join(change(path.read_text().split("\n"))))


def _set_line(index: int, line: int, value: str) -> Callable[[Path], None]:
    def change(lines: list[str]) -> list[str]:
        lines[line - 1] = value
        return lines

    return lambda home: _edit_csv(home, index, change)


def _write(relative: str, text: str | bytes) -> Callable[[Path], None]:
    def edit(home: Path) -> None:
        path = home / relative
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text, encoding="utf-8")

    return edit


def _remove(relative: str) -> Callable[[Path], None]:
    def edit(home: Path) -> None:
        path = home / relative
        if path.is_dir():
            shutil.rmtree(path)
        else:
            path.unlink()

    return edit


def _samples_line(line: int, text: str) -> Callable[[Path], None]:
    def edit(home: Path) -> None:
        lines = (home / "samples.csv").read_text(encoding="utf-8").splitlines()
        lines[line - 1] = text
        (home / "samples.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")

    return edit


def _missing_mask(mask: np.ndarray) -> Callable[[Path], None]:
    """visual.npz with a 'missing' array (which samples have no view) beside its counts.
    (A home without any visual file is valid: it has no views.)"""
    def edit(home: Path) -> None:
        (home / "visual.npz").unlink()
        np.savez(home / "visual.npz", visual=np.ones((8, 12), dtype=np.int64), missing=mask)

    return edit


def _visual(array: np.ndarray) -> Callable[[Path], None]:
    def edit(home: Path) -> None:
        (home / "visual.npz").unlink()
        np.save(home / "visual.npy", array)

    return edit


sigverse_case("missing visual file", "3.csv")(_remove("vision_fc7_normalized/3.csv"))
sigverse_case("missing visual folder", "vision_fc7_normalized")(_remove("vision_fc7_normalized"))
sigverse_case("gap in sample ids", "2.txt")(_remove("position/2.txt"))
sigverse_case("duplicate sample ids", "01.txt")(_write("position/01.txt", "0 0\n0 1"))
sigverse_case("empty home", "position")(lambda h: [p.unlink() for p in (h / "position").iterdir()])
sigverse_case("vector too short", "1.csv")(lambda h: _edit_csv(h, 1, lambda lines: lines[:4095]))
sigverse_case("vector too long", "2.csv")(lambda h: _edit_csv(h, 2, lambda lines: ["0", *lines]))
sigverse_case("non-numeric count", "4.csv")(_set_line(4, 7, "seven"))
sigverse_case("negative count", "0.csv")(_set_line(0, 3, "-2"))
sigverse_case("fractional count", "5.csv")(_set_line(5, 3, "2.5"))
sigverse_case("NaN position", "3.txt")(_write("position/3.txt", "nan 1.0\n0 1"))
sigverse_case("inf position", "1.txt")(_write("position/1.txt", "1.0 -inf\n0 1"))
sigverse_case("heading far from a unit vector", "0.txt")(_write("position/0.txt", "1.0 1.0\n0.8 0.9"))
sigverse_case("cos missing", "0.txt")(_write("position/0.txt", "1.0 1.0\n0.8"))
sigverse_case("garbage position", "5.txt")(_write("position/5.txt", b"\x89PNG\r\n"))
sigverse_case("test list names missing samples", "test_num.txt")(_write("test_num.txt", "4,5,6,"))
sigverse_case("bad test list", "test_num.txt")(_write("test_num.txt", "4,five,"))
sigverse_case("Last_data_number disagrees", "Environment_parameter.txt")(
    _write("Environment_parameter.txt", "Last_data_number 9 #5\n"))
sigverse_case("sentence for a missing sample", "sentence9.txt")(
    _write("sentence/per_100/sentence9.txt", "this is the bath"))
sigverse_case("sentence not UTF-8", "sentence1.txt")(
    _write("sentence/per_100/sentence1.txt", b"this is the k\xfctchen"))

plain_case("no samples file", "samples.csv")(_remove("samples.csv"))
plain_case("missing-view mask of the wrong length", "visual.npz")(_missing_mask(np.ones(3, dtype=bool)))
plain_case("missing-view mask not boolean", "visual.npz")(_missing_mask(np.full(8, 2)))
plain_case("wrong number of rows", "visual.npy")(_visual(np.ones((5, 12))))
plain_case("negative counts", "visual.npy")(_visual(-np.ones((8, 12))))
plain_case("NaN features", "visual.npy")(_visual(np.full((8, 12), np.nan)))
plain_case("corrupt visual", "visual.npz")(_write("visual.npz", b"PK\x03\x04 truncated"))
plain_case("non-numeric x", "samples.csv")(_samples_line(3, "101,left,0.5,0,"))
plain_case("NaN position", "samples.csv")(_samples_line(3, "101,nan,0.5,0,"))
plain_case("duplicate ids", "samples.csv")(_samples_line(3, "100,1,0.5,0,"))
plain_case("missing id", "samples.csv")(_samples_line(3, ",1,0.5,0,"))
plain_case("bad header", "samples.csv")(_samples_line(1, "id,x,y,heading"))
plain_case("empty home", "samples.csv")(_write("samples.csv", "id,x,y,theta,sentence\n"))
plain_case("test list names missing samples", "test.txt")(_write("test.txt", "100 999"))
plain_case("bad jsonl", "samples.jsonl")(lambda h: [
    (h / "samples.csv").unlink(),
    (h / "samples.jsonl").write_text('{"id": 1, "x": 0, "y": 0, "theta": 0}\n{"id": 2, "x": 0,\n')])
plain_case("bad home.json", "home.json")(_write("home.json", json.dumps({"extent": [1, 0, 0, 1]})))
plain_case("labels of missing samples", "labels.csv")(_write("labels.csv", "id,label\n100,kitchen\n5,bath\n"))
plain_case("bad regions", "regions.json")(_write("regions.json", '{"kitchen": [[1, 0, 0, 1]]}'))
plain_case("home.json not JSON", "home.json: not valid JSON")(_write("home.json", '{"name": "flat",'))
plain_case("regions.json not JSON", "regions.json: not valid JSON")(_write("regions.json", "{'kitchen': []}"))


def _file(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def _truncated_cache(tmp: Path, make: Callable[..., Path]) -> Path:
    home = write_home(tiny_env("flat", dim=300), tmp / "flat")
    write_cache(home, tmp / "full.npz")
    return _file(tmp / "c.npz", (tmp / "full.npz").read_bytes()[:3000])


def _empty_folder(tmp: Path, make: Callable[..., Path]) -> Path:
    (tmp / "empty").mkdir()
    return tmp / "empty"


OTHER_CASES: dict[str, tuple[Builder, str]] = {
    "missing path": (lambda tmp, make: tmp / "no_such_home", "no_such_home"),
    "folder without homes": (_empty_folder, "empty"),
    "not a cache": (lambda tmp, make: _file(tmp / "notes.npz", b"hello"), "notes.npz"),
    "truncated cache": (_truncated_cache, "c.npz"),
}

CASES = {**SIGVERSE_CASES, **{f"plain: {k}": v for k, v in PLAIN_CASES.items()}, **OTHER_CASES}


@pytest.mark.parametrize("case", CASES)
def test_bad_input_names_the_file(case: str, tmp_path: Path, make_sigverse_home) -> None:
    build, culprit = CASES[case]
    path = build(tmp_path, make_sigverse_home)
    with pytest.raises(DataFormatError) as err:
        load(path)
    assert culprit in str(err.value)
    result = CliRunner().invoke(main, ["inspect", str(path)])
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith("error: ") and culprit in result.stderr
    assert "Traceback" not in result.output


def test_python_dash_m_reports_bad_input(tmp_path: Path, make_sigverse_home) -> None:
    home = SIGVERSE_CASES["vector too short"][0](tmp_path, make_sigverse_home)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")}
    proc = subprocess.run([sys.executable, "-m", "spco", "inspect", str(home)], capture_output=True,
                          text=True, env=env, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ") and "1.csv" in proc.stderr and "4095" in proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout


def _snapshot(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def test_reading_never_modifies_the_source(tmp_path: Path, make_sigverse_home) -> None:
    src = tmp_path / "src"
    make_sigverse_home("sig", root=src)
    write_home(tiny_env("plain", dim=4096), src / "plain")
    before = _snapshot(src)
    load(src)
    write_cache(src, tmp_path / "cache.npz")
    CliRunner().invoke(main, ["inspect", str(src), "--json"])
    CliRunner().invoke(main, ["inspect", str(src / "sig"), "--teaching-rate", "0"])
    assert _snapshot(src) == before


@pytest.mark.sigverse
def test_reading_the_data_set_never_modifies_it(sigverse_dir: Path, tmp_path: Path) -> None:
    home = sigverse_dir / "3LDK_9"
    before = _snapshot(home)
    load(home, teaching_rate=20)
    write_cache(home, tmp_path / "c.npz")
    assert _snapshot(home) == before
