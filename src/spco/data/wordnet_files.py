"""How NLTK's WordNet reader is given Debian's WordNet files (:mod:`spco.data.lexicon` asks it).

NLTK's :class:`~nltk.corpus.reader.wordnet.WordNetCorpusReader` reads corpora only under its data
path, refuses files that resolve outside its root and hard-linked files, and opens ``lexnames`` (the
table of WordNet's 45 lexicographer files, lexnames(5WN)), which Debian's ``wordnet-base`` lacks:
:func:`reader_folder` makes a private folder with copies of the database files and that table, and
:func:`open_reader` reads it.
"""

from __future__ import annotations

import gc
import hashlib
import os
import shutil
import warnings
from pathlib import Path
from typing import Any

#: The database files the reader needs (``lexnames`` is written by :func:`reader_folder`).
DATABASE = ("data.noun", "data.verb", "data.adj", "data.adv", "index.noun", "index.verb", "index.adj",
            "index.adv", "noun.exc", "verb.exc", "adj.exc", "adv.exc", "cntlist.rev")

#: The files NLTK reads once from start to end when the reader starts (the lemma index, the
#: exception lists, the lexicographer files' table), opened as plain text files by
#: :func:`open_reader`; the others are read at byte offsets through NLTK's seekable reader.
READ_THROUGH = frozenset({*DATABASE[4:12], "lexnames"})

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


def reader_folder(source: Path, cache_root: Path) -> Path:
    """A private folder under ``cache_root`` with copies of ``source``'s database files and the
    ``lexnames`` table (made once; a file whose size differs from the source's is copied again)."""
    digest = hashlib.sha256(str(source.resolve()).encode()).hexdigest()[:12]
    folder = cache_root / f"wordnet-{digest}"
    folder.mkdir(parents=True, exist_ok=True)
    for name in DATABASE:
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


def open_reader(root: Path) -> Any:
    """NLTK's WordNet reader of the folder ``root`` (made by :func:`reader_folder`)."""
    import nltk.data
    from nltk.corpus.reader.wordnet import WordNetCorpusReader

    if str(root) not in nltk.data.path:
        nltk.data.path.append(str(root))  # NLTK reads corpora only under its data path

    class _Reader(WordNetCorpusReader):  # type: ignore[misc]
        def map_wn(self, version: str = "wordnet") -> None:
            """No mapping to another WordNet's synsets (only the Open Multilingual Wordnet,
            which spco does not read, needs it; NLTK would look for its own download)."""
            return None

        def open(self, fileid: str) -> Any:
            """The files of :data:`READ_THROUGH` as plain text files (the same lines; NLTK's
            seekable reader decodes the 147,306 lines of the lemma index ~0.3 s of CPU slower)."""
            if fileid in READ_THROUGH:
                return (root / fileid).open(encoding=self._encoding)
            return super().open(fileid)

    collecting = gc.isenabled()
    # The reader's index is ~150,000 small dicts and lists made at once, in no reference cycle: every
    # few hundred of them the cyclic garbage collector would run, and its full passes walk every object
    # of the process (a server's or writer's NumPy, SciPy, Numba and home: 3-4 s there instead of 1).
    gc.disable()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "the multilingual functions are not available"
            return _Reader(str(root), None)
    finally:
        if collecting:
            gc.enable()
