"""One way to do each thing in the benchmarks and the tests (issue 33): the development seeds refused
in one function (``split_seeds.refuse_other_seeds``), the SIGVerse data set's default in one
(``data_paths.sigverse_path``), the diagnoses' loop over the natural-speech fits in one
(``natural_speech.diagnosed``), and ``spco serve`` started and its address read in one
(:class:`spco.service.client.ServeProcess`)."""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


def _sources(*folders: str) -> dict[str, str]:
    """The Python files of ``folders`` (but this one), by their path in the project."""
    return {str(p.relative_to(ROOT)): p.read_text(encoding="utf-8")
            for folder in folders for p in sorted((ROOT / folder).glob("*.py"))
            if p != Path(__file__).resolve()}


class _Stop(Exception):
    """Raised by a patched step after the seed check: the script got past it."""


def _stop(*_args, **_kwargs):
    raise _Stop


@pytest.mark.parametrize(("script", "patched", "argv"), [
    ("unheard_errors", "never_heard", []),
    ("written_errors", "settings_hyperparameters", ["--speech", "speech.csv"]),
])
def test_the_error_scripts_refuse_every_seed_outside_the_development_sets(script, patched, argv, monkeypatch,
                                                                          capsys) -> None:
    """Held-out seeds (100–119), the unassigned 120–199 and seeds from 400 are refused before anything
    is read; 0–99 and 200–399 pass the check."""
    module = __import__(script)
    monkeypatch.setattr(module, patched, _stop)
    if script == "unheard_errors":
        monkeypatch.setattr(module, "read_names", lambda path: {})
    for seed in (100, 150, 400):
        monkeypatch.setattr(sys, "argv", [script, *argv, "--seeds", "0", str(seed)])
        with pytest.raises(SystemExit):
            module.main()
        assert "0-99 and 200-399" in capsys.readouterr().err
    for seed in (99, 200, 299, 300, 399):
        monkeypatch.setattr(sys, "argv", [script, *argv, "--seeds", str(seed)])
        with pytest.raises(_Stop):
            module.main()


def test_no_script_writes_its_own_seed_ranges() -> None:
    """A comparison with the split's bounds (100 and 200) is split_seeds.py's alone."""
    found = []
    for name, text in _sources("benchmarks").items():
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.Compare):
                numbers = {c.value for c in ast.walk(node) if isinstance(c, ast.Constant)}
                if {100, 200} <= numbers:
                    found.append(name)
    assert found == []


def test_one_definition_of_where_the_sigverse_data_is(monkeypatch, tmp_path: Path) -> None:
    import conftest
    import data_paths

    assert conftest.sigverse_path is data_paths.sigverse_path
    monkeypatch.setenv("SPCO_SIGVERSE", str(tmp_path))
    assert data_paths.sigverse_path() == tmp_path  # read when asked, as the tests' fixture asks
    monkeypatch.delenv("SPCO_SIGVERSE")
    assert data_paths.sigverse_path() == ROOT.parent / "shared" / "datasets" / "sigverse"
    readers = [name for name, text in _sources("benchmarks", "tests").items()
               if "environ" in text and '"SPCO_SIGVERSE"' in text]
    assert readers == ["benchmarks/data_paths.py"]


def test_the_diagnoses_share_one_loop_over_the_fits(monkeypatch, capsys) -> None:
    """``natural_speech.diagnosed``: the seed check, the configurations, each fit's rows with the
    knowledge homes' speech and the configuration's home, a line of progress; both diagnoses use it."""
    import nameless_answers
    import natural_speech
    import other_place_answers

    calls = []
    monkeypatch.setattr(natural_speech, "read_names", lambda path: {"kitchen": ("kitchen",)})
    monkeypatch.setattr(natural_speech, "configurations",
                        lambda sigverse, accepted, leave_one_out: (["K"], [("3LDK_9", ["K"], "env"),
                                                                          ("1LDK_1 (out)", ["K"], "env")]))
    monkeypatch.setattr(natural_speech, "place_speech", lambda homes, corpus: {"said": corpus})

    def runs(configs, labels, seeds, **kwargs):
        assert labels == ["3LDK_9", "1LDK_1 (out)"] and kwargs["settings"] == ["name_answer=listener"]
        for seed in seeds:
            for label, _, env in configs:
                yield seed, label, env, f"corpus {seed}", "model", 1, "scored"

    def diagnose(model, corpus, e, env, scored, seed, accepted, said, home):
        calls.append((seed, home, said["said"]))
        return [{"seed": seed}]

    monkeypatch.setattr(natural_speech, "fitted_runs", runs)
    monkeypatch.setattr(sys, "argv", ["x", "--seeds", "3", "204", "--set", "name_answer=listener"])
    parser = natural_speech.fit_arguments(argparse.ArgumentParser())
    args, rows = natural_speech.diagnosed(parser, diagnose, "test")
    assert args.json is None and not args.leave_one_out and len(rows) == 4
    assert calls == [(3, "3LDK_9", "corpus 3"), (3, "1LDK_1", "corpus 3"), (204, "3LDK_9", "corpus 204"),
                     (204, "1LDK_1", "corpus 204")]
    assert "seed 204 1LDK_1 (out): 4 test views so far" in capsys.readouterr().out
    monkeypatch.setattr(sys, "argv", ["x", "--seeds", "100"])
    with pytest.raises(SystemExit):
        natural_speech.diagnosed(natural_speech.fit_arguments(argparse.ArgumentParser()), diagnose, "test")
    for script in (nameless_answers, other_place_answers):
        names = script.main.__code__.co_names
        assert "diagnosed" in names and "fitted_runs" not in names and "refuse_other_seeds" not in names


def test_spco_serve_is_started_and_its_address_read_in_one_place(tmp_path: Path) -> None:
    """Only :class:`ServeProcess` reads the line ``spco serve`` prints when it listens; a server that
    exits before it listens is a ClientError with what it printed."""
    from spco.service.client import ClientError, ServeProcess

    readers = [name for name, text in _sources("benchmarks", "tests", "src/spco/service").items()
               if r"\(page\)" in text]
    assert readers == ["src/spco/service/client.py"]
    with pytest.raises(ClientError, match=r"spco serve did not start:(.|\n)*no-such-home"):
        ServeProcess(tmp_path / "no-such-home.spco", "--port", "0", timeout=120)
