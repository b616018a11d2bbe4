"""Latency of ``spco ros`` on loopback, run as on a companion computer: query → answer, and utterance →
updated markers.

Starts a real ROS 1 master (Debian's ``rosmaster``) on a free loopback port, ``spco ros`` in a process
of its own (ROS_MASTER_URI / ROS_IP set for loopback) on a tour home (``tour_home`` of
``tests/ros_harness.py``: three tours fitted, a fourth adapted, 80 samples), and plays the robot in
this process with rospy: the pose (PoseStamped) at 10 Hz and the head camera (CompressedImage,
640×480 JPEG, as the HSR's ``…/image_rect_color/compressed``) at 15 Hz, from a background thread,
as the robot drives the tour.

- **query → answer**: ``--queries`` queries one after the other, alternating ``where`` (a name, 10
  poses) and ``what`` (the robot's current pose and camera frame); the time from publishing the query
  to receiving the answer with its ``id``.
- **utterance → markers**: ``--utterances`` sentences ("this is the <room>") on the speech topic, each
  a few seconds apart; the time from publishing the String to receiving the updated, latched
  MarkerArray (the teaching is in the journal on disk before the markers go out). The first
  teaching of a node is reported apart: it also loads the sampler's kernels in the home's writer
  process.

``--markers-png PATH`` draws the last MarkerArray received (ellipse outlines, filled ellipses, the
name texts; as RViz shows them, top view of the map frame) with matplotlib.

    python benchmarks/ros_latency.py --queries 1000 --utterances 20 --markers-png docs/images/ros_markers.png
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

# the ROS master, node process and stand-in robot the tests use (tests/ros_harness.py)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from latency_report import percentiles as _percentiles  # benchmarks/, next to this script
from latency_report import print_report, query_rows


class Drive(threading.Thread):
    """The robot driving the tour at 0.3 m/s: pose at ``pose_hz``, JPEG frames at ``image_hz``."""

    def __init__(self, robot: Any, pose_hz: float = 10.0, image_hz: float = 15.0, size=(640, 480)) -> None:
        super().__init__(daemon=True)
        from ros_harness import tour_pose

        from spco.data.bagtour import view

        self.robot, self.pose_hz, self.image_hz, self.size = robot, pose_hz, image_hz, size
        self.view, self.tour_pose = view, tour_pose
        self.stop = threading.Event()
        self.distance = 0.0
        self.frames = [view(*tour_pose(d), size, np.random.default_rng(int(d * 10)))
                       for d in np.arange(0, 24, 0.5)]

    def run(self) -> None:
        start = time.perf_counter()
        next_pose = next_image = 0.0
        while not self.stop.is_set():
            now = time.perf_counter() - start
            self.distance = (0.3 * now) % 24.0
            x, y, theta = self.tour_pose(self.distance)
            if now >= next_pose:
                self.robot.publish_pose(x, y, theta)
                next_pose += 1.0 / self.pose_hz
            if now >= next_image:
                self.robot.publish_image(self.frames[int(self.distance / 0.5) % len(self.frames)])
                next_image += 1.0 / self.image_hz
            time.sleep(max(0.0, min(next_pose, next_image) - (time.perf_counter() - start)))


def draw_markers(message: Any, path: Path, title: str) -> None:
    """Draw a received visualization_msgs/MarkerArray as RViz shows it from above (map frame)."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Ellipse

    fig = Figure(figsize=(11, 3.4), layout="constrained", facecolor="#303030")
    ax = fig.add_subplot()
    ax.set_facecolor("#303030")
    for marker in message.markers:
        if marker.action != 0:
            continue
        colour = (marker.color.r, marker.color.g, marker.color.b)
        if marker.type == 4:  # LINE_STRIP
            ax.plot([p.x for p in marker.points], [p.y for p in marker.points], color=colour,
                    linewidth=marker.scale.x * 60, zorder=3)
        elif marker.type == 3:  # CYLINDER: a flat ellipse
            q = marker.pose.orientation
            angle = math.degrees(math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)))
            ax.add_patch(Ellipse((marker.pose.position.x, marker.pose.position.y), marker.scale.x,
                                 marker.scale.y, angle=angle, facecolor=colour, alpha=marker.color.a,
                                 zorder=2))
        elif marker.type == 9:  # TEXT_VIEW_FACING
            ax.text(marker.pose.position.x, marker.pose.position.y + 0.15, marker.text, color="white",
                    fontsize=marker.scale.z * 36, ha="center", va="bottom", zorder=4,
                    bbox={"boxstyle": "round,pad=0.2", "fc": colour, "ec": "none", "alpha": 0.75})
    ax.set_aspect("equal")
    ax.grid(True, color="#5a5a5a", linewidth=0.6)
    ax.tick_params(colors="#c8c8c8")
    for side in ax.spines.values():
        side.set_color("#5a5a5a")
    ax.set_xlabel("x [m] (frame map)", color="#c8c8c8")
    ax.set_ylabel("y [m]", color="#c8c8c8")
    ax.set_title(title, color="white", fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, facecolor=fig.get_facecolor())


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--queries", type=int, default=1000)
    parser.add_argument("--utterances", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the tour home and of the node's teachings")
    parser.add_argument("--markers-png", type=Path, default=None)
    parser.add_argument("--writer", choices=("process", "thread"), default="process",
                        help="spco ros --writer: where the teachings are applied")
    parser.add_argument("--dir", type=Path, default=None,
                        help="folder for the home and the logs (default: a temporary one)")
    return parser.parse_args()


def _time_queries(robot: Any, n: int) -> tuple[dict[str, list[float]], int]:
    """``n`` queries, where and what in turn: their latencies (s) and the errors."""
    names = ["kitchen", "living room", "bedroom"]
    latencies: dict[str, list[float]] = {"where": [], "what": []}
    errors = 0
    for k in range(n):
        op = "where" if k % 2 == 0 else "what"
        request = {"id": k, "op": op, **({"name": names[k % 3], "n": 10} if op == "where" else {})}
        answer, seconds = robot.query(request)
        errors += "error" in answer
        latencies[op].append(seconds)
    return latencies, errors


def _time_utterances(robot: Any, drive: Drive, n: int) -> dict[str, Any]:
    """``n`` utterances of the room the robot drives through, 2 s apart: the utterance -> markers and
    -> teach answer times after the first (s), the writer's own seconds, the first's (ms), the node's
    seconds per part, the errors."""
    from spco.data.bagtour import ROOMS, room_at

    teach, markers, writer, first, errors = [], [], [], None, 0
    parts: dict[str, list[float]] = {}
    for k in range(n):
        time.sleep(2.0)  # the robot drives on
        room = ROOMS[room_at(robot_x := drive.tour_pose(drive.distance)[0])][0]
        before_markers, before_answers = len(robot.markers), len(robot.answers)
        sent = robot.say(f"this is the {room}")
        got_markers, _ = robot.wait_for(
            lambda b=before_markers: robot.markers[-1] if len(robot.markers) > b else None, timeout=30)
        got_answer, answer = robot.wait_for(
            lambda b=before_answers: next(
                ((t, a) for t, a in robot.answers[b:] if a.get("op") == "teach"), None), timeout=30)
        errors += "error" in answer
        if k == 0:
            first = {"markers_ms": (got_markers - sent) * 1e3, "answer_ms": (got_answer - sent) * 1e3,
                     "x": robot_x}
        else:
            markers.append(got_markers - sent)
            teach.append(got_answer - sent)
            writer.append(float(answer.get("seconds", math.nan)))  # the writer's own time
            for part, seconds in answer.get("node_seconds", {}).items():
                parts.setdefault(part, []).append(seconds)
    return {"markers": markers, "teach": teach, "writer": writer, "first": first, "parts": parts,
            "errors": errors}


def main() -> None:
    """Start the master, the node and the robot; measure; print a table and a JSON line."""
    args = _arguments()
    from ros_harness import (
        FakeRobot,
        free_port,
        ros_environment,
        start_master,
        start_node,
        stop_process,
        tour_home,
    )

    folder = args.dir or Path(tempfile.mkdtemp(prefix="spco-ros-bench-"))
    folder.mkdir(parents=True, exist_ok=True)
    home = tour_home(folder, seed=args.seed)
    port = free_port()
    master = start_master(port, folder)
    os.environ.update(ros_environment(port, folder))
    node = start_node(home, port, folder, ["--pose-topic", "/global_pose", "--image-topic", "/camera/image",
                                           "--speech-topic", "/speech", "--seed", str(args.seed),
                                           "--writer", args.writer])
    drive = None
    try:
        robot = FakeRobot(compressed=True)
        robot.wait_connected(120)
        drive = Drive(robot)
        drive.start()
        time.sleep(1.0)
        # warm-up: the first what builds the extractor, the first where draws
        robot.query({"id": "warm-where", "op": "where", "name": "kitchen"})
        robot.query({"id": "warm-what", "op": "what"})
        load_start = os.getloadavg()
        latencies, errors = _time_queries(robot, args.queries)
        said = _time_utterances(robot, drive, args.utterances)
        w = _percentiles(said["writer"]) if said["writer"] else None
        result = {**query_rows(latencies),
                  "utterance_to_markers": _percentiles(said["markers"]) if said["markers"] else None,
                  "utterance_to_teach_answer": _percentiles(said["teach"]) if said["teach"] else None,
                  "writer_seconds_per_teaching": w,
                  "node_seconds_per_teaching": {part: _percentiles(v) for part, v in said["parts"].items()},
                  "first_teaching": said["first"], "errors": errors + said["errors"],
                  "loadavg_start": load_start, "writer": args.writer}
        print_report(result,
                     f"query -> answer (ms), {args.queries} queries, loopback (writer: {args.writer}):",
                     f"; of which the writer process p50 {w['p50']:.1f} max {w['max']:.1f}" if w else "")
        if args.markers_png is not None:
            draw_markers(robot.markers[-1][1], args.markers_png,
                         "/spco/markers as received over ROS 1 (visualization_msgs/MarkerArray, frame map): "
                         f"the tour home after {len(said['markers']) + 1} teachings")
            print(f"Wrote {args.markers_png}")
    finally:
        if drive is not None:
            drive.stop.set()
        stop_process(node)
        stop_process(master)


if __name__ == "__main__":
    main()
