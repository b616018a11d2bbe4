"""Names never heard: ``where`` with a name no home said finds the learnt place through WordNet.

A user may ask for "the restroom", "the lounge" or "the powder room" in a home whose people said
"toilet", "living room" and "loo". When the name asked for is not one usable vocabulary token
(several words never said as one name, "bath area", count as not said),
:func:`resolve_name` looks for the known name it stands for with the lexicon
(:meth:`spco.data.lexicon.Lexicon.closest`: WordNet synonyms, definitions, head words, similarity)
among the home's usable words that are names (name prior ≥ :data:`MIN_CANDIDATE_PRIOR` when the
model has a prior, :mod:`spco.model.name_evidence`) and place-bound in this home (mutual information
≥ :data:`MIN_CANDIDATE_INFORMATION` of the largest), and ``where`` answers for that name, saying
which one it used ("restroom -> toilet": :attr:`spco.model.position_prediction.PositionPrediction.asked`).

Without the lexicon (no NLTK or no WordNet database, see :mod:`spco.data.lexicon`), nothing is
resolved: a name nobody said is an unknown name, or its known words said together, as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spco.data.language import Vocabulary, normalize_name

__all__ = ["MIN_CANDIDATE_INFORMATION", "MIN_CANDIDATE_PRIOR", "OBJECT_BELOW", "STAND_IN_HOW", "ResolvedName",
           "resolve_name", "stand_in_names"]

#: Known words below this name prior are not candidates for a name nobody said (verbs and function
#: words: "sleep" 0.004, "my" 0.005; names with weak evidence such as "laundry" 0.12 or "bath"
#: 0.14 stay candidates, and so do objects, which WordNet relates to few names and which stand at
#: their place anyway).
MIN_CANDIDATE_PRIOR = 0.05
#: ... nor words whose mutual information with the home's concepts is below this share of the
#: largest (said everywhere or nowhere in this home: "house", "corner"; names of places score
#: 0.01–0.25 nats against 0.24 for the best, such words < 0.0003).
MIN_CANDIDATE_INFORMATION = 0.01


@dataclass(frozen=True)
class ResolvedName:
    """A name nobody said, and the known name used for it.

    asked: the name asked for (normalised); name: the known vocabulary token used; how: how the
    lexicon related them (``"synonym"``, ``"gloss"``, ``"definition"``, ``"head"``, ``"head …"``,
    ``"similarity"``); score: the lexicon's similarity in (0, 1]."""

    asked: str
    name: str
    how: str
    score: float


def resolve_name(vocabulary: Vocabulary, word_mask: np.ndarray, name: str,
                 name_prior: np.ndarray | None = None, lexicon: object | None = None,
                 information: np.ndarray | None = None) -> ResolvedName | None:
    """The known name that ``name`` stands for, when ``name`` is not a usable token; else None.

    Parameters
    ----------
    vocabulary: the home's vocabulary; word_mask: (V,) bool, the usable words.
    name: the name asked for (any spelling: it is normalised like a sentence).
    name_prior: (V,) the words' name prior, or None (every usable word is a candidate).
    lexicon: a :class:`spco.data.lexicon.Lexicon` (default: the process's, which may be None).
    information: (V,) the words' mutual information with the home's concepts
        (:func:`spco.model.prediction.mutual_information_weights`), or None (no such filter).

    Returns
    -------
    A :class:`ResolvedName`, or None when ``name`` is one usable token, the lexicon is missing, or
    it finds no known name for ``name`` (the caller then uses the name's own known tokens said
    together, as without the lexicon: "study + room").
    """
    mask = np.asarray(word_mask, dtype=bool)
    asked = normalize_name(name)
    tokens, indices = vocabulary.query(name)
    if len(tokens) == 1 and len(indices) == 1 and mask[indices[0]]:
        return None  # said, as one token: nothing to resolve
    if lexicon is None:
        from spco.data.lexicon import lexicon as load

        lexicon = load()
        if lexicon is None:
            return None
    usable = np.flatnonzero(mask)
    if information is not None and usable.size:
        info = np.asarray(information, dtype=np.float64)
        usable = usable[info[usable] >= MIN_CANDIDATE_INFORMATION * info[usable].max()]
    if name_prior is not None:
        prior = np.asarray(name_prior, dtype=np.float64)
        usable = usable[prior[usable] >= MIN_CANDIDATE_PRIOR]
        usable = usable[np.argsort(-prior[usable], kind="stable")]
    candidates = [vocabulary.words[k] for k in usable]
    match = lexicon.closest(asked, candidates)  # type: ignore[attr-defined]
    if match is None:
        return None
    return ResolvedName(asked=asked, name=match.name, how=match.how, score=float(match.score))


#: A word whose name evidence p(name | word) is below this is an object, an act or a person said at
#: a place, not its name (:func:`stand_in_names`): "door" 0.08, "bed" 0.07, "table" 0.04; place names
#: are 0.2–0.8 ("toilet" 0.19, "entrance" 0.32, "kitchen" 0.57).
OBJECT_BELOW = 0.15
#: How the lexicon may relate an object to the place name that stands in for it: the object's
#: definition names the place ("door": "a swinging or sliding barrier that will close the entrance
#: to a room or building"), or a term's head or modifier is the name ("dining table" → "dining").
#: Not synonyms ("pot", slang for a toilet) nor mere similarity ("vase" and "bath").
STAND_IN_HOW = ("gloss", "head", "head gloss")


def stand_in_names(vocabulary: Vocabulary, word_mask: np.ndarray, name_prior: np.ndarray,
                   asked: np.ndarray, lexicon: object | None = None) -> dict[int, int]:
    """The place name that stands in for each object among ``asked`` (column indices): {object column:
    name column}.

    People often call a place by what is there ("near the door" at the entrance, "by the dining
    table"); where a home's people never said the room's name, the model's best word for the place
    is then the object (low name evidence, :data:`OBJECT_BELOW`). The lexicon relates the object to a
    name the corpus knows with stronger evidence (:meth:`spco.data.lexicon.Lexicon.closest`, the
    relations of :data:`STAND_IN_HOW` only); :func:`spco.model.prediction.predict_names` then
    answers that name with the object's score added to it. Likewise a word WordNet does not know
    stands in for its spelling the vocabulary holds and WordNet knows ("livingroom" for "living
    room", "kicthen" for "kitchen": :func:`spco.model.name_evidence.spelling_variants`). Objects
    without such a name, and every word without the lexicon, are left out.

    Parameters
    ----------
    vocabulary, word_mask: the corpus vocabulary and its usable words (V,).
    name_prior: (V,) p(name | word), the word channels' switch prior of the names channel.
    asked: the columns to look up (the answers' candidates).
    lexicon: a :class:`spco.data.lexicon.Lexicon` (default: the process's, asked through its cache
        files, so that WordNet is read only for words not asked before; none without the lexicon).
    """
    if lexicon is None:
        from spco.data.lexicon import lexicon_unavailable_reason

        if lexicon_unavailable_reason() is not None:
            return {}
        lexicon = _FILE_LEXICON
    prior = np.asarray(name_prior, dtype=np.float64)
    mask = np.asarray(word_mask, dtype=bool)
    out: dict[int, int] = {}
    for k in sorted({int(k) for k in np.asarray(asked).ravel()}):
        if not mask[k]:
            continue
        spelled = _spelled(lexicon, vocabulary, mask, k)
        if spelled is not None:
            out[k] = spelled
            continue
        if prior[k] >= OBJECT_BELOW:
            continue
        stronger = np.flatnonzero(mask & (prior >= OBJECT_BELOW) & (prior > prior[k]))
        stronger = stronger[np.argsort(-prior[stronger], kind="stable")]
        match = _closest(lexicon, vocabulary.words[k], tuple(vocabulary.words[j] for j in stronger))
        if match is not None and match.how in STAND_IN_HOW:
            j = vocabulary.index(match.name)
            if j is not None and j != k:
                out[k] = j
    return out


def _spelled(lexicon: object, vocabulary: Vocabulary, mask: np.ndarray, k: int) -> int | None:
    """The column of the spelling of word ``k`` that WordNet knows, when WordNet does not know ``k``
    itself and the vocabulary holds that spelling (:func:`spco.model.name_evidence.spelling_variants`:
    "livingroom" → "living room", "kicthen" → "kitchen"); else None."""
    from spco.model.name_evidence import spelling_variants

    word = vocabulary.words[k]
    if lexicon.knows(word):  # type: ignore[attr-defined]
        return None
    for variant in spelling_variants(word, vocabulary.words):
        j = vocabulary.index(variant)
        if j is not None and j != k and mask[j] and lexicon.knows(variant):  # type: ignore[attr-defined]
            return j
    return None


class _FileLexicon:
    """The two questions :func:`stand_in_names` asks the lexicon, answered from the lexicon's cache
    files (:func:`spco.data.lexicon.word_facts`, :func:`spco.data.lexicon.closest_names`): the same
    answers, and WordNet (NLTK's import and reading, seconds) is loaded only for words not asked
    before on this machine."""

    @staticmethod
    def knows(word: str) -> bool:
        from spco.data.lexicon import word_facts

        facts = word_facts([word])
        return bool(facts is not None and facts[word].known)

    @staticmethod
    def closest(name: str, known: list[str]):
        from spco.data.lexicon import closest_names

        found = closest_names([(name, known)])
        return None if found is None else found[0]


_FILE_LEXICON = _FileLexicon()


_STAND_IN_CACHE: dict[tuple[int, str, tuple[str, ...]], object] = {}


def _closest(lexicon: object, word: str, known: tuple[str, ...]):
    """:meth:`Lexicon.closest`, remembered per (lexicon, word, candidates) for the process."""
    key = (id(lexicon), word, known)
    if key not in _STAND_IN_CACHE:
        if len(_STAND_IN_CACHE) > 4096:
            _STAND_IN_CACHE.clear()
        _STAND_IN_CACHE[key] = lexicon.closest(word, list(known)) if known else None  # type: ignore[attr-defined]
    return _STAND_IN_CACHE[key]
