"""`spco ros`: the ROS 1 node against a real ROS master, driven by rospy as a robot would drive it.

As on a companion computer: a real `rosmaster` (Debian's python3-rosmaster) on a free loopback
port, `spco ros` in a process of its own with ROS_MASTER_URI / ROS_IP set for loopback, and this
process as the robot (rospy publishers of the pose, camera and speech; subscribers of the answers,
goals and markers). One master and one node for the module; the tests run in file order on the same
node (teaching comes after the checks that need the home as adapted).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import missing_tool
from ros_harness import MALFORMED_QUERIES, SWAPPED_ROOM_COLOURS

from spco.data.bagtour import view
from spco.errors import SpcoError

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

TOPICS = ["--pose-topic", "/global_pose", "--image-topic", "/camera/image", "--speech-topic", "/speech"]


@pytest.fixture(scope="module")
def ros_node(tmp_path_factory: pytest.TempPathFactory, tour_home_file: Path):
    """(robot, home file, node process): the node on a tour home, connected to this process's robot."""
    try:
        from spco.ros import import_rospy

        import_rospy()
    except SpcoError as exc:
        missing_tool(str(exc))
    if shutil.which("rosmaster") is None:
        missing_tool("no rosmaster program (sudo apt-get install python3-rosmaster)")
    from ros_harness import (
        FakeRobot,
        free_port,
        ros_environment,
        start_master,
        start_node,
        stop_process,
    )

    folder = tmp_path_factory.mktemp("ros_node")
    home = tour_home_file
    port = free_port()
    master = start_master(port, folder)
    os.environ.update(ros_environment(port, folder))  # rospy reads them once, at init_node
    node = start_node(home, port, folder, TOPICS)
    robot = None
    try:
        robot = FakeRobot()
        robot.wait_connected(90)
        yield robot, home, node
    except BaseException:
        print((folder / "node.log").read_text(errors="replace")[-3000:])
        raise
    finally:
        if robot is not None:
            robot.close()
        stop_process(node)
        stop_process(master)


def _look(robot, distance: float, frames: int = 3, encoding: str = "bgr8", seed: int = 0) -> np.ndarray:
    """Publish the robot's pose at ``distance`` along the tour and a few camera frames of it."""
    from ros_harness import tour_pose

    x, y, theta = tour_pose(distance)
    image = view(x, y, theta, (320, 240), np.random.default_rng(seed), SWAPPED_ROOM_COLOURS)
    pixels = image[:, :, ::-1] if encoding == "rgb8" else image
    for _ in range(frames):
        robot.publish_pose(x, y, theta)
        robot.publish_image(np.ascontiguousarray(pixels), encoding)
        time.sleep(0.03)
    time.sleep(0.1)
    return image


def test_markers_are_latched_with_every_region_and_its_names(ros_node) -> None:
    robot, _, _ = ros_node
    _, message = robot.markers[-1]
    markers = message.markers
    assert markers[0].action == 3  # DELETEALL: regions that are gone disappear
    kinds = {ns: [m for m in markers[1:] if m.ns == ns] for ns in ("spco/regions", "spco/fill", "spco/names")}
    # every region drawn; a label (`where`'s places there) only on the regions `where` goes to
    assert len(kinds["spco/regions"]) == len(kinds["spco/fill"]) >= len(kinds["spco/names"]) >= 1
    assert all(m.header.frame_id == "map" for m in markers)
    assert all(m.type == 4 and len(m.points) == 49 for m in kinds["spco/regions"])  # closed LINE_STRIPs
    text = "\n".join(m.text for m in kinds["spco/names"])
    for name in ("kitchen", "living room", "bedroom"):
        assert name in text
    # a late subscriber gets the latched array at once
    from visualization_msgs.msg import MarkerArray

    late = robot.rospy.wait_for_message("/spco/markers", MarkerArray, timeout=10)
    assert len(late.markers) == len(markers)


def test_where_answers_with_the_id_and_sends_no_goal_by_default(ros_node) -> None:
    robot, _, _ = ros_node
    goals = len(robot.goals)
    answer, _ = robot.query({"id": 7, "op": "where", "name": "kitchen", "n": 5})
    assert answer["id"] == 7 and answer["op"] == "where" and answer["name"] == "kitchen"
    assert len(answer["positions"]) == 5 and "error" not in answer
    best = max(answer["positions"], key=lambda p: p["probability"])
    assert 0.0 <= best["x"] <= 4.5  # the kitchen is x 0…4 m
    time.sleep(0.5)
    assert len(robot.goals) == goals and "goal" not in answer


def test_where_with_goal_publishes_a_pose_stamped(ros_node) -> None:
    robot, _, _ = ros_node
    answer, _ = robot.query({"id": "g1", "op": "where", "name": "bedroom", "goal": True})
    assert answer["id"] == "g1" and answer["goal"]["frame"] == "map"
    _, goal = robot.wait_for(lambda: robot.goals[-1] if robot.goals else None)
    assert goal.header.frame_id == "map"
    assert goal.header.stamp.to_nsec() == 0  # stamp 0: move_base transforms it with the latest tf
    position = goal.pose.position
    assert (position.x, position.y) == pytest.approx((answer["goal"]["x"], answer["goal"]["y"]))
    q = goal.pose.orientation
    assert math.atan2(2 * q.w * q.z, 1 - 2 * q.z * q.z) == pytest.approx(answer["goal"]["theta"])
    best = max(answer["positions"], key=lambda p: p["probability"])
    assert best["x"] == answer["goal"]["x"] and best["x"] >= 7.5  # in the bedroom (x 8…12 m)


def test_what_answers_at_the_current_pose_and_view(ros_node) -> None:
    robot, _, _ = ros_node
    _look(robot, 6.0)  # the living room
    answer, _ = robot.query({"id": 8, "op": "what"})
    assert answer["id"] == 8 and answer["vision"] is True and answer["view_age"] < 2.0
    assert answer["pose"]["x"] == pytest.approx(6.0) and answer["names"][0]["name"] == "living room"
    answer, _ = robot.query({"id": 9, "op": "what", "x": 10.0, "y": 1.0, "theta": 0.0, "view": False,
                             "top": 2})
    assert answer["vision"] is False and answer["pose"] == {"x": 10.0, "y": 1.0, "theta": 0.0}
    assert len(answer["names"]) == 2 and answer["id"] == 9


def test_an_rgb_frame_declared_rgb8_gives_the_names_of_the_bgr_frame_and_of_the_file(ros_node,
                                                                                     tmp_path: Path) -> None:
    """The kitchen is orange and the bedroom the same colour with red and blue swapped: read in the
    wrong order, a kitchen frame looks like the bedroom (what the issue saw at 41 of 60 poses, at
    p = 1.0) — at the kitchen's pose the bedroom goes from nothing to about even with the kitchen."""
    robot, home, _ = ros_node
    from ros_harness import tour_pose

    from spco.cli.knowledge import what

    distance = 2.0  # in the kitchen
    answers = {}
    for encoding in ("bgr8", "rgb8"):
        image = _look(robot, distance, encoding=encoding, seed=5)
        answers[encoding], _ = robot.query({"id": encoding, "op": "what", "top": 3})
    assert answers["rgb8"]["names"] == answers["bgr8"]["names"]
    assert answers["rgb8"]["names"][0]["name"] == "kitchen" and answers["rgb8"]["vision"] is True
    # the same frame as a PNG file, through `spco what --image`: the same names and probabilities
    file = tmp_path / "view.png"
    cv2.imwrite(str(file), image)
    x, y, theta = tour_pose(distance)
    result = CliRunner().invoke(what, [str(home), "--x", str(x), "--y", str(y), "--theta", str(theta),
                                       "--image", str(file), "--json"])
    assert result.exit_code == 0, result.output
    from_file = json.loads(result.output)["names"]
    assert [n["name"] for n in from_file] == [n["name"] for n in answers["rgb8"]["names"]]
    assert [n["probability"] for n in from_file] == pytest.approx(
        [n["probability"] for n in answers["rgb8"]["names"]], abs=1e-9)
    # the RGB frame declared bgr8 (red and blue swapped): the bedroom
    for _ in range(3):
        robot.publish_pose(x, y, theta)
        robot.publish_image(np.ascontiguousarray(image[:, :, ::-1]), "bgr8")
        time.sleep(0.03)
    time.sleep(0.1)
    swapped, _ = robot.query({"id": "swapped", "op": "what", "top": 3})

    def bedroom(answer: dict) -> float:
        return next((n["probability"] for n in answer["names"] if n["name"] == "bedroom"), 0.0)

    assert bedroom(answers["rgb8"]) < 1e-6 and bedroom(swapped) > 0.25


def test_malformed_queries_get_an_error_answer_and_the_node_stays_up(ros_node) -> None:
    robot, _, node = ros_node
    for request, expected_id, message in MALFORMED_QUERIES:
        # an unknown name is looked up in WordNet: its first load takes seconds on a loaded machine
        answer, _ = robot.query(request, timeout=60)
        assert answer["id"] == expected_id and message in answer["error"], answer
    answer, _ = robot.query({"id": 10, "op": "where", "name": "kitchen", "n": 1})
    assert "error" not in answer and node.poll() is None


def test_an_utterance_is_taught_durably_and_answers_the_next_query(ros_node) -> None:
    robot, home, _ = ros_node
    from ros_harness import tour_pose

    before = len(robot.markers)
    answers = len(robot.answers)
    _look(robot, 1.5, frames=1)
    sent = robot.say("this is the pantry")
    x, y, theta = tour_pose(1.5)
    for _ in range(5):  # the camera goes on after the utterance
        robot.publish_pose(x, y, theta)
        robot.publish_image(view(x, y, theta, (320, 240), np.random.default_rng(1), SWAPPED_ROOM_COLOURS))
        time.sleep(0.03)
    # a new word's first teaching loads WordNet in the writer: seconds on a loaded machine (latency is
    # benchmarks/ros_latency.py's to measure, not this test's)
    _, taught = robot.wait_for(lambda: next(((t, a) for t, a in robot.answers[answers:]
                                             if a.get("op") == "teach"), None), timeout=60)
    assert "error" not in taught, taught
    assert taught["sentence"] == "this is the pantry" and taught["new_words"] == ["pantry"]
    assert taught["x"] == pytest.approx(1.5) and taught["seq"] >= 1
    robot.wait_for(lambda: len(robot.markers) > before, timeout=10)  # the markers are published again
    assert robot.markers[-1][0] > sent and robot.markers[-1][1].markers[0].action == 3
    # saved in the journal spco serve uses, before it was acknowledged
    journal = Path(f"{home}.journal")
    assert journal.is_file() and "pantry" in journal.read_text(errors="replace")
    answer, _ = robot.query({"id": 11, "op": "where", "name": "pantry", "n": 3})
    best = max(answer["positions"], key=lambda p: p["probability"])
    assert "error" not in answer and best["x"] < 4.5  # where it was said


def test_an_utterance_without_a_camera_frame_is_not_taught_and_says_why(ros_node) -> None:
    robot, _, _ = ros_node
    from ros_harness import tour_pose

    answers = len(robot.answers)
    x, y, theta = tour_pose(9.0)
    robot.publish_pose(x, y, theta)
    time.sleep(1.0)  # the last frame is now a second old, beyond the tolerance of 0.5 s
    robot.say("this is the study")
    for _ in range(10):
        robot.publish_pose(x, y, theta)
        time.sleep(0.1)
    _, answer = robot.wait_for(lambda: next(((t, a) for t, a in robot.answers[answers:]
                                             if a.get("op") == "teach"), None), timeout=10)
    assert "no camera frame within 0.5 s" in answer["error"] and "--tolerance" in answer["error"]


def test_roslaunch_arguments_rename_the_node_and_remap_its_topics(ros_node, tmp_path: Path) -> None:
    """As roslaunch starts a node: `__name:=`, `__log:=` and `from:=to` remappings after HOME. A second
    node on a copy of the home answers on its remapped topics under its own name."""
    robot, home, _ = ros_node
    from ros_harness import start_node, stop_process
    from std_msgs.msg import String

    rospy = robot.rospy
    copy = Path(shutil.copy2(home, tmp_path / "second.spco"))
    port = int(os.environ["ROS_MASTER_URI"].rsplit(":", 1)[1].strip("/"))
    node = start_node(copy, port, tmp_path, [*TOPICS, "/spco/query:=/second/query",
                                             "/spco/answer:=/second/answer", "/spco/markers:=/second/markers",
                                             "/spco/goal:=/second/goal", "__name:=spco_second",
                                             f"__log:={tmp_path / 'second.log'}"])
    answers: list[dict] = []
    subscriber = rospy.Subscriber("/second/answer", String, lambda m: answers.append(json.loads(m.data)))
    publisher = rospy.Publisher("/second/query", String, queue_size=10)
    from geometry_msgs.msg import PoseArray

    try:
        deadline = time.monotonic() + 90
        while publisher.get_num_connections() == 0 or subscriber.get_num_connections() == 0:
            assert node.poll() is None, (tmp_path / "node.log").read_text(errors="replace")[-3000:]
            assert time.monotonic() < deadline, "the remapped node did not connect"
            time.sleep(0.1)
        while not answers and time.monotonic() < deadline:
            publisher.publish(String(data=json.dumps({"id": "r1", "op": "where", "name": "kitchen", "n": 2})))
            time.sleep(0.3)
        assert answers and answers[0]["id"] == "r1" and len(answers[0]["positions"]) == 2
        _, _, (publishers, _, _) = rospy.get_master().getSystemState()
        assert ["/spco_second"] in [nodes for topic, nodes in publishers if topic == "/second/markers"]
        poses = rospy.wait_for_message("/spco/where", PoseArray, timeout=10)
        assert poses.header.frame_id == "map" and len(poses.poses) >= 1  # latched: the last where's poses
    finally:
        subscriber.unregister()
        publisher.unregister()
        stop_process(node)
    text = (tmp_path / "node.log").read_text(errors="replace")
    # the start-up line names the topics as remapped; stopping prints a last line
    assert "spco ros: node /spco_second; listening to pose /global_pose" in text, text[-2000:]
    assert "queries on /second/query, answers on /second/answer, markers on /second/markers" in text
    assert "goals on /second/goal" in text
    assert text.strip().splitlines()[-1].startswith("spco ros: stopped after 0 teachings and ")


def test_an_argument_that_is_not_a_remapping_is_refused(tmp_path: Path) -> None:
    from spco.cli.main import main

    result = CliRunner().invoke(main, ["ros", str(tmp_path / "home.spco"), "kitchen"])
    assert result.exit_code == 2 and "unexpected argument 'kitchen'" in result.output
    assert "FROM:=TO" in result.output and "Traceback" not in result.output
