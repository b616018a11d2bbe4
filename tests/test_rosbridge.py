"""`spco ros --rosbridge`: the node through a rosbridge server, with roslibpy, as for a ROS 2 robot.

No rosbridge server can be installed here, so the server is tests/fake_rosbridge.py: a small
WebSocket server written for the test that speaks rosbridge's protocol v2 (advertise, publish,
subscribe) and routes messages between the node and this test, which publishes what a ROS 2 robot's
rosbridge would send (ROS 2 stamps ``sec``/``nanosec``, image bytes as base64). What passes here was
not run against a real ROS 2 system.
"""

from __future__ import annotations

import base64
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from conftest import missing_tool
from ros_harness import SWAPPED_ROOM_COLOURS, free_port, stop_process, tour_pose

from spco.data.bagtour import view
from spco.ros.messages import quaternion_from_yaw

IMAGE = "/head_rgbd_sensor/rgb/image_rect_color/compressed"  # the HSR's head camera under ROS 2
SUBSCRIBED = ("/global_pose", IMAGE, "/speech", "/spco/query")


@pytest.fixture(scope="module")
def bridge(tmp_path_factory: pytest.TempPathFactory, tour_home_file: Path):
    for package, extra in (("roslibpy", "ros"), ("websockets", "test")):
        try:
            __import__(package)
        except ImportError:
            missing_tool(f"{package} is not installed (pip install -e '.[{extra}]')")
    from fake_rosbridge import FakeRosbridge

    folder = tmp_path_factory.mktemp("rosbridge")
    home = tour_home_file
    server = FakeRosbridge(free_port())
    log = open(folder / "node.log", "wb")  # closed below
    command = [sys.executable, "-m", "spco", "ros", str(home), "--rosbridge", server.url, "--pose-topic",
               "/global_pose", "--image-topic", IMAGE, "--speech-topic", "/speech"]
    node = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
    try:
        server.wait_for(lambda: all(server.subscribers.get(t) for t in SUBSCRIBED)
                        and server.published.get("/spco/markers"), timeout=90)
        yield server, node
    except BaseException:
        log.flush()
        print((folder / "node.log").read_text(errors="replace")[-3000:])
        raise
    finally:
        stop_process(node)
        log.close()
        server.close()


def _stamp() -> dict:
    now = time.time()
    return {"sec": int(now), "nanosec": int((now % 1) * 1e9)}


def _look(server: Any, distance: float, frames: int = 3, seed: int = 0) -> None:
    x, y, theta = tour_pose(distance)
    image = view(x, y, theta, (320, 240), np.random.default_rng(seed), SWAPPED_ROOM_COLOURS)
    ok, jpeg = cv2.imencode(".jpg", image)
    assert ok
    for _ in range(frames):
        server.publish("/global_pose", {"header": {"stamp": _stamp(), "frame_id": "map"},
                                        "pose": {"pose": {"position": {"x": x, "y": y, "z": 0.0},
                                                          "orientation": quaternion_from_yaw(theta)},
                                                 "covariance": [0.0] * 36}})
        server.publish(IMAGE, {"header": {"stamp": _stamp(), "frame_id": "head_rgbd_sensor_rgb_frame"},
                               "format": "jpeg", "data": base64.b64encode(jpeg.tobytes()).decode()})
        time.sleep(0.03)
    time.sleep(0.1)


def _query(server: Any, request: dict | str, timeout: float = 10.0) -> dict:
    seen = len(server.messages("/spco/answer"))
    server.publish("/spco/query", {"data": request if isinstance(request, str) else json.dumps(request)})

    def answer() -> dict | None:
        for msg in server.messages("/spco/answer")[seen:]:
            data = json.loads(msg["data"])
            if data.get("op") != "teach":
                return data
        return None

    return server.wait_for(answer, timeout)


def test_advertises_spco_topics_and_latches_the_markers(bridge) -> None:
    server, _ = bridge
    assert server.advertised["/spco/markers"] == {"type": "visualization_msgs/MarkerArray", "latch": True}
    assert server.advertised["/spco/answer"]["type"] == "std_msgs/String"
    assert server.advertised["/spco/goal"]["type"] == "geometry_msgs/PoseStamped"
    markers = server.latched["/spco/markers"]["markers"]
    assert markers[0]["action"] == 3 and {m["header"]["frame_id"] for m in markers} == {"map"}
    text = "\n".join(m.get("text", "") for m in markers)
    assert all(name in text for name in ("kitchen", "living room", "bedroom"))


def test_queries_over_rosbridge(bridge) -> None:
    server, node = bridge
    answer = _query(server, {"id": 21, "op": "where", "name": "bedroom", "n": 4})
    assert answer["id"] == 21 and len(answer["positions"]) == 4 and not server.messages("/spco/goal")
    answer = _query(server, {"id": 22, "op": "where", "name": "kitchen", "goal": True})
    goal = server.wait_for(lambda: server.messages("/spco/goal"))[-1]
    assert goal["header"]["frame_id"] == "map" and goal["pose"]["position"]["x"] == answer["goal"]["x"]
    _look(server, 10.0)
    answer = _query(server, {"id": 23, "op": "what"})
    assert answer["id"] == 23 and answer["vision"] is True and answer["names"][0]["name"] == "bedroom"
    answer = _query(server, "{'id': 24}")
    assert answer["id"] is None and "not JSON" in answer["error"] and node.poll() is None


def test_an_utterance_is_taught_over_rosbridge(bridge) -> None:
    server, _ = bridge
    markers = len(server.messages("/spco/markers"))
    answers = len(server.messages("/spco/answer"))
    _look(server, 6.0, frames=1)
    server.publish("/speech", {"data": "this is the lounge"})
    _look(server, 6.0, frames=5, seed=1)

    def taught() -> dict | None:
        for msg in server.messages("/spco/answer")[answers:]:
            data = json.loads(msg["data"])
            if data.get("op") == "teach":
                return data
        return None

    answer = server.wait_for(taught, timeout=20)
    assert "error" not in answer and answer["new_words"] == ["lounge"] and answer["x"] == pytest.approx(6.0)
    server.wait_for(lambda: len(server.messages("/spco/markers")) > markers)
    where = _query(server, {"id": 25, "op": "where", "name": "lounge", "n": 3})
    best = max(where["positions"], key=lambda p: p["probability"])
    assert "error" not in where and 3.5 <= best["x"] <= 8.5  # where it was said: the living room
