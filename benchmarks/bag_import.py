"""Import speed of ``spco import-bag`` (messages per second) on tour bags of realistic size.

Writes (once, into ``--dir``) tour bags with :func:`spco.data.bagtour.write_tour`: by default 300 s
of a robot touring three rooms, poses at 10 Hz, 640×480 JPEG camera images at 5 Hz and an
utterance every 10 s — 4,530 messages, ~37 MB — as a ROS 1 bag, a ROS 2 sqlite3 bag and a ROS 2 mcap
bag, and the ROS 1 bag again with the pose on /tf (map → odom → base_footprint). Then imports each
``--repeats`` times (every 0.5 m and at each utterance) and prints the median time, messages/s and
MB/s of the whole import (reading, decoding the chosen images, writing the home folder), and the
process's CPU time (steadier than the wall time on a machine shared with other jobs; the import is
single-threaded).

    python benchmarks/bag_import.py --dir /tmp/bagbench
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from spco.data.bagtour import write_tour
from spco.data.rosbag import BagImportSettings, import_bags

CASES = (  # name, ros, storage, pose
    ("ROS 1 .bag, pose topic", 1, "sqlite3", "PoseWithCovarianceStamped"),
    ("ROS 2 sqlite3, pose topic", 2, "sqlite3", "PoseWithCovarianceStamped"),
    ("ROS 2 mcap, pose topic", 2, "mcap", "PoseWithCovarianceStamped"),
    ("ROS 1 .bag, /tf chain", 1, "sqlite3", "tf"),
)


def _size(path: Path) -> int:
    return (
        path.stat().st_size
        if path.is_file()
        else sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    )


def main() -> None:
    """Write the bags if needed, import each, print a table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dir", type=Path, default=Path(tempfile.gettempdir()) / "spco-bag-bench")
    parser.add_argument("--seconds", type=float, default=300.0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    args.dir.mkdir(parents=True, exist_ok=True)
    print(
        f"{'bag':<28} {'messages':>8} {'MB':>6} {'samples':>7} {'seconds':>7} {'messages/s':>10} {'MB/s':>6} "
        f"{'CPU s':>6} {'messages/CPU s':>14}"
    )
    for name, ros, storage, pose in CASES:
        stem = f"tour_{int(args.seconds)}s_ros{ros}_{storage if ros == 2 else 'bag'}_{pose}"
        bag = args.dir / (stem + ".bag" if ros == 1 else stem)
        if not bag.exists():
            write_tour(
                bag,
                ros=ros,
                storage=storage,
                seconds=args.seconds,
                pose_hz=10.0,
                image_hz=5.0,
                size=(640, 480),
                pose=pose,
            )
        settings = BagImportSettings(
            pose_topic="/tf" if pose == "tf" else "/global_pose",
            image_topic="/camera/image/compressed",
            speech_topic="/speech",
        )
        times, cpu_times, summary = [], [], None
        for _ in range(args.repeats):
            out = args.dir / "home"
            shutil.rmtree(out, ignore_errors=True)
            cpu = time.process_time()
            summary = import_bags([bag], out, settings)
            cpu_times.append(time.process_time() - cpu)
            times.append(summary.seconds)
        assert summary is not None
        seconds, cpu_seconds = statistics.median(times), statistics.median(cpu_times)
        mb = _size(bag) / 1e6
        print(
            f"{name:<28} {summary.messages:>8,} {mb:>6.1f} {summary.samples:>7} {seconds:>7.2f} "
            f"{summary.messages / seconds:>10,.0f} {mb / seconds:>6.1f} {cpu_seconds:>6.2f} "
            f"{summary.messages / cpu_seconds:>14,.0f}"
        )


if __name__ == "__main__":
    main()
