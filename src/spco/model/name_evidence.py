"""Which words are names: linguistic evidence beside the regions (docs/model.md, "What counts as a name").

The naming rule (:func:`spco.model.pruning.judge_names`) tells a word said at one place from a word
said everywhere. It cannot tell a place's name from another word said consistently at that place:
"home" in "hi, I'm home!" at the entrance, "table" at the dining area, "towel" in the bath, "sleep"
in the bedroom, "left" in "the bathroom is to your left". Those words are as place-bound as the
name, often more (a place's name is split over its synonyms, the greeting is not). What tells them
apart is how they are said and what they are:

- **Where in the sentence** (:func:`frame_features`, shares over the word's uses): a name heads the
  noun phrase that names the place — after a determiner or a possessive ("this is *the* kitchen",
  "*my* room", "*Emma's* room"; a term holding its own possessive, "emma's room", counts as said after
  one: :func:`holds_determiner`), in a naming frame ("this is X", "X is here", "we call it X", "X"
  said alone) — while objects and directions come after prepositions ("*on the* table", "to *the*
  left"), greetings and activities after pronouns or verbs ("I'm home", "I sleep here").
- **What the word is** (:func:`lexical_features`, WordNet through :mod:`spco.data.lexicon`): the
  share of its senses that are nouns, and the share of its physical noun senses (those that can be
  pointed at: a word said of a place names something there, not an act or a report) that are
  places (rooms, areas, passages, structures, locations) rather than furniture, objects or people. A term
  unknown to WordNet ("emma's room", "kids bedroom") is judged by its head word ("room",
  "bedroom"); a word WordNet does not know at all (typos, loanwords such as "genkan") is neutral.

The two are combined by a logistic model, P(name | features) = σ(b + w·f), whose weights
(:data:`WEIGHTS`) were fitted by ``benchmarks/name_evidence.py`` on development data only (the
tokens of the development speech set, the hand-written SIGVerse sentences, the free-form synthetic
homes of seeds 0–1 and the SIGVerse templates, labelled by their accepted names). It is *soft*
evidence: :func:`name_prior` gives each vocabulary word P(name | how it was said) in (0, 1). By
default it decides which known words may stand for a name nobody said
(:func:`spco.model.unheard.resolve_name`). Only with the opt-in ``name_prior="wordnet"``
(:class:`~spco.model.hyperparameters.TransferHyperparameters`,
:func:`spco.model.prediction.predict_names`) does prediction reorder each concept's words by it
(:func:`within_concepts`); it is off by default because on the held-out speech set a place whose
only name is weak evidence ("dining") lost the views of a concept it shared with "kitchen".

Without the lexicon (no NLTK or no WordNet database) the lexical features take their "unknown word"
values, so the prior rests on the sentence frames alone.

The frames use English function words (:mod:`spco.data.function_words`: determiners, prepositions,
copulas, pronouns): grammar, not names. In another language none of them occurs and every word gets
the same frame features: the prior then only scales all words alike (and the lexicon, English
WordNet, knows none of the words either).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from spco.data.function_words import (
    CLOSED_CLASS,
    COPULAS,
    DETERMINERS,
    NAME_OPENERS,
    PREPOSITIONS,
    PRONOUNS,
    is_function_word,
)
from spco.data.language import Vocabulary

__all__ = [
    "FEATURES",
    "WEIGHTS",
    "channel_evidence",
    "content_share",
    "feature_matrix",
    "frame_features",
    "has_english",
    "holds_determiner",
    "lexical_features",
    "name_prior",
    "within_concepts",
]

# The English function-word lists: :mod:`spco.data.function_words` (the tokeniser's term rule reads
# them too).
#: Words after a name in "X is here", "X here", "X's here".
AFTER_NAME = frozenset({"is", "are", "here", "'s"})

#: The features, in the order of :data:`WEIGHTS` (all in [0, 1]).
FEATURES = ("determiner", "naming_frame", "preposition", "pronoun", "sentence_start", "alone",
            "known", "noun_share", "place_share", "function_word", "spelling_variant")

#: Intercept and weights of the logistic model (fitted by ``benchmarks/name_evidence.py --subject
#: …/sigverse_subject --terms-from distinct`` on development data only — the development homes of
#: people's sentences among its corpora — L2 penalty 1; see docs/model.md).
WEIGHTS: tuple[float, ...] = (-4.407, 1.831, 1.452, -0.334, -0.472, 0.399, 0.749, -1.278, 1.068, 2.947,
                               -1.484, -3.702)


def content_share(words: Sequence[str]) -> np.ndarray:
    """(V,) the share of each vocabulary entry's words that are content words (not
    :func:`is_function_word`): 1 for "wash basin", 0.5 for "front of", 0 for "you are in"."""
    out = np.empty(len(words))
    for k, word in enumerate(words):
        parts = word.split() or [word]
        out[k] = sum(not is_function_word(p) for p in parts) / len(parts)
    return out


def _possessive(token: str) -> bool:
    return token.endswith("'s") or token.endswith("s'")


def holds_determiner(token: str) -> bool:
    """Whether a term carries its own determiner: a possessive before its head ("emma's room", "mum
    and dad's room", "kids' room") or a possessive pronoun first ("my room", "our bedroom"). The
    term is then a noun phrase already determined, as "room" is in "emma's room" said as two
    tokens: :func:`frame_features` reads it as said after a determiner, wherever it is said."""
    words = token.split()
    return len(words) >= 2 and (words[0] in NAME_OPENERS or any(_possessive(w) for w in words[:-1]))


def frame_features(vocabulary: Vocabulary, sentences: Iterable[str | None]) -> np.ndarray:
    """Where each vocabulary word is said in ``sentences``: (V, 6) shares of its uses that come
    after a determiner or possessive, in a naming frame, after a preposition (possibly with a
    determiner between), after a pronoun, at the start of the sentence, and alone (the sentence is
    the word, possibly after a determiner). A word never said has all shares 0.

    Parameters
    ----------
    vocabulary: the corpus vocabulary (tokens as :meth:`Vocabulary.tokenize` gives them).
    sentences: the taught sentences (``None`` entries are skipped).

    Returns
    -------
    (V, 6) float64 in [0, 1].
    """
    n_words = len(vocabulary)
    sums = np.zeros((n_words, 6))
    uses = np.zeros(n_words)
    for sentence in sentences:
        if sentence is None:
            continue
        tokens = vocabulary.tokenize(sentence)
        for i, token in enumerate(tokens):
            k = vocabulary.index(token)
            if k is None:
                continue
            prev = tokens[i - 1] if i >= 1 else ""
            prev2 = tokens[i - 2] if i >= 2 else ""
            after = tokens[i + 1] if i + 1 < len(tokens) else ""
            det_before = prev in DETERMINERS or _possessive(prev)
            det = det_before or holds_determiner(token)  # "the X", "emma's X", or "emma's room" itself
            before_det = prev2 if det_before else prev
            frame = (before_det in COPULAS or (det_before and prev2 == "") or after in AFTER_NAME
                     or after == "")
            prep = before_det in PREPOSITIONS
            pron = prev in PRONOUNS
            alone = len(tokens) == 1 or (len(tokens) == 2 and i == 1 and det_before)
            sums[k] += (det, frame and not prep, prep, pron, i == 0 or (i == 1 and det_before), alone)
            uses[k] += 1
    return sums / np.maximum(uses, 1.0)[:, None]


def lexical_features(words: Sequence[str], lexicon: object | None = None) -> np.ndarray:
    """What each word is, from WordNet: (V, 5) = known (1: WordNet knows the word, or one of its
    :func:`spelling_variants`, or for a term its head word, tried in that order), share of noun
    senses, share of physical noun senses that are places (:meth:`spco.data.lexicon.Lexicon.place_share`),
    function word (one of spco's English
    function-word lists), spelling variant (1: the facts are those of a word one
    edit away, "kicthen", "bathrooom": a misspelt name is where the name is, but not the name to
    answer; a compound written as one or in two, "bed room", "livingroom", is not a misspelling).
    Unknown words: (0, 0.5, 0, function word, 0).

    ``lexicon``: a :class:`spco.data.lexicon.Lexicon` (default: :func:`spco.data.lexicon.lexicon`,
    which may be None: then every word is unknown to it)."""
    out = np.zeros((len(words), 5))
    out[:, 1] = 0.5
    asked: list[int] = []
    for k, word in enumerate(words):
        out[k, 3] = float(" " not in word and (word in DETERMINERS or word in PREPOSITIONS
                                               or word in COPULAS or word in PRONOUNS))
        if not out[k, 3] and not word.endswith("'s"):
            asked.append(k)
    facts = _lookup([words[k] for k in asked], lexicon)
    if facts is None:
        return out
    # the words WordNet does not know: their other spellings, then a term's head word
    unknown = [k for k in asked if not facts[words[k]].known]
    others = {k: [c for c in (*spelling_variants(words[k], words), *words[k].split()[1:][-1:])
                  if not c.endswith("'s")] for k in unknown}
    more = _lookup(sorted({c for cs in others.values() for c in cs} - set(facts)), lexicon)
    facts.update(more or {})
    for k in asked:
        for candidate in (words[k], *others.get(k, ())):
            fact = facts[candidate]
            if fact.known:
                out[k, :4] = (1.0, fact.noun_share, 0.0 if np.isnan(fact.place_share) else fact.place_share,
                              0.0)
                # a misspelling (not the word, its head, or the word written as one or in two)
                out[k, 4] = float(candidate.replace(" ", "") != words[k].replace(" ", "")
                                  and candidate not in words[k].split()[1:][-1:])
                break
    return out


def _lookup(texts: Sequence[str], lexicon: object | None) -> dict | None:
    """:class:`spco.data.word_facts.WordFacts` of ``texts``: from ``lexicon``, or the process's WordNet
    through the cache of word facts (no NLTK if all known); None without a lexicon."""
    if lexicon is None:
        from spco.data.word_facts import word_facts

        return word_facts(list(texts))
    return {c: _facts_of(lexicon, c) for c in texts}


#: Shortest word whose misspellings are looked for (:func:`spelling_variants`): shorter words are
#: one letter from too many others ("bed", "bad", "bid").
MIN_VARIANT_CHARS = 5


def _one_edit(a: str, b: str) -> bool:
    """Whether ``a`` and ``b`` differ by one deletion, insertion, substitution or transposition of
    adjacent letters (Damerau–Levenshtein distance 1)."""
    if a == b or abs(len(a) - len(b)) > 1:
        return False
    if len(a) > len(b):
        a, b = b, a
    if len(a) < len(b):  # one insertion into a
        return any(b[:i] + b[i + 1:] == a for i in range(len(b)))
    diff = [i for i in range(len(a)) if a[i] != b[i]]
    return len(diff) == 1 or (len(diff) == 2 and diff[1] == diff[0] + 1
                              and a[diff[0]] == b[diff[1]] and a[diff[1]] == b[diff[0]])


def spelling_variants(word: str, vocabulary: Sequence[str] = ()) -> list[str]:
    """Other spellings of ``word`` whose WordNet facts stand for its own when WordNet does not know it
    (what :func:`lexical_features` asks after the word itself, before a term's head word): the word
    written as one ("bath room" → "bathroom", "bed room" → "bedroom") or, for one word, split in two
    ("livingroom" → "living room") or with a doubled letter single ("bathrooom" → "bathroom"); and
    the words of ``vocabulary`` one edit apart (:func:`_one_edit`: "toiket" → "toilet", "dinning room"
    → "dining room"), for words of :data:`MIN_VARIANT_CHARS` letters or more.
    No list of words: WordNet decides which variant is a word (:func:`lexical_features` takes the
    first it knows)."""
    out: list[str] = []
    compact = word.replace(" ", "")
    if " " in word:
        out.append(compact)
    elif word.isalpha():
        out += [f"{word[:i]} {word[i:]}" for i in range(3, len(word) - 2)]
        out += [word[:i] + word[i + 1:] for i in range(1, len(word)) if word[i] == word[i - 1]]
    if len(compact) >= MIN_VARIANT_CHARS:
        out += [v for v in vocabulary if v != word and len(v.replace(" ", "")) >= MIN_VARIANT_CHARS
                and v.count(" ") == word.count(" ") and _one_edit(v, word)]
    return list(dict.fromkeys(out))


def _facts_of(lexicon: object, word: str):
    """:class:`spco.data.word_facts.WordFacts` of ``word`` from a lexicon object."""
    from spco.data.word_facts import WordFacts

    known = bool(lexicon.knows(word))  # type: ignore[attr-defined]
    return WordFacts(known, lexicon.noun_share(word) if known else float("nan"),  # type: ignore[attr-defined]
                     lexicon.place_share(word) if known else float("nan"))  # type: ignore[attr-defined]


def feature_matrix(vocabulary: Vocabulary, sentences: Iterable[str | None],
                   lexicon: object | None = None) -> np.ndarray:
    """(V, len(FEATURES)): :func:`frame_features` beside :func:`lexical_features`."""
    return np.hstack([frame_features(vocabulary, sentences), lexical_features(vocabulary.words, lexicon)])


def name_prior(vocabulary: Vocabulary, sentences: Iterable[str | None], lexicon: object | None = None,
               weights: Sequence[float] = WEIGHTS) -> np.ndarray:
    """P(name | how the word is said and what it is) for every vocabulary word: (V,) in (0, 1).

    Parameters
    ----------
    vocabulary, sentences: as :func:`frame_features`.
    lexicon: as :func:`lexical_features`.
    weights: intercept, then one weight per feature of :data:`FEATURES`.
    """
    features = feature_matrix(vocabulary, sentences, lexicon)
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (features.shape[1] + 1,):
        raise ValueError(f"expected {features.shape[1] + 1} weights, got {w.shape}")
    return 1.0 / (1.0 + np.exp(-(w[0] + features @ w[1:])))


#: A word with at least this many kinds under one of its two commonest noun senses in WordNet is
#: the name of a kind of place, not of one place ("room" 195, "area" 91, "house" 59, "place" 55;
#: "entrance" 16, "bed" 23, "bedroom" 11, "toilet" 7, "kitchen" 4). Not whether the word is the
#: WordNet hypernym of other place words said: a household's names for one place are often a
#: word and its WordNet kinds ("toilet" and "bathroom", whose WordNet sense toilet.n.01 is the
#: hypernym of "loo", "restroom" and "washroom"; "bedroom" and "master bedroom"), and that test took
#: those names for kinds of place.
KINDS_BELOW = 50
#: The factor of a kind word's name evidence in the word channels' prior.
KIND_FACTOR = 0.1


def channel_evidence(vocabulary: Vocabulary, sentences: Iterable[str | None],
                     lexicon: object | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The evidence of the word channels' switch prior (:mod:`spco.model.word_channels`): (ν, a), each
    (V,). ν: :func:`name_prior`, times :data:`KIND_FACTOR` for a place word with :data:`KINDS_BELOW`
    kinds or more under a commonest sense in WordNet ("room", "place", "area");
    a: :func:`content_share`. A word without any evidence (unknown to WordNet and never said in a
    sentence holding an English function word: text in another language) gets ν = a = 0.5."""
    sentences = list(sentences)
    features = feature_matrix(vocabulary, sentences, lexicon)
    w = np.asarray(WEIGHTS, dtype=np.float64)
    nu = 1.0 / (1.0 + np.exp(-(w[0] + features @ w[1:])))
    words = list(vocabulary.words)
    place = features[:, FEATURES.index("place_share")] > 0
    candidates = [words[k] for k in np.flatnonzero(place)]
    if lexicon is None:  # the process's WordNet, through the cache of kind facts (no NLTK if all known)
        from spco.data.word_facts import kind_facts

        kinds = kind_facts(candidates)
        if kinds is not None:
            for k in np.flatnonzero(place):
                if kinds[words[k]].kinds_below >= KINDS_BELOW:
                    nu[k] *= KIND_FACTOR
    else:
        for k in np.flatnonzero(place):
            if lexicon.kinds_below(words[k]) >= KINDS_BELOW:  # type: ignore[attr-defined]
                nu[k] *= KIND_FACTOR
    content = content_share(words)
    # a word with no evidence at all — unknown to WordNet, never said in a sentence with an English
    # function word, not one itself (text in another language: Japanese particles and names alike) —
    # gets the neutral prior: name, place or background as its uses say, not "no name" (σ of the
    # intercept, 0.006)
    english = np.zeros(len(words), dtype=bool)  # said in a sentence holding an English function word
    for sentence in sentences:
        if sentence is None:
            continue
        tokens = vocabulary.tokenize(sentence)
        if any(t in CLOSED_CLASS for t in tokens):
            english[[k for k in map(vocabulary.index, tokens) if k is not None]] = True
    silent = (features[:, FEATURES.index("known")] == 0) & ~english & (content == 1.0)
    nu[silent], content[silent] = 0.5, 0.5
    return nu, content


def has_english(vocabulary: Vocabulary, sentences: Iterable[str | None]) -> bool:
    """Whether any of ``sentences`` holds an English function word (:data:`CLOSED_CLASS`): the
    evidence of the word channels is English; speech without any is learnt with the naming rule."""
    return any(any(t in CLOSED_CLASS for t in vocabulary.tokenize(s)) for s in sentences if s)


def within_concepts(weighted: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """Reorder each concept's words by the name prior without moving weight between concepts.

    ``weighted`` (L, V) ≥ 0: each concept's word scores (θ^w_{e,l,w} · I(w) in prediction);
    ``prior`` (V,): :func:`name_prior`. Row l becomes ``weighted[l] · prior`` rescaled to the sum
    of ``weighted[l]``: the words of one place compete by how name-like they are ("dining room"
    before "table" at the dining area), while the concepts keep the weight the model gives them.
    A place whose only name is weak evidence ("dining", an act in WordNet) keeps a concept of its
    own, but loses a concept it shares with a stronger name ("kitchen"): why prediction uses this
    only when asked (``name_prior="wordnet"``). Rows of zeros stay zeros. Returns (L, V) float64.
    """
    weighted = np.asarray(weighted, dtype=np.float64)
    scaled = weighted * np.asarray(prior, dtype=np.float64)[None, :]
    total, new_total = weighted.sum(axis=1, keepdims=True), scaled.sum(axis=1, keepdims=True)
    return np.divide(scaled * total, new_total, out=np.zeros_like(scaled), where=new_total > 0)


def extend_prior(prior: np.ndarray | None, vocabulary: Vocabulary,
                 sentences: Iterable[str | None]) -> np.ndarray | None:
    """A name prior for a vocabulary that extends the one ``prior`` was computed for (a home's new
    words after the knowledge's): the known words keep theirs, the new ones get
    :func:`name_prior` from ``sentences`` (the home's). ``None`` stays ``None`` (knowledge without a
    prior: every word alike). Returns (len(vocabulary),)."""
    if prior is None:
        return None
    prior = np.asarray(prior, dtype=np.float64)
    n_known = prior.size
    if n_known >= len(vocabulary):
        return prior[: len(vocabulary)]
    return np.concatenate([prior, name_prior(vocabulary, sentences)[n_known:]])
