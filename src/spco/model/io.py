"""Loading fitted models, and their file: one ``.npz`` file, no pickle (written by
:func:`spco.model.transfer.save_model`, or a model's ``save``).

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

import json
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError, ModelFileError
from spco.model.archive import check_format_version, checksum
from spco.model.hyperparameters import SpCoAHyperparameters, TransferHyperparameters
from spco.model.parameters import ConceptParameters
from spco.model.transfer import FORMAT_NAME, PARAM_PREFIX, SpatialConceptModel, SpCoA, SpCoTransfer

__all__ = ["FORMAT_VERSION", "load", "load_model"]

#: The newest version of the file layout this spco reads; files of a newer version are refused
#: (:func:`spco.model.transfer.save_model` writes 2 only where version 1 would be read otherwise).
FORMAT_VERSION = 2

_UNREADABLE = "not a readable spco model file (truncated or corrupted?)"
_MODEL_CLASSES: dict[str, type[SpatialConceptModel]] = {"SpCoTransfer": SpCoTransfer, "SpCoA": SpCoA}


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
        if checksum(arrays[name]) != expected:
            raise ModelFileError(path, f"checksum mismatch for array {name!r}: the file was modified or "
                                 "corrupted after it was written")


_REQUIRED_KEYS = ("model_class", "variant", "prune_words", "n_iterations", "hyperparameters", "vocabulary",
                  "word_increment", "home_names")


def load_model(path: str | PathLike[str]) -> SpatialConceptModel:
    """Read a model written by :func:`~spco.model.transfer.save_model`.

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
        params = ConceptParameters(**{name[len(PARAM_PREFIX):]: arrays[name] for name in arrays
                                      if name.startswith(PARAM_PREFIX)})
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

