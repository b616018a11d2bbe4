"""The node's logic without ROS (spco.ros.core): which pose and camera frame an utterance is taught
with, waiting for a frame, poses from tf, and the answers — on a real LiveHome (thread writer)."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from ros_harness import SWAPPED_ROOM_COLOURS, tour_pose

from spco.data.bagtour import view
from spco.ros.core import NodeCore, NodeSettings
from spco.ros.messages import quaternion_from_yaw
from spco.service.live import LiveHome


class Clock:
    def __init__(self, t: float = 100.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


def _core(live: LiveHome, clock=time.time, **settings) -> tuple[NodeCore, dict[str, list]]:
    sent: dict[str, list] = {"answer": [], "goal": [], "markers": []}
    core = NodeCore(live, NodeSettings(**settings),
                    publish_answer=lambda d: sent["answer"].append(json.loads(d["data"])),
                    publish_goal=sent["goal"].append, publish_markers=sent["markers"].append, now=clock,
                    n_concepts=live.home.knowledge.n_concepts)
    return core, sent


def _pose_msg(x: float, y: float, theta: float, frame: str = "map") -> dict:
    return {"header": {"frame_id": frame}, "pose": {"position": {"x": x, "y": y, "z": 0.0},
                                                    "orientation": quaternion_from_yaw(theta)}}


def _image_msg(pixels: np.ndarray) -> dict:
    ok, data = cv2.imencode(".png", pixels)
    assert ok
    return {"header": {}, "format": "png", "data": data.tobytes()}


def _room_view(distance: float, seed: int = 0) -> np.ndarray:
    x, y, theta = tour_pose(distance)
    return view(x, y, theta, (160, 120), np.random.default_rng(seed), SWAPPED_ROOM_COLOURS)


def _taught_counts(live: LiveHome) -> np.ndarray:
    return live.home.visual[[live.home.n_samples - 1]].toarray()[0]


def test_the_nearest_pose_and_frame_within_the_tolerance_are_taught(tour_home_file: Path) -> None:
    clock = Clock()
    with LiveHome(tour_home_file, seed=0, writer="thread") as live:
        core, sent = _core(live, clock)
        extractor = live.home.knowledge.image_extractor()
        kitchen, bedroom = _room_view(2.0), _room_view(10.0)
        core.on_pose(_pose_msg(1.0, 1.0, 0.0), received=100.0)
        core.on_pose(_pose_msg(2.0, 1.0, 0.1), received=100.35)
        core.on_pose(_pose_msg(9.0, 1.0, 0.0, frame="odom"), received=100.3)  # another frame: ignored
        core.on_image(_image_msg(kitchen), received=100.0)
        core.on_image(_image_msg(bedroom), received=100.4)
        answer = core.teach_utterance(100.3, "this is the study")
        assert "error" not in answer, answer
        assert (answer["x"], answer["theta"]) == (2.0, pytest.approx(0.1))  # the pose 0.05 s away
        assert np.array_equal(_taught_counts(live), extractor.extract(bedroom, "bgr8"))  # 0.1 s away
        assert answer["op"] == "teach" and answer["sample"] == live.home.ids[-1] and answer["seq"] == 1
        assert len(sent["markers"]) == 1 and sent["markers"][0]["markers"][0]["action"] == 3
        # a camera at 0.5 Hz: a frame every 2 s, none within 0.5 s of an utterance between two
        core.on_image(_image_msg(kitchen), received=102.4)
        core.on_pose(_pose_msg(1.5, 1.0, 0.0), received=101.4)
        refused = core.teach_utterance(101.4, "this is the larder")
        assert "no camera frame within 0.5 s" in refused["error"]
        assert "the nearest frame is 1.00 s away" in refused["error"] and "--tolerance 1" in refused["error"]
        assert live.home.n_samples == 81  # not taught
        core.settings = NodeSettings(tolerance=1.0)
        answer = core.teach_utterance(101.4, "this is the larder")
        assert "error" not in answer and live.home.n_samples == 82
        refused = core.teach_utterance(200.0, "this is the hall")
        assert "no pose within 1 s" in refused["error"]


def test_an_utterance_waits_for_the_frame_that_follows_it(tour_home_file: Path) -> None:
    with LiveHome(tour_home_file, seed=0, writer="thread") as live:
        core, sent = _core(live, tolerance=0.5)
        extractor = live.home.knowledge.image_extractor()
        core.start()
        try:
            old, new = _room_view(2.0, seed=3), _room_view(2.0, seed=4)
            now = time.time()
            core.on_pose(_pose_msg(2.0, 1.0, 0.0), received=now - 0.05)
            core.on_image(_image_msg(old), received=now - 0.3)
            core.on_speech("this is the scullery", received=now)
            time.sleep(0.1)
            assert not [a for a in sent["answer"] if a["op"] == "teach"]  # still waiting for a frame
            core.on_image(_image_msg(new), received=time.time())  # 0.1 s after: nearer than 0.3 s before
            deadline = time.time() + 20
            while not [a for a in sent["answer"] if a["op"] == "teach"] and time.time() < deadline:
                time.sleep(0.02)
        finally:
            core.stop()
        (answer,) = [a for a in sent["answer"] if a["op"] == "teach"]
        assert "error" not in answer and answer["sentence"] == "this is the scullery"
        assert np.array_equal(_taught_counts(live), extractor.extract(new, "bgr8"))


def test_an_utterance_just_after_a_frame_does_not_wait_for_the_next(tour_home_file: Path) -> None:
    """A frame 0.02 s before the utterance: a later one could be nearer only within 0.02 s, so the
    node decides then, not after the tolerance (0.5 s)."""
    with LiveHome(tour_home_file, seed=0, writer="thread") as live:
        core, _ = _core(live, tolerance=0.5)
        now = time.time()
        core.on_pose(_pose_msg(2.0, 1.0, 0.0), received=now)
        core.on_image(_image_msg(_room_view(2.0)), received=now - 0.02)
        started = time.monotonic()
        core._wait_for_frame(now)
        assert time.monotonic() - started < 0.25  # not the 0.5 s of the tolerance
        core, _ = _core(live, tolerance=0.5)
        now = time.time()
        core.on_image(_image_msg(_room_view(2.0)), received=now - 0.3)
        started = time.monotonic()
        core._wait_for_frame(now)  # the last frame 0.3 s before: waits 0.3 s for a nearer one
        assert 0.2 < time.monotonic() - started < 0.49


def test_poses_from_tf_and_answers(tour_home_file: Path) -> None:
    with LiveHome(tour_home_file, seed=0, writer="thread") as live:
        clock = Clock(50.0)
        core, sent = _core(live, clock, robot_frame="base_footprint")

        def edge(parent: str, child: str, x: float, y: float, theta: float) -> dict:
            return {"header": {"frame_id": parent, "stamp": {"secs": 49, "nsecs": 0}},
                    "child_frame_id": child, "transform": {"translation": {"x": x, "y": y, "z": 0.0},
                                  "rotation": quaternion_from_yaw(theta)}}

        core.on_tf({"transforms": [edge("map", "odom", 1.0, 0.0, math.pi / 2)]}, static=False, received=50.0)
        core.on_tf({"transforms": [edge("odom", "base_footprint", 0.0, -1.0, -math.pi / 2)]}, received=50.0)
        answer = core.on_query(json.dumps({"id": "w", "op": "what", "view": False}))
        assert answer["pose"] == {"x": pytest.approx(2.0), "y": pytest.approx(0.0),
                                  "theta": pytest.approx(0.0)}
        assert answer["id"] == "w" and sent["answer"][-1] == json.loads(json.dumps(answer))
        clock.t = 60.0  # ten seconds later, no new pose: no current pose
        stale = core.on_query('{"id": 2, "op": "what"}')
        assert "the last pose is 10.0 s old" in stale["error"]
        where = core.on_query('{"id": 3, "op": "where", "name": "Kitchen", "n": 2, "goal": true}')
        assert where["name"] == "kitchen" and len(where["positions"]) == 2
        (goal,) = sent["goal"]
        assert goal["header"]["frame_id"] == "map" and goal["pose"]["position"]["x"] == where["goal"]["x"]
        assert core.on_query('{"id": 4, "op": "where", "name": "kitchen", "n": 0}')["error"] == \
            "'n' must be at least 1, got 0"


@pytest.mark.parametrize("args, message", [
    (["--tolerance", "0"], "--tolerance must be > 0 seconds"),
    (["--image-wait", "-1"], "--image-wait must be ≥ 0 seconds"),
    (["--max-age", "0"], "--max-age must be > 0 seconds"),
    (["--rosbridge", "http://robot:9090"], "--rosbridge takes a WebSocket URL"),
])
def test_spco_ros_refuses_bad_options_before_it_starts(tour_home_file: Path, args: list[str],
                                                      message: str) -> None:
    from click.testing import CliRunner

    from spco.cli import main

    result = CliRunner().invoke(main, ["ros", str(tour_home_file), *args])
    assert result.exit_code == 2 and message in result.output, result.output


def _jpeg_bomb(width: int, height: int) -> bytes:
    """A JPEG whose frame header claims ``width`` × ``height`` pixels, without the data to decode."""
    sof = b"\xff\xc0\x00\x11\x08" + height.to_bytes(2, "big") + width.to_bytes(2, "big") \
        + b"\x03\x01\x22\x00\x02\x11\x01\x03\x11\x01"
    return b"\xff\xd8\xff\xe0\x00\x10JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00" + sof + b"\x00" * 64


def test_a_camera_frame_claiming_too_many_pixels_is_refused_before_it_is_decoded(
        tour_home_file: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """ROS message → counts: a CompressedImage whose JPEG header claims 16384 × 16384 pixels (more than
    DEFAULT_MAX_PIXELS) is refused, in a teaching and in a what, without OpenCV decoding it."""
    from spco.features.pixels import DEFAULT_MAX_PIXELS

    decoded: list[int] = []
    real = cv2.imdecode
    monkeypatch.setattr(cv2, "imdecode", lambda raw, flags: decoded.append(len(raw)) or real(raw, flags))
    with LiveHome(tour_home_file, seed=0, writer="thread") as live:
        core, _ = _core(live)
        n = live.home.n_samples
        now = time.time()
        core.on_pose(_pose_msg(2.0, 1.0, 0.0), received=now)
        core.on_image({"header": {}, "format": "jpeg", "data": _jpeg_bomb(16384, 16384)}, received=now)
        refused = core.teach_utterance(now, "this is the kitchen")
        assert "camera frame cannot be read" in refused["error"]
        assert f"16384×16384 pixels is more than the {DEFAULT_MAX_PIXELS} accepted" in refused["error"]
        answer = core.on_query('{"id": 1, "op": "what"}')
        assert "16384×16384 pixels is more than" in answer["error"] and answer["id"] == 1
        assert live.home.n_samples == n and decoded == []  # nothing taught, nothing decoded
        # a real frame after it is decoded (once per use) and taught
        core.on_image(_image_msg(_room_view(2.0)), received=time.time())
        answer = core.teach_utterance(time.time(), "this is the kitchen")
        assert "error" not in answer and live.home.n_samples == n + 1 and len(decoded) == 1
