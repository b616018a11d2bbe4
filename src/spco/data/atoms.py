"""The atoms of a sentence: text normalised and split into words and emoji, before any vocabulary.

A sentence is normalised with Unicode NFKC and case-folded, typographic apostrophes and hyphens made
plain (:func:`normalize_text`), then split into *atoms* (:func:`found_atoms`): words of letters,
digits and combining marks joined by single apostrophes or hyphens (a hyphenated compound is one atom
written with spaces), and emoji; the rest is dropped. :data:`NO_SPACE` finds the scripts written
without spaces between words. What :mod:`spco.data.language` (the tokenizer and vocabulary) and
:mod:`spco.data.segmentation` (the words of such scripts) both read text with.
"""

from __future__ import annotations

import functools
import re
import unicodedata

__all__ = ["NO_SPACE", "LanguageWarning", "found_atoms", "normalize_text"]


class LanguageWarning(UserWarning):
    """Text that spco can learn from only in part (cut, or written without spaces)."""


_PUNCTUATION = str.maketrans({"\u2019": "'", "\u2018": "'", "\u02bc": "'", "`": "'", "\u00b4": "'",
                              "\u2010": "-", "\u2011": "-", "\u2013": "-", "\u2012": "-"})
_EMOJI_CHARS = "\u2600-\u27bf\U0001f000-\U0001faff"
_EMOJI_TAIL = "\ufe0f\U0001f3fb-\U0001f3ff"
#: Scripts usually written without spaces between words (Thai, Lao, Myanmar, Khmer, kana, Han).
NO_SPACE = re.compile("[\u0e00-\u0eff\u1000-\u109f\u1780-\u17ff\u3040-\u30ff\u3400-\u4dbf"
                      "\u4e00-\u9fff\uf900-\ufaff\uff66-\uff9f]")


def _ranges(codes: list[int]) -> str:
    out, start, prev = [], None, None
    for c in codes:
        if start is None:
            start = prev = c
        elif c == prev + 1:
            prev = c
        else:
            out.append((start, prev))
            start = prev = c
    if start is not None:
        out.append((start, prev))
    return "".join(re.escape(chr(a)) if a == b else f"{re.escape(chr(a))}-{re.escape(chr(b))}"
                   for a, b in out)


def _pattern(marks: str) -> re.Pattern[str]:
    letter = rf"(?:[^\W_]|[{marks}])" if marks else r"[^\W_]"
    word = rf"{letter}+(?:['\-]{letter}+)*"
    emoji = rf"[{_EMOJI_CHARS}][{_EMOJI_TAIL}]*(?:\u200d[{_EMOJI_CHARS}][{_EMOJI_TAIL}]*)*"
    return re.compile(f"{emoji}|{word}")


_PLAIN_ATOMS = _pattern("")


@functools.cache
def _atoms_with_marks() -> re.Pattern[str]:
    """Like ``_PLAIN_ATOMS``, with combining marks (Unicode categories M*) as letters; built on first
    need (a scan of the code points with marks, under a second)."""
    codes = [c for r in (range(0x300, 0x1E950), range(0xE0100, 0xE01F0)) for c in r
             if unicodedata.category(chr(c))[0] == "M"]
    return _pattern(_ranges(codes))


def _atom_pattern(text: str) -> re.Pattern[str]:
    if text.isascii() or not any(unicodedata.category(c)[0] == "M" for c in text):
        return _PLAIN_ATOMS
    return _atoms_with_marks()


def normalize_text(text: str) -> str:
    """NFKC, case-folded, with typographic apostrophes and hyphens made plain."""
    return unicodedata.normalize("NFKC", text).casefold().translate(_PUNCTUATION)


@functools.lru_cache(maxsize=1 << 16)
def found_atoms(sentence: str) -> tuple[str, ...]:
    """The atoms of a sentence as found, before any cut (cached: sentences and labels repeat)."""
    text = normalize_text(sentence)
    return tuple(a.replace("-", " ") for a in _atom_pattern(text).findall(text))
