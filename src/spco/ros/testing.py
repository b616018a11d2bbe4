"""Try the node without a robot: a ROS master on this computer, ``spco ros`` in its own process, and
a stand-in for the robot (rospy publishers and subscribers) — what the tests and
``benchmarks/ros_latency.py`` use.

The processes talk over loopback as a companion computer talks to a robot over its network:
``ROS_MASTER_URI`` names the master, ``ROS_IP`` each process's own address.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import threading
import time
import xmlrpc.client
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from spco.errors import SpcoError
from spco.ros import import_rospy
from spco.ros.messages import quaternion_from_yaw

__all__ = ["FakeRobot", "free_port", "ros_environment", "start_master", "start_node", "stop_process"]


def free_port() -> int:
    """A TCP port free on the loopback interface now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def ros_environment(port: int, log_dir: str | os.PathLike[str]) -> dict[str, str]:
    """The environment of a process on the ROS network of the master at ``127.0.0.1:port``."""
    env = dict(os.environ)
    env.update({"ROS_MASTER_URI": f"http://127.0.0.1:{port}/", "ROS_IP": "127.0.0.1",
                "ROS_HOME": str(log_dir), "ROS_LOG_DIR": str(log_dir)})
    env.pop("ROS_HOSTNAME", None)
    return env


def start_master(port: int, log_dir: str | os.PathLike[str],
                 timeout: float = 20.0) -> subprocess.Popen[bytes]:
    """Start ``rosmaster --core -p PORT`` (the ROS 1 master of Debian's python3-rosmaster, or a ROS
    installation's) and wait until it answers. Raises :class:`~spco.errors.SpcoError` if there is no
    ``rosmaster`` or it does not come up within ``timeout`` seconds."""
    master = shutil.which("rosmaster")
    if master is None:
        raise SpcoError("no rosmaster program: sudo apt-get install python3-rosmaster")
    env = ros_environment(port, log_dir)
    process = subprocess.Popen([master, "--core", "-p", str(port), "-w", "3"], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    proxy = xmlrpc.client.ServerProxy(env["ROS_MASTER_URI"])
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if process.poll() is not None:
            said = process.stderr.read().decode(errors="replace")[-500:] if process.stderr else ""
            raise SpcoError(f"rosmaster exited ({process.returncode}): {said}")
        try:
            code, _, _ = proxy.getPid("/spco_test")
            if code == 1:
                return process
        except OSError:
            time.sleep(0.1)
    stop_process(process)
    raise SpcoError(f"rosmaster did not answer on port {port} within {timeout:g} s")


def start_node(home_file: str | os.PathLike[str], port: int, log_dir: str | os.PathLike[str],
               args: Sequence[str] = (), extra_env: Mapping[str, str] | None = None
               ) -> subprocess.Popen[bytes]:
    """Start ``spco ros HOME_FILE ARGS…`` in its own process on the master at ``127.0.0.1:port``; its
    output goes to ``log_dir/node.log``."""
    env = ros_environment(port, log_dir)
    env.update(extra_env or {})
    log = open(Path(log_dir) / "node.log", "ab")  # closed below: the process keeps its own copy
    try:
        return subprocess.Popen([sys.executable, "-m", "spco", "ros", str(home_file), *args], env=env,
                                stdout=log, stderr=subprocess.STDOUT)
    finally:
        log.close()


def stop_process(process: subprocess.Popen[Any], timeout: float = 10.0) -> None:
    """SIGINT, then SIGTERM, then SIGKILL, until ``process`` has ended."""
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if process.poll() is not None:
            break
        process.send_signal(sig)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            continue
    for stream in (process.stdout, process.stderr):
        if stream is not None:
            stream.close()


class FakeRobot:
    """The robot's side, with rospy in this process: publishes a pose (PoseStamped), camera frames
    (Image or CompressedImage) and utterances (String), sends queries and collects answers and the
    latched markers.

    Needs ``ROS_MASTER_URI`` / ``ROS_IP`` in the environment before it is created (rospy reads them
    once per process: one master per process).
    """

    def __init__(self, pose_topic: str = "/global_pose", image_topic: str = "/camera/image",
                 speech_topic: str = "/speech", compressed: bool = False, name: str = "fake_robot") -> None:
        rospy = import_rospy()
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import CompressedImage, Image
        from std_msgs.msg import String
        from visualization_msgs.msg import MarkerArray

        from spco.ros.node import ANSWER_TOPIC, GOAL_TOPIC, MARKER_TOPIC, QUERY_TOPIC

        self.rospy = rospy
        if not rospy.core.is_initialized():
            rospy.init_node(name, anonymous=True, disable_signals=True, argv=sys.argv[:1])
        self._classes = {"PoseStamped": PoseStamped, "Image": Image, "CompressedImage": CompressedImage,
                         "String": String}
        self.compressed = compressed
        self.pose_pub = rospy.Publisher(pose_topic, PoseStamped, queue_size=10)
        self.image_pub = rospy.Publisher(image_topic, CompressedImage if compressed else Image, queue_size=2)
        self.speech_pub = rospy.Publisher(speech_topic, String, queue_size=10)
        self.query_pub = rospy.Publisher(QUERY_TOPIC, String, queue_size=100)
        self._lock = threading.Condition()
        self.answers: list[tuple[float, dict[str, Any]]] = []
        self.markers: list[tuple[float, Any]] = []
        self.goals: list[tuple[float, Any]] = []
        self._subs = [
            rospy.Subscriber(ANSWER_TOPIC, String, self._on_answer, queue_size=1000, tcp_nodelay=True),
            rospy.Subscriber(MARKER_TOPIC, MarkerArray, self._on_markers, queue_size=10, tcp_nodelay=True),
            rospy.Subscriber(GOAL_TOPIC, PoseStamped, self._on_goal, queue_size=10, tcp_nodelay=True),
        ]

    # ------------------------------------------------------------------ received
    def _on_answer(self, msg: Any) -> None:
        with self._lock:
            self.answers.append((time.perf_counter(), json.loads(msg.data)))
            self._lock.notify_all()

    def _on_markers(self, msg: Any) -> None:
        with self._lock:
            self.markers.append((time.perf_counter(), msg))
            self._lock.notify_all()

    def _on_goal(self, msg: Any) -> None:
        with self._lock:
            self.goals.append((time.perf_counter(), msg))
            self._lock.notify_all()

    def wait_for(self, predicate: Any, timeout: float = 10.0) -> Any:
        """Wait until ``predicate()`` returns something truthy (checked on every message); return it."""
        deadline = time.monotonic() + timeout
        with self._lock:
            while True:
                value = predicate()
                if value:
                    return value
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(f"nothing came within {timeout:g} s")
                self._lock.wait(min(remaining, 0.1))

    def wait_connected(self, timeout: float = 30.0) -> None:
        """Wait until the node subscribes to every topic this robot publishes and publishes its markers."""
        publishers = [self.pose_pub, self.image_pub, self.speech_pub, self.query_pub]
        deadline = time.monotonic() + timeout
        while any(p.get_num_connections() == 0 for p in publishers) or not self.markers:
            if time.monotonic() > deadline:
                missing = [p.resolved_name for p in publishers if p.get_num_connections() == 0]
                raise TimeoutError(f"the node did not connect within {timeout:g} s (no subscriber on "
                                   f"{', '.join(missing) or '-'}; markers received: {len(self.markers)})")
            time.sleep(0.05)

    # ------------------------------------------------------------------ sent
    def publish_pose(self, x: float, y: float, theta: float, frame: str = "map") -> None:
        """The robot's pose, stamped now."""
        msg = self._classes["PoseStamped"]()
        msg.header.stamp = self.rospy.Time.now()
        msg.header.frame_id = frame
        msg.pose.position.x, msg.pose.position.y = float(x), float(y)
        q = quaternion_from_yaw(theta)
        msg.pose.orientation.z, msg.pose.orientation.w = q["z"], q["w"]
        self.pose_pub.publish(msg)

    def publish_image(self, pixels: np.ndarray, encoding: str = "bgr8") -> None:
        """A camera frame: raw in ``encoding`` (rgb8, bgr8, mono8), or JPEG of the BGR ``pixels`` when the
        robot was made with ``compressed``."""
        if self.compressed:
            import cv2

            msg = self._classes["CompressedImage"]()
            msg.format = "jpeg"
            ok, data = cv2.imencode(".jpg", pixels, [cv2.IMWRITE_JPEG_QUALITY, 90])
            if not ok:
                raise SpcoError("the frame could not be encoded")
            msg.data = data.tobytes()
        else:
            msg = self._classes["Image"]()
            msg.height, msg.width = int(pixels.shape[0]), int(pixels.shape[1])
            msg.encoding = encoding
            msg.step = int(pixels.strides[0])
            msg.data = np.ascontiguousarray(pixels).tobytes()
        msg.header.stamp = self.rospy.Time.now()
        msg.header.frame_id = "head_rgbd_sensor_rgb_frame"
        self.image_pub.publish(msg)

    def say(self, sentence: str) -> float:
        """An utterance; returns the time it was sent (``time.perf_counter()``)."""
        sent = time.perf_counter()
        self.speech_pub.publish(self._classes["String"](data=sentence))
        return sent

    def query(self, request: Mapping[str, Any] | str, timeout: float = 10.0) -> tuple[dict[str, Any], float]:
        """Send a query (a dict with an ``id``, or raw text) and wait for the answer with its ``id`` (for raw
        text: the next answer); returns ``(answer, seconds from sending to receiving)``."""
        text = request if isinstance(request, str) else json.dumps(request)
        wanted = None if isinstance(request, str) else request.get("id")
        with self._lock:
            seen = len(self.answers)
        sent = time.perf_counter()
        self.query_pub.publish(self._classes["String"](data=text))

        def match() -> tuple[float, dict[str, Any]] | None:
            for t, answer in self.answers[seen:]:
                if answer.get("op") != "teach" and (wanted is None or answer.get("id") == wanted):
                    return t, answer
            return None

        t, answer = self.wait_for(match, timeout)
        return answer, t - sent

    def close(self) -> None:
        """Unregister this robot's publishers and subscribers."""
        for sub in self._subs:
            sub.unregister()
        for pub in (self.pose_pub, self.image_pub, self.speech_pub, self.query_pub):
            pub.unregister()
