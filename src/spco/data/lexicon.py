"""WordNet, read offline: what a word can be (noun, verb, …), whether a noun names a place, and
which known place name a name nobody said stands for.

The lexicon is the English WordNet 3.0 of the Debian package ``wordnet-base`` (files in
``/usr/share/wordnet``), read through NLTK's :class:`~nltk.corpus.reader.wordnet.WordNetCorpusReader`
(the optional extra ``spco[words]``: ``pip install "spco[words]"`` and ``apt-get install
wordnet-base``). Nothing is downloaded. Debian's package lacks the ``lexnames`` file NLTK's reader
opens (the table of WordNet's 45 lexicographer files, fixed by the format, lexnames(5WN)), so the
reader is given a private folder (under ``~/.cache/spco``, or ``SPCO_CACHE_DIR``) holding copies of
the package's files (NLTK reads no linked file) and that table. ``SPCO_WORDNET`` names another
folder of WordNet database files; ``SPCO_WORDNET=off`` turns the lexicon off (spco then works as
without it: see docs/model.md).

Without the lexicon (:func:`lexicon` returns ``None``) every function of spco that uses it falls
back to what the data alone say: the naming rule weighs words by their place in the sentences only,
and ``where`` with a name nobody said is an unknown name, as before.

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
import hashlib
import itertools
import os
import shutil
import threading
import warnings
from dataclasses import dataclass
from pathlib import Path

__all__ = ["PLACE_ROOTS", "Lexicon", "LexiconMatch", "lexicon", "lexicon_unavailable_reason"]

#: Where Debian's wordnet-base puts the database files.
DEBIAN_WORDNET = Path("/usr/share/wordnet")

#: The WordNet noun concepts that places in a home fall under (see the module docstring).
PLACE_ROOTS = ("room.n.01", "area.n.05", "building.n.01", "structure.n.01", "location.n.01",
               "housing.n.01", "way.n.06")

#: WordNet 3.0's lexicographer files by number (lexnames(5WN)); written as the ``lexnames`` file
#: NLTK's reader needs and Debian's package does not ship.
_LEXNAMES = ("adj.all", "adj.pert", "adv.all", "noun.Tops", "noun.act", "noun.animal", "noun.artifact",
             "noun.attribute", "noun.body", "noun.cognition", "noun.communication", "noun.event",
             "noun.feeling", "noun.food", "noun.group", "noun.location", "noun.motive", "noun.object",
             "noun.person", "noun.phenomenon", "noun.plant", "noun.possession", "noun.process",
             "noun.quantity", "noun.relation", "noun.shape", "noun.state", "noun.substance", "noun.time",
             "verb.body", "verb.change", "verb.cognition", "verb.communication", "verb.competition",
             "verb.consumption", "verb.contact", "verb.creation", "verb.emotion", "verb.motion",
             "verb.perception", "verb.possession", "verb.social", "verb.stative", "verb.weather", "adj.ppl")
_CATEGORY = {"adj": 3, "adv": 4, "noun": 1, "verb": 2}
_DATABASE = ("data.noun", "data.verb", "data.adj", "data.adv", "index.noun", "index.verb", "index.adj",
             "index.adv", "noun.exc", "verb.exc", "adj.exc", "adv.exc", "cntlist.rev")


def _cache_root() -> Path:
    return Path(os.environ.get("SPCO_CACHE_DIR") or Path.home() / ".cache" / "spco")


def _wordnet_folder() -> Path | None:
    """The folder of WordNet database files to read (``SPCO_WORDNET`` or Debian's), or None."""
    chosen = os.environ.get("SPCO_WORDNET", "").strip()
    if chosen.lower() in ("off", "0", "none", "no"):
        return None
    folder = Path(chosen).expanduser() if chosen else DEBIAN_WORDNET
    return folder if all((folder / f).is_file() for f in _DATABASE) else None


def lexicon_unavailable_reason() -> str | None:
    """Why :func:`lexicon` returns None (a sentence for messages and skips), or None when it works."""
    chosen = os.environ.get("SPCO_WORDNET", "").strip()
    if chosen.lower() in ("off", "0", "none", "no"):
        return "the lexicon is turned off (SPCO_WORDNET=off)"
    try:
        import nltk  # noqa: F401
    except ImportError:
        return "NLTK is not installed (pip install 'spco[words]')"
    if _wordnet_folder() is None:
        where = chosen or str(DEBIAN_WORDNET)
        return f"no WordNet database in {where} (apt-get install wordnet-base)"
    return None


def _reader_folder(source: Path) -> Path:
    """A private folder with links to ``source``'s database files and the ``lexnames`` table."""
    digest = hashlib.sha256(str(source.resolve()).encode()).hexdigest()[:12]
    folder = _cache_root() / f"wordnet-{digest}"
    folder.mkdir(parents=True, exist_ok=True)
    for name in _DATABASE:
        target, original = folder / name, (source / name).resolve()
        if not target.exists() or target.stat().st_size != original.stat().st_size:
            # NLTK refuses files that resolve outside its root and hard-linked files: a copy (27 MB)
            tmp = folder / f".{name}.{os.getpid()}"
            shutil.copyfile(original, tmp)
            os.replace(tmp, target)
    lexnames = folder / "lexnames"
    if not lexnames.exists():
        text = "".join(f"{i:02d}\t{name}\t{_CATEGORY[name.split('.')[0]]}\n"
                       for i, name in enumerate(_LEXNAMES))
        tmp = folder / f".lexnames.{os.getpid()}"
        tmp.write_text(text, encoding="ascii")
        os.replace(tmp, lexnames)
    return folder


@dataclass(frozen=True)
class LexiconMatch:
    """A known name found for a name nobody said (:meth:`Lexicon.closest`).

    name: the known name; score: its similarity in (0, 1] (1: a synonym); how: ``"synonym"``,
    ``"head"`` (same head noun: "kitchen nook" -> "kitchen"), ``"gloss"`` (the known name is in the
    asked name's definition) or ``"similarity"`` (WordNet's Wu–Palmer similarity of the nouns)."""

    name: str
    score: float
    how: str


class Lexicon:
    """WordNet through NLTK (use :func:`lexicon`, which caches one per process)."""

    def __init__(self, folder: Path) -> None:
        import nltk.data
        from nltk.corpus.reader.wordnet import WordNetCorpusReader

        root = _reader_folder(folder)
        if str(root) not in nltk.data.path:
            nltk.data.path.append(str(root))  # NLTK reads corpora only under its data path
        class _Reader(WordNetCorpusReader):  # type: ignore[misc]
            def map_wn(self, version: str = "wordnet") -> None:
                """No mapping to another WordNet's synsets (only the Open Multilingual Wordnet,
                which spco does not read, needs it; NLTK would look for its own download)."""
                return None

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "the multilingual functions are not available"
            self._wn = _Reader(str(root), None)
        self._roots = [self._wn.synset(name) for name in PLACE_ROOTS]
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
        lemma = self._lemma(word)
        weights = {"n": 0.0, "other": 0.0}
        for synset in self.synsets(word):
            count = sum(lem.count() for lem in synset.lemmas() if lem.name().lower() == lemma)
            weights["n" if synset.pos() == "n" else "other"] += 1.0 + count
        total = weights["n"] + weights["other"]
        return weights["n"] / total if total else float("nan")

    @functools.lru_cache(maxsize=65536)  # noqa: B019 - one lexicon per process
    def _is_place_synset(self, name: str) -> bool:
        synset = self._wn.synset(name)
        if synset.lexname() == "noun.location":
            return True
        closure = {synset, *synset.closure(lambda s: s.hypernyms() + s.instance_hypernyms())}
        return any(root in closure for root in self._roots)

    def place_share(self, word: str) -> float:
        """Share of the word's noun senses (weighted as :meth:`noun_share`) that are places (see the
        module docstring); NaN for a word without noun senses."""
        lemma = self._lemma(word)
        place = total = 0.0
        for synset in self.synsets(word, pos="n"):
            weight = 1.0 + sum(lem.count() for lem in synset.lemmas() if lem.name().lower() == lemma)
            total += weight
            with self._lock:
                if self._is_place_synset(synset.name()):
                    place += weight
        return place / total if total else float("nan")

    # ------------------------------------------------------------------ unheard names
    def closest(self, name: str, known: list[str]) -> LexiconMatch | None:
        """The known name that stands for ``name`` (a name nobody said), or None.

        In order: a known name that is a synonym of ``name`` (shares a noun synset); a known name
        in a definition (gloss) of ``name``'s noun senses or of their hypernyms (a "powder room" is
        "a toilet that …"); ``name``'s head noun (its last word) or, for a head such as "room" or
        "area", its first word, if known ("kitchen nook" -> "kitchen"); else the known name of
        highest Wu–Palmer similarity between their noun senses (≥ 0.5). Known names are
        vocabulary tokens (lower case, words separated by spaces)."""
        words = name.lower().split()
        if not words or not known:
            return None
        known_set = {k.lower(): k for k in known}
        if name.lower() in known_set:
            return LexiconMatch(known_set[name.lower()], 1.0, "synonym")
        senses = self.synsets(name, pos="n")
        # 1. synonyms: a lemma of one of the name's senses is a known name
        for synset in senses:
            for lemma in synset.lemmas():
                text = lemma.name().replace("_", " ").lower()
                if text in known_set:
                    return LexiconMatch(known_set[text], 1.0, "synonym")
        # 2. glosses: a known name in the definition of a sense or of its hypernyms
        for depth, group in enumerate(self._gloss_layers(senses)):
            for synset in group:
                for token in self._gloss_terms(synset.definition()):
                    if token in known_set:
                        return LexiconMatch(known_set[token], 0.9 - 0.1 * depth, "gloss")
        # 3. the head word, or the modifier of a general head ("nook", "area", "corner")
        if len(words) > 1:
            head, first = words[-1], " ".join(words[:-1])
            if head in known_set:
                return LexiconMatch(known_set[head], 0.8, "head")
            if first in known_set:
                return LexiconMatch(known_set[first], 0.75, "head")
            senses = senses or self.synsets(head, pos="n")
        # 4. similarity of the nouns
        best: LexiconMatch | None = None
        for text, original in known_set.items():
            for synset in senses[:4]:
                for other in self.synsets(text, pos="n")[:4]:
                    with self._lock:
                        score = synset.wup_similarity(other) or 0.0
                    if score >= 0.5 and (best is None or score > best.score):
                        best = LexiconMatch(original, float(score), "similarity")
        return best

    @staticmethod
    def _gloss_layers(senses: list) -> list[list]:
        """The senses, then their hypernyms (two layers of definitions to read)."""
        return [senses, [h for s in senses for h in s.hypernyms()]]

    @staticmethod
    def _gloss_terms(definition: str) -> list[str]:
        """Words and adjacent word pairs of a definition, lower case, in order."""
        words = [w.strip(".,;:()'\"").lower() for w in definition.split()]
        words = [w for w in words if w]
        return [*(" ".join(p) for p in itertools.pairwise(words)), *words]


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
    return _load(str(folder))
