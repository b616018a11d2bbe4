"""The classes of ``benchmarks/speech_errors.py`` (where the natural-speech errors come from) on
hand-made inputs: no fit, no data set."""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from speech_errors import SAID_HERE, classify_answer, classify_miss, share_said

ACCEPTED = {"kitchen": ("kitchen",), "dining": ("dining", "dining room"), "living room": ("living room",)}
#: 10 sentences at the dining area (2 say "kitchen", 8 "table"), 10 at the kitchen (9 "kitchen")
SAID = {"dining": Counter({"": 10, "kitchen": 2, "table": 8, "dining room": 1}),
        "kitchen": Counter({"": 10, "kitchen": 9, "dining room": 3})}


def test_a_wrong_answer_is_put_in_one_class() -> None:
    assert share_said(SAID, "dining", "kitchen") == 0.2 >= SAID_HERE
    assert classify_answer("dining", "kitchen", ACCEPTED, SAID) == "b"  # another place's name said here
    assert classify_answer("dining", "living room", ACCEPTED, SAID) == "c"  # never said here
    assert classify_answer("dining", "table", ACCEPTED, SAID) == "a"  # no place's name
    assert classify_answer("living room", "livingroom", ACCEPTED, SAID) == "e"  # called so, not accepted
    # what people call another place (an owner's room, not in the accepted file) is that place's name
    with_bedroom = {**ACCEPTED, "bedroom": ("bedroom",)}
    assert classify_answer("dining", "taro's room", with_bedroom, SAID) == "c"
    assert classify_answer("dining", "livingroom", ACCEPTED, SAID) == "c"  # the living room's, by its table
    assert share_said(SAID, "bath", "bath") == 0.0  # a place nobody spoke at


def test_a_missed_where_is_put_in_one_class() -> None:
    names = np.array([True, False, True])
    assert classify_miss("dining", "dining", None, names, SAID) == "d"  # never said
    assert classify_miss("dining", "dining", 1, names, SAID) == "d"  # said, but no name of the home
    assert classify_miss("dining", "dining room", 2, names, SAID) == "b"  # said most at the kitchen
    assert classify_miss("kitchen", "kitchen", 0, names, SAID) == "c"  # said most here, found elsewhere


def test_repeated_set_options_are_all_kept() -> None:
    """``--set a --set b`` keeps both settings (with ``nargs="*"`` argparse kept only the last one, so
    ``--set target=power --set visual_prior=estimate`` silently fitted the cut sampler), and
    ``--set a b`` still works."""
    from speech_errors import _parser

    repeated = _parser().parse_args(["--set", "target=power", "--set", "visual_prior=estimate"])
    assert repeated.set == ["target=power", "visual_prior=estimate"]
    together = _parser().parse_args(["--set", "target=power", "visual_prior=estimate"])
    assert together.set == ["target=power", "visual_prior=estimate"]
    assert _parser().parse_args([]).set == []


def test_the_development_seeds_are_0_to_99_and_200_to_399() -> None:
    """benchmarks/SPLIT.md (2026-12-07 14:55 and 22:47 UTC): seeds 200–299 and 300–399 are development too;
    100–119 stay held-out and 120–199 are not used, so the natural-speech scripts refuse them."""
    from natural_speech import SIDES

    development = SIDES["development"]["seeds"]
    assert all(s in development for s in (0, 99, 200, 229, 299, 300, 399))
    assert not any(s in development for s in (100, 119, 120, 199, 400, -1))
    assert list(SIDES["heldout"]["seeds"]) == list(range(100, 120))


def test_view_in_room_answers_with_the_view_in_its_room(monkeypatch) -> None:
    """``--view-in-room`` is parsed and the scores are the robot's answers with the override
    ``AnswerSettings(view_in_room=True)`` (``evaluate_answers``; without the flag none: the model's own);
    with ``--fit-parameters`` (no rooms) it is refused."""
    import speech_errors

    from spco.model.answer_settings import AnswerSettings

    assert speech_errors._parser().parse_args(["--view-in-room"]).view_in_room
    assert not speech_errors._parser().parse_args([]).view_in_room

    class Scored(Exception):
        pass

    def spy(model, e, scored, rng, settings):
        raise Scored(settings)

    monkeypatch.setattr(speech_errors, "read_names", lambda path: {})
    monkeypatch.setattr(speech_errors, "configurations", lambda *a: (None, [("3LDK_9", None)]))
    monkeypatch.setattr(speech_errors, "fitted_runs",
                        lambda *a, **k: iter([(0, "3LDK_9", None, None, None, 1, None)]))
    monkeypatch.setattr(speech_errors, "evaluate_answers", spy)
    for flags, expected in (([], None), (["--view-in-room"], AnswerSettings(view_in_room=True))):
        monkeypatch.setattr(sys, "argv", ["speech_errors.py", "--seeds", "0", *flags])
        with pytest.raises(Scored) as scored:
            speech_errors.main()
        assert scored.value.args == (expected,)
    monkeypatch.setattr(sys, "argv", ["speech_errors.py", "--seeds", "0", "--view-in-room",
                                      "--fit-parameters"])
    with pytest.raises(SystemExit) as exit_info:
        speech_errors.main()
    assert exit_info.value.code == 2
