"""The first teaching after ``spco serve`` says it is ready: its latency over real HTTP.

Each round copies the home file afresh, starts ``spco serve`` on it (a fresh process: nothing
compiled or loaded but what start-up did), waits for the line that says it is ready, then sends
one teaching at once — alternately a sentence with a word the home never heard for a recorded
sample, and a new observation without a view at a recorded sample's pose — and times the answer
(``spco.service.client.Client``, loopback). Then a second teaching, for comparison. Prints p50/p99 over
``--rounds`` rounds. With ``--new-words`` every word is one no run asked about before, so the
lexicon's facts files lack it (WordNet is asked: it must be loaded before ready).

The home is SIGVerse 3LDK_9 adapted from the 16-home knowledge (built as in
``benchmarks/serve_latency.py``: ``--home``).

    python benchmarks/first_teaching.py --home /tmp/serve-bench/home_3LDK_9.spco --rounds 20
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import tempfile
import time
from pathlib import Path

import numpy as np

WORDS = ("quokka", "zephyr", "marimba", "tundra", "saffron", "obsidian", "lagoon", "juniper")


def one_round(
    home: Path, folder: Path, k: int, health_first: bool = False, suffix: str = ""
) -> tuple[tuple[float, float], tuple[float, float]]:
    """(first, second) teaching: (latency, the writer's own seconds) after a fresh start."""
    from spco import knowledge as kn
    from spco.service.client import Client, ServeProcess

    served = folder / "served.spco"
    for suffix in ("", ".journal", ".lock", ".undo"):
        Path(str(served) + suffix).unlink(missing_ok=True)
    shutil.copyfile(home, served)
    model = kn.load_home_model(served)
    server = ServeProcess(served, "--port", "0", "--seed", "0")
    process, url = server.process, server.url
    try:
        client = Client(url)
        if health_first:  # a request before the teaching: what is first-request cost of the HTTP stack
            client.health()
        rng = np.random.default_rng(k)
        times = []
        for n in range(2):
            row = int(rng.integers(0, model.n_samples))
            sentence = f"this is the {WORDS[(k + n) % len(WORDS)]}{suffix} room"
            start = time.perf_counter()
            if (k + n) % 2 == 0:
                answer = client.teach(id=int(model.ids[row]), sentence=sentence)
            else:
                x, y = (float(v) for v in model.positions[row, :2])
                answer = client.teach(x=x, y=y, theta=0.0, sentence=sentence)
            times.append((time.perf_counter() - start, float(answer["seconds"])))
        return times[0], times[1]
    finally:
        process.send_signal(signal.SIGINT)
        process.wait(120)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--home", type=Path, required=True)
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument(
        "--health-first",
        action="store_true",
        help="send GET /health before the first teaching (to tell the HTTP stack's first request apart)",
    )
    parser.add_argument(
        "--new-words",
        action="store_true",
        help="words no run asked about before (a suffix unique to this run and round): their facts are "
        "not in the lexicon's files, so a teaching looks them up in WordNet",
    )
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    run = f"{os.getpid():x}{int(time.time()) % 100000:x}"
    firsts, seconds, writer_firsts, writer_seconds = [], [], [], []
    with tempfile.TemporaryDirectory() as folder:
        for k in range(args.rounds):
            suffix = f"q{run}r{k}" if args.new_words else ""
            first, second = one_round(args.home.resolve(), Path(folder), k, args.health_first, suffix)
            firsts.append(first[0] * 1000)
            seconds.append(second[0] * 1000)
            writer_firsts.append(first[1] * 1000)
            writer_seconds.append(second[1] * 1000)
            print(
                f"round {k}: first {first[0] * 1000:.0f} ms (writer {first[1] * 1000:.0f}), second "
                f"{second[0] * 1000:.0f} ms (writer {second[1] * 1000:.0f})",
                flush=True,
            )
    print("| teaching after ready | n | p50 ms | p99 ms | max ms | writer's part p50 / p99 ms |")
    print("|---|---|---|---|---|---|")
    for label, values, writer in (("first", firsts, writer_firsts), ("second", seconds, writer_seconds)):
        print(
            f"| {label} | {len(values)} | {np.percentile(values, 50):.0f} | "
            f"{np.percentile(values, 99):.0f} | {max(values):.0f} | "
            f"{np.percentile(writer, 50):.0f} / {np.percentile(writer, 99):.0f} |"
        )
    print(f"load average at the end: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "first_ms": firsts,
                    "second_ms": seconds,
                    "writer_first_ms": writer_firsts,
                    "writer_second_ms": writer_seconds,
                }
            )
        )


if __name__ == "__main__":
    main()
