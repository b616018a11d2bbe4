"""``reserve_ros_domain`` (tests/ros_harness.py): concurrent spco test and benchmark runs on one machine
get different ROS 2 domains, so that their nodes and robots never see each other."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from ros_harness import reserve_ros_domain

TESTS = Path(__file__).resolve().parent


def _reserve_in_another_process(first: int, hold: bool = False) -> subprocess.Popen[str]:
    code = ("import sys; from ros_harness import reserve_ros_domain; "
            f"print(reserve_ros_domain(first={first}), flush=True)" + ("; sys.stdin.read()" if hold else ""))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))
    return subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True, env=env)


def test_a_process_keeps_its_domain_and_another_process_gets_another() -> None:
    mine = reserve_ros_domain()
    assert 1 <= mine <= 101 and reserve_ros_domain() == mine
    holders = []
    try:
        for _ in range(3):  # each starts its search at this process's domain, then the others' are held
            holders.append(_reserve_in_another_process(mine, hold=True))
        theirs = [int(p.stdout.readline()) for p in holders]  # type: ignore[union-attr]
        assert len({mine, *theirs}) == 4, (mine, theirs)
    finally:
        for p in holders:
            p.communicate("", timeout=30)
    # their locks went with them: a domain they held can be taken again
    again = _reserve_in_another_process(mine)
    out, _ = again.communicate(timeout=30)
    nearest = min(theirs, key=lambda d: (d - mine) % 101)  # the first after mine that was free
    assert int(out) != mine and (int(out) - mine) % 101 <= (nearest - mine) % 101, (mine, theirs, out)
