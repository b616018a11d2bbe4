"""Tokenizer and vocabulary: examples and properties."""

from __future__ import annotations

from collections import Counter
from itertools import pairwise

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spco.data.language import Vocabulary, normalize_name, tokenize
from spco.errors import ConfigurationError

WORDS = ["kitchen", "emma's-room", "living-room", "this", "is", "the", "bath", "father's", "ダイニング"]


def test_examples() -> None:
    assert tokenize("This is Emma's-room!") == ["this", "is", "emma's-room"]
    assert tokenize("Emma’s room, the LIVING-ROOM.") == ["emma's", "room", "the", "living-room"]
    assert tokenize("kitchen – bath -- 'quoted' toilet's") == ["kitchen", "bath", "quoted", "toilet's"]
    assert tokenize("snake_case x2") == ["snake", "case", "x2"]
    assert tokenize(None) == [] and tokenize("") == [] and tokenize(" ,.! ") == []
    assert normalize_name("Emma's Room") == "emma's-room"


@settings(max_examples=300)
@given(st.text(max_size=80))
def test_tokens_are_clean_words(sentence: str) -> None:
    for token in tokenize(sentence):
        assert token and token == token.lower()
        assert not any(ch.isspace() for ch in token)
        assert all(ch.isalnum() or ch in "'-" for ch in token)
        assert token[0] not in "'-" and token[-1] not in "'-"
        assert not any(a in "'-" and b in "'-" for a, b in pairwise(token))


@settings(max_examples=300)
@given(st.text(max_size=80))
def test_tokenize_is_idempotent(sentence: str) -> None:
    tokens = tokenize(sentence)
    assert tokenize(" ".join(tokens)) == tokens


@given(st.lists(st.sampled_from(WORDS), max_size=12), st.sampled_from([" ", "  ", "\t", ", ", "! "]))
def test_possessive_and_hyphenated_names_stay_whole(words: list[str], sep: str) -> None:
    sentence = sep.join(w.upper() if i % 2 else w for i, w in enumerate(words))
    assert tokenize(sentence) == words


sentences = st.lists(st.one_of(st.none(), st.lists(st.sampled_from([*WORDS, "unknown", "zebra"]),
                                                   max_size=10).map(" ".join)), max_size=8)


@given(sentences, st.lists(st.sampled_from(WORDS), unique=True), st.integers(1, 10_000))
def test_encode_counts_increment_times_occurrences(texts: list[str | None], vocab_words: list[str],
                                                   increment: int) -> None:
    vocab = Vocabulary(tuple(vocab_words))
    counts = vocab.encode(texts, increment)
    assert counts.shape == (len(texts), len(vocab_words)) and counts.dtype == np.int64
    dense = counts.toarray()
    for row, text in enumerate(texts):
        occurrences = Counter(tokenize(text))
        expected = [increment * occurrences[w] for w in vocab_words]
        assert dense[row].tolist() == expected  # unknown words contribute nothing
        assert vocab.unknown_words(text) == [w for w in tokenize(text) if w not in vocab_words]


@given(sentences)
def test_vocabulary_from_sentences_in_order_of_first_appearance(texts: list[str | None]) -> None:
    vocab = Vocabulary.from_sentences(texts)
    expected = list(dict.fromkeys(w for t in texts for w in tokenize(t)))
    assert list(vocab.words) == expected
    assert all(vocab.index(w) == k for k, w in enumerate(expected))
    extended = vocab.extended(["a brand-new word"])
    assert extended.words[: len(vocab)] == vocab.words and "brand-new" in extended


def test_vocabulary_errors() -> None:
    with pytest.raises(ConfigurationError):
        Vocabulary(("a", "a"))
    with pytest.raises(ConfigurationError):
        Vocabulary(("a",)).encode(["a"], 0)
