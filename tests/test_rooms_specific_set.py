"""benchmarks/rooms_specific.py's ``--set NAME=VALUE``: read as ``spco experiment specific --set``.

A bad setting is a usage error naming it before any fit; a good one reaches the configured run's fit as
its transfer hyperparameters (and none gives the model's defaults). No data is read: the run's data and
fit are replaced by stand-ins that record what they were given.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import rooms_specific

import spco.evaluation.specific_config as sc
from spco.evaluation.specific_config import ConfiguredRun
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.transfer import SpatialConceptModel


@pytest.mark.parametrize(("setting", "named"), [("warm_start=bogus", "warm_start must be one of"),
                                                ("no_such_name=1", "no hyperparameter 'no_such_name'")])
def test_bad_setting_is_a_usage_error_naming_it(setting: str, named: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """Exit status 2 (argparse's usage error) before the configuration or the data is read."""
    with pytest.raises(SystemExit) as exc:
        rooms_specific.main(["--data", "/no/such/folder", "--config", "/no/such/config.json",
                             "--set", setting])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Invalid value for --set" in err and named in err


@pytest.mark.parametrize("settings", [(), ("warm_start=words",), ("warm_start=words", "warm_start=names")])
def test_settings_reach_the_fit(settings: tuple[str, ...], monkeypatch: pytest.MonkeyPatch) -> None:
    """The run fits with ``TransferHyperparameters().with_settings(settings)``, or ``None`` without any."""
    # run() swaps these two for its scoring wrappers; restore them after the test
    monkeypatch.setattr(SpatialConceptModel, "answer_inputs", SpatialConceptModel.answer_inputs)
    monkeypatch.setattr(sc, "score_rooms", sc.score_rooms)
    seen: dict[str, Any] = {}

    def execute(data: Any, key: Any, iterations: int, n_positions: int, fingerprint: str = "",
                hyperparameters: Any = None) -> dict[str, Any]:
        seen.update(key=key, iterations=iterations, hyperparameters=hyperparameters)
        rooms_specific._ROOMS[:] = [{}, {}]
        return {}

    file = type("File", (), {"select": lambda self, ids: ids})()
    monkeypatch.setattr(rooms_specific, "load_specific_config", lambda config: file)
    monkeypatch.setattr(rooms_specific, "ConfiguredData", lambda file, data, selected: None)
    monkeypatch.setattr(sc, "execute_configured_run", execute)
    key = ConfiguredRun("c", 40, 3, "spcotransfer+mi")
    record = rooms_specific.run(("config.json", "data", key, 7, settings, False))
    assert record == {"rooms_account": {}, "positions_fit_account": {}}
    assert seen["key"] == key and seen["iterations"] == 7
    if not settings:
        assert seen["hyperparameters"] is None
    else:
        assert seen["hyperparameters"] == TransferHyperparameters().with_settings(list(settings))
        assert seen["hyperparameters"].warm_start == settings[-1].split("=")[1]
