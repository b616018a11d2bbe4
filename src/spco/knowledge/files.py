"""Knowledge and home files: the archive format, its headers and checksums.

Knowledge (``.spco``, format ``spco-knowledge``) and home (``.spco``, format ``spco-home``) files
are NumPy ``.npz`` archives read with ``allow_pickle=False``: arrays plus a ``header`` array holding
a UTF-8 JSON document with the format name, ``format_version`` (2; 3 when the vocabulary segments
text written without spaces; 4 for the ``spcotransfer+mi`` model, whose word channels the file
carries as ``channels.*`` arrays; 5 for a home file holding the home's own place words ψ_{e,l},
:data:`FORMAT_VERSION`), the spco version, the hyperparameters,
the vocabulary, its
``segmentation`` (``null``, or how Japanese or Chinese text is cut into words:
:meth:`spco.data.segmentation.Segmentation.to_dict`), provenance, the image extractor
(``extractor``: name, version, settings and checksum of its weights, ``null`` for knowledge fitted
on count vectors; its weights, such as a codebook, as arrays ``extractor.<name>``; version 1 files,
which predate it, are read as fitted on count vectors), a sha256 checksum of every array and a ``checksum`` of
the whole content (header and arrays). They are written to a temporary file in the target's folder,
flushed and renamed into place (atomic), and never replace an existing file unless asked
(``overwrite=True``, ``--force``). A missing, truncated, edited or foreign file, or one written by
a newer spco, raises :class:`~spco.errors.ModelFileError` naming the file and the problem.
Every save holds the file's write lock (:func:`spco.knowledge.locking.locked`, a ``flock`` on
``<file>.lock``); to read, update and replace a file without losing another process's update, hold
it around all three (``with locked(path): home = load_home_model(path); …; home.save(path,
overwrite=True)``).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from spco.errors import ModelFileError
from spco.knowledge.locking import locked
from spco.model.archive import check_format_version, checksum, write_npz_atomic

#: Header ``format`` of knowledge files and home files.
KNOWLEDGE_FORMAT = "spco-knowledge"
HOME_FORMAT = "spco-home"
#: Version of both file layouts written by this module; newer files are refused. Version 2 added
#: the image extractor (``extractor`` in the header); version 1 files are read as count-vector ones.
#: Version 3 added the segmentation of text written without spaces (``segmentation``): it is
#: written only for a vocabulary that segments such text (older spco would cut it otherwise);
#: other files stay version 2.
#: Version 4 is the word model of the ``spcotransfer+mi`` files (exact sampler with pruning): their
#: words are learnt with the word channels (``channels.*`` arrays: :class:`spco.knowledge.KnowledgeChannels`,
#: and a home's ``state.switches``), or with the naming rule for speech without English function words
#: (``hyperparameters.word_model``). Such files of an earlier version were learnt with the naming rule
#: for every language and are refused (:func:`check_word_model`): fit the knowledge again.
#: Version 5 is a home file that holds the home's own place words ψ_{e,l} (``state.log_place_home``:
#: the place channel's home level, ``place_channel="home"``, :mod:`spco.model.home_place`), written only
#: for such a home (an older spco would drop ψ_{e,l}); other files keep their version. A home file of
#: ``place_channel="home"`` written before (version 4, no ψ_{e,l}) loads with none held: the home reads
#: ψ_l, ψ_{e,l}'s prior mean — what a new home reads before its first home step — until a teaching
#: draws ψ_{e,l} of the concepts it updates.
FORMAT_VERSION = 5
#: The first version whose ``spcotransfer+mi`` files carry the word channels.
CHANNELS_FORMAT_VERSION = 4
#: The version of a home file holding its ψ_{e,l}.
HOME_PLACE_FORMAT_VERSION = 5


def format_version(vocabulary: Any, word_model: bool = False) -> int:
    """The version to write for a file of ``vocabulary``: 4 for a model with a word model
    (``word_model``: the exact sampler with pruning, ``spcotransfer+mi``); otherwise 3 if the
    vocabulary segments text written without spaces, else 2 (readable by older spco)."""
    if word_model:
        return CHANNELS_FORMAT_VERSION
    seg = vocabulary.segmentation
    return 3 if seg is not None and seg.segments else 2


def check_word_model(path: Path, header: Mapping[str, Any]) -> None:
    """Refuse a ``spcotransfer+mi`` file written before the word channels (format version < 4): its
    words were learnt with the naming rule whatever the language, a word model this spco no longer
    runs for English speech. Raises :class:`~spco.errors.ModelFileError` saying what to do."""
    version = header.get("format_version")
    if (isinstance(version, int) and version < CHANNELS_FORMAT_VERSION and header.get("variant") == "exact"
            and bool(header.get("prune_words"))):
        what = _FORMAT_NAMES.get(str(header.get("format")), "file")
        redo = ("fit the knowledge again with `spco fit` (same homes and seed), then `spco adapt` the "
                "home" if header.get("format") == HOME_FORMAT
                else "fit it again with `spco fit` (same homes and seed)")
        raise ModelFileError(path, f"an old {what} (format version {version}, spco "
                             f"{header.get('spco_version', '?')}): its words were learnt with the naming "
                             f"rule, which this spco replaced by the word channels for model "
                             f"spcotransfer+mi; {redo}")


def segmentation_of(header: Mapping[str, Any]) -> Any:
    """The vocabulary's :class:`~spco.data.segmentation.Segmentation` recorded in a file header
    (``None`` if none)."""
    data = header.get("segmentation")
    if data is None:
        return None
    from spco.data.segmentation import Segmentation

    return Segmentation.from_dict(data)


_FORMAT_NAMES = {KNOWLEDGE_FORMAT: "knowledge file", HOME_FORMAT: "home file",
                 "spco-model": "spco model file (spco fit --save / model.save)"}
_UNREADABLE = "not a readable spco file (truncated or corrupted?)"


def _version() -> str:
    from spco import __version__

    return __version__


# ============================================================================ file helpers


def _canonical(obj: Any) -> bytes:
    return json.dumps(obj, sort_keys=True, ensure_ascii=False, allow_nan=True,
                      separators=(",", ":")).encode("utf-8")


def _content_checksum(header: Mapping[str, Any]) -> str:
    """sha256 of the header, which holds every array's checksum; its own ``checksum`` and the
    version of the spco that wrote it are left out (the same content has the same checksum)."""
    content = {k: v for k, v in header.items() if k not in ("checksum", "spco_version")}
    return hashlib.sha256(_canonical(content)).hexdigest()


def _write_archive(path: str | PathLike[str], arrays: Mapping[str, np.ndarray], header: dict[str, Any],
                   overwrite: bool, what: str) -> Path:
    """Write ``arrays`` and ``header`` (+ array and content checksums) to ``path`` atomically,
    holding the file's write lock (:func:`spco.knowledge.locking.locked`; re-entrant, so a caller may hold it
    already while it reads and updates the file)."""
    target = Path(path).expanduser()
    if target.is_dir() or not target.parent.is_dir():  # no lock to take: the writer says what is wrong
        return write_npz_atomic(path, header, arrays, overwrite, what, seal=_content_checksum)
    with locked(target):
        return write_npz_atomic(path, header, arrays, overwrite, what, seal=_content_checksum)


def _read_archive(path: str | PathLike[str],
                  expected: str) -> tuple[Path, dict[str, Any], dict[str, np.ndarray]]:
    """Header and arrays of a file of format ``expected``, verified; any problem -> ModelFileError."""
    file = Path(path).expanduser()
    what = _FORMAT_NAMES[expected]
    if not file.exists():
        raise ModelFileError(file, f"no such {what}")
    if file.is_dir():
        raise ModelFileError(file, f"is a folder, not a {what}")
    try:
        archive = np.load(file, allow_pickle=False)
    except Exception as exc:  # any failure to parse means it is not a readable file
        raise ModelFileError(file, f"{_UNREADABLE}: {exc}") from exc
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise ModelFileError(file, f"not a {what} (a single NumPy array, not an .npz archive)")
    try:
        with archive:
            if "header" not in archive.files:
                raise ModelFileError(file, f"not a {what} (no header; is it another program's .npz?)")
            header = _decode_header(file, archive["header"], expected)
            arrays = {name: archive[name] for name in archive.files if name != "header"}
    except ModelFileError:
        raise
    except Exception as exc:  # zipfile.BadZipFile (bad CRC), EOFError, ValueError, OSError, ...
        raise ModelFileError(file, f"{_UNREADABLE}: {exc}") from exc
    checksums = header.get("array_checksums")
    if not isinstance(checksums, dict):
        raise ModelFileError(file, "the header has no array checksums")
    missing = sorted(set(checksums) - set(arrays))
    extra = sorted(set(arrays) - set(checksums))
    if missing or extra:
        raise ModelFileError(file, "the arrays do not match the header (missing: "
                             f"{', '.join(missing) or '-'}; unexpected: {', '.join(extra) or '-'})")
    for name, expected_sum in checksums.items():
        if checksum(arrays[name]) != expected_sum:
            raise ModelFileError(file, f"checksum mismatch for array {name!r}: the file was modified or "
                                 "corrupted after it was written")
    if header.get("checksum") != _content_checksum(header):
        raise ModelFileError(file, "checksum mismatch of the header: the file was modified after it "
                             "was written")
    return file, header, arrays


def _decode_header(path: Path, raw: np.ndarray, expected: str) -> dict[str, Any]:
    what = _FORMAT_NAMES[expected]
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise ModelFileError(path, f"not a {what} (its header is not a JSON byte string)")
    try:
        header = json.loads(raw.tobytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(path, f"the header is not valid JSON: {exc}") from exc
    found = header.get("format") if isinstance(header, dict) else None
    if found != expected:
        hint = ""
        if found in _FORMAT_NAMES:
            hint = f": it is a {_FORMAT_NAMES[found]}"
            if expected == HOME_FORMAT and found == KNOWLEDGE_FORMAT:
                hint += " — make a home file from it with `spco adapt`"
            if expected == KNOWLEDGE_FORMAT and found == HOME_FORMAT:
                hint += " — `spco adapt` needs the knowledge file written by `spco fit`"
        raise ModelFileError(path, f"not a {what} (format {found!r}, expected {expected!r}){hint}")
    check_format_version(path, header, what, FORMAT_VERSION)
    return header


def _require(path: Path, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray],
             keys: Iterable[str], names: Iterable[str]) -> None:
    missing = [k for k in keys if k not in header]
    missing += [n for n in names if n not in arrays]
    if missing:
        raise ModelFileError(path, f"incomplete file: it lacks {', '.join(missing)}")



def model_file_format(path: str | PathLike[str]) -> str | None:
    """:data:`KNOWLEDGE_FORMAT` or :data:`HOME_FORMAT` if ``path`` is such a file (by its header), else
    ``None`` (a folder, a cache file, another program's file: not verified here)."""
    file = Path(path).expanduser()
    if not file.is_file():
        return None
    try:
        with np.load(file, allow_pickle=False) as archive:
            if "header" not in archive.files:
                return None
            header = json.loads(archive["header"].tobytes().decode("utf-8"))
    except Exception:  # not an .npz archive with a JSON header: not a model file
        return None
    found = header.get("format") if isinstance(header, dict) else None
    return found if found in (KNOWLEDGE_FORMAT, HOME_FORMAT) else None
