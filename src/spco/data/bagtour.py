"""Write ROS bags of a robot touring a home, with `rosbags`' own writers (tests, benchmarks, examples).

:class:`BagWriter` writes poses, transforms, images, speech and feature vectors to a ROS 1 ``.bag``
or a ROS 2 bag (sqlite3 or mcap), serialised with rosbags' type stores, hiding the differences
between the two. :func:`write_tour` uses it to write a tour: the robot drives a loop through three
rooms (kitchen, living room, bedroom), its camera sees each room in the room's colours, and a
person names the room the robot is in now and then. ``python -m spco.data.bagtour OUT.bag`` writes
one (see ``--help``), to try ``spco import-bag`` without a robot.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

__all__ = ["ROOMS", "BagWriter", "write_tour"]

_NS = 1_000_000_000
#: The tour's rooms: name, x range (metres), colour (BGR).
ROOMS = (
    ("kitchen", (0.0, 4.0), (40, 160, 230)),
    ("living room", (4.0, 8.0), (60, 200, 80)),
    ("bedroom", (8.0, 12.0), (200, 90, 60)),
)


class BagWriter:
    """A ROS 1 (``ros=1``, a ``.bag`` file) or ROS 2 (``ros=2``, a folder; ``storage`` "sqlite3" or
    "mcap") bag being written. Times are nanoseconds; ``stamp`` (header) defaults to the record time."""

    def __init__(
        self, path: str | Path, ros: int = 1, storage: str = "sqlite3", compress: bool = False
    ) -> None:
        """``compress``: LZ4 chunks (ROS 1) or zstd messages (ROS 2), as recorders can write them."""
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        self.ros = ros
        if ros == 1:
            from rosbags.rosbag1 import Writer as Writer1

            self.store = get_typestore(Stores.ROS1_NOETIC)
            self.store.register(
                get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage")
            )
            self.writer: Any = Writer1(Path(path))
            if compress:
                self.writer.set_compression(Writer1.CompressionFormat.LZ4)
        else:
            from rosbags.rosbag2 import StoragePlugin
            from rosbags.rosbag2 import Writer as Writer2

            self.store = get_typestore(Stores.ROS2_HUMBLE)
            plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
            self.writer = Writer2(Path(path), version=9, storage_plugin=plugin)
            if compress:
                from rosbags.rosbag2 import CompressionFormat, CompressionMode

                self.writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
        self.types = self.store.types
        self._connections: dict[str, Any] = {}

    def __enter__(self) -> BagWriter:
        self.writer.open()
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.writer.close()

    # -------------------------------------------------------------------------- building blocks
    def register(self, definition: str, msgtype: str) -> None:
        """Add a message type (``.msg`` text) to the type store, e.g. a custom one."""
        from rosbags.typesys import get_types_from_msg

        self.store.register(get_types_from_msg(definition, msgtype))
        self.types = self.store.types

    def write(self, topic: str, msgtype: str, t: int, msg: Any) -> None:
        """Serialise ``msg`` and write it on ``topic`` at record time ``t`` (ns)."""
        if topic not in self._connections:
            self._connections[topic] = self.writer.add_connection(topic, msgtype, typestore=self.store)
        data = (
            self.store.serialize_ros1(msg, msgtype)
            if self.ros == 1
            else self.store.serialize_cdr(msg, msgtype)
        )
        self.writer.write(self._connections[topic], t, data)

    def header(self, stamp: int, frame: str = "") -> Any:
        time_msg = self.types["builtin_interfaces/msg/Time"](sec=stamp // _NS, nanosec=stamp % _NS)
        if self.ros == 1:
            return self.types["std_msgs/msg/Header"](seq=0, stamp=time_msg, frame_id=frame)
        return self.types["std_msgs/msg/Header"](stamp=time_msg, frame_id=frame)

    def _pose(self, x: float, y: float, yaw: float) -> Any:
        T = self.types
        return T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
            ),
        )

    # -------------------------------------------------------------------------- messages
    def pose(
        self,
        topic: str,
        t: int,
        x: float,
        y: float,
        yaw: float,
        kind: str = "PoseWithCovarianceStamped",
        frame: str = "map",
        stamp: int | None = None,
    ) -> None:
        """A pose as ``geometry_msgs/PoseWithCovarianceStamped``, ``PoseStamped`` or ``nav_msgs/Odometry``."""
        T, header, pose = self.types, self.header(t if stamp is None else stamp, frame), self._pose(x, y, yaw)
        covariance = np.zeros(36)
        if kind == "PoseStamped":
            msgtype, msg = (
                "geometry_msgs/msg/PoseStamped",
                T["geometry_msgs/msg/PoseStamped"](header=header, pose=pose),
            )
        elif kind == "PoseWithCovarianceStamped":
            msgtype = "geometry_msgs/msg/PoseWithCovarianceStamped"
            msg = T[msgtype](
                header=header,
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=covariance),
            )
        else:
            msgtype = "nav_msgs/msg/Odometry"
            zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
            msg = T[msgtype](
                header=header,
                child_frame_id="base_footprint",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=covariance),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=covariance
                ),
            )
        self.write(topic, msgtype, t, msg)

    def transforms(
        self,
        topic: str,
        t: int,
        edges: Sequence[tuple[str, str, float, float, float]],
        stamp: int | None = None,
    ) -> None:
        """A ``tf2_msgs/TFMessage`` of planar transforms (parent, child, x, y, yaw)."""
        T = self.types
        items = []
        for parent, child, x, y, yaw in edges:
            items.append(
                T["geometry_msgs/msg/TransformStamped"](
                    header=self.header(t if stamp is None else stamp, parent),
                    child_frame_id=child,
                    transform=T["geometry_msgs/msg/Transform"](
                        translation=T["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0),
                        rotation=T["geometry_msgs/msg/Quaternion"](
                            x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
                        ),
                    ),
                )
            )
        self.write(topic, "tf2_msgs/msg/TFMessage", t, T["tf2_msgs/msg/TFMessage"](transforms=items))

    def compressed_image(
        self,
        topic: str,
        t: int,
        bgr: np.ndarray,
        fmt: str = "jpeg",
        stamp: int | None = None,
        data: bytes | None = None,
    ) -> None:
        """A ``sensor_msgs/CompressedImage`` (JPEG or PNG of ``bgr``, or the given ``data``)."""
        import cv2

        if data is None:
            _ok, encoded = cv2.imencode(
                ".png" if fmt == "png" else ".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 80]
            )
            data = encoded.tobytes()
        msgtype = "sensor_msgs/msg/CompressedImage"
        self.write(
            topic,
            msgtype,
            t,
            self.types[msgtype](
                header=self.header(t if stamp is None else stamp, "camera"),
                format=fmt,
                data=np.frombuffer(data, dtype=np.uint8),
            ),
        )

    def raw_image(
        self, topic: str, t: int, pixels: np.ndarray, encoding: str = "rgb8", stamp: int | None = None
    ) -> None:
        """A ``sensor_msgs/Image`` holding ``pixels`` (H, W[, C] uint8) as they are, labelled ``encoding``."""
        pixels = np.ascontiguousarray(pixels, dtype=np.uint8)
        height, width = pixels.shape[:2]
        step = pixels.nbytes // height
        msgtype = "sensor_msgs/msg/Image"
        self.write(
            topic,
            msgtype,
            t,
            self.types[msgtype](
                header=self.header(t if stamp is None else stamp, "camera"),
                height=height,
                width=width,
                encoding=encoding,
                is_bigendian=0,
                step=step,
                data=pixels.reshape(-1),
            ),
        )

    def text(self, topic: str, t: int, text: str) -> None:
        """A ``std_msgs/String``."""
        self.write(topic, "std_msgs/msg/String", t, self.types["std_msgs/msg/String"](data=text))

    def features(self, topic: str, t: int, values: np.ndarray) -> None:
        """A ``std_msgs/Float32MultiArray``."""
        T = self.types
        layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
        self.write(
            topic,
            "std_msgs/msg/Float32MultiArray",
            t,
            T["std_msgs/msg/Float32MultiArray"](layout=layout, data=np.asarray(values, dtype=np.float32)),
        )


def room_at(x: float) -> int:
    """Index into :data:`ROOMS` of the room holding ``x``."""
    return min(max(int(x // 4.0), 0), len(ROOMS) - 1)


def view(x: float, y: float, yaw: float, size: tuple[int, int], rng: np.random.Generator,
         colours: Sequence[tuple[int, int, int]] | None = None) -> np.ndarray:
    """A camera image (H, W, 3 BGR uint8) of the room at (x, y): the room's colour, shapes, some noise.
    ``colours``: the rooms' colours (BGR) instead of those of :data:`ROOMS`."""
    import cv2

    width, height = size
    colour = np.array((colours or [room[2] for room in ROOMS])[room_at(x)], dtype=np.float64)
    image = np.empty((height, width, 3), dtype=np.uint8)
    image[:] = (colour * 0.6).astype(np.uint8)
    shift = int((yaw % (2 * math.pi)) / (2 * math.pi) * width)
    for k in range(6):
        cx = (shift + k * width // 6) % width
        cy = height // 3 + (k % 3) * height // 6
        shade = tuple(int(v) for v in np.clip(colour * (0.8 + 0.1 * k) + 20 * k, 0, 255))
        cv2.rectangle(image, (cx, cy), (cx + width // 10, cy + height // 5), shade, -1)
        cv2.circle(image, ((cx + width // 12) % width, height - height // 6), height // 12, shade[::-1], -1)
    noise = rng.normal(0, 6, (height // 8, width // 8, 3))
    image = np.clip(image + cv2.resize(noise, (width, height)), 0, 255).astype(np.uint8)
    return image


def write_tour(
    path: str | Path,
    ros: int = 1,
    storage: str = "sqlite3",
    seconds: float = 60.0,
    pose_hz: float = 10.0,
    image_hz: float = 2.0,
    size: tuple[int, int] = (640, 480),
    pose: str = "PoseWithCovarianceStamped",
    raw_images: bool = False,
    speech_every: float = 10.0,
    seed: int = 0,
) -> dict[str, Any]:
    """Write a tour bag; returns its topics and the counts of what it holds.

    The robot drives a loop through :data:`ROOMS` at 0.3 m/s (lap of 24 m) facing its direction of
    travel; poses on ``/global_pose`` (``pose``: a message kind, or ``"tf"`` for ``/tf`` map → odom →
    base_footprint), images on ``/camera/image/compressed`` (or ``/camera/image_raw``, rgb8, with
    ``raw_images``), and every ``speech_every`` seconds "this is the <room>" on ``/speech``.
    """
    rng = np.random.default_rng(seed)
    image_topic = "/camera/image_raw" if raw_images else "/camera/image/compressed"
    pose_topic = "/tf" if pose == "tf" else "/global_pose"
    events: list[tuple[int, int, str]] = []  # (time ns, order, kind)
    events += [(round(k * _NS / pose_hz), 0, "pose") for k in range(int(seconds * pose_hz))]
    events += [(round(k * _NS / image_hz) + 3_000_000, 1, "image") for k in range(int(seconds * image_hz))]
    if speech_every > 0:
        events += [
            (round((k + 0.5) * speech_every * _NS), 2, "speech") for k in range(int(seconds / speech_every))
        ]
    events.sort()
    start = 1_700_000_000 * _NS
    counts = {"pose": 0, "image": 0, "speech": 0}
    with BagWriter(path, ros=ros, storage=storage) as bag:
        for t, _, kind in events:
            s = t / _NS
            lap = (0.3 * s) % 24.0
            x, y, yaw = (lap, 1.0, 0.0) if lap < 12 else (24.0 - lap, 3.0, math.pi)
            when = start + t
            if kind == "pose" and pose == "tf":
                odom = (0.5, -0.2, 0.1)  # map -> odom; odom -> base_footprint makes up the rest
                dx, dy = x - odom[0], y - odom[1]
                c, si = math.cos(-odom[2]), math.sin(-odom[2])
                bag.transforms(
                    "/tf",
                    when,
                    [
                        ("map", "odom", *odom),
                        ("odom", "base_footprint", c * dx - si * dy, si * dx + c * dy, yaw - odom[2]),
                    ],
                )
            elif kind == "pose":
                bag.pose(pose_topic, when, x, y, yaw, kind=pose)
            elif kind == "image":
                image = view(x, y, yaw, size, rng)
                if raw_images:
                    bag.raw_image(image_topic, when, image[:, :, ::-1], "rgb8")
                else:
                    bag.compressed_image(image_topic, when, image)
            else:
                bag.text("/speech", when, f"this is the {ROOMS[room_at(x)][0]}")
            counts[kind] += 1
    return {"pose_topic": pose_topic, "image_topic": image_topic, "speech_topic": "/speech", **counts}


def main(argv: Sequence[str] | None = None) -> None:
    """``python -m spco.data.bagtour OUT``: write a tour bag."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", help="the bag to write (.bag for ROS 1, a folder for ROS 2)")
    parser.add_argument("--ros", type=int, choices=(1, 2), default=1)
    parser.add_argument("--storage", choices=("sqlite3", "mcap"), default="sqlite3")
    parser.add_argument("--seconds", type=float, default=160.0)
    parser.add_argument("--pose-hz", type=float, default=10.0)
    parser.add_argument("--image-hz", type=float, default=5.0)
    parser.add_argument(
        "--pose",
        default="PoseWithCovarianceStamped",
        choices=("PoseWithCovarianceStamped", "PoseStamped", "Odometry", "tf"),
    )
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    info = write_tour(
        args.out,
        ros=args.ros,
        storage=args.storage,
        seconds=args.seconds,
        pose_hz=args.pose_hz,
        image_hz=args.image_hz,
        pose=args.pose,
        seed=args.seed,
    )
    print(
        f"wrote {args.out}: {info['pose']} poses on {info['pose_topic']}, {info['image']} images on "
        f"{info['image_topic']}, {info['speech']} utterances on {info['speech_topic']}"
    )


if __name__ == "__main__":  # pragma: no cover
    main()
