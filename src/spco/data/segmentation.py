"""Words of speech written without spaces: Japanese and Chinese word segmentation.

Japanese and Chinese are written, and printed by speech recognisers, without spaces between words
(``"ここはお風呂です"``, ``"这里是厨房"``). spco cuts such text into words with a maintained segmenter
chosen for the language, and makes the cuts consistent over all sentences with a lexicon learnt
from the sentences themselves:

- Japanese: SudachiPy with its core dictionary, split mode C (the longest units: 洗面所, not
  洗面 + 所) — ``pip install 'spco[ja]'``;
- Chinese: jieba — ``pip install 'spco[zh]'``.

Both ship their dictionary inside the package (nothing is downloaded at run time).

Which text is segmented
-----------------------
:func:`resolve` decides, for the training sentences of a fit (``language``):

- ``"auto"`` (default): text in a script written without spaces is found by its Unicode script
  (:func:`script_language`: any kana → Japanese; Han characters without kana → Chinese). If at
  least half of the sentences holding such text already separate it into two or more
  space-separated runs (:func:`written_with_spaces`: ``"ここ わ といれ です"``), the spaces are the
  word boundaries and nothing is segmented; otherwise the text is segmented. Without the
  language's segmenter installed, a :class:`~spco.data.atoms.LanguageWarning` says which extra
  to install and each run stays one token (spco's behaviour before segmenters).
- ``"ja"``, ``"zh"``: segment every run of such text with that language's segmenter (an error
  naming the extra if it is not installed).
- ``"spaced"``: never segment; the words are separated by spaces.

The choice is recorded in the vocabulary (:class:`Segmentation`, written into knowledge and home
files), so ``adapt``, ``teach``, ``serve``, ``what`` and ``where`` cut text the same way as the fit.

The learnt lexicon
------------------
A segmenter knows the words of its dictionary. A name it does not know — a lab called
はぎわらけん — it cuts into dictionary words, and not always the same way: はぎ|わら|けん in one
sentence, は|ぎわ|ら|けん in ``"ここわはぎわらけんです"`` (where the recogniser printed the particle は as
わ). :meth:`Segmentation.learn` therefore learns, from the training sentences, *units* with their
counts:

1. every run of such text (between spaces and punctuation) is cut by the segmenter;
2. adjacent pieces are joined into one unit when they *always come together*: every use of the
   first is followed by the second, or every use of the second is preceded by the first, seen
   together at least :data:`TOGETHER_MIN_COUNT` times (two passes, as for terms; はぎ|わら|けん →
   はぎわらけん, お|風呂 → お風呂, but not 台所|です: 台所 is said before other words too, and です
   after many). A unit is then grown by a character that the segmenter cuts off inconsistently:
   when every use of a unit is preceded by the same character but by different pieces
   (しかわけん after に, わに and がに), the character belongs to the unit (にしかわけん); the same on
   the right;
3. the units and their counts form a unigram model, and every run is cut again by its most
   probable split (Viterbi over the segmenter's pieces and every unit of the lexicon found in the
   run; a unit costs ``−log(count / total)``, a piece outside the lexicon
   ``−log(UNKNOWN_COUNT / total)``, a single character where the segmenter made no cut that much
   and ``log 2`` more);
4. steps 2–3 are repeated :data:`LEARN_ROUNDS` times; before each cut, units that are two units
   of the lexicon side by side, each at least as frequent as the whole, are dropped (わにしかわけん
   = わ + にしかわけん: a particle the segmenter glued to a name); the lexicon is the units' counts
   in the final cut.

Multi-word terms are then learnt over these words as over any (:func:`spco.data.language.learn_terms`),
with one more condition for two words of such scripts: they must always come together in one
direction (so a name followed by です in most sentences does not become the term 台所 です, in spaced
or unspaced text alike).

The most probable split prefers units seen often: ここ|わ|はぎわらけん|です (はぎわらけん seen 5 times)
rather than ここ|わ|は|ぎわ|ら|けん|です, and わ|かいだんまえ rather than わかい|だん|ま|え. Every later
cut (a new home's sentences, a taught sentence, a name asked for) uses the same segmenter and
lexicon (:meth:`Segmentation.split`), so the same text always gives the same words. Units are
written as the text is (``"はぎわらけん"``, no spaces inside). New sentences (``adapt``, ``teach``)
add units for pieces the lexicon does not know (:meth:`Segmentation.extended`) and never change
the counts of known ones, so sentences cut before are cut the same way after.
"""

from __future__ import annotations

import functools
import importlib.metadata
import itertools
import math
import re
import threading
import warnings
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from spco.data.atoms import NO_SPACE, LanguageWarning, found_atoms
from spco.errors import ConfigurationError

__all__ = [
    "EXTRAS",
    "LEARN_ROUNDS",
    "SEGMENTERS",
    "TEXT_LANGUAGES",
    "TOGETHER_MIN_COUNT",
    "UNKNOWN_COUNT",
    "Segmentation",
    "available",
    "resolve",
    "script_language",
    "segmenter_version",
    "written_with_spaces",
]

#: Values of the ``language`` option of fits (CLI ``--text-language``).
TEXT_LANGUAGES: tuple[str, ...] = ("auto", "ja", "zh", "spaced")
#: The segmenter of each language.
SEGMENTERS: dict[str, str] = {"ja": "sudachipy", "zh": "jieba"}
#: The extra that installs each language's segmenter.
EXTRAS: dict[str, str] = {"ja": "spco[ja]", "zh": "spco[zh]"}
#: Rounds of joining and re-cutting when the lexicon is learnt.
LEARN_ROUNDS = 3
#: Pieces that always come together are joined once they are seen together this often.
TOGETHER_MIN_COUNT = 2
#: Count given to a segmenter piece outside the lexicon in the most probable split.
UNKNOWN_COUNT = 0.5
#: Extra cost (nats) of cutting a single character off where the segmenter made no cut.
_CHARACTER_PENALTY = math.log(2.0)
#: Runs remembered per :class:`Segmentation` (their cuts).
_CACHE_SIZE = 1 << 15

_KANA = re.compile("[\u3040-\u30ff\u31f0-\u31ff\uff66-\uff9f]")
_HAN = re.compile("[\u3400-\u4dbf\u4e00-\u9fff\uf900-\ufaff]")
_WORD = re.compile(r"[^\W_]")
_LOCK = threading.Lock()  # the segmenters' tokenizers are not safe to share between threads


# ------------------------------------------------------------------------------------- scripts
def _runs(sentences: Iterable[str | None]) -> list[list[str]]:
    """Per sentence, its runs of text in a script written without spaces (normalised)."""
    out = []
    for sentence in sentences:
        if sentence:
            runs = [part for atom in found_atoms(str(sentence)) if NO_SPACE.search(atom)
                    for part in atom.split(" ") if part]
            if runs:
                out.append(runs)
    return out


def script_language(sentences: Iterable[str | None]) -> str | None:
    """The language of the text written without spaces in ``sentences``, by Unicode script.

    Returns ``"ja"`` if any such text holds kana, ``"zh"`` if it holds Han characters and no kana,
    ``"other"`` for other scripts written without spaces (Thai, Lao, Khmer, Myanmar), ``None`` if
    there is no such text.
    """
    runs = [r for s in _runs(sentences) for r in s]
    if not runs:
        return None
    if any(_KANA.search(r) for r in runs):
        return "ja"
    if any(_HAN.search(r) for r in runs):
        return "zh"
    return "other"


def written_with_spaces(sentences: Iterable[str | None]) -> bool:
    """Whether text in a script written without spaces already has its words separated by spaces:
    at least half of the sentences holding such text hold two or more space-separated runs of it
    (``"ここ わ といれ です"``: yes; ``"ここわといれです"``: no). ``False`` when there is no such text."""
    per_sentence = _runs(sentences)
    if not per_sentence:
        return False
    return 2 * sum(len(runs) >= 2 for runs in per_sentence) >= len(per_sentence)


# ------------------------------------------------------------------------------------- segmenters
class _Sudachi:
    """SudachiPy with the core dictionary, split mode C."""

    def __init__(self) -> None:
        from sudachipy import Dictionary, SplitMode

        dictionary = Dictionary(dict="core")
        make = getattr(dictionary, "tokenizer", None) or dictionary.create  # create(): SudachiPy < 0.6.9
        self._tokenizer = make(mode=SplitMode.C)

    def spans(self, text: str) -> list[tuple[int, int]]:
        return [(m.begin(), m.end()) for m in self._tokenizer.tokenize(text)]


class _Jieba:
    """jieba's default dictionary, with its HMM for words not in the dictionary."""

    def __init__(self) -> None:
        import logging

        import jieba

        jieba.setLogLevel(logging.WARNING)  # it announces loading its dictionary on stderr otherwise
        self._tokenizer = jieba.Tokenizer()

    def spans(self, text: str) -> list[tuple[int, int]]:
        return [(start, end) for _, start, end in self._tokenizer.tokenize(text)]


_PACKAGES = {"ja": ("sudachipy", "sudachidict_core"), "zh": ("jieba",)}


def segmenter_version(language: str) -> str | None:
    """Version(s) of the installed segmenter of ``language`` (``"sudachipy 0.7.0, sudachidict_core
    20261015"``), or ``None`` if it is not installed."""
    try:
        return ", ".join(f"{p} {importlib.metadata.version(p)}" for p in _PACKAGES[language])
    except (importlib.metadata.PackageNotFoundError, KeyError):
        return None


def available(language: str) -> bool:
    """Whether the segmenter of ``language`` (``"ja"``, ``"zh"``) is installed."""
    return language in SEGMENTERS and segmenter_version(language) is not None


@functools.cache
def _backend(language: str) -> _Sudachi | _Jieba:
    if language not in SEGMENTERS:
        raise ConfigurationError(f"no segmenter for language {language!r}; languages: "
                                 f"{', '.join(SEGMENTERS)}")
    name = SEGMENTERS[language]
    try:
        return _Sudachi() if language == "ja" else _Jieba()
    except ImportError as exc:
        raise ConfigurationError(f"text in {'Japanese' if language == 'ja' else 'Chinese'} is segmented "
                                 f"with {name}, which is not installed ({exc}): pip install "
                                 f"'{EXTRAS[language]}'") from None
    except Exception as exc:  # a segmenter without its dictionary fails in its own way
        raise ConfigurationError(f"the {name} segmenter could not start ({type(exc).__name__}: {exc}); "
                                 f"reinstall it with pip install '{EXTRAS[language]}'") from None


def _pieces(language: str, text: str) -> list[tuple[int, int]]:
    """The segmenter's cut of ``text`` as (start, end) spans covering it without gaps."""
    backend = _backend(language)
    with _LOCK:
        spans = backend.spans(text)
    out: list[tuple[int, int]] = []
    at = 0
    for start, end in sorted(spans):
        start, end = max(start, at), min(end, len(text))
        if end <= start:
            continue
        if start > at:  # a gap (should not happen): keep it as a piece of its own
            out.append((at, start))
        out.append((start, end))
        at = end
    if at < len(text):
        out.append((at, len(text)))
    return out


# ------------------------------------------------------------------------------------- joining
def _together(streams: Sequence[list[str]], min_count: int, both: bool = False,
              only: Mapping[str, Any] | None = None) -> set[tuple[str, str]]:
    """Adjacent pairs ``a b`` seen at least ``min_count`` times where every use of ``a`` is followed
    by ``b`` or every use of ``b`` is preceded by ``a`` (with ``both``: and); with ``only``, pairs
    of units not in ``only`` (new units)."""
    uses: Counter[str] = Counter()
    pairs: Counter[tuple[str, str]] = Counter()
    for stream in streams:
        uses.update(stream)
        pairs.update(itertools.pairwise(stream))
    return {(a, b) for (a, b), k in pairs.items()
            if k >= min_count and a != b
            and ((k == uses[a] and k == uses[b]) if both else (k == uses[a] or k == uses[b]))
            and (only is None or (a not in only and b not in only))}


def _concatenate(stream: list[str], pairs: set[tuple[str, str]]) -> list[str]:
    out: list[str] = []
    i = 0
    while i < len(stream):
        if i + 1 < len(stream) and (stream[i], stream[i + 1]) in pairs:
            out.append(stream[i] + stream[i + 1])
            i += 2
        else:
            out.append(stream[i])
            i += 1
    return out


def _join_units(streams: list[list[str]]) -> list[list[str]]:
    """Two passes of the always-together rule, joining units without a space, then units grown by
    the characters the segmenter cuts off inconsistently (:func:`_extended_units`)."""
    for _ in range(2):
        pairs = _together(streams, TOGETHER_MIN_COUNT)
        if not pairs:
            break
        streams = [_concatenate(s, pairs) for s in streams]
    return _extended_units(streams)


def _extended_units(streams: list[list[str]]) -> list[list[str]]:
    """Units grown by a character the segmenter cuts off inconsistently.

    When every use of a unit (at least :data:`TOGETHER_MIN_COUNT`) is preceded by the same
    character, yet by different units (``しかわけん`` after ``に``, ``わに`` and ``がに``: the
    segmenter glued the name's first character to the particle before it), the character belongs
    to the unit (``にしかわけん``); the same on the right. Repeated until nothing changes."""
    for _ in range(8):
        changed = False
        for side in (0, 1):  # 0: the character before, 1: the character after
            seen: dict[str, tuple[set[str | None], set[str | None], int]] = {}
            for stream in streams:
                for i, unit in enumerate(stream):
                    j = i - 1 if side == 0 else i + 1
                    other = stream[j] if 0 <= j < len(stream) else None
                    char = None if other is None else (other[-1] if side == 0 else other[0])
                    chars, others, n = seen.get(unit, (set(), set(), 0))
                    seen[unit] = (chars | {char}, others | {other}, n + 1)
            grow = {u for u, (chars, others, n) in seen.items()
                    if n >= TOGETHER_MIN_COUNT and len(chars) == 1 and None not in chars and len(others) > 1}
            if not grow:
                continue
            changed = True
            out = []
            for stream in streams:
                stream = list(stream)
                for i in range(len(stream)) if side == 0 else reversed(range(len(stream))):
                    j = i - 1 if side == 0 else i + 1
                    if stream[i] in grow and 0 <= j < len(stream) and stream[j]:
                        if side == 0:
                            stream[i], stream[j] = stream[j][-1] + stream[i], stream[j][:-1]
                        else:
                            stream[i], stream[j] = stream[i] + stream[j][0], stream[j][1:]
                out.append([u for u in stream if u])
            streams = out
        if not changed:
            break
    return streams


def _pruned(counts: Counter[str]) -> Counter[str]:
    """``counts`` without the units that are two units of ``counts`` side by side, each at least as
    frequent as the whole: ``わにしかわけん`` (2) is ``わ`` (40) + ``にしかわけん`` (3), a particle
    the segmenter glued to a name, not a word of its own."""
    def composed(unit: str, count: int) -> bool:
        return any(counts.get(unit[:i], 0) >= count and counts.get(unit[i:], 0) >= count
                   for i in range(1, len(unit)))

    return Counter({u: c for u, c in counts.items() if not composed(u, c)})


# ------------------------------------------------------------------------------------- segmentation
@dataclass(frozen=True)
class Segmentation:
    """How the text of a vocabulary written without spaces is cut into words.

    Attributes
    ----------
    language: ``"ja"`` or ``"zh"``.
    segmenter: ``"sudachipy"`` or ``"jieba"`` (see :data:`SEGMENTERS`); ``None``: the text
        separates its words by spaces already, nothing is cut.
    lexicon: ``(unit, count)`` pairs, sorted: the units learnt from the training sentences and
        their counts (module docstring); empty: the segmenter's cut as it is.

    Build one with :meth:`learn` (or :func:`resolve`). Equal segmentations cut equally.
    """

    language: str
    segmenter: str | None = None
    lexicon: tuple[tuple[str, int], ...] = ()
    _counts: dict[str, int] = field(init=False, repr=False, compare=False)
    _lengths: tuple[int, ...] = field(init=False, repr=False, compare=False)
    _log_total: float = field(init=False, repr=False, compare=False)
    _cache: dict[str, tuple[str, ...]] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.language not in SEGMENTERS:
            raise ConfigurationError(f"segmentation language must be one of {', '.join(SEGMENTERS)}, got "
                                     f"{self.language!r}")
        if self.segmenter is not None and self.segmenter != SEGMENTERS[self.language]:
            raise ConfigurationError(f"the segmenter of {self.language!r} is {SEGMENTERS[self.language]!r}, "
                                     f"not {self.segmenter!r}")
        counts: dict[str, int] = {}
        for unit, count in self.lexicon:
            unit, count = str(unit), int(count)
            if not unit or count < 1 or unit in counts:
                raise ConfigurationError(f"a segmentation lexicon needs distinct, non-empty units with "
                                         f"counts >= 1; got {unit!r}: {count}")
            counts[unit] = count
        object.__setattr__(self, "lexicon", tuple(sorted(counts.items())))
        object.__setattr__(self, "_counts", counts)
        object.__setattr__(self, "_lengths", tuple(sorted({len(u) for u in counts}, reverse=True)))
        object.__setattr__(self, "_log_total", math.log(sum(counts.values()) + 1.0))
        object.__setattr__(self, "_cache", {})

    def __reduce__(self) -> tuple[Any, ...]:  # pickled without the cache
        return (Segmentation, (self.language, self.segmenter, self.lexicon))

    @property
    def segments(self) -> bool:
        """Whether text is cut (a segmenter is set)."""
        return self.segmenter is not None

    def count(self, unit: str) -> int:
        """Count of ``unit`` in the lexicon (0 if it is not there)."""
        return self._counts.get(unit, 0)

    # -------------------------------------------------------------- cutting
    def split(self, run: str) -> tuple[str, ...]:
        """The words of ``run``, a stretch of normalised text without spaces (its most probable
        split: module docstring). Without a segmenter, ``(run,)``."""
        if self.segmenter is None or not run:
            return (run,) if run else ()
        cached = self._cache.get(run)
        if cached is not None:
            return cached
        spans = _pieces(self.language, run)
        if self._counts:
            spans = self._best_split(run, spans)
        words = tuple(w for w in (run[a:b] for a, b in spans) if _WORD.search(w))
        if len(self._cache) >= _CACHE_SIZE:
            self._cache.clear()
        self._cache[run] = words
        return words

    def _cost(self, unit: str) -> float:
        count = self._counts.get(unit)
        return self._log_total - math.log(count if count else UNKNOWN_COUNT)

    def _best_split(self, run: str, pieces: list[tuple[int, int]]) -> list[tuple[int, int]]:
        """Viterbi over the segmenter's pieces and the lexicon's units found in ``run``."""
        n = len(run)
        edges: list[list[tuple[int, float]]] = [[] for _ in range(n)]
        for a, b in pieces:
            edges[a].append((b, self._cost(run[a:b])))
        for a in range(n):  # a character of its own, dearer than a piece: a unit may end inside a piece
            edges[a].append((a + 1, self._cost(run[a]) + _CHARACTER_PENALTY))
        for a in range(n):
            for length in self._lengths:
                b = a + length
                if b <= n and run[a:b] in self._counts:
                    edges[a].append((b, self._cost(run[a:b])))
        best = [math.inf] * (n + 1)
        back = [0] * (n + 1)
        best[0] = 0.0
        for a in range(n):
            if best[a] == math.inf:
                continue
            for b, cost in edges[a]:  # the segmenter's piece first: it wins ties
                if best[a] + cost < best[b] - 1e-9:
                    best[b] = best[a] + cost
                    back[b] = a
        out = []
        b = n
        while b > 0:
            out.append((back[b], b))
            b = back[b]
        return out[::-1]

    def split_atoms(self, atoms: Iterable[str]) -> list[str]:
        """``atoms`` (normalised, as :mod:`spco.data.language` finds them) with every atom in a
        script written without spaces replaced by its words (:meth:`split`)."""
        out: list[str] = []
        for atom in atoms:
            if self.segmenter is not None and NO_SPACE.search(atom):
                for part in atom.split(" "):
                    out.extend(self.split(part))
            else:
                out.append(atom)
        return out

    # -------------------------------------------------------------- learning
    @classmethod
    def learn(cls, sentences: Iterable[str | None], language: str) -> Segmentation:
        """The segmentation of ``language`` with the lexicon learnt from ``sentences`` (module
        docstring). Raises :class:`~spco.errors.ConfigurationError` if the segmenter is not
        installed."""
        segmenter = SEGMENTERS.get(language)
        if segmenter is None:
            raise ConfigurationError(f"no segmenter for language {language!r}; languages: "
                                     f"{', '.join(SEGMENTERS)}")
        _backend(language)  # fails early, naming the extra, if it is not installed
        runs = [r for s in _runs(sentences) for r in s]
        model = cls(language, segmenter)
        streams = _join_units([list(model.split(r)) for r in runs])
        for _ in range(LEARN_ROUNDS):
            model = cls(language, segmenter, tuple(_pruned(Counter(u for s in streams for u in s)).items()))
            streams = _join_units([list(model.split(r)) for r in runs])
        model = cls(language, segmenter, tuple(_pruned(Counter(u for s in streams for u in s)).items()))
        return cls(language, segmenter, tuple(Counter(u for r in runs for u in model.split(r)).items()))

    def extended(self, sentences: Iterable[str | None]) -> Segmentation:
        """This segmentation with units for what ``sentences`` say that the lexicon does not know.

        The runs are cut with this lexicon; adjacent pieces outside the lexicon that always come
        together in ``sentences`` (even once: a new name taught once) are joined into one unit;
        the new units are added with their counts. Known units keep their counts, so text cut
        before is cut the same way after (unless it held those new pieces)."""
        if self.segmenter is None:
            return self
        runs = [r for s in _runs(sentences) for r in s]
        streams = [list(self.split(r)) for r in runs]
        for _ in range(8):  # runs of new pieces said together (each pass joins pairs)
            pairs = _together(streams, 1, both=True, only=self._counts)
            if not pairs:
                break
            streams = [_concatenate(s, pairs) for s in streams]
        new = Counter(u for s in streams for u in s if u not in self._counts and _WORD.search(u))
        if not new:
            return self
        return Segmentation(self.language, self.segmenter, (*self.lexicon, *new.items()))

    # -------------------------------------------------------------- files
    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready description (``language``, ``segmenter``, ``segmenter_version``, ``lexicon``
        as ``{unit: count}``)."""
        return {"language": self.language, "segmenter": self.segmenter,
                "segmenter_version": segmenter_version(self.language) if self.segmenter else None,
                "lexicon": dict(self.lexicon)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Segmentation:
        """Read :meth:`to_dict`'s output (raises :class:`~spco.errors.ConfigurationError` if malformed)."""
        if not isinstance(data, Mapping) or "language" not in data:
            raise ConfigurationError("a segmentation must be an object with a 'language'")
        lexicon = data.get("lexicon") or {}
        if not isinstance(lexicon, Mapping):
            raise ConfigurationError("a segmentation's 'lexicon' must map units to counts")
        for count in lexicon.values():
            if isinstance(count, bool) or not isinstance(count, int):
                raise ConfigurationError(f"a segmentation's lexicon counts must be integers, got {count!r}")
        segmenter = data.get("segmenter")
        return cls(str(data["language"]), None if segmenter is None else str(segmenter),
                   tuple((str(u), c) for u, c in lexicon.items()))

    def describe(self) -> str:
        """One line for people: the language, the segmenter and the size of the lexicon."""
        name = {"ja": "Japanese", "zh": "Chinese"}[self.language]
        if self.segmenter is None:
            return f"{name}, words separated by spaces (not segmented)"
        version = segmenter_version(self.language) or f"{self.segmenter}, not installed"
        return f"{name}, segmented with {version}; {len(self.lexicon)} units learnt"


def resolve(language: str, sentences: Iterable[str | None], learn: bool = True) -> Segmentation | None:
    """The segmentation of a fit's training ``sentences`` under the ``language`` option
    (:data:`TEXT_LANGUAGES`; module docstring), or ``None`` (text separated by spaces, or in no
    script written without spaces, or no segmenter installed for it under ``"auto"``, with a
    :class:`~spco.data.atoms.LanguageWarning`).

    With ``learn`` the lexicon is learnt from ``sentences`` (:meth:`Segmentation.learn`); without,
    the segmenter's cut is used as it is.
    """
    if language not in TEXT_LANGUAGES:
        raise ConfigurationError(f"text language must be one of {', '.join(TEXT_LANGUAGES)}, got "
                                 f"{language!r}")
    texts = [s for s in sentences if s]
    script = script_language(texts)
    if language == "spaced":
        return Segmentation(script) if script in SEGMENTERS else None
    if language == "auto":
        if script is None or script == "other":
            return None
        if written_with_spaces(texts):
            return Segmentation(script)
        if not available(script):
            warnings.warn(f"the sentences are {'Japanese' if script == 'ja' else 'Chinese'} written "
                          f"without spaces, and its segmenter ({SEGMENTERS[script]}) is not installed: "
                          f"each run of text stays one token; pip install '{EXTRAS[script]}' to "
                          "segment it into words", LanguageWarning, stacklevel=3)
            return None
        language = script
    if learn:
        return Segmentation.learn(texts, language)
    _backend(language)
    return Segmentation(language, SEGMENTERS[language])
