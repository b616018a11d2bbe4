"""``spco ros2 HOME.spco``: the node for ROS 2 (Humble, Jazzy): the node's core
(:class:`spco.ros.core.NodeCore`, the same as the ROS 1 node's) on the ROS 2 graph through
:mod:`spco.ros.thin` (rclpy: parameters, topics, QoS, messages).

Two ways to run, the same node on the graph:

- **in process** (the default): spco's own Python imports rclpy — a Jazzy robot's (Python 3.12,
  ``source /opt/ros/jazzy/setup.bash`` and a Python 3.12 environment for spco);
- **relayed** (``--ros-python /usr/bin/python3``): the ROS 2 side runs in a child process of the
  robot's Python (:func:`spco.ros.thin.relay_main`, which needs nothing of spco), and spco keeps the
  core in its own Python, relaying over the child's stdin and stdout — for a Humble robot, whose
  rclpy is for Python 3.10 while spco needs 3.11 or later.

See :mod:`spco.ros.thin` for the parameters, names and QoS.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from spco.errors import ConfigurationError, SpcoError
from spco.ros import RosUnavailableError, import_rclpy
from spco.ros.core import NodeCore, NodeSettings
from spco.ros.thin import ParameterError, Ros2Transport, read_frame, write_frame

__all__ = ["THIN_NODE", "run_ros2", "settings_of"]

log = logging.getLogger("spco.ros")

#: The ROS 2 side as a script for the robot's Python (``--ros-python``).
THIN_NODE = Path(__file__).with_name("thin.py")


def settings_of(values: Mapping[str, Any]) -> NodeSettings:
    """The :class:`NodeSettings` of the node's parameter values (raises ConfigurationError)."""
    wait = float(values["image_wait"])
    return NodeSettings(tolerance=float(values["tolerance"]), image_wait=None if wait < 0 else wait,
                        clock=str(values["clock"]), max_age=float(values["max_age"]),
                        goal=bool(values["goal"]),
                        map_frame=str(values["map_frame"]), robot_frame=str(values["robot_frame"]),
                        n=int(values["n"]), top=int(values["top"]))


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


class _CoreBackend:
    """The transport's messages handed to the core in this process."""

    def __init__(self) -> None:
        self.core: NodeCore | None = None
        self.settings: NodeSettings | None = None

    def check(self, values: Mapping[str, Any]) -> str | None:
        try:
            settings = settings_of(values)
        except (ConfigurationError, TypeError, ValueError) as exc:
            return str(exc)
        self.settings = settings
        if self.core is not None:
            self.core.settings = settings
        return None

    def pose(self, msg: dict[str, Any], received: float) -> None:
        assert self.core is not None
        self.core.on_pose(msg, received)

    def tf(self, msg: dict[str, Any], static: bool, received: float) -> None:
        assert self.core is not None
        self.core.on_tf(msg, static, received)

    def image(self, msg: dict[str, Any], received: float) -> None:
        assert self.core is not None
        self.core.on_image(msg, received)

    def speech(self, text: str, received: float) -> None:
        assert self.core is not None
        self.core.on_speech(text, received)

    def query(self, text: str) -> None:
        assert self.core is not None
        self.core.on_query(text)


def _signals(stop: threading.Event) -> dict[int, Any]:
    previous: dict[int, Any] = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, lambda *_: stop.set())
    return previous


def run_ros2(home: Any, *, ros_arguments: Sequence[str] = (), node_name: str = "spco",
             uses_images: bool = True, n_concepts: int = 10, ros_python: str | None = None,
             stop: threading.Event | None = None,
             ready: Callable[[NodeCore, Mapping[str, str]], None] | None = None,
             echo: Callable[[str], None] = print) -> dict[str, int]:
    """Run the ROS 2 node until SIGINT/SIGTERM (or ``stop`` is set); return ``{"taught", "answered"}``.

    Parameters
    ----------
    home: the resident home (:class:`~spco.service.live.LiveHome`); not closed here.
    ros_arguments: ROS 2 arguments (``--ros-args -p tolerance:=1.0 -r __node:=spco2 …``).
    node_name: the node's name unless remapped (``-r __node:=…``).
    uses_images, n_concepts: see :class:`~spco.ros.core.NodeCore`.
    ros_python: run the ROS 2 side with this Python (the robot's, whose rclpy it imports) in a
        child process; ``None``: in this process.
    stop: an event that ends the node (default: set by SIGINT and SIGTERM).
    ready: called with the core and the node's resolved names once it is set up.
    echo: where the start-up and last lines go.

    ``ROS_DOMAIN_ID`` and ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (Jazzy) or ``ROS_LOCALHOST_ONLY`` (Humble)
    come from the environment, as for any ROS 2 node.
    """
    stop = stop or threading.Event()
    if ros_python is not None:
        return _run_relayed(home, ros_python, ros_arguments, node_name, uses_images, n_concepts, stop, ready,
                            echo)
    import_rclpy()
    backend = _CoreBackend()
    try:
        transport = Ros2Transport(backend, ros_arguments, node_name=node_name, echo=echo)
    except ParameterError as exc:
        raise ConfigurationError(str(exc)) from None
    assert backend.settings is not None
    core = NodeCore(home, backend.settings, publish_answer=transport.publish_answer,
                    publish_goal=transport.publish_goal, publish_markers=transport.publish_markers,
                    publish_poses=transport.publish_poses, now=transport.now, uses_images=uses_images,
                    n_concepts=n_concepts)
    backend.core = core
    previous = _signals(stop)
    try:
        core.start()
        if ready is not None:
            ready(core, transport.names)
        transport.spin(stop)
    finally:
        core.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        transport.close()
    counts = {"taught": core.taught, "answered": core.answered}
    echo(f"spco ros2: stopped after {_count(counts['taught'], 'teaching')} and "
         f"{_count(counts['answered'], 'answer')}")
    return counts


class _RelayClock:
    """The robot process's clock (ROS time) as last reported, advanced by this process's monotonic clock."""

    def __init__(self) -> None:
        self.robot = time.time()
        self.local = time.monotonic()

    def seen(self, robot_time: float) -> None:
        self.robot, self.local = robot_time, time.monotonic()

    def __call__(self) -> float:
        return self.robot + (time.monotonic() - self.local)


class _Relay:
    """This process's end of the pipe to the ROS 2 side (``ros_python`` running :data:`THIN_NODE`):
    frames to it (:meth:`send`), and a reader thread handing the robot's frames to the core."""

    def __init__(self, ros_python: str, ros_arguments: Sequence[str], node_name: str,
                 stop: threading.Event, echo: Callable[[str], None]) -> None:
        env = dict(os.environ, SPCO_ROS2_NODE_NAME=node_name)
        try:
            self.child = subprocess.Popen([ros_python, str(THIN_NODE), *ros_arguments], stdin=subprocess.PIPE,
                                          stdout=subprocess.PIPE, env=env, start_new_session=True)
        except OSError as exc:
            raise RosUnavailableError(f"--ros-python {ros_python}: cannot start it ({exc})") from None
        assert self.child.stdin is not None and self.child.stdout is not None
        self.to_child, self.lock = self.child.stdin, threading.Lock()
        self.ros_python, self.stop, self.echo = ros_python, stop, echo
        self.clock = _RelayClock()
        self.ready = threading.Event()
        self.settings: Any = None
        self.names: Mapping[str, str] = {}
        self.failed: str | None = None
        self.core: NodeCore | None = None

    def send(self, kind: str, msg: Mapping[str, Any]) -> None:
        """One frame to the ROS 2 side; a closed pipe stops the node."""
        with self.lock:
            try:
                write_frame(self.to_child, {"kind": kind, "msg": msg})
            except (BrokenPipeError, ValueError):
                self.stop.set()

    def start_reading(self) -> None:
        """Read the robot's frames in a daemon thread until the pipe closes."""
        threading.Thread(target=self._dispatch, name="spco-relay", daemon=True).start()

    def _dispatch(self) -> None:
        while True:
            frame = read_frame(self.child.stdout)  # type: ignore[arg-type]
            if frame is None:
                self.stop.set()
                return
            header, payload = frame
            kind = header.get("kind")
            if "received" in header:
                self.clock.seen(float(header["received"]))
            try:
                self._handle(kind, header, payload)
            except SpcoError:
                log.exception("spco ros2: a %s from the robot's process could not be used", kind)

    def _handle(self, kind: Any, header: dict[str, Any], payload: bytes) -> None:
        if kind == "check":
            self._check(header)
        elif kind == "started":
            self.echo(str(header["line"]))
        elif kind == "names":
            self.names = header["names"]
            self.ready.set()
        elif kind == "failed":
            self.failed = header["error"]
            self.ready.set()
        elif self.core is not None:
            self._to_core(self.core, kind, header, payload)

    def _check(self, header: dict[str, Any]) -> None:
        """Answer the ROS 2 side's parameter check; keep the settings it accepted."""
        try:
            settings = settings_of(header["values"])
            reason = None
        except (ConfigurationError, TypeError, ValueError, KeyError) as exc:
            reason, settings = str(exc), None
        if settings is not None:
            self.settings = settings
            if self.core is not None:
                self.core.settings = settings
        with self.lock:
            write_frame(self.to_child, {"kind": "checked", "ask": header.get("ask"), "reason": reason})

    @staticmethod
    def _to_core(core: NodeCore, kind: Any, header: dict[str, Any], payload: bytes) -> None:
        if kind == "query":
            core.on_query(header["text"])
        elif kind == "speech":
            core.on_speech(header["text"], header["received"])
        elif kind == "pose":
            core.on_pose(header["msg"], header["received"])
        elif kind == "tf":
            core.on_tf(header["msg"], bool(header["static"]), header["received"])
        elif kind == "image":
            core.on_image({**header["msg"], "data": payload}, header["received"])

    def wait_until_up(self) -> None:
        """Wait for the ROS 2 side's topic names; raise if it stops or fails first."""
        while not self.ready.wait(0.2):
            if self.stop.is_set() or self.child.poll() is not None:
                raise RosUnavailableError(
                    f"the ROS 2 side ({self.ros_python} {THIN_NODE.name}) stopped before it was up (exit "
                    f"code {self.child.poll()}): does that Python import rclpy? (source "
                    "/opt/ros/<distro>/setup.bash first)")
        if self.failed is not None:
            raise ConfigurationError(self.failed)

    def close(self) -> None:
        """Stop the core, tell the ROS 2 side to stop and wait for it (killed after 10 s)."""
        if self.core is not None:
            self.core.stop()
        with self.lock:
            try:
                write_frame(self.to_child, {"kind": "stop"})
                self.to_child.close()
            except (BrokenPipeError, ValueError, OSError):
                pass
        try:
            self.child.wait(10)
        except subprocess.TimeoutExpired:
            self.child.kill()
            self.child.wait()


def _run_relayed(home: Any, ros_python: str, ros_arguments: Sequence[str], node_name: str, uses_images: bool,
                 n_concepts: int, stop: threading.Event,
                 ready: Callable[[NodeCore, Mapping[str, str]], None] | None,
                 echo: Callable[[str], None]) -> dict[str, int]:
    """The core here, the ROS 2 side in ``ros_python`` running :data:`THIN_NODE`."""
    relay = _Relay(ros_python, ros_arguments, node_name, stop, echo)
    previous = _signals(stop)
    relay.start_reading()
    try:
        relay.wait_until_up()
        send = relay.send
        core = relay.core = NodeCore(
            home, relay.settings, publish_answer=lambda d: send("answer", d),
            publish_goal=lambda d: send("goal", d), publish_markers=lambda d: send("markers", d),
            publish_poses=lambda d: send("poses", d), now=relay.clock, uses_images=uses_images,
            n_concepts=n_concepts)
        core.start()
        if ready is not None:
            ready(core, relay.names)
        while not stop.wait(0.2):
            if relay.child.poll() is not None:
                break
    finally:
        relay.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    core = relay.core
    counts = {"taught": core.taught if core else 0, "answered": core.answered if core else 0}
    echo(f"spco ros2: stopped after {_count(counts['taught'], 'teaching')} and "
         f"{_count(counts['answered'], 'answer')}")
    return counts
