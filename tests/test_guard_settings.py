"""``--set NAME=VALUE`` of the guard scripts ``benchmarks/japanese.py cc4f``, ``benchmarks/teaching.py``
and ``benchmarks/unheard_errors.py`` (branch guards22), without a data set or a fit: a bad setting stops
the run naming it, a good one reaches the fit's hyperparameters, and without it the run is the default's
(no hyperparameters passed, the unheard cache's key unchanged)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import japanese
import teaching
import unheard_errors

from spco.model.hyperparameters import TransferHyperparameters

N = ["place_channel=home", "name_answer=looks"]


def _cc4f_args(monkeypatch: pytest.MonkeyPatch, extra: list[str]) -> argparse.Namespace:
    seen: list[argparse.Namespace] = []
    monkeypatch.setattr(japanese, "run_cc4f", seen.append)
    monkeypatch.setattr(sys, "argv", ["japanese.py", "cc4f", "--data", "nowhere", *extra])
    japanese.main()
    return seen[0]


def test_cc4f_settings_reach_the_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    args = _cc4f_args(monkeypatch, ["--set", *N, "--model-answer"])
    assert (args.hyper.place_channel, args.hyper.name_answer) == ("home", "looks")
    assert args.model_answer
    default = _cc4f_args(monkeypatch, [])
    assert default.hyper is None and not default.model_answer


def test_cc4f_bad_setting_is_named(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit):
        _cc4f_args(monkeypatch, ["--set", "name_answer=loud"])
    assert "--set" in capsys.readouterr().err


def test_teaching_settings_reach_the_knowledge(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: dict[str, object] = {}

    class Stop(Exception):
        pass

    def fit_knowledge(corpus: object, **kwargs: object) -> None:
        seen.update(kwargs)
        raise Stop

    monkeypatch.setattr(teaching.kn, "fit_knowledge", fit_knowledge)
    with pytest.raises(Stop):
        teaching.synthetic_home(3, settings=tuple(N))
    hyper = seen["hyperparameters"]
    assert isinstance(hyper, TransferHyperparameters)
    assert (hyper.place_channel, hyper.name_answer) == ("home", "looks")
    with pytest.raises(Stop):
        teaching.synthetic_home(3)
    assert seen["hyperparameters"] is None  # the default run: the knowledge's own


def test_teaching_bad_setting_is_named(capsys: pytest.CaptureFixture) -> None:
    parser = argparse.ArgumentParser()
    with pytest.raises(SystemExit):
        teaching._check_settings(parser, ["place_channel=garden"])
    assert "--set" in capsys.readouterr().err
    teaching._check_settings(parser, N)  # no error


def _unheard_args(monkeypatch: pytest.MonkeyPatch, extra: list[str]) -> argparse.Namespace:
    monkeypatch.setattr(sys, "argv", ["unheard_errors.py", "--seeds", "0", *extra])
    return unheard_errors._arguments()


def test_unheard_settings_reach_the_fit_and_its_cache_key(monkeypatch: pytest.MonkeyPatch,
                                                          tmp_path: Path) -> None:
    args = _unheard_args(monkeypatch, ["--set", *N, "--cache", str(tmp_path)])
    assert (args.hyper.place_channel, args.hyper.name_answer) == ("home", "looks")
    assert _unheard_args(monkeypatch, []).hyper is None

    speech = tmp_path / "speech.csv"
    speech.write_text("x\n")
    key = unheard_errors.hashlib.sha256(b"x\n").hexdigest()[:16]
    default = _unheard_args(monkeypatch, ["--cache", str(tmp_path)])
    assert unheard_errors.cache_path(default, speech, 7, "3LDK_9") == tmp_path / f"{key}-3LDK_9-s7-w200.pkl"
    with_n = unheard_errors.cache_path(args, speech, 7, "3LDK_9")
    assert with_n.name.startswith(f"{key}-") and with_n.name.endswith("-3LDK_9-s7-w200.pkl")
    assert with_n != unheard_errors.cache_path(default, speech, 7, "3LDK_9")
    reordered = _unheard_args(monkeypatch, ["--set", *reversed(N), "--cache", str(tmp_path)])
    assert unheard_errors.cache_path(reordered, speech, 7, "3LDK_9") == with_n


def test_unheard_bad_setting_is_named(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit):
        _unheard_args(monkeypatch, ["--set", "bogus=1"])
    assert "bogus" in capsys.readouterr().err
