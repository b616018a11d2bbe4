"""The "names never heard" lists of the speech sets hold only names their teaching speech never says
(a membership check of the files: nothing is fitted or scored, so held-out files may be read)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from spco.data.language import normalize_name

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
SIDES = [("development", "speech_dev.csv", "unheard_names_dev.json"),
         ("heldout", "speech_heldout.csv", "unheard_names_heldout.json"),
         ("heldout/speech2", "speech.csv", "unheard_names.json")]


@pytest.mark.parametrize(("folder", "speech", "unheard"), SIDES)
def test_no_unheard_name_is_said_by_the_teaching_speech(folder: str, speech: str, unheard: str) -> None:
    with open(BENCH / folder / speech, encoding="utf-8", newline="") as fh:
        said = [f" {normalize_name(row['sentence'])} " for row in csv.DictReader(fh)]
    names = {place: list(v) for place, v in json.loads((BENCH / folder / unheard).read_text("utf-8")).items()
             if not place.startswith("_")}
    heard = [(place, name) for place, v in names.items() for name in v
             if any(f" {normalize_name(name)} " in sentence for sentence in said)]
    assert not heard, f"{unheard}: said by {speech}: {heard}"
    assert sum(len(v) for v in names.values()) > 0
