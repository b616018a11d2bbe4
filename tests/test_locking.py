"""Safe concurrent use of a home file: writers lock it, readers never see a half-written file.

On main before the lock, two `spco teach` processes on one home lost one of the two teachings
(both reported "1 taught"). These tests run real processes (`python -m spco teach …`).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from conftest import fit_and_adapt, synthetic_home_folders
from serve_helpers import env as _env

from spco import knowledge as kn
from spco.knowledge.locking import LockTimeoutError, lock_path, locked


@pytest.fixture(scope="module")
def home_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folders = synthetic_home_folders(tmp_path_factory.mktemp("locking"), 3, seed=5, n_features=64)
    return fit_and_adapt(folders, ["--iterations", 8], ["--teaching-rate", 0, "--iterations", 5],
                         knowledge="k.spco")[1]


def _teach(path: Path, sample: int, sentence: str, **env: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "spco", "teach", str(path), "--id", str(sample),
                             "--sentence", sentence, "--sweeps", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(**env))


_READER = textwrap.dedent("""
    import sys, time
    from spco.knowledge import load_home_model
    path, stop = sys.argv[1], sys.argv[2]
    reads = 0
    import os
    while not os.path.exists(stop):
        load_home_model(path)  # raises on a half-written file
        reads += 1
        time.sleep(0.01)  # leave the two cores to the writers
    print(reads)
""")


def test_concurrent_teachers_keep_every_teaching(tmp_path: Path, home_file: Path) -> None:
    path = tmp_path / "home.spco"
    path.write_bytes(home_file.read_bytes())
    ids = [int(i) for i in kn.load_home_model(path).ids[:3]]
    stop = tmp_path / "stop"
    reader = subprocess.Popen([sys.executable, "-c", _READER, str(path), str(stop)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, env=_env())
    teachers = [_teach(path, sample, f"this is place{k}-room") for k, sample in enumerate(ids)]
    outputs = [p.communicate(timeout=300) for p in teachers]
    stop.touch()
    reads, reader_errors = reader.communicate(timeout=120)
    for p, (out, err) in zip(teachers, outputs, strict=True):
        assert p.returncode == 0, out + err
    home = kn.load_home_model(path)
    assert home.n_taught == 3, home.sentences
    for k, sample in enumerate(ids):
        assert home.sentences[list(home.ids).index(sample)] == f"this is place{k}-room"
        assert f"place{k} room" in home.vocabulary  # hyphenated names are one spaced term
    assert home.provenance["teach_updates"] == 3
    # the reader loaded the file over and over while it was replaced, and never saw a broken file
    assert reader.returncode == 0, reader_errors
    assert int(reads) >= 1
    # each teacher built on the ones before it: they report 1, 2 and 3 taught samples
    reported = sorted(int(re.search(r"samples, (\d+) taught", out).group(1)) for out, _ in outputs)
    assert reported == [1, 2, 3]


_HOLDER = textwrap.dedent("""
    import sys, time
    from spco.knowledge.locking import locked
    with locked(sys.argv[1]):
        print("held", flush=True)
        time.sleep(120)
""")


def test_killed_lock_holder_does_not_block_the_next_writer(tmp_path: Path, home_file: Path) -> None:
    path = tmp_path / "home.spco"
    path.write_bytes(home_file.read_bytes())
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(path)], stdout=subprocess.PIPE, text=True,
                              env=_env())
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        # while the holder lives, a writer waits, then gives up with one clear line
        waiting = _teach(path, 0, "this is the kitchen", SPCO_LOCK_TIMEOUT="0.5")
        out, err = waiting.communicate(timeout=120)
        assert waiting.returncode == 2, out + err
        assert f"process {holder.pid} is still writing this file" in err and "SPCO_LOCK_TIMEOUT" in err
        assert "Traceback" not in err
        assert kn.load_home_model(path).n_taught == 0
        # killed (no chance to clean up): the kernel drops its lock, the next writer goes ahead
        os.kill(holder.pid, signal.SIGKILL)
        holder.wait(timeout=30)
        start = time.perf_counter()
        after = _teach(path, 0, "this is the kitchen", SPCO_LOCK_TIMEOUT="30")
        out, err = after.communicate(timeout=120)
        assert after.returncode == 0, out + err
        assert kn.load_home_model(path).n_taught == 1
        assert time.perf_counter() - start < 30
        assert lock_path(path).exists()  # the lock file stays; it is the flock that was released
    finally:
        if holder.poll() is None:
            holder.kill()
            holder.wait()


def test_lock_is_reentrant_and_times_out(tmp_path: Path) -> None:
    path = tmp_path / "file.spco"
    with locked(path) as sidecar, locked(path):  # the same thread does not wait for itself
        assert sidecar == tmp_path / "file.spco.lock"
        # another process cannot take it
        probe = subprocess.run([sys.executable, "-c", "import sys\n"
                                "from spco.knowledge.locking import locked\n"
                                "with locked(sys.argv[1], timeout=0.2): pass", str(path)],
                               capture_output=True, text=True, env=_env())
        assert probe.returncode != 0 and "LockTimeoutError" in probe.stderr
    with locked(path, timeout=0):  # released after the outer block
        pass


def test_lock_timeout_message_and_bad_setting(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "file.spco"
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(path)], stdout=subprocess.PIPE, text=True,
                              env=_env())
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        with pytest.raises(LockTimeoutError, match=f"process {holder.pid}"), locked(path, timeout=0.1):
            pass
    finally:
        holder.kill()
        holder.wait()
    monkeypatch.setenv("SPCO_LOCK_TIMEOUT", "soon")
    with pytest.raises(Exception, match="SPCO_LOCK_TIMEOUT must be a number"), locked(path):
        pass


def test_adapt_force_waits_for_the_lock(home_file: Path) -> None:
    """`adapt --force` replacing a home that another writer holds waits for it (then gives up here)."""
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(home_file)], stdout=subprocess.PIPE,
                              text=True, env=_env())
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        before = home_file.read_bytes()
        new_home = next((home_file.parent / "new").iterdir())
        result = subprocess.run(
            [sys.executable, "-m", "spco", "adapt", str(home_file.parent / "k.spco"), "--home", str(new_home),
             "--teaching-rate", "0", "--iterations", "1", "--out", str(home_file), "--force"],
            capture_output=True, text=True, env=_env(SPCO_LOCK_TIMEOUT="0.3"), timeout=300)
        assert result.returncode == 2, result.stdout + result.stderr
        assert f"process {holder.pid} is still writing this file" in result.stderr
        assert "Traceback" not in result.stderr
        assert home_file.read_bytes() == before
    finally:
        holder.kill()
        holder.wait()
