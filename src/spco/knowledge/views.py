"""One observation's pose and view, checked: what :func:`~spco.knowledge.teach` and
:func:`~spco.knowledge.what` take, and the feature files ``spco what --visual`` reads."""

from __future__ import annotations

from collections.abc import Callable
from os import PathLike
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp

from spco.errors import ConfigurationError, DataFormatError
from spco.model.prediction import validate_visual_counts

if TYPE_CHECKING:
    from spco.features import Extractor
    from spco.knowledge.home import HomeModel
    from spco.knowledge.knowledge import Knowledge

def _visual_row(visual: Any, n_features: int) -> sp.csr_array:
    """One observation's visual counts as a (1, D) int64 CSR row, validated (``None``: the
    observation has no view, an empty row)."""
    if visual is None:
        return sp.csr_array((1, n_features), dtype=np.int64)
    if sp.issparse(visual):
        row = sp.csr_array(visual)
    else:
        dense = np.asarray(visual)
        if dense.ndim == 2 and dense.shape[0] == 1:
            dense = dense[0]
        if dense.ndim != 1:
            raise ConfigurationError(f"visual counts of one observation must be a vector, got shape "
                                     f"{dense.shape}")
        if not np.issubdtype(dense.dtype, np.number):
            raise ConfigurationError("visual counts must be numbers")
        row = sp.csr_array(dense[None, :])
    if row.shape != (1, n_features):
        raise ConfigurationError(f"visual counts have {row.shape[1]} values, the home's views {n_features}")
    out = sp.csr_array(validate_visual_counts(row, n_features), dtype=np.int64)  # the library's checks
    out.eliminate_zeros()
    return out


#: How far beyond its map (in map sizes) a pose is still answered (with a warning) by :func:`what`.
FAR_OUTSIDE_MAP = 1.0


def map_bounds(home: HomeModel) -> tuple[float, float, float, float]:
    """``(x_min, x_max, y_min, y_max)`` of the home's map: its extent, or the box around its samples."""
    if home.extent is not None:
        return tuple(float(v) for v in home.extent)  # type: ignore[return-value]
    xy = home.positions[:, :2]
    return float(xy[:, 0].min()), float(xy[:, 0].max()), float(xy[:, 1].min()), float(xy[:, 1].max())


def pose_outside_map(home: HomeModel, x: float, y: float) -> str | None:
    """``None`` if ``(x, y)`` lies on the home's map (:func:`map_bounds`), else a sentence saying how far
    outside it is. Raises :class:`ConfigurationError` when the pose is more than
    :data:`FAR_OUTSIDE_MAP` map sizes beyond the map: the robot has learnt nothing about such a place,
    and the region Gaussians' densities there are all zero in floating point."""
    x0, x1, y0, y1 = map_bounds(home)
    size = max(x1 - x0, y1 - y0, 1.0)
    beyond = max(x0 - x, x - x1, y0 - y, y - y1, 0.0)
    if beyond == 0.0:
        return None
    where = (f"the pose ({x:g}, {y:g}) is {beyond:.3g} m outside the map of home {home.name!r} "
             f"(x {x0:g}…{x1:g}, y {y0:g}…{y1:g} m)")
    if beyond > FAR_OUTSIDE_MAP * size:
        raise ConfigurationError(f"{where}: the robot has learnt nothing there; give a pose on the map, "
                                 f"in metres, in the map frame the home was recorded in")
    return where



def view_counts(knowledge: Knowledge, visual: Any = None, image: Any = None, encoding: str | None = None,
                extractor: Callable[[], Extractor] | None = None) -> Any:
    """One view's visual counts, as every entry point takes a view (library, CLI, HTTP, ROS).

    ``visual``: the counts themselves, returned as given (checked where they are used,
    :func:`_visual_row`); or ``image``: a file, encoded bytes or an array of pixels in ``encoding``,
    turned into counts by the knowledge's extractor (``extractor``: a function giving the
    extractor to use, e.g. one the caller keeps; default :meth:`Knowledge.image_extractor`); neither:
    ``None`` (no view). Raises :class:`~spco.errors.ConfigurationError` for both, and for an image
    when the knowledge was fitted on count vectors.
    """
    if image is None:
        return visual
    if visual is not None:
        raise ConfigurationError("give the view either as visual counts or as an image, not both")
    if not knowledge.fitted_on_images:
        raise ConfigurationError("the knowledge of this home was fitted on visual count vectors, not on "
                                 "images: give the view's features (visual counts, --visual), not an image")
    return (extractor or knowledge.image_extractor)().extract(image, encoding)



def read_visual_vector(path: str | PathLike[str], n_features: int | None = None,
                       scale: float | None = None) -> np.ndarray:
    """One view's visual features from a file, as a (D,) int64 count vector.

    Accepted: ``.npy`` (a vector or a 1-row matrix), ``.npz`` (one array, or a sparse 1-row matrix
    saved with ``scipy.sparse.save_npz``), or text (``.csv``, ``.txt``: numbers separated by
    newlines, commas or spaces — the SIGVerse ``vision_fc7_normalized/<i>.csv`` files). With
    ``scale``, real-valued features become counts ``floor(max(f, 0) × scale)``; without, the
    values must be non-negative whole numbers. Raises :class:`~spco.errors.DataFormatError`.
    """
    from spco.data.plain import features_to_counts

    file = Path(path).expanduser()
    if not file.is_file():
        raise DataFormatError(file, "no such visual feature file")
    try:
        if file.suffix in (".npy", ".npz"):
            from spco.data.plain import _load_visual_file

            raw, _ = _load_visual_file(file)
            values = np.asarray(raw.toarray() if sp.issparse(raw) else raw, dtype=np.float64)
        else:
            text = file.read_text(encoding="utf-8-sig")
            tokens = text.replace(",", " ").split()
            values = np.array([float(t) for t in tokens], dtype=np.float64)
    except DataFormatError:
        raise
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise DataFormatError(file, f"not a readable feature vector ({exc})") from None
    if values.ndim == 2 and values.shape[0] == 1:
        values = values[0]
    if values.ndim != 1 or values.size == 0:
        raise DataFormatError(file, f"expected one feature vector, got shape {values.shape}")
    if n_features is not None and values.size != n_features:
        raise DataFormatError(file, f"has {values.size} values; the model's views have {n_features}")
    if not np.isfinite(values).all():
        raise DataFormatError(file, "holds NaN or infinite values")
    if scale is not None:
        return np.asarray(features_to_counts(values, scale), dtype=np.int64)
    if (values < 0).any() or (values != np.floor(values)).any():
        raise DataFormatError(file, "holds negative or non-integer values; visual counts must be whole "
                              "numbers >= 0 (for real-valued CNN features pass a visual scale, e.g. 5)")
    return values.astype(np.int64)
