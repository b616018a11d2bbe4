"""`import_rospy` and `import_rclpy` name a missing message package and how to install it (no ROS
needed)."""

from __future__ import annotations

import types

import pytest

import spco.ros
from spco.ros import RosUnavailableError, import_rclpy, import_rospy


@pytest.mark.parametrize(("load", "ros", "missing", "install"), [
    (import_rospy, "ROS", "tf2_msgs.msg", "on Debian 12: sudo apt-get install python3-tf2-msgs"),
    (import_rclpy, "ROS 2", "rcl_interfaces.msg", "install ros-<distro>-rcl-interfaces"),
    (import_rclpy, "ROS 2", "std_msgs.msg", "install ros-<distro>-std-msgs"),
])
def test_a_missing_message_package_is_named_with_its_install(monkeypatch, load, ros, missing,
                                                              install) -> None:
    imported: list[str] = []

    def fake(name: str) -> types.ModuleType:
        if name == missing:
            raise ImportError(f"No module named {name!r}")
        imported.append(name)
        return types.ModuleType(name)

    monkeypatch.setattr(spco.ros.importlib, "import_module", fake)
    with pytest.raises(RosUnavailableError) as caught:
        load()
    package = missing.split(".")[0]
    assert str(caught.value) == (f"the {ros} message package {package} is missing (No module named "
                                 f"{missing!r}); {install}")
    assert missing not in imported and imported[0] in ("rospy", "rclpy")
