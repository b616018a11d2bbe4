"""A ROS occupancy map as map_server and Nav2's map_saver write it: ``map.yaml`` beside an image.

``map.yaml`` names the ``image`` (PGM, PNG; a path relative to the YAML file), its ``resolution``
(metres per pixel) and the ``origin`` ``[x, y, yaw]`` of its lower-left pixel on the map (metres,
radians), with ``negate`` (0/1) and the thresholds ``occupied_thresh`` / ``free_thresh``, which
spco does not need to draw it. The image's top row is the map's largest y. :func:`read_ros_map`
returns the image as grey levels with the map's extent in metres, ready for
``imshow(extent=…)``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from spco.errors import DataFormatError
from spco.features.pixels import decode_grey

__all__ = ["MAP_YAML_SUFFIXES", "RosMap", "read_ros_map"]

#: File name endings read as a ROS map description.
MAP_YAML_SUFFIXES = (".yaml", ".yml")


@dataclass(frozen=True)
class RosMap:
    """A ROS map: ``image`` (H, W) uint8 grey levels as drawn (free space light, walls dark; ``negate``
    applied), ``resolution`` (m/pixel), ``origin`` (x, y, yaw) and ``extent`` (x_min, x_max, y_min,
    y_max) in metres; ``path`` the YAML file."""

    image: np.ndarray
    resolution: float
    origin: tuple[float, float, float]
    extent: tuple[float, float, float, float]
    path: Path


def _number(path: Path, meta: dict[str, Any], key: str) -> float:
    value = meta.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise DataFormatError(path, f"{key!r} must be a number, got {value!r}")
    return float(value)


def read_ros_map(path: str | os.PathLike[str]) -> RosMap:
    """Read ``map.yaml`` and its image.

    Raises :class:`~spco.errors.DataFormatError` naming the file and the field for a missing or
    unreadable file, a missing ``image``, ``resolution`` or ``origin``, a resolution ≤ 0, or a
    rotated map (``origin`` yaw ≠ 0, which spco does not draw).
    """
    import yaml

    file = Path(path).expanduser()
    if not file.is_file():
        raise DataFormatError(file, "no such map file")
    try:
        meta = yaml.safe_load(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise DataFormatError(file, f"not a readable map.yaml ({str(exc).splitlines()[0]})") from None
    if not isinstance(meta, dict):
        raise DataFormatError(file, "not a map.yaml: expected image, resolution and origin")
    for key in ("image", "resolution", "origin"):
        if key not in meta:
            raise DataFormatError(file, f"no {key!r} (a ROS map.yaml names image, resolution and origin)")
    resolution = _number(file, meta, "resolution")
    if resolution <= 0:
        raise DataFormatError(file, f"'resolution' must be > 0 metres per pixel, got {resolution}")
    origin = meta["origin"]
    if not isinstance(origin, list) or len(origin) not in (2, 3):
        raise DataFormatError(file, f"'origin' must be [x, y, yaw], got {origin!r}")
    x0, y0, yaw = (_number(file, {"origin": v}, "origin") for v in [*origin, 0.0][:3])
    if abs(yaw) > 1e-9:
        raise DataFormatError(file, f"the map is rotated (origin yaw {yaw:g} rad); spco draws maps whose "
                              "origin yaw is 0")
    image_file = Path(str(meta["image"])).expanduser()
    if not image_file.is_absolute():
        image_file = file.parent / image_file
    if not image_file.is_file():
        raise DataFormatError(file, f"its image {image_file} does not exist")
    image = decode_grey(np.fromfile(image_file, dtype=np.uint8), image_file)
    if meta.get("negate") in (1, True):
        image = 255 - image
    height, width = image.shape
    extent = (x0, x0 + width * resolution, y0, y0 + height * resolution)
    return RosMap(image=image, resolution=resolution, origin=(x0, y0, yaw), extent=extent, path=file)
