"""The plain per-home format: how to give spco the data of your own robot.

One folder per home::

    my_home/
      samples.csv     (or samples.jsonl)  required: one row per sample
      visual.npz      (or visual.npy)     visual features, one row per sample (none: no views)
      images/<id>.jpg (or .jpeg, .png)    or, in place of visual.npz: the view of each sample
      test.txt                            optional: ids of the test samples
      home.json                           optional: name, map extent, visual_scale
      labels.csv                          optional, evaluation only: true place names
      specific_test.txt                   optional, evaluation only: home-specific test samples
      regions.json                        optional, evaluation only: true place areas
      accepted_names.json                 optional, evaluation only: synonyms counted right

``samples.csv``
    UTF-8 CSV with the header ``id,x,y,theta,sentence`` (column order free; other columns are ignored;
    ``sentence`` may be left out). ``id`` is an integer, unique within the home; ``x`` and ``y`` are
    the robot's position in metres; ``theta`` its heading in radians; ``sentence`` what the user said
    at that place — empty when nothing was said. Standard CSV quoting applies (a sentence holding a
    comma is written in double quotes)::

        id,x,y,theta,sentence
        0,1.25,-0.40,1.5708,this is the kitchen
        1,1.31,-0.52,1.4000,
        2,3.02,2.10,-3.1000,"well, this is emma's room"

    (:func:`write_home` quotes every sentence, so that any text — even one holding a line break —
    reads back unchanged.)

``samples.jsonl``
    The same as JSON lines, one object per line:
    ``{"id": 0, "x": 1.25, "y": -0.4, "theta": 1.5708, "sentence": "this is the kitchen"}``
    (``sentence`` may be ``null`` or missing). Give ``samples.csv`` *or* ``samples.jsonl``, not both.

``visual.npz`` / ``visual.npy``
    An (N, D) matrix, row *k* belonging to row *k* of the samples file: either a sparse matrix saved
    with ``scipy.sparse.save_npz``, or a dense array saved with ``numpy.save`` (``.npy``) or
    ``numpy.savez`` (``.npz`` holding one array, or the arrays ``visual`` and ``missing``).

    *Samples without a view* (a camera that dropped the frame): a ``.npz`` may hold beside the
    matrix a boolean array ``missing`` of N entries, True for each sample that has no view — its
    row is ignored (write zeros) and its visual likelihood is left out of the model (marginalised,
    not imputed); a sparse matrix's file gets it with ``numpy.savez(path, format="csr",
    shape=…, data=…, indices=…, indptr=…, missing=mask)`` (what :func:`write_home` writes). A
    home *without any view* (a robot without a camera) has no visual file at all: every view is
    missing, and the home is learnt from poses and words. Values are visual bag-of-features *counts*:
    non-negative whole numbers. Real-valued CNN features (e.g. fc7 activations) are accepted when
    ``home.json`` gives ``visual_scale``: the file is then always converted with
    :func:`features_to_counts`, ``floor(max(f, 0) × visual_scale)`` — what Hagiwara et al. did with
    S^v = 5. Without ``visual_scale`` a non-integer value is an error. Files are read without pickle.

``images/<id>.jpg`` / ``.jpeg`` / ``.png``
    The camera image of each sample, in place of ``visual.npz``: the views then become counts with
    an image extractor (:mod:`spco.features`): ``spco fit`` uses the default one (or ``--extractor``)
    and stores it in the knowledge file; ``adapt`` uses the knowledge's. A sample without an image
    has no view. A home with images and no ``visual.npz`` cannot be read without an extractor; a
    home read for knowledge fitted on images must have images (or no view at all).

``test.txt``
    Sample ids of the test samples (never learnt from), separated by commas and/or blanks. Without
    the file every sample is a training sample.

``home.json``
    ``{"name": "my_flat", "extent": [x_min, x_max, y_min, y_max], "visual_scale": 5.0}``, every key
    optional: ``name`` defaults to the folder name; ``extent`` (metres) is the map area used for plots
    and the prior's centre (default: none); ``visual_scale`` is described above. Other keys are refused
    (to catch typos).

``labels.csv`` (evaluation only, never given to a learner)
    Header ``id,label`` and optionally ``specific_label``: the true place name of samples
    (``living room``, ``emma's room``); samples not listed, or with an empty label, are unlabelled.

``specific_test.txt`` (evaluation only)
    Ids of the samples scored in the home-specific experiment, same syntax as ``test.txt``.

``regions.json`` (evaluation only)
    ``{"kitchen": [[x_min, x_max, y_min, y_max], ...], ...}``: each place a union of axis-aligned
    rectangles in metres, as the inner mapping of ``sigverse_regions.json``.

``accepted_names.json`` (evaluation only)
    ``{"bath": ["bath", "bathroom", "shower"], ...}``: for a place, every name counted right when it is
    predicted (A_n) and asked for with ``where`` (A_p). Without the file only the place's own name.

:func:`read_home` reads a home, :func:`write_home` writes one (every field, ground truth included;
the heading is stored as ``theta = atan2(sin θ, cos θ)``, so it is read back as a unit vector), and
:func:`write_corpus` writes a folder of homes. Writing never replaces existing files unless asked.
"""

from __future__ import annotations

import csv
import io
import json
import math
import numbers
import os
import re
import shutil
import uuid
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from spco.data.environment import Corpus, Environment, make_ground_truth
from spco.data.regions import PlaceRegions
from spco.errors import ConfigurationError, DataFormatError

SAMPLES_CSV = "samples.csv"
SAMPLES_JSONL = "samples.jsonl"
VISUAL_NPZ = "visual.npz"
VISUAL_NPY = "visual.npy"
#: The array of ``visual.npz`` that marks the samples without a view.
MISSING_KEY = "missing"
TEST_TXT = "test.txt"
HOME_JSON = "home.json"
LABELS_CSV = "labels.csv"
SPECIFIC_TEST_TXT = "specific_test.txt"
REGIONS_JSON = "regions.json"
ACCEPTED_NAMES_JSON = "accepted_names.json"
#: Every file name of the plain format (what :func:`write_home` may create or replace).
PLAIN_FILES = (SAMPLES_CSV, SAMPLES_JSONL, VISUAL_NPZ, VISUAL_NPY, TEST_TXT, HOME_JSON, LABELS_CSV,
               SPECIFIC_TEST_TXT, REGIONS_JSON, ACCEPTED_NAMES_JSON)
_HOME_KEYS = ("name", "extent", "visual_scale")


def is_plain_home(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a folder holding ``samples.csv`` or ``samples.jsonl``."""
    folder = Path(path)
    return (folder / SAMPLES_CSV).is_file() or (folder / SAMPLES_JSONL).is_file()


def plain_home_name(folder: str | os.PathLike[str]) -> str:
    """The name of the plain home in ``folder``: ``name`` of its home.json, else the folder's name."""
    home = Path(folder)
    name = _read_home_json(home / HOME_JSON).get("name")
    return str(name).strip() if name else home.resolve().name


def features_to_counts(features: Any, scale: float = 5.0) -> Any:
    """Turn real-valued CNN features into visual counts: ``floor(max(f, 0) × scale)``.

    This is how Hagiwara et al. built their visual bags of features (fc7 activations × S^v = 5,
    truncated). ``features`` may be a dense array or a scipy sparse matrix; the result has the same
    kind and int64 values. Raises :class:`~spco.errors.ConfigurationError` for a non-positive scale and
    :class:`~spco.errors.DataFormatError` for NaN or infinite features.
    """
    if isinstance(scale, bool) or not isinstance(scale, numbers.Real) or not (
            math.isfinite(scale) and scale > 0):
        raise ConfigurationError(f"visual scale must be a positive number, got {scale!r}")
    if sp.issparse(features):
        out = sp.csr_array(features, dtype=np.float64, copy=True)
        if not np.isfinite(out.data).all():
            raise DataFormatError(None, "visual features contain NaN or inf")
        out.data = np.floor(np.maximum(out.data, 0.0) * scale)
        out = sp.csr_array(out, dtype=np.int64)
        out.eliminate_zeros()
        return out
    arr = np.asarray(features, dtype=np.float64)
    if not np.isfinite(arr).all():
        raise DataFormatError(None, "visual features contain NaN or inf")
    return np.floor(np.maximum(arr, 0.0) * scale).astype(np.int64)


# ------------------------------------------------------------------------------------------ reading
def _read_text(path: Path) -> str:
    """The file's text, line ends untouched (a quoted CSV field may hold a carriage return)."""
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            return fh.read()
    except UnicodeDecodeError as exc:
        raise DataFormatError(path, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise DataFormatError(path, f"cannot be read ({exc.strerror})") from None


def _read_json(path: Path) -> Any:
    """The file's JSON value (:class:`DataFormatError` naming the file when it is not valid JSON)."""
    try:
        return json.loads(_read_text(path))
    except json.JSONDecodeError as exc:
        raise DataFormatError(path, f"not valid JSON ({exc.msg}, line {exc.lineno})") from None


def _number(path: Path, where: str, column: str, value: Any) -> float:
    if isinstance(value, bool) or value is None or value == "":
        raise DataFormatError(path, f"{where}: {column} is missing")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise DataFormatError(path, f"{where}: {column} {value!r} is not a number") from None
    if not math.isfinite(out):
        raise DataFormatError(path, f"{where}: {column} is not finite ({value!r})")
    return out


def _integer(path: Path, where: str, value: Any) -> int:
    if isinstance(value, bool):
        raise DataFormatError(path, f"{where}: id {value!r} is not an integer")
    if isinstance(value, int):
        return value
    if isinstance(value, str) and re.fullmatch(r"\s*[+-]?\d+\s*", value):
        return int(value)
    raise DataFormatError(path, f"{where}: id {value!r} is not an integer" if value not in (None, "")
                          else f"{where}: id is missing")


def _read_samples_csv(path: Path) -> tuple[list[int], list[tuple[float, float, float]], list[str | None]]:
    reader = csv.DictReader(io.StringIO(_read_text(path), newline=""))
    header = [h.strip() for h in (reader.fieldnames or [])]
    missing = [c for c in ("id", "x", "y", "theta") if c not in header]
    if missing:
        raise DataFormatError(path, f"header must name the columns id,x,y,theta[,sentence]; missing "
                              f"{', '.join(missing)} (header: {','.join(header) or 'none'})")
    reader.fieldnames = header
    ids, poses, sentences = [], [], []
    for row in reader:
        where = f"line {reader.line_num}"
        if None in row:
            hint = ""
            if header and header[-1] == "sentence":
                hint = (f"; a sentence holding a comma must be quoted: "
                        f"\"{','.join([row['sentence'] or '', *row[None]])}\"")
            raise DataFormatError(path, f"{where}: more fields than the header has columns{hint}")
        if all((v or "").strip() == "" for v in row.values()):
            continue
        ids.append(_integer(path, where, (row["id"] or "").strip()))
        poses.append(tuple(_number(path, where, c, (row[c] or "").strip()) for c in ("x", "y", "theta")))
        text = row.get("sentence")
        sentences.append(text if text and text.strip() else None)
    return ids, poses, sentences


def _read_samples_jsonl(path: Path) -> tuple[list[int], list[tuple[float, float, float]], list[str | None]]:
    ids, poses, sentences = [], [], []
    for lineno, line in enumerate(_read_text(path).split("\n"), start=1):
        if not line.strip():
            continue
        where = f"line {lineno}"
        try:
            obj = json.loads(line)
        except json.JSONDecodeError as exc:
            raise DataFormatError(path, f"{where}: not valid JSON ({exc.msg})") from None
        if not isinstance(obj, dict):
            raise DataFormatError(path, f"{where}: expected an object with id, x, y, theta, sentence")
        if "id" not in obj:
            raise DataFormatError(path, f"{where}: id is missing")
        ids.append(_integer(path, where, obj["id"]))
        poses.append(tuple(_number(path, where, c, obj.get(c)) for c in ("x", "y", "theta")))
        text = obj.get("sentence")
        if text is not None and not isinstance(text, str):
            raise DataFormatError(path, f"{where}: sentence must be a string or null")
        sentences.append(text if text and text.strip() else None)
    return ids, poses, sentences


def _read_home_json(path: Path) -> dict[str, Any]:
    if not path.is_file():
        return {}
    meta = _read_json(path)
    if not isinstance(meta, dict):
        raise DataFormatError(path, 'expected an object such as {"name": "my_home"}')
    unknown = sorted(set(meta) - set(_HOME_KEYS))
    if unknown:
        raise DataFormatError(path, f"unknown key(s) {', '.join(unknown)}; allowed: {', '.join(_HOME_KEYS)}")
    if "name" in meta and not (isinstance(meta["name"], str) and meta["name"].strip()):
        raise DataFormatError(path, "name must be a non-empty string")
    if "extent" in meta:
        ext = meta["extent"]
        if (not isinstance(ext, list) or len(ext) != 4
                or not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                           for v in ext)
                or ext[0] > ext[1] or ext[2] > ext[3]):
            raise DataFormatError(path, "extent must be [x_min, x_max, y_min, y_max] with finite numbers, "
                                  "min <= max")
    if "visual_scale" in meta:
        scale = meta["visual_scale"]
        if isinstance(scale, bool) or not isinstance(scale, int | float) or not (scale > 0) \
                or not math.isfinite(scale):
            raise DataFormatError(path, "visual_scale must be a positive number")
    return meta


def _load_visual_file(path: Path) -> tuple[Any, Any]:
    """The matrix of a visual file and its ``missing`` array (``None`` if it has none)."""
    try:
        if path.suffix == ".npy":
            return np.load(path, allow_pickle=False), None
        with np.load(path, allow_pickle=False) as npz:
            keys = set(npz.files)
            missing = npz[MISSING_KEY] if MISSING_KEY in keys else None
            keys.discard(MISSING_KEY)
            if {"format", "shape", "data", "indices", "indptr"} <= keys:
                fmt = npz["format"].item()
                fmt = fmt.decode() if isinstance(fmt, bytes) else str(fmt)
                if fmt not in ("csr", "csc", "coo", "bsr"):
                    raise DataFormatError(path, f"unsupported sparse format {fmt!r} (save a CSR matrix)")
                return sp.load_npz(path), missing
            if len(keys) == 1:
                return npz[next(iter(keys))], missing
            if "visual" in keys:
                return npz["visual"], missing
            raise DataFormatError(path, f"holds several arrays ({', '.join(sorted(keys))}); save one "
                                  "array (and a 'missing' mask), or a sparse matrix with "
                                  "scipy.sparse.save_npz")
    except DataFormatError:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        raise DataFormatError(path, f"not a readable numpy/scipy file ({exc})") from None


def _missing_mask(path: Path, raw: Any, n: int) -> np.ndarray:
    """The ``missing`` array of a visual file as an (n,) bool mask (all False without one)."""
    if raw is None:
        return np.zeros(n, dtype=bool)
    mask = np.asarray(raw)
    if mask.shape != (n,):
        raise DataFormatError(path, f"its '{MISSING_KEY}' array must have one entry per sample, shape "
                              f"({n},), got {mask.shape}")
    if mask.dtype != bool:
        if not np.issubdtype(mask.dtype, np.integer) or not np.isin(mask, (0, 1)).all():
            raise DataFormatError(path, f"its '{MISSING_KEY}' array must be boolean (True: the sample has "
                                  f"no view), got {mask.dtype}")
        mask = mask.astype(bool)
    return mask


def _read_visual(folder: Path, n: int, scale: float | None) -> tuple[sp.csr_array, np.ndarray]:
    """The visual counts of a plain home and its (n,) mask of samples without a view; without a
    visual file every view is missing (a home recorded without a camera, ``D = 0``)."""
    npz, npy = folder / VISUAL_NPZ, folder / VISUAL_NPY
    if npz.is_file() and npy.is_file():
        raise DataFormatError(folder, f"holds both {VISUAL_NPZ} and {VISUAL_NPY}; keep one")
    path = npz if npz.is_file() else npy
    if not path.is_file():
        return sp.csr_array((n, 0), dtype=np.int64), np.ones(n, dtype=bool)
    raw, raw_missing = _load_visual_file(path)
    missing = _missing_mask(path, raw_missing, n)
    if raw.ndim != 2:
        raise DataFormatError(path, f"expected a 2-D matrix (samples × features), got shape {raw.shape}")
    if raw.shape[0] != n:
        raise DataFormatError(path, f"has {raw.shape[0]} rows, but the samples file lists {n} samples")
    if raw.shape[1] == 0:
        raise DataFormatError(path, "has no feature columns (a home without any view has no visual file)")
    return _visual_counts(path, raw, scale), missing


def _visual_counts(path: Path, raw: Any, scale: float | None) -> sp.csr_array:
    values = raw.data if sp.issparse(raw) else np.asarray(raw)
    if values.dtype == bool:
        values = values.astype(np.int64)
    if not (np.issubdtype(values.dtype, np.integer) or np.issubdtype(values.dtype, np.floating)):
        raise DataFormatError(path, f"values must be numbers, got dtype {values.dtype}")
    if values.size and not np.isfinite(values).all():
        raise DataFormatError(path, "holds NaN or infinite values")
    if scale is not None:
        return sp.csr_array(features_to_counts(raw if sp.issparse(raw) else values, scale))
    if values.size and (values < 0).any():
        raise DataFormatError(path, "holds negative values; visual counts must be >= 0 (for real-valued "
                              "CNN features set visual_scale in home.json)")
    if np.issubdtype(values.dtype, np.floating) and values.size and (values != np.floor(values)).any():
        raise DataFormatError(path, "holds non-integer values; visual counts must be whole numbers. For "
                              "real-valued CNN features set visual_scale in home.json (5.0 is what the "
                              "authors used): counts = floor(max(f, 0) × visual_scale)")
    return sp.csr_array(sp.csr_array(raw) if sp.issparse(raw) else values, dtype=np.int64)


def has_images(folder: str | os.PathLike[str]) -> bool:
    """Whether a plain home holds its views as images (an ``images/`` folder)."""
    return (Path(folder) / "images").is_dir()


def _read_views(home: Path, ids: list[int], scale: float | None,
                extractor: Any) -> tuple[Any, np.ndarray]:
    """Visual counts of a plain home and its mask of samples without a view: from
    visual.npz/.npy, or its images through ``extractor`` (a sample without an image has no view)."""
    from spco.data.image_views import IMAGES_DIR, extract_views, image_files

    images = home / IMAGES_DIR
    has_counts = (home / VISUAL_NPZ).exists() or (home / VISUAL_NPY).exists()
    if extractor is None:
        if not has_counts and images.is_dir():
            raise DataFormatError(home, f"holds its views as {IMAGES_DIR}/ (no {VISUAL_NPZ}): they become "
                                  "features with an image extractor — learn knowledge from it with `spco "
                                  "fit` (or `spco features`), or use a knowledge file fitted on images")
        return _read_visual(home, len(ids), scale)
    if not images.is_dir() and not has_counts:  # no view at all (a home recorded without a camera)
        return sp.csr_array((len(ids), 0), dtype=np.int64), np.ones(len(ids), dtype=bool)
    if not images.is_dir():
        found = f" (it holds count vectors, {VISUAL_NPZ}, which that knowledge cannot use)" if has_counts \
            else ""
        raise DataFormatError(images, f"missing: the views must be images (<id>.jpg or .png) for the "
                              f"extractor {extractor.name!r} of knowledge fitted on images{found}")
    return extract_views(image_files(images, ids, missing_ok=True), extractor)


def plain_training_images(folder: str | os.PathLike[str]) -> list[Path]:
    """The image files of the training samples of the plain home in ``folder`` (not test.txt's)."""
    from spco.data.image_views import IMAGES_DIR, image_files

    home = Path(folder)
    csv_path = home / SAMPLES_CSV
    read = _read_samples_csv if csv_path.is_file() else _read_samples_jsonl
    ids = read(csv_path if csv_path.is_file() else home / SAMPLES_JSONL)[0]
    index = {sample: row for row, sample in enumerate(ids)}
    test = (_read_id_list(home / TEST_TXT, index) if (home / TEST_TXT).is_file()
            else np.zeros(len(ids), dtype=bool))
    files = image_files(home / IMAGES_DIR, [i for i, t in zip(ids, test, strict=True) if not t],
                        missing_ok=True)
    return [f for f in files if f is not None]


def _read_id_list(path: Path, index: dict[int, int]) -> np.ndarray:
    mask = np.zeros(len(index), dtype=bool)
    unknown = []
    for token in re.split(r"[,\s]+", _read_text(path).strip()):
        if not token:
            continue
        try:
            sample = int(token)
        except ValueError:
            raise DataFormatError(path, f"{token!r} is not a sample id (expected integers separated by "
                                  "commas or blanks)") from None
        if sample in index:
            mask[index[sample]] = True
        else:
            unknown.append(sample)
    if unknown:
        raise DataFormatError(path, f"names samples that do not exist: {sorted(set(unknown))[:10]}")
    return mask


def _read_labels(path: Path, index: dict[int, int]) -> tuple[tuple[str | None, ...] | None,
                                                             tuple[str | None, ...] | None]:
    reader = csv.DictReader(io.StringIO(_read_text(path), newline=""))
    header = [h.strip() for h in (reader.fieldnames or [])]
    if "id" not in header or not ({"label", "specific_label"} & set(header)):
        raise DataFormatError(path, "header must be id,label[,specific_label]")
    reader.fieldnames = header
    n = len(index)
    general: list[str | None] | None = [None] * n if "label" in header else None
    specific: list[str | None] | None = [None] * n if "specific_label" in header else None
    seen: set[int] = set()
    for row in reader:
        where = f"line {reader.line_num}"
        if all((v or "").strip() == "" for v in row.values() if isinstance(v, str)):
            continue
        sample = _integer(path, where, (row["id"] or "").strip())
        if sample not in index:
            raise DataFormatError(path, f"{where}: sample id {sample} does not exist")
        if sample in seen:
            raise DataFormatError(path, f"{where}: duplicate sample id {sample}")
        seen.add(sample)
        if general is not None:
            general[index[sample]] = (row.get("label") or "").strip() or None
        if specific is not None:
            specific[index[sample]] = (row.get("specific_label") or "").strip() or None
    return (None if general is None else tuple(general)), (None if specific is None else tuple(specific))


def _read_regions(path: Path) -> PlaceRegions:
    raw = _read_json(path)
    if not isinstance(raw, dict):
        raise DataFormatError(path, "expected an object place -> list of [x_min, x_max, y_min, y_max]")
    try:
        return PlaceRegions({p: tuple(tuple(r) for r in rects) for p, rects in raw.items()})
    except DataFormatError as exc:
        raise DataFormatError(path, exc.problem) from None
    except (TypeError, ValueError) as exc:
        raise DataFormatError(path, f"rectangles must be lists of 4 numbers ({exc})") from None


def _read_accepted_names(path: Path) -> dict[str, list[str]]:
    raw = _read_json(path)
    if not isinstance(raw, dict) or not all(isinstance(v, list) and all(isinstance(n, str) for n in v)
                                            for v in raw.values()):
        raise DataFormatError(path, "expected an object place -> list of accepted names (strings)")
    return {str(k): list(v) for k, v in raw.items()}


def read_home(folder: str | os.PathLike[str], teaching_rate: int = 100, extractor: Any = None) -> Environment:
    """Read one home in the plain format (see the module docstring).

    ``extractor`` (a :class:`spco.features.Extractor`): compute the visual counts from the home's
    ``images/`` with it (required for a home whose views are images only, refused for one that
    has none). ``teaching_rate`` below 100 keeps that percentage of the taught training samples' sentences, a
    seeded random subset (:meth:`Environment.with_teaching_rate` with ``seed=0``). Raises
    :class:`~spco.errors.DataFormatError` naming the file at fault.
    """
    home = Path(folder)
    if not home.exists():
        raise DataFormatError(home, "no such file or folder")
    if not home.is_dir():
        raise DataFormatError(home, "not a folder (a plain home is a folder holding samples.csv)")
    csv_path, jsonl_path = home / SAMPLES_CSV, home / SAMPLES_JSONL
    if csv_path.is_file() and jsonl_path.is_file():
        raise DataFormatError(home, f"holds both {SAMPLES_CSV} and {SAMPLES_JSONL}; keep one")
    if csv_path.is_file():
        samples_path = csv_path
        ids, poses, sentences = _read_samples_csv(csv_path)
    elif jsonl_path.is_file():
        samples_path = jsonl_path
        ids, poses, sentences = _read_samples_jsonl(jsonl_path)
    else:
        raise DataFormatError(csv_path, f"missing: a plain home needs {SAMPLES_CSV} or {SAMPLES_JSONL}")
    if not ids:
        raise DataFormatError(samples_path, "holds no samples: the home is empty")
    index: dict[int, int] = {}
    duplicates = []
    for row, sample in enumerate(ids):
        if sample in index:
            duplicates.append(sample)
        index[sample] = row
    if duplicates:
        raise DataFormatError(samples_path, f"duplicate sample ids: {sorted(set(duplicates))[:10]}")

    meta = _read_home_json(home / HOME_JSON)
    pose = np.asarray(poses, dtype=np.float64)
    positions = np.column_stack([pose[:, 0], pose[:, 1], np.sin(pose[:, 2]), np.cos(pose[:, 2])])
    visual, view_missing = _read_views(home, ids, meta.get("visual_scale"), extractor)
    is_test = (_read_id_list(home / TEST_TXT, index) if (home / TEST_TXT).is_file()
               else np.zeros(len(ids), dtype=bool))

    labels = specific = specific_test = regions = None
    if (home / LABELS_CSV).is_file():
        labels, specific = _read_labels(home / LABELS_CSV, index)
    if (home / SPECIFIC_TEST_TXT).is_file():
        specific_test = _read_id_list(home / SPECIFIC_TEST_TXT, index)
    if (home / REGIONS_JSON).is_file():
        regions = _read_regions(home / REGIONS_JSON)
    accepted = None
    if (home / ACCEPTED_NAMES_JSON).is_file():
        accepted = _read_accepted_names(home / ACCEPTED_NAMES_JSON)
    ground_truth = None
    if labels is not None or specific is not None or specific_test is not None or regions is not None:
        ground_truth = make_ground_truth(labels, specific, specific_test, regions, accepted)
    extent = meta.get("extent")
    env = Environment(
        name=str(meta["name"]).strip() if meta.get("name") else home.resolve().name,
        ids=np.asarray(ids, dtype=np.int64),
        positions=positions,
        visual=visual,
        sentences=tuple(sentences),
        is_test=is_test,
        extent=None if extent is None else tuple(extent),
        ground_truth=ground_truth,
        source=str(home),
        view_missing=view_missing,
    )
    return env if teaching_rate == 100 else env.with_teaching_rate(teaching_rate, seed=0)


# ------------------------------------------------------------------------------------------ writing
def _check_name(name: str) -> None:
    if (not name or name in (".", "..") or name.startswith(".") or any(c in name for c in "/\\\0")
            or name != name.strip()):
        raise ConfigurationError(f"home name {name!r} cannot be used as a folder name")


def _existing_files(folder: Path) -> list[str]:
    return [f for f in PLAIN_FILES if (folder / f).exists()] if folder.is_dir() else []


def _refuse_overwrite(folder: Path, existing: Sequence[str]) -> None:
    raise ConfigurationError(f"{folder} already holds a home ({', '.join(existing)}); use --force "
                             "(overwrite=True) to replace it")


def _write_files(env: Environment, folder: Path) -> None:
    """Write every file of ``env`` into the (new, empty) folder ``folder``."""
    theta = np.arctan2(env.positions[:, 2], env.positions[:, 3])
    with open(folder / SAMPLES_CSV, "w", encoding="utf-8", newline="") as fh:
        fh.write("id,x,y,theta,sentence\n")
        # every sentence is quoted: csv would leave a lone carriage return unquoted otherwise
        writer = csv.writer(fh, lineterminator="\n", quoting=csv.QUOTE_NONNUMERIC)
        for sample, (x, y), t, sentence in zip(env.ids.tolist(), env.positions[:, :2].tolist(),
                                               theta.tolist(), env.sentences, strict=True):
            writer.writerow([sample, x, y, t, sentence or ""])
    visual = sp.csr_array(env.visual)
    if not env.view_missing.any():
        sp.save_npz(folder / VISUAL_NPZ, visual, compressed=True)
    elif env.n_features > 0:  # the sparse matrix's arrays and the mask of samples without a view
        np.savez_compressed(folder / VISUAL_NPZ, format=np.array("csr"), shape=np.array(visual.shape),
                            data=visual.data, indices=visual.indices, indptr=visual.indptr,
                            **{MISSING_KEY: env.view_missing})
    # a home without any view (D = 0) has no visual file
    if env.is_test.any():
        (folder / TEST_TXT).write_text(", ".join(map(str, env.ids[env.is_test].tolist())) + "\n",
                                       encoding="utf-8")
    meta: dict[str, Any] = {"name": env.name}
    if env.extent is not None:
        meta["extent"] = list(env.extent)
    (folder / HOME_JSON).write_text(json.dumps(meta, indent=1) + "\n", encoding="utf-8")
    gt = env.ground_truth
    if gt is None:
        return
    if gt.labels is not None or gt.specific_labels is not None:
        columns = [("label", gt.labels), ("specific_label", gt.specific_labels)]
        columns = [(c, v) for c, v in columns if v is not None]
        with open(folder / LABELS_CSV, "w", encoding="utf-8", newline="") as fh:
            writer = csv.writer(fh, lineterminator="\n")
            writer.writerow(["id", *(c for c, _ in columns)])
            for row, sample in enumerate(env.ids.tolist()):
                writer.writerow([sample, *((v[row] or "") for _, v in columns)])
    if gt.specific_test is not None:
        chosen = env.ids[np.asarray(gt.specific_test, dtype=bool)].tolist()
        (folder / SPECIFIC_TEST_TXT).write_text(", ".join(map(str, chosen)) + "\n", encoding="utf-8")
    if gt.regions is not None:
        (folder / REGIONS_JSON).write_text(json.dumps(gt.regions.to_json(), indent=1) + "\n",
                                           encoding="utf-8")
    if gt.accepted_names is not None:
        (folder / ACCEPTED_NAMES_JSON).write_text(
            json.dumps({k: list(v) for k, v in gt.accepted_names.items()}, indent=1, ensure_ascii=False)
            + "\n", encoding="utf-8")


def write_home(env: Environment, folder: str | os.PathLike[str], overwrite: bool = False) -> Path:
    """Write ``env`` as a plain home into ``folder``; returns the folder.

    Every field is written, ground truth included. The files are first written into a temporary
    folder beside ``folder`` and then moved into place, so an interrupted write leaves no half home.
    If ``folder`` already holds files of the plain format, :class:`~spco.errors.ConfigurationError` is
    raised unless ``overwrite=True``, which replaces them (other files in the folder are left alone).
    """
    given = Path(folder)
    target = given.resolve()
    if target.exists() and not target.is_dir():
        raise ConfigurationError(f"{given} exists and is not a folder")
    existing = _existing_files(target)
    if existing and not overwrite:
        _refuse_overwrite(given, existing)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.parent / f".{target.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp"
    tmp.mkdir()
    try:
        _write_files(env, tmp)
        if not target.exists():
            os.replace(tmp, target)
            return given
        written = set(os.listdir(tmp))
        for name in PLAIN_FILES:
            if name in written:
                os.replace(tmp / name, target / name)
            elif (target / name).exists():
                (target / name).unlink()  # a stale file of an earlier home would contradict the new one
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return given


def write_corpus(corpus: Corpus | Sequence[Environment], folder: str | os.PathLike[str],
                 overwrite: bool = False) -> list[Path]:
    """Write every home of ``corpus`` into ``folder/<home name>/`` (plain format); returns the folders.

    Nothing is written if any home folder already holds plain-format files and ``overwrite`` is
    false (:class:`~spco.errors.ConfigurationError`, suggesting ``--force``).
    """
    root = Path(folder)
    if root.exists() and not root.is_dir():
        raise ConfigurationError(f"{root} exists and is not a folder")
    envs = list(corpus)
    for env in envs:
        _check_name(env.name)
    if not overwrite:
        taken = [env.name for env in envs if _existing_files(root / env.name)]
        if taken:
            raise ConfigurationError(f"{root} already holds home(s) {', '.join(taken[:5])}"
                                     f"{' …' if len(taken) > 5 else ''}; use --force (overwrite=True) to "
                                     "replace them")
    root.mkdir(parents=True, exist_ok=True)
    return [write_home(env, root / env.name, overwrite=overwrite) for env in envs]
