"""``spco ros HOME.spco --rosbridge ws://HOST:9090``: the node for ROS 2 (or ROS 1) robots, through a
rosbridge server, with roslibpy.

The same topics and messages as the ROS 1 node (:mod:`spco.ros.node`), over rosbridge's JSON
protocol (v2: ``advertise``, ``publish``, ``subscribe``): the robot runs ``rosbridge_server``
(ROS 2: ``ros2 launch rosbridge_server rosbridge_websocket_launch.xml``), spco runs anywhere that
reaches its port. Subscriptions name no type unless one is given (``--pose-type``,
``--image-type``): rosbridge then takes the type the topic has on the robot, and the node tells
the pose and image messages apart by their fields. Times are the times messages arrive
(``--clock receive``, the default), so the robot's clock does not matter.
"""

from __future__ import annotations

import logging
import signal
import threading
import time
from collections.abc import Callable
from typing import Any

from spco.errors import SpcoError
from spco.ros.core import ANSWER_TOPIC, GOAL_TOPIC, MARKER_TOPIC, QUERY_TOPIC, NodeCore, NodeSettings, Topics

__all__ = ["RosbridgeError", "run_rosbridge"]

log = logging.getLogger("spco.ros")


class RosbridgeError(SpcoError, ConnectionError):
    """The rosbridge server cannot be reached, or roslibpy is missing."""


def _roslibpy() -> Any:
    try:
        import roslibpy
    except ImportError:
        raise RosbridgeError("roslibpy is not installed: pip install 'spco[ros]' (or pip install roslibpy)") \
            from None
    return roslibpy


def _connect(roslibpy: Any, url: str, timeout: float) -> Any:
    """A ``roslibpy.Ros`` connected to the rosbridge server at ``url`` (a :class:`RosbridgeError` when
    the URL is not a WebSocket URL or the server does not answer within ``timeout`` seconds)."""
    if not url.startswith(("ws://", "wss://")):
        raise RosbridgeError(f"--rosbridge takes a WebSocket URL such as ws://robot:9090, got {url!r}")
    ros = roslibpy.Ros(url)
    try:
        ros.run(timeout=timeout)
    except Exception as exc:
        raise RosbridgeError(f"cannot reach the rosbridge server at {url} within {timeout:g} s "
                             f"({exc or type(exc).__name__}); is rosbridge_server running on the robot, "
                             "and is its port reachable from here?") from None
    return ros


def run_rosbridge(home: Any, url: str, topics: Topics, settings: NodeSettings, *,
                  pose_type: str | None = None, image_type: str | None = None, uses_images: bool = True,
                  n_concepts: int = 10,
                  connect_timeout: float = 10.0, stop: threading.Event | None = None,
                  ready: Callable[[NodeCore], None] | None = None) -> None:
    """Run the node through the rosbridge server at ``url`` until ``stop`` is set (or SIGINT/SIGTERM).

    Parameters
    ----------
    home: the resident home (:class:`~spco.service.live.LiveHome`); not closed here.
    url: ``ws://HOST:PORT`` (``wss://`` for TLS).
    topics, settings: as for :func:`spco.ros.node.run_node`.
    pose_type, image_type: the topics' types when the server should not look them up (e.g.
        ``geometry_msgs/msg/PoseStamped``); default: the types the topics have on the robot.
    uses_images, n_concepts: see :class:`~spco.ros.core.NodeCore`.
    connect_timeout: seconds to wait for the server; a :class:`RosbridgeError` after that.
    stop: an event that ends the node (default: a new one, set by SIGINT and SIGTERM).
    ready: called with the node's core once every topic is set up.
    """
    roslibpy = _roslibpy()
    ros = _connect(roslibpy, url, connect_timeout)
    stop = stop or threading.Event()
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: stop.set())

    answers = roslibpy.Topic(ros, ANSWER_TOPIC, "std_msgs/String", queue_size=100)
    goals = roslibpy.Topic(ros, GOAL_TOPIC, "geometry_msgs/PoseStamped")
    markers = roslibpy.Topic(ros, MARKER_TOPIC, "visualization_msgs/MarkerArray", latch=True, queue_size=1)
    for topic in (answers, goals, markers):
        topic.advertise()
    core = NodeCore(home, settings,
                    publish_answer=lambda d: answers.publish(roslibpy.Message(d)),
                    publish_goal=lambda d: goals.publish(roslibpy.Message(d)),
                    publish_markers=lambda d: markers.publish(roslibpy.Message(d)),
                    now=time.time, uses_images=uses_images, n_concepts=n_concepts)

    subscriptions = [roslibpy.Topic(ros, QUERY_TOPIC, "std_msgs/String")]
    subscriptions[0].subscribe(lambda m: core.on_query(m.get("data", "")))
    if topics.speech:
        speech = roslibpy.Topic(ros, topics.speech, "std_msgs/String")
        speech.subscribe(lambda m: core.on_speech(m.get("data", ""), time.time()))
        subscriptions.append(speech)
    if topics.pose.strip("/") == "tf":
        for name, static in (("/tf", False), ("/tf_static", True)):
            tf = roslibpy.Topic(ros, name, "tf2_msgs/TFMessage")
            tf.subscribe(lambda m, s=static: core.on_tf(m, s, time.time()))
            subscriptions.append(tf)
    else:
        pose = roslibpy.Topic(ros, topics.pose, pose_type)
        pose.subscribe(lambda m: core.on_pose(m, time.time()))
        subscriptions.append(pose)
    if topics.image:
        image = roslibpy.Topic(ros, topics.image, image_type, queue_length=1)
        image.subscribe(lambda m: core.on_image(m, time.time()))
        subscriptions.append(image)
    core.start()
    log.info("spco ros: connected to %s; listening to pose %s, image %s, speech %s", url, topics.pose,
             topics.image or "(none)", topics.speech or "(none)")
    if ready is not None:
        ready(core)
    try:
        while not stop.wait(0.2):
            pass
    finally:
        core.stop()
        for topic in subscriptions:
            topic.unsubscribe()
        try:
            ros.close(timeout=2.0)
        except Exception:  # the server may be gone already
            log.debug("rosbridge connection closed with an error", exc_info=True)
        ros.terminate()
