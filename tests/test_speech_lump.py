"""benchmarks/speech_lump.py: the new home's clustering read from a fit (issue 29 diagnostic)."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from speech_lump import new_home_clusters


def _fit(concepts: list[int], homes: list[int]) -> SimpleNamespace:
    """A stand-in for a fitted model: only what the diagnostic reads."""
    return SimpleNamespace(state_=SimpleNamespace(concepts=np.asarray(concepts)),
                           data_=SimpleNamespace(homes=np.asarray(homes), n_homes=max(homes) + 1))


def _env(labels: list[str], is_test: list[bool]) -> SimpleNamespace:
    return SimpleNamespace(ground_truth=SimpleNamespace(labels=labels), is_test=is_test)


def test_reads_only_the_new_homes_labelled_training_samples() -> None:
    # home 0's samples (concepts 5) are not the new home's; the test sample and the "None" one are left out
    env = _env(["a", "a", "b", "b", "None", "c"], [False, False, False, False, False, True])
    fit = _fit([5, 5, 0, 0, 1, 1, 9], [0, 0, 1, 1, 1, 1, 1])
    out = new_home_clusters(fit, env)
    assert out == {"ari": 1.0, "concepts_used": 2, "places": 2}


def test_a_lump_scores_zero_and_counts_one_concept() -> None:
    env = _env(["a", "a", "b", "b"], [False] * 4)
    out = new_home_clusters(_fit([3, 3, 3, 3], [0, 0, 0, 0]), env)
    assert out["ari"] == 0.0 and out["concepts_used"] == 1 and out["places"] == 2


def test_a_count_mismatch_is_refused() -> None:
    with pytest.raises(SystemExit, match="labels"):
        new_home_clusters(_fit([0, 1], [0, 0]), _env(["a", "b", "c"], [False] * 3))
