"""spco on a running robot: a ROS 2 node (rclpy), a ROS 1 node (rospy), a rosbridge client (roslibpy),
and the home for Foxglove (foxglove-sdk).

``spco ros2 HOME.spco`` (:mod:`spco.ros.ros2`, its rclpy side in :mod:`spco.ros.thin`) and ``spco ros
HOME.spco`` (:mod:`spco.ros.node`) run the same core; each learns from what the robot hears and
answers questions on topics (the ROS 1 node's names below; the ROS 2 node's in docs/ros.md):

- it subscribes the robot's pose (``PoseWithCovarianceStamped``, ``PoseStamped``, ``Odometry`` or
  ``/tf`` from the map frame to the robot's), its camera (``Image`` or ``CompressedImage``) and
  speech as text (``std_msgs/String``); each utterance is taught at the pose and camera frame
  nearest in time (:mod:`spco.ros.core`), durably, through the same journal as ``spco serve``;
- it answers JSON queries on ``/spco/query`` on ``/spco/answer`` (and, when asked, publishes a
  navigation goal on ``/spco/goal``);
- it publishes the learnt regions as a latched ``visualization_msgs/MarkerArray`` on
  ``/spco/markers`` (:mod:`spco.ros.messages`), for RViz and Foxglove.

Modules: :mod:`spco.ros.messages` (ROS messages as plain dicts, both ways; markers; no ROS
needed), :mod:`spco.ros.core` (the node's logic, for every transport), :mod:`spco.ros.ros2` and
:mod:`spco.ros.thin` (rclpy), :mod:`spco.ros.node` (rospy), :mod:`spco.ros.rosbridge` (roslibpy),
:mod:`spco.ros.foxglove` (Foxglove's WebSocket and MCAP). A ROS master, the node in its own process and a
stand-in robot, for the tests and ``benchmarks/ros_latency.py``, are in the repository's
``tests/ros_harness.py``.

rospy and the message packages are not pip packages: they come with the Linux distribution (Debian
12: ``apt-get install python3-rospy python3-rosmaster python3-catkin python3-std-msgs
python3-geometry-msgs python3-sensor-msgs python3-nav-msgs python3-visualization-msgs
python3-tf2-msgs``) or a ROS
installation (``/opt/ros/noetic``). :func:`import_rospy` finds them from a virtual environment
(see its docstring).
"""

from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path
from types import ModuleType

from spco.errors import SpcoError

__all__ = ["ROS2_MESSAGE_MODULES", "ROS_PYTHON_DIRS", "RosUnavailableError", "import_rclpy", "import_rospy"]

#: Where ROS 1's Python packages live when they are not on ``sys.path`` already: ``$SPCO_ROS_PYTHONPATH``
#: (colon-separated) first, then a ROS Noetic installation, then Debian's packages.
ROS_PYTHON_DIRS = ("/opt/ros/noetic/lib/python3/dist-packages", "/usr/lib/python3/dist-packages")

#: The Debian 12 packages the ROS 1 node needs.
DEBIAN_PACKAGES = ("python3-rospy", "python3-rosmaster", "python3-catkin", "python3-std-msgs",
                   "python3-geometry-msgs", "python3-sensor-msgs", "python3-nav-msgs",
                   "python3-visualization-msgs", "python3-tf2-msgs")

#: The ROS 2 message packages the ROS 2 node needs (tf2_msgs only for poses from /tf).
ROS2_MESSAGE_MODULES = ("std_msgs.msg", "geometry_msgs.msg", "sensor_msgs.msg", "nav_msgs.msg",
                        "visualization_msgs.msg", "rcl_interfaces.msg")

_MESSAGE_MODULES = ("std_msgs.msg", "geometry_msgs.msg", "sensor_msgs.msg", "nav_msgs.msg",
                    "visualization_msgs.msg", "tf2_msgs.msg")


class RosUnavailableError(SpcoError, ImportError):
    """rospy or a message package cannot be imported."""


def _import_messages(modules: tuple[str, ...], ros: str, install: str) -> None:
    """Import the message modules ``modules`` (``"std_msgs.msg"``, ...) of ``ros`` ("ROS", "ROS 2");
    raise :class:`RosUnavailableError` naming the first missing package and how to install it
    (``install`` followed by the package's name with dashes, e.g. ``std-msgs``)."""
    for name in modules:
        package = name.split(".")[0]
        try:
            importlib.import_module(name)
        except ImportError as exc:
            raise RosUnavailableError(f"the {ros} message package {package} is missing ({exc}); "
                                      f"{install}{package.replace('_', '-')}") from None


def import_rospy() -> ModuleType:
    """Import rospy and the message packages the node uses; return the ``rospy`` module.

    A virtual environment does not see the system's Python packages. When ``import rospy`` fails,
    the directories of ``$SPCO_ROS_PYTHONPATH`` (colon-separated) and then :data:`ROS_PYTHON_DIRS`
    that hold a ``rospy`` package are **appended** to ``sys.path`` — after the environment's own
    packages, so the environment's NumPy, OpenCV etc. are the ones used — and the import is tried
    again. Nothing is added when rospy imports as it is (a sourced ROS setup, or ``PYTHONPATH``).

    Raises :class:`RosUnavailableError` with the install line when rospy or a message package is
    missing.
    """
    try:
        rospy = importlib.import_module("rospy")
    except ImportError:
        extra = [d for d in os.environ.get("SPCO_ROS_PYTHONPATH", "").split(os.pathsep) if d]
        for directory in [*extra, *ROS_PYTHON_DIRS]:
            if (Path(directory) / "rospy").is_dir() and directory not in sys.path:
                sys.path.append(directory)
        try:
            rospy = importlib.import_module("rospy")
        except ImportError as exc:
            raise RosUnavailableError(
                f"rospy is not installed ({exc}); on Debian 12: sudo apt-get install "
                f"{' '.join(DEBIAN_PACKAGES)} (or point SPCO_ROS_PYTHONPATH at a ROS installation's "
                "lib/python3/dist-packages)") from None
    _import_messages(_MESSAGE_MODULES, "ROS", "on Debian 12: sudo apt-get install python3-")
    return rospy


def import_rclpy() -> ModuleType:
    """Import rclpy and the ROS 2 message packages the node uses; return the ``rclpy`` module.

    rclpy is a compiled extension built for one Python: the ROS installation's (``source
    /opt/ros/jazzy/setup.bash`` puts it on ``PYTHONPATH``; Jazzy's is Python 3.12). Raises
    :class:`RosUnavailableError` naming what to do when it cannot be imported — including on a
    Python other than the installation's (Humble's 3.10: ``spco ros2 --ros-python`` runs
    :mod:`spco.ros.thin` with it instead).
    """
    try:
        rclpy = importlib.import_module("rclpy")
    except ImportError as exc:
        raise RosUnavailableError(
            f"rclpy cannot be imported by Python {sys.version_info.major}.{sys.version_info.minor} ({exc}): "
            "source the ROS 2 installation first (source /opt/ros/jazzy/setup.bash; Jazzy's rclpy is for "
            "Python 3.12, so run spco from a Python 3.12 environment made with --system-site-packages); "
            "on Humble (Python 3.10) give spco ros2 --ros-python /usr/bin/python3 to run the ROS 2 side "
            "with the robot's Python (docs/ros.md)") from None
    _import_messages(ROS2_MESSAGE_MODULES, "ROS 2", "install ros-<distro>-")
    return rclpy
