"""Tokenizer and vocabulary: from taught sentences to bags of words.

A sentence such as ``"This is Emma's room!"`` is lower-cased, stripped of punctuation and split into
words; a word may hold inner apostrophes and hyphens, so possessive and hyphenated place names stay
whole (``"emma's-room"``, ``"living-room"``). The vocabulary is built from the training sentences
themselves, never from a fixed word list. Each occurrence of a word counts ``word_increment``
(S^w, 5000 by default, as in the paper).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from spco.errors import ConfigurationError

#: Default count added per word occurrence (S^w in the paper).
DEFAULT_WORD_INCREMENT = 5000

# A word: letters/digits, optionally joined by single apostrophes or hyphens ("emma's-room").
_WORD = re.compile(r"[^\W_]+(?:['\-][^\W_]+)*")
_APOSTROPHES = str.maketrans({"\u2019": "'", "\u2018": "'", "\u02bc": "'", "`": "'",
                              "\u2010": "-", "\u2011": "-", "\u2013": "-"})


def tokenize(sentence: str | None) -> list[str]:
    """Split a sentence into lower-case words.

    Punctuation is dropped; apostrophes and hyphens inside a word are kept, so ``"Emma's-room"`` is
    one word ``"emma's-room"``. Typographic apostrophes are normalised to ``'``. ``None`` or an
    empty string gives an empty list.
    """
    if not sentence:
        return []
    return _WORD.findall(sentence.translate(_APOSTROPHES).lower())


def normalize_name(name: str) -> str:
    """Normalise a place name the way the tokenizer normalises words (``"Emma's-room"`` →
    ``"emma's-room"``); a name of several words is joined with hyphens."""
    return "-".join(tokenize(name))


@dataclass(frozen=True)
class Vocabulary:
    """An ordered set of words; word ``k`` is column ``k`` of every word-count matrix.

    Build one with :meth:`from_sentences`. Words unknown to the vocabulary are ignored by
    :meth:`encode` (and reported by :meth:`unknown_words`), never an error: at prediction time the
    robot may hear a word it has never learnt.
    """

    words: tuple[str, ...]
    _index: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        index = {word: k for k, word in enumerate(self.words)}
        if len(index) != len(self.words):
            raise ConfigurationError("a vocabulary cannot hold the same word twice")
        object.__setattr__(self, "_index", index)

    @classmethod
    def from_sentences(cls, sentences: Iterable[str | None]) -> Vocabulary:
        """The vocabulary of all words in ``sentences``, in order of first appearance."""
        seen: dict[str, None] = {}
        for sentence in sentences:
            for word in tokenize(sentence):
                seen.setdefault(word, None)
        return cls(tuple(seen))

    def __len__(self) -> int:
        return len(self.words)

    def __contains__(self, word: object) -> bool:
        return isinstance(word, str) and word in self._index

    def index(self, word: str) -> int | None:
        """Column of ``word`` (normalised like the tokenizer), or ``None`` if it is unknown."""
        return self._index.get(normalize_name(word))

    def unknown_words(self, sentence: str | None) -> list[str]:
        """Words of ``sentence`` that are not in the vocabulary."""
        return [w for w in tokenize(sentence) if w not in self._index]

    def extended(self, sentences: Iterable[str | None]) -> Vocabulary:
        """A vocabulary with the new words of ``sentences`` appended (existing columns kept)."""
        words = dict.fromkeys(self.words)
        for sentence in sentences:
            for word in tokenize(sentence):
                words.setdefault(word, None)
        return Vocabulary(tuple(words))

    def encode(
        self, sentences: Sequence[str | None], word_increment: int = DEFAULT_WORD_INCREMENT
    ) -> sp.csr_array:
        """Bag-of-words counts, shape ``(len(sentences), len(self))``, int64.

        Each occurrence of a known word adds ``word_increment``; unknown words and ``None``
        sentences contribute nothing.
        """
        if word_increment < 1:
            raise ConfigurationError(f"word_increment must be a positive integer, got {word_increment}")
        rows: list[int] = []
        cols: list[int] = []
        for row, sentence in enumerate(sentences):
            for word in tokenize(sentence):
                col = self._index.get(word)
                if col is not None:
                    rows.append(row)
                    cols.append(col)
        data = np.full(len(rows), word_increment, dtype=np.int64)
        counts = sp.coo_array(
            (data, (np.asarray(rows, dtype=np.int64), np.asarray(cols, dtype=np.int64))),
            shape=(len(sentences), len(self.words)),
        )
        out = counts.tocsr()
        out.sum_duplicates()
        return out
