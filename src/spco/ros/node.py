"""``spco ros HOME.spco``: the ROS 1 node, with rospy (see :mod:`spco.ros` and :mod:`spco.ros.core`).

Topics (names of the robot's topics are options; spco's own are fixed):

==========================  ===========================================  =========================
topic                       type                                         direction
==========================  ===========================================  =========================
``--pose-topic``            PoseWithCovarianceStamped, PoseStamped,      subscribed (type found
                            Odometry — or ``/tf`` + ``/tf_static``        from the publisher)
``--image-topic``           sensor_msgs/Image or CompressedImage         subscribed
``--speech-topic``          std_msgs/String                              subscribed
``/spco/query``             std_msgs/String (JSON)                       subscribed
``/spco/answer``            std_msgs/String (JSON)                       published
``/spco/goal``              geometry_msgs/PoseStamped (stamp 0)          published when asked
``/spco/where``             geometry_msgs/PoseArray                      published, latched
``/spco/markers``           visualization_msgs/MarkerArray               published, latched
==========================  ===========================================  =========================

The pose and image topics are subscribed as ``rospy.AnyMsg`` and decoded with the class their
publisher announces, so one option takes any of the accepted types. The goal's stamp is 0, which
move_base reads as "transform with the latest tf" (:func:`spco.ros.messages.goal_message`).
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Callable, Sequence
from typing import Any

from spco.ros import import_rospy
from spco.ros.core import (
    ANSWER_TOPIC,
    GOAL_TOPIC,
    MARKER_TOPIC,
    QUERY_TOPIC,
    WHERE_TOPIC,
    NodeCore,
    NodeSettings,
    Topics,
)

__all__ = ["message_to_dict", "run_node"]

#: Message types accepted on the pose and image topics (ROS 1 names).
POSE_TYPES = ("geometry_msgs/PoseWithCovarianceStamped", "geometry_msgs/PoseStamped", "nav_msgs/Odometry")
IMAGE_TYPES = ("sensor_msgs/Image", "sensor_msgs/CompressedImage")

log = logging.getLogger("spco.ros")


def message_to_dict(msg: Any) -> Any:
    """A rospy (genpy) message as nested dicts and lists, as rosbridge sends it: times as
    ``{"secs", "nsecs"}``, byte arrays (``uint8[]``) left as ``bytes``."""
    import genpy

    if isinstance(msg, genpy.TVal):
        return {"secs": int(msg.secs), "nsecs": int(msg.nsecs)}
    if isinstance(msg, genpy.Message):
        return {name: message_to_dict(getattr(msg, name)) for name in msg.__slots__}
    if isinstance(msg, list | tuple):
        return [message_to_dict(v) for v in msg]
    return msg


def _decoder(expected: tuple[str, ...], topic: str) -> Callable[[Any], dict[str, Any] | None]:
    """Turn a ``rospy.AnyMsg`` into a dict with the class its publisher announced."""
    import roslib.message

    classes: dict[str, Any] = {}
    refused: set[str] = set()

    def decode(raw: Any) -> dict[str, Any] | None:
        kind = raw._connection_header.get("type", "")
        if kind not in expected:
            if kind not in refused:
                refused.add(kind)
                log.error("%s carries %s; expected %s", topic, kind or "an unknown type",
                          " or ".join(expected))
            return None
        if kind not in classes:
            classes[kind] = roslib.message.get_message_class(kind)
        msg = classes[kind]()
        msg.deserialize(raw._buff)
        return message_to_dict(msg)

    return decode


def _filled(cls: Any, data: dict[str, Any]) -> Any:
    import genpy.message

    msg = cls()
    genpy.message.fill_message_args(msg, [data])
    return msg


def run_node(home: Any, topics: Topics, settings: NodeSettings, *, node_name: str = "spco",
             uses_images: bool = True, n_concepts: int = 10,
             ready: Callable[[NodeCore], None] | None = None,
             ros_arguments: Sequence[str] = (), echo: Callable[[str], None] = print) -> None:
    """Run the node until ROS shuts it down (Ctrl-C, ``rosnode kill``, the master gone).

    Parameters
    ----------
    home: the resident home (:class:`~spco.service.live.LiveHome`); not closed here.
    topics: the robot's topics; settings: :class:`~spco.ros.core.NodeSettings`.
    node_name: the node's name on the ROS graph.
    uses_images, n_concepts: see :class:`~spco.ros.core.NodeCore`.
    ready: called with the node's core once every topic is set up (the tests and benchmarks use it).
    ros_arguments: ROS remappings as on a node's command line (``/spco/query:=/robot/query``,
        ``__name:=spco2``, ``__ns:=``, ``__log:=``: what roslaunch passes); they win over ``node_name``
        and rename every topic, ``/spco/…`` included.
    echo: where the start-up line (the topics as remapped) and the last line go.

    ``ROS_MASTER_URI`` and ``ROS_IP`` (or ``ROS_HOSTNAME``) come from the environment, as for any
    ROS node: on a companion computer, the robot's master and this computer's own address.
    """
    rospy = import_rospy()
    from geometry_msgs.msg import PoseArray, PoseStamped
    from std_msgs.msg import String
    from tf2_msgs.msg import TFMessage
    from visualization_msgs.msg import MarkerArray

    # remappings (from:=to, __name:=, __ns:=, __log:=) as rospy reads a node's command line
    rospy.init_node(node_name, anonymous=False, argv=[*sys.argv[:1], *ros_arguments])
    answers = rospy.Publisher(ANSWER_TOPIC, String, queue_size=100)
    goals = rospy.Publisher(GOAL_TOPIC, PoseStamped, queue_size=10)
    markers = rospy.Publisher(MARKER_TOPIC, MarkerArray, queue_size=1, latch=True)
    poses = rospy.Publisher(WHERE_TOPIC, PoseArray, queue_size=1, latch=True)

    core = NodeCore(home, settings,
                    publish_answer=lambda d: answers.publish(String(data=d["data"])),
                    publish_goal=lambda d: goals.publish(_filled(PoseStamped, d)),  # stamp 0: latest tf
                    publish_markers=lambda d: markers.publish(_filled(MarkerArray, d)),
                    publish_poses=lambda d: poses.publish(_filled(PoseArray, d)),
                    now=lambda: rospy.get_rostime().to_sec(), uses_images=uses_images,
                    n_concepts=n_concepts)

    def received() -> float:
        return rospy.get_rostime().to_sec()

    def any_type(topic: str, expected: tuple[str, ...], handle: Callable[[dict[str, Any], float], None],
                 **options: Any) -> Any:
        """A subscriber of any of ``expected`` on ``topic``, decoded with the publisher's class."""
        decode = _decoder(expected, topic)

        def callback(raw: Any) -> None:
            msg = decode(raw)
            if msg is not None:
                handle(msg, received())

        return rospy.Subscriber(topic, rospy.AnyMsg, callback, tcp_nodelay=True, **options)

    query = rospy.Subscriber(QUERY_TOPIC, String, lambda m: core.on_query(m.data), queue_size=100,
                             tcp_nodelay=True)
    names = {"query": query.resolved_name, "pose": "/tf + /tf_static", "image": "(none)", "speech": "(none)"}
    subscribers = [query]
    if topics.speech:
        subscribers.append(rospy.Subscriber(topics.speech, String,
                                            lambda m: core.on_speech(m.data, received()), queue_size=100,
                                            tcp_nodelay=True))
        names["speech"] = subscribers[-1].resolved_name
    if topics.pose.strip("/") == "tf":
        subscribers.append(rospy.Subscriber("/tf", TFMessage,
                                            lambda m: core.on_tf(message_to_dict(m), False, received()),
                                            queue_size=100, tcp_nodelay=True))
        subscribers.append(rospy.Subscriber("/tf_static", TFMessage,
                                            lambda m: core.on_tf(message_to_dict(m), True, received()),
                                            queue_size=100, tcp_nodelay=True))
    else:
        subscribers.append(any_type(topics.pose, POSE_TYPES, core.on_pose, queue_size=100))
        names["pose"] = subscribers[-1].resolved_name
    if topics.image:  # a camera's frames are large: keep the newest few, never a backlog
        subscribers.append(any_type(topics.image, IMAGE_TYPES, core.on_image, queue_size=2, buff_size=2**24))
        names["image"] = subscribers[-1].resolved_name
    core.start()
    rospy.on_shutdown(core.stop)
    echo(f"spco ros: node {rospy.get_name()}; listening to pose {names['pose']}, image {names['image']}, "
         f"speech {names['speech']}; queries on {names['query']}, answers on {answers.resolved_name}, "
         f"markers on {markers.resolved_name}, where poses on {poses.resolved_name}, goals on "
         f"{goals.resolved_name} ({'every where' if settings.goal else 'when a query asks'})")
    if ready is not None:
        ready(core)
    rospy.spin()
    core.stop()
    echo(f"spco ros: stopped after {core.taught} teaching{'' if core.taught == 1 else 's'} and "
         f"{core.answered} answer{'' if core.answered == 1 else 's'}")
