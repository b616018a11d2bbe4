"""The "names never heard" lists of the speech sets hold only names their teaching speech never says
(a membership check of the files: nothing is fitted or scored, so held-out files may be read)."""

from __future__ import annotations

import csv
import json
import sys
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


def test_names_of_the_development_list_said_by_the_later_set_are_written_down(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """speech_dev_words.csv (written after the development list) says four of its names: the list
    writes them down (``_said_by``), and free_speech.py leaves names said by the speech it teaches out
    of the unheard score."""
    import importlib.util

    folder = BENCH / "development"
    raw = json.loads((folder / "unheard_names_dev.json").read_text("utf-8"))
    with open(folder / "speech_dev_words.csv", encoding="utf-8", newline="") as fh:
        said = [f" {normalize_name(row['sentence'])} " for row in csv.DictReader(fh)]
    names = [normalize_name(n) for place, v in raw.items() if not place.startswith("_") for n in v]
    heard = sorted(n for n in names if any(f" {n} " in sentence for sentence in said))
    assert heard == sorted(normalize_name(n) for n in raw["_said_by"]["speech_dev_words.csv"])
    spec = importlib.util.spec_from_file_location("free_speech", BENCH / "free_speech.py")
    free_speech = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    monkeypatch.setitem(sys.modules, "free_speech", free_speech)  # its dataclasses look it up there
    spec.loader.exec_module(free_speech)  # type: ignore[union-attr]
    speech = free_speech.read_speech(folder / "speech_dev_words.csv")
    unheard = free_speech.read_names(folder / "unheard_names_dev.json")
    kept, left_out = free_speech.never_heard(unheard, speech)
    assert sorted(left_out) == heard
    assert sum(map(len, kept.values())) == len(names) - len(heard)
    kept, left_out = free_speech.never_heard(unheard, free_speech.read_speech(folder / "speech_dev.csv"))
    assert left_out == [] and sum(map(len, kept.values())) == len(names)
