"""The first hour, again (issue 24 point 3): long runs show progress on any terminal, the demo's
timing line says what happened, ``where`` says how many regions its poses came from, and a fleet fit
from Python gives a knowledge file.

Small synthetic homes (128 visual features, a few sweeps): these tests check behaviour, not accuracy.
"""

from __future__ import annotations

import os
import pty
import select
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import synthetic_home_folders

from spco.cli import main
from spco.cli.knowledge import _where_drawn_from
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.engines import LocalEngine
from spco.knowledge import fit_knowledge, load_knowledge
from spco.model import precompile
from spco.model.sources import SyntheticHomes
from spco.progress import progress_bar

CONFIG = SyntheticConfig(n_features=128)


def _read_all(fd: int, until: float) -> bytes:
    """What the other end of a pseudo-terminal wrote, until it closes or ``until`` (a time) passes."""
    out = b""
    while time.monotonic() < until:
        ready, _, _ = select.select([fd], [], [], 0.2)
        if ready:
            try:
                chunk = os.read(fd, 65536)
            except OSError:  # the other end closed
                break
            if not chunk:
                break
            out += chunk
    return out


def test_a_bar_is_drawn_on_a_terminal_that_reports_no_size(monkeypatch: pytest.MonkeyPatch) -> None:
    """A new pseudo-terminal reports 0 columns and 0 lines, as a multiplexer before its first resize
    does; tqdm left alone draws nothing on such a standard error (the fit looked hung), spco's bar
    draws itself."""
    master, slave = pty.openpty()
    assert os.get_terminal_size(slave) == os.terminal_size((0, 0))
    with os.fdopen(slave, "w", closefd=True) as stream:
        monkeypatch.setattr(sys, "stderr", stream)
        bar = progress_bar(total=3, desc="fit", unit="sweep")
        for _ in range(3):
            bar.update(1)
        bar.close()
    text = _read_all(master, time.monotonic() + 5).decode(errors="replace")
    os.close(master)
    assert "fit" in text and "3/3" in text


@pytest.fixture(scope="module")
def homes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Four experienced synthetic homes and a new one, in the plain format."""
    return synthetic_home_folders(tmp_path_factory.mktemp("first_hour_again"), 5, seed=3)


def test_spco_fit_shows_its_sweeps_on_a_terminal(homes: dict[str, Path]) -> None:
    """``spco fit`` with standard error on a (size-less) terminal draws a bar of sweeps; with standard
    error in a file, none."""
    out = homes["root"] / "progress.spco"
    command = [sys.executable, "-m", "spco", "fit", "--data", str(homes["experienced"]),
               "--iterations", "30", "--out", str(out), "--force"]
    master, slave = pty.openpty()
    process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave)
    os.close(slave)
    text = _read_all(master, time.monotonic() + 300).decode(errors="replace")
    os.close(master)
    assert process.wait(timeout=60) == 0, text
    assert "fit (spcotransfer+mi)" in text and "/30" in text and "sweep" in text
    piped = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert piped.returncode == 0, piped.stderr
    assert "/30" not in piped.stderr


def _demo_line(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, cold: bool) -> str:
    import spco.synthetic_transfer

    calls: list[int] = []

    def compile_in_turn(turns) -> float:  # this process's turns
        calls.append(turns.value)
        time.sleep(0.3)
        return 0.3

    monkeypatch.setattr(precompile, "kernels_compiled", lambda: not cold)
    monkeypatch.setattr(spco.synthetic_transfer, "compile_in_turn", compile_in_turn)
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    result = CliRunner().invoke(main, ["demo", "--homes", "2", "--iterations", "3", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert len(calls) == (1 if cold else 0)
    return next(line for line in result.stdout.splitlines() if line.startswith("Learnt"))


def test_the_demo_says_it_compiled_on_a_first_run_and_loaded_afterwards(monkeypatch, tmp_path) -> None:
    """Right after announcing the compilation, the demo's timing line counts it (it said "0.4 s
    compiling or loading" after 20 s of compiling); on a warm cache it says the kernels were loaded."""
    line = _demo_line(monkeypatch, tmp_path / "cold", cold=True)
    assert "compiling the kernels for this machine, a first run only" in line
    seconds = float(line.split("(after ")[1].split(" s ")[0])
    assert seconds >= 0.3  # the (stubbed) compilation is counted
    line = _demo_line(monkeypatch, tmp_path / "warm", cold=False)
    assert "loading the compiled kernels" in line and "compiling" not in line


def test_where_says_how_many_regions_its_poses_came_from(homes: dict[str, Path]) -> None:
    root = homes["root"]
    knowledge, home = root / "k.spco", root / "home.spco"
    assert CliRunner().invoke(main, ["fit", "--data", str(homes["experienced"]), "--iterations", "20",
                                     "--seed", "1", "--out", str(knowledge)]).exit_code == 0
    assert CliRunner().invoke(main, ["adapt", str(knowledge), "--home", str(homes["new"]),
                                     "--iterations", "15", "--out", str(home)]).exit_code == 0
    # a new name taught at two samples far apart: its poses come from both places
    positions = np.loadtxt(homes["new"] / "samples.csv", delimiter=",", skiprows=1, usecols=(1, 2))
    far = int(np.argmax(np.linalg.norm(positions - positions[0], axis=1)))
    result = CliRunner().invoke(main, ["teach", str(home), "--id", "0", "--sentence", "this is the study",
                                       "--id", str(far), "--sentence", "this is the study"])
    assert result.exit_code == 0, result.output
    result = CliRunner().invoke(main, ["where", str(home), "study", "-n", "6"])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    header = next(k for k, line in enumerate(lines) if line.split()[:1] == ["x"])
    assert lines[header].split() == ["x", "y", "theta", "probability", "region"]
    drawn = [int(line.split()[4]) for line in lines[header + 1:header + 7]]
    assert len(set(drawn)) >= 2  # the poses came from both places
    assert f"6 poses drawn from {len(set(drawn))} regions in proportion to p(region | study)" in result.stdout
    assert "region's Gaussian" not in result.stdout


def test_where_names_one_region_when_its_poses_came_from_one() -> None:
    assert _where_drawn_from([4, 4, 4], "kitchen").startswith("3 poses drawn from the region's Gaussian")
    assert _where_drawn_from([4, 7, 4], "kitchen").startswith(
        "3 poses drawn from 2 regions in proportion to p(region | kitchen) (region 4: 2, region 7: 1)")


def test_a_fleet_fit_from_python_saves_as_a_knowledge_file(tmp_path: Path) -> None:
    """``fit_knowledge`` takes a fleet that its shards generate (``SyntheticHomes``) and an engine, and
    returns a ``Knowledge`` that saves and loads; in one process it is the knowledge of the same
    homes loaded as a corpus."""
    source = SyntheticHomes.create(5, seed=4, config=CONFIG)
    corpus = generate_homes(5, seed=4, config=CONFIG, specific_rooms=False)
    assert source.names == corpus.names
    assert source.n_samples == sum(env.n_train for env in corpus)
    knowledge = fit_knowledge(source, n_iterations=6, random_state=0, engine=LocalEngine(2))
    path = knowledge.save(tmp_path / "fleet.spco")
    loaded = load_knowledge(path)
    assert loaded.provenance["homes"] == corpus.names
    assert loaded.provenance["n_samples"] == source.n_samples
    np.testing.assert_array_equal(loaded.log_phi_visual, knowledge.log_phi_visual)
    one = fit_knowledge(source, n_iterations=6, random_state=0)
    same = fit_knowledge(corpus, n_iterations=6, random_state=0)
    np.testing.assert_array_equal(one.log_phi_visual, same.log_phi_visual)
