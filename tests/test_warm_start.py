"""The warm start of a fit that learns its words with the word channels (issue 28, class c: concepts
that hold two rooms): words that can denote no place mark none
(:func:`spco.model.word_channels.warm_start_settings`).
The start is not part of either target: the chain's conditionals are those of
``tests/test_word_channels.py`` and ``tests/test_power_target.py``."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from spco.data.language import Vocabulary, normalize_name
from spco.model.name_evidence import lexical_features
from spco.model.state import SamplerSettings
from spco.model.word_channels import warm_start_settings


def test_the_warm_start_settings_leave_out_the_words_that_can_denote_no_place(wordnet) -> None:
    vocabulary = Vocabulary(["this", "is", "the", "table", "sofa", "dining table", "kitchen", "toilet",
                             "bathroom", "entrance", "genkan", "emma's room"])
    settings = SamplerSettings.create("exact", prune=True, view_counts=16.0)
    assert settings.start_not_names == ()  # as before
    out = warm_start_settings(settings, vocabulary, wordnet)
    # function words, and words WordNet knows none of whose senses is a place ("dining table" by its
    # head); a room ("toilet", "bathroom": rooms as well as fixtures), a word WordNet does not know
    # ("genkan") and a possessive are not left out
    left_out = {vocabulary.words[k] for k in out.start_not_names}
    assert left_out == {"this", "is", "the", "table", "sofa", "dining table"}
    facts = lexical_features(list(vocabulary.words), wordnet)
    for k in out.start_not_names:
        assert facts[k, 3] == 1 or (facts[k, 0] == 1 and facts[k, 2] == 0)
    assert out.view_counts == 16.0 and out.variant == "exact"  # the rest as it was
    assert warm_start_settings(settings, None).start_not_names == ()


#: The development homes' people's sentences (benchmarks/SPLIT.md, "Natural speech").
_HOMES = ("1LDK_1", "1LDK_3", "1LDK_7", "2LDK_1", "2LDK_3", "2LDK_5", "2LDK_7")


@pytest.mark.sigverse
def test_an_object_said_in_two_rooms_does_not_start_them_as_one(sigverse_dir: Path) -> None:
    """2LDK_5's people say "table", "chairs", "sofa" at both its dining space and its living room: as
    names at the start they made the two rooms one place (synonyms through the table), and the
    chain kept them in one concept (development speech, 1LDK_5 left out, seed 0 of speech_errors.py:
    19 of 20 living-room and 19 of 20 dining samples in one concept). With the objects marking no
    place they start apart and stay apart."""
    from spco.data import Corpus
    from spco.data.loading import load
    from spco.data.sigverse import read_indexed_texts
    from spco.model import SpCoTransfer

    subject = sigverse_dir.parent / "sigverse_subject"
    if not subject.is_dir():
        pytest.skip(f"people's sentences not found at {subject}")
    homes = []
    for name in _HOMES:
        env = load(sigverse_dir / name)[name]
        texts = read_indexed_texts(subject / name / "per_100", "sentence", env.n_samples, strict=False)
        homes.append(env.with_sentences([None if t else s for s, t in zip(texts, env.is_test, strict=True)]))
    corpus = Corpus(homes)
    model = SpCoTransfer(variant="exact", prune_words=True, n_iterations=3, random_state=0).fit(corpus)
    e = _HOMES.index("2LDK_5")
    taught = [label for label, test in zip(corpus[e].ground_truth.labels, corpus[e].is_test, strict=True)
              if not test]
    labels = [normalize_name(label) if label else None for label in taught]
    held = {place: Counter(int(c) for c, label in zip(model.concepts_[e], labels, strict=True)
                           if label == place) for place in ("dining", "living room")}
    shared = sum(min(held["dining"][c], held["living room"][c]) for c in held["dining"])
    # (the start before: 7 dining samples in the living room's concept of 17; now 3 of 20, seed 0)
    assert shared <= 5, held
