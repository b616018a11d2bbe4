"""WordNet, read offline: what a word can be (noun, verb, …), whether a noun names a place, and
which known place name a name nobody said stands for.

The lexicon is the English WordNet 3.0 of Debian's ``wordnet-base`` (``/usr/share/wordnet``), read
through NLTK's :class:`~nltk.corpus.reader.wordnet.WordNetCorpusReader` (``pip install "spco[words]"``,
``apt-get install wordnet-base``); nothing is downloaded. NLTK's reader also opens ``lexnames`` (the
table of WordNet's 45 lexicographer files, lexnames(5WN)), which Debian lacks: the reader gets a
private folder (under ``~/.cache/spco`` or ``SPCO_CACHE_DIR``) with copies of the package's files and
that table (:mod:`spco.data.wordnet_files`). ``SPCO_WORDNET`` names another folder of WordNet
files; ``SPCO_WORDNET=off`` turns the lexicon off: every function that uses it (:func:`lexicon`
returns ``None``) then falls back to what the data alone say, and ``where`` with a name nobody
said is an unknown name.

What a *place* noun is (:meth:`Lexicon.place_share`): a sense of the word whose hypernym closure
holds one of :data:`PLACE_ROOTS` — a room, an area of a building (WordNet's ``area.n.05``), a
building or a structure (walls, stairs), a passage (``way.n.06``: halls, entrances, doorways), a
point or region of space (``location.n.01``) — as
opposed to an artifact that is not a structure (furniture, appliances, towels), an act ("dining" as
the act of eating), a person or a feeling. These are the general categories of WordNet's noun
hierarchy that places fall under, not names of rooms; no room name is listed anywhere in spco.
"""

from __future__ import annotations

import functools
import importlib.util
import itertools
import os
import threading
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from spco.data.wordnet_files import DATABASE, open_reader, reader_folder

__all__ = ["KINDS_BELOW", "MIN_SIMILARITY", "NOT_PLACE_ROOTS", "PLACE_ROOTS", "THING_FILES",
           "THING_PLACE_BELOW", "THING_SHARE", "Lexicon", "LexiconMatch", "lexicon",
           "lexicon_unavailable_reason"]

#: Where Debian's wordnet-base puts the database files.
DEBIAN_WORDNET = Path("/usr/share/wordnet")

#: The WordNet noun concepts that places in a home fall under (see the module docstring).
PLACE_ROOTS = ("room.n.01", "area.n.05", "building.n.01", "structure.n.01", "location.n.01",
               "housing.n.01", "way.n.06")

#: The kinds of structure that bound or hold places without being one (a sense under one of these is
#: not a place, whatever root is above it): barriers (doors, gates, fences), partitions (walls),
#: supporting structures (frames, windows, beams) and storage spaces (drawers, cupboards). A person
#: is *in* a room or a hall, *at* a door or a wall: "in front of the door" at the entrance names the
#: door, not the place.
NOT_PLACE_ROOTS = ("obstruction.n.01", "partition.n.01", "supporting_structure.n.01",
                   "storage_space.n.01")

#: Least Wu–Palmer similarity for a known name to stand for an asked one: kinds of room are about
#: 0.85–0.9 apart (siblings under "room"), a room and a garage (an outbuilding) about 0.6.
MIN_SIMILARITY = 0.8

#: A word with at least this many kinds (hyponyms, at every depth) under one of its two commonest noun
#: senses names a kind of place, not a place ("room" 195, "area" 91, "home" 76, "house" 59, "place" 55;
#: "entrance" 16, "bedroom" 11, "kitchen" 4): as a head it leaves the choice of place to the words
#: before it ("laundry area"), and it is never the known name a name nobody said stands for.
KINDS_BELOW = 50

#: WordNet's lexicographer files (lexnames(5WN)) of things that stand somewhere in a home — objects,
#: substances, food, plants, animals — as opposed to acts, people, qualities or feelings: a kind of place
#: named after one of them ("washbasin area", "tub room") is where that thing is
#: (:meth:`Lexicon.thing_words`).
THING_FILES = frozenset({"noun.artifact", "noun.object", "noun.substance", "noun.food", "noun.plant",
                         "noun.animal"})

#: Least share of a word's noun senses (weighted by tagged frequency) that are things for the word to be
#: one (:meth:`Lexicon.is_thing`): most of what the word means as a noun is an object, a substance or
#: food, not an act, a group or a quality ("table" as furniture, not as a table of data).
THING_SHARE = 0.5

#: A thing (:meth:`Lexicon.is_thing`) is a place in less than this share of the senses it can be pointed
#: at in (:meth:`Lexicon.place_share`): "bed" (0.09, a flower bed), "window" (0.02) are things;
#: "laundry" (0.33, a laundry room) is not.
THING_PLACE_BELOW = 0.2

#: Prepositions of location: a known name after one of them in a definition is where the defined
#: place is, not what it is.
_LOCATIVE = frozenset({"off", "near", "in", "inside", "next", "beside", "behind", "at", "on", "from",
                       "into", "outside", "adjacent", "beyond", "opposite"})

#: Words of definitions that say nothing of what a place is for (with the words in many known
#: names' definitions, left out when definitions are compared).
_FUNCTION_WORDS = frozenset({"a", "an", "the", "or", "and", "of", "for", "in", "with", "to", "on", "at",
                             "by", "as", "that", "which", "where", "is", "are", "be", "can", "used",
                             "usually", "one", "more", "some", "any", "etc", "e.g", "especially"})

def _cache_root() -> Path:
    return Path(os.environ.get("SPCO_CACHE_DIR") or Path.home() / ".cache" / "spco")


def _wordnet_folder() -> Path | None:
    """The folder of WordNet database files to read (``SPCO_WORDNET`` or Debian's), or None."""
    chosen = os.environ.get("SPCO_WORDNET", "").strip()
    if chosen.lower() in ("off", "0", "none", "no"):
        return None
    folder = Path(chosen).expanduser() if chosen else DEBIAN_WORDNET
    return folder if all((folder / f).is_file() for f in DATABASE) else None


def lexicon_unavailable_reason() -> str | None:
    """Why :func:`lexicon` returns None (a sentence for messages and skips), or None when it works."""
    return _unavailable(os.environ.get("SPCO_WORDNET", "").strip())


@functools.lru_cache(maxsize=8)
def _unavailable(chosen: str) -> str | None:  # once per process and setting: every `what` asks
    if chosen.lower() in ("off", "0", "none", "no"):
        return "the lexicon is turned off (SPCO_WORDNET=off)"
    if importlib.util.find_spec("nltk") is None:  # (importing NLTK takes seconds: only looked up)
        return "NLTK is not installed (pip install 'spco[words]')"
    if _wordnet_folder() is None:
        where = chosen or str(DEBIAN_WORDNET)
        return f"no WordNet database in {where} (apt-get install wordnet-base)"
    return None


@dataclass(frozen=True)
class LexiconMatch:
    """A known name found for a name nobody said (:meth:`Lexicon.closest`).

    name: the known name; score: its similarity in (0, 1] (1: a synonym); how: ``"synonym"``,
    ``"head"`` (same head noun: "kitchen nook" -> "kitchen"), ``"gloss"`` (the known name is in the
    asked name's definition), ``"definition"`` (the asked name's word is in the known name's
    definition) or ``"similarity"`` (WordNet's Wu–Palmer similarity of the nouns)."""

    name: str
    score: float
    how: str


class Lexicon:
    """WordNet through NLTK (use :func:`lexicon`, which caches one per process)."""

    def __init__(self, folder: Path) -> None:
        self._wn = open_reader(reader_folder(folder, _cache_root()))
        self._roots = [self._wn.synset(name) for name in PLACE_ROOTS]
        self._not_roots = [self._wn.synset(name) for name in NOT_PLACE_ROOTS]
        self._physical = self._wn.synset("physical_entity.n.01")
        self._lock = threading.Lock()
        self.version = str(self._wn.get_version())

    # ------------------------------------------------------------------ words
    @staticmethod
    def _lemma(word: str) -> str:
        return "_".join(word.strip().lower().split())

    def synsets(self, word: str, pos: str | None = None) -> list:
        """WordNet synsets of a word or multi-word name (spaces or underscores), most frequent first."""
        with self._lock:  # NLTK's lazy loading is not thread-safe
            return list(self._wn.synsets(self._lemma(word), pos=pos))

    def knows(self, word: str) -> bool:
        """Whether WordNet has the word (in any part of speech, after its own lemmatisation)."""
        return bool(self.synsets(word))

    def noun_share(self, word: str) -> float:
        """Share of the word's senses that are nouns, weighted by the senses' tagged frequency
        (+1 each); NaN for a word WordNet does not know."""
        weights = {"n": 0.0, "other": 0.0}
        for pos, weight in self._sense_weights(word):
            weights["n" if pos == "n" else "other"] += weight
        total = weights["n"] + weights["other"]
        return weights["n"] / total if total else float("nan")

    def _sense_weights(self, word: str) -> list[tuple[str, float]]:
        """(part of speech, weight) of each of the word's senses: 1 + the sense's tagged frequency
        for the word's lemma; what :meth:`noun_share` and :meth:`quality_share` weigh senses by."""
        lemma = self._lemma(word)
        return [(synset.pos(),
                 1.0 + sum(lem.count() for lem in synset.lemmas() if lem.name().lower() == lemma))
                for synset in self.synsets(word)]

    def quality_share(self, word: str) -> float:
        """Share of the word's senses (weighted as :meth:`noun_share`) that are adjectives or adverbs:
        a quality ("wet" 0.78, "small" 0.99), not a thing or an act ("sink", "bath": 0); NaN for a
        word WordNet does not know."""
        quality = total = 0.0
        for pos, weight in self._sense_weights(word):
            total += weight
            quality += weight if pos in ("a", "s", "r") else 0.0
        return quality / total if total else float("nan")

    @functools.lru_cache(maxsize=65536)  # noqa: B019 - one lexicon per process
    def _is_place_synset(self, name: str) -> bool:
        synset = self._wn.synset(name)
        if synset.lexname() == "noun.location":
            return True
        closure = {synset, *synset.closure(lambda s: s.hypernyms() + s.instance_hypernyms())}
        if any(root in closure for root in self._not_roots):
            return False
        return any(root in closure for root in self._roots)

    @functools.lru_cache(maxsize=65536)  # noqa: B019 - one lexicon per process
    def _is_physical_synset(self, name: str) -> bool:
        synset = self._wn.synset(name)
        return self._physical in {synset, *synset.closure(lambda s: s.hypernyms() + s.instance_hypernyms())}

    def place_share(self, word: str) -> float:
        """Share of the word's noun senses that can be pointed at — physical entities (WordNet's
        ``physical_entity.n.01``), weighted as :meth:`noun_share` — that are places (see the module
        docstring); NaN for a word without noun senses. A word said of a place ("this is the study")
        is said of something there: its abstract senses (acts, cognition, communication, states:
        "study" as learning or a report) are not what it can name, so they do not dilute its place
        senses ("study" 0.64 of its physical senses is the room; 0.05 of all its senses). Objects
        keep their share ("table", "desk" 0, "door" 0.28). A word whose noun senses are all abstract
        ("music", "dining" as an act) has no place sense: 0."""
        lemma = self._lemma(word)
        place = total = 0.0
        seen = False
        for synset in self.synsets(word, pos="n"):
            seen = True
            with self._lock:
                if not self._is_physical_synset(synset.name()):
                    continue
                is_place = self._is_place_synset(synset.name())
            weight = 1.0 + sum(lem.count() for lem in synset.lemmas() if lem.name().lower() == lemma)
            total += weight
            place += weight if is_place else 0.0
        if not seen:
            return float("nan")
        return place / total if total else 0.0

    def room_share(self, word: str) -> float:
        """Share of the word's own noun senses (those with the word itself as a lemma, not a base form
        of it: "has" is no "ha"), weighted as :meth:`noun_share`, that are rooms or areas of a
        building in WordNet (under ``room.n.01`` or ``area.n.05``, and none of
        :data:`NOT_PLACE_ROOTS`); 0 for a word without such senses."""
        lemma = self._lemma(word)
        room = total = 0.0
        for synset in self.synsets(word, pos="n"):
            counts = [lem.count() for lem in synset.lemmas() if lem.name().lower() == lemma]
            if not counts:
                continue
            weight = 1.0 + sum(counts)
            total += weight
            with self._lock:
                closure = {synset, *synset.closure(lambda s: s.hypernyms())}
            rooms = any(root in closure for root in self._roots[:2])  # room.n.01, area.n.05
            if rooms and not any(r in closure for r in self._not_roots):
                room += weight
        return room / total if total else 0.0

    def thing_share(self, word: str) -> float:
        """Share of the word's noun senses, weighted as :meth:`noun_share` (1 + the tagged frequency of the
        word or of its noun base form: "shoes" weighs by "shoe"), that are things: in one of
        :data:`THING_FILES` and not a place (see the module docstring: "bath" as a room is an
        artifact of WordNet, but a place); NaN for a word without noun senses."""
        lemma = self._lemma(word)
        with self._lock:
            base = self._wn.morphy(lemma, "n")
        forms = {lemma, base} if base else {lemma}
        thing = total = 0.0
        for synset in self.synsets(word, pos="n"):
            weight = 1.0 + sum(lem.count() for lem in synset.lemmas() if lem.name().lower() in forms)
            total += weight
            with self._lock:
                is_thing = synset.lexname() in THING_FILES and not self._is_place_synset(synset.name())
            thing += weight if is_thing else 0.0
        return thing / total if total else float("nan")

    def is_thing(self, word: str) -> bool:
        """Whether WordNet gives positive evidence that the word names a thing and never a room: it knows
        the word; the word is mostly a noun (:meth:`noun_share` at least 0.5: not "dining" or "living",
        mostly an act or a verb's form); its commonest noun sense is a thing (:data:`THING_FILES`, not a
        place); at least :data:`THING_SHARE` of its noun senses are things (:meth:`thing_share`: not
        "table", mostly a table of data, nor "shower"); it is rarely a place (:meth:`place_share` below
        :data:`THING_PLACE_BELOW`: not "laundry"); and none of its own noun senses is a room or an area
        of a building (:meth:`room_share` 0: not "toilet", "closet"), nor is a word that shares one of
        its noun senses (:meth:`room_namesakes` empty: a thing WordNet also calls by a room's word is
        what people name the room after — bathtub.n.01 is also "bath", so "tub" and "bathtub" are no
        evidence of an object rather than the bath's name; sofa.n.01 is also "lounge"; the toilet bowl,
        "stool" and "pot", is also "toilet"). "fridge", "towel", "bed", "kettle": yes; a word WordNet
        does not know ("dormitorio", "wc"): no — the absence of a room sense is no evidence of an object."""
        senses = self.synsets(word, pos="n")
        if not senses or not self.noun_share(word) >= 0.5:
            return False
        with self._lock:
            first = senses[0].lexname() in THING_FILES and not self._is_place_synset(senses[0].name())
        return (first and self.thing_share(word) >= THING_SHARE and self.place_share(word) < THING_PLACE_BELOW
                and not self.room_share(word) > 0.0 and not self.room_namesakes(word))

    def room_namesakes(self, word: str) -> list[str]:
        """The other words of the word's noun senses (their WordNet lemmas, not the word or its noun base
        form) that have a room sense of their own (:meth:`room_share` above 0), in WordNet's order:
        "tub" → ["bath"] (bathtub.n.01: bathtub, bathing tub, bath, tub), "couch" → ["lounge"],
        "wardrobe" → ["closet"], "fridge" → []. Words of a lemma are joined by spaces."""
        lemma = self._lemma(word)
        with self._lock:
            base = self._wn.morphy(lemma, "n")
            others = [name.lower() for synset in self._wn.synsets(lemma, pos="n")
                      for name in synset.lemma_names()]
        own = {lemma, base} if base else {lemma}
        candidates = dict.fromkeys(o for o in others if o not in own)
        return [c.replace("_", " ") for c in candidates if self.room_share(c) > 0.0]

    def synonyms_among(self, word: str, others: Sequence[str]) -> list[str]:
        """Those of ``others`` that share one of the two commonest noun senses of ``word`` as one of
        their own two commonest ("parlour" and "living room": living_room.n.01), in their order."""
        senses = set(self.synsets(word, pos="n")[:2])
        if not senses:
            return []
        return [o for o in others if o != word and senses & set(self.synsets(o, pos="n")[:2])]

    # ------------------------------------------------------------------ unheard names
    def _variants(self, words: list[str]) -> list:
        """Noun senses of a name written with spaces, joined ("guest room" -> "guestroom") or
        hyphenated; its place senses first (``where`` asks for a place: "lounge" the room before
        "lounge" the sofa), each group in WordNet's order (commonest first)."""
        for text in (" ".join(words), "".join(words), "-".join(words)):
            senses = self.synsets(text, pos="n")
            if senses:
                with self._lock:
                    places = [self._is_place_synset(synset.name()) for synset in senses]
                return ([sy for sy, p in zip(senses, places, strict=True) if p]
                        + [sy for sy, p in zip(senses, places, strict=True) if not p])
        return []

    def _by_senses(self, senses: list, known: dict[str, str], kinds: bool = False,
                   located: bool = False) -> LexiconMatch | None:
        """A known name that is a synonym of one of ``senses`` or is in their definitions (or in
        their hypernyms' definitions); with ``kinds`` (the asked name's own senses, not those of a
        word of it or of a compound, one relation away already), before the hypernyms'
        definitions, a known name that is a hypernym of the commonest sense ("dining hall" is a
        "dining room"). A phrase of location is skipped in a definition (:meth:`_gloss_terms`); with
        ``located``, only in a definition of a place: "a small area off *a kitchen*" says where a
        dinette is, "immersed *in water*" what soaking is done with."""
        for synset in senses:
            for lemma in synset.lemmas():
                text = lemma.name().replace("_", " ").lower()
                if text in known:
                    return LexiconMatch(known[text], 1.0, "synonym")
        for synset in senses[:1]:  # the commonest sense, then its hypernyms
            for depth, layer in enumerate(([synset], synset.hypernyms())):
                for gloss in layer:
                    skip = True
                    if located:
                        with self._lock:
                            skip = self._is_place_synset(gloss.name())
                    for token in self._gloss_terms(gloss.definition(), skip_located=skip):
                        if token in known:
                            return LexiconMatch(known[token], 0.9 - 0.1 * depth, "gloss")
                if depth == 0 and kinds:
                    for kind in synset.hypernyms():
                        for lemma in kind.lemmas():
                            text = lemma.name().replace("_", " ").lower()
                            if text in known:
                                return LexiconMatch(known[text], 0.85, "hypernym")
        return None

    def _derived(self, words: str, known: dict[str, str]) -> LexiconMatch | None:
        """A known name derived from the word (WordNet's derivational links: "sleeping" -> "sleep"
        -> "sleeper"), or a verb of the same synset as the word's verb ("bathing" -> "bathe", whose
        synset holds the verb "bath")."""
        for word in words.split():
            for base in sorted(self.base_forms(word)):
                for pos in ("v", "n"):
                    for synset in self.synsets(base, pos=pos)[:3]:
                        for lemma in synset.lemmas():
                            if lemma.name().lower() != base:
                                continue
                            related = list(lemma.derivationally_related_forms())
                            if pos == "v":  # the verb's synonyms (noun synonyms are _by_senses')
                                related += [other for other in synset.lemmas() if other is not lemma]
                            for other in related:
                                text = other.name().replace("_", " ").lower()
                                if text in known:
                                    return LexiconMatch(known[text], 0.7, "derivation")
        return None

    def split_compound(self, word: str) -> list[str] | None:
        """A single word WordNet does not know, read as two nouns it knows ("mudroom" -> "mud room",
        "cookroom" -> "cook room"; each part at least three letters, the longest known tail), or
        None."""
        word = word.lower()
        if " " in word or self.synsets(word):
            return None
        for i in range(3, len(word) - 2):
            head, tail = word[:i], word[i:]
            if self.synsets(tail, pos="n") and self.synsets(head):
                return [head, tail]
        return None

    def base_forms(self, word: str) -> set[str]:
        """The word and its WordNet base forms as a noun and a verb ("sitting" -> "sit")."""
        forms = {word}
        with self._lock:
            for pos in ("n", "v"):
                base = self._wn.morphy(word, pos)
                if base:
                    forms.add(base)
        return forms

    def _defined_by(self, words: str, known: dict[str, str]) -> LexiconMatch | None:
        """The known place name whose commonest sense's definition holds one of ``words`` (in a base
        form) or a synonym of their verbs ("cook": "prepare"), if the names that do are one concept
        (synonyms: "bedroom", "bedchamber")."""
        wanted = {f for w in words.split() for f in self.base_forms(w)}
        for base in list(wanted):  # and the verb's synonyms ("cook": "prepare", as in "preparing meals")
            wanted |= {lemma.name().lower() for synset in self.synsets(base, pos="v")[:3]
                       for lemma in synset.lemmas() if "_" not in lemma.name()}
        hits, concepts = [], set()
        for text, original in known.items():
            senses = self.synsets(text, pos="n")[:1]
            if not senses:
                continue
            terms = {f for t in self._gloss_terms(senses[0].definition()) if " " not in t
                     for f in self.base_forms(t)}
            with self._lock:
                place = self._is_place_synset(senses[0].name())
            if place and terms & wanted:  # a place defined by the word ("a bed" is no place)
                hits.append(original)
                concepts.add(senses[0])  # synonyms ("bedroom", "bedchamber") are one concept
        return LexiconMatch(hits[0], 0.7, "definition") if len(concepts) == 1 else None

    def _compound_of(self, modifier: str, head: str, known: dict[str, str],
                     located: bool = False) -> LexiconMatch | None:
        """A known name related (:meth:`_by_senses`: a synonym, or in the definition) to the places that
        WordNet names by ``modifier`` before another head ("comfort room", unknown to WordNet ->
        "comfort station": "a toilet that is available to the public", a synonym of "restroom"), when
        those compounds' known names are one (several places named so, or none: None)."""
        prefix = "_".join(modifier.split()) + "_"
        found: dict[str, LexiconMatch] = {}
        for lemma in self._compounds(prefix):
            if lemma.count("_") != prefix.count("_") or lemma.endswith("_" + head):
                continue  # the modifier before one other word, not the name asked for itself
            senses = self.synsets(lemma, pos="n")[:1]
            with self._lock:
                if not senses or not self._is_place_synset(senses[0].name()):
                    continue
            match = self._by_senses(senses, known, located=located)
            if match is not None and match.name != lemma.rsplit("_", 1)[-1]:  # "great hall": a hall,
                found.setdefault(match.name, match)  # which says nothing of a "great room"
        if len(found) != 1:
            return None
        match = next(iter(found.values()))
        return replace(match, score=match.score * 0.8, how=f"compound {match.how}")

    def _compounds(self, prefix: str) -> list[str]:
        """WordNet's noun lemmas starting with ``prefix`` ("comfort_"), from an index of them built
        once per lexicon."""
        with self._lock:
            if not hasattr(self, "_by_first"):
                by_first: dict[str, list[str]] = {}
                for lemma in self._wn.all_lemma_names(pos="n"):
                    if "_" in lemma:
                        by_first.setdefault(lemma.split("_", 1)[0], []).append(lemma)
                self._by_first = by_first
        return [lemma for lemma in self._by_first.get(prefix.split("_", 1)[0], [])
                if lemma.startswith(prefix)]

    def _general(self, word: str, known: dict[str, str]) -> bool:
        """Whether a head word is more general than the known names ("room", "area": a hypernym of
        one of their noun senses), so that the word before it says which place is meant."""
        heads = set(self.synsets(word, pos="n")[:3])
        if not heads or self.kinds_below(word) >= KINDS_BELOW:
            return True
        for text in known:
            for synset in self.synsets(text, pos="n")[:2]:
                with self._lock:
                    ancestors = set(synset.closure(lambda s: s.hypernyms()))
                if heads & ancestors:
                    return True
        return False

    def thing_words(self, name: str, known: Sequence[str]) -> list[str]:
        """The words of the thing a name nobody said is named after, when it is a kind of place after a
        thing: WordNet does not know the name whole (nor written as one word or hyphenated; a single
        word it does not know is read as two, :meth:`split_compound`), its head is general (a kind of
        place, or a hypernym of one of ``known``'s senses: "area", "room") and the commonest noun
        sense of the words before it is a thing (:data:`THING_FILES`) and none of their senses is a
        place (:meth:`place_share` 0: "washbasin area", washbasin.n.01, an artifact; not "lounge room"
        nor "laundry area", whose words can name the place itself). Then: the words before the head,
        the other lemmas of that sense (its synonyms: "basin", "washbowl", "washstand", "lavatory"),
        then those of its hypernyms (its kind: "sink"), lower case, words separated by spaces; else
        []."""
        words = name.lower().split()
        if len(words) == 1:
            words = self.split_compound(words[0]) or words
        if len(words) < 2 or self._variants(words):
            return []
        head, modifier = words[-1], " ".join(words[:-1])
        if not self._general(head, {k.lower(): k for k in known}):
            return []
        senses = self.synsets(modifier, pos="n")[:1]
        if not senses or self.place_share(modifier) > 0:  # a word that can name a place ("lounge",
            return []  # "laundry", "bath") before a kind of place names that place, not a thing there
        with self._lock:
            if senses[0].lexname() not in THING_FILES or self._is_place_synset(senses[0].name()):
                return []
            layers = [senses[0], *senses[0].hypernyms()]
        out: list[str] = [modifier]  # the thing as asked, then its synonyms, then its kinds
        for synset in layers:
            for lemma in synset.lemmas():
                text = lemma.name().replace("_", " ").lower()
                if text not in out:
                    out.append(text)
        return out

    def kinds_below(self, word: str) -> int:
        """The most kinds (hyponyms, at every depth) under one of the word's two commonest noun senses:
        195 for "room", 91 for "area", 55 for "place" against 4 for "kitchen", 11 for "bedroom";
        0 for a word without noun senses. A term is judged by its own senses only."""
        best = 0
        for synset in self.synsets(word, pos="n")[:2]:
            with self._lock:
                best = max(best, sum(1 for _ in synset.closure(lambda s: s.hyponyms())))
        return best

    def kind_heads(self, word: str) -> frozenset[str]:
        """The names of the word's three commonest noun senses (a word is a WordNet kind of another when
        one of them is among the other's :meth:`kind_ancestors`)."""
        return frozenset(synset.name() for synset in self.synsets(word, pos="n")[:3])

    def kind_ancestors(self, text: str) -> frozenset[str]:
        """The names of the hypernyms (at every depth) of the two commonest noun senses of ``text``
        (or, when it has none, of the commonest of its head word): where another word's
        :meth:`kind_heads` are looked for."""
        ancestors: set[str] = set()
        for synset in self.synsets(text, pos="n")[:2] or self.synsets(text.split()[-1], pos="n")[:1]:
            with self._lock:
                ancestors.update(s.name() for s in synset.closure(lambda s: s.hypernyms()))
        return frozenset(ancestors)

    def closest(self, name: str, known: list[str], similarity: bool = True,
                located: bool = False) -> LexiconMatch | None:
        """The known name that stands for ``name`` (a name nobody said), or None.

        In order: a known name that is a synonym of ``name`` (shares a noun synset; "privy" ->
        "toilet"), or is in a definition of ``name``'s senses or of their hypernyms ("powder room":
        "a toilet that is available to the public") or is a hypernym of its commonest sense ("dining
        hall", a dining room); for a name of several words (a single word
        WordNet does not know is first read as two nouns it knows, :meth:`split_compound`:
        "mudroom" -> "mud room"), the words before a general head ("room", "area": a hypernym of
        known names, or :data:`KINDS_BELOW` kinds under it) or the head itself, when known ("kitchen
        nook" -> "kitchen"), a known term of the same words before another general head ("laundry
        area" -> "laundry room"), or found so (then also a known term of a synonym before another
        general head: "washing area" -> "laundry room"): a synonym or definition ("tub room" -> "tub" ->
        "bath"), the one place (or synonyms) defined by the word ("sleeping quarters" -> "bedroom":
        "a room used primarily for sleeping"), a synonym or definition of the one place WordNet
        names by the words before a general head and another word ("comfort room" -> "comfort
        station", a restroom; :meth:`_compound_of`: the same construction, nearer the name than a
        word derived from its modifier), a derivation or verb synonym ("bathing room" -> "bathe" ->
        "bath"); else the known name of highest Wu–Palmer similarity between noun senses (≥
        :data:`MIN_SIMILARITY`) of the name or its words, among near ties (kinds of room are all
        about as similar) the one whose definition shares most words with the name's or its
        kinds' (:meth:`_most_similar`: "rec room", "a room equipped for informal entertaining",
        shares nothing with "living room", its kind "family room", "a recreation room in a
        private house", does), and none when they share none. ``known``: candidate names
        (vocabulary tokens, lower case, words separated by spaces), most name-like first.
        ``similarity=False``: only the relations before similarity (synonym, gloss, head,
        definition, derivation). ``located``: a phrase of location in a definition is read unless the
        definition is a place's (:meth:`_by_senses`; the look-up of a name nobody said asks so, the
        stand-ins of ``what`` do not)."""
        words = name.lower().split()
        if not words or not known:
            return None
        if len(words) == 1:  # a compound written as one word ("mudroom"): its nouns
            words = self.split_compound(words[0]) or words
        known_set = {k.lower(): k for k in known}
        if name.lower() in known_set:
            return LexiconMatch(known_set[name.lower()], 1.0, "synonym")
        # only nouns (or terms with a noun head: "laundry room") can be the name of a place ("is" in a
        # definition is no answer)
        known_set = {k: v for k, v in known_set.items()
                     if self.synsets(k, pos="n") or (" " in k and self.synsets(k.split()[-1], pos="n"))}
        senses = self._variants(words)
        found = self._by_senses(senses, known_set, kinds=True, located=located)
        if found is not None:
            return found
        parts: list[str] = []
        if len(words) > 1:
            head, modifier = words[-1], " ".join(words[:-1])
            general = self._general(head, known_set)
            parts = [modifier] if general else [head, modifier]
            for part in parts:
                if part in known_set:
                    return LexiconMatch(known_set[part], 0.8, "head")
            if general:  # a known name of the same words before another general head: "laundry
                for text, original in known_set.items():  # area" -> "laundry room"
                    kw = text.split()
                    if len(kw) > 1 and " ".join(kw[:-1]) == modifier and self._general(kw[-1], known_set):
                        return LexiconMatch(original, 0.8, "head")
            for part in parts:
                found = self._by_senses(self._variants(part.split()), known_set, located=located)
                if found is not None:
                    return replace(found, score=found.score * 0.8, how=f"head {found.how}")
            mine = set(self.synsets(modifier, pos="n")[:3]) if general else set()
            for text, original in known_set.items():  # a known term of a synonym before another
                kw = text.split()  # general head: "washing area" -> "laundry room" (washing ~ laundry)
                if (mine and len(kw) > 1 and mine & set(self.synsets(" ".join(kw[:-1]), pos="n")[:3])
                        and self._general(kw[-1], known_set)):
                    return LexiconMatch(original, 0.8 * 0.8, "head synonym")
            for part in parts:  # a known name defined by the word: "sleeping quarters" -> bedroom,
                found = self._defined_by(part, known_set)  # "a room used primarily for sleeping"
                if found is not None:
                    return found
            # the modifier's own compound naming a place ("comfort room" -> "comfort station", a
            # restroom; "dressing area" -> "dressing room"), then a derivation ("bathing" -> "bathe")
            later = itertools.chain((self._compound_of(modifier, head, known_set, located)
                                     for _ in range(general)),
                                    (self._derived(part, known_set) for part in parts))
            found = next((f for f in later if f is not None), None)
            if found is not None:
                return found
        if not similarity:
            return None
        # similarity of the nouns (the name's, else its words')
        groups = [g for g in ([senses] if senses else [self._variants(p.split()) for p in parts]) if g]
        return self._most_similar(groups, known_set)

    def _most_similar(self, groups: list[list], known_set: dict[str, str]) -> LexiconMatch | None:
        """The known name of highest Wu–Palmer similarity (≥ :data:`MIN_SIMILARITY`) between its
        commonest noun sense and the commonest of each group of ``groups`` (the asked name's senses,
        or its words'); among near ties (rooms are all siblings under "room"), the one whose
        definition shares most words with the asked senses' definitions and lemmas and their kinds'
        (direct hyponyms: extended Lesk), words common to many known names' definitions left out;
        None when the best shares none."""
        firsts = {text: self.synsets(text, pos="n")[:1] for text in known_set}
        firsts = {text: f[0] for text, f in firsts.items() if f}
        if not groups or not firsts:
            return None
        scores: dict[str, float] = {}
        for text, other in firsts.items():
            with self._lock:
                scores[text] = max(g[0].wup_similarity(other) or 0.0 for g in groups)
        top = max(scores.values())
        if top < MIN_SIMILARITY:
            return None
        near = [t for t, v in scores.items() if v >= top - 0.05]
        glosses = {t: set(self._gloss_terms(firsts[t].definition())) for t in firsts}
        frequency: dict[str, int] = {}
        for terms in glosses.values():
            for term in terms:
                frequency[term] = frequency.get(term, 0) + 1
        common = {t for t, c in frequency.items() if c > max(2, len(glosses) // 5)} | _FUNCTION_WORDS
        asked: set[str] = set()
        for synset in (s for g in groups for s in g[:2]):  # the senses and their kinds (extended Lesk:
            with self._lock:  # "rec room" is "a room equipped for …", a family room "… in a private house")
                related = [synset, *synset.hyponyms()]
            for sense in related:
                asked |= set(self._gloss_terms(sense.definition()))
                asked |= {w for lemma in sense.lemmas() for w in lemma.name().lower().split("_")}
        overlap = {t: len((glosses[t] & asked) - common) for t in near}
        near.sort(key=lambda t: (-overlap[t], -scores[t]))
        if overlap[near[0]] == 0:  # similar kinds (all rooms), nothing in common said: no answer
            return None
        return LexiconMatch(known_set[near[0]], float(scores[near[0]]), "similarity")

    @staticmethod
    def _gloss_terms(definition: str, skip_located: bool = False) -> list[str]:
        """Adjacent word pairs, then words of a definition, lower case, in order. ``skip_located``:
        leave out words in a phrase of location ("a small area off of *a kitchen*": the dinette is
        beside the kitchen, not the kitchen), i.e. after one of :data:`_LOCATIVE` and any
        articles."""
        words = [w.strip(".,;:()'\"").lower() for w in definition.split()]
        words = [w for w in words if w]
        if skip_located:
            kept, located = [], False
            for w in words:
                if w in _LOCATIVE:
                    located = True
                elif located:
                    located = w in ("a", "an", "the", "of")  # the noun located ends the phrase
                    continue
                kept.append(w)
            words = kept
        return [*(" ".join(p) for p in itertools.pairwise(words)), *words]

    def seldom_in(self, word: str, other: str) -> bool:
        """Whether ``word`` shares noun senses with ``other`` only in senses WordNet's tagged texts never
        use ``word`` in, while they use it in another of its noun senses: "bathroom" for "privy" (6 uses
        as the room with the bathtub, none as a toilet), not "hall" for "foyer" (10 of its 46 uses in
        the sense of an anteroom) nor "parlour" for "living room" (no tagged use at all)."""
        lemma = self._lemma(word)
        shared = set(self.synsets(other, pos="n"))
        uses = {synset: sum(lem.count() for lem in synset.lemmas() if lem.name().lower() == lemma)
                for synset in self.synsets(word, pos="n")}
        common = [synset for synset in uses if synset in shared]
        return (bool(common) and all(uses[synset] == 0 for synset in common)
                and any(n > 0 for synset, n in uses.items() if synset not in shared))

    def thing_sense_words(self, word: str) -> list[str]:
        """The words of every sense of ``word`` that is a thing (:data:`THING_FILES`), in WordNet's order
        (commonest first): each sense's lemmas, then its kinds' (direct hypernyms'), lower case, words
        separated by spaces, each once ("bunk": "bunk", "feed bunk", "manger", "trough" — a feeding
        trough, its commonest sense —, then "berth", "built in bed", "bed", …); [] when one of its senses
        is a place (:meth:`place_share` > 0: "lounge", "bath" name the place, not a thing there)."""
        if self.place_share(word) > 0:
            return []
        out: list[str] = []
        for synset in self.synsets(word, pos="n"):
            with self._lock:
                if synset.lexname() not in THING_FILES:
                    continue
                layers = [synset, *synset.hypernyms()]
            for layer in layers:
                for lemma in layer.lemmas():
                    text = lemma.name().replace("_", " ").replace("-", " ").lower()
                    if text not in out:
                        out.append(text)
        return out


_load_lock = threading.Lock()  # (lexicon() and the facts' lookups load WordNet once)


@functools.lru_cache(maxsize=1)
def _load(folder: str) -> Lexicon:
    return Lexicon(Path(folder))


def lexicon() -> Lexicon | None:
    """The process's WordNet lexicon, or None when NLTK or the database is missing or the lexicon
    is turned off (:func:`lexicon_unavailable_reason` says which)."""
    if lexicon_unavailable_reason() is not None:
        return None
    folder = _wordnet_folder()
    assert folder is not None
    with _load_lock:  # threads asking at once (a server loading it at start) load it once
        return _load(str(folder))
