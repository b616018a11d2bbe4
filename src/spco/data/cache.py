"""A compact single-file cache of many homes: ``spco import SRC cache.npz``
(:func:`spco.data.loading.write_cache`), then load in a blink.

The file is a compressed ``.npz`` (a zip of ``.npy`` arrays, read with ``allow_pickle=False``):

``header``
    UTF-8 JSON as a uint8 array: ``{"format": "spco-cache", "format_version": 1, "spco_version",
    "home_names", "homes": [...]}``; each home gives ``name``, ``source``, ``n_samples``,
    ``n_features``, ``extent``, its sentences — ``{"mode": "rates", "rates": {"20": [...], ...}}``
    (SIGVerse homes: the sentences of every stored teaching rate) or ``{"mode": "subsample",
    "sentences": [...]}`` (plain homes: a lower rate keeps a seeded random subset) — and its
    evaluation-only ground truth (``labels``, ``specific_labels``, ``specific_test`` as row indices,
    ``regions``) and, when some samples have no view, ``view_missing`` (their row indices; their
    counts are zero; ``n_features`` is 0 for a home without any view).
``ids``, ``positions``, ``is_test``
    The samples of all homes, concatenated in home order: int64 (N,), float64 (N, 4), bool (N,).
``sample_offsets``
    int64 (H + 1,): home *h* owns rows ``sample_offsets[h]:sample_offsets[h + 1]``.
``visual_row_nnz``, ``visual_indices``, ``visual_data``
    The visual counts of all rows as one CSR matrix: non-zeros per row, column indices and counts
    (stored in the smallest unsigned integer type that holds them).

The file is written to a temporary file in the same folder and renamed into place, so readers never
see a half-written cache. A truncated, edited or foreign file raises
:class:`~spco.errors.DataFormatError` naming the file (the zip's CRC-32 checks catch damaged bytes).
"""

from __future__ import annotations

import json
import os
import uuid
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from spco.data.environment import Environment, make_ground_truth
from spco.data.records import HomeRecord
from spco.data.regions import PlaceRegions
from spco.errors import ConfigurationError, DataFormatError

CACHE_FORMAT = "spco-cache"
CACHE_VERSION = 1
_ARRAYS = ("ids", "positions", "is_test", "sample_offsets", "visual_row_nnz", "visual_indices",
           "visual_data")


def is_cache_file(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a zip (``.npz``) file holding an spco cache header (cheap check)."""
    try:
        with zipfile.ZipFile(path) as zf:
            return "header.npy" in zf.namelist()
    except (OSError, zipfile.BadZipFile, ValueError):
        return False


def _smallest_uint(values: np.ndarray) -> np.ndarray:
    top = int(values.max()) if values.size else 0
    for dtype in (np.uint8, np.uint16, np.uint32):
        if top <= np.iinfo(dtype).max:
            return values.astype(dtype)
    return values.astype(np.int64)


def _labels(values: tuple[str | None, ...] | None) -> list[str | None] | None:
    return None if values is None else list(values)


def _home_header(rec: HomeRecord, teaching_rate: int | None) -> dict[str, Any]:
    env = rec.environment
    if teaching_rate is not None:
        chosen = rec.at_rate(teaching_rate)
        empty = rec.rates is not None and not rec.rates
        sentences = {"mode": "rates",
                     "rates": {} if empty else {str(teaching_rate): list(chosen.sentences)}}
    elif rec.rates is not None:
        sentences = {"mode": "rates", "rates": {str(r): list(s) for r, s in sorted(rec.rates.items())}}
    else:
        sentences = {"mode": "subsample", "sentences": list(env.sentences)}
    gt = env.ground_truth
    return {
        "name": env.name,
        "source": env.source,
        "n_samples": env.n_samples,
        "n_features": env.n_features,
        "extent": None if env.extent is None else list(env.extent),
        "sentences": sentences,
        "labels": None if gt is None else _labels(gt.labels),
        "specific_labels": None if gt is None else _labels(gt.specific_labels),
        "specific_test": (None if gt is None or gt.specific_test is None
                          else np.flatnonzero(gt.specific_test).tolist()),
        "regions": None if gt is None or gt.regions is None else gt.regions.to_json(),
        # rows of the samples without a view (absent: every sample has one)
        **({"view_missing": np.flatnonzero(env.view_missing).tolist()} if env.view_missing.any() else {}),
    }


def write_records(records: list[HomeRecord], out: str | os.PathLike[str],
                  teaching_rate: int | None = None) -> None:
    """Write ``records`` as a cache file ``out`` (atomically; replaces ``out`` if it exists)."""
    from spco import __version__

    if not records:
        raise DataFormatError(None, "no homes to write to the cache")
    envs = [r.environment for r in records]
    header = {
        "format": CACHE_FORMAT,
        "format_version": CACHE_VERSION,
        "spco_version": __version__,
        "home_names": [e.name for e in envs],
        "homes": [_home_header(r, teaching_rate) for r in records],
    }
    visual = [sp.csr_array(e.visual) for e in envs]
    arrays = {
        "header": np.frombuffer(json.dumps(header, ensure_ascii=False).encode("utf-8"), dtype=np.uint8),
        "ids": np.concatenate([e.ids for e in envs]).astype(np.int64),
        "positions": np.concatenate([e.positions for e in envs]).astype(np.float64),
        "is_test": np.concatenate([e.is_test for e in envs]).astype(bool),
        "sample_offsets": np.concatenate([[0], np.cumsum([e.n_samples for e in envs])]).astype(np.int64),
        "visual_row_nnz": _smallest_uint(np.concatenate([np.diff(v.indptr) for v in visual])),
        "visual_indices": _smallest_uint(np.concatenate([v.indices for v in visual])),
        "visual_data": _smallest_uint(np.concatenate([v.data for v in visual])),
    }
    target = Path(out)
    tmp = target.parent / f".{target.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp"
    try:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    finally:
        if tmp.exists():
            tmp.unlink()


# ------------------------------------------------------------------------------------------ reading
def _damaged(path: Path, problem: str) -> DataFormatError:
    return DataFormatError(path, f"damaged or edited spco cache: {problem} (rebuild it with spco import)")


def _load_arrays(path: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    try:
        with np.load(path, allow_pickle=False) as npz:
            if "header" not in npz.files:
                raise DataFormatError(path, "not an spco cache file (no header)")
            raw = npz["header"]
            try:
                header = json.loads(raw.tobytes().decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError, ValueError):
                raise _damaged(path, "unreadable header") from None
            if not isinstance(header, dict) or header.get("format") != CACHE_FORMAT:
                raise DataFormatError(path, "not an spco cache file (foreign header)")
            version = header.get("format_version")
            if not isinstance(version, int) or version < 1:
                raise _damaged(path, f"invalid format version {version!r}")
            if version > CACHE_VERSION:
                raise DataFormatError(path, f"written by a newer spco (cache format {version}, this "
                                      f"spco reads {CACHE_VERSION}); upgrade spco or rebuild the cache")
            missing = [k for k in _ARRAYS if k not in npz.files]
            if missing:
                raise _damaged(path, f"missing arrays {', '.join(missing)}")
            arrays = {k: npz[k] for k in _ARRAYS}
    except DataFormatError:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise DataFormatError(path, f"not a readable spco cache file, truncated or damaged ({exc}); "
                              "rebuild it with spco import") from None
    return header, arrays


def _check(path: Path, ok: bool, problem: str) -> None:
    if not ok:
        raise _damaged(path, problem)


def read_cache_records(path: str | os.PathLike[str]) -> list[HomeRecord]:
    """Read a cache file into :class:`~spco.data.records.HomeRecord` objects (every stored rate)."""
    src = Path(path)
    if not src.is_file():
        raise DataFormatError(src, "no such file" if not src.exists() else "not a file")
    header, a = _load_arrays(src)
    homes = header.get("homes")
    _check(src, isinstance(homes, list) and len(homes) > 0, "no homes listed")
    h = len(homes)
    offsets = a["sample_offsets"]
    n_total = a["ids"].shape[0] if a["ids"].ndim == 1 else -1
    _check(src, offsets.shape == (h + 1,) and np.issubdtype(offsets.dtype, np.integer)
           and offsets[0] == 0 and (np.diff(offsets) > 0).all() and offsets[-1] == n_total,
           "sample offsets do not match the homes")
    _check(src, a["positions"].shape == (n_total, 4) and a["is_test"].shape == (n_total,)
           and a["visual_row_nnz"].shape == (n_total,), "array shapes do not match")
    for key in ("ids", "visual_row_nnz", "visual_indices", "visual_data"):
        _check(src, np.issubdtype(a[key].dtype, np.integer), f"{key} must hold integers")
    _check(src, np.issubdtype(a["positions"].dtype, np.floating) and a["is_test"].dtype == bool,
           "positions or test mask have the wrong type")
    indptr = np.zeros(n_total + 1, dtype=np.int64)
    np.cumsum(a["visual_row_nnz"], out=indptr[1:])
    _check(src, indptr[-1] == a["visual_indices"].size == a["visual_data"].size,
           "visual arrays do not match their row counts")
    indices = a["visual_indices"].astype(np.int32)
    data = a["visual_data"].astype(np.int64)
    records = []
    for k, meta in enumerate(homes):
        lo, hi = int(offsets[k]), int(offsets[k + 1])
        try:
            records.append(_record(src, meta, a, indptr, indices, data, lo, hi))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            if isinstance(exc, DataFormatError):
                raise
            raise _damaged(src, f"home #{k + 1}: malformed entry ({type(exc).__name__}: {exc})") from None
    return records


def _row_mask(src: Path, name: str, rows: Any, n: int, what: str) -> np.ndarray | None:
    """A (n,) mask of the rows listed in a cached home's ``what`` (``None`` when not recorded)."""
    if rows is None:
        return None
    rows = np.asarray(rows, dtype=np.int64)
    _check(src, rows.ndim == 1 and ((rows >= 0) & (rows < n)).all(), f"home {name!r}: bad {what}")
    mask = np.zeros(n, dtype=bool)
    mask[rows] = True
    return mask


def _cached_sentences(src: Path, name: str, teaching: dict[str, Any], n: int, strings: Any
                      ) -> tuple[dict[int, tuple[str | None, ...]] | None, tuple[str | None, ...]]:
    """A cached home's sentences: (per teaching rate, or ``None``; the sentences it starts with)."""
    if teaching["mode"] == "rates":
        _check(src, isinstance(teaching["rates"], dict), f"home {name!r}: bad sentences")
        rates: dict[int, tuple[str | None, ...]] = {}
        for r, s in teaching["rates"].items():
            chosen = strings(s, "sentences")
            _check(src, chosen is not None and 0 <= int(r) <= 100, f"home {name!r}: bad sentences")
            rates[int(r)] = chosen
        return rates, rates[max(rates)] if rates else (None,) * n
    if teaching["mode"] == "subsample":
        base = strings(teaching["sentences"], "sentences")
        _check(src, base is not None, f"home {name!r}: bad sentences")
        return None, base
    raise _damaged(src, f"home {name!r}: unknown sentence mode {teaching['mode']!r}")


def _record(src: Path, meta: dict[str, Any], a: dict[str, np.ndarray], indptr: np.ndarray,
            indices: np.ndarray, data: np.ndarray, lo: int, hi: int) -> HomeRecord:
    name = meta["name"]
    n, dim = int(meta["n_samples"]), int(meta["n_features"])
    _check(src, isinstance(name, str) and n == hi - lo and dim >= 0, f"home {name!r}: wrong sample count")
    view_missing = _row_mask(src, name, meta.get("view_missing"), n, "view_missing")
    if view_missing is None:
        view_missing = np.zeros(n, dtype=bool)
    p0, p1 = int(indptr[lo]), int(indptr[hi])
    cols = indices[p0:p1]
    _check(src, cols.size == 0 or int(cols.max()) < dim, f"home {name!r}: visual column out of range")
    visual = sp.csr_array((data[p0:p1], cols, indptr[lo:hi + 1] - p0), shape=(n, dim))

    def strings(values: Any, what: str) -> tuple[str | None, ...] | None:
        if values is None:
            return None
        _check(src, isinstance(values, list) and len(values) == n
               and all(v is None or isinstance(v, str) for v in values), f"home {name!r}: bad {what}")
        return tuple(values)

    rates, base = _cached_sentences(src, name, meta["sentences"], n, strings)
    labels = strings(meta.get("labels"), "labels")
    specific = strings(meta.get("specific_labels"), "specific labels")
    specific_test = _row_mask(src, name, meta.get("specific_test"), n, "specific_test")
    regions = None
    if meta.get("regions") is not None:
        try:
            regions = PlaceRegions({p: tuple(tuple(r) for r in rects)
                                    for p, rects in meta["regions"].items()})
        except DataFormatError as exc:
            raise _damaged(src, f"home {name!r}: {exc.problem}") from None
    ground_truth = None
    if labels is not None or specific is not None or specific_test is not None or regions is not None:
        ground_truth = make_ground_truth(labels, specific, specific_test, regions)
    extent = meta.get("extent")
    where = f"{src}:{name}"
    try:
        env = Environment(
            name=name,
            ids=a["ids"][lo:hi],
            positions=a["positions"][lo:hi],
            visual=visual,
            sentences=base,
            is_test=a["is_test"][lo:hi],
            extent=None if extent is None else tuple(extent),
            ground_truth=ground_truth,
            source=where,
            view_missing=view_missing,
        )
    except DataFormatError as exc:
        raise _damaged(src, f"home {name!r}: {exc.problem}") from None
    return HomeRecord(env, rates, str(src))


def read_cache(path: str | os.PathLike[str], teaching_rate: int = 100) -> list[Environment]:
    """The homes of cache file ``path`` as taught at ``teaching_rate`` percent.

    A SIGVerse home answers with the stored sentences of that rate (an error lists the stored rates if
    it is missing); a plain home keeps a seeded random ``teaching_rate`` percent of its sentences.
    """
    if isinstance(teaching_rate, bool) or not isinstance(teaching_rate, int) or not 0 <= teaching_rate <= 100:
        raise ConfigurationError(f"teaching rate must be an integer within 0..100, got {teaching_rate!r}")
    return [r.at_rate(teaching_rate) for r in read_cache_records(path)]
