"""CPU time of ``where`` in one process (``time.process_time``, so a shared machine's load inflates it
less than wall-clock latency): per call on a home already asked (every name in turn, ``--rounds``
times, two measurements), and the first call after loading the home file (what each new home
version — a teaching, an undo — pays once: the answer's parameters and the rooms' evidence; min and
median of ``--loads``).

    PYTHONPATH=src python benchmarks/where_cpu.py HOME.spco [HOME.spco ...] [--rounds 20] [--loads 5]

Compare two versions of the code in the same minutes by running this script with ``PYTHONPATH`` at
each (e.g. a ``git archive`` of the older commit).
"""

from __future__ import annotations

import argparse
import statistics
import time


def main() -> None:
    """Print one line per home: warm CPU per call (two measurements) and the first call's."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("homes", nargs="+")
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--loads", type=int, default=5)
    args = parser.parse_args()

    from spco import knowledge as kn

    for path in args.homes:
        home = kn.load_home_model(path)
        names = home.known_names
        kn.where(home, names[0])
        warm = []
        for _ in range(2):
            start = time.process_time()
            for _ in range(args.rounds):
                for name in names:
                    kn.where(home, name, n=10, random_state=0)
            warm.append(1000 * (time.process_time() - start) / (args.rounds * len(names)))
        first = []
        for _ in range(args.loads):
            fresh = kn.load_home_model(path)
            start = time.process_time()
            kn.where(fresh, names[0], n=10, random_state=0)
            first.append(1000 * (time.process_time() - start))
        print(f"{path}: {len(names)} names; where per call {warm[0]:.2f} / {warm[1]:.2f} ms CPU; first call "
              f"after loading {min(first):.1f} ms (median {statistics.median(first):.1f})")


if __name__ == "__main__":
    main()
