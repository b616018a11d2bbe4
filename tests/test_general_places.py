"""``benchmarks/general_places.py``'s settings (``--set NAME=VALUE``) and summary, without a fit or
a data set: the settings reach the fits' hyperparameters, a bad one stops the run before any data is
read, and the figures record them."""

from __future__ import annotations

import math
import sys
from dataclasses import fields
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from general_places import main, model_hyperparameters, summarise

from spco.errors import ConfigurationError
from spco.model.hyperparameters import TransferHyperparameters


def test_no_setting_leaves_the_model_its_own_defaults() -> None:
    assert model_hyperparameters(()) is None


def test_settings_change_only_what_they_name() -> None:
    hyper = model_hyperparameters(["target=power", "visual_prior=estimate"])
    assert isinstance(hyper, TransferHyperparameters)
    assert (hyper.target, hyper.visual_prior) == ("power", "estimate")
    default = TransferHyperparameters()
    changed = {f.name for f in fields(hyper) if getattr(hyper, f.name) != getattr(default, f.name)}
    assert changed == {"target", "visual_prior"}


def test_a_bad_setting_is_named() -> None:
    with pytest.raises(ConfigurationError, match="bogus"):
        model_hyperparameters(["bogus=1"])
    with pytest.raises(ConfigurationError, match="target"):
        model_hyperparameters(["target=warm"])


def test_the_command_line_refuses_a_bad_setting_before_reading_data(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as exit_info:  # (no data set at tmp_path: the setting is checked first)
        main(["--sigverse", str(tmp_path), "--seeds", "0", "--set", "target=warm"])
    assert exit_info.value.code == 2
    assert "--set" in capsys.readouterr().err


def test_the_summary_records_settings_only_when_given() -> None:
    runs = [{"seed": s, "home": "3LDK_9", "A_n": a, "A_p": a, "A_p_mixture": math.nan,
             "A_n_places": {"kitchen": a}} for s, a in ((0, 0.5), (1, 1.0))]
    plain = summarise("development", [0, 1], 10, ["3LDK_9"], runs)
    assert "settings" not in plain
    assert plain["A_n"]["mean"] == pytest.approx(0.75)
    assert plain["A_p_mixture"] is None
    power = summarise("development", [0, 1], 10, ["3LDK_9"], runs, settings=("target=power",))
    assert power["settings"] == ["target=power"]
    assert power["A_n"] == plain["A_n"]


def test_the_command_line_knows_the_view_in_room_answer(tmp_path: Path,
                                                         capsys: pytest.CaptureFixture) -> None:
    """``--answers view_in_room`` is accepted (the run stops at the missing data set, after the answers
    are checked); an unknown answer is refused naming ``--answers`` and the choices."""
    with pytest.raises(SystemExit) as exit_info:
        main(["--sigverse", str(tmp_path), "--seeds", "0", "--answers", "rooms,view_in_room,looks"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "error: --sigverse" in err and "error: --answers" not in err
    with pytest.raises(SystemExit) as exit_info:
        main(["--sigverse", str(tmp_path), "--seeds", "0", "--answers", "rooms,in_room"])
    assert exit_info.value.code == 2
    assert "--answers: choose from view, rooms, view_in_room, listener, looks" in capsys.readouterr().err
