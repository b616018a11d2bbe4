"""Helpers of the ``spco serve`` tests: a small served home, and a real server process."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

from spco import knowledge as kn
from spco.service.client import ClientError, ServeProcess

SRC = str(Path(kn.__file__).resolve().parents[2])  # src/spco/knowledge/__init__.py -> src


def env(**extra: str) -> dict[str, str]:
    """The environment of a child process that imports this checkout's spco."""
    values = dict(os.environ)
    values["PYTHONPATH"] = SRC + os.pathsep + values.get("PYTHONPATH", "")
    values.update(extra)
    return values


def build_home(folder: Path) -> Path:
    """A small home whose knowledge was fitted on images (colour-hog), so that views can be images:
    two experienced synthetic homes (8 sweeps), one new home (5 sweeps); about 2 s."""
    from spco.data.environment import Corpus
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.features import build_extractor

    extractor = build_extractor("colour-hog")
    corpus = generate_homes(3, seed=5, config=SyntheticConfig(n_features=extractor.n_features), new_homes=1,
                            specific_rooms=False)
    envs = list(corpus)
    knowledge = kn.fit_knowledge(Corpus(envs[:2]), n_iterations=8, random_state=0, extractor=extractor)
    home = kn.adapt(knowledge, envs[2], n_iterations=5, random_state=0)
    path = folder / "home.spco"
    home.save(path)
    return path


def copy_home(source: Path, folder: Path, name: str = "home.spco") -> Path:
    """A fresh copy of the home file ``source`` (without its lock or journal) in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / name
    shutil.copyfile(source, target)
    return target


class Server(ServeProcess):
    """A real ``spco serve`` process on a free loopback port (``python -m spco serve``, this checkout's
    spco, seed 0; :class:`spco.service.client.ServeProcess`)."""

    def __init__(self, home: Path, *args: str, timeout: float = 120.0) -> None:
        self.home = home
        try:
            super().__init__(home, "--port", "0", "--seed", "0", *args, timeout=timeout,
                             stdout=subprocess.PIPE, env=env())
        except ClientError as error:
            raise AssertionError(str(error)) from None

    def stop(self, timeout: float = 60.0) -> int:
        """Ctrl-C, and wait for the orderly stop; the exit status."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        code = self.process.wait(timeout)
        self.join()
        return code


def wait_unlocked(home: Path, timeout: float = 20.0) -> None:
    """Wait until no server holds ``home`` (a killed server's writer process exits with it)."""
    from spco.knowledge.locking import served_by

    deadline = time.monotonic() + timeout
    while served_by(home) is not None:
        if time.monotonic() > deadline:
            raise AssertionError(f"{home} is still held by {served_by(home)}")
        time.sleep(0.05)
