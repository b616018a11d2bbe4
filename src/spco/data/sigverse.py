"""Reader for the authors' SIGVerse dataset layout (Hagiwara et al., 2021).

One home is one folder; samples ``0 … N-1`` share one index across modalities::

    <home>/
      Environment_parameter.txt          optional: map extent, Last_data_number
      position/<i>.txt                   line 1 "x y" (metres), line 2 "sin(θ) cos(θ)"
      vision_fc7_normalized/<i>.csv      4,096 lines, one non-negative integer count each
      sentence/per_<XX>/sentence<i>.txt  optional: the sentence taught at teaching rate XX %
      test_num.txt                       optional: "3,4,5," test indices, or "999" = none
      name_label/word<i>.txt             optional, evaluation only: place name of sample i
      name_label_specific/word<i>.txt    optional, evaluation only: home-specific place name
      test_num_specific.txt              optional, evaluation only: home-specific test samples

How each quirk of the published data is handled:

- **Number of samples.** N is the number of ``position/<i>.txt`` files; they must be numbered
  ``0 … N-1`` without gaps, and every ``vision_fc7_normalized/<i>.csv`` must exist (and no more).
  ``Last_data_number`` (``359 #299``: a trailing ``#comment`` is ignored) must equal N-1 when the
  parameter file gives it. Stray files (``.DS_Store``, editor back-ups) are ignored.
- **Final newlines** may be missing anywhere; CRLF line ends and surrounding blanks are accepted.
- **Headings.** Each pose keeps ``(sin θ, cos θ)`` exactly as written when
  ``|sin²θ + cos²θ - 1| <= 0.01`` (four-decimal rounding in the data set gives at most 2e-4). A cos
  value that is truncated or mistyped is *recovered from sin θ*: ``cos θ = ±sqrt(1 - sin²θ)`` with the
  sign of the written value, provided the written digits are within 0.1 of that magnitude (or only the
  sign survived, as in ``-`` or ``-0.``). Anything else — sin θ outside [-1, 1], both values far off,
  a missing cos value — is refused with :class:`~spco.errors.DataFormatError`, because the heading
  cannot be known. Loading stays quiet about recovered values. In the published data set exactly
  one file needs this: ``1LDK_7/position/121.txt`` holds ``0.7351 0.625`` (sin²+cos² = 0.931); its
  cos is read as 0.6779. Thirteen other files (``3LDK_1/position/{5,111,123,124,126,127,128}.txt``
  and ``position/{7,8}.txt`` of the three ``3LDK_9*`` folders) carry hand-typed ``±1.0000``/``±1.000``
  cos values with a final newline; they are within rounding of a unit vector and are kept as written.
- **Map extent.** ``Max_x_value_of_map`` etc. are read as given. In several homes x and y are
  swapped (``1DK_8``: x in [-3, 3], y in [-5, 5], while the robot's x positions reach ±4.2). The
  loader keeps the extent as written when it contains every position, otherwise takes the swapped
  extent when *that* contains every position, otherwise the orientation that contains more of them.
  (When both orientations contain every position the extent stays as written, e.g. ``1LDK_9``, whose
  floor plan in ``maps/extents.json`` suggests it too is swapped.)
  Without a parameter file (``1LDK_10``, ``2LDK_10``) the extent is the positions' bounding box.
- **Teaching rate.** ``teaching_rate=XX`` reads ``sentence/per_XX``. A home without a ``sentence/``
  folder was taught nothing (every rate gives no sentences); rate 0 gives no sentences; asking for a
  rate the home does not have, when it has others, is an error that lists the available rates.
- **Test split.** ``test_num.txt`` is a comma or blank separated list (a trailing comma is fine);
  ``999`` alone means "no test samples"; a missing file means no test samples. An index outside
  ``0 … N-1`` is an error naming the file.
- **Ground truth** (evaluation only): ``name_label`` may lack files for some samples (``3LDK_9``
  samples 300–359 have none): those samples get the label ``None``. Region rectangles are taken from a
  ``sigverse_regions.json`` (format of :func:`~spco.data.regions.load_region_file`) lying in the home's
  parent folder or the folder above it, when there is one, or passed explicitly.
- **Visual counts** must be non-negative integers, 4,096 per file; a file of another length, or a line
  that is not a non-negative integer, is an error naming the file (and the line).

Reading is fast: each csv file is read as bytes, all files of a home are parsed together by a few
vectorised numpy operations (no Python loop over lines), and the counts go straight into a CSR matrix.
"""

from __future__ import annotations

import functools
import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from spco.data.environment import Environment, make_ground_truth
from spco.data.regions import PlaceRegions, load_region_file
from spco.errors import DataFormatError

#: Visual dimension of the SIGVerse layout (CaffeNet fc7).
FC7_DIM = 4096
#: Name of the optional region file looked for beside the data set.
REGION_FILE_NAME = "sigverse_regions.json"
#: sin²+cos² may differ from 1 by this much before the cos value is treated as damaged.
_KEEP_TOLERANCE = 0.01
#: A damaged cos value is recovered only if its digits are within this of sqrt(1 - sin²).
_RECOVER_TOLERANCE = 0.1

_CHUNK = 1 << 20
_OPEN_FLAGS = os.O_RDONLY | getattr(os, "O_BINARY", 0)
_NUMBER_PREFIX = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)?")
RatesMap = dict[int, tuple[str | None, ...]]
_EXTENT_KEYS = ("Min_x_value_of_map", "Max_x_value_of_map", "Min_y_value_of_map", "Max_y_value_of_map")
_NUMERIC_KEYS = (*_EXTENT_KEYS, "Number_of_place", "Initial_data_number", "Last_data_number")


def is_sigverse_home(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a folder in the SIGVerse layout (it has a ``position/`` folder)."""
    return (Path(path) / "position").is_dir()


# --------------------------------------------------------------------------------------- low level
def _read_bytes(path: str) -> bytes:
    fd = os.open(path, _OPEN_FLAGS)
    try:
        data = os.read(fd, _CHUNK)
        if len(data) < _CHUNK:
            return data
        chunks = [data]
        while chunk := os.read(fd, _CHUNK):
            chunks.append(chunk)
        return b"".join(chunks)
    finally:
        os.close(fd)


def _read_data_file(base: str, name: str) -> bytes:
    """Bytes of file ``base + name``; an unreadable file is a DataFormatError naming it."""
    try:
        return _read_bytes(base + name)
    except OSError as exc:
        raise DataFormatError(base + name, f"cannot be read ({exc.strerror})") from None


def _read_text(path: str | Path) -> str:
    try:
        return _read_bytes(str(path)).decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataFormatError(path, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise DataFormatError(path, f"cannot be read ({exc.strerror})") from None


def _indexed_files(folder: Path, prefix: str, suffix: str) -> dict[int, str]:
    """Map index -> file name for ``<prefix><i><suffix>`` files of ``folder`` (others ignored)."""
    out: dict[int, str] = {}
    plen, slen = len(prefix), len(suffix)
    try:
        names = os.listdir(folder)
    except OSError as exc:
        raise DataFormatError(folder, f"cannot be listed ({exc.strerror})") from None
    for name in names:
        if not (name.startswith(prefix) and name.endswith(suffix)):
            continue
        stem = name[plen:len(name) - slen]
        if not stem.isascii() or not stem.isdigit():
            continue
        index = int(stem)
        if index in out:
            raise DataFormatError(folder, f"duplicate sample ids: {out[index]} and {name} are both "
                                  f"sample {index}")
        out[index] = name
    return out


def _parse_index_list(path: Path, text: str) -> list[int]:
    out = []
    for token in re.split(r"[,\s]+", text.strip()):
        if not token:
            continue
        try:
            out.append(int(token))
        except ValueError:
            raise DataFormatError(path, f"{token!r} is not a sample index (expected comma-separated "
                                  "integers)") from None
    return out


def _read_index_mask(path: Path, n: int, sentinel: bool) -> np.ndarray | None:
    """Boolean mask from a test list file; ``None`` if the file does not exist."""
    if not path.is_file():
        return None
    indices = _parse_index_list(path, _read_text(path))
    mask = np.zeros(n, dtype=bool)
    if sentinel and indices == [999] and n <= 999:
        return mask
    arr = np.asarray(indices, dtype=np.int64)
    bad = arr[(arr < 0) | (arr >= n)]
    if bad.size:
        raise DataFormatError(path, f"names samples that do not exist: {sorted(set(bad.tolist()))[:10]} "
                              f"(the home has {n} samples, 0..{n - 1})")
    mask[arr] = True
    return mask


def _read_parameters(path: Path) -> dict[str, tuple[float, int]]:
    """``key value #comment`` lines -> {key: (value, line number)} for numeric values."""
    out: dict[str, tuple[float, int]] = {}
    for lineno, raw in enumerate(_read_text(path).splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        if len(parts) < 2 or parts[0] not in _NUMERIC_KEYS:
            continue
        try:
            value = float(parts[1])
        except ValueError:
            raise DataFormatError(path, f"line {lineno}: value {parts[1]!r} of {parts[0]} is not a "
                                  "number") from None
        if not math.isfinite(value):
            raise DataFormatError(path, f"line {lineno}: value of {parts[0]} is not finite")
        out[parts[0]] = (value, lineno)
    return out


# --------------------------------------------------------------------------------------- positions
def _float(token: str) -> float | None:
    try:
        return float(token)
    except ValueError:
        return None


def _recover_cos(path: Path, s: float, cos_token: str | None) -> float:
    """cos θ of a pose whose written cos value is damaged (see module docstring)."""
    if cos_token is None:
        raise DataFormatError(path, "line 2: cos θ is missing and cannot be recovered from sin θ "
                              "(its sign is unknown)")
    magnitude = math.sqrt(max(0.0, 1.0 - s * s))
    value = _float(cos_token)
    if value is not None and not cos_token.endswith("."):
        if not math.isfinite(value):
            raise DataFormatError(path, "non-finite (NaN or inf) position or heading")
        if abs(abs(value) - magnitude) <= _RECOVER_TOLERANCE:
            return math.copysign(magnitude, value)
        raise DataFormatError(path, f"line 2: sin²θ + cos²θ = {s * s + value * value:.3f} is far from 1 "
                              f"(sin θ = {s:g}, cos θ = {value:g})")
    match = _NUMBER_PREFIX.match(cos_token)
    kept = match.group(0) if match else ""
    sign = -1.0 if kept.startswith("-") else 1.0
    body = kept.lstrip("+-")
    if body and not body.endswith("."):  # leading digits survived, e.g. "0.62" of "0.62.5"
        if abs(float(body) - magnitude) <= _RECOVER_TOLERANCE:
            return sign * magnitude
    elif kept and body in ("", ".", "0.", "1."):  # only the sign survived: "-", "-0.", "0."
        return sign * magnitude
    raise DataFormatError(path, f"line 2: cos θ value {cos_token!r} is malformed and cannot be "
                          "recovered from sin θ")


def _parse_position(path: Path, data: bytes) -> tuple[float, float, float, float]:
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError:
        raise DataFormatError(path, "not a text file of numbers") from None
    lines = [ln.split() for ln in text.splitlines() if ln.strip()]
    if len(lines) != 2 or len(lines[0]) != 2 or not 1 <= len(lines[1]) <= 2:
        raise DataFormatError(path, "expected two lines 'x y' and 'sin(θ) cos(θ)', got "
                              f"{text.strip()[:60]!r}")
    x, y, s = _float(lines[0][0]), _float(lines[0][1]), _float(lines[1][0])
    if x is None or y is None:
        raise DataFormatError(path, f"line 1: expected two numbers 'x y', got {' '.join(lines[0])!r}")
    if s is None:
        raise DataFormatError(path, f"line 2: sin θ {lines[1][0]!r} is not a number")
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(s)):
        raise DataFormatError(path, "non-finite (NaN or inf) position or heading")
    if abs(s) > 1.0 + _KEEP_TOLERANCE:
        raise DataFormatError(path, f"line 2: sin θ = {s} is outside [-1, 1]")
    cos_token = lines[1][1] if len(lines[1]) == 2 else None
    c = _float(cos_token) if cos_token is not None else None
    if c is not None and math.isnan(c):
        raise DataFormatError(path, "non-finite (NaN or inf) position or heading")
    if c is not None and math.isfinite(c) and abs(s * s + c * c - 1.0) <= _KEEP_TOLERANCE:
        return x, y, s, c
    if c is not None and math.isinf(c):
        raise DataFormatError(path, "non-finite (NaN or inf) position or heading")
    return x, y, s, _recover_cos(path, s, cos_token)


def _read_positions(folder: Path, n: int, names: dict[int, str]) -> np.ndarray:
    out = np.empty((n, 4), dtype=np.float64)
    base = str(folder) + os.sep
    for i in range(n):
        name = names[i]
        data = _read_data_file(base, name)
        try:  # fast path: "x y" / "sin cos", four finite numbers forming a unit heading
            first, second, *rest = data.split(b"\n")
            if any(r.strip() for r in rest):
                raise ValueError
            tx, ty = first.split()
            ts, tc = second.split()
            x, y, s, c = float(tx), float(ty), float(ts), float(tc)
            if not (math.isfinite(x) and math.isfinite(y) and abs(s * s + c * c - 1.0) <= _KEEP_TOLERANCE):
                raise ValueError
        except ValueError:
            x, y, s, c = _parse_position(folder / name, data)
        out[i] = (x, y, s, c)
    return out


# ----------------------------------------------------------------------------------- visual counts
class _NotCanonical(Exception):
    """The fast parser met something other than digits and single newlines."""


_PAD = 8  # bytes put before the buffer so that shifted views stay aligned (lines up to 7 digits)


def _parse_counts_fast(blobs: Sequence[bytes], dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Parse visual files given as newline-terminated byte strings of one count per line.

    All files are parsed together with a handful of whole-buffer numpy operations (no Python loop over
    lines). Returns ``(line, value)`` for the non-zero lines, ``line`` counted across all files.
    Raises :class:`_NotCanonical` unless every byte is a digit or a newline, no line is empty, no
    count has more than seven digits and every file holds exactly ``dim`` lines — the careful per-file
    parser then takes over and explains what is wrong.
    """
    buf = b"".join([b" " * (_PAD - 1) + b"\n", *blobs])
    a = np.frombuffer(buf, dtype=np.uint8)
    d = a - np.uint8(48)  # digits -> 0..9, newline -> 218, anything else elsewhere
    is_nl = a == 10
    is_digit = d < 10
    m = a.size
    if np.count_nonzero(is_digit) + np.count_nonzero(is_nl) != m - (_PAD - 1):
        raise _NotCanonical
    start = _PAD
    for blob in blobs:  # every file must hold exactly `dim` lines
        if np.count_nonzero(is_nl[start:start + len(blob)]) != dim:
            raise _NotCanonical
        start += len(blob)
    ends = np.flatnonzero(is_nl[_PAD:])
    ends += _PAD  # position of each line's newline in `a`
    last = d[ends - 1]
    if last.size and last.max() > 9:  # an empty line
        raise _NotCanonical
    more = d[ends - 2] < 10
    nonzero = np.flatnonzero((last != 0) | more)
    values = last[nonzero].astype(np.int64)
    more = more[nonzero]
    ends = ends[nonzero]
    k, scale = 2, 10
    while more.any():
        if k >= _PAD:
            raise _NotCanonical
        values += (d[ends - k] * more).astype(np.int64) * scale
        k, scale = k + 1, scale * 10
        more &= d[ends - k] < 10
    return nonzero, values


def _parse_counts_slow(path: Path, data: bytes) -> np.ndarray:
    """Careful parse of one visual file; tolerates blanks and CRLF, names the bad line."""
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise DataFormatError(path, f"line {line}: not a non-negative integer count") from None
    lines = text.split("\n")
    while lines and not lines[-1].strip():
        lines.pop()
    tokens = np.array([ln.strip() for ln in lines], dtype=str) if lines else np.array([], dtype=str)
    ok = np.char.isdigit(tokens) if tokens.size else np.zeros(0, dtype=bool)
    if not ok.all():
        line = int(np.flatnonzero(~ok)[0])
        token = str(tokens[line])
        value = _float(token)
        if value is not None and value < 0:
            problem = f"negative count {token!r}"
        elif value is not None and math.isfinite(value) and not token.lstrip("+").isdigit():
            problem = f"{token!r} is not a whole number"
        else:
            problem = f"{token[:30]!r} is not a non-negative integer count"
        raise DataFormatError(path, f"line {line + 1}: {problem}")
    try:
        return tokens.astype(np.int64) if tokens.size else np.zeros(0, dtype=np.int64)
    except (ValueError, OverflowError):
        raise DataFormatError(path, "holds a count too large for a 64-bit integer") from None


def _wrong_length(path: Path, found: int, dim: int) -> DataFormatError:
    return DataFormatError(path, f"holds {found} values, expected {dim} (one count per line)")


def _read_visual(folder: Path, n: int, names: dict[int, str], dim: int = FC7_DIM) -> sp.csr_array:
    base = str(folder) + os.sep
    blobs = []
    for i in range(n):
        data = _read_data_file(base, names[i])
        if not data.endswith(b"\n"):
            data += b"\n"
        blobs.append(data)
    try:
        line, values = _parse_counts_fast(blobs, dim)
    except _NotCanonical:
        dense = np.empty((n, dim), dtype=np.int64)
        for i, data in enumerate(blobs):
            path = folder / names[i]
            try:
                nz, vals = _parse_counts_fast([data], dim)
                row = np.zeros(dim, dtype=np.int64)
                row[nz] = vals
            except _NotCanonical:
                row = _parse_counts_slow(path, data)
            if row.size != dim:
                raise _wrong_length(path, row.size, dim) from None
            dense[i] = row
        line = np.flatnonzero(dense)
        values = dense.ravel()[line]
    indptr = np.searchsorted(line, np.arange(n + 1, dtype=np.int64) * dim).astype(np.int64)
    return sp.csr_array((values, (line % dim).astype(np.int32), indptr), shape=(n, dim))


# --------------------------------------------------------------------------------------- sentences
def _rate_folders(home: Path) -> dict[int, Path]:
    folder = home / "sentence"
    if not folder.is_dir():
        return {}
    out = {}
    for entry in sorted(os.listdir(folder)):
        m = re.fullmatch(r"per_(\d+)", entry)
        if m and (folder / entry).is_dir():
            out[int(m.group(1))] = folder / entry
    return out


def read_indexed_texts(folder: Path, prefix: str, n: int, *, strict: bool) -> tuple[str | None, ...]:
    """Text of ``<prefix><i>.txt`` of a SIGVerse folder for i in 0..n-1, whitespace collapsed
    (``None`` where absent or blank). ``strict``: a file for a sample i ≥ n raises
    :class:`~spco.errors.DataFormatError`; otherwise it is ignored."""
    names = _indexed_files(folder, prefix, ".txt")
    extra = sorted(i for i in names if i >= n)
    if extra and strict:
        raise DataFormatError(folder / names[extra[0]], f"is for sample {extra[0]}, but the home has "
                              f"only {n} samples (0..{n - 1})")
    out: list[str | None] = [None] * n
    base = str(folder) + os.sep
    for i, name in names.items():
        if i < n:
            text = " ".join(_read_text(base + name).split())
            out[i] = text or None
    return tuple(out)


def sigverse_teaching_rates(path: str | os.PathLike[str]) -> list[int]:
    """The teaching rates (percent) a SIGVerse home has sentences for, ascending (may be empty)."""
    return sorted(_rate_folders(Path(path)))


# --------------------------------------------------------------------------------------- extent
def _choose_extent(path: Path, params: Mapping[str, tuple[float, int]],
                   positions: np.ndarray) -> tuple[float, float, float, float]:
    keys = _EXTENT_KEYS
    xy = positions[:, :2]
    bbox = (float(xy[:, 0].min()), float(xy[:, 0].max()), float(xy[:, 1].min()), float(xy[:, 1].max()))
    if not all(k in params for k in keys):
        return bbox
    x0, x1, y0, y1 = (params[k][0] for k in keys)
    if x0 > x1 or y0 > y1:
        raise DataFormatError(path, f"map extent has a minimum above its maximum (x {x0}..{x1}, "
                              f"y {y0}..{y1})")

    def inside(ext: tuple[float, float, float, float]) -> int:
        return int(((xy[:, 0] >= ext[0]) & (xy[:, 0] <= ext[1])
                    & (xy[:, 1] >= ext[2]) & (xy[:, 1] <= ext[3])).sum())

    given = (x0, x1, y0, y1)
    swapped = (y0, y1, x0, x1)
    n = xy.shape[0]
    if inside(given) == n:
        return given
    if inside(swapped) == n:
        return swapped
    return swapped if inside(swapped) > inside(given) else given


# --------------------------------------------------------------------------------------- regions
@functools.lru_cache(maxsize=8)
def _region_file(path: str, mtime_ns: int) -> dict[str, PlaceRegions]:
    return load_region_file(path)


def _find_regions(home: Path) -> PlaceRegions | None:
    home = home.resolve()
    for folder in (home.parent, home.parent.parent):
        candidate = folder / REGION_FILE_NAME
        if candidate.is_file():
            return _region_file(str(candidate), candidate.stat().st_mtime_ns).get(home.name)
    return None


# --------------------------------------------------------------------------------------- homes
def _sample_files(home: Path) -> tuple[Path, dict[int, str], Path, dict[int, str]]:
    """A SIGVerse home's ``position/`` and ``vision_fc7_normalized/`` folders and their files by
    sample index, checked: numbered 0..n-1 without gaps, one visual file per position file."""
    if not home.exists():
        raise DataFormatError(home, "no such file or folder")
    pos_dir = home / "position"
    if not pos_dir.is_dir():
        raise DataFormatError(home, "not a SIGVerse home: it has no position/ folder")
    pos_names = _indexed_files(pos_dir, "", ".txt")
    if not pos_names:
        raise DataFormatError(pos_dir, "holds no position files (<i>.txt): the home is empty")
    n = max(pos_names) + 1
    if len(pos_names) != n:
        missing = sorted(set(range(n)) - set(pos_names))
        raise DataFormatError(pos_dir, f"sample files must be numbered 0..{n - 1} without gaps; missing "
                              f"{', '.join(f'{i}.txt' for i in missing[:10])}"
                              f"{' …' if len(missing) > 10 else ''}")
    vis_dir = home / "vision_fc7_normalized"
    if not vis_dir.is_dir():
        raise DataFormatError(vis_dir, "missing: every SIGVerse home needs its visual counts")
    vis_names = _indexed_files(vis_dir, "", ".csv")
    missing = sorted(set(range(n)) - set(vis_names))
    if missing:
        raise DataFormatError(vis_dir / f"{missing[0]}.csv",
                              f"missing ({len(missing)} visual files missing for the {n} samples of "
                              "position/)")
    if len(vis_names) != n:
        extra = sorted(set(vis_names) - set(range(n)))
        raise DataFormatError(vis_dir, f"holds visual files for samples without a position file: "
                              f"{', '.join(vis_names[i] for i in extra[:10])}")
    return pos_dir, pos_names, vis_dir, vis_names


def _checked_parameters(param_file: Path, n: int) -> dict[str, tuple[float, int]]:
    """``Environment_parameter.txt`` (empty without one), checked against the ``n`` samples."""
    params = _read_parameters(param_file) if param_file.is_file() else {}
    if "Last_data_number" in params:
        last, lineno = params["Last_data_number"]
        if last != n - 1:
            raise DataFormatError(param_file, f"line {lineno}: Last_data_number is {last:g}, but "
                                  f"position/ holds {n} samples (0..{n - 1})")
    if "Initial_data_number" in params and params["Initial_data_number"][0] != 0:
        raise DataFormatError(param_file, "Initial_data_number must be 0 (samples are numbered from 0)")
    return params


def read_sigverse_home(
    path: str | os.PathLike[str],
    regions: PlaceRegions | str | None = "auto",
) -> tuple[Environment, RatesMap]:
    """Read a SIGVerse home with the sentences of *every* teaching rate it has.

    Returns the home (its sentences: those of the highest rate, or none) and a mapping
    ``rate -> sentences`` (empty if the home has no ``sentence/`` folder). ``regions="auto"`` looks for
    ``sigverse_regions.json`` beside the data set; pass a :class:`PlaceRegions` or ``None`` instead to
    choose. Used by :func:`load_sigverse_home` and by the cache, which stores every rate.
    """
    home = Path(path)
    pos_dir, pos_names, vis_dir, vis_names = _sample_files(home)
    n = len(pos_names)
    param_file = home / "Environment_parameter.txt"
    params = _checked_parameters(param_file, n)
    positions = _read_positions(pos_dir, n, pos_names)
    visual = _read_visual(vis_dir, n, vis_names)
    is_test = _read_index_mask(home / "test_num.txt", n, sentinel=True)
    if is_test is None:
        is_test = np.zeros(n, dtype=bool)

    rates: RatesMap = {}
    for rate, folder in _rate_folders(home).items():
        rates[rate] = read_indexed_texts(folder, "sentence", n, strict=True)

    labels = specific = None
    if (home / "name_label").is_dir():
        labels = read_indexed_texts(home / "name_label", "word", n, strict=False)
    if (home / "name_label_specific").is_dir():
        specific = read_indexed_texts(home / "name_label_specific", "word", n, strict=False)
    specific_test = _read_index_mask(home / "test_num_specific.txt", n, sentinel=True)
    if regions == "auto":
        regions = _find_regions(home)
    elif isinstance(regions, str):
        raise ValueError(f"regions must be 'auto', a PlaceRegions or None, got {regions!r}")
    ground_truth = None
    if labels is not None or specific is not None or specific_test is not None or regions is not None:
        ground_truth = make_ground_truth(labels, specific, specific_test, regions)

    env = Environment(
        name=home.resolve().name,
        ids=np.arange(n, dtype=np.int64),
        positions=positions,
        visual=visual,
        sentences=rates[max(rates)] if rates else (None,) * n,
        is_test=is_test,
        extent=_choose_extent(param_file, params, positions),
        ground_truth=ground_truth,
        source=str(home),
    )
    return env, rates


def select_rate(env: Environment, rates: RatesMap, teaching_rate: int, where: str) -> Environment:
    """The home ``env`` with the sentences of ``teaching_rate`` taken from ``rates``.

    ``rates`` empty (nothing was ever taught) or ``teaching_rate == 0`` give a home without sentences;
    a rate missing from a non-empty ``rates`` raises :class:`DataFormatError` naming ``where``.
    """
    if not rates or teaching_rate == 0:
        if all(s is None for s in env.sentences):
            return env
        return env.with_sentences((None,) * env.n_samples)
    if teaching_rate not in rates:
        available = ", ".join(str(r) for r in sorted(rates))
        raise DataFormatError(where, f"no sentences for teaching rate {teaching_rate}% in home "
                              f"{env.name!r}; available rates: {available}")
    chosen = rates[teaching_rate]
    return env if chosen == env.sentences else env.with_sentences(chosen)


def load_sigverse_home(
    path: str | os.PathLike[str],
    teaching_rate: int = 100,
    regions: PlaceRegions | str | None = "auto",
) -> Environment:
    """Load one home in the SIGVerse layout.

    Parameters
    ----------
    path:
        The home's folder (it holds ``position/`` and ``vision_fc7_normalized/``).
    teaching_rate:
        Which ``sentence/per_<rate>`` folder to read (0 = nothing taught).
    regions:
        Ground-truth place regions; ``"auto"`` (default) reads ``sigverse_regions.json`` from the home's
        parent folder or the one above when present.

    Raises :class:`~spco.errors.DataFormatError` naming the file at fault. See the module docstring for
    every quirk of the published data and how it is handled.
    """
    env, rates = read_sigverse_home(path, regions=regions)
    return select_rate(env, rates, teaching_rate, str(Path(path) / "sentence"))


def sigverse_homes(path: str | os.PathLike[str]) -> list[Path]:
    """Subfolders of ``path`` in the SIGVerse layout, sorted by name (hidden folders skipped)."""
    folder = Path(path)
    return [folder / name for name in sorted(os.listdir(folder))
            if not name.startswith(".") and is_sigverse_home(folder / name)]


def load_sigverse_folder(
    path: str | os.PathLike[str],
    teaching_rate: int = 100,
    progress: bool = False,
    names: Sequence[str] | None = None,
) -> list[Environment]:
    """Load every SIGVerse home in folder ``path`` (each subfolder with ``position/``), by name.

    ``names`` restricts (and orders) the homes to load. ``progress=True`` shows a progress bar on
    standard error when it is a terminal (the bar is wiped when done).
    """
    from spco.progress import progress_bar

    folder = Path(path)
    if not folder.is_dir():
        raise DataFormatError(folder, "no such folder")
    homes = sigverse_homes(folder)
    if names is not None:
        by_name = {h.name: h for h in homes}
        unknown = [n for n in names if n not in by_name]
        if unknown:
            raise DataFormatError(folder, f"no home named {', '.join(map(repr, unknown))}; homes: "
                                  f"{', '.join(by_name)}")
        homes = [by_name[n] for n in names]
    if not homes:
        raise DataFormatError(folder, "holds no SIGVerse homes (subfolders with position/)")
    with progress_bar(homes, desc="reading homes", unit="home", leave=False,
                      disable=None if progress else True) as bar:
        return [load_sigverse_home(home, teaching_rate) for home in bar]
