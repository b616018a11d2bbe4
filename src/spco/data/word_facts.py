"""WordNet's facts of words, kept in files: what :mod:`spco.data.lexicon` says of a word or a name
(:class:`WordFacts`: known, noun share, place share; :class:`KindFacts`; the closest learnt name of a
name never heard), computed once per word and WordNet database and read from a file beside the
reader's folder afterwards, so that a process answering a few words does not load WordNet (seconds of
CPU). The same numbers as asking :func:`spco.data.lexicon.lexicon` each time."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import math
import os
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from spco.data.lexicon import (
    Lexicon,
    LexiconMatch,
    _cache_root,
    _load,
    _load_lock,
    _wordnet_folder,
    lexicon_unavailable_reason,
)
from spco.data.wordnet_files import DATABASE

__all__ = ["KindFacts", "WordFacts", "closest_names", "kind_facts", "word_facts"]


@dataclass(frozen=True)
class WordFacts:
    """What WordNet says of one word, as :func:`spco.model.name_evidence.lexical_features` uses it:
    ``known`` (:meth:`Lexicon.knows`), ``noun_share`` (:meth:`Lexicon.noun_share`) and
    ``place_share`` (:meth:`Lexicon.place_share`); the shares are NaN for an unknown word."""

    known: bool
    noun_share: float
    place_share: float


@dataclass(frozen=True)
class KindFacts:
    """What WordNet says of one word's kinds, as :func:`spco.model.name_evidence.channel_evidence`
    uses them: ``kinds_below`` (:meth:`Lexicon.kinds_below`)."""

    kinds_below: int


#: Format of the file of :func:`word_facts` (a file of another format is computed again; 2: places
#: without :data:`NOT_PLACE_ROOTS`; 3: the place share among the physical senses).
_FACTS_FORMAT = 3
#: Format of the file of :func:`kind_facts` (2: only the kinds below a word, which is all the
#: evidence reads).
_KINDS_FORMAT = 2
_facts_lock = threading.Lock()
_facts_memory: dict[str, dict[str, WordFacts]] = {}
#: The facts kept of each word by a cache file (:class:`WordFacts`, :class:`KindFacts`).
_F = TypeVar("_F")


def _facts_file(folder: Path, what: str = "facts") -> Path:
    """The file of word facts (``what``: "facts" or "kinds") for the WordNet files in ``folder``:
    named by a digest of their names, sizes and modification times and of NLTK's version (a changed
    database or reader is a new file), once per process and cache folder: every `what` asks."""
    return _facts_file_in(folder, what, _cache_root())


@functools.lru_cache(maxsize=16)
def _facts_file_in(folder: Path, what: str, root: Path) -> Path:
    from importlib.metadata import PackageNotFoundError, version

    digest = hashlib.sha256(str(folder.resolve()).encode())
    try:
        digest.update(version("nltk").encode())
    except PackageNotFoundError:
        pass
    for name in DATABASE:
        stat = (folder / name).stat()
        digest.update(f"{name}:{stat.st_size}:{stat.st_mtime_ns}".encode())
    return root / f"wordnet-{what}-{digest.hexdigest()[:16]}.json"


def _read_cache(path: Path, fmt: int, decode: Callable[[Any], _F]) -> dict[str, _F]:
    """The words' facts of a cache file written by :func:`_write_cache` (empty when there is no file
    yet or it is not one of ours: the facts are computed again and the file rewritten)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        if data.get("format") != fmt:
            return {}
        return {w: decode(row) for w, row in data["words"].items()}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return {}


def _write_cache(path: Path, fmt: int, rows: dict[str, Any]) -> None:
    """Write ``{"format": fmt, "words": rows}`` to ``path`` atomically (nothing on a read-only cache:
    the facts are computed again next time)."""
    text = json.dumps({"format": fmt, "words": dict(sorted(rows.items()))})
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except OSError:
        pass


def _cached_facts(words: Sequence[str], what: str, fmt: int, memory: dict[str, dict[str, _F]],
                  compute: Callable[[Lexicon, str], _F], encode: Callable[[_F], Any],
                  decode: Callable[[Any], _F]) -> dict[str, _F] | None:
    """The facts of ``words`` from the cache file ``what`` (and this process's ``memory`` of it),
    WordNet loaded only for words not in it yet, which are then added; None when the lexicon is
    unavailable."""
    if lexicon_unavailable_reason() is not None:
        return None
    folder = _wordnet_folder()
    assert folder is not None
    path = _facts_file(folder, f"{what}-v{fmt}")  # one file per format: codes of two formats do not
    key = str(path)  # rewrite each other's file
    with _facts_lock:
        facts = memory.get(key)
        if facts is None:
            facts = memory[key] = _read_cache(path, fmt, decode)
        missing = [w for w in dict.fromkeys(words) if w not in facts]
        if missing:
            # one process at a time fills the file: processes missing the same words at once (spco
            # demo's two on a first run) load WordNet (seconds of CPU) once, the others read its answers
            with _file_lock(path):
                on_file = _read_cache(path, fmt, decode)
                facts.update({w: f for w, f in on_file.items() if w not in facts})
                missing = [w for w in missing if w not in facts]
                if missing:
                    with _load_lock:
                        lex = _load(str(folder))
                    for word in missing:
                        facts[word] = compute(lex, word)
                    _write_cache(path, fmt, {w: encode(f) for w, f in {**on_file, **facts}.items()})
        return {w: facts[w] for w in words}


@contextlib.contextmanager
def _file_lock(path: Path) -> Iterator[None]:
    """Hold an exclusive lock between processes on a lock file beside ``path`` (POSIX ``flock``);
    without ``fcntl`` or where the lock file cannot be made (a read-only cache), no lock: each
    process then computes what it misses, the same answers."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle = open(path.with_name(f".{path.name}.lock"), "a")
    except OSError:
        yield
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _nan_or(x: float | None) -> float:
    return math.nan if x is None else float(x)


def _number(x: float) -> float | None:
    return None if math.isnan(x) else x


def _word_facts_of(lex: Lexicon, word: str) -> WordFacts:
    known = lex.knows(word)
    return WordFacts(known, lex.noun_share(word) if known else math.nan,
                     lex.place_share(word) if known else math.nan)


def word_facts(words: Sequence[str]) -> dict[str, WordFacts] | None:
    """:class:`WordFacts` of each of ``words`` (lower-case words or terms), or None when the lexicon
    is unavailable (:func:`lexicon_unavailable_reason`).

    The facts are a function of the word and the WordNet files only, so they are kept in a file
    beside the reader's folder (``$SPCO_CACHE_DIR``, default ``~/.cache/spco``): WordNet (and
    NLTK, seconds to import and read) is loaded only for words not in it yet, which are then added.
    The same numbers as asking :func:`lexicon` each time."""
    return _cached_facts(
        words, "facts", _FACTS_FORMAT, _facts_memory, _word_facts_of,
        lambda f: [f.known, _number(f.noun_share), _number(f.place_share)],
        lambda row: WordFacts(bool(row[0]), _nan_or(row[1]), _nan_or(row[2])))


_kinds_memory: dict[str, dict[str, KindFacts]] = {}


def kind_facts(words: Sequence[str]) -> dict[str, KindFacts] | None:
    """:class:`KindFacts` of each of ``words``, or None when the lexicon is unavailable
    (:func:`lexicon_unavailable_reason`); kept in a file as :func:`word_facts` keeps its facts
    (WordNet is loaded only for words not in it yet). The same numbers as asking :func:`lexicon`."""
    return _cached_facts(
        words, "kinds", _KINDS_FORMAT, _kinds_memory,
        lambda lex, word: KindFacts(lex.kinds_below(word)),
        lambda f: [f.kinds_below],
        lambda row: KindFacts(int(row[0])))


#: Format of the file of :func:`closest_names`.
_CLOSEST_FORMAT = 1
_closest_memory: dict[str, dict[str, LexiconMatch | None]] = {}
#: Separates the asked name from the candidates, and the candidates, in a key of :func:`closest_names`.
_ASKED_SEP, _KNOWN_SEP = "\t", "|"


def _closest_of(lex: Lexicon, key: str) -> LexiconMatch | None:
    name, _, known = key.partition(_ASKED_SEP)
    return lex.closest(name, known.split(_KNOWN_SEP) if known else [])


@functools.lru_cache(maxsize=1)
def _code_digest() -> str:
    """A digest of :mod:`spco.data.lexicon`'s and this module's source: :meth:`Lexicon.closest` is
    spco's code, so its remembered answers are kept per version of it (a changed rule starts a new
    file)."""
    from spco.data import lexicon as lexicon_module

    digest = hashlib.sha256()
    for source in (lexicon_module.__file__, __file__):
        digest.update(Path(source).read_bytes())
    return digest.hexdigest()[:12]


def closest_names(queries: Sequence[tuple[str, Sequence[str]]]) -> list[LexiconMatch | None] | None:
    """:meth:`Lexicon.closest` of each ``(name, known)`` of ``queries``, or None when the lexicon is
    unavailable (:func:`lexicon_unavailable_reason`); kept in a file as :func:`word_facts` keeps its
    facts (WordNet is loaded only for queries not in it yet). The same matches as asking
    :func:`lexicon`."""
    keys = [name + _ASKED_SEP + _KNOWN_SEP.join(known) for name, known in queries]
    found = _cached_facts(
        keys, f"closest-{_code_digest()}", _CLOSEST_FORMAT, _closest_memory, _closest_of,
        lambda m: None if m is None else [m.name, m.score, m.how],
        lambda row: None if row is None else LexiconMatch(str(row[0]), float(row[1]), str(row[2])))
    return None if found is None else [found[k] for k in keys]
