"""The node without a robot: a ROS master on this computer, ``spco ros`` in its own process, and
a stand-in for the robot (rospy publishers and subscribers) — what the tests (through
``conftest.py``) and ``benchmarks/ros_latency.py`` use.

The processes talk over loopback as a companion computer talks to a robot over its network:
``ROS_MASTER_URI`` names the master, ``ROS_IP`` each process's own address.
"""

from __future__ import annotations

import json
import math
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

__all__ = [
    "MALFORMED_QUERIES",
    "SWAPPED_ROOM_COLOURS",
    "FakeRobot",
    "Mailbox",
    "free_port",
    "reserve_ros_domain",
    "ros_environment",
    "start_master",
    "start_node",
    "stop_process",
    "tour_home",
    "tour_pose",
]


def free_port() -> int:
    """A TCP port free on the loopback interface now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


#: Queries the node must answer with an error on the answer topic, and stay up — the same for every
#: transport (ROS 1, ROS 2): (the query: a JSON object, or a text sent as is; the id the error answer
#: echoes; a part of its error message).
MALFORMED_QUERIES: list[tuple[Any, Any, str]] = [
    ("not json", None, "not JSON"),
    ("[1, 2]", None, "must be a JSON object"),
    ({"id": 1, "op": "fly"}, 1, "unknown op 'fly'"),
    ({"id": 2, "op": "where"}, 2, "has no 'name'"),
    ({"id": 3, "op": "where", "name": "kitchen", "n": "ten"}, 3, "'n' must be an integer"),
    ({"id": 4, "op": "where", "name": "kichen"}, 4, "kichen"),
    ({"id": 5, "op": "what", "x": 1.0}, 5, "give all of 'x', 'y' and 'theta'"),
    ({"id": 6, "op": "what", "x": 1.0, "y": 1.0, "theta": 90.0}, 6, "radians"),
    ({"id": 7, "op": "where", "name": "kitchen", "goal": "yes"}, 7, "'goal' must be true or false"),
]

_DOMAIN_LOCKS: dict[int, Any] = {}


def reserve_ros_domain(low: int = 1, high: int = 101, first: int | None = None) -> int:
    """A ``ROS_DOMAIN_ID`` in ``low..high`` that no other spco test or benchmark run on this machine
    holds, reserved until this process exits (an exclusive ``flock`` on
    ``<tmp>/spco-ros2-domain-N.lock``; the same id again on later calls).

    Concurrent runs in the same domain see each other's nodes and robots (the same ``/spco`` names):
    each node then answers the other robot's queries and takes its camera frames — wrong answers and
    latencies that are not the node's. The search starts at ``first`` (default: an id drawn from the
    process id) and takes the first free one. Raises ``RuntimeError`` when every id is held.
    """
    import fcntl
    import tempfile

    if _DOMAIN_LOCKS:
        return next(iter(_DOMAIN_LOCKS))
    span = high - low + 1
    start = (os.getpid() if first is None else first - low) % span
    for k in range(span):
        domain = low + (start + k) % span
        handle = (Path(tempfile.gettempdir()) / f"spco-ros2-domain-{domain}.lock").open("a")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        _DOMAIN_LOCKS[domain] = handle  # kept open: the lock lasts as long as this process
        return domain
    raise RuntimeError(f"every ROS 2 domain {low}..{high} is held by another spco test or benchmark run")


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


class Mailbox:
    """What a stand-in received, guarded by one condition (``self._lock``, notified on every message),
    and :meth:`wait_for` to wait for something in it."""

    def __init__(self) -> None:
        self._lock = threading.Condition()

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


class FakeRobot(Mailbox):
    """The robot's side, with rospy in this process: publishes a pose (PoseStamped), camera frames
    (Image or CompressedImage) and utterances (String), sends queries and collects answers and the
    latched markers.

    Needs ``ROS_MASTER_URI`` / ``ROS_IP`` in the environment before it is created (rospy reads them
    once per process: one master per process).
    """

    def __init__(self, pose_topic: str = "/global_pose", image_topic: str = "/camera/image",
                 speech_topic: str = "/speech", compressed: bool = False, name: str = "fake_robot") -> None:
        super().__init__()
        rospy = import_rospy()
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import CompressedImage, Image
        from std_msgs.msg import String
        from visualization_msgs.msg import MarkerArray

        from spco.ros.core import ANSWER_TOPIC, GOAL_TOPIC, MARKER_TOPIC, QUERY_TOPIC

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


#: Room colours (BGR) for a home where the colour order of a frame matters: the kitchen orange, the
#: living room green, the bedroom the kitchen's colour with red and blue swapped — an RGB frame of the
#: kitchen read as BGR looks like the bedroom.
SWAPPED_ROOM_COLOURS = ((40, 160, 230), (60, 200, 80), (230, 160, 40))

#: The tour's lap (metres): along y = 1 m from x = 0 to 12 facing +x, back along y = 3 m facing −x.
LAP_METRES = 24.0


def tour_pose(distance: float) -> tuple[float, float, float]:
    """``(x, y, θ)`` of the robot ``distance`` metres into a lap of the tour of
    :mod:`spco.data.bagtour` (kitchen, living room, bedroom along x)."""
    lap = distance % LAP_METRES
    return (lap, 1.0, 0.0) if lap < 12.0 else (LAP_METRES - lap, 3.0, math.pi)


def _tour_environment(name: str, seed: int, taught_every: int, size: tuple[int, int],
                      extractor: Any, colours: Sequence[tuple[int, int, int]] | None) -> Any:
    from spco.data.bagtour import ROOMS, room_at, view
    from spco.data.environment import Environment

    rng = np.random.default_rng(seed)
    poses, sentences, images = [], [], []
    for k, distance in enumerate(np.arange(0.15, LAP_METRES, 0.3)):
        x, y, theta = tour_pose(float(distance))
        x, y = x + rng.normal(0, 0.05), y + rng.normal(0, 0.05)
        poses.append([x, y, math.sin(theta), math.cos(theta)])
        images.append(view(x, y, theta, size, rng, colours))
        said = taught_every > 0 and k % taught_every == 0
        sentences.append(f"this is the {ROOMS[room_at(x)][0]}" if said else None)
    n = len(poses)
    visual = extractor.extract_many(images, jobs=1, encoding="bgr8")  # bagtour.view draws in BGR
    return Environment(name=name, ids=np.arange(n), positions=np.asarray(poses), sentences=tuple(sentences),
                       visual=visual, is_test=np.zeros(n, dtype=bool), extent=(-0.5, 12.5, 0.0, 4.0))


def tour_home(folder: str | os.PathLike[str], seed: int = 0, experienced: int = 3, taught_every: int = 4,
              new_taught_every: int = 0, iterations: int = 60, size: tuple[int, int] = (160, 120),
              colours: Sequence[tuple[int, int, int]] | None = None) -> Path:
    """A home file to run the node on, made as a robot would: ``experienced`` tours of the three-room
    home of :mod:`spco.data.bagtour` (80 samples each, "this is the <room>" at every
    ``taught_every``-th, views drawn by :func:`spco.data.bagtour.view`, ``colour-hog`` features),
    a knowledge fitted on them, and a new tour adapted with it (taught at every
    ``new_taught_every``-th sample; 0: nothing taught); ``colours``: the rooms' colours (BGR; default
    those of :data:`spco.data.bagtour.ROOMS`). Writes ``folder/home.spco`` and returns it.
    """
    from spco.data.environment import Corpus
    from spco.features import DEFAULT_EXTRACTOR, build_extractor
    from spco.knowledge import adapt, fit_knowledge

    extractor = build_extractor(DEFAULT_EXTRACTOR)
    homes = [_tour_environment(f"tour{k}", seed * 100 + k, taught_every, size, extractor, colours)
             for k in range(experienced)]
    knowledge = fit_knowledge(Corpus(homes), n_iterations=iterations, random_state=seed, extractor=extractor)
    new = _tour_environment("new_tour", seed * 100 + 99, new_taught_every, size, extractor, colours)
    home = adapt(knowledge, new, n_iterations=max(iterations // 2, 10), random_state=seed)
    out = Path(folder) / "home.spco"
    home.save(out, overwrite=True)
    return out
