"""A flood of teachings of random words: does the home stay small and fast?

A served home (the service's writer, :class:`spco.service.writer.HomeWriter`, on a fresh copy of the
home file) gets ``--n`` teachings of random "words" (4–9 random letters each, 1–15 words a
sentence), half as sentences for recorded samples, half as new observations at random poses on the
map, back to back; each accepted or refused by the teaching limits (``--no-limits``: none). Then
it measures

- what was refused, by limit;
- the words the home holds of its own, and its samples;
- ``what`` (the library's, on the served snapshot) at 200 random poses: p50/p99 before and after;
- the home file's size before, and after the writer closed (compacted), with its journal and
  undo base beside it.

    python benchmarks/flood.py --home /tmp/serve-bench/home_3LDK_9.spco --n 1000
"""

from __future__ import annotations

import argparse
import json
import shutil
import string
import tempfile
import time
import warnings
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from spco import knowledge as kn


def what_ms(home: kn.HomeModel, rng: np.random.Generator, n: int = 200) -> tuple[float, float]:
    """``what`` at ``n`` random poses on the home's map: (p50, p99) in ms."""
    x0, x1, y0, y1 = kn.map_bounds(home)
    times = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kn.what(home, float(x0), float(y0), 0.0)
        for _ in range(n):
            x, y = rng.uniform(x0, x1), rng.uniform(y0, y1)
            start = time.perf_counter()
            kn.what(home, float(x), float(y), float(rng.uniform(-3, 3)))
            times.append((time.perf_counter() - start) * 1000)
    return float(np.percentile(times, 50)), float(np.percentile(times, 99))


def flood(home_file: Path, n: int, limits: kn.TeachingLimits | None, seed: int) -> dict[str, Any]:
    """The flood on a fresh copy of ``home_file`` (module docstring)."""
    from spco.knowledge.requests import Pose, Teach
    from spco.service.writer import HomeWriter

    rng = np.random.default_rng(seed)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "flood.spco"
        shutil.copyfile(home_file, path)
        size_before = path.stat().st_size
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            writer = HomeWriter(path, seed=seed, limits=limits)
            home = writer.snapshot()
            before = what_ms(home, rng)
            x0, x1, y0, y1 = kn.map_bounds(home)
            refused: Counter[str] = Counter()
            start = time.perf_counter()
            for k in range(n):
                words = [
                    "".join(rng.choice(list(string.ascii_lowercase), size=int(rng.integers(4, 10))))
                    for _ in range(int(rng.integers(1, 16)))
                ]
                sentence = " ".join(words)
                if k % 2 == 0:
                    request = Teach(sentence=sentence, id=int(home.ids[int(rng.integers(0, home.n_samples))]))
                else:
                    request = Teach(sentence=sentence,
                                    pose=Pose(float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)), 0.0))
                result = writer.handle([request])[0]
                if not result["ok"]:
                    refused[result.get("limit") or result.get("kind", "error")] += 1
            seconds = time.perf_counter() - start
            after_home = writer.snapshot()
            after = what_ms(after_home, rng)
            writer.close()
        sizes = {
            suffix or "home": Path(str(path) + suffix).stat().st_size
            for suffix in ("", ".journal", ".undo")
            if Path(str(path) + suffix).exists()
        }
    return {
        "teachings": n,
        "refused": dict(refused),
        "accepted": n - sum(refused.values()),
        "own_words": after_home.vocabulary.__len__() - after_home.n_knowledge_words,
        "samples_before": home.n_samples,
        "samples_after": after_home.n_samples,
        "what_ms_before": before,
        "what_ms_after": after,
        "file_bytes_before": size_before,
        "file_bytes_after": sizes,
        "seconds": seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--home", type=Path, required=True)
    parser.add_argument("--n", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-limits", action="store_true")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    result = flood(args.home.resolve(), args.n, None if args.no_limits else kn.DEFAULT_LIMITS, args.seed)
    print(json.dumps(result, indent=1))
    b, a = result["what_ms_before"], result["what_ms_after"]
    home_after = result["file_bytes_after"]["home"]
    print(
        "| limits | teachings | accepted | refused (by limit) | own words | samples "
        "| what p50 ms before → after | home file MB before → after (×) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    refused = ", ".join(f"{k} {v}" for k, v in result["refused"].items()) or "none"
    print(
        f"| {'none' if args.no_limits else 'default'} | {result['teachings']} | {result['accepted']} | "
        f"{refused} | "
        f"{result['own_words']} | {result['samples_before']} → {result['samples_after']} | "
        f"{b[0]:.2f} → {a[0]:.2f} | {result['file_bytes_before'] / 1e6:.2f} → {home_after / 1e6:.2f} "
        f"({home_after / result['file_bytes_before']:.2f}×) |"
    )
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
