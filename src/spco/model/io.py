"""Saving and loading fitted models: one ``.npz`` file, no pickle.

Format (``format_version`` 1)
-----------------------------
A NumPy ``.npz`` archive written with :func:`numpy.savez` and read back with
``allow_pickle=False``. It holds

- ``param.<name>`` — every array of the model's :class:`~spco.model.parameters.ConceptParameters`
  (:meth:`~spco.model.parameters.ConceptParameters.arrays`);
- ``log_joint`` — the log-joint trace of the fit;
- ``concepts``, ``regions``, ``training_ids`` — the per-home concept and region assignments and
  sample ids of the training samples, concatenated over homes, with ``home_offsets`` (E + 1,) so
  that home ``e`` holds entries ``home_offsets[e]:home_offsets[e + 1]``;
- ``header`` — a UTF-8 JSON document stored as a ``uint8`` array::

      {"format": "spco-model", "format_version": 1, "spco_version": ..., "model_class":
       "SpCoTransfer" | "SpCoA", "variant", "prune_words", "n_iterations", "random_state" (int or
       null), "hyperparameters" (TransferHyperparameters.to_dict(), SpCoAHyperparameters for
       SpCoA), "vocabulary" (list of words), "segmentation" (null, or how text written without
       spaces is cut: :meth:`spco.data.segmentation.Segmentation.to_dict`), "word_increment",
       "home_names", "array_checksums" (name -> sha256 of the array's dtype, shape and bytes),
       "created" (ISO 8601, UTC), ...}

   ``format_version`` is 2 when the vocabulary segments text written without spaces (Japanese,
   Chinese), so that an older spco refuses the file instead of cutting that text otherwise.

Files are written atomically (a temporary file in the target's folder, flushed and fsync'ed, then
renamed over the target), so a crash never leaves a partial model file; an existing file is only
replaced with ``overwrite=True``. Every problem on loading — a missing, truncated or foreign file,
an edited array (checksum mismatch), a file from a newer spco — raises
:class:`~spco.errors.ModelFileError` naming the file.

A loaded model holds the saved one's ``parameters_``, vocabulary and home names, but not the sampler
state (``state_``, ``data_``): it can be evaluated from its parameters
(:func:`spco.evaluation.evaluate_home`), not continue sampling. A loaded SpCoA predicts exactly like
the saved one; a loaded transfer model's ``predict_names`` and ``predict_positions`` refuse with a
:class:`~spco.errors.ConfigurationError`: they answer as the robot does, from the home's rooms (its
training samples' regions, views and names), which the file does not keep. To learn more, or to
predict as the robot does, fit again (or adapt a knowledge to the home: :mod:`spco.knowledge`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from collections.abc import Callable, Mapping
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError, ModelFileError
from spco.model.hyperparameters import SpCoAHyperparameters, TransferHyperparameters
from spco.model.parameters import ConceptParameters
from spco.model.transfer import SpatialConceptModel, SpCoA, SpCoTransfer
from spco.timestamps import utc_now

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "load", "load_model", "save_model"]

#: Value of the header's ``"format"`` field.
FORMAT_NAME = "spco-model"
#: Version of the file layout written by this module; files of a newer version are refused.
FORMAT_VERSION = 2

_PARAM_PREFIX = "param."
_UNREADABLE = "not a readable spco model file (truncated or corrupted?)"
_MODEL_CLASSES: dict[str, type[SpatialConceptModel]] = {"SpCoTransfer": SpCoTransfer, "SpCoA": SpCoA}


def _checksum(array: np.ndarray) -> str:
    """sha256 of an array's dtype, shape and bytes (C order)."""
    digest = hashlib.sha256()
    digest.update(array.dtype.str.encode())
    digest.update(repr(tuple(int(s) for s in array.shape)).encode())
    digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def _model_class_name(model: SpatialConceptModel) -> str:
    if isinstance(model, SpCoA):
        return "SpCoA"
    if isinstance(model, SpatialConceptModel):
        return "SpCoTransfer"
    raise ConfigurationError(f"save_model() expects a fitted SpCoTransfer or SpCoA, "
                             f"got {type(model).__name__}")


def _concatenate(per_home: list[np.ndarray], dtype: type) -> np.ndarray:
    if not per_home:
        return np.zeros(0, dtype=dtype)
    return np.concatenate([np.asarray(a, dtype=dtype).ravel() for a in per_home])


def _arrays_and_header(model: SpatialConceptModel) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays to store and the header (without its checksums)."""
    if not hasattr(model, "parameters_"):
        raise ConfigurationError(f"this {type(model).__name__} is not fitted yet: "
                                 "call fit(corpus) before saving")
    arrays: dict[str, np.ndarray] = {}
    for name, value in model.parameters_.arrays().items():
        arrays[_PARAM_PREFIX + name] = np.asarray(value)
    arrays["log_joint"] = np.asarray(model.log_joint_, dtype=np.float64)
    concepts = list(model.concepts_)
    sizes = [np.asarray(c).size for c in concepts]
    for name, values in (("regions", model.regions_), ("training_ids", model.training_ids_)):
        if [np.asarray(v).size for v in values] != sizes:
            raise ConfigurationError(f"the model's {name}_ do not match its concepts_ (one entry per "
                                     "training sample of each home)")
    arrays["home_offsets"] = np.concatenate([[0], np.cumsum(sizes, dtype=np.int64)]).astype(np.int64)
    arrays["concepts"] = _concatenate(concepts, np.int64)
    arrays["regions"] = _concatenate(list(model.regions_), np.int64)
    arrays["training_ids"] = _concatenate(list(model.training_ids_), np.int64)

    from spco import __version__

    random_state = model.random_state
    if isinstance(random_state, bool) or not isinstance(random_state, int | np.integer):
        random_state = None  # a Generator (or None) cannot be written down
    hyper: TransferHyperparameters = model.hyperparameters_
    segmentation = model.vocabulary_.segmentation
    header: dict[str, Any] = {
        "format": FORMAT_NAME,
        # version 2 only for a vocabulary that segments text written without spaces (``segmentation``)
        "format_version": 2 if segmentation is not None and segmentation.segments else 1,
        "spco_version": __version__,
        "model_class": _model_class_name(model),
        "hyperparameters_class": type(hyper).__name__,
        "variant": model.variant,
        "prune_words": bool(model.prune_words),
        "n_iterations": int(model.n_iterations),
        "n_iter": int(getattr(model, "n_iter_", model.n_iterations)),
        "random_state": None if random_state is None else int(random_state),
        "hyperparameters": hyper.to_dict(),
        "vocabulary": list(model.vocabulary_.words),
        "segmentation": None if segmentation is None else segmentation.to_dict(),
        "word_increment": int(model.word_increment_),
        "home_names": list(model.home_names_),
        "fit_seconds": float(getattr(model, "fit_seconds_", float("nan"))),
        "created": utc_now(),
    }
    return arrays, header


def save_model(model: SpatialConceptModel, path: str | PathLike[str], overwrite: bool = False) -> Path:
    """Write a fitted model to ``path`` (a ``.npz`` file), atomically.

    Parameters
    ----------
    model: a fitted :class:`~spco.model.transfer.SpCoTransfer` or :class:`~spco.model.transfer.SpCoA`.
    path: the file to write (used as given: no suffix is added).
    overwrite: replace an existing file; without it an existing ``path`` raises
        :class:`~spco.errors.ModelFileError`.

    Returns
    -------
    The path written.

    The file is first written to a temporary file in the same folder, flushed to disk, then renamed
    over ``path``; on any error the temporary file is removed and ``path`` is left as it was.
    """
    arrays, header = _arrays_and_header(model)
    return write_npz_atomic(path, header, arrays, overwrite, "model file")


def write_npz_atomic(path: str | PathLike[str], header: dict[str, Any], arrays: Mapping[str, np.ndarray],
                     overwrite: bool, what: str,
                     seal: Callable[[dict[str, Any]], str] | None = None) -> Path:
    """Write ``arrays`` and a JSON ``header`` as one ``.npz`` (no pickle), atomically.

    Adds ``header["array_checksums"]`` (sha256 per array) and, with ``seal``, ``header["checksum"]
    = seal(header)``. The data go to a temporary file in the same folder, flushed to disk, then
    renamed over ``path`` (permissions: those of the file replaced, else the usual ones); on any
    error the temporary file is removed and ``path`` is left as it was. An existing ``path`` is
    replaced only with ``overwrite``; problems raise :class:`~spco.errors.ModelFileError` naming
    the ``what`` ("model file", "knowledge file", …).
    """
    target = Path(path).expanduser()
    if target.is_dir():
        raise ModelFileError(target, f"is a folder; give the name of the {what} to write")
    folder = target.parent
    if not folder.is_dir():
        raise ModelFileError(target, f"cannot write the {what}: the folder {str(folder)!r} does not exist")
    if target.exists() and not overwrite:
        raise ModelFileError(target, "the file already exists; pass overwrite=True (or --force on the "
                             "command line) to replace it")
    arrays = {name: np.asarray(a) for name, a in arrays.items()}
    header = dict(header)
    header["array_checksums"] = {name: _checksum(a) for name, a in arrays.items()}
    if seal is not None:
        header["checksum"] = seal(header)
    encoded = np.frombuffer(json.dumps(header, ensure_ascii=False, allow_nan=True).encode("utf-8"),
                            dtype=np.uint8)
    tmp_name: str | None = None
    try:
        with tempfile.NamedTemporaryFile(mode="wb", delete=False, dir=folder, prefix=f".{target.name}.",
                                         suffix=".tmp") as handle:
            tmp_name = handle.name
            np.savez(handle, header=encoded, **arrays)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp_name, _file_mode(target))
        os.replace(tmp_name, target)
        tmp_name = None
    except OSError as exc:
        raise ModelFileError(target, f"cannot write the {what}: {exc.strerror or exc}") from exc
    finally:
        if tmp_name is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp_name)
    _fsync_folder(folder)
    return target


def _file_mode(target: Path) -> int:
    """Permissions for a file written to ``target``: those of the file it replaces, else the
    usual ones (0o666 less the umask; temporary files are created 0o600)."""
    try:
        return target.stat().st_mode & 0o777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def _fsync_folder(folder: Path) -> None:
    """Make the rename durable (POSIX); a no-op where folders cannot be opened."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


# ----------------------------------------------------------------------------- loading


def _read_archive(path: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Header and arrays of a model file, with every read error turned into ModelFileError."""
    if not path.exists():
        raise ModelFileError(path, "no such model file")
    if path.is_dir():
        raise ModelFileError(path, "is a folder, not a model file")
    try:
        archive = np.load(path, allow_pickle=False)
    except Exception as exc:  # any failure to parse the file means it is not a readable model
        raise ModelFileError(path, f"{_UNREADABLE}: {exc}") from exc
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise ModelFileError(path, "not a spco model file (a single NumPy array, not an .npz archive)")
    try:
        with archive:
            names = list(archive.files)
            if "header" not in names:
                raise ModelFileError(path, "not a spco model file (no header; is it another program's .npz?)")
            header = _decode_header(path, archive["header"])
            arrays = {name: archive[name] for name in names if name != "header"}
    except ModelFileError:
        raise
    except Exception as exc:  # zipfile.BadZipFile (bad CRC), EOFError, ValueError, OSError, ...
        raise ModelFileError(path, f"{_UNREADABLE}: {exc}") from exc
    return header, arrays


def _decode_header(path: Path, raw: np.ndarray) -> dict[str, Any]:
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise ModelFileError(path, "not a spco model file (its header is not a JSON byte string)")
    try:
        header = json.loads(raw.tobytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(path, f"the model header is not valid JSON: {exc}") from exc
    if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
        found = header.get("format") if isinstance(header, dict) else None
        raise ModelFileError(path, f"not a spco model file (format {found!r}, expected {FORMAT_NAME!r})")
    check_format_version(path, header, "model", FORMAT_VERSION)
    return header


def check_format_version(path: Path, header: Mapping[str, Any], what: str, newest: int) -> int:
    """The ``format_version`` of a file's ``header``; :class:`~spco.errors.ModelFileError` naming
    ``path`` when it is not a whole number ≥ 1, or newer than ``newest`` (written by a newer spco: the
    ``what`` file format's version that this spco reads up to)."""
    version = header.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise ModelFileError(path, f"invalid format_version {version!r}")
    if version > newest:
        raise ModelFileError(path, f"written by a newer spco ({what} format version {version}, spco "
                             f"{header.get('spco_version', '?')}); this spco reads up to version "
                             f"{newest} — upgrade spco to read it")
    return version


def _verify(path: Path, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    checksums = header.get("array_checksums")
    if not isinstance(checksums, dict):
        raise ModelFileError(path, "the model header has no array checksums")
    missing = sorted(set(checksums) - set(arrays))
    if missing:
        raise ModelFileError(path, f"arrays missing from the model file: {', '.join(missing)}")
    extra = sorted(set(arrays) - set(checksums))
    if extra:
        raise ModelFileError(path, f"unexpected arrays in the model file: {', '.join(extra)}")
    for name, expected in checksums.items():
        if _checksum(arrays[name]) != expected:
            raise ModelFileError(path, f"checksum mismatch for array {name!r}: the file was modified or "
                                 "corrupted after it was written")


_REQUIRED_KEYS = ("model_class", "variant", "prune_words", "n_iterations", "hyperparameters", "vocabulary",
                  "word_increment", "home_names")


def load_model(path: str | PathLike[str]) -> SpatialConceptModel:
    """Read a model written by :func:`save_model`.

    Returns a :class:`~spco.model.transfer.SpCoTransfer` or :class:`~spco.model.transfer.SpCoA`
    with ``parameters_``, ``vocabulary_``, ``word_increment_``, ``home_names_``, ``log_joint_``,
    ``concepts_``, ``regions_``, ``training_ids_``, ``hyperparameters_``, ``settings_`` and
    ``n_iter_`` restored. It has no sampler state (``state_``, ``data_``), so it cannot continue
    sampling, nor (a transfer model) predict as the robot does (module docstring).

    Raises
    ------
    ModelFileError: the file is missing, truncated, not a spco model, edited after it was written
        (checksum mismatch) or written by a newer spco.
    """
    file = Path(path).expanduser()
    header, arrays = _read_archive(file)
    _verify(file, header, arrays)
    missing = [key for key in _REQUIRED_KEYS if key not in header]
    if missing:
        raise ModelFileError(file, f"the model header lacks {', '.join(missing)}")
    class_name = header["model_class"]
    if class_name not in _MODEL_CLASSES:
        raise ModelFileError(file, f"unknown model class {class_name!r}")
    cls = _MODEL_CLASSES[class_name]
    try:
        hyper_cls = SpCoAHyperparameters if header.get("hyperparameters_class") == "SpCoAHyperparameters" \
            else TransferHyperparameters
        hyper = hyper_cls.from_dict(header["hyperparameters"])
        params = ConceptParameters(**{name[len(_PARAM_PREFIX):]: arrays[name] for name in arrays
                                      if name.startswith(_PARAM_PREFIX)})
        segmentation = None
        if header.get("segmentation") is not None:
            from spco.data.segmentation import Segmentation

            segmentation = Segmentation.from_dict(header["segmentation"])
        vocabulary = Vocabulary(tuple(str(w) for w in header["vocabulary"]), segmentation)
    except (TypeError, ValueError) as exc:
        raise ModelFileError(file, f"inconsistent model file: {exc}") from exc
    home_names = [str(n) for n in header["home_names"]]
    _check_shapes(file, params, vocabulary, home_names, arrays)

    random_state = header.get("random_state")
    common = dict(prune_words=bool(header["prune_words"]), n_iterations=int(header["n_iterations"]),
                  random_state=random_state)
    if cls is SpCoA:
        model: SpatialConceptModel = SpCoA(hyper, **common)
    else:
        model = cls(hyper, variant=str(header["variant"]), **common)
    try:
        model.settings_ = model.sampler_settings()
    except ConfigurationError as exc:
        raise ModelFileError(file, f"inconsistent model file: {exc}") from exc
    model.hyperparameters_ = hyper
    model.parameters_ = params
    model.vocabulary_ = vocabulary
    model.word_increment_ = int(header["word_increment"])
    model.home_names_ = home_names
    model.log_joint_ = arrays["log_joint"]
    model.n_iter_ = int(header.get("n_iter", header["n_iterations"]))
    model.fit_seconds_ = float(header.get("fit_seconds", float("nan")))
    offsets = arrays["home_offsets"]
    model.concepts_ = _split(arrays["concepts"], offsets)
    model.regions_ = _split(arrays["regions"], offsets)
    model.training_ids_ = _split(arrays["training_ids"], offsets)
    return model


def _split(values: np.ndarray, offsets: np.ndarray) -> list[np.ndarray]:
    return [values[offsets[e]:offsets[e + 1]].copy() for e in range(offsets.size - 1)]


def _check_shapes(path: Path, params: ConceptParameters, vocabulary: Vocabulary, home_names: list[str],
                  arrays: dict[str, np.ndarray]) -> None:
    """Refuse files whose parts do not fit together (written by a broken writer)."""
    n_homes = params.n_environments
    problems = []
    if len(home_names) != n_homes:
        problems.append(f"{len(home_names)} home names for {n_homes} homes")
    if params.word_probabilities.shape[-1] != len(vocabulary):
        problems.append(f"{params.word_probabilities.shape[-1]} word columns for {len(vocabulary)} words")
    offsets = arrays["home_offsets"]
    if offsets.ndim != 1 or offsets.size != n_homes + 1 or offsets[0] != 0 or (np.diff(offsets) < 0).any() \
            or any(arrays[k].size != offsets[-1] for k in ("concepts", "regions", "training_ids")):
        problems.append("the per-home assignments do not match the home offsets")
    if problems:
        raise ModelFileError(path, "inconsistent model file: " + "; ".join(problems))


def load(path: str | PathLike[str]) -> SpatialConceptModel:
    """Shorthand for :func:`load_model`."""
    return load_model(path)

