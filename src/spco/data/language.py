"""Tokenizer and vocabulary: from taught sentences to bags of *tokens* (words and multi-word terms).

Normalisation (any text)
------------------------
A sentence is normalised with Unicode NFKC and case-folded (``"Ｌｉｖｉｎｇ"`` → ``"living"``,
``"STRASSE"`` and ``"Straße"`` → ``"strasse"``), typographic apostrophes and hyphens become ``'`` and
``-``, then it is split into *atoms*:

- a word: letters, digits and combining marks (so accents and scripts such as Devanagari stay whole),
  optionally joined by single apostrophes or hyphens. A hyphenated compound is one atom written with
  spaces: ``"Emma's-room"`` → ``"emma's room"``, ``"living-room"`` → ``"living room"`` (the writer
  declared it one name);
- an emoji (with its modifiers and zero-width-joiner sequences) on its own;
- punctuation and other symbols are dropped.

*Scripts written without spaces* (Chinese, Japanese, Thai, Lao, Khmer, Myanmar) are **not** cut into
single characters. A vocabulary learnt from Japanese or Chinese written without spaces cuts them into
words with a segmenter for the language (SudachiPy, jieba; the extras ``spco[ja]``, ``spco[zh]``)
and a lexicon learnt from the sentences (:mod:`spco.data.segmentation`), recorded with the
vocabulary. Without one (no segmenter installed, another script, or :func:`tokenize` called without
a segmentation), a run of such text between spaces is one atom (``"ここはリビングです"`` is one
token) and :class:`LanguageWarning` says so.

*Over-long input* is cut, with a :class:`LanguageWarning`: an atom longer than
:data:`MAX_TOKEN_CHARS` characters keeps its first :data:`MAX_TOKEN_CHARS`, a sentence of more than
:data:`MAX_SENTENCE_TOKENS` atoms keeps its first :data:`MAX_SENTENCE_TOKENS`. Nothing already learnt
is touched (a cut sentence is still learnt from, just shorter).

Terms (multi-word names)
------------------------
People say "living room", "front door", "emma's room": names of several words.
:meth:`Vocabulary.from_sentences` learns such *terms* from the training sentences themselves, with no
list of names (:func:`learn_terms`): two adjacent atoms ``a b`` become the term ``"a b"`` when

1. they occur together at least ``min_count`` (3) times;
2. Dunning's log-likelihood ratio G² of the 2 × 2 table (``a`` first or not × ``b`` second or not,
   over all adjacent pairs) is at least ``min_g2`` = 10.83 (p < 0.001, one degree of freedom) and
   they occur together more often than chance;
3. ``a`` is followed by ``b`` in at least ``min_follow`` = 50 % of its occurrences ("living" is
   almost always followed by "room"; "the" is followed by many words, "kitchen" often ends the
   sentence);
4. neither atom is a *frame word*: one that occurs in more than ``max_sentence_share`` = 50 % of the
   sentences ("this", "is", "the" in "this is the kitchen"). Names are specific to a place, so none
   is in half of all sentences;
4b. the term is a noun phrase without its determiner: no closed-class word or number starts it,
   ends it or comes at a join ("wash your hands" is none, nor "my room": the parent calls the
   child's "my room" "your room"); inside one atom they stay ("walk-in closet", rule 7's "mum and
   dad's"), and a possessive *noun* opens a term ("emma's room");
5. for two words of a script written without spaces (Japanese, Chinese), they *always* come
   together on one side: every use of ``a`` is followed by ``b``, or every use of ``b`` is
   preceded by ``a``. There a name is followed by particles and copulas (台所 です, キッチン だ よ)
   that no frame rule catches — each style of speech is in fewer than half of the sentences — so a
   name followed by です in most sentences stays the name ``台所``.

Where two candidate pairs overlap in a sentence ("in emma's" and "emma's room" in "we are in emma's
room now"), the pair with the larger G² is joined there (best first, left to right among equals),
and a pair becomes a term only if it is joined at least ``min_count`` times: a word is joined with
the neighbour it belongs to, so a frame never swallows the first word of a name.

:meth:`Vocabulary.from_sentences` counts each distinct sentence once: a sentence said again word for
word is one use of its word pairs, so a phrase of one sentence repeated many times ("big bedroom",
when "bedroom" is also said alone) does not become a term. One exception keeps the terms of a
speaker who says one sentence per place ("this is the living room" each time, as a robot's teacher
may): two words that are *never said apart* — every use of ``a`` followed by ``b``, every use of
``b`` preceded by ``a``, neither a frame word — are a term when said at least ``min_count`` times
counting repeats. Joining them changes nothing about where they are said (their counts are the
same), and keeps the place from being answered as "living" or "room".

6. **Compounds the lexicon knows** (:func:`lexicon_compounds`): a pair whose compound is a noun of
   WordNet, written with a space or as one word ("dining room", "dining table", "bath room" as
   "bathroom", "bath tub" as "bathtub"), needs rules 1, 2 and 4 only, not 3: a modifier said with
   several heads ("dining" with "table", "room", "space") is followed by none of them in half of
   its uses, yet each compound is one name or one object. Without the lexicon (no NLTK or WordNet,
   :mod:`spco.data.lexicon`) only rules 1–5 apply.

7. **A coordinated possessive is one atom** before pairs are counted (:func:`_coordinated`: "mum",
   "and", "dad's" -> "mum and dad's"), so "mum and dad's room" comes out whole, as "dad's room" would
   (pair by pair it cannot: neither "mum and" nor "and dad's" may be a term).

A second pass over the sentences with the learnt pairs joined finds longer terms ("walk in closet").
The rule also joins set phrases that are not names ("this is", "welcome to" when people say them in
fewer than half of the sentences): they are tokens like any other, spread over all places, and the
model's own rule keeps them from being answered as names.

The interface for the rest of spco
----------------------------------
A *token* is a string; a term is one token whose words are separated by single spaces
(``"living room"``). :meth:`Vocabulary.tokenize` turns a sentence into tokens: at every atom it
takes the longest run of atoms (up to :data:`MAX_TERM_WORDS` words) whose words, joined by spaces, are
a token of the vocabulary. The vocabulary's multi-word tokens therefore *are* its term list: it
travels with the vocabulary (in knowledge and model files) and every command tokenises the same way.
So ``"Living Room"``, ``"living-room"`` and ``"living room"`` are all the token ``"living room"``.
Column ``k`` of every word-count matrix is ``vocabulary.words[k]``; each occurrence of a token counts
``word_increment`` (S^w, 5000 by default, as in the paper).
"""

from __future__ import annotations

import functools
import itertools
import math
import re
import warnings
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from spco.data.atoms import NO_SPACE, LanguageWarning, found_atoms, normalize_text
from spco.data.function_words import NAME_LEADING_WORDS, NAME_OPENERS, is_function_word
from spco.data.segmentation import Segmentation, resolve
from spco.errors import ConfigurationError


def _may_start_name(word: str) -> bool:
    """Whether a name may start with ``word``: not a function word, but a possessive ("my room")."""
    return word in NAME_OPENERS or not is_function_word(word)


def _joinable(a: str, b: str) -> bool:
    """Whether ``a b`` may be a learnt term: no closed-class word or number starts it, ends it or
    comes at the join (rule 4b of the module docstring: "wash your hands", "my room" are none)."""
    return not any(map(is_function_word, (a.split()[0], b.split()[0], b.split()[-1])))


#: Default count added per word occurrence (S^w in the paper).
DEFAULT_WORD_INCREMENT = 5000
#: Longest atom kept whole (characters); longer ones are cut, with a warning.
MAX_TOKEN_CHARS = 100
#: Most atoms kept of one sentence; the rest is cut, with a warning.
MAX_SENTENCE_TOKENS = 200
#: Longest term, in words.
MAX_TERM_WORDS = 4

#: Term learning: minimum count, G² threshold (p < 0.001, 1 d.o.f.), minimum share of the first
#: atom's occurrences followed by the second, maximum share of sentences holding either atom.
TERM_MIN_COUNT = 3
TERM_MIN_G2 = 10.83
TERM_MIN_FOLLOW = 0.5
TERM_MAX_SENTENCE_SHARE = 0.5


def _cut(atoms: Sequence[str]) -> tuple[tuple[str, ...], bool, bool]:
    """Atoms with over-long words and sentences cut, and whether a word, the sentence was cut."""
    long_word = any(len(a) > MAX_TOKEN_CHARS for a in atoms)
    if long_word:
        atoms = [a[:MAX_TOKEN_CHARS].rstrip("' ") if len(a) > MAX_TOKEN_CHARS else a for a in atoms]
    return tuple(atoms[:MAX_SENTENCE_TOKENS]), long_word, len(atoms) > MAX_SENTENCE_TOKENS


@functools.lru_cache(maxsize=1 << 16)
def _atoms(sentence: str) -> tuple[tuple[str, ...], bool, bool, bool]:
    """Atoms of a sentence, and whether a word was cut, text without spaces was seen, the sentence was
    cut (cached; the warnings are issued by :func:`tokenize`)."""
    found = found_atoms(sentence)
    no_space = any(len(a) > 1 and NO_SPACE.search(a) for a in found)
    atoms, long_word, long_sentence = _cut(found)
    return atoms, long_word, no_space, long_sentence


def tokenize(sentence: str | None, segmentation: Segmentation | None = None) -> list[str]:
    """Split a sentence into atoms: normalised words, hyphenated compounds and emoji (no learnt terms).

    ``"This is Emma's-room!"`` → ``["this", "is", "emma's room"]``: a hyphenated compound is one atom
    whose words are separated by spaces. ``None`` or an empty string gives an empty list. See the
    module docstring for scripts without spaces and over-long input (cut, with a
    :class:`LanguageWarning`). With a ``segmentation``
    (:class:`~spco.data.segmentation.Segmentation`), text in a script written without spaces is cut
    into its words. Use :meth:`Vocabulary.tokenize` to also join learnt terms.
    """
    if not sentence:
        return []
    if segmentation is None:
        atoms, long_word, no_space, long_sentence = _atoms(str(sentence))
    else:
        atoms, long_word, long_sentence = _cut(segmentation.split_atoms(found_atoms(str(sentence))))
        no_space = False
    if long_word:
        warnings.warn(f"a word longer than {MAX_TOKEN_CHARS} characters was cut to its first "
                      f"{MAX_TOKEN_CHARS} (spco.data.language.MAX_TOKEN_CHARS)", LanguageWarning,
                      stacklevel=2)
    if no_space:
        warnings.warn("text in a script written without spaces (Chinese, Japanese, Thai, …) is kept as one "
                      "token per space-separated chunk, not cut into characters; for Japanese or Chinese "
                      "install a segmenter (pip install 'spco[ja]' or 'spco[zh]'; spco fit uses it), or "
                      "separate the words by spaces", LanguageWarning, stacklevel=2)
    if long_sentence:
        warnings.warn(f"a sentence of more than {MAX_SENTENCE_TOKENS} words was cut to its first "
                      f"{MAX_SENTENCE_TOKENS} (spco.data.language.MAX_SENTENCE_TOKENS)", LanguageWarning,
                      stacklevel=2)
    return list(atoms)


_SPACE_IN_NO_SPACE = re.compile(f"(?<={NO_SPACE.pattern}) (?={NO_SPACE.pattern})")


def normalize_name(name: str) -> str:
    """A place name as a token without learnt terms: its atoms joined by single spaces
    (``"Emma's-room"``, ``"EMMA'S ROOM"`` → ``"emma's room"``), except between two characters of a
    script written without spaces (``"エマ の 部屋"`` → ``"エマの部屋"``, however the words were cut).
    No warning is issued (a name is a name)."""
    return _SPACE_IN_NO_SPACE.sub("", " ".join(_atoms(str(name))[0])) if name else ""


# ------------------------------------------------------------------------------------- terms
def _g2(k11: int, k12: int, k21: int, k22: int) -> float:
    """Dunning's log-likelihood ratio G² of a 2 × 2 contingency table."""
    n = k11 + k12 + k21 + k22
    rows, cols = (k11 + k12, k21 + k22), (k11 + k21, k12 + k22)
    total = 0.0
    for k, r, c in ((k11, rows[0], cols[0]), (k12, rows[0], cols[1]),
                    (k21, rows[1], cols[0]), (k22, rows[1], cols[1])):
        if k > 0:
            total += k * math.log(k * n / (r * c))
    return 2.0 * total


@dataclass
class _PairCounts:
    """Counts of adjacent word pairs in a list of sentences (word lists), for the term rules."""

    pairs: Counter[tuple[str, str]]  # (a, b) -> times said next to each other
    first: Counter[str]  # a -> times a word pair starts with a
    second: Counter[str]  # b -> times a word pair ends with b
    in_sentences: Counter[str]  # word -> sentences holding it
    occurrences: Counter[str]  # word -> times said
    n_sentences: int

    @classmethod
    def of(cls, sentences: list[list[str]]) -> _PairCounts:
        counts = cls(Counter(), Counter(), Counter(), Counter(), Counter(), len(sentences))
        for atoms in sentences:
            counts.in_sentences.update(set(atoms))
            counts.occurrences.update(atoms)
            for a, b in itertools.pairwise(atoms):
                counts.pairs[(a, b)] += 1
                counts.first[a] += 1
                counts.second[b] += 1
        return counts


def _term_pass(counts: _PairCounts, min_count: int, min_g2: float, min_follow: float,
               max_sentence_share: float) -> dict[tuple[str, str], float]:
    """The candidate pairs of one pass and their G² (the rule of the module docstring)."""
    pairs, first, second = counts.pairs, counts.first, counts.second
    in_sentences, occurrences = counts.in_sentences, counts.occurrences
    n_pairs = sum(pairs.values())
    frame = max_sentence_share * counts.n_sentences
    out: dict[tuple[str, str], float] = {}
    for (a, b), k11 in pairs.items():
        if k11 < min_count or a == b or in_sentences[a] > frame or in_sentences[b] > frame:
            continue
        if not _joinable(a, b):
            continue
        if k11 / occurrences[a] < min_follow:
            continue
        if k11 < occurrences[a] and k11 < occurrences[b] and NO_SPACE.search(a) and NO_SPACE.search(b):
            continue  # in Japanese, Chinese: only words that always come together (not "台所 です")
        k12, k21 = first[a] - k11, second[b] - k11
        k22 = n_pairs - k11 - k12 - k21
        if k11 * n_pairs <= first[a] * second[b]:  # not more often than chance
            continue
        score = _g2(k11, k12, k21, k22)
        if score >= min_g2:
            out[(a, b)] = score
    return out


def lexicon_compounds(pairs: Iterable[tuple[str, str]]) -> set[tuple[str, str]]:
    """The pairs of single words whose compound is a WordNet noun, written with a space ("dining
    room") or as one word ("bath room" as "bathroom"): rule 6 of the module docstring. Empty when
    the lexicon is unavailable (:func:`spco.data.word_facts.word_facts`)."""
    asked = [(a, b) for a, b in pairs if " " not in a and " " not in b and a.isalpha() and b.isalpha()]
    if not asked:
        return set()
    from spco.data.word_facts import word_facts

    facts = word_facts(sorted({f for a, b in asked for f in (f"{a} {b}", f"{a}{b}")}))
    if facts is None:
        return set()

    def noun(text: str) -> bool:
        fact = facts[text]
        return fact.known and not math.isnan(fact.noun_share) and fact.noun_share > 0

    return {(a, b) for a, b in asked if noun(f"{a} {b}") or noun(f"{a}{b}")}


def _lexicon_pass(counts: _PairCounts, min_count: int, min_g2: float, max_sentence_share: float,
                  found: Mapping[tuple[str, str], float]) -> dict[tuple[str, str], float]:
    """The pairs rule 6 adds to a pass's ``found`` ones: compounds the lexicon knows, said together
    at least ``min_count`` times, more often than chance, G² ≥ ``min_g2``, no frame word (rule 3,
    the share of ``a`` followed by ``b``, is not asked)."""
    pairs, first, second = counts.pairs, counts.first, counts.second
    n_pairs = sum(pairs.values())
    frame = max_sentence_share * counts.n_sentences
    candidates = [(a, b) for (a, b), k11 in pairs.items()
                  if (a, b) not in found and k11 >= min_count and a != b and counts.in_sentences[a] <= frame
                  and counts.in_sentences[b] <= frame and _joinable(a, b) and not NO_SPACE.search(a + b)
                  and k11 * n_pairs > first[a] * second[b]]
    out: dict[tuple[str, str], float] = {}
    for a, b in lexicon_compounds(candidates):
        k11 = pairs[(a, b)]
        score = _g2(k11, first[a] - k11, second[b] - k11, n_pairs - first[a] - second[b] + k11)
        if score >= min_g2:
            out[(a, b)] = score
    return out


def _join(atoms: list[str], pairs: Mapping[tuple[str, str], float],
          joined: Counter[tuple[str, str]] | None = None) -> list[str]:
    """``atoms`` with the candidate ``pairs`` (pair -> G²) joined, the strongest first where two
    overlap (equal scores: the leftmost first); ``joined`` (optional) counts the pairs joined."""
    found = [(pairs[(a, b)], -i) for i, (a, b) in enumerate(itertools.pairwise(atoms)) if (a, b) in pairs]
    starts: set[int] = set()
    used: set[int] = set()
    for _, neg in sorted(found, reverse=True):
        i = -neg
        if i not in used and i + 1 not in used:
            starts.add(i)
            used.update((i, i + 1))
    out: list[str] = []
    i = 0
    while i < len(atoms):
        if i in starts:
            out.append(f"{atoms[i]} {atoms[i + 1]}")
            if joined is not None:
                joined[(atoms[i], atoms[i + 1])] += 1
            i += 2
        else:
            out.append(atoms[i])
            i += 1
    return out


def learn_terms(
    sentences: Iterable[str | None],
    min_count: int = TERM_MIN_COUNT,
    min_g2: float = TERM_MIN_G2,
    min_follow: float = TERM_MIN_FOLLOW,
    max_sentence_share: float = TERM_MAX_SENTENCE_SHARE,
    passes: int = 2,
    segmentation: Segmentation | None = None,
    distinct: bool = False,
    lexicon: bool = True,
) -> list[str]:
    """The multi-word terms of ``sentences`` (the rule of the module docstring), sorted.

    Hyphenated compounds of the text are terms already (one atom each) and are not listed unless a
    pass joins them with a neighbour. Each pass joins the pairs it finds (left to right) before the
    next pass looks for longer terms; terms longer than :data:`MAX_TERM_WORDS` words are not formed.
    Text written without spaces is cut into words by ``segmentation`` first.

    With ``distinct`` the rule counts each distinct sentence once, and a pair whose two words are
    never said apart (every use of ``a`` followed by ``b``, every use of ``b`` preceded by ``a``;
    neither a frame word) is a term when it is said at least ``min_count`` times counting repeats
    (as :meth:`Vocabulary.from_sentences` learns; the module docstring).
    """
    streams = [_coordinated(tokenize(s, segmentation)) for s in sentences if s]
    streams = [s for s in streams if s]
    uses = [1] * len(streams)
    if distinct:  # each distinct sentence once, with how often it was said
        said = Counter(tuple(s) for s in streams)
        streams, uses = [list(s) for s in said], list(said.values())
    terms: set[str] = set()
    for _ in range(passes):
        counts = _PairCounts.of(streams)
        pairs = {(a, b): score for (a, b), score in
                 _term_pass(counts, min_count, min_g2, min_follow, max_sentence_share).items()
                 if len(a.split()) + len(b.split()) <= MAX_TERM_WORDS}
        if lexicon:
            pairs.update(_lexicon_pass(counts, min_count, min_g2, max_sentence_share, pairs))
        together = {} if not distinct else {
            pair: score for pair, score in _never_apart(counts, max_sentence_share).items()
            if pair not in pairs and len(pair[0].split()) + len(pair[1].split()) <= MAX_TERM_WORDS}
        if not pairs and not together:
            break
        joined: Counter[tuple[str, str]] = Counter()
        joined_said: Counter[tuple[str, str]] = Counter()  # counting repeats
        joined_here: Counter[tuple[str, str]] = Counter()
        out = []
        for stream, n in zip(streams, uses, strict=True):
            joined_here.clear()
            out.append(_join(stream, {**pairs, **together}, joined_here))
            joined.update(joined_here)
            joined_said.update({pair: k * n for pair, k in joined_here.items()})
        streams = out
        terms |= {f"{a} {b}" for (a, b), n in joined.items() if (a, b) in pairs and n >= min_count}
        terms |= {f"{a} {b}" for (a, b), n in joined_said.items() if (a, b) in together and n >= min_count}
    return sorted(terms)


def _coordinated(atoms: list[str]) -> list[str]:
    """``atoms`` with each coordinated possessive joined into one atom ("mum", "and", "dad's" ->
    "mum and dad's"), so that "mum and dad's room" can be a term as "dad's room" is (a term is
    otherwise joined pair by pair, and neither "mum and" nor "and dad's" may be one)."""
    out: list[str] = []
    i = 0
    while i < len(atoms):
        if (i + 2 < len(atoms) and atoms[i + 1] == "and" and atoms[i + 2].endswith(("'s", "s'"))
                and len(atoms[i + 2]) > 2 and " " not in atoms[i] + atoms[i + 2]
                and not is_function_word(atoms[i]) and not is_function_word(atoms[i + 2])):
            out.append(f"{atoms[i]} and {atoms[i + 2]}")
            i += 3
        else:
            out.append(atoms[i])
            i += 1
    return out


def _never_apart(counts: _PairCounts, max_sentence_share: float) -> dict[tuple[str, str], float]:
    """Adjacent pairs whose words are never said apart in the counted sentences (every use of ``a``
    is followed by ``b`` and every use of ``b`` preceded by ``a``), neither a frame word; -> G²."""
    pairs, first, second = counts.pairs, counts.first, counts.second
    in_sentences, occurrences = counts.in_sentences, counts.occurrences
    n_pairs = sum(pairs.values())
    frame = max_sentence_share * counts.n_sentences
    return {(a, b): _g2(k11, first[a] - k11, second[b] - k11, n_pairs - first[a] - second[b] + k11)
            for (a, b), k11 in pairs.items()
            if a != b and k11 == occurrences[a] == occurrences[b] and in_sentences[a] <= frame
            and in_sentences[b] <= frame and _joinable(a, b)}


def _canonical(word: str) -> str:
    return " ".join(normalize_text(word).replace("-", " ").split())


# ------------------------------------------------------------------------------------- vocabulary
@dataclass(frozen=True)
class Vocabulary:
    """An ordered set of tokens; token ``k`` is column ``k`` of every word-count matrix.

    A token of several words (``"living room"``) is a term: :meth:`tokenize` joins those words into
    it wherever they appear in a sentence. Words are stored in canonical form (NFKC, case-folded,
    hyphens as spaces: a vocabulary written by an older spco with ``"living-room"`` reads as
    ``"living room"``).

    Build one with :meth:`from_sentences`. Tokens unknown to the vocabulary are ignored by
    :meth:`encode` (and reported by :meth:`unknown_words`), never an error: at prediction time the
    robot may hear a word it has never learnt.

    ``segmentation`` (:class:`~spco.data.segmentation.Segmentation`, or ``None``): how text in a
    script written without spaces (Japanese, Chinese) is cut into words; it travels with the
    vocabulary, so every command cuts such text the same way.
    """

    words: tuple[str, ...]
    segmentation: Segmentation | None = None
    _index: dict[str, int] = field(init=False, repr=False, compare=False)
    _longest: int = field(init=False, repr=False, compare=False)
    _holders: dict[str, tuple[int, ...]] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        words = tuple(_canonical(str(w)) for w in self.words)
        index = {word: k for k, word in enumerate(words)}
        if len(index) != len(words):
            raise ConfigurationError("a vocabulary cannot hold the same word twice")
        if any(not w for w in words):
            raise ConfigurationError("a vocabulary cannot hold an empty word")
        object.__setattr__(self, "words", words)
        object.__setattr__(self, "_index", index)
        object.__setattr__(self, "_longest", min(MAX_TERM_WORDS, max((len(w.split()) for w in words),
                                                                     default=1)))

    @classmethod
    def from_sentences(cls, sentences: Iterable[str | None], learn: bool = True,
                       language: str = "auto") -> Vocabulary:
        """The vocabulary of all tokens in ``sentences``, in order of first appearance.

        With ``learn`` (the default) the multi-word terms of :func:`learn_terms` are learnt first, so
        ``"living room"`` said often enough is one token; without, the tokens are the atoms.
        ``language`` (``"auto"``, ``"ja"``, ``"zh"``, ``"spaced"``) says whether text written
        without spaces is segmented into words, and how (:func:`spco.data.segmentation.resolve`;
        ``"auto"`` decides from the text itself).
        """
        texts = [s for s in sentences if s]
        segmentation = resolve(language, texts, learn=learn)
        # terms from the distinct sentences: a sentence said again word for word is one use of its
        # word pairs, not many ("big bedroom" said 60 times is no term; "living room" in many
        # different sentences is, and so is "living room" of "this is the living room" said again
        # and again when "living" and "room" are never said apart)
        base = cls(tuple(learn_terms(texts, segmentation=segmentation, distinct=True)), segmentation) \
            if learn else cls((), segmentation)
        seen: dict[str, None] = {}
        for sentence in texts:
            for word in base.tokenize(sentence):
                seen.setdefault(word, None)
        return cls(tuple(seen), segmentation)

    def __len__(self) -> int:
        return len(self.words)

    def __contains__(self, word: object) -> bool:
        return isinstance(word, str) and word in self._index

    def terms_holding(self, words: str) -> tuple[int, ...]:
        """Columns of the terms holding ``words`` side by side, in vocabulary order, ``words`` included
        ("dining" → "dining room", "dining space"); the terms' runs of words are indexed once."""
        if not hasattr(self, "_holders"):
            holders: dict[str, tuple[int, ...]] = {}
            for k, p in ((k, w.split()) for k, w in enumerate(self.words) if " " in w):
                for run in {" ".join(p[i:j]) for j in range(len(p) + 1) for i in range(j)}:
                    holders[run] = (*holders.get(run, ()), k)
            object.__setattr__(self, "_holders", holders)
        return self._holders.get(" ".join(words.split()), ())

    @property
    def terms(self) -> tuple[str, ...]:
        """The multi-word tokens (terms), in vocabulary order."""
        return tuple(w for w in self.words if " " in w)

    def tokenize(self, sentence: str | None) -> list[str]:
        """Tokens of ``sentence``: its atoms (:func:`tokenize`), with every run of words that forms a
        multi-word token of this vocabulary joined into that token (longest run first); text written
        without spaces is cut into words by the vocabulary's segmentation first."""
        atoms = tokenize(sentence, self.segmentation)
        if self._longest < 2 or len(atoms) < 2:
            return atoms
        words = [a.split() for a in atoms]
        out: list[str] = []
        i = 0
        while i < len(atoms):
            taken = None
            n_words = 0
            for j in range(i, len(atoms)):  # candidate spans end at atom boundaries
                n_words += len(words[j])
                if n_words > self._longest:
                    break
                if j > i:
                    joined = " ".join(atoms[i:j + 1])
                    if joined in self._index:
                        taken = (joined, j + 1)
            if taken is None:
                out.append(atoms[i])
                i += 1
            else:
                out.append(taken[0])
                i = taken[1]
        return out

    def index(self, word: str) -> int | None:
        """Column of ``word`` (a name, normalised and tokenised like a sentence), or ``None`` if it is
        unknown or does not form a single token."""
        tokens = self.tokenize(word)
        return self._index.get(tokens[0]) if len(tokens) == 1 else None

    def query(self, name: str) -> tuple[list[str], list[int]]:
        """The tokens of a name asked for, and the columns of those that are known.

        ``"Living Room"`` → ``(["living room"], [k])`` when the term is known; ``"study room"`` →
        ``(["study", "room"], [k_study, k_room])`` when only the words are (also for
        ``"study-room"``: an unknown compound is split into its words). A leading article or
        possessive pronoun (:data:`NAME_LEADING_WORDS`) is not part of the name: ``"the kids'
        bedroom"`` → ``(["kids bedroom"], [k])`` ("the" alone stays).
        """
        tokens: list[str] = []
        said = self.tokenize(name)
        if len(said) > 1 and said[0] in NAME_LEADING_WORDS:  # "the kids' bedroom" asks for "kids bedroom"
            said = said[1:]
        for token in said:
            if token in self._index or " " not in token:
                tokens.append(token)
            else:  # an unknown hyphenated compound ("study-room"): its words
                tokens += self.tokenize(token)
        if tokens and not any(t in self._index for t in tokens):
            # no token known: the name may be part of a longer term ("grandma's room" of the term
            # "grandma's room okay", learnt from one sentence): the shortest term holding its words
            if holding := self.terms_holding(" ".join(tokens)):
                best = min(holding, key=lambda k: (len(self.words[k].split()), k))
                return [self.words[best]], [best]
        return tokens, [self._index[t] for t in tokens if t in self._index]

    def unknown_words(self, sentence: str | None) -> list[str]:
        """Tokens of ``sentence`` that are not in the vocabulary."""
        return [w for w in self.tokenize(sentence) if w not in self._index]

    def extended(self, sentences: Iterable[str | None], learn: bool = True) -> Vocabulary:
        """A vocabulary with the new tokens of ``sentences`` appended (existing columns kept).

        The known terms apply. With ``learn``, terms learnt from ``sentences`` alone
        (:func:`learn_terms`) are added too, but only those holding a word this vocabulary does not
        know ("study room" said often in a new home, when "study" is new): a term made of known
        tokens would take their occurrences away from the columns that carry what was learnt
        before. So sentences tokenised before are tokenised the same way after.
        """
        texts = [s for s in sentences if s]
        grown = self
        if learn and self.segmentation is not None:  # units for the new text written without spaces
            grown = Vocabulary(self.words, self.segmentation.extended(texts))
        elif learn and not any(NO_SPACE.search(w) for w in self.words):
            # the first text of such a script: as a fit would
            found = resolve("auto", texts)
            if found is not None:
                grown = Vocabulary(self.words, found)
        segmentation = grown.segmentation
        base = grown
        if learn:
            new_terms = tuple(t for t in learn_terms(texts, segmentation=segmentation) if t not in self._index
                              and any(tok not in self._index for tok in grown.tokenize(t)))
            new_terms += tuple(t for t in grown.new_word_runs(texts) if t not in new_terms)
            if new_terms:
                base = Vocabulary((*self.words, *new_terms), segmentation)
        words = dict.fromkeys(self.words)
        for sentence in texts:
            for word in base.tokenize(sentence):
                words.setdefault(word, None)
        return Vocabulary(tuple(words), segmentation)

    def new_word_runs(self, sentences: Iterable[str | None]) -> list[str]:
        """Names of several new words said together, taught even once: runs of two to
        :data:`MAX_TERM_WORDS` adjacent tokens that this vocabulary does not know and that are
        never said apart in ``sentences`` (every use of each of their words is inside the run).

        "this is the study room", the first sentence with "study" and "room", gives the term
        ``"study room"`` at once — too few uses for :func:`learn_terms`' counts, but a name of
        several words said once is one name, and its words alone ("room") would be answered as
        names. A word also said elsewhere ("study" in "the study is here") keeps the run from
        forming; known tokens never join one, so columns learnt before keep their occurrences.
        A name neither starts with a function word, but a possessive ("my room": a name taught once
        is kept as it was said, where :func:`learn_terms` leaves the possessive pronoun out), nor ends
        with one: a run is cut to the words between, so "we call it mum and dad's room", all new
        words, gives ``"mum and dad's room"``, and "i cook" is no run.
        """
        streams = [self.tokenize(s) for s in sentences if s]
        uses: dict[str, int] = {}
        for stream in streams:
            for token in stream:
                uses[token] = uses.get(token, 0) + 1
        runs: dict[tuple[str, ...], int] = {}
        for stream in streams:
            i = 0
            while i < len(stream):
                j = i
                while j < len(stream) and stream[j] not in self._index:
                    j += 1
                a, b = i, j  # the run without its leading and trailing function words
                while a < b and not _may_start_name(stream[a]):
                    a += 1
                while b > a and is_function_word(stream[b - 1]):  # never ends a name ("front of")
                    b -= 1
                if b - a >= 2 and sum(len(w.split()) for w in stream[a:b]) <= MAX_TERM_WORDS:
                    run = tuple(stream[a:b])
                    runs[run] = runs.get(run, 0) + 1
                i = max(j, i + 1)
        inside: dict[str, int] = {}
        for run, count in runs.items():
            for token in run:
                inside[token] = inside.get(token, 0) + count
        return [" ".join(run) for run in runs if all(inside[w] == uses[w] for w in run)
                and len(set(run)) == len(run)]

    def encode(
        self, sentences: Sequence[str | None], word_increment: int = DEFAULT_WORD_INCREMENT
    ) -> sp.csr_array:
        """Bag-of-tokens counts, shape ``(len(sentences), len(self))``, int64.

        Each occurrence of a known token adds ``word_increment``; unknown tokens and ``None``
        sentences contribute nothing.
        """
        if word_increment < 1:
            raise ConfigurationError(f"word_increment must be a positive integer, got {word_increment}")
        rows: list[int] = []
        cols: list[int] = []
        for row, sentence in enumerate(sentences):
            for word in self.tokenize(sentence):
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
