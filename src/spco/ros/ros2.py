"""``spco ros2 HOME.spco``: the node for ROS 2 (Humble, Jazzy), with rclpy, in spco's own process.

The same behaviour as the ROS 1 node (:mod:`spco.ros.node`) through the same core
(:class:`spco.ros.core.NodeCore`), the way a ROS 2 node is configured and wired:

- **parameters** (:data:`PARAMETERS`), declared with descriptions and ranges: set at start with
  ``--ros-args -p tolerance:=1.0`` (or ``--params-file``), read and changed at run time through the
  node's ``rcl_interfaces`` services (``ros2 param get|set /spco …``). The topic parameters are
  read-only (they choose the subscriptions); the others take effect with the next message;
- **names**: the node's own topics are private (``~/query`` is ``/spco/query`` for a node named
  ``spco``), the goal is ``goal_pose`` (``/goal_pose``, Nav2's), and every name can be remapped
  (``--ros-args -r __node:=spco_kitchen -r __ns:=/robot1 -r /spco/query:=/hsr/query``);
- **QoS**: the pose and camera are subscribed best-effort (sensor data: compatible with reliable and
  best-effort publishers), speech and queries reliable, answers reliable, the markers and the last
  ``where`` poses reliable and transient local (RViz2 and Foxglove get them on connect), the goal
  reliable and volatile (as RViz2's "2D Goal Pose");
- **types**: the pose topic may carry ``PoseWithCovarianceStamped`` (AMCL's ``/amcl_pose``),
  ``PoseStamped`` or ``Odometry``, the camera ``Image`` or ``CompressedImage``: with ``pose_type`` or
  ``image_type`` ``auto`` (the default) the node subscribes once a publisher has announced the type
  on the graph; ``/tf`` (the default pose topic) composes ``map_frame`` → ``robot_frame`` from
  ``/tf`` and ``/tf_static``.

rclpy comes from the robot's ROS installation (``/opt/ros/<distro>``), for that installation's
Python: Jazzy's Python 3.12 runs this module (spco needs 3.11 or later); a Humble robot (Python
3.10) runs :mod:`spco.ros.thin` with its own Python instead, against ``spco serve``.
"""

from __future__ import annotations

import array
import importlib
import logging
import signal
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from spco.errors import ConfigurationError
from spco.ros import RosUnavailableError, import_rclpy
from spco.ros.core import NodeCore, NodeSettings

__all__ = ["PARAMETERS", "Parameter2", "fill_message", "message_to_dict", "run_ros2"]

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


def _full_type(value: str, accepted: tuple[str, ...], parameter: str) -> str | None:
    """``None`` for auto, else the full ROS 2 type name of ``value`` (short or full)."""
    text = value.strip()
    if text.lower() in ("", "auto"):
        return None
    full = _TYPE_ALIASES.get(text.lower(), text if text in accepted else "")
    if full not in accepted:
        names = ", ".join(t.rsplit("/", 1)[-1] for t in accepted)
        raise ConfigurationError(f"parameter {parameter}: {value!r} is not a type the node reads "
                                 f"(auto, {names})")
    return full


def _message_class(type_name: str) -> Any:
    """The Python class of a ROS 2 type, ``pkg/msg/Name`` or ``pkg/Name``."""
    parts = type_name.split("/")
    package, name = parts[0], parts[-1]
    return getattr(importlib.import_module(f"{package}.msg"), name)


def message_to_dict(msg: Any) -> Any:
    """An rclpy message as nested dicts and lists, as rosbridge sends it (times ``{"sec", "nanosec"}``),
    ``uint8[]`` (image data) as ``bytes``, other arrays as lists."""
    fields = getattr(msg, "get_fields_and_field_types", None)
    if fields is not None:
        return {name: message_to_dict(getattr(msg, name)) for name in fields()}
    if isinstance(msg, array.array):
        return msg.tobytes() if msg.typecode == "B" else msg.tolist()
    if isinstance(msg, bytes | bytearray):
        return bytes(msg)
    if isinstance(msg, list | tuple):
        return [message_to_dict(v) for v in msg]
    tolist = getattr(msg, "tolist", None)  # NumPy arrays (covariances)
    return tolist() if tolist is not None else msg


def fill_message(cls: Any, data: Mapping[str, Any]) -> Any:
    """An instance of the rclpy message class ``cls`` filled from ``data`` (nested dicts and lists, as
    :mod:`spco.ros.messages` makes them; fields not given keep their defaults). Raises
    :class:`~spco.errors.ConfigurationError` for a field the message does not have."""
    msg = cls()
    types = cls.get_fields_and_field_types()
    for key, value in data.items():
        kind = types.get(key)
        if kind is None:
            raise ConfigurationError(f"{cls.__name__} has no field {key!r}")
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


def _settings_of(values: Mapping[str, Any]) -> NodeSettings:
    """The :class:`NodeSettings` of the node's parameter values (raises ConfigurationError)."""
    wait = float(values["image_wait"])
    return NodeSettings(tolerance=float(values["tolerance"]), image_wait=None if wait < 0 else wait,
                        clock=str(values["clock"]), max_age=float(values["max_age"]),
                        goal=bool(values["goal"]),
                        map_frame=str(values["map_frame"]), robot_frame=str(values["robot_frame"]),
                        n=int(values["n"]), top=int(values["top"]))


def run_ros2(home: Any, *, ros_arguments: Sequence[str] = (), node_name: str = "spco",
             uses_images: bool = True, n_concepts: int = 10, stop: threading.Event | None = None,
             ready: Callable[[NodeCore, Mapping[str, str]], None] | None = None,
             echo: Callable[[str], None] = print) -> dict[str, int]:
    """Run the ROS 2 node until SIGINT/SIGTERM (or ``stop`` is set); return ``{"taught", "answered"}``.

    Parameters
    ----------
    home: the resident home (:class:`~spco.service.live.LiveHome`); not closed here.
    ros_arguments: ROS 2 arguments (``--ros-args -p tolerance:=1.0 -r __node:=spco2 …``).
    node_name: the node's name unless remapped (``-r __node:=…``).
    uses_images, n_concepts: see :class:`~spco.ros.core.NodeCore`.
    stop: an event that ends the node (default: set by SIGINT and SIGTERM).
    ready: called with the core and the node's resolved topic names once it is set up.
    echo: where the start-up and last lines go.

    ``ROS_DOMAIN_ID`` and ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (Jazzy) or ``ROS_LOCALHOST_ONLY`` (Humble)
    come from the environment, as for any ROS 2 node.
    """
    rclpy = import_rclpy()
    from geometry_msgs.msg import PoseArray, PoseStamped
    from rcl_interfaces.msg import (
        FloatingPointRange,
        IntegerRange,
        ParameterDescriptor,
        SetParametersResult,
    )
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import (
        DurabilityPolicy,
        HistoryPolicy,
        QoSProfile,
        ReliabilityPolicy,
        qos_profile_sensor_data,
    )
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import String
    from visualization_msgs.msg import MarkerArray

    context = rclpy.Context()
    rclpy.init(args=["spco", *ros_arguments], context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(node_name, context=context)
    try:
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
            values[name] = node.declare_parameter(name, spec.default, descriptor).value
        settings = _settings_of(values)
        pose_type = _full_type(str(values["pose_type"]), POSE_TYPES, "pose_type")
        image_type = _full_type(str(values["image_type"]), IMAGE_TYPES, "image_type")

        keep_last = HistoryPolicy.KEEP_LAST
        reliable = QoSProfile(history=keep_last, depth=100, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)
        latched = QoSProfile(history=keep_last, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        best_effort = QoSProfile(history=keep_last, depth=100, reliability=ReliabilityPolicy.BEST_EFFORT,
                                 durability=DurabilityPolicy.VOLATILE)
        answers = node.create_publisher(String, "~/answer", reliable)
        goals = node.create_publisher(PoseStamped, "goal_pose", QoSProfile(depth=10))
        poses = node.create_publisher(PoseArray, "~/where", latched)
        markers = node.create_publisher(MarkerArray, "~/markers", latched)

        def now() -> float:
            return node.get_clock().now().nanoseconds * 1e-9

        core = NodeCore(home, settings,
                        publish_answer=lambda d: answers.publish(String(data=d["data"])),
                        publish_goal=lambda d: goals.publish(fill_message(PoseStamped, d)),
                        publish_markers=lambda d: markers.publish(fill_message(MarkerArray, d)),
                        publish_poses=lambda d: poses.publish(fill_message(PoseArray, d)),
                        now=now, uses_images=uses_images, n_concepts=n_concepts)

        def on_parameters(changes: list[Any]) -> Any:
            merged = {k: node.get_parameter(k).value for k in PARAMETERS}
            merged.update({p.name: p.value for p in changes})
            try:
                new = _settings_of(merged)
            except (ConfigurationError, TypeError, ValueError) as exc:
                return SetParametersResult(successful=False, reason=str(exc))
            core.settings = new
            log.info("spco ros2: parameters %s", ", ".join(f"{p.name}={p.value!r}" for p in changes))
            return SetParametersResult(successful=True)

        node.add_on_set_parameters_callback(on_parameters)

        subscriptions: list[Any] = [node.create_subscription(String, "~/query",
                                                             lambda m: core.on_query(m.data), reliable)]
        if values["speech_topic"]:
            subscriptions.append(node.create_subscription(String, str(values["speech_topic"]),
                                                          lambda m: core.on_speech(m.data, now()), reliable))
        pose_topic = str(values["pose_topic"])
        pending: dict[str, tuple[tuple[str, ...], Callable[[dict[str, Any], float], None], Any]] = {}

        def subscribe_typed(topic: str, type_name: str, handle: Callable[[dict[str, Any], float], None],
                            qos: Any) -> Any:
            return node.create_subscription(_message_class(type_name), topic,
                                            lambda m: handle(message_to_dict(m), now()), qos)

        if pose_topic.strip("/") == "tf":
            try:
                from tf2_msgs.msg import TFMessage
            except ImportError:
                raise RosUnavailableError("pose_topic /tf needs the tf2_msgs package (ros-<distro>-tf2-msgs, "
                                          "part of any ROS 2 installation); or give a pose topic "
                                          "(-p pose_topic:=/amcl_pose)") from None
            static_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                                    reliability=ReliabilityPolicy.RELIABLE,
                                    durability=DurabilityPolicy.TRANSIENT_LOCAL)
            subscriptions.append(node.create_subscription(
                TFMessage, "/tf", lambda m: core.on_tf(message_to_dict(m), False, now()), best_effort))
            subscriptions.append(node.create_subscription(
                TFMessage, "/tf_static", lambda m: core.on_tf(message_to_dict(m), True, now()), static_qos))
        elif pose_type is not None:
            subscriptions.append(subscribe_typed(pose_topic, pose_type, core.on_pose, best_effort))
        else:
            pending[pose_topic] = (POSE_TYPES, core.on_pose, best_effort)
        image_topic = str(values["image_topic"])
        if image_topic:
            camera_qos = qos_profile_sensor_data  # best effort, the newest 5 frames
            if image_type is not None:
                subscriptions.append(subscribe_typed(image_topic, image_type, core.on_image, camera_qos))
            else:
                pending[image_topic] = (IMAGE_TYPES, core.on_image, camera_qos)
        refused: set[tuple[str, str]] = set()

        def resolve_types() -> None:
            """Subscribe the topics whose type was ``auto`` once a publisher announces an accepted type."""
            if not pending:
                return
            known = dict(node.get_topic_names_and_types())
            for topic in list(pending):
                resolved = node.resolve_topic_name(topic)
                accepted, handle, qos = pending[topic]
                for type_name in known.get(resolved, ()):
                    if type_name in accepted:
                        subscriptions.append(subscribe_typed(topic, type_name, handle, qos))
                        log.info("spco ros2: %s is %s", resolved, type_name)
                        del pending[topic]
                        break
                    if (resolved, type_name) not in refused:
                        refused.add((resolved, type_name))
                        log.error("spco ros2: %s carries %s; expected %s", resolved, type_name,
                                  " or ".join(accepted))
        timer = node.create_timer(0.25, resolve_types)
        resolve_types()

        stop = stop or threading.Event()
        previous: dict[int, Any] = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                previous[sig] = signal.signal(sig, lambda *_: stop.set())
        core.start()
        from_tf = pose_topic.strip("/") == "tf"
        names = {"query": node.resolve_topic_name("~/query"), "answer": answers.topic_name,
                 "markers": markers.topic_name, "where": poses.topic_name, "goal": goals.topic_name,
                 "pose": "/tf + /tf_static" if from_tf else node.resolve_topic_name(pose_topic),
                 "image": node.resolve_topic_name(image_topic) if image_topic else "(none)",
                 "speech": node.resolve_topic_name(str(values["speech_topic"])) if values["speech_topic"]
                 else "(none)"}
        echo(f"spco ros2: node {node.get_fully_qualified_name()}; listening to pose {names['pose']}, image "
             f"{names['image']}, speech {names['speech']}; queries on {names['query']}, answers on "
             f"{names['answer']}, markers on {names['markers']}, where poses on {names['where']}, goals on "
             f"{names['goal']} ({'every where' if settings.goal else 'when a query asks'})")
        if ready is not None:
            ready(core, names)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        try:
            while not stop.is_set() and context.ok():
                executor.spin_once(timeout_sec=0.1)
        finally:
            core.stop()
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            timer.cancel()
            executor.shutdown(timeout_sec=1.0)
    finally:
        node.destroy_node()
        if context.ok():
            rclpy.shutdown(context=context)
    counts = {"taught": core.taught, "answered": core.answered}
    echo(f"spco ros2: stopped after {counts['taught']} teachings and {counts['answered']} answers")
    return counts
