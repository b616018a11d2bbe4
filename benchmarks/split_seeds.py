"""The seeds of benchmarks/SPLIT.md, one definition for every benchmark script: development seeds
0–99, 200–299 and 300–399 (200–299 and 300–399 added 2026-12-07 before any run with them), held-out
100–119."""

from __future__ import annotations

import argparse
from collections.abc import Iterable

#: The seeds of each side (benchmarks/SPLIT.md).
SEEDS: dict[str, tuple[int, ...]] = {"development": (*range(0, 100), *range(200, 400)),
                                     "heldout": tuple(range(100, 120))}
#: The same, as a person reads them in an error.
SEED_TEXT = {"development": "0-99 and 200-399", "heldout": "100-119"}


def refuse_other_seeds(parser: argparse.ArgumentParser, seeds: Iterable[int],
                       side: str = "development") -> None:
    """``parser.error`` naming every seed of ``seeds`` that is not one of ``side``'s (:data:`SEEDS`)."""
    bad = [s for s in seeds if s not in SEEDS[side]]
    if bad:
        parser.error(f"--seeds {bad}: the {side} side's seeds are {SEED_TEXT[side]} (benchmarks/SPLIT.md)")
