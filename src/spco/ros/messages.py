"""ROS messages as plain dicts, both ways: what the node reads (poses, tf, camera frames) and what it
publishes (markers, goals).

Every function here works on the JSON form of a message — nested dicts and lists, as rosbridge
sends them and as :func:`spco.ros.node.message_to_dict` makes of a rospy message — so the ROS 1
node and the rosbridge client share it, and it needs no ROS installation. Both dialects of a time
are read: ROS 1's ``{"secs", "nsecs"}`` and ROS 2's ``{"sec", "nanosec"}``; byte arrays (image
data) may be ``bytes``, a list of ints, or base64 text (rosbridge's form).
"""

from __future__ import annotations

import base64
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from spco.data import tf
from spco.errors import DataFormatError
from spco.features.pixels import (
    DEFAULT_MAX_PIXELS,
    check_encoding,
    decode_compressed,
    pixels_from_buffer,
    to_bgr,
)

__all__ = [
    "CHI2_95_2D",
    "MARKER_NAMESPACES",
    "CameraFrame",
    "PoseReading",
    "TfBuffer",
    "concept_colour",
    "ellipse_axes",
    "frame_from_message",
    "goal_message",
    "marker_array",
    "places_text",
    "pose_array_message",
    "pose_from_message",
    "quaternion_from_yaw",
    "stamp_seconds",
    "time_message",
    "yaw_from_quaternion",
]

#: χ²(2) quantile of 0.95: a 2-D Gaussian's 95 % ellipse has semi-axes sqrt(5.991 λ).
CHI2_95_2D = 5.991464547107979
#: Marker namespaces, one per kind of marker, so RViz can show or hide each kind.
MARKER_NAMESPACES = {"outline": "spco/regions", "fill": "spco/fill", "names": "spco/names"}
# visualization_msgs/Marker constants
_CYLINDER, _LINE_STRIP, _TEXT_VIEW_FACING = 3, 4, 9
_ADD, _DELETEALL = 0, 3
_ELLIPSE_POINTS = 48


# ------------------------------------------------------------------------------------- time
def stamp_seconds(header: Mapping[str, Any] | None) -> float | None:
    """Seconds of a header's stamp (ROS 1 ``secs/nsecs`` or ROS 2 ``sec/nanosec``); ``None`` for a zero
    or missing stamp."""
    if not isinstance(header, Mapping):
        return None
    stamp = header.get("stamp")
    if not isinstance(stamp, Mapping):
        return None
    secs = stamp.get("secs", stamp.get("sec", 0)) or 0
    nsecs = stamp.get("nsecs", stamp.get("nanosec", 0)) or 0
    value = float(secs) + float(nsecs) * 1e-9
    return value if value > 0 else None


def time_message(seconds: float, ros_version: int = 1) -> dict[str, int]:
    """A time as a message: ``{"secs", "nsecs"}`` (ROS 1) or ``{"sec", "nanosec"}`` (ROS 2)."""
    whole = math.floor(seconds)
    fraction = round((seconds - whole) * 1e9)
    if fraction >= 1_000_000_000:
        whole, fraction = whole + 1, fraction - 1_000_000_000
    return {"secs": int(whole), "nsecs": fraction} if ros_version == 1 else {"sec": int(whole),
                                                                               "nanosec": fraction}


# ------------------------------------------------------------------------------------- poses
def yaw_from_quaternion(q: Mapping[str, Any]) -> float:
    """Heading (radians, about z) of a quaternion ``{"x", "y", "z", "w"}``."""
    x, y, z, w = (float(q.get(k, 0.0)) for k in ("x", "y", "z", "w"))
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_from_yaw(theta: float) -> dict[str, float]:
    """The quaternion of a rotation by ``theta`` radians about z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(theta / 2.0), "w": math.cos(theta / 2.0)}


@dataclass(frozen=True)
class PoseReading:
    """The robot's pose on the map at one time: metres and radians; ``stamp`` in seconds (``None`` when
    the message had no stamp); ``frame`` the frame it is given in."""

    x: float
    y: float
    theta: float
    frame: str
    stamp: float | None


def pose_from_message(msg: Mapping[str, Any]) -> PoseReading:
    """The pose in a ``geometry_msgs/PoseStamped``, ``PoseWithCovarianceStamped`` or ``nav_msgs/Odometry``.

    Raises :class:`~spco.errors.DataFormatError` for a message of another shape or with non-finite
    values.
    """
    if not isinstance(msg, Mapping) or not isinstance(msg.get("pose"), Mapping):
        raise DataFormatError(None, "not a pose message (PoseStamped, PoseWithCovarianceStamped or "
                              "Odometry): it has no 'pose' field")
    pose = msg["pose"]
    if isinstance(pose.get("pose"), Mapping):  # PoseWithCovariance (also inside Odometry)
        pose = pose["pose"]
    position, orientation = pose.get("position"), pose.get("orientation")
    if not isinstance(position, Mapping) or not isinstance(orientation, Mapping):
        raise DataFormatError(None, "a pose message needs pose.position and pose.orientation")
    x, y = float(position.get("x", 0.0)), float(position.get("y", 0.0))
    theta = yaw_from_quaternion(orientation)
    if not all(math.isfinite(v) for v in (x, y, theta)):
        raise DataFormatError(None, f"a pose message holds non-finite values (x={x}, y={y}, θ={theta})")
    header = msg.get("header") if isinstance(msg.get("header"), Mapping) else {}
    return PoseReading(x, y, theta, tf.frame_name(header.get("frame_id")), stamp_seconds(header))


class TfBuffer:
    """The latest transform of every tf edge (``tf2_msgs/TFMessage`` on ``/tf`` and ``/tf_static``), and the
    robot's pose on the map composed along the tree (e.g. map → odom → base_footprint).

    Only the latest transform of each edge is kept: a live node wants the robot's pose now, and the
    node keeps its own history of the composed poses (:class:`spco.ros.core.NodeCore`).
    """

    def __init__(self) -> None:
        self._edges: dict[str, tuple[str, np.ndarray, float | None, bool]] = {}  # child -> parent, T, stamp

    def add(self, msg: Mapping[str, Any], static: bool = False) -> None:
        """Take in a ``TFMessage`` (its ``transforms``); non-finite transforms and zero rotations are
        ignored."""
        for transform in msg.get("transforms") or ():
            header = transform.get("header") or {}
            parent = tf.frame_name(header.get("frame_id"))
            child = tf.frame_name(transform.get("child_frame_id"))
            t, r = (transform.get("transform") or {}).get("translation"), \
                (transform.get("transform") or {}).get("rotation")
            if not parent or not child or not isinstance(t, Mapping) or not isinstance(r, Mapping):
                continue
            value = np.array([float(t.get(k, 0.0)) for k in "xyz"] + [float(r.get(k, 0.0)) for k in "xyzw"])
            if np.isfinite(value).all() and value[3:].any():
                self._edges[child] = (parent, value, stamp_seconds(header), static)

    def frames(self) -> list[str]:
        """Every frame named by a transform so far."""
        return sorted({f for child, (parent, *_) in self._edges.items() for f in (child, parent)})

    def lookup(self, map_frame: str, robot_frame: str) -> PoseReading | None:
        """The pose of ``robot_frame`` in ``map_frame`` from the latest transforms, or ``None`` while the
        tree does not connect them. Its stamp is the oldest of the dynamic transforms used."""
        source, target = tf.frame_name(map_frame), tf.frame_name(robot_frame)
        parent_of = {child: parent for child, (parent, *_) in self._edges.items()}
        steps = tf.path_between(parent_of, source, target)
        if steps is None:
            return None
        stamps: list[float] = []

        def value_of(edge: tf.Edge) -> np.ndarray:
            _, value, stamp, static = self._edges[edge[1]]
            if not static and stamp is not None:
                stamps.append(stamp)
            return value

        t, q = tf.compose_path(steps, value_of)
        theta = float(tf.yaw(q[0]))
        return PoseReading(float(t[0, 0]), float(t[0, 1]), theta, source, min(stamps) if stamps else None)


# ------------------------------------------------------------------------------------- images
def _bytes_of(data: Any) -> bytes | np.ndarray:
    """An image message's ``data``: bytes as they are, base64 text decoded, a list as uint8."""
    if isinstance(data, bytes | bytearray | memoryview):
        return bytes(data)
    if isinstance(data, str):
        try:
            return base64.b64decode(data, validate=True)
        except ValueError:
            raise DataFormatError(None, "image data is text but not base64") from None
    return np.asarray(data, dtype=np.uint8)


@dataclass(frozen=True)
class CameraFrame:
    """One camera frame as received: decoded only when used (:meth:`pixels`).

    ``stamp`` in seconds (``None`` without one); ``encoding`` the raw image's encoding (``rgb8``,
    ``bgr8``, ``mono8``, ``rgba8``, ``bgra8``) or ``jpeg`` / ``png`` for a compressed one.
    """

    stamp: float | None
    encoding: str
    data: Any
    height: int = 0
    width: int = 0
    step: int = 0

    def pixels(self, max_pixels: int | None = DEFAULT_MAX_PIXELS) -> tuple[np.ndarray, str]:
        """``(pixel array, its encoding)`` with the encoding one of ``rgb8``, ``bgr8`` (H, W, 3) or
        ``mono8`` (H, W): a raw rgb8, bgr8 or mono8 frame's pixels as they are, in their own channel
        order; a frame with alpha and a compressed one converted to (decoded into) ``bgr8``. A
        compressed frame of more than ``max_pixels`` pixels is refused from its header before it is
        decoded (:class:`~spco.features.pixels.ImageTooLargeError`). Raises
        :class:`~spco.errors.DataFormatError` for data that do not make an image."""
        raw = _bytes_of(self.data)
        if self.encoding in ("jpeg", "png"):
            return decode_compressed(raw, self.encoding, max_pixels=max_pixels), "bgr8"
        pixels = pixels_from_buffer(raw, self.height, self.width, self.step, self.encoding)
        if self.encoding in ("rgba8", "bgra8"):
            return to_bgr(pixels, self.encoding), "bgr8"
        return pixels, self.encoding


def frame_from_message(msg: Mapping[str, Any]) -> CameraFrame:
    """The frame in a ``sensor_msgs/Image`` (``encoding`` rgb8, bgr8, mono8, rgba8, bgra8) or
    ``sensor_msgs/CompressedImage`` (``format`` with jpeg or png). Raises
    :class:`~spco.errors.DataFormatError` for another encoding (depth, Bayer, 16-bit) or shape."""
    if not isinstance(msg, Mapping) or "data" not in msg:
        raise DataFormatError(None, "not an image message (Image or CompressedImage): it has no 'data' field")
    stamp = stamp_seconds(msg.get("header"))
    if "format" in msg and "encoding" not in msg:
        encoding = check_encoding(str(msg.get("format") or ""))
        if encoding not in ("jpeg", "png"):
            raise DataFormatError(None, f"compressed image format {msg.get('format')!r} is not supported "
                                  "(JPEG or PNG)")
        return CameraFrame(stamp, encoding, msg["data"])
    encoding = check_encoding(str(msg.get("encoding") or ""), compressed_ok=False)
    assert encoding is not None
    return CameraFrame(stamp, encoding, msg["data"], int(msg.get("height", 0)), int(msg.get("width", 0)),
                       int(msg.get("step", 0)))


# ------------------------------------------------------------------------------------- output
def goal_message(x: float, y: float, theta: float, frame: str = "map", stamp: float | None = None,
                 ros_version: int = 1) -> dict[str, Any]:
    """A ``geometry_msgs/PoseStamped`` goal at ``(x, y, θ)`` in ``frame``.

    With ``stamp`` ``None`` (what both nodes send) the header has no stamp, i.e. time 0: move_base
    and Nav2 transform a goal with stamp 0 with the latest transform they have (tf's "latest"),
    where a goal stamped "now" could wait for, or fail on, a transform not yet received."""
    header: dict[str, Any] = {"frame_id": frame}
    if stamp is not None:
        header["stamp"] = time_message(stamp, ros_version)
    return {"header": header, "pose": {"position": {"x": float(x), "y": float(y), "z": 0.0},
                                       "orientation": quaternion_from_yaw(float(theta))}}


def pose_array_message(positions: Sequence[Mapping[str, Any]], frame: str = "map") -> dict[str, Any]:
    """A ``geometry_msgs/PoseArray`` of a ``where`` answer's positions (``{"x", "y", "theta"}``, most
    probable first), in ``frame``, stamp 0 (as the goal)."""
    return {"header": {"frame_id": frame},
            "poses": [{"position": {"x": float(p["x"]), "y": float(p["y"]), "z": 0.0},
                       "orientation": quaternion_from_yaw(float(p["theta"]))} for p in positions]}


def concept_colour(concept: int, n_concepts: int) -> tuple[float, float, float]:
    """The colour of a concept, as ``spco show`` draws it: matplotlib's tab10 for up to 10 concepts,
    else tab20 with its dark shades first. Returns (r, g, b) in [0, 1]."""
    import matplotlib

    if n_concepts <= 10:
        return tuple(float(v) for v in matplotlib.colormaps["tab10"](concept % 10)[:3])  # type: ignore[return-value]
    order = [*range(0, 20, 2), *range(1, 20, 2)]
    return tuple(float(v) for v in matplotlib.colormaps["tab20"](order[concept % 20])[:3])  # type: ignore[return-value]


def ellipse_axes(covariance: Sequence[Sequence[float]] | np.ndarray) -> tuple[float, float, float]:
    """Semi-axes (major, minor, metres) and the major axis' angle (radians) of the 95 % ellipse of a
    2-D Gaussian with ``covariance`` (2 × 2; a larger one's x–y block is used)."""
    cov = np.asarray(covariance, dtype=float)[:2, :2]
    cov = 0.5 * (cov + cov.T)
    values, vectors = np.linalg.eigh(cov)
    values = np.maximum(values, 0.0)
    major, minor = math.sqrt(CHI2_95_2D * values[1]), math.sqrt(CHI2_95_2D * values[0])
    return major, minor, math.atan2(vectors[1, 1], vectors[0, 1])


def places_text(region: Mapping[str, Any], top: int = 3) -> str:
    """A region's label on a map: the places ``where`` goes to this region for (``region["places"]``,
    :func:`spco.service.answers.regions_answer`), at most ``top``, one a line, each with p(region |
    name); ``""`` where ``where`` finds no place."""
    return "\n".join(f"{n['name']} {float(n['p']):.2f}" for n in list(region.get("places") or ())[:top])


def marker_array(regions: Sequence[Mapping[str, Any]], n_concepts: int, frame: str = "map",
                 top_names: int = 3, z: float = 0.0) -> dict[str, Any]:
    """A ``visualization_msgs/MarkerArray`` of learnt regions: for each region an ellipse outline
    (``LINE_STRIP``, namespace ``spco/regions``), a translucent filled ellipse (a flat ``CYLINDER``,
    ``spco/fill``) and, for a region where ``where`` finds places, their names with p(region | name)
    (``TEXT_VIEW_FACING``, ``spco/names``, :func:`places_text`: the label is ``where``'s answer),
    coloured by the region's concept as ``spco show`` colours it. The first marker deletes every
    earlier marker (``DELETEALL``), so regions that are gone disappear.

    Parameters
    ----------
    regions: one mapping per region: ``region`` (its index: the markers' id), ``mean`` (x, y, …
        metres), ``covariance`` (2 × 2 or larger, metres²), ``concept`` (int) and ``places``
        (``[{"name", "p"}]``, the places ``where`` finds there, most probable first).
    n_concepts: the number of concepts (chooses the palette).
    frame: the map frame. top_names: at most ``top_names`` places are written. z: height of the
        ellipses (metres).

    Returns
    -------
    The message as a dict (``{"markers": [...]}``).
    """
    header = {"frame_id": frame}
    markers: list[dict[str, Any]] = [{"header": header, "ns": MARKER_NAMESPACES["outline"], "id": 0,
                                      "action": _DELETEALL}]
    for region in regions:
        index = int(region["region"])
        mx, my = (float(v) for v in list(region["mean"])[:2])
        major, minor, angle = ellipse_axes(region["covariance"])
        r, g, b = concept_colour(int(region["concept"]), n_concepts)
        c, s = math.cos(angle), math.sin(angle)
        points = []
        for k in range(_ELLIPSE_POINTS + 1):
            a = 2.0 * math.pi * k / _ELLIPSE_POINTS
            ex, ey = major * math.cos(a), minor * math.sin(a)
            points.append({"x": mx + c * ex - s * ey, "y": my + s * ex + c * ey, "z": z})
        identity = {"position": {"x": 0.0, "y": 0.0, "z": 0.0}, "orientation": quaternion_from_yaw(0.0)}
        markers.append({"header": header, "ns": MARKER_NAMESPACES["outline"], "id": index,
                        "type": _LINE_STRIP, "action": _ADD, "pose": identity,
                        "scale": {"x": 0.04, "y": 0.0, "z": 0.0},
                        "color": {"r": r, "g": g, "b": b, "a": 1.0}, "points": points})
        markers.append({"header": header, "ns": MARKER_NAMESPACES["fill"], "id": index,
                        "type": _CYLINDER, "action": _ADD,
                        "pose": {"position": {"x": mx, "y": my, "z": z},
                                 "orientation": quaternion_from_yaw(angle)},
                        "scale": {"x": max(2.0 * major, 1e-3), "y": max(2.0 * minor, 1e-3), "z": 0.01},
                        "color": {"r": r, "g": g, "b": b, "a": 0.25}})
        label = places_text(region, top_names)
        if not label:
            continue
        markers.append({"header": header, "ns": MARKER_NAMESPACES["names"], "id": index,
                        "type": _TEXT_VIEW_FACING, "action": _ADD,
                        "pose": {"position": {"x": mx, "y": my, "z": z + 0.3},
                                 "orientation": quaternion_from_yaw(0.0)},
                        "scale": {"x": 0.0, "y": 0.0, "z": 0.25},
                        "color": {"r": r, "g": g, "b": b, "a": 1.0}, "text": label})
    return {"markers": markers}
