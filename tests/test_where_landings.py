"""``benchmarks/where_landings.py``'s split of the words' start (``--start-part``) on hand-made settings:
no fit, no data set."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import where_landings

import spco.model.transfer as transfer
from spco.model.state import SamplerSettings


def _words_start(start, hyper, evidence, vocabulary, word_increment, lexicon=None):
    """A stand-in for the words' start: both of its parts set; ``hyper`` None stands for the names' start."""
    if hyper is None:
        return start
    return replace(start, word_weight=0.25, start_not_names=(3, 7))


@pytest.mark.parametrize(("part", "weight", "objects"), [("weight", 0.25, ()), ("objects", 1.0, (3, 7))])
def test_a_start_part_keeps_only_its_part(monkeypatch, part, weight, objects) -> None:
    monkeypatch.setattr(transfer, "warm_start_settings", _words_start)
    start = SamplerSettings.create("exact", True)
    assert start.word_weight == 1.0 and start.start_not_names == ()
    out = where_landings.only_part(part)(start, "words", None, None, 1)
    assert out.word_weight == weight and out.start_not_names == objects
    assert where_landings.only_part(part)(start, None, None, None, 1) is start  # the names' start: as it is
