"""A stand-in robot for ``spco ros2``, in the ROS 2 virtual environment: rclpy publishers of the pose,
camera and speech, subscribers of the node's answers, markers, where poses and goals, and clients of
its parameter services — driven by JSON lines on stdin, one JSON line of result on stdout each.

Run by tests/test_ros2_node.py and benchmarks/ros2_latency.py with the ROS 2 environment's Python
(rclpy from the registry's Jazzy wheels), never imported by pytest itself. Needs only the standard
library, NumPy and rclpy. Commands (``{"cmd": …}``):

- ``pose`` ``{x, y, theta, frame?, type?}``: publish the robot's pose (``type`` PoseStamped,
  PoseWithCovarianceStamped (default) or Odometry) on ``--pose-topic``;
- ``image`` ``{data (base64), width, height, encoding}``: publish a camera frame on ``--image-topic``;
- ``say`` ``{sentence}``: publish on ``--speech-topic``; returns the send time;
- ``query`` ``{request, timeout?}``: publish a query (JSON text, or a string as is) and wait for the
  answer echoing its id (``"match": "error"`` waits for the next answer with an error); returns
  ``{"answer", "seconds", "hops"}`` (``hops``: the answer's ``transit`` in the middleware and
  ``dispatch`` by this side's executor, seconds);
- ``answer`` ``{op, timeout?}``: wait for the next answer with that op (e.g. a teaching's);
- ``markers`` ``{after?, timeout?}``: wait for a MarkerArray received after ``after`` (a time from
  ``say``); returns its markers summarised and the time it came;
- ``late_markers`` ``{timeout?}``: a new subscriber (transient local) and the first MarkerArray it gets;
- ``goal`` / ``where_poses`` ``{timeout?}``: the last goal / PoseArray received (waiting for one);
- ``get_parameters`` ``{names}``, ``set_parameters`` ``{values}``, ``describe_parameters``
  ``{names}``: through the node's rcl_interfaces services;
- ``graph``: the topics and their types;
- ``quit``.
"""

from __future__ import annotations

import argparse
import base64
import json
import math
import sys
import threading
import time
from typing import Any

import rclpy
from geometry_msgs.msg import PoseArray, PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Image
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


def make_executor(kind: str) -> Any:
    """The robot's executor, spun in a thread of its own: ``multi`` (rclpy's multi-threaded executor,
    two threads) or ``single`` (the single-threaded one, ``rclpy.spin``'s). Not rclpy 7.1's events
    executor: it fails on a subscription callback that takes the message's MessageInfo, as the
    answers' does (``SystemError: null argument to internal routine``)."""
    if kind == "multi":
        return MultiThreadedExecutor(num_threads=2)
    if kind == "single":
        return SingleThreadedExecutor()
    raise ValueError(f"executor: expected multi or single, got {kind!r}")


class Robot:
    """The robot's side of the graph."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.node = rclpy.create_node("fake_robot")
        self.lock = threading.Condition()
        self.answers: list[tuple[float, dict[str, Any]]] = []
        self.answer_hops: list[dict[str, float]] = []  # of each answer: see _on_answer
        self.markers: list[tuple[float, Any]] = []
        self.goals: list[Any] = []
        self.where: list[Any] = []
        n = self.node
        self.pose_types = {"PoseStamped": PoseStamped, "PoseWithCovarianceStamped": PoseWithCovarianceStamped,
                           "Odometry": Odometry}
        self.pose_kind = args.pose_type
        self.pose_pub = n.create_publisher(self.pose_types[args.pose_type], args.pose_topic, 10)
        self.image_pub = n.create_publisher(Image, args.image_topic, qos_profile_sensor_data)
        self.speech_pub = n.create_publisher(String, args.speech_topic, RELIABLE)
        self.query_pub = n.create_publisher(String, args.query_topic, RELIABLE)
        n.create_subscription(String, args.answer_topic, self._on_answer, RELIABLE)
        n.create_subscription(MarkerArray, args.markers_topic, self._on_markers, LATCHED)
        n.create_subscription(PoseStamped, args.goal_topic, self._on_goal, 10)
        n.create_subscription(PoseArray, args.where_topic, self._on_where, LATCHED)
        node_name = args.node
        self.target = node_name
        self.clients = {"get": n.create_client(GetParameters, f"{node_name}/get_parameters"),
                        "set": n.create_client(SetParameters, f"{node_name}/set_parameters"),
                        "describe": n.create_client(DescribeParameters, f"{node_name}/describe_parameters")}
        self.executor = make_executor(getattr(args, "executor", "multi"))
        self.executor.add_node(n)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    # ------------------------------------------------------------------ callbacks
    def _on_answer(self, msg: String, info: Any) -> None:
        """An answer, with where its time went on this side (``info``: the middleware's MessageInfo):
        ``transit`` from the node's publish to the middleware here (source → received timestamps,
        both the system clock) and ``dispatch`` from there to this callback (the executor)."""
        called = time.perf_counter()
        now_ns = time.time_ns()
        source, received = info.get("source_timestamp"), info.get("received_timestamp")
        hops = ({"transit": max(0.0, (received - source) * 1e-9),
                 "dispatch": max(0.0, (now_ns - received) * 1e-9)} if source and received else {})
        try:
            answer = json.loads(msg.data)
        except ValueError:
            answer = {"unparsed": msg.data}
        with self.lock:
            self.answers.append((called, answer))
            self.answer_hops.append(hops)
            self.lock.notify_all()

    def _on_markers(self, msg: MarkerArray) -> None:
        with self.lock:
            self.markers.append((time.perf_counter(), msg))
            self.lock.notify_all()

    def _on_goal(self, msg: PoseStamped) -> None:
        with self.lock:
            self.goals.append(msg)
            self.lock.notify_all()

    def _on_where(self, msg: PoseArray) -> None:
        with self.lock:
            self.where.append(msg)
            self.lock.notify_all()

    def _wait(self, predicate: Any, timeout: float) -> Any:
        deadline = time.monotonic() + timeout
        with self.lock:
            while True:
                found = predicate()
                if found is not None:
                    return found
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self.lock.wait(min(remaining, 0.05))

    # ------------------------------------------------------------------ commands
    def wait_connected(self, timeout: float) -> dict[str, Any]:
        """Wait until the node subscribes every topic this robot publishes and its services are ready."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            # every publisher matched: a pose or frame published before its subscription is matched is
            # lost (volatile QoS), and a later `what` would find no current pose
            # — matched by the node under test itself: a shared topic (/pose, /camera/image, /speech) may
            # already be matched by another node, which says nothing about this one's subscription
            publishers = (self.query_pub, self.speech_pub, self.pose_pub, self.image_pub)
            if (all(p.get_subscription_count() > 0 and self._target_subscribes(p.topic_name)
                    for p in publishers)
                    and all(c.service_is_ready() for c in self.clients.values())):
                return {"connected": True}
            time.sleep(0.05)
        return {"connected": False}

    def _target_subscribes(self, topic: str) -> bool:
        """Whether the node under test (``--node``) has a subscription on ``topic`` in the ROS graph."""
        names = {f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                 for info in self.node.get_subscriptions_info_by_topic(topic)}
        return self.target in names

    def pose(self, x: float, y: float, theta: float, frame: str = "map", kind: str | None = None) -> dict:
        kind = kind or self.pose_kind
        msg = self.pose_types[kind]()
        msg.header.frame_id = frame
        msg.header.stamp = self.node.get_clock().now().to_msg()
        target = msg.pose.pose if kind != "PoseStamped" else msg.pose
        target.position.x, target.position.y = float(x), float(y)
        target.orientation.z, target.orientation.w = math.sin(theta / 2), math.cos(theta / 2)
        self.pose_pub.publish(msg)
        return {"sent": time.perf_counter()}

    def image(self, data: str, width: int, height: int, encoding: str) -> dict:
        msg = Image()
        msg.header.frame_id = "camera"
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.width, msg.height, msg.encoding = int(width), int(height), encoding
        raw = base64.b64decode(data)
        msg.step = len(raw) // int(height)
        msg.data = raw
        self.image_pub.publish(msg)
        return {"sent": time.perf_counter()}

    def say(self, sentence: str) -> dict:
        sent = time.perf_counter()
        self.speech_pub.publish(String(data=sentence))
        return {"sent": sent}

    def query(self, request: Any, timeout: float = 10.0, match: str = "id") -> dict:
        text = request if isinstance(request, str) else json.dumps(request)
        with self.lock:
            start_index = len(self.answers)
        wanted = request.get("id") if isinstance(request, dict) else None
        sent = time.perf_counter()
        self.query_pub.publish(String(data=text))

        def found() -> Any:
            for k, (t, answer) in enumerate(self.answers[start_index:], start_index):
                if match == "error" and "error" in answer and answer.get("op") != "teach":
                    return t, answer, self.answer_hops[k]
                if match == "id" and answer.get("id") == wanted and answer.get("op") != "teach":
                    return t, answer, self.answer_hops[k]
            return None

        got = self._wait(found, timeout)
        if got is None:
            return {"answer": None, "seconds": None, "hops": {}}
        return {"answer": got[1], "seconds": got[0] - sent, "hops": got[2]}

    def answer(self, op: str, after: float = 0.0, timeout: float = 10.0) -> dict:
        got = self._wait(lambda: next(((t, a) for t, a in self.answers if t > after and a.get("op") == op),
                                      None), timeout)
        return {"answer": None if got is None else got[1], "received": None if got is None else got[0]}

    @staticmethod
    def _summary(msg: MarkerArray) -> list[dict[str, Any]]:
        return [{"ns": m.ns, "id": m.id, "type": m.type, "action": m.action, "frame": m.header.frame_id,
                 "text": m.text, "points": len(m.points), "x": m.pose.position.x, "y": m.pose.position.y}
                for m in msg.markers]

    def markers_after(self, after: float = 0.0, timeout: float = 10.0) -> dict:
        got = self._wait(lambda: next(((t, m) for t, m in self.markers if t > after), None), timeout)
        if got is None:
            return {"markers": None}
        return {"markers": self._summary(got[1]), "received": got[0], "count": len(self.markers)}

    def late_markers(self, timeout: float = 10.0) -> dict:
        box: list[Any] = []
        event = threading.Event()

        def on(msg: MarkerArray) -> None:
            box.append(msg)
            event.set()

        sub = self.node.create_subscription(MarkerArray, self.args.markers_topic, on, LATCHED)
        event.wait(timeout)
        self.node.destroy_subscription(sub)
        return {"markers": self._summary(box[0]) if box else None}

    def goal(self, timeout: float = 10.0, count: int = 1) -> dict:
        got = self._wait(lambda: self.goals[count - 1] if len(self.goals) >= count else None, timeout)
        if got is None:
            return {"goal": None, "count": len(self.goals)}
        q = got.pose.orientation
        stamp = [got.header.stamp.sec, got.header.stamp.nanosec]
        return {"goal": {"frame": got.header.frame_id, "stamp": stamp,
                         "x": got.pose.position.x, "y": got.pose.position.y,
                         "theta": math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))},
                "count": len(self.goals)}

    def where_poses(self, timeout: float = 10.0, count: int = 1) -> dict:
        got = self._wait(lambda: self.where[count - 1] if len(self.where) >= count else None, timeout)
        if got is None:
            return {"poses": None}
        return {"frame": got.header.frame_id,
                "poses": [[p.position.x, p.position.y] for p in got.poses], "count": len(self.where)}

    def _call(self, kind: str, request: Any, timeout: float = 10.0) -> Any:
        client = self.clients[kind]
        if not client.wait_for_service(timeout_sec=timeout):
            raise RuntimeError(f"the {kind} parameters service is not there")
        future = client.call_async(request)
        deadline = time.monotonic() + timeout
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        if not future.done():
            raise RuntimeError(f"the {kind} parameters service did not answer")
        return future.result()

    @staticmethod
    def _value(value: ParameterValue) -> Any:
        kinds = {ParameterType.PARAMETER_BOOL: "bool_value", ParameterType.PARAMETER_INTEGER: "integer_value",
                 ParameterType.PARAMETER_DOUBLE: "double_value",
                 ParameterType.PARAMETER_STRING: "string_value"}
        return getattr(value, kinds[value.type]) if value.type in kinds else None

    def get_parameters(self, names: list[str]) -> dict:
        result = self._call("get", GetParameters.Request(names=names))
        return {"values": dict(zip(names, (self._value(v) for v in result.values), strict=True))}

    def set_parameters(self, values: dict[str, Any]) -> dict:
        parameters = []
        for name, value in values.items():
            v = ParameterValue()
            if isinstance(value, bool):
                v.type, v.bool_value = ParameterType.PARAMETER_BOOL, value
            elif isinstance(value, int):
                v.type, v.integer_value = ParameterType.PARAMETER_INTEGER, value
            elif isinstance(value, float):
                v.type, v.double_value = ParameterType.PARAMETER_DOUBLE, value
            else:
                v.type, v.string_value = ParameterType.PARAMETER_STRING, str(value)
            parameters.append(Parameter(name=name, value=v))
        result = self._call("set", SetParameters.Request(parameters=parameters))
        return {"results": [{"successful": r.successful, "reason": r.reason} for r in result.results]}

    def describe_parameters(self, names: list[str]) -> dict:
        result = self._call("describe", DescribeParameters.Request(names=names))
        return {"descriptors": {d.name: {"description": d.description, "read_only": d.read_only,
                                         "type": d.type} for d in result.descriptors}}

    def graph(self) -> dict:
        return {"topics": {name: types for name, types in self.node.get_topic_names_and_types()}}

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--node", default="/spco")
    parser.add_argument("--pose-topic", default="/pose")
    parser.add_argument("--pose-type", default="PoseWithCovarianceStamped")
    parser.add_argument("--image-topic", default="/camera/image")
    parser.add_argument("--speech-topic", default="/speech")
    parser.add_argument("--query-topic", default="/spco/query")
    parser.add_argument("--answer-topic", default="/spco/answer")
    parser.add_argument("--markers-topic", default="/spco/markers")
    parser.add_argument("--where-topic", default="/spco/where")
    parser.add_argument("--goal-topic", default="/goal_pose")
    parser.add_argument("--connect-timeout", type=float, default=120.0)
    parser.add_argument("--executor", choices=("multi", "single"), default="multi")
    args = parser.parse_args()
    rclpy.init()
    robot = Robot(args)
    commands = {"pose": lambda c: robot.pose(c["x"], c["y"], c["theta"], c.get("frame", "map"),
                                             c.get("type")),
                "image": lambda c: robot.image(c["data"], c["width"], c["height"], c["encoding"]),
                "say": lambda c: robot.say(c["sentence"]),
                "query": lambda c: robot.query(c["request"], c.get("timeout", 10.0), c.get("match", "id")),
                "answer": lambda c: robot.answer(c["op"], c.get("after", 0.0), c.get("timeout", 10.0)),
                "markers": lambda c: robot.markers_after(c.get("after", 0.0), c.get("timeout", 10.0)),
                "late_markers": lambda c: robot.late_markers(c.get("timeout", 10.0)),
                "goal": lambda c: robot.goal(c.get("timeout", 10.0), c.get("count", 1)),
                "where_poses": lambda c: robot.where_poses(c.get("timeout", 10.0), c.get("count", 1)),
                "get_parameters": lambda c: robot.get_parameters(c["names"]),
                "set_parameters": lambda c: robot.set_parameters(c["values"]),
                "describe_parameters": lambda c: robot.describe_parameters(c["names"]),
                "graph": lambda c: robot.graph(),
                "now": lambda c: {"now": time.perf_counter()}}
    print(json.dumps(robot.wait_connected(args.connect_timeout)), flush=True)
    try:
        for line in sys.stdin:
            if not line.strip():
                continue
            command = json.loads(line)
            if command.get("cmd") == "quit":
                break
            try:
                result = commands[command["cmd"]](command)
            except Exception as exc:  # reported to the test, which fails on it
                result = {"exception": f"{type(exc).__name__}: {exc}"}
            print(json.dumps(result), flush=True)
    finally:
        robot.close()
        rclpy.shutdown()


if __name__ == "__main__":
    main()
