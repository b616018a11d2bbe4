"""``spco ros``: run a home on a robot's ROS network (see :mod:`spco.ros`).

Registered in :mod:`spco.cli.main`.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any

import click

from spco.cli.errors import friendly_errors
from spco.cli.limits import limits_from_options, teaching_limit_options

__all__ = ["ros", "ros2"]


def node_teaching_options(command: Any) -> Any:
    """``--sweeps``, ``--writer`` and ``--seed``: how a node (``spco ros``, ``spco ros2``) applies its
    teachings."""
    for option in reversed([
        click.option("--sweeps", default=10, show_default=True, type=click.IntRange(1, 1000),
                     help="Gibbs sweeps per teaching (as spco teach)."),
        click.option("--writer", type=click.Choice(["process", "thread"]), default="process",
                     show_default=True,
                     help="Where teachings are applied (spco.service.LiveHome): a writer process of their "
                          "own (the answers never wait for them), or a thread of the node."),
        click.option("--seed", default=0, show_default=True, type=int, help="Base seed of the teachings."),
    ]):
        command = option(command)
    return command


@click.command(name="ros", context_settings={"ignore_unknown_options": True})
@click.argument("home", type=click.Path(path_type=Path))
@click.argument("ros_arguments", nargs=-1, type=click.UNPROCESSED, metavar="[FROM:=TO ...]")
@click.option("--pose-topic", default="/tf", show_default=True,
              help="The robot's pose on the map: a PoseWithCovarianceStamped, PoseStamped or Odometry topic "
              "(HSR: /global_pose), or /tf (then --map-frame → --robot-frame).")
@click.option("--map-frame", default="map", show_default=True, help="The map's frame (poses, goal, markers).")
@click.option("--robot-frame", default="base_footprint", show_default=True,
              help="The robot's tf frame (with --pose-topic /tf).")
@click.option("--image-topic", default=None,
              help="The camera: sensor_msgs/Image (rgb8, bgr8, mono8, rgba8, bgra8) or CompressedImage "
              "(JPEG, PNG). HSR: /hsrb/head_rgbd_sensor/rgb/image_rect_color/compressed. "
              "Needed to teach a home whose views are images.")
@click.option("--speech-topic", default=None,
              help="What people say, as std_msgs/String text: each utterance is taught at the pose and "
              "frame nearest to it. Default: none (the node only answers queries).")
@click.option("--tolerance", default=0.5, show_default=True, type=float,
              help="Seconds an utterance's pose and camera frame may be from it (as import-bag's).")
@click.option("--image-wait", default=None, type=float,
              help="Seconds to wait after an utterance for a camera frame (default: the tolerance).")
@click.option("--clock", type=click.Choice(["receive", "header"]), default="receive", show_default=True,
              help="Times of messages: when they arrive (any clocks), or their header stamps (clocks in "
              "step).")
@click.option("--max-age", default=2.0, show_default=True, type=float,
              help="Seconds after which the last pose and frame are no longer the robot's current ones.")
@click.option("--goal/--no-goal", default=False, show_default=True,
              help="Publish a PoseStamped on /spco/goal with every where answer (else only when the query "
              'says "goal": true).')
@click.option("--rosbridge", default=None, metavar="ws://HOST:PORT",
              help="Connect to a rosbridge server (ROS 2, or ROS 1 without rospy here) instead of a ROS 1 "
              "master.")
@click.option("--pose-type", default=None, help="With --rosbridge: the pose topic's type, if the server "
              "should not look it up (e.g. geometry_msgs/msg/PoseStamped).")
@click.option("--image-type", default=None, help="With --rosbridge: the image topic's type.")
@click.option("--node-name", default="spco", show_default=True, help="The node's name (ROS 1).")
@node_teaching_options
@teaching_limit_options
@friendly_errors
def ros(home: Path, ros_arguments: tuple[str, ...], pose_topic: str, map_frame: str, robot_frame: str,
        image_topic: str | None,
        speech_topic: str | None, tolerance: float, image_wait: float | None, clock: str, max_age: float,
        goal: bool, rosbridge: str | None, pose_type: str | None, image_type: str | None, node_name: str,
        sweeps: int, writer: str, seed: int, undo_limit: int, **limit_options: int) -> None:
    """Run HOME (a home file, from spco adapt) as a node on the robot's ROS network: learn from what
    it hears, answer where/what queries, draw its places in RViz.

    Each utterance on --speech-topic is taught at the robot's pose and camera frame nearest to it
    in time and saved at once in HOME's journal (the same as spco serve's). Queries are JSON on
    /spco/query ({"id": 7, "op": "where", "name": "kitchen"}, {"id": 8, "op": "what"}); answers
    on /spco/answer echo the id. /spco/markers (latched MarkerArray, frame --map-frame) shows
    the learnt regions with their names; /spco/goal gets a PoseStamped when a where query asks
    ("goal": true) or with --goal.

    ROS 1: ROS_MASTER_URI and ROS_IP as for any node (rospy from the system: apt-get install
    python3-rospy …); ROS remappings after HOME as for any node, e.g. /spco/query:=/hsr/query or
    __name:=spco_kitchen (roslaunch adds __name:= and __log:=). ROS 2: --rosbridge ws://ROBOT:9090.
    """
    for argument in ros_arguments:
        if ":=" not in argument or argument.startswith(":=") or argument.startswith("-"):
            raise click.UsageError(f"unexpected argument {argument!r}: after HOME come only ROS remappings "
                                   "written FROM:=TO (e.g. /spco/query:=/robot/query, __name:=spco2)")
        if rosbridge is not None:
            raise click.UsageError(f"{argument!r}: ROS remappings are for a ROS 1 node, not --rosbridge")
    from spco.ros.core import NodeSettings, Topics
    from spco.service.live import LiveHome

    settings = NodeSettings(tolerance=tolerance, image_wait=image_wait, clock=clock, max_age=max_age,
                            goal=goal, map_frame=map_frame, robot_frame=robot_frame)
    topics = Topics(pose=pose_topic, image=image_topic, speech=speech_topic)
    _log_to_stderr()
    if rosbridge is None:
        from spco.ros import import_rospy

        import_rospy()  # before opening the home: a missing rospy is one clear error
    elif not rosbridge.startswith(("ws://", "wss://")):
        from spco.errors import ConfigurationError

        raise ConfigurationError(f"--rosbridge takes a WebSocket URL such as ws://robot:9090, got "
                                 f"{rosbridge!r}")
    where = rosbridge or os.environ.get("ROS_MASTER_URI", "http://localhost:11311 (ROS_MASTER_URI unset)")
    limits = limits_from_options(limit_options)
    with LiveHome(home, seed=seed, sweeps=sweeps, writer=writer, undo_limit=undo_limit, limits=limits,
                  holder=f"spco ros (process {os.getpid()})") as live:
        model = live.home
        uses_images = bool(model.knowledge.fitted_on_images)
        if uses_images and speech_topic and not image_topic:
            click.echo("warning: the views of this home are images and no --image-topic is given: utterances "
                       "cannot be taught", err=True)
        click.echo(f"spco ros: home {model.name} ({model.n_samples} samples, names: "
                   f"{', '.join(model.known_names) or 'none yet'}) on {where}", err=True)
        if rosbridge is not None:
            from spco.ros.rosbridge import run_rosbridge

            run_rosbridge(live, rosbridge, topics, settings, pose_type=pose_type, image_type=image_type,
                          uses_images=uses_images, n_concepts=model.knowledge.n_concepts)
        else:
            from spco.ros.node import run_node

            run_node(live, topics, settings, node_name=node_name, uses_images=uses_images,
                     n_concepts=model.knowledge.n_concepts, ros_arguments=ros_arguments,
                     echo=lambda line: click.echo(line, err=True))


@click.command(name="ros2", context_settings={"ignore_unknown_options": True, "allow_extra_args": True})
@click.argument("home", type=click.Path(path_type=Path))
@click.argument("ros_arguments", nargs=-1, type=click.UNPROCESSED, metavar="[--ros-args ...]")
@node_teaching_options
@click.option("--ros-python", default=None, metavar="PYTHON",
              help="Run the ROS 2 side with this Python (the robot's: /usr/bin/python3 after sourcing "
              "/opt/ros/humble/setup.bash) in a child process, relaying to spco here; default: rclpy in "
              "this process (Jazzy: Python 3.12).")
@friendly_errors
def ros2(home: Path, ros_arguments: tuple[str, ...], sweeps: int, writer: str, seed: int,
         ros_python: str | None) -> None:
    """Run HOME (a home file, from spco adapt) as a ROS 2 node (rclpy): learn from what the robot
    hears, answer where/what queries, draw its places in RViz2 and Foxglove, send Nav2 goals.

    Everything about ROS is set the ROS 2 way, after --ros-args: parameters (-p
    pose_topic:=/amcl_pose -p speech_topic:=/speech -p image_topic:=/camera/image_raw -p
    tolerance:=1.0, or --params-file spco.yaml; readable and settable with ros2 param) and
    remappings (-r __node:=spco_kitchen -r __ns:=/robot1 -r /spco/query:=/hsr/query). Queries are
    JSON on ~/query ({"id": 7, "op": "where", "name": "kitchen"}); answers on ~/answer echo the
    id; ~/markers (MarkerArray) and ~/where (PoseArray) are transient local; goal_pose gets a
    PoseStamped when a where query asks ("goal": true) or with -p goal:=true.

    rclpy comes from the robot's ROS 2 installation: source it first. Jazzy (Python 3.12): spco in
    a Python 3.12 environment imports it. Humble (Python 3.10, older than spco needs): --ros-python
    /usr/bin/python3 runs the ROS 2 side with the robot's Python, relaying to spco.
    """
    if ros_arguments and ros_arguments[0] != "--ros-args":
        raise click.UsageError(f"unexpected argument {ros_arguments[0]!r}: after HOME come only ROS 2 "
                               "arguments, starting with --ros-args "
                               "(e.g. --ros-args -p pose_topic:=/amcl_pose)")
    from spco.ros import import_rclpy
    from spco.service.live import LiveHome

    _log_to_stderr()
    if ros_python is None:
        import_rclpy()  # before opening the home: a missing rclpy is one clear error
    from spco.ros.ros2 import run_ros2

    with LiveHome(home, seed=seed, sweeps=sweeps, writer=writer,
                  holder=f"spco ros2 (process {os.getpid()})") as live:
        model = live.home
        uses_images = bool(model.knowledge.fitted_on_images)
        domain = os.environ.get("ROS_DOMAIN_ID", "0")
        click.echo(f"spco ros2: home {model.name} ({model.n_samples} samples, names: "
                   f"{', '.join(model.known_names) or 'none yet'}) on ROS_DOMAIN_ID {domain}", err=True)
        run_ros2(live, ros_arguments=ros_arguments, uses_images=uses_images, ros_python=ros_python,
                 n_concepts=model.knowledge.n_concepts, echo=lambda line: click.echo(line, err=True))


def _log_to_stderr() -> None:
    """The nodes' log (logger ``spco.ros``, INFO and above) as plain lines on standard error."""
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("%(message)s"))
    log = logging.getLogger("spco.ros")
    log.addHandler(handler)
    log.setLevel(logging.INFO)
