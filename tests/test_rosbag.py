"""spco import-bag: ROS 1 and ROS 2 bags written with rosbags' own writers, good and broken."""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from spco.cli import main
from spco.data.bagtour import ROOMS, BagWriter, room_at, write_tour
from spco.data.plain import read_home
from spco.data.rosbag import BagImportSettings, import_bags
from spco.errors import ConfigurationError, DataFormatError

SMALL = (64, 48)
S = 1_000_000_000
T0 = 1_700_000_000 * S


def _rows(home: Path) -> list[dict[str, str]]:
    with open(home / "samples.csv", encoding="utf-8", newline="") as fh:
        return list(csv.DictReader(fh))


def _cli(args: list[str]):
    return CliRunner().invoke(main, ["import-bag", *map(str, args)], catch_exceptions=False)


def _truth(t_ns: int) -> tuple[float, float, float]:
    """Where write_tour's robot is at time t (ns after its start)."""
    lap = (0.3 * t_ns / S) % 24.0
    return (lap, 1.0, 0.0) if lap < 12 else (24.0 - lap, 3.0, math.pi)


def _check_tour_home(home: Path, n_utterances: int) -> list[dict[str, str]]:
    rows = _rows(home)
    assert [int(r["id"]) for r in rows] == list(range(len(rows)))
    taught = [r for r in rows if r["sentence"]]
    assert len(taught) == n_utterances
    for r in taught:  # the sentence names the room the robot is in
        assert r["sentence"] == f"this is the {ROOMS[room_at(float(r['x']))][0]}"
    for r in rows:
        images = list((home / "images").glob(f"{r['id']}.*"))
        assert len(images) == 1
    meta = json.loads((home / "home.json").read_text())
    assert meta["name"] == home.name and len(meta["extent"]) == 4
    return rows


# ------------------------------------------------------------------------------------ good bags
def test_ros1_bag_with_compressed_images(tmp_path: Path) -> None:
    bag = tmp_path / "tour.bag"
    info = write_tour(bag, ros=1, seconds=40, size=SMALL)
    result = _cli(
        [bag, "--out", tmp_path / "home", "--pose-topic", "/global_pose", "--speech-topic", "/speech"]
    )
    assert result.exit_code == 0, result.output
    rows = _check_tour_home(tmp_path / "home", info["speech"])
    # every 0.5 m along 12 m (the lap is 24 m; 40 s at 0.3 m/s) plus the utterances
    assert 20 <= len(rows) <= 30
    assert "messages/s" in result.output and f"{len(rows)} samples ({info['speech']} taught)" in result.output
    summary = json.loads((tmp_path / "home" / "import.json").read_text())
    assert summary["messages"] == info["pose"] + info["image"] + info["speech"]
    assert summary["settings"]["speech_topic"] == "/speech" and summary["settings"]["every_metres"] == 0.5
    assert summary["settings"]["speech_topic"] == "/speech" and summary["settings"]["every_metres"] == 0.5
    # images are the bag's JPEG bytes, decodable, of the camera's size
    image = cv2.imread(str(tmp_path / "home" / "images" / "0.jpg"))
    assert image.shape == (SMALL[1], SMALL[0], 3)


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_ros2_bag_raw_rgb_images_keep_their_colours(tmp_path: Path, storage: str) -> None:
    bag = tmp_path / "tour"
    info = write_tour(
        bag, ros=2, storage=storage, seconds=30, size=SMALL, raw_images=True, pose="PoseStamped"
    )
    settings = BagImportSettings(speech_topic="/speech", image_format="png", every_metres=1.0)
    summary = import_bags([bag], tmp_path / "home", settings)  # pose and image topics found by type
    assert summary.topics == {"pose": "/global_pose", "image": "/camera/image_raw", "speech": "/speech"}
    rows = _check_tour_home(tmp_path / "home", info["speech"])
    for r in rows:  # PNG: lossless; rgb8 turned into OpenCV's BGR, so the room's colour is right
        image = cv2.imread(str(tmp_path / "home" / "images" / f"{r['id']}.png"))
        room = np.array(ROOMS[room_at(float(r["x"]))][2])
        assert np.abs(np.median(image.reshape(-1, 3), axis=0) - room * 0.6).max() < 25


def test_tf_chain_map_odom_base_footprint(tmp_path: Path) -> None:
    bag = tmp_path / "tf"
    write_tour(bag, ros=2, storage="mcap", seconds=30, size=SMALL, pose="tf")
    summary = import_bags(
        [bag], tmp_path / "home", BagImportSettings(pose_topic="/tf", speech_topic="/speech")
    )
    assert summary.topics["pose"] == "/tf"
    rows = _rows(tmp_path / "home")
    # composed map -> odom -> base_footprint gives back the robot's pose at each sample's time
    times = json.loads((tmp_path / "home" / "import.json").read_text())
    assert times["samples"] == len(rows)
    for r in rows:
        x, y, theta = float(r["x"]), float(r["y"]), float(r["theta"])
        assert y == pytest.approx(1.0, abs=1e-3) or y == pytest.approx(3.0, abs=1e-3)
        assert math.cos(theta) == pytest.approx(1.0 if y < 2 else -1.0, abs=1e-3)
        assert 0 <= x <= 12
    taught = [r for r in rows if r["sentence"]]
    assert len(taught) == 3
    for k, r in enumerate(taught):  # the k-th utterance is at (k + 0.5) × 10 s
        assert float(r["x"]) == pytest.approx(_truth(round((k + 0.5) * 10 * S))[0], abs=0.05)


def test_tf_unknown_frame_is_a_clear_error(tmp_path: Path) -> None:
    bag = tmp_path / "tf.bag"
    write_tour(bag, ros=1, seconds=5, size=SMALL, pose="tf")
    with pytest.raises(
        DataFormatError,
        match=r"no chain of transforms from 'map' to 'base_link'.*frames seen: "
        r"base_footprint, map, odom",
    ):
        import_bags([bag], tmp_path / "home", BagImportSettings(pose_topic="/tf", robot_frame="base_link"))


def test_odometry_mono8_and_png_views_and_several_bags(tmp_path: Path) -> None:
    first, second = tmp_path / "a.bag", tmp_path / "b.bag"
    rng = np.random.default_rng(0)
    grey = rng.integers(0, 255, (SMALL[1], SMALL[0]), dtype=np.uint8)
    with BagWriter(first) as bag:
        for k in range(20):
            bag.pose("/odom", T0 + k * S // 10, 0.1 * k, 0.0, 0.0, kind="Odometry", frame="map")
            bag.raw_image("/cam", T0 + k * S // 10, grey, "mono8")
        bag.text("/speech", T0 + S, "this is the hall")
    with BagWriter(second) as bag:  # a second recording, later
        for k in range(20):
            bag.pose("/odom", T0 + 10 * S + k * S // 10, 5 + 0.1 * k, 0.0, 0.0, kind="Odometry", frame="map")
        bag.text("/speech", T0 + 11 * S, "this is the study")
    summary = import_bags(
        [second, first], tmp_path / "home", BagImportSettings(speech_topic="/speech", every_metres=0.5)
    )
    rows = _rows(tmp_path / "home")
    assert [r["sentence"] for r in rows if r["sentence"]] == ["this is the hall"]
    assert summary.skipped["utterance: no image within 0.5 s"] == 1  # the second bag has no camera
    assert summary.skipped["along the way: no image within 0.5 s"] >= 1
    written = cv2.imread(str(tmp_path / "home" / "images" / "0.jpg"), cv2.IMREAD_GRAYSCALE)
    assert np.abs(written.astype(int) - grey).mean() < 20  # JPEG of the grey view


def test_visual_topic_makes_a_home_spco_reads(tmp_path: Path) -> None:
    bag = tmp_path / "fc7.bag"
    rng = np.random.default_rng(1)
    with BagWriter(bag) as w:
        for k in range(30):
            w.pose("/pose", T0 + k * S // 2, 0.2 * k, 0.5, 0.3, kind="PoseStamped")
            w.features("/fc7", T0 + k * S // 2, rng.random(16) * 3)
        w.text("/speech", T0 + 5 * S, "this is the kitchen")
    result = _cli(
        [
            bag,
            "--out",
            tmp_path / "home",
            "--visual-topic",
            "/fc7",
            "--visual-scale",
            5,
            "--speech-topic",
            "/speech",
        ]
    )
    assert result.exit_code == 0, result.output
    env = read_home(tmp_path / "home")
    assert env.n_samples == len(_rows(tmp_path / "home")) and env.visual.shape[1] == 16
    assert env.n_taught == 1
    assert not (tmp_path / "home" / "images").exists()
    # without a scale, real-valued features are refused
    result = _cli([bag, "--out", tmp_path / "other", "--visual-topic", "/fc7"])
    assert result.exit_code == 2 and "not counts" in result.output and str(bag) in result.output


# ------------------------------------------------------------------------------------ broken bags
def test_missing_topic_names_the_bag_and_lists_topics(tmp_path: Path) -> None:
    bag = tmp_path / "tour.bag"
    write_tour(bag, seconds=3, size=SMALL)
    result = _cli([bag, "--out", tmp_path / "home", "--speech-topic", "/hsrb/voice/text"])
    assert result.exit_code == 2
    assert result.output.startswith(f"error: {bag}: no topic /hsrb/voice/text (--speech-topic)")
    assert "/global_pose (geometry_msgs/msg/PoseWithCovarianceStamped)" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "home").exists()


def test_unknown_message_type_is_refused(tmp_path: Path) -> None:
    bag = tmp_path / "custom"
    with BagWriter(bag, ros=2) as w:
        w.register("string[] sentences\nfloat32[] scores", "my_msgs/msg/Recognition")
        w.pose("/pose", T0, 0.0, 0.0, 0.0)
        w.write(
            "/voice",
            "my_msgs/msg/Recognition",
            T0,
            w.types["my_msgs/msg/Recognition"](sentences=["kitchen"], scores=np.zeros(1, np.float32)),
        )
    with pytest.raises(
        DataFormatError,
        match="/voice carries my_msgs/msg/Recognition, which is not a speech message spco reads; "
        "expected std_msgs/msg/String",
    ):
        import_bags(
            [bag],
            tmp_path / "home",
            BagImportSettings(speech_topic="/voice", image_topic=None, visual_topic=None),
        )


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_truncated_bag_is_one_clear_error(tmp_path: Path, kind: str) -> None:
    path = tmp_path / ("tour.bag" if kind == "ros1" else "tour")
    write_tour(
        path,
        ros=1 if kind == "ros1" else 2,
        storage="mcap" if kind == "mcap" else "sqlite3",
        seconds=5,
        size=SMALL,
    )
    data_file = path if kind == "ros1" else next(p for p in path.iterdir() if p.suffix in (".db3", ".mcap"))
    data = data_file.read_bytes()
    data_file.write_bytes(data[: len(data) // 2])  # the recorder was killed
    result = _cli([path, "--out", tmp_path / "home"])
    assert result.exit_code == 2, result.output
    assert result.output.startswith(f"error: {path}: cannot read the bag")
    assert "reindex" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "home").exists()


def test_not_a_bag_and_missing_bag(tmp_path: Path) -> None:
    junk = tmp_path / "notes.bag"
    junk.write_text("hello")
    for path, message in ((junk, "cannot read the bag"), (tmp_path / "absent.bag", "no such bag")):
        result = _cli([path, "--out", tmp_path / "home"])
        assert result.exit_code == 2 and message in result.output and str(path) in result.output


@pytest.mark.parametrize("pose", ["PoseWithCovarianceStamped", "tf"])
def test_tours_whose_clocks_overlap_are_read_one_after_the_other(tmp_path: Path, pose: str) -> None:
    """Two tours recorded with the same clock origin (simulated time, a clock reset) used to lose
    most of the second one as "time went backwards"; now each is read on its own time line and the
    home holds every sample of both, the first tour's first."""
    tours = [tmp_path / "tour_a.bag", tmp_path / "tour_b.bag"]
    write_tour(tours[0], seconds=30, size=SMALL, pose=pose, seed=1)
    write_tour(tours[1], seconds=20, size=SMALL, pose=pose, seed=2)  # same start time as the first
    settings = BagImportSettings(speech_topic="/speech")
    alone = [import_bags([bag], tmp_path / f"alone_{bag.stem}", settings) for bag in tours]
    both = import_bags(tours, tmp_path / "both", settings)  # same start: in the order given
    assert both.tours == 2 and "2 tours whose clocks overlap" in both.format()
    assert both.dropped == {} and Counter(both.skipped) == sum((Counter(a.skipped) for a in alone), Counter())
    assert both.samples == sum(a.samples for a in alone) and both.taught == 3 + 2
    rows = _check_tour_home(tmp_path / "both", n_utterances=5)
    first = _rows(tmp_path / "alone_tour_a")
    assert [(r["x"], r["y"], r["sentence"]) for r in rows[:len(first)]] == \
        [(r["x"], r["y"], r["sentence"]) for r in first]
    assert filecmp_images(tmp_path / "both", tmp_path / "alone_tour_b", offset=len(first))


def filecmp_images(home: Path, alone: Path, offset: int) -> bool:
    """The views of ``alone``'s samples are those of ``home``'s samples from ``offset`` on."""
    return all((home / "images" / f"{int(r['id']) + offset}.jpg").read_bytes()
               == (alone / "images" / f"{r['id']}.jpg").read_bytes() for r in _rows(alone))


def test_camera_and_poses_in_separate_bags_at_the_same_time_are_one_tour(tmp_path: Path) -> None:
    """Bags recording other topics over the same time (a camera bag beside a pose bag) are one
    tour: the same samples as one bag holding everything."""
    rng = np.random.default_rng(3)
    together, poses, camera = tmp_path / "all.bag", tmp_path / "poses.bag", tmp_path / "camera.bag"
    views = [rng.integers(0, 255, (8, 8, 3), dtype=np.uint8) for _ in range(40)]
    with BagWriter(together) as everything, BagWriter(poses) as pose_bag, BagWriter(camera) as camera_bag:
        for k in range(40):
            for bag in (everything, pose_bag):
                bag.pose("/pose", T0 + k * S // 4, 0.1 * k, 0.0, 0.0)
            for bag in (everything, camera_bag):
                bag.compressed_image("/cam", T0 + k * S // 4 + S // 100, views[k])
        for bag in (everything, pose_bag):
            bag.text("/speech", T0 + 2 * S, "this is the hall")
    settings = BagImportSettings(speech_topic="/speech")
    one = import_bags([together], tmp_path / "one", settings)
    two = import_bags([camera, poses], tmp_path / "two", settings)
    assert two.tours == 1 and two.dropped == {} and two.samples == one.samples and two.taught == 1
    assert _rows(tmp_path / "one") == _rows(tmp_path / "two")


def test_time_going_backwards_is_dropped_and_counted(tmp_path: Path) -> None:
    bag = tmp_path / "clock.bag"
    with BagWriter(bag) as w:
        for k in range(40):
            stamp = T0 + k * S // 4 - (3 * S if 20 <= k < 25 else 0)  # five poses stamped 3 s in the past
            w.pose("/pose", T0 + k * S // 4, 0.1 * k, 0.0, 0.0, stamp=stamp)
            w.compressed_image("/cam", T0 + k * S // 4, np.full((8, 8, 3), 100, np.uint8))
        w.text("/speech", T0 + 2 * S, "this is the hall")
    summary = import_bags([bag], tmp_path / "home", BagImportSettings(speech_topic="/speech"))
    assert summary.dropped == {"/pose: time went backwards": 5}
    assert summary.taught == 1 and "time went backwards" in summary.format()
    # with the record times the stamps do not matter
    again = import_bags([bag], tmp_path / "home2", BagImportSettings(speech_topic="/speech", clock="bag"))
    assert again.dropped == {}


@pytest.mark.parametrize("encoding", ["bayer_rggb8", "16UC1", "rgba8"])
def test_unsupported_image_encoding_is_refused(tmp_path: Path, encoding: str) -> None:
    bag = tmp_path / "enc.bag"
    with BagWriter(bag) as w:
        for k in range(5):
            w.pose("/pose", T0 + k * S, 0.6 * k, 0.0, 0.0)
            w.raw_image("/cam", T0 + k * S, np.zeros((4, 4), np.uint8), encoding)
    result = _cli([bag, "--out", tmp_path / "home"])
    assert result.exit_code == 2
    assert f"/cam: image encoding '{encoding}' is not supported (rgb8, bgr8, mono8)" in result.output
    assert str(bag) in result.output and not (tmp_path / "home").exists()
    assert not list(tmp_path.glob(".home*"))  # no half-written folder left behind


def test_undecodable_image_is_a_counted_skip_and_depth_is_refused(tmp_path: Path) -> None:
    bag = tmp_path / "jpeg.bag"
    good = cv2.imencode(".jpg", np.full((8, 8, 3), 90, np.uint8))[1].tobytes()
    with BagWriter(bag) as w:
        for k in range(6):
            w.pose("/pose", T0 + k * S, 0.6 * k, 0.0, 0.0)
            w.compressed_image("/cam", T0 + k * S, None, data=good if k != 2 else good[:4] + b"\0" * 10)
    summary = import_bags([bag], tmp_path / "home", BagImportSettings())
    assert summary.skipped == {"along the way: image could not be decoded": 1}
    assert summary.samples == 5 and sorted(p.name for p in (tmp_path / "home" / "images").iterdir()) == [
        f"{i}.jpg" for i in range(5)
    ]
    depth = tmp_path / "depth.bag"
    with BagWriter(depth) as w:
        w.pose("/pose", T0, 0.0, 0.0, 0.0)
        w.compressed_image("/cam", T0, None, fmt="16UC1; compressedDepth", data=b"\0" * 20)
    with pytest.raises(DataFormatError, match="depth images"):
        import_bags([depth], tmp_path / "home2", BagImportSettings())


def test_pose_in_another_frame_is_refused(tmp_path: Path) -> None:
    bag = tmp_path / "odom.bag"
    with BagWriter(bag) as w:
        w.pose("/odom", T0, 0.0, 0.0, 0.0, kind="Odometry", frame="odom")
        w.compressed_image("/cam", T0, np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(DataFormatError, match="poses are in frame 'odom', not the map frame 'map'"):
        import_bags([bag], tmp_path / "home", BagImportSettings())
    summary = import_bags([bag], tmp_path / "home", BagImportSettings(map_frame="odom"))
    assert summary.samples == 1


# ------------------------------------------------------------------------------------ the home folder
def test_out_is_never_overwritten_without_force_nor_a_non_home(tmp_path: Path) -> None:
    bag = tmp_path / "tour.bag"
    write_tour(bag, seconds=5, size=SMALL)
    out = tmp_path / "home"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    result = _cli([bag, "--out", out])
    assert result.exit_code == 2 and "pass --force" in result.output
    result = _cli([bag, "--out", out, "--force"])
    assert result.exit_code == 2 and "holds files but no home" in result.output
    assert (out / "notes.txt").read_text() == "mine"
    shutil.rmtree(out)
    assert _cli([bag, "--out", out]).exit_code == 0
    first = (out / "samples.csv").read_text()
    assert _cli([bag, "--out", out]).exit_code == 2
    result = _cli([bag, "--out", out, "--force", "--every-metres", 0.2])
    assert result.exit_code == 0, result.output
    assert (out / "samples.csv").read_text() != first
    assert not list(tmp_path.glob(".home*"))
    with pytest.raises(ConfigurationError, match="would hold or replace the bag"):
        import_bags([bag], tmp_path, overwrite=True)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--tolerance", 0], "--tolerance must be > 0"),
        (["--every-metres", 0, "--at", "travel"], "no sample to make"),
        (["--at", "utterances"], "--at utterances makes samples only where people speak"),
        (["--every-seconds", -1], "--every-seconds must be ≥ 0"),
    ],
)
def test_bad_settings(tmp_path: Path, args: list, message: str) -> None:
    bag = tmp_path / "tour.bag"
    write_tour(bag, seconds=2, size=SMALL)
    result = _cli([bag, "--out", tmp_path / "home", *args])
    assert result.exit_code == 2 and message in result.output


def test_every_seconds_and_tolerance(tmp_path: Path) -> None:
    bag = tmp_path / "tour.bag"
    info = write_tour(bag, seconds=20, size=SMALL, image_hz=1.0)
    summary = import_bags(
        [bag], tmp_path / "home", BagImportSettings(every_metres=0, every_seconds=2.0, tolerance=0.1)
    )
    # a sample every 2 s over 20 s; the camera (1 Hz, 3 ms after the poses) is within 0.1 s of each
    assert summary.periodic == 10 and summary.samples == 10 and info["image"] == 20
    with pytest.raises(
        DataFormatError, match=re.escape(
            "no sample has every modality: 10 along the way: no image within 0.001 s; the camera records one "
            "image every 1.0 s: --tolerance 0.5 takes the nearest one; --at images makes a sample at each "
            "camera image")
    ):
        import_bags(
            [bag], tmp_path / "home2",
            BagImportSettings(every_metres=0, every_seconds=2.0, tolerance=0.001, at="travel"),
        )
    assert not (tmp_path / "home2").exists()


def test_header_stamps_off_the_record_times_are_warned_about(tmp_path: Path) -> None:
    bag = tmp_path / "sim.bag"
    with BagWriter(bag) as w:  # a robot on simulated time, a recorder on the wall clock
        for k in range(40):
            t = T0 + k * S // 4
            w.pose("/pose", t, 0.1 * k, 0.0, 0.0, stamp=k * S // 4 + S)
            w.compressed_image("/cam", t, np.full((8, 8, 3), 100, np.uint8), stamp=k * S // 4 + S)
        w.text("/speech", T0 + 2 * S, "this is the hall")
    summary = import_bags([bag], tmp_path / "home", BagImportSettings(speech_topic="/speech"))
    assert summary.skipped == {"utterance: no pose within 0.5 s": 1} and summary.taught == 0
    assert any("/pose: header stamps are" in w and "--clock bag" in w for w in summary.warnings)
    assert "warning: /cam: header stamps are" in summary.format()
    fixed = import_bags([bag], tmp_path / "home2", BagImportSettings(speech_topic="/speech", clock="bag"))
    assert fixed.taught == 1 and not fixed.warnings


def _se2(x: float, y: float, yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, x], [s, c, y], [0, 0, 1]])


def test_tf_chain_through_a_common_parent_matches_matrix_products(tmp_path: Path) -> None:
    """map and odom both children of world: map→base = inv(world→map) · world→odom · odom→base."""
    bag = tmp_path / "tree.bag"
    rng = np.random.default_rng(3)
    world_map = (1.0, -2.0, 0.7)
    truth = []
    with BagWriter(bag) as w:
        w.transforms("/tf_static", T0, [("world", "map", *world_map)])
        for k in range(30):
            world_odom = (0.1 * k, 0.05 * k, 0.02 * k)
            odom_base = tuple(rng.uniform(-1, 1, 3))
            w.transforms(
                "/tf",
                T0 + k * S // 5,
                [("world", "odom", *world_odom), ("odom", "base_footprint", *odom_base)],
            )
            w.compressed_image("/cam", T0 + k * S // 5, np.full((8, 8, 3), 8 * k, np.uint8))
            m = np.linalg.inv(_se2(*world_map)) @ _se2(*world_odom) @ _se2(*odom_base)
            truth.append((m[0, 2], m[1, 2], math.atan2(m[1, 0], m[0, 0])))
    summary = import_bags([bag], tmp_path / "home", BagImportSettings(every_metres=0, every_seconds=0.2))
    assert summary.topics["pose"] == "/tf" and summary.samples == 30
    for r, (x, y, theta) in zip(_rows(tmp_path / "home"), truth, strict=True):
        assert float(r["x"]) == pytest.approx(x, abs=1e-3) and float(r["y"]) == pytest.approx(y, abs=1e-3)
        assert math.remainder(float(r["theta"]) - theta, 2 * math.pi) == pytest.approx(0, abs=1e-3)


@pytest.mark.parametrize("ros", [1, 2])
def test_compressed_bags(tmp_path: Path, ros: int) -> None:
    """LZ4-chunked ROS 1 bags and zstd-compressed ROS 2 messages, as recorders write them."""
    bag = tmp_path / ("lz4.bag" if ros == 1 else "zstd")
    with BagWriter(bag, ros=ros, compress=True) as w:
        for k in range(10):
            w.pose("/pose", T0 + k * S, 0.6 * k, 0.0, 0.0, kind="PoseStamped")
            w.compressed_image("/cam", T0 + k * S, np.full((8, 8, 3), 20 * k, np.uint8))
        w.text("/speech", T0 + 3 * S, "this is the hall")
    summary = import_bags([bag], tmp_path / "home", BagImportSettings(speech_topic="/speech"))
    assert summary.messages == 21 and summary.samples == 10 and summary.taught == 1


def test_ros2_bag_without_message_definitions(tmp_path: Path) -> None:
    """Bags recorded before ROS 2 Iron store no message definitions: the standard types are known."""
    import sqlite3

    bag = tmp_path / "humble"
    write_tour(bag, ros=2, seconds=10, size=SMALL)
    database = next(bag.glob("*.db3"))
    with sqlite3.connect(database) as db:
        db.execute("DELETE FROM message_definitions")
    from rosbags.highlevel import AnyReader, AnyReaderError

    with pytest.raises(AnyReaderError, match="no type definitions"), AnyReader([bag]):
        pass
    summary = import_bags([bag], tmp_path / "home", BagImportSettings(speech_topic="/speech"))
    assert summary.taught == 1 and summary.samples >= 6


# ------------------------------------------------------------------------- recordings as robots make them
def test_a_throttled_camera_without_speech_imports_with_the_default_options(tmp_path: Path) -> None:
    """The camera at 0.5 Hz, nobody speaking: a sample at each image (along the way, samples every
    0.5 m fall up to a second from the nearest image and most would have none within 0.5 s)."""
    bag = tmp_path / "throttled.bag"
    info = write_tour(bag, seconds=60, size=SMALL, image_hz=0.5, speech_every=0)
    result = _cli([bag, "--out", tmp_path / "home"])
    assert result.exit_code == 0, result.output
    rows = _rows(tmp_path / "home")
    assert len(rows) == info["image"] == 30 and not any(r["sentence"] for r in rows)
    assert "a sample at each camera image (one every 2.0 s)" in result.output
    assert "Skipped" not in result.output and "Not taught" not in result.output
    for r in rows:  # each sample has the pose of its image's time (images 3 ms after a pose)
        x, y, _ = _truth(int(r["id"]) * 2 * S)
        assert (float(r["x"]), float(r["y"])) == pytest.approx((x, y), abs=1e-3)
    record = json.loads((tmp_path / "home" / "import.json").read_text())
    assert record["sampling"] == "images" and record["image_interval"] == pytest.approx(2.0)
    # forced along the way, half the samples find no image, and the summary says what to change
    result = _cli([bag, "--out", tmp_path / "travel", "--at", "travel"])
    assert result.exit_code == 0 and len(_rows(tmp_path / "travel")) < 30
    assert "samples along the way found no camera image (the camera records one every 2.0 s): --at images" \
        in result.output


def test_utterances_with_a_throttled_camera_take_the_nearest_image(tmp_path: Path) -> None:
    """Utterances at 5, 15, 25 … s and images every 2 s: each utterance is 1 s from the nearest image.
    At each image (the default here), an utterance takes the nearest one; along the way (forced), the
    tolerance of 0.5 s loses them, and the summary lists them with the tolerance that would keep them."""
    bag = tmp_path / "throttled.bag"
    info = write_tour(bag, seconds=80, size=SMALL, image_hz=0.5, speech_every=10)
    summary = import_bags([bag], tmp_path / "home", BagImportSettings(speech_topic="/speech"))
    assert summary.sampling == "images" and summary.taught == info["speech"] == 8
    assert "an utterance takes the nearest image up to 1.2 s away" in summary.format()
    _check_tour_home(tmp_path / "home", info["speech"])
    forced = import_bags([bag], tmp_path / "travel", BagImportSettings(speech_topic="/speech", at="travel"))
    text = forced.format()
    lost = forced.skipped["utterance: no image within 0.5 s"]
    assert lost == 8 and forced.taught == 0
    assert "Not taught: 8 utterances:" in text and "--tolerance 1 takes the nearest one" in text
    assert "same camera image" not in text  # no noise
    kept = import_bags([bag], tmp_path / "travel", BagImportSettings(speech_topic="/speech", at="travel",
                                                                     tolerance=1.0), overwrite=True)
    assert kept.taught == 8 and "Not taught" not in kept.format()


def test_a_good_import_prints_no_skipped_samples(tmp_path: Path) -> None:
    bag = tmp_path / "tour.bag"
    write_tour(bag, seconds=60, size=SMALL, image_hz=5.0)
    summary = import_bags([bag], tmp_path / "home", BagImportSettings(speech_topic="/speech"))
    assert summary.sampling == "travel" and summary.taught == 6
    assert summary.skipped  # samples along the way that would repeat a view, in import.json only
    assert "Skipped" not in summary.format() and "Not taught" not in summary.format()
    assert "6 utterances heard; a sample along the way as the robot travelled" in summary.format()


def test_a_robot_that_stops_to_look_gets_a_sample_at_each_look(tmp_path: Path) -> None:
    """The robot drives between three places and takes two pictures at each stop: along the way no
    sample finds a picture, so the samples are the pictures."""
    bag = tmp_path / "stops.bag"
    stops = [(1.0, 1.0), (5.0, 1.0), (9.0, 1.0)]
    with BagWriter(bag) as w:
        t = T0
        for k, (x, y) in enumerate(stops):
            for step in range(30):  # drive there at 0.5 m/s: 3 s, poses at 10 Hz
                t += S // 10
                w.pose("/pose", t, x - 1.5 + 0.05 * step, y, 0.0, kind="PoseStamped")
            for shot in range(2):  # stand still, look twice
                t += S
                w.pose("/pose", t, x, y, 0.0, kind="PoseStamped")
                w.compressed_image("/cam", t + 1_000_000, np.full((16, 16, 3), 40 * k + shot, np.uint8))
    summary = import_bags([bag], tmp_path / "home", BagImportSettings())
    assert summary.sampling == "images" and summary.samples == 6
    rows = _rows(tmp_path / "home")
    assert [(float(r["x"]), float(r["y"])) for r in rows] == [s for s in stops for _ in "ab"]


def test_out_creates_its_missing_folders(tmp_path: Path) -> None:
    bag = tmp_path / "tour.bag"
    write_tour(bag, seconds=10, size=SMALL)
    result = _cli([bag, "--out", tmp_path / "a" / "b" / "home"])
    assert result.exit_code == 0, result.output and (tmp_path / "a" / "b" / "home" / "samples.csv").is_file()
    (tmp_path / "file").write_text("not a folder")
    result = _cli([bag, "--out", tmp_path / "file" / "home"])
    assert result.exit_code == 2 and "is a file, not a folder" in result.output
