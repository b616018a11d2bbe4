"""`spco inspect` and `spco import` on the data layouts."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from spco.cli import main

EXPERIENCED_16 = ["3LDK_1", "1LDK_8", "2LDK_8", "1LDK_7", "2LDK_7", "1LDK_6", "2LDK_6", "1LDK_5",
                  "2LDK_5", "1LDK_4", "2LDK_4", "1LDK_3", "2LDK_3", "1LDK_2", "2LDK_2", "1LDK_1"]


def run(*args: str) -> str:
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return result.stdout


def rows(*args: str) -> list[dict]:
    return json.loads(run("inspect", *args, "--json"))


def test_inspect_and_import_tiny_homes(tmp_path: Path, make_sigverse_home) -> None:
    make_sigverse_home("a_home", n=6, test=(4, 5), root=tmp_path / "homes")
    make_sigverse_home("b_home", n=5, test=(), rates={20: (1,), 100: range(5)}, root=tmp_path / "homes")
    direct = rows(tmp_path / "homes")
    assert [(r["home"], r["samples"], r["train"], r["test"], r["taught"]) for r in direct] == [
        ("a_home", 6, 4, 2, 4), ("b_home", 5, 5, 0, 5)]
    assert direct[0]["places"] == 2 and direct[0]["vocabulary"] == 5
    out = run("import", tmp_path / "homes", tmp_path / "cache.npz")
    assert "2 homes" in out and "cache.npz" in out
    assert rows(tmp_path / "cache.npz") == direct
    assert rows(tmp_path / "homes" / "b_home", "--teaching-rate", "20")[0]["taught"] == 1

    table = run("inspect", tmp_path / "homes").splitlines()
    assert table[0].split() == ["home", "samples", "train", "test", "taught", "places", "vocabulary"]
    assert table[1].split() == ["a_home", "6", "4", "2", "4", "2", "5"]
    assert table[-1].startswith("2 homes, 11 samples")


def test_import_refuses_to_overwrite(tmp_path: Path, make_sigverse_home) -> None:
    home = make_sigverse_home("flat")
    run("import", home, tmp_path / "c.npz")
    result = CliRunner().invoke(main, ["import", str(home), str(tmp_path / "c.npz")])
    assert result.exit_code == 2 and "--force" in result.stderr
    assert "1 homes" in run("import", home, tmp_path / "c.npz", "--force")
    assert "teaching rate 0%" in run("import", home, tmp_path / "c0.npz", "-r", "0")
    assert rows(tmp_path / "c0.npz", "-r", "0")[0]["taught"] == 0


def test_missing_teaching_rate_is_shown_not_fatal(make_sigverse_home) -> None:
    home = make_sigverse_home("flat")
    result = CliRunner().invoke(main, ["inspect", str(home), "-r", "40", "--json"])
    assert result.exit_code == 0
    (row,) = json.loads(result.stdout)
    assert row["taught"] is None and row["samples"] > 0
    table = CliRunner().invoke(main, ["inspect", str(home), "-r", "40"])
    assert "hold no sentences for 40%" in table.stdout


def test_missing_teaching_rate_is_a_clean_error_when_loading(make_sigverse_home) -> None:
    from spco.data.loading import load
    from spco.errors import DataFormatError

    home = make_sigverse_home("flat")
    with pytest.raises(DataFormatError, match="available rates: 100"):
        load(home, teaching_rate=40)


@pytest.mark.sigverse
def test_inspect_sigverse_facts(sigverse_dir: Path, tmp_path: Path) -> None:
    table = {r["home"]: r for r in rows(sigverse_dir)}
    assert len(table) == 25
    assert {k: table["1LDK_9"][k] for k in ("samples", "train", "test", "taught")} == {
        "samples": 240, "train": 160, "test": 80, "taught": 0}
    assert {k: table["3LDK_9"][k] for k in ("samples", "test")} == {"samples": 360, "test": 100}
    assert sum(table[h]["samples"] for h in EXPERIENCED_16) == 2660
    assert all(table[h]["taught"] == table[h]["samples"] for h in EXPERIENCED_16)
    assert rows(sigverse_dir / "3LDK_9", "--teaching-rate", "20")[0]["taught"] == 24

    out = run("import", sigverse_dir, tmp_path / "cache.npz")
    assert "25 homes" in out
    assert rows(tmp_path / "cache.npz") == list(table.values())
    assert run("inspect", tmp_path / "cache.npz") == run("inspect", sigverse_dir)
