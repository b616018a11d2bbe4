"""Names never heard: ``where`` with a name no home said finds the learnt place through WordNet.

A user may ask for "the restroom", "the lounge" or "the powder room" in a home whose people said
"toilet", "living room" and "loo". When the name asked for is not one usable vocabulary token
(several words never said as one name, "bath area", count as not said),
:func:`resolve_name` looks for the known name it stands for with the lexicon
(:meth:`spco.data.lexicon.Lexicon.closest`: WordNet synonyms, definitions, head words and modifiers,
derivations, similarity) among the home's candidate names (:func:`candidate_names`: usable words that
are names by the model — name prior ≥ :data:`MIN_CANDIDATE_PRIOR` when the model has a prior,
:mod:`spco.model.name_evidence`, and mutual information ≥ :data:`MIN_CANDIDATE_INFORMATION` of the
largest — or rooms by WordNet, never kinds of place such as "room" or "area"). It asks in steps
and keeps the first answer: for a kind of place named after a thing that WordNet does not know whole
("washbasin area", "tub room"), the word of a place that says the thing, a synonym of it or its kind
(:func:`_by_thing`: "basin", "sink"); a lexical relation (synonym, definition, head, modifier,
derivation) to one of the home's firmly bound names (information ≥ :data:`FIRM_INFORMATION` of the
largest: one or two per place), the same to any candidate, then the name's own words that the home's
people say, kinds of place left out (:func:`said_words`: "sink area" -> "sink", "soaking room" ->
"soak"), then a lexical relation to a word said at a place (:func:`place_words`, by the names θ and
the words of a place ψ: "telly room" -> "tv", "bathing room" -> "bath" said as a thing), then
WordNet similarity to a firmly bound name, then to any candidate, last a word said among those of
every sense of the thing a kind of place is named after (:func:`_by_thing_senses`: "bunk room" ->
"bed"). A synonym only in a sense WordNet never uses it in ("bathroom" for "privy") gives way to a
candidate used in it (:meth:`spco.data.lexicon.Lexicon.seldom_in`). A name found that the home binds
weakly gives way to a firmly bound WordNet synonym of it (one sharing one of its two commonest noun
senses), unless the firm name is never used in the senses they share ("shower stall", by its definition
"bathroom", is the firmly bound "toilet", WordNet's second sense of "bathroom"). ``where`` answers
for that name, saying which one it used ("restroom -> toilet":
:attr:`spco.model.position_prediction.PositionPrediction.asked`). When nothing is found, the name's
own known words said together answer ("great + room"); a name none of whose words is known is an
unknown name (:class:`spco.model.prediction.UnknownNameError`).

Without the lexicon (no NLTK or no WordNet database, see :mod:`spco.data.lexicon`), nothing is
resolved: a name nobody said is an unknown name, or its known words said together, as before.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from spco.data.function_words import is_function_word
from spco.data.language import Vocabulary, normalize_name

__all__ = [
    "FIRM_INFORMATION",
    "MIN_CANDIDATE_INFORMATION",
    "MIN_CANDIDATE_PRIOR",
    "OBJECT_BELOW",
    "PLACE_CANDIDATE_SHARE",
    "PLACE_WORD",
    "QUALITY_SHARE",
    "SAID_WORDS",
    "STAND_IN_HOW",
    "THING",
    "THING_SENSE",
    "ResolvedName",
    "candidate_names",
    "place_words",
    "resolve_name",
    "said_words",
    "stand_in_columns",
    "stand_in_names",
]

#: Known words below this name prior are not candidates for a name nobody said (verbs and function
#: words: "sleep" 0.004, "my" 0.005; names with weak evidence such as "laundry" 0.12 or "bath"
#: 0.14 stay candidates, and so do objects, which WordNet relates to few names and which stand at
#: their place anyway).
MIN_CANDIDATE_PRIOR = 0.05
#: ... nor words whose mutual information with the home's concepts is below this share of the
#: largest (said everywhere or nowhere in this home: "house", "corner"; names of places score
#: 0.01–0.25 nats against 0.24 for the best, such words < 0.0003).
MIN_CANDIDATE_INFORMATION = 0.01
#: Names whose information is at least this share of the largest are the home's firmly bound names
#: (one per place: "kitchen" 0.48, "entrance" 0.43, "washroom" 0.35 against "hall" 0.02): the lexicon
#: looks for the name asked among them first, then among all candidates.
FIRM_INFORMATION = 0.1


def said_as_one(vocabulary: Vocabulary, word_mask: np.ndarray, name: str) -> bool:
    """Whether ``name`` is one usable token of ``vocabulary`` (``word_mask`` (V,) bool): a name said,
    which :func:`resolve_name` leaves as it is."""
    tokens, indices = vocabulary.query(name)
    return len(tokens) == 1 and len(indices) == 1 and bool(np.asarray(word_mask, dtype=bool)[indices[0]])


@dataclass(frozen=True)
class ResolvedName:
    """A name nobody said, and the known name used for it.

    asked: the name asked for (normalised); name: the known vocabulary token used; how: how the
    lexicon related them (``"synonym"``, ``"gloss"``, ``"hypernym"``, ``"definition"``, ``"head"``,
    ``"head …"``, ``"compound …"``, ``"derivation"``, ``"similarity"``; :data:`SAID_WORDS`,
    :data:`PLACE_WORD` and the relation, or :data:`THING_SENSE`); score: the lexicon's similarity in
    (0, 1]."""

    asked: str
    name: str
    how: str
    score: float


def resolve_name(vocabulary: Vocabulary, word_mask: np.ndarray, name: str,
                 name_prior: np.ndarray | None = None, lexicon: object | None = None,
                 information: np.ndarray | None = None,
                 place_information: np.ndarray | None = None) -> ResolvedName | None:
    """The known name that ``name`` stands for, when ``name`` is not a usable token; else None.

    Parameters
    ----------
    vocabulary: the home's vocabulary; word_mask: (V,) bool, the usable words.
    name: the name asked for (any spelling: it is normalised like a sentence).
    name_prior: (V,) the words' name prior, or None (every usable word is a candidate).
    lexicon: a :class:`spco.data.lexicon.Lexicon` (default: the process's, which may be None).
    information: (V,) the words' mutual information with the home's concepts
        (:func:`spco.model.prediction.mutual_information_weights`), or None (no such filter).
    place_information: (V,) the same for the words as ``where`` reads them, names or words of a
        place (:func:`spco.model.position_prediction.place_word_information`), or None: the words
        of a place (:func:`place_words`) the lexicon may relate the name to when no candidate
        name is related to it; None: no such step.

    Returns
    -------
    A :class:`ResolvedName`, or None when ``name`` is one usable token, the lexicon is missing, or
    it finds no known name for ``name`` (the caller then uses the name's own known tokens said
    together, as without the lexicon: "study + room").
    """
    mask = np.asarray(word_mask, dtype=bool)
    asked = normalize_name(name)
    if said_as_one(vocabulary, mask, name):
        return None  # said, as one token: nothing to resolve
    if lexicon is None:
        from spco.data.lexicon import lexicon as load

        lexicon = load()
        if lexicon is None:
            return None
    candidates = candidate_names(vocabulary, mask, name_prior, lexicon, information)
    firm = candidates
    if information is not None and mask.any():  # the home's firmly bound names
        info = np.asarray(information, dtype=np.float64)
        floor = FIRM_INFORMATION * info[mask].max()
        firm = [c for c in candidates if info[vocabulary.index(c)] >= floor]
    # the words of a place (the candidates left out: they are asked first), worked out once, when needed
    words_of_places = functools.cache(lambda: place_words(vocabulary, mask, place_information, lexicon,
                                                          exclude=candidates))
    if place_information is not None:  # a kind of place named after a thing: where the thing is said
        found = _by_thing(vocabulary, mask, asked, lexicon, candidates, words_of_places)
        if found is not None:
            return found
    match = None
    for group in (firm, candidates):  # a lexical relation, to a firmly bound name before the others
        if match is None and group:
            match = lexicon.closest(asked, group, similarity=False, located=True)  # type: ignore[attr-defined]
    if match is None:  # the name's own words that this home's people say ("sink area": "sink")
        said = said_words(vocabulary, mask, asked, lexicon)
        if said:
            return ResolvedName(asked=asked, name=" ".join(said), how=SAID_WORDS, score=0.5)
    if match is None and place_information is not None:  # a word said at a place: "telly room" -> "tv"
        found = _by_place_words(asked, lexicon, words_of_places())
        if found is not None:
            return found
    for group in (firm, candidates):  # then mere similarity
        if match is None and group:
            match = lexicon.closest(asked, group, similarity=True, located=True)  # type: ignore[attr-defined]
    if match is None:  # a kind of place after a thing of a rarer sense: "bunk room", where beds are
        return None if place_information is None else _by_thing_senses(vocabulary, mask, asked, lexicon)
    name, how = match.name, match.how
    if how == "synonym" and lexicon.seldom_in(name, asked):  # type: ignore[attr-defined]
        # a synonym only in a sense the name is never used in ("privy" and "bathroom", whose uses are
        # all of the room with the bathtub): a candidate used in that sense, when the home says one
        name = next((c for c in candidates if _synonym_in_use(lexicon, c, asked)), name)
    if name not in firm:  # a synonym of it that this home binds firmly names the same place
        same = [f for f in lexicon.synonyms_among(name, firm)  # type: ignore[attr-defined]
                if not lexicon.seldom_in(f, name)]  # type: ignore[attr-defined]
        if same:
            name, how = same[0], f"{how} synonym"
    return ResolvedName(asked=asked, name=name, how=how, score=float(match.score))


#: :attr:`ResolvedName.how` of a kind of place after a thing, answered by a word of one of the thing's
#: senses or of its kind (:func:`_by_thing_senses`).
THING_SENSE = "thing sense"


def _by_thing_senses(vocabulary: Vocabulary, mask: np.ndarray, asked: str,
                     lexicon: object) -> ResolvedName | None:
    """For a kind of place named after a thing ("bunk room": the words before a kind of place, "room",
    "area", that name no place), the first word said in this home among the lemmas of every sense of
    the thing and of its kinds, commonest sense first (:meth:`spco.data.lexicon.Lexicon.thing_sense_words`:
    "bunk" is first a feeding trough, then a bed: "bed"); or None. The last step of the look-up, when
    no relation of the name and no word of it said answered (:func:`_by_thing` reads the commonest
    sense only; like it and the other steps through the words of a place, asked only when
    :func:`resolve_name` is given ``place_information``)."""
    words = asked.split()
    if len(words) == 1:
        words = lexicon.split_compound(words[0]) or words  # type: ignore[attr-defined]
    if len(words) < 2 or not _stands_for_no_place(lexicon, words[-1]):
        return None
    for text in lexicon.thing_sense_words(" ".join(words[:-1])):  # type: ignore[attr-defined]
        k = vocabulary.index(text)
        if k is not None and mask[k] and not _stands_for_no_place(lexicon, vocabulary.words[k], thing=True):
            return ResolvedName(asked=asked, name=vocabulary.words[k], how=THING_SENSE, score=0.5)
    return None


def _synonym_in_use(lexicon: object, known: str, asked: str) -> bool:
    """Whether the known name shares a noun sense with ``asked`` and is used in one of the shared
    senses (:meth:`spco.data.lexicon.Lexicon.seldom_in`: "toilet" or "lavatory" for "privy", not
    "bathroom")."""
    shared = set(lexicon.synsets(known, pos="n")) & set(lexicon.synsets(asked, pos="n"))  # type: ignore[attr-defined]
    return bool(shared) and not lexicon.seldom_in(known, asked)  # type: ignore[attr-defined]


#: A word whose senses are more than this share adjectives or adverbs in WordNet is a quality ("wet"
#: 0.78, "small" 0.99, "hot" 1.0), not a thing or an act ("sink", "bath", "eating" 0; "spare" 0.29):
#: said at a place, it does not say which place a name means (:func:`said_words`, :func:`place_words`).
QUALITY_SHARE = 0.5
#: :attr:`ResolvedName.how` of a name answered by its own words that the home's people say.
SAID_WORDS = "its words"
#: :attr:`ResolvedName.how` (its first word) of a name answered by a word of a place (:func:`place_words`).
PLACE_WORD = "place word"
#: :attr:`ResolvedName.how` (after :data:`PLACE_WORD`) of a kind of place named after a thing, answered
#: where the thing is said (:func:`_by_thing`).
THING = "thing"


def _by_place_words(asked: str, lexicon: object, objects: list[str]) -> ResolvedName | None:
    """The word of a place among ``objects`` (:func:`place_words`, the candidate names left out: they
    were asked first) that the lexicon relates ``asked`` to by a relation of its own
    (:meth:`spco.data.lexicon.Lexicon.closest` without similarity: a synonym, in its definition, a
    derivation, its head or modifier, or the place WordNet names by its modifier before another
    head: "dressing area" -> "dressing room", "a room in which you can change clothes" ->
    "clothes"), or None."""
    found = (lexicon.closest(asked, objects, similarity=False, located=True)  # type: ignore[attr-defined]
             if objects else None)
    if found is None:
        return None
    return ResolvedName(asked=asked, name=found.name, how=f"{PLACE_WORD} {found.how}",
                        score=float(found.score))


def _by_thing(vocabulary: Vocabulary, mask: np.ndarray, asked: str, lexicon: object, candidates: list[str],
              words_of_places: Callable[[], list[str]]) -> ResolvedName | None:
    """The word of a place (:func:`place_words`, the candidate names left out) that says the thing
    ``asked`` is named after (:meth:`spco.data.lexicon.Lexicon.thing_words`: "washbasin area" is where
    the washbasin is), as said or in a base form ("boots" for "boot"): the thing's synonyms first,
    then its kind ("washbasin", a "sink"), each the most informative word saying it, or the word
    itself when it is said but no more at some places than at others (as :func:`said_words` reads a
    name's own words); or None. Where a thing stands differs from home to home (a Japanese home's
    washbasin is in the washroom, WordNet's in the bathroom: "a bathroom sink …"), so the home's own
    words of a place are asked before the names WordNet's definitions put it with."""
    things = lexicon.thing_words(asked, candidates)  # type: ignore[attr-defined]
    if not things:
        return None
    objects = words_of_places()  # place_words, the candidates left out
    forms = {word: lexicon.base_forms(word) for word in objects}  # type: ignore[attr-defined]
    skip = set(candidates)
    for thing in things:
        found = next((word for word in objects if thing in forms[word]), None)
        if found is None:  # said, but not more at some places than at others: as its own words are read
            k = vocabulary.index(thing)
            if k is not None and mask[k] and thing not in skip and not is_function_word(thing):
                found = vocabulary.words[k]
        if found is not None:
            return ResolvedName(asked=asked, name=found, how=f"{PLACE_WORD} {THING}", score=0.7)
    return None


def place_words(vocabulary: Vocabulary, word_mask: np.ndarray, place_information: np.ndarray,
                lexicon: object, exclude: list[str] | tuple[str, ...] = ()) -> list[str]:
    """The home's words of a place: usable words said at some places more than at others — objects,
    acts, names — by the model's account of what is said where (names θ and words of a place ψ:
    ``place_information`` ≥ :data:`MIN_CANDIDATE_INFORMATION` of the largest), most informative
    first; function words, kinds of place ("room", "area"; not "water", a thing with many kinds:
    :func:`_stands_for_no_place` with ``thing``), qualities (mostly adjectives or adverbs
    in WordNet: "wet", "small"; :meth:`spco.data.lexicon.Lexicon.quality_share` > 0.5: a quality
    said at a place does not stand for it) and ``exclude`` left out. A name nobody
    said that WordNet relates to one of them ("bunk room": a bunk is "a rough bed"; "bathing room":
    "bathe", whose verb holds "bath") is looked for where that word is said."""
    mask = np.asarray(word_mask, dtype=bool)
    info = np.asarray(place_information, dtype=np.float64)
    usable = np.flatnonzero(mask)
    if usable.size == 0 or not info[usable].max() > 0:
        return []
    floor = MIN_CANDIDATE_INFORMATION * info[usable].max()
    order = usable[np.argsort(-info[usable], kind="stable")]
    skip = set(exclude)
    return [vocabulary.words[k] for k in order if info[k] >= floor and vocabulary.words[k] not in skip
            and not _stands_for_no_place(lexicon, vocabulary.words[k], thing=True)]


def said_words(vocabulary: Vocabulary, word_mask: np.ndarray, name: str, lexicon: object) -> list[str]:
    """The usable tokens of the words of ``name`` (several words, or one WordNet does not know read as
    two: :meth:`spco.data.lexicon.Lexicon.split_compound`) that say which place is meant: every word
    but function words and kinds of place (:data:`spco.data.lexicon.KINDS_BELOW` kinds under it:
    "room", "area"), each as said or, when not said so, as a WordNet base form said ("soaking room":
    "soak"). Empty for a name of one word, or when only kinds of place are said ("comfort room":
    "room" names no place, so the caller's answer is the name's own tokens said together, as
    without the lexicon)."""
    words = normalize_name(name).split()
    if len(words) == 1:
        words = lexicon.split_compound(words[0]) or words  # type: ignore[attr-defined]
    if len(words) < 2:
        return []
    mask = np.asarray(word_mask, dtype=bool)
    out: list[str] = []
    for word in words:
        if _stands_for_no_place(lexicon, word):
            continue
        for form in (word, *sorted(lexicon.base_forms(word) - {word})):  # type: ignore[attr-defined]
            k = vocabulary.index(form)
            if k is not None and mask[k] and not is_function_word(vocabulary.words[k]):
                if vocabulary.words[k] not in out:
                    out.append(vocabulary.words[k])
                break
    return out


#: A known word is a candidate whatever its name prior and information when this share of its own noun
#: senses (weighted by frequency, :meth:`spco.data.lexicon.Lexicon.room_share`) are rooms or areas of a
#: building in WordNet: "toilet" (0.44) is said so often beside "go to the" and its objects that its
#: prior is low and, one word among many at its place, its information small, yet it is the place's
#: own name ("corner" 0.16, "hall" 0.36, "kitchen" 1.0).
PLACE_CANDIDATE_SHARE = 0.25


def candidate_names(vocabulary: Vocabulary, word_mask: np.ndarray, name_prior: np.ndarray | None,
                    lexicon: object, information: np.ndarray | None = None) -> list[str]:
    """The home's known words a name nobody said may stand for, most name-like first.

    A usable word is a candidate when it is a name by the model (name prior ≥
    :data:`MIN_CANDIDATE_PRIOR` and information ≥ :data:`MIN_CANDIDATE_INFORMATION` of the largest,
    when given) or a place by WordNet (place share ≥ :data:`PLACE_CANDIDATE_SHARE`), and does not
    stand for no place (the test of the words of a place, :func:`_stands_for_no_place`: not a function
    word, nor a kind of place with :data:`spco.data.lexicon.KINDS_BELOW` kinds under it in WordNet —
    "room", "area", "house", "home" — nor a quality). The names by the model come first (by
    prior), then the places by WordNet (by prior)."""
    mask = np.asarray(word_mask, dtype=bool)
    usable = np.flatnonzero(mask)
    named = np.ones(mask.size, dtype=bool)
    if information is not None and usable.size:
        info = np.asarray(information, dtype=np.float64)
        named &= info >= MIN_CANDIDATE_INFORMATION * info[usable].max()
    prior = np.zeros(mask.size) if name_prior is None else np.asarray(name_prior, dtype=np.float64)
    if name_prior is not None:
        named &= prior >= MIN_CANDIDATE_PRIOR
    order = usable[np.argsort(-prior[usable], kind="stable")]
    first = [k for k in order if named[k]]
    then = [k for k in order
            if not named[k] and _fact(lexicon, "room_share", vocabulary.words[k]) >= PLACE_CANDIDATE_SHARE]
    return [vocabulary.words[k] for k in (*first, *then)
            if not _stands_for_no_place(lexicon, vocabulary.words[k])]


_FACTS: dict[tuple[int, str, str], float] = {}


def _fact(lexicon: object, fact: str, word: str) -> float:
    """``lexicon.<fact>(word)`` (:class:`~spco.data.lexicon.Lexicon`'s ``room_share``, ``place_share``,
    ``quality_share``, ``kinds_below``), remembered for the process; NaN (a word without noun senses)
    as 0, which every test here reads alike (each asks for a share or count above a positive bound)."""
    key = (id(lexicon), fact, word)
    if key not in _FACTS:
        value = float(getattr(lexicon, fact)(word))
        _FACTS[key] = 0.0 if np.isnan(value) else value
    return _FACTS[key]


def _stands_for_no_place(lexicon: object, word: str, thing: bool = False) -> bool:
    """A word said at a place or in a name that does not say which place is meant: a function word, a
    kind of place ("room", "area": :data:`~spco.data.lexicon.KINDS_BELOW` kinds below it or more) or a
    quality (:data:`QUALITY_SHARE`: "wet", "small"). ``thing``: the word is said at a place as a
    thing (:func:`place_words`): with many kinds below it, it is a kind of place only when WordNet
    has it as a place (:meth:`~spco.data.lexicon.Lexicon.place_share` > 0); "water" (75 kinds) and
    "food" are no places, and many kinds of water are still water, said where it is."""
    from spco.data.lexicon import KINDS_BELOW

    kind = (_fact(lexicon, "kinds_below", word) >= KINDS_BELOW
            and (not thing or _fact(lexicon, "place_share", word) > 0))
    return is_function_word(word) or kind or _fact(lexicon, "quality_share", word) > QUALITY_SHARE


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
        known = [vocabulary.words[j] for j in stronger]
        match = _closest(lexicon, vocabulary.words[k], tuple(known))
        while match is not None and match.how.endswith("gloss") and not _is_place(lexicon, match.name):
            rest = [w for w in known if w != match.name]  # a definition names a thing ("water"), not
            if len(rest) == len(known):  # a place: the next name the lexicon relates it to
                match = None
                break
            known = rest
            match = _closest(lexicon, vocabulary.words[k], tuple(known))
        if match is not None and match.how in STAND_IN_HOW:
            j = vocabulary.index(match.name)
            if j is not None and j != k:
                out[k] = j
    return out


def _is_place(lexicon: object, word: str) -> bool:
    """Whether WordNet has ``word`` (or, for a term it does not know, its head) as a place: a place
    share > 0 among its physical noun senses (:func:`spco.model.name_evidence.lexical_features`).
    What an object's definition must name for the object to stand in for it: "door" ("… the
    entrance to a room") for "entrance", not "bathtub" ("… fill with water …") for "water"."""
    from spco.model.name_evidence import FEATURES, lexical_features

    facts = lexical_features([word], None if lexicon is _FILE_LEXICON else lexicon)
    return bool(facts[0, FEATURES.index("place_share") - FEATURES.index("known")] > 0)


def stand_in_columns(vocabulary: Vocabulary, name_prior: np.ndarray, asked: np.ndarray | None = None,
                     lexicon: object | None = None) -> np.ndarray:
    """(V,) int: for each word the column of the place name it stands in for (:func:`stand_in_names`
    over every word of the vocabulary, or of ``asked``, against every word of stronger name evidence:
    "dining table" → "dining room", "door" → "entrance", "stove" → "kitchen"), −1 for none. Used by
    :func:`spco.model.word_channels.place_names`: an object said at a place counts for the name it
    stands in for. All −1 without the lexicon."""
    out = np.full(len(vocabulary.words), -1, dtype=np.int64)
    prior = np.asarray(name_prior, dtype=np.float64)
    if prior.shape != out.shape:
        raise ValueError(f"name_prior must have shape {out.shape}, got {prior.shape}")
    candidates = np.flatnonzero(prior < OBJECT_BELOW) if asked is None else np.asarray(asked, dtype=np.int64)
    if candidates.size == 0:
        return out
    for k, j in stand_in_names(vocabulary, np.ones(out.size, dtype=bool), prior, candidates,
                               lexicon).items():
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
    files (:func:`spco.data.word_facts.word_facts`, :func:`spco.data.word_facts.closest_names`): the same
    answers, and WordNet (NLTK's import and reading, seconds) is loaded only for words not asked
    before on this machine."""

    @staticmethod
    def knows(word: str) -> bool:
        from spco.data.word_facts import word_facts

        facts = word_facts([word])
        return bool(facts is not None and facts[word].known)

    @staticmethod
    def closest(name: str, known: list[str]):
        from spco.data.word_facts import closest_names

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
