"""Reading a robot's ROS bags for ``spco import-bag`` (:mod:`spco.data.rosbag`): open bags and
their topics (with `rosbags <https://gitlab.com/ternaris/rosbags>`_), message times, time series
matched nearest in time, the tf tree composed along its edges, and the robot's trajectory."""

from __future__ import annotations

import struct
from collections import Counter, defaultdict
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from spco.data import tf
from spco.errors import DataFormatError

POSE_TYPES = {  # message type -> how to reach its geometry_msgs/Pose
    "geometry_msgs/msg/PoseWithCovarianceStamped": lambda m: m.pose.pose,
    "geometry_msgs/msg/PoseStamped": lambda m: m.pose,
    "nav_msgs/msg/Odometry": lambda m: m.pose.pose,
}
TF_TYPES = ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage")
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
SPEECH_TYPES = ("std_msgs/msg/String",)
VISUAL_TYPES = tuple(
    f"std_msgs/msg/{k}MultiArray"
    for k in ("Float32", "Float64", "Int8", "Int16", "Int32", "Int64", "UInt8", "UInt16", "UInt32", "UInt64")
)
RAW_ENCODINGS = ("rgb8", "bgr8", "mono8")
_NS = 1_000_000_000
_HEADER_OFFSET_WARNING_S = 5.0
#: Seconds between the end of one tour and the start of the next on the import's time line (far
#: beyond any --tolerance or --every-seconds, so no sample takes a modality from another tour).
TOUR_GAP_SECONDS = 3600.0



# ------------------------------------------------------------------------------------ reading bags
class _Bag:
    """One open bag: its path, rosbags reader and topics (topic -> message type)."""

    def __init__(self, path: Path, stack: ExitStack) -> None:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        self.path = path
        if not path.exists():
            raise DataFormatError(
                path, "no such bag (a ROS 1 .bag file, or a ROS 2 bag folder, .db3 or .mcap)"
            )
        try:
            reader = AnyReader([path], default_typestore=get_typestore(Stores.LATEST))
            stack.enter_context(reader)
            self.topics = {name: info.msgtype or "" for name, info in reader.topics.items()}
            self.start = reader.start_time if reader.message_count else 0
            self.end = reader.end_time if reader.message_count else 0
        except Exception as exc:  # rosbags, sqlite and the OS raise many kinds; all mean "unreadable"
            raise _unreadable(path, exc) from None
        self.reader = reader
        self.is2 = reader.is2

    def connections(self, topic: str) -> list[Any]:
        return [c for c in self.reader.connections if c.topic == topic]

    def messages(self, topics: Sequence[str]) -> Iterator[tuple[Any, int, bytes]]:
        """(connection, bag time ns, raw bytes) of ``topics`` in record order; errors name the bag."""
        connections = [c for t in topics for c in self.connections(t)]
        if not connections:
            return
        stream = self.reader.messages(connections=connections)
        while True:
            try:
                item = next(stream)
            except StopIteration:
                return
            except Exception as exc:
                raise _unreadable(self.path, exc) from None
            yield item

    def deserialize(self, raw: bytes, connection: Any) -> Any:
        try:
            return self.reader.deserialize(raw, connection.msgtype)
        except Exception as exc:
            raise DataFormatError(
                self.path, f"{connection.topic}: cannot decode a {connection.msgtype} message ({exc})"
            ) from None


def _version() -> str:
    from spco import __version__

    return __version__


def _unreadable(path: Path, exc: Exception) -> DataFormatError:
    text = str(exc).strip() or type(exc).__name__
    return DataFormatError(
        path,
        f"cannot read the bag: {text}. If the recording was cut short, reindex it "
        "(ROS 1: `rosbag reindex`; ROS 2: `ros2 bag reindex`)",
    )


def _raw_stamp(raw: bytes, is2: bool) -> int:
    """Header stamp (ns) of a serialized message whose first field is a std_msgs/Header.

    ROS 1: ``uint32 seq, uint32 sec, uint32 nsec``; ROS 2 CDR: a 4-byte encapsulation header, then
    ``int32 sec, uint32 nanosec`` (byte order given by the encapsulation). 0 when too short.
    """
    if len(raw) < 12:
        return 0
    if not is2:
        sec, nsec = struct.unpack_from("<II", raw, 4)
    else:
        sec, nsec = struct.unpack_from("<iI" if raw[1] == 1 else ">iI", raw, 4)
    return int(sec) * _NS + int(nsec)


def _stamp(header: Any) -> int:
    return int(header.stamp.sec) * _NS + int(header.stamp.nanosec)


class _Series:
    """Times (ns) and values of one stream, in order; a time going backwards is dropped and counted."""

    def __init__(self, label: str, dropped: Counter[str]) -> None:
        self.label = label
        self.times: list[int] = []
        self.values: list[Any] = []
        self._dropped = dropped

    def add(self, t: int, value: Any) -> None:
        if self.times and t < self.times[-1]:
            self._dropped[f"{self.label}: time went backwards"] += 1
            return
        self.times.append(t)
        self.values.append(value)

    def array(self) -> np.ndarray:
        return np.asarray(self.times, dtype=np.int64)


def _nearest(times: np.ndarray, queries: np.ndarray, tolerance_ns: int) -> np.ndarray:
    """Index of the element of sorted ``times`` nearest to each query, -1 if none within tolerance."""
    if times.size == 0:
        return np.full(queries.shape, -1, dtype=np.int64)
    right = np.clip(np.searchsorted(times, queries), 0, times.size - 1)
    left = np.clip(right - 1, 0, times.size - 1)
    pick = np.where(np.abs(times[left] - queries) <= np.abs(times[right] - queries), left, right)
    return np.where(np.abs(times[pick] - queries) <= tolerance_ns, pick, -1)


# ------------------------------------------------------------------------------------ geometry
class _TfTree:
    """Transforms parent -> child from /tf (time series) and /tf_static, and chains between frames."""

    def __init__(self, dropped: Counter[str]) -> None:
        self.dynamic: dict[tuple[str, str], _Series] = {}
        self.static: dict[tuple[str, str], np.ndarray] = {}
        self._dropped = dropped

    def add(self, transform: Any, t: int | None, static: bool) -> None:
        parent, child = tf.frame_name(transform.header.frame_id), tf.frame_name(transform.child_frame_id)
        tr, rot = transform.transform.translation, transform.transform.rotation
        value = np.array([tr.x, tr.y, tr.z, rot.x, rot.y, rot.z, rot.w], dtype=np.float64)
        if not np.isfinite(value).all():
            self._dropped[f"/tf {parent}→{child}: not finite"] += 1
            return
        if static:
            self.static[(parent, child)] = value
        else:
            key = (parent, child)
            if key not in self.dynamic:
                self.dynamic[key] = _Series(f"/tf {parent}→{child}", self._dropped)
            self.dynamic[key].add(int(t or 0), value)

    def chain(self, source: str, target: str) -> list[tf.Step]:
        """Edges (parent, child) and whether each is walked forwards, from ``source`` to ``target``
        (:func:`spco.data.tf.path_between`); ``[]`` when the tree does not connect them."""
        parent_of = {child: parent for parent, child in [*self.dynamic, *self.static]}
        return tf.path_between(parent_of, source, target) or []

    def frames(self) -> list[str]:
        return sorted({f for edge in [*self.dynamic, *self.static] for f in edge})


@dataclass
class _Trajectory:
    """Robot poses over time: times (ns), x, y, yaw, and a lookup at other times."""

    times: np.ndarray
    xy: np.ndarray
    yaw: np.ndarray
    lookup: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]  # -> valid, xy, yaw


def _pose_trajectory(series: _Series, tolerance_ns: int) -> _Trajectory:
    times = series.array()
    values = np.asarray(series.values, dtype=np.float64).reshape(-1, 3)

    def lookup(queries: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        idx = _nearest(times, queries, tolerance_ns)
        safe = np.maximum(idx, 0)
        return idx >= 0, values[safe, :2], values[safe, 2]

    return _Trajectory(times, values[:, :2], values[:, 2], lookup)


def _tf_trajectory(tree: _TfTree, map_frame: str, robot_frame: str, tolerance_ns: int,
                   where: str) -> _Trajectory:
    """The robot's trajectory: the transform from ``map_frame`` to ``robot_frame`` along the tf tree."""
    source, target = tf.frame_name(map_frame), tf.frame_name(robot_frame)
    steps = tree.chain(source, target)
    if not steps:
        raise DataFormatError(
            where,
            f"/tf holds no chain of transforms from {source!r} to {target!r} (frames "
            f"seen: {', '.join(tree.frames()) or 'none'}); check --map-frame and --robot-frame",
        )
    dynamic = [edge for edge, _ in steps if edge in tree.dynamic]
    if not dynamic:
        raise DataFormatError(where, f"the transform {source}→{target} is static: the robot never moves")
    edge_times = {edge: tree.dynamic[edge].array() for edge in dynamic}
    edge_values = {edge: np.asarray(tree.dynamic[edge].values) for edge in dynamic}
    times = edge_times[max(dynamic, key=lambda e: edge_times[e].size)]

    def lookup(queries: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        valid = np.ones(queries.size, dtype=bool)

        def value_of(edge: tf.Edge) -> np.ndarray:  # each edge's transform nearest each query
            nonlocal valid
            if edge in tree.static:
                return tree.static[edge]
            idx = _nearest(edge_times[edge], queries, tolerance_ns)
            valid &= idx >= 0
            return edge_values[edge][np.maximum(idx, 0)]

        t, q = tf.compose_path(steps, value_of, queries.size)
        return valid, t[:, :2], tf.yaw(q)

    valid, xy, yaw = lookup(times)
    return _Trajectory(times[valid], xy[valid], yaw[valid], lookup)


def _periodic_indices(traj: _Trajectory, every_seconds: float, every_metres: float) -> np.ndarray:
    """Indices into the trajectory: its start, then each point ``every_seconds`` or ``every_metres``
    after the previous one, whichever comes first."""
    n = traj.times.size
    if n == 0 or (every_seconds <= 0 and every_metres <= 0):
        return np.zeros(0, dtype=np.int64)
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(traj.xy, axis=0).T))])
    chosen = [0]
    while True:  # one step per sample, each a binary search
        i = chosen[-1]
        nxt = n
        if every_metres > 0:
            nxt = min(nxt, int(np.searchsorted(travelled, travelled[i] + every_metres)))
        if every_seconds > 0:
            nxt = min(nxt, int(np.searchsorted(traj.times, traj.times[i] + round(every_seconds * _NS))))
        if nxt >= n:
            return np.asarray(chosen, dtype=np.int64)
        chosen.append(max(nxt, i + 1))


# ------------------------------------------------------------------------------------ what was read
@dataclass
class _Streams:
    """Everything read in the first pass."""

    pose: _Series
    tf: _TfTree
    speech: _Series
    images: _Series  # values: (bag index, ordinal among the topic's messages in that bag)
    visual: _Series
    header_offsets: dict[str, list[int]] = field(default_factory=lambda: defaultdict(list))
    tours: int = 1  # recordings whose clocks overlap (:func:`spco.data.rosbag._tours`)


@dataclass
class _Sample:
    time: int
    x: float
    y: float
    theta: float
    sentence: str | None
    image: int  # index into streams.images, -1 if none
    visual: int  # index into streams.visual, -1 if none
