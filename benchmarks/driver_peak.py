"""Run an ``spco`` command in this process and print its peak resident memory at exit.

The driver's own peak (``ru_maxrss`` of this process; Ray's actors and daemons are other
processes and not counted), e.g.::

    python benchmarks/driver_peak.py fit --data homes/ --engine ray --shards 2 --iterations 20 -o k.spco

prints ``DRIVER_PEAK_RSS_MB <MB> wall <s> s`` on stderr when the command ends.
"""

from __future__ import annotations

import atexit
import resource
import runpy
import sys
import time


def _report(start: float) -> None:
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # bytes on macOS, KiB elsewhere
    peak_mb = peak / 2**20 if sys.platform == "darwin" else peak / 1024
    print(f"DRIVER_PEAK_RSS_MB {peak_mb:.0f} wall {time.perf_counter() - start:.1f} s", file=sys.stderr)


if __name__ == "__main__":
    atexit.register(_report, time.perf_counter())
    sys.argv = ["spco", *sys.argv[1:]]
    runpy.run_module("spco", run_name="__main__")
