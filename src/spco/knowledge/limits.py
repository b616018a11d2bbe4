"""Limits of what one teaching may bring into a home, so that a home taught for months (or flooded
with nonsense) stays small and fast.

A home learns every word a person says to it: each new word is a column of θ^w and φ^w of every
concept, kept in the home file and scored by every answer. Without limits, a stream of sentences of
random words grows the vocabulary, the file and the answers' time without bound (60 teachings of
142 random words each once made 8,530 "place names" and slowed ``what`` from 1.1 to 9.3 ms).
:class:`TeachingLimits` bounds that; a teaching beyond a limit is refused whole with a
:class:`~spco.errors.TeachingLimitError` naming the limit (HTTP 422; too many observations a minute
is a :class:`~spco.errors.TeachingRateError`, HTTP 429), and nothing of it is learnt.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, fields

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError, TeachingLimitError

__all__ = ["DEFAULT_LIMITS", "TeachingLimits", "check_sentences"]


@dataclass(frozen=True)
class TeachingLimits:
    """The limits of one home's teachings (``None``: no limit of that kind).

    max_sentence_words: the words of one sentence (tokens, as the vocabulary reads it).
    max_new_words: words one teaching may add to the home's vocabulary (all its sentences together).
    max_home_words: words first heard in the home (beyond the knowledge's) the home may hold.
    max_observations_per_minute: new observations a served home takes in any 60 s (the server's
        writer counts them; a library call has no clock of its own).
    """

    max_sentence_words: int | None = 40
    max_new_words: int | None = 10
    max_home_words: int | None = 500
    max_observations_per_minute: int | None = 120

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 0):
                raise ConfigurationError(f"{f.name}: expected an integer >= 0 or None, got {value!r}")


#: The limits :func:`spco.knowledge.teach`, ``spco teach``, ``spco serve`` and ``spco ros`` apply
#: unless told otherwise.
DEFAULT_LIMITS = TeachingLimits()


def check_sentences(vocabulary: Vocabulary, n_knowledge_words: int, sentences: Iterable[str | None],
                    limits: TeachingLimits | None) -> int:
    """Raise :class:`~spco.errors.TeachingLimitError` if ``sentences`` (one teaching) break ``limits``
    for a home whose vocabulary is ``vocabulary`` (its first ``n_knowledge_words`` from the
    knowledge). Returns the number of new words they add."""
    texts = [s for s in sentences if s]
    if limits is None or not texts:
        return 0
    if limits.max_sentence_words is not None:
        for text in texts:
            n = len(vocabulary.tokenize(text))
            if n > limits.max_sentence_words:
                raise TeachingLimitError(
                    f"sentence: {n} words; a teaching's sentence may have at most "
                    f"{limits.max_sentence_words} (limit max_sentence_words; say one place at a time)",
                    "max_sentence_words", n, limits.max_sentence_words)
    added = len(vocabulary.extended(texts)) - len(vocabulary)
    if limits.max_new_words is not None and added > limits.max_new_words:
        raise TeachingLimitError(
            f"sentence: {added} words the home never heard; one teaching may bring at most "
            f"{limits.max_new_words} (limit max_new_words)", "max_new_words", added, limits.max_new_words)
    home_words = len(vocabulary) - n_knowledge_words + added
    if added and limits.max_home_words is not None and home_words > limits.max_home_words:
        raise TeachingLimitError(
            f"sentence: the home would hold {home_words} words of its own; it may hold at most "
            f"{limits.max_home_words} (limit max_home_words): teach with the names it knows, or raise "
            "the limit",
            "max_home_words", home_words, limits.max_home_words)
    return added
