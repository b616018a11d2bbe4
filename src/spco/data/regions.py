"""Ground-truth place regions: each place name is a union of axis-aligned rectangles (metres).

This is how the authors scored position prediction (``../shared/datasets/sigverse_regions.json``);
synthetic homes produce their own. A point on a rectangle's edge is inside (bounds inclusive).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spco.data.language import normalize_name
from spco.errors import DataFormatError

Rectangle = tuple[float, float, float, float]  # x_min, x_max, y_min, y_max


@dataclass(frozen=True)
class PlaceRegions:
    """The ground-truth area of every place of one home.

    ``places`` maps a normalised place name (``"emma's-room"``) to its rectangles
    ``(x_min, x_max, y_min, y_max)`` in metres.
    """

    places: Mapping[str, tuple[Rectangle, ...]]

    def __post_init__(self) -> None:
        clean: dict[str, tuple[Rectangle, ...]] = {}
        for name, rects in self.places.items():
            checked = []
            for rect in rects:
                x0, x1, y0, y1 = (float(v) for v in rect)
                if not (np.isfinite([x0, x1, y0, y1]).all() and x0 <= x1 and y0 <= y1):
                    raise DataFormatError(None, f"place {name!r}: invalid rectangle {rect!r} "
                                          "(expected x_min <= x_max, y_min <= y_max, finite)")
                checked.append((x0, x1, y0, y1))
            clean[normalize_name(name)] = tuple(checked)
        object.__setattr__(self, "places", clean)

    def contains(self, place: str, xy: np.ndarray) -> np.ndarray:
        """Whether each point of ``xy`` (shape ``(n, 2)``, metres) lies in ``place``.

        Returns a boolean array of shape ``(n,)``. Raises ``KeyError`` for an unknown place.
        """
        rects = np.asarray(self.places[normalize_name(place)], dtype=float).reshape(-1, 4)
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        x = xy[:, 0:1]
        y = xy[:, 1:2]
        inside = (x >= rects[:, 0]) & (x <= rects[:, 1]) & (y >= rects[:, 2]) & (y <= rects[:, 3])
        return inside.any(axis=1)

    def to_json(self) -> dict[str, list[list[float]]]:
        """A JSON-ready mapping place -> list of ``[x_min, x_max, y_min, y_max]``."""
        return {name: [list(r) for r in rects] for name, rects in self.places.items()}


def load_region_file(path: str | Path) -> dict[str, PlaceRegions]:
    """Read a region file in the format of ``sigverse_regions.json``.

    The file holds ``{"homes": {home: {place: [[x_min, x_max, y_min, y_max], ...]}}}``.
    Returns a mapping home name -> :class:`PlaceRegions`.
    """
    path = Path(path)
    if not path.is_file():
        raise DataFormatError(path, "region file not found")
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataFormatError(path, f"not a readable JSON file ({exc})") from None
    homes = raw.get("homes") if isinstance(raw, dict) else None
    if not isinstance(homes, dict):
        raise DataFormatError(path, 'expected an object with a "homes" mapping')
    out: dict[str, PlaceRegions] = {}
    for home, places in homes.items():
        if not isinstance(places, dict):
            raise DataFormatError(path, f"home {home!r}: expected a mapping place -> rectangles")
        try:
            out[home] = PlaceRegions({p: tuple(tuple(r) for r in rects) for p, rects in places.items()})
        except DataFormatError as exc:
            raise DataFormatError(path, f"home {home!r}: {exc.problem}") from None
        except (TypeError, ValueError) as exc:
            raise DataFormatError(path, f"home {home!r}: rectangles must be lists of 4 numbers "
                                  f"({exc})") from None
    return out
