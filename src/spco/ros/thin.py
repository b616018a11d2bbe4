"""The ROS 2 side of ``spco ros2``: parameters, topics, QoS and messages with rclpy — and nothing of
spco, so that it runs with the robot's own Python (Humble's 3.10, Jazzy's 3.12) whatever Python spco
runs on.

It needs only the standard library and rclpy (with the message packages of any ROS 2 installation),
and is used two ways:

- **in process** (:func:`spco.ros.ros2.run_ros2` without ``--ros-python``): spco imports
  :class:`Ros2Transport` and connects it to the node's core directly;
- **as the robot's process** (``spco ros2 HOME --ros-python /usr/bin/python3``): spco starts this
  file as a script with the robot's Python (``python3 thin.py --ros-args …``) and relays over the
  child's stdin and stdout (:func:`relay_main`): the child sends what the robot publishes (poses,
  frames, utterances, queries) and parameter changes, spco sends back what to publish (answers,
  markers, where poses, goals) and whether a parameter change is accepted. Frames are length-prefixed
  JSON with binary payloads (camera data are never base64'd).

The node's parameters (:data:`PARAMETERS`) are declared with descriptions and ranges; the topic
parameters are read-only. Its own topics are private (``~/query`` is ``/spco/query`` for a node
named ``spco``), the goal is ``goal_pose``; every name can be remapped with ``--ros-args -r``.
"""

from __future__ import annotations

import array
import importlib
import json
import logging
import os
import queue
import signal
import struct
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, BinaryIO, Protocol

__all__ = ["IMAGE_TYPES", "PARAMETERS", "POSE_TYPES", "Backend", "Parameter2", "ParameterError",
           "Ros2Transport", "fill_message", "message_to_dict", "read_frame", "relay_main", "write_frame"]

log = logging.getLogger("spco.ros")

#: Accepted types of the pose and camera topics (ROS 2 names).
POSE_TYPES = ("geometry_msgs/msg/PoseWithCovarianceStamped", "geometry_msgs/msg/PoseStamped",
              "nav_msgs/msg/Odometry")
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")


@dataclass(frozen=True)
class Parameter2:
    """A parameter of the node: its default, description, whether it is read-only, and its range."""

    default: Any
    description: str
    read_only: bool = False
    low: float | None = None
    high: float | None = None


#: The node's parameters (``ros2 param describe /spco NAME`` shows the description).
PARAMETERS: dict[str, Parameter2] = {
    "pose_topic": Parameter2("/tf", "The robot's pose on the map: a PoseWithCovarianceStamped (AMCL's "
                             "/amcl_pose), PoseStamped or Odometry topic, or /tf (map_frame -> robot_frame "
                             "from /tf and /tf_static)", read_only=True),
    "pose_type": Parameter2("auto", "The pose topic's type: auto (as its publisher announces it), "
                            "PoseWithCovarianceStamped, PoseStamped or Odometry", read_only=True),
    "image_topic": Parameter2("", "The camera: sensor_msgs/Image (rgb8, bgr8, mono8, rgba8, bgra8) or "
                              "CompressedImage (JPEG, PNG); empty: no camera", read_only=True),
    "image_type": Parameter2("auto", "The camera topic's type: auto, Image or CompressedImage",
                             read_only=True),
    "speech_topic": Parameter2("", "What people say (std_msgs/String): each utterance is taught at the pose "
                               "and camera frame nearest to it; empty: the node only answers queries",
                               read_only=True),
    "map_frame": Parameter2("map", "The map's frame: poses in another frame are refused; the frame of the "
                            "goal, the where poses and the markers"),
    "robot_frame": Parameter2("base_footprint", "The robot's frame (pose_topic /tf)"),
    "tolerance": Parameter2(0.5, "Seconds an utterance's pose and camera frame may be from it", low=0.001,
                            high=30.0),
    "image_wait": Parameter2(-1.0, "Seconds to wait after an utterance for a camera frame (negative: the "
                             "tolerance)", low=-1.0, high=30.0),
    "clock": Parameter2("receive", "Times of messages: receive (when they arrive; any clocks) or header "
                        "(their header stamps; clocks kept in step)"),
    "max_age": Parameter2(2.0, "Seconds after which the last pose and frame are no longer the robot's "
                          "current ones (what queries)", low=0.001, high=3600.0),
    "goal": Parameter2(False, "Publish the best pose of every where answer on goal_pose (else only when the "
                       "query says \"goal\": true)"),
    "n": Parameter2(10, "Poses a where answer gives when the query does not say", low=1, high=1000),
    "top": Parameter2(3, "Names a what answer gives when the query does not say", low=1, high=100),
}

_TYPE_ALIASES = {"posewithcovariancestamped": POSE_TYPES[0], "posestamped": POSE_TYPES[1],
                 "odometry": POSE_TYPES[2], "image": IMAGE_TYPES[0], "compressedimage": IMAGE_TYPES[1]}


class ParameterError(ValueError):
    """A parameter value the node cannot take."""


def full_type(value: str, accepted: tuple[str, ...], parameter: str) -> str | None:
    """``None`` for auto, else the full ROS 2 type name of ``value`` (short or full)."""
    text = value.strip()
    if text.lower() in ("", "auto"):
        return None
    full = _TYPE_ALIASES.get(text.lower(), text if text in accepted else "")
    if full not in accepted:
        names = ", ".join(t.rsplit("/", 1)[-1] for t in accepted)
        raise ParameterError(f"parameter {parameter}: {value!r} is not a type the node reads (auto, {names})")
    return full


def _message_class(type_name: str) -> Any:
    """The Python class of a ROS 2 type, ``pkg/msg/Name`` or ``pkg/Name``."""
    parts = type_name.split("/")
    return getattr(importlib.import_module(f"{parts[0]}.msg"), parts[-1])


def message_to_dict(msg: Any) -> Any:
    """An rclpy message as nested dicts and lists, as rosbridge sends it (times ``{"sec", "nanosec"}``),
    ``uint8[]`` (image data) as ``bytes``, other arrays as lists."""
    fields = getattr(msg, "get_fields_and_field_types", None)
    if fields is not None:
        return {name: message_to_dict(getattr(msg, name)) for name in fields()}
    if isinstance(msg, array.array):
        return msg.tobytes() if msg.typecode == "B" else msg.tolist()
    if isinstance(msg, (bytes, bytearray)):
        return bytes(msg)
    if isinstance(msg, (list, tuple)):
        return [message_to_dict(v) for v in msg]
    tolist = getattr(msg, "tolist", None)  # NumPy arrays (covariances)
    return tolist() if tolist is not None else msg


def fill_message(cls: Any, data: Mapping[str, Any]) -> Any:
    """An instance of the rclpy message class ``cls`` filled from ``data`` (nested dicts and lists;
    fields not given keep their defaults). Raises :class:`ValueError` for a field it does not have."""
    msg = cls()
    types = cls.get_fields_and_field_types()
    for key, value in data.items():
        kind = types.get(key)
        if kind is None:
            raise ValueError(f"{cls.__name__} has no field {key!r}")
        if kind.startswith("sequence<") and "/" in kind:
            element = _message_class(kind[len("sequence<"):].split(",")[0].rstrip(">"))
            setattr(msg, key, [fill_message(element, v) for v in value])
        elif "/" in kind and not kind.endswith("]"):
            setattr(msg, key, fill_message(_message_class(kind), value))
        elif kind in ("double", "float"):
            setattr(msg, key, float(value))
        else:
            setattr(msg, key, value)
    return msg


class Backend(Protocol):
    """What the transport hands the robot's messages to: the node's core (in process) or the relay."""

    def check(self, values: Mapping[str, Any]) -> str | None:
        """``None`` if the parameter values are accepted (and now in force), else the reason."""

    def pose(self, msg: dict[str, Any], received: float) -> None: ...
    def tf(self, msg: dict[str, Any], static: bool, received: float) -> None: ...
    def image(self, msg: dict[str, Any], received: float) -> None: ...
    def speech(self, text: str, received: float) -> None: ...
    def query(self, text: str) -> None: ...


def _qos_profiles() -> dict[str, Any]:
    """The node's QoS: ``reliable`` (queries, answers, speech), ``latched`` (the last markers and
    where poses), ``best_effort`` (poses, /tf), ``static`` (/tf_static), ``camera`` (the newest frames)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    keep_last = HistoryPolicy.KEEP_LAST
    return {
        "reliable": QoSProfile(history=keep_last, depth=100, reliability=ReliabilityPolicy.RELIABLE,
                               durability=DurabilityPolicy.VOLATILE),
        "latched": QoSProfile(history=keep_last, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.TRANSIENT_LOCAL),
        "best_effort": QoSProfile(history=keep_last, depth=100, reliability=ReliabilityPolicy.BEST_EFFORT,
                                  durability=DurabilityPolicy.VOLATILE),
        "static": QoSProfile(history=keep_last, depth=100, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL),
        "camera": QoSProfile(history=keep_last, depth=5, reliability=ReliabilityPolicy.BEST_EFFORT,
                             durability=DurabilityPolicy.VOLATILE),  # sensor data: the newest frames
    }


class Ros2Transport:
    """The node on the ROS 2 graph: parameters, subscriptions and publishers; messages go to ``backend``.

    ``ros_arguments``: ``--ros-args …`` as on any node's command line (parameters, remappings,
    ``--params-file``, ``--log-level``). ``echo`` gets the start-up line.
    """

    def __init__(self, backend: Backend, ros_arguments: Sequence[str] = (), node_name: str = "spco",
                 echo: Callable[[str], None] = print) -> None:
        import rclpy

        self.rclpy, self.backend = rclpy, backend
        self.context = rclpy.Context()
        try:
            from rclpy.signals import SignalHandlerOptions

            rclpy.init(args=["spco", *ros_arguments], context=self.context,
                       signal_handler_options=SignalHandlerOptions.NO)
        except ImportError:  # older rclpy: no signal handler options
            rclpy.init(args=["spco", *ros_arguments], context=self.context)
        self.node = rclpy.create_node(node_name, context=self.context)
        values = self.values = self._declare_parameters()
        pose_type = full_type(str(values["pose_type"]), POSE_TYPES, "pose_type")
        image_type = full_type(str(values["image_type"]), IMAGE_TYPES, "image_type")
        reason = backend.check(values)
        if reason is not None:
            raise ParameterError(reason)
        self.node.add_on_set_parameters_callback(self._on_parameters)
        qos = _qos_profiles()
        self._make_publishers(qos)
        from_tf = self._subscribe_inputs(qos, pose_type, image_type)
        self._refused: set[tuple[str, str]] = set()
        self.timer = self.node.create_timer(0.25, self._resolve_types)
        self._resolve_types()
        self.names = self._topic_names(from_tf)
        names = self.names
        echo(f"spco ros2: node {names['node']}; listening to pose {names['pose']}, image {names['image']}, "
             f"speech {names['speech']}; queries on {names['query']}, answers on {names['answer']}, markers "
             f"on {names['markers']}, where poses on {names['where']}, goals on {names['goal']} "
             f"({'every where' if values['goal'] else 'when a query asks'})")

    def _declare_parameters(self) -> dict[str, Any]:
        """Declare :data:`PARAMETERS` on the node (descriptions, ranges); their values as given."""
        from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

        values: dict[str, Any] = {}
        for name, spec in PARAMETERS.items():
            descriptor = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
            ranged = spec.low is not None and spec.high is not None
            if ranged and isinstance(spec.default, float):
                descriptor.floating_point_range = [FloatingPointRange(from_value=spec.low,
                                                                      to_value=spec.high)]
            elif ranged and isinstance(spec.default, int) and not isinstance(spec.default, bool):
                descriptor.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high),
                                                         step=1)]
            values[name] = self.node.declare_parameter(name, spec.default, descriptor).value
        return values

    def _on_parameters(self, changes: list[Any]) -> Any:
        """A parameter change, accepted (and in force) if the backend accepts the merged values."""
        from rcl_interfaces.msg import SetParametersResult

        merged = {k: self.node.get_parameter(k).value for k in PARAMETERS}
        merged.update({p.name: p.value for p in changes if p.name in PARAMETERS})
        problem = self.backend.check(merged)
        if problem is None:
            self.values = merged
            log.info("spco ros2: parameters %s", ", ".join(f"{p.name}={p.value!r}" for p in changes))
        return SetParametersResult(successful=problem is None, reason=problem or "")

    def _make_publishers(self, qos: Mapping[str, Any]) -> None:
        from geometry_msgs.msg import PoseArray, PoseStamped
        from rclpy.qos import QoSProfile
        from std_msgs.msg import String
        from visualization_msgs.msg import MarkerArray

        node = self.node
        self._String, self._PoseStamped = String, PoseStamped
        self._MarkerArray, self._PoseArray = MarkerArray, PoseArray
        self.answers = node.create_publisher(String, "~/answer", qos["reliable"])
        self.goals = node.create_publisher(PoseStamped, "goal_pose", QoSProfile(depth=10))
        self.poses = node.create_publisher(PoseArray, "~/where", qos["latched"])
        self.markers = node.create_publisher(MarkerArray, "~/markers", qos["latched"])

    def _subscribe_inputs(self, qos: Mapping[str, Any], pose_type: str | None,
                          image_type: str | None) -> bool:
        """Subscribe the query, speech, pose (or /tf) and image topics (those of type ``auto`` once their
        type is known); whether the pose comes from /tf."""
        from std_msgs.msg import String

        node, backend, values = self.node, self.backend, self.values
        self.subscriptions: list[Any] = [node.create_subscription(
            String, "~/query", lambda m: backend.query(m.data), qos["reliable"])]
        speech_topic = str(values["speech_topic"])
        if speech_topic:
            self.subscriptions.append(node.create_subscription(
                String, speech_topic, lambda m: backend.speech(m.data, self.now()), qos["reliable"]))
        pose_topic = str(values["pose_topic"])
        self.pending: dict[str, tuple[tuple[str, ...], Callable[[dict[str, Any], float], None], Any]] = {}
        from_tf = pose_topic.strip("/") == "tf"
        if from_tf:
            self._subscribe_tf(qos)
        elif pose_type is not None:
            self._subscribe(pose_topic, pose_type, backend.pose, qos["best_effort"])
        else:
            self.pending[pose_topic] = (POSE_TYPES, backend.pose, qos["best_effort"])
        image_topic = str(values["image_topic"])
        if image_topic and image_type is not None:
            self._subscribe(image_topic, image_type, backend.image, qos["camera"])
        elif image_topic:
            self.pending[image_topic] = (IMAGE_TYPES, backend.image, qos["camera"])
        return from_tf

    def _subscribe_tf(self, qos: Mapping[str, Any]) -> None:
        try:
            from tf2_msgs.msg import TFMessage
        except ImportError:
            raise ParameterError("pose_topic /tf needs the tf2_msgs package (ros-<distro>-tf2-msgs, part "
                                 "of any ROS 2 installation); or give a pose topic "
                                 "(-p pose_topic:=/amcl_pose)") from None
        node, backend = self.node, self.backend
        self.subscriptions.append(node.create_subscription(
            TFMessage, "/tf", lambda m: backend.tf(message_to_dict(m), False, self.now()),
            qos["best_effort"]))
        self.subscriptions.append(node.create_subscription(
            TFMessage, "/tf_static", lambda m: backend.tf(message_to_dict(m), True, self.now()),
            qos["static"]))

    def _topic_names(self, from_tf: bool) -> dict[str, str]:
        """The node's and its topics' resolved names (the start-up line's)."""
        node, values = self.node, self.values
        pose_topic, image_topic = str(values["pose_topic"]), str(values["image_topic"])
        speech_topic = str(values["speech_topic"])
        return {"node": node.get_fully_qualified_name(), "query": node.resolve_topic_name("~/query"),
                "answer": self.answers.topic_name, "markers": self.markers.topic_name,
                "where": self.poses.topic_name, "goal": self.goals.topic_name,
                "pose": "/tf + /tf_static" if from_tf else node.resolve_topic_name(pose_topic),
                "image": node.resolve_topic_name(image_topic) if image_topic else "(none)",
                "speech": node.resolve_topic_name(speech_topic) if speech_topic else "(none)"}

    def now(self) -> float:
        """The node's clock in seconds (ROS time: simulated time under ``use_sim_time``)."""
        return float(self.node.get_clock().now().nanoseconds) * 1e-9

    def _subscribe(self, topic: str, type_name: str, handle: Callable[[dict[str, Any], float], None],
                   qos: Any) -> None:
        self.subscriptions.append(self.node.create_subscription(
            _message_class(type_name), topic, lambda m: handle(message_to_dict(m), self.now()), qos))

    def _resolve_types(self) -> None:
        """Subscribe the topics whose type is ``auto`` once a publisher announces an accepted type."""
        if not self.pending:
            return
        known = dict(self.node.get_topic_names_and_types())
        for topic in list(self.pending):
            resolved = self.node.resolve_topic_name(topic)
            accepted, handle, qos = self.pending[topic]
            for type_name in known.get(resolved, ()):
                if type_name in accepted:
                    self._subscribe(topic, type_name, handle, qos)
                    log.info("spco ros2: %s is %s", resolved, type_name)
                    del self.pending[topic]
                    break
                if (resolved, type_name) not in self._refused:
                    self._refused.add((resolved, type_name))
                    log.error("spco ros2: %s carries %s; expected %s", resolved, type_name,
                              " or ".join(accepted))

    # ------------------------------------------------------------------ publishing (any thread)
    def publish_answer(self, data: Mapping[str, Any]) -> None:
        """An answer (``{"data": json text}``) on ``~/answer``."""
        self.answers.publish(self._String(data=data["data"]))

    def publish_goal(self, data: Mapping[str, Any]) -> None:
        """A PoseStamped (as a dict) on ``goal_pose``."""
        self.goals.publish(fill_message(self._PoseStamped, data))

    def publish_markers(self, data: Mapping[str, Any]) -> None:
        """A MarkerArray (as a dict) on ``~/markers``."""
        self.markers.publish(fill_message(self._MarkerArray, data))

    def publish_poses(self, data: Mapping[str, Any]) -> None:
        """A PoseArray (as a dict) on ``~/where``."""
        self.poses.publish(fill_message(self._PoseArray, data))

    # ------------------------------------------------------------------ running
    def spin(self, stop: threading.Event) -> None:
        """Handle messages until ``stop`` is set or the context shuts down.

        With rclpy's events executor where it has one (Jazzy's rclpy 7.1 and later: callbacks
        dispatched from the middleware's events in C++, a fraction of the Python executor's cost
        per message), else the single-threaded executor (Humble)."""
        try:
            from rclpy.experimental import EventsExecutor

            executor = EventsExecutor(context=self.context)
        except ImportError:
            from rclpy.executors import SingleThreadedExecutor

            executor = SingleThreadedExecutor(context=self.context)
        executor.add_node(self.node)
        try:
            while not stop.is_set() and self.context.ok():
                executor.spin_once(timeout_sec=0.1)
        finally:
            self.timer.cancel()
            executor.shutdown(timeout_sec=1.0)

    def close(self) -> None:
        """Leave the graph."""
        self.node.destroy_node()
        if self.context.ok():
            self.rclpy.shutdown(context=self.context)


# ---------------------------------------------------------------------------------------- relay
_LENGTH = struct.Struct(">I")


def write_frame(stream: BinaryIO, header: Mapping[str, Any], payload: bytes = b"") -> None:
    """One frame: the JSON header's length, the header, the payload's length, the payload."""
    text = json.dumps(header, separators=(",", ":")).encode()
    stream.write(_LENGTH.pack(len(text)) + text + _LENGTH.pack(len(payload)))
    if payload:
        stream.write(payload)
    stream.flush()


def read_frame(stream: BinaryIO) -> tuple[dict[str, Any], bytes] | None:
    """The next frame (header, payload), or ``None`` at the end of the stream."""
    def exactly(n: int) -> bytes | None:
        chunks, got = [], 0
        while got < n:
            chunk = stream.read(n - got)
            if not chunk:
                return None
            chunks.append(chunk)
            got += len(chunk)
        return b"".join(chunks)

    size = exactly(4)
    if size is None:
        return None
    header = exactly(_LENGTH.unpack(size)[0])
    size = exactly(4) if header is not None else None
    if header is None or size is None:
        return None
    length = _LENGTH.unpack(size)[0]
    payload = exactly(length) if length else b""
    if payload is None:
        return None
    return json.loads(header), payload


class _PipeBackend:
    """The robot's messages written as frames to spco (stdout); parameter checks wait for its reply."""

    def __init__(self, out: BinaryIO) -> None:
        self.out = out
        self.lock = threading.Lock()
        self.replies: queue.Queue[dict[str, Any]] = queue.Queue()
        self.asked = 0

    def _send(self, header: Mapping[str, Any], payload: bytes = b"") -> None:
        with self.lock:
            write_frame(self.out, header, payload)

    def check(self, values: Mapping[str, Any]) -> str | None:
        self.asked += 1
        self._send({"kind": "check", "ask": self.asked, "values": dict(values)})
        while True:
            try:
                reply = self.replies.get(timeout=10.0)
            except queue.Empty:
                return "spco did not answer the parameter change within 10 s"
            if reply.get("ask") == self.asked:
                return reply.get("reason")

    def pose(self, msg: dict[str, Any], received: float) -> None:
        self._send({"kind": "pose", "msg": msg, "received": received})

    def tf(self, msg: dict[str, Any], static: bool, received: float) -> None:
        self._send({"kind": "tf", "msg": msg, "static": static, "received": received})

    def image(self, msg: dict[str, Any], received: float) -> None:
        data = msg.pop("data", b"")
        self._send({"kind": "image", "msg": msg, "received": received}, bytes(data))

    def speech(self, text: str, received: float) -> None:
        self._send({"kind": "speech", "text": text, "received": received})

    def query(self, text: str) -> None:
        self._send({"kind": "query", "text": text})


def relay_main(argv: Sequence[str] | None = None) -> int:
    """The robot's process of ``spco ros2 --ros-python``: the node on the graph, relaying to spco over
    stdin (what to publish, parameter replies, ``stop``) and stdout (what the robot publishes)."""
    args = list(sys.argv[1:] if argv is None else argv)
    node_name = os.environ.get("SPCO_ROS2_NODE_NAME", "spco")
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stderr)
    out, inp = sys.stdout.buffer, sys.stdin.buffer
    backend = _PipeBackend(out)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):  # spco stops the relay; Ctrl-C reaches both processes
        signal.signal(sig, lambda *_: None)
    transport: Ros2Transport | None = None
    publishers: dict[str, Callable[[Mapping[str, Any]], None]] = {}

    def read() -> None:
        while True:
            frame = read_frame(inp)
            if frame is None or frame[0].get("kind") == "stop":
                stop.set()
                return
            header, _ = frame
            if header.get("kind") == "checked":
                backend.replies.put(header)
            elif header.get("kind") in publishers:
                try:
                    publishers[header["kind"]](header["msg"])
                except Exception:  # one bad message does not stop the relay
                    log.exception("spco ros2: publishing %s failed", header["kind"])

    reader = threading.Thread(target=read, name="spco-relay", daemon=True)
    reader.start()
    try:
        transport = Ros2Transport(backend, args, node_name=node_name,
                                  echo=lambda line: backend._send({"kind": "started", "line": line}))
    except ParameterError as exc:
        backend._send({"kind": "failed", "error": str(exc)})
        return 2
    publishers.update({"answer": transport.publish_answer, "goal": transport.publish_goal,
                       "markers": transport.publish_markers, "poses": transport.publish_poses})
    backend._send({"kind": "names", "names": transport.names})
    try:
        transport.spin(stop)
    finally:
        transport.close()
    return 0


if __name__ == "__main__":
    # run as a script, this file's folder is first on sys.path: its siblings (core, node, messages…)
    # must not shadow modules of the same names that rclpy's packages may import
    here = os.path.dirname(os.path.abspath(__file__))
    sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != here]
    sys.exit(relay_main())
