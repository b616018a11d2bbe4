"""Floor plans of synthetic homes (:mod:`spco.data.synthetic`): a rectangle cut into rooms of
target areas (:func:`_plan`), which rooms touch (:func:`_adjacent`), and a home's plan read back
from its ground truth (:func:`floor_plan`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from spco.data.environment import Environment, Extent
from spco.data.regions import Rectangle
from spco.data.synthetic_config import _GRID, _MAX_ASPECT, _MIN_ROOM_SIDE, _PLAN_ATTEMPTS, SyntheticConfig


# ----------------------------------------------------------------------------------- floor plans
def _split(rng: np.random.Generator, rect: Rectangle, areas: np.ndarray, rooms: np.ndarray,
           out: dict[int, Rectangle]) -> None:
    """Guillotine-split ``rect`` among ``rooms`` (indices into ``areas``), filling ``out``."""
    if rooms.size == 1:
        out[int(rooms[0])] = rect
        return
    order = rng.permutation(rooms)
    cum = np.cumsum(areas[order])
    cut = int(np.argmin(np.abs(cum[:-1] - cum[-1] / 2))) + 1
    first, second = order[:cut], order[cut:]
    frac = cum[cut - 1] / cum[-1]
    x0, x1, y0, y1 = rect
    if rng.random() < 0.5:  # which part goes left/bottom
        first, second, frac = second, first, 1.0 - frac
    if x1 - x0 >= y1 - y0:
        xc = round(float(np.clip(round((x0 + frac * (x1 - x0)) / _GRID) * _GRID, x0, x1)), 6)
        _split(rng, (x0, xc, y0, y1), areas, first, out)
        _split(rng, (xc, x1, y0, y1), areas, second, out)
    else:
        yc = round(float(np.clip(round((y0 + frac * (y1 - y0)) / _GRID) * _GRID, y0, y1)), 6)
        _split(rng, (x0, x1, y0, yc), areas, first, out)
        _split(rng, (x0, x1, yc, y1), areas, second, out)


def _badness(rects: Sequence[Rectangle]) -> float:
    r = np.asarray(rects, dtype=float)
    w, h = r[:, 1] - r[:, 0], r[:, 3] - r[:, 2]
    short, long_ = np.minimum(w, h), np.maximum(w, h)
    aspect = long_ / np.maximum(short, 1e-9)
    return float(np.maximum(aspect / _MAX_ASPECT, _MIN_ROOM_SIDE / np.maximum(short, 1e-9)).max())


def _plan(rng: np.random.Generator, room_types: Sequence[str],
          config: SyntheticConfig) -> tuple[list[Rectangle], Extent]:
    """Room rectangles (in the order of ``room_types``) tiling a house rectangle, and that extent."""
    areas = np.array([config.area_of(t) for t in room_types]) * rng.lognormal(0.0, 0.2, len(room_types))
    total = float(areas.sum())
    best: tuple[float, list[Rectangle], Extent] | None = None
    for _ in range(_PLAN_ATTEMPTS):
        aspect = rng.uniform(1.0, 1.6)
        if rng.random() < 0.5:
            aspect = 1.0 / aspect
        half_width = round(round(float(np.sqrt(total * aspect)) / (2 * _GRID)) * _GRID, 6)
        half_height = round(round(total / (4 * half_width) / _GRID) * _GRID, 6)
        extent: Extent = (-half_width, half_width, -half_height, half_height)
        out: dict[int, Rectangle] = {}
        _split(rng, extent, areas, np.arange(len(room_types)), out)
        rects = [out[i] for i in range(len(room_types))]
        score = _badness(rects)
        if best is None or score < best[0]:
            best = (score, rects, extent)
        if score <= 1.0:
            break
    assert best is not None
    return best[1], best[2]


def _adjacent(rects: Sequence[Rectangle], min_overlap: float = 0.5) -> list[list[int]]:
    """For each room, the rooms sharing a wall of at least ``min_overlap`` metres with it."""
    eps = 1e-6
    out: list[list[int]] = [[] for _ in rects]
    for i, a in enumerate(rects):
        for j, b in enumerate(rects):
            if i == j:
                continue
            touch_x = abs(a[1] - b[0]) < eps or abs(b[1] - a[0]) < eps
            touch_y = abs(a[3] - b[2]) < eps or abs(b[3] - a[2]) < eps
            over_y = min(a[3], b[3]) - max(a[2], b[2])
            over_x = min(a[1], b[1]) - max(a[0], b[0])
            if (touch_x and over_y >= min_overlap) or (touch_y and over_x >= min_overlap):
                out[i].append(j)
    return out


def floor_plan(environment: Environment) -> tuple[Extent | None, dict[str, tuple[Rectangle, ...]]]:
    """The map extent and the rectangles of every place (general and home-specific) of a home.

    For a synthetic home the rectangles tile the extent; for a loaded home they are whatever its
    ground-truth regions hold (empty if none).
    """
    gt = environment.ground_truth
    regions = {} if gt is None or gt.regions is None else dict(gt.regions.places)
    return environment.extent, regions
