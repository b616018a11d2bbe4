"""The file cache of WordNet's word facts (spco.data.lexicon.word_facts): the same numbers as the
lexicon, read without loading WordNet once known, rewritten when missing or of another format."""

from __future__ import annotations

import json

import numpy as np
import pytest

from spco.data import lexicon as lexicon_module
from spco.model.name_evidence import lexical_features

WORDS = ["kitchen", "emma's room", "room", "the", "genkan", "sofa", "living room", "greet"]


@pytest.fixture()
def empty_cache(tmp_path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("SPCO_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(lexicon_module, "_facts_memory", {})
    return tmp_path


def test_cached_features_equal_the_lexicon_s_and_need_no_wordnet_once_known(
        wordnet, empty_cache, monkeypatch: pytest.MonkeyPatch) -> None:
    direct = lexical_features(WORDS, wordnet)
    first = lexical_features(WORDS)  # computes and writes the file
    np.testing.assert_array_equal(first, direct)
    files = list(empty_cache.glob("wordnet-facts-*.json"))
    assert len(files) == 1 and json.loads(files[0].read_text())["format"] == 1

    def no_wordnet(folder: str):
        raise AssertionError("WordNet loaded although every word's facts are in the file")

    monkeypatch.setattr(lexicon_module, "_load", no_wordnet)
    monkeypatch.setattr(lexicon_module, "_facts_memory", {})  # a new process: from the file alone
    np.testing.assert_array_equal(lexical_features(WORDS), direct)


def test_a_file_of_another_format_or_broken_is_computed_again(wordnet, empty_cache) -> None:
    lexical_features(["kitchen"])
    path = next(empty_cache.glob("wordnet-facts-*.json"))
    for text in ('{"format": 999, "words": {"kitchen": [false, null, null]}}', "not json"):
        path.write_text(text)
        lexicon_module._facts_memory.clear()
        facts = lexicon_module.word_facts(["kitchen"])
        assert facts is not None and facts["kitchen"].known and facts["kitchen"].place_share >= 0.99
        assert json.loads(path.read_text())["format"] == 1


def test_no_facts_without_the_lexicon(monkeypatch: pytest.MonkeyPatch, empty_cache) -> None:
    monkeypatch.setenv("SPCO_WORDNET", "off")
    assert lexicon_module.word_facts(["kitchen"]) is None
    features = lexical_features(["kitchen", "the"])
    assert features[0].tolist() == [0.0, 0.5, 0.0, 0.0] and features[1, 3] == 1.0
