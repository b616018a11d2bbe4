"""ROS messages as dicts (spco.ros.messages) and pixel encodings (spco.features.pixels): no ROS needed."""

from __future__ import annotations

import base64
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from spco.errors import DataFormatError
from spco.features.pixels import (
    UndeclaredEncodingWarning,
    check_encoding,
    decode_compressed,
    pixels_from_buffer,
    to_bgr,
)
from spco.ros.messages import (
    CHI2_95_2D,
    MARKER_NAMESPACES,
    TfBuffer,
    ellipse_axes,
    frame_from_message,
    goal_message,
    marker_array,
    places_text,
    pose_from_message,
    quaternion_from_yaw,
    stamp_seconds,
    time_message,
    yaw_from_quaternion,
)


def _pose(x: float, y: float, theta: float) -> dict:
    return {"position": {"x": x, "y": y, "z": 0.0}, "orientation": quaternion_from_yaw(theta)}


def test_times_in_both_dialects() -> None:
    assert stamp_seconds({"stamp": {"secs": 12, "nsecs": 500_000_000}}) == pytest.approx(12.5)
    assert stamp_seconds({"stamp": {"sec": 3, "nanosec": 250_000_000}}) == pytest.approx(3.25)
    assert stamp_seconds({"stamp": {"secs": 0, "nsecs": 0}}) is None  # zero: no stamp
    assert stamp_seconds(None) is None
    assert time_message(12.5) == {"secs": 12, "nsecs": 500_000_000}
    assert time_message(3.999_999_999_9, ros_version=2) == {"sec": 4, "nanosec": 0}


@pytest.mark.parametrize("theta", [0.0, 1.0, -2.5, math.pi - 1e-9])
def test_yaw_round_trip(theta: float) -> None:
    assert yaw_from_quaternion(quaternion_from_yaw(theta)) == pytest.approx(theta)


def test_every_pose_type_gives_the_same_pose() -> None:
    header = {"frame_id": "/map", "stamp": {"secs": 5, "nsecs": 0}}
    stamped = {"header": header, "pose": _pose(1.5, -2.0, 0.7)}
    with_cov = {"header": header, "pose": {"pose": _pose(1.5, -2.0, 0.7), "covariance": [0.0] * 36}}
    odometry = {"header": header, "child_frame_id": "base_footprint",
                "pose": {"pose": _pose(1.5, -2.0, 0.7), "covariance": [0.0] * 36}, "twist": {}}
    for msg in (stamped, with_cov, odometry):
        pose = pose_from_message(msg)
        assert (pose.x, pose.y, pose.frame, pose.stamp) == (1.5, -2.0, "map", 5.0)
        assert pose.theta == pytest.approx(0.7)
    with pytest.raises(DataFormatError, match="not a pose message"):
        pose_from_message({"data": "hello"})
    with pytest.raises(DataFormatError, match="non-finite"):
        pose_from_message({"pose": _pose(float("nan"), 0.0, 0.0)})


def _transform(parent: str, child: str, x: float, y: float, theta: float, secs: int = 1) -> dict:
    return {"header": {"frame_id": parent, "stamp": {"secs": secs, "nsecs": 0}}, "child_frame_id": child,
            "transform": {"translation": {"x": x, "y": y, "z": 0.0}, "rotation": quaternion_from_yaw(theta)}}


def test_tf_chain_is_composed_along_the_tree() -> None:
    tf = TfBuffer()
    assert tf.lookup("map", "base_footprint") is None
    tf.add({"transforms": [_transform("map", "odom", 1.0, 2.0, math.pi / 2, secs=3)]})
    assert tf.lookup("map", "base_footprint") is None  # not connected yet
    tf.add({"transforms": [_transform("odom", "base_footprint", 1.0, 0.0, 0.5, secs=4)]})
    tf.add({"transforms": [_transform("base_footprint", "head", 0.1, 0.0, 0.0, secs=0)]}, static=True)
    pose = tf.lookup("map", "base_footprint")
    # odom is turned a quarter: its x axis is the map's y axis
    assert (pose.x, pose.y) == pytest.approx((1.0, 3.0))
    assert pose.theta == pytest.approx(math.pi / 2 + 0.5)
    assert pose.stamp == 3.0  # the oldest dynamic transform used
    # a frame below the robot's, and the robot in a frame above it
    head = tf.lookup("map", "head")
    assert (head.x, head.y) == pytest.approx((1.0 + 0.1 * math.cos(math.pi / 2 + 0.5),
                                              3.0 + 0.1 * math.sin(math.pi / 2 + 0.5)))
    back = tf.lookup("base_footprint", "map")
    assert math.hypot(back.x, back.y) == pytest.approx(math.hypot(1.0, 3.0))
    assert tf.frames() == ["base_footprint", "head", "map", "odom"]


def _frame(h: int = 12, w: int = 16) -> np.ndarray:
    rng = np.random.default_rng(3)
    return rng.integers(0, 256, (h, w, 3), dtype=np.uint8)


def test_raw_images_in_every_encoding_decode_to_the_same_bgr() -> None:
    bgr = _frame()
    rgb = np.ascontiguousarray(bgr[:, :, ::-1])
    for pixels, encoding in ((bgr, "bgr8"), (rgb, "rgb8")):
        padded = np.zeros((12, 16 * 3 + 4), dtype=np.uint8)  # rows padded to a step of 52 bytes
        padded[:, :48] = pixels.reshape(12, 48)
        for data in (padded.tobytes(), list(padded.ravel()), base64.b64encode(padded.tobytes()).decode()):
            frame = frame_from_message({"header": {}, "height": 12, "width": 16, "step": 52,
                                        "encoding": encoding.upper(), "data": data})
            array, name = frame.pixels()
            assert name == encoding and np.array_equal(to_bgr(array, name), bgr)
    grey = bgr[:, :, 0].copy()
    frame = frame_from_message({"height": 12, "width": 16, "step": 16, "encoding": "mono8",
                                "data": grey.tobytes()})
    array, name = frame.pixels()
    assert name == "mono8" and np.array_equal(to_bgr(array, name), np.repeat(grey[:, :, None], 3, axis=2))
    with pytest.raises(DataFormatError, match="'16UC1' is not supported"):
        frame_from_message({"height": 2, "width": 2, "step": 4, "encoding": "16UC1", "data": b"\0" * 8})
    short = frame_from_message({"height": 12, "width": 16, "step": 48, "encoding": "rgb8",
                                "data": b"\0" * 10})
    with pytest.raises(DataFormatError, match="do not match its size"):
        short.pixels()


def test_compressed_images() -> None:
    bgr = _frame(32, 40)
    ok, png = cv2.imencode(".png", bgr)
    assert ok
    frame = frame_from_message({"header": {}, "format": "rgb8; png compressed bgr8", "data": png.tobytes()})
    array, name = frame.pixels()
    assert frame.encoding == "png" and name == "bgr8" and np.array_equal(array, bgr)
    assert np.array_equal(decode_compressed(png.tobytes(), "png"), bgr)
    with pytest.raises(DataFormatError, match="declared jpeg holds png"):
        decode_compressed(png.tobytes(), "jpeg")
    with pytest.raises(DataFormatError, match="not supported"):
        frame_from_message({"format": "tiff", "data": b"II*\0"})
    with pytest.raises(DataFormatError, match="could not be decoded"):
        decode_compressed(png.tobytes()[:40])


def test_encodings_declared_undeclared_and_refused() -> None:
    bgr = _frame()
    rgb = np.ascontiguousarray(bgr[:, :, ::-1])
    assert np.array_equal(to_bgr(rgb, "rgb8"), bgr)
    assert np.array_equal(to_bgr(bgr, "bgr8"), bgr)
    rgba = np.concatenate([rgb, np.full((12, 16, 1), 255, np.uint8)], axis=2)
    assert np.array_equal(to_bgr(rgba, "rgba8"), bgr)
    with pytest.warns(UndeclaredEncodingWarning, match="declare encoding='rgb8'"):
        assert np.array_equal(to_bgr(bgr), bgr)
    with pytest.raises(DataFormatError, match="declared mono8 has 1 channel"):
        to_bgr(bgr, "mono8")
    with pytest.raises(DataFormatError, match="'bayer_rggb8' is not supported"):
        to_bgr(bgr, "bayer_rggb8")
    assert check_encoding("JPG") == "jpeg" and check_encoding("8UC1") == "mono8"
    assert pixels_from_buffer(bgr.tobytes(), 12, 16, 48, "bgr8").shape == (12, 16, 3)


def test_markers_draw_each_region_and_label_the_places_where_finds_there() -> None:
    regions = [
        {"region": 4, "mean": [1.0, 2.0], "covariance": [[0.5, 0.2], [0.2, 0.3]], "concept": 1,
         "names": [{"name": "kitchen", "p": 0.81}, {"name": "dining room", "p": 0.12}],
         "places": [{"name": "kitchen", "p": 0.64}, {"name": "dining room", "p": 0.05}]},
        {"region": 7, "mean": [-3.0, 0.5, 0.2, 0.9], "covariance": np.diag([0.1, 0.4, 1.0, 1.0]),
         "concept": 12, "names": [{"name": "bedroom", "p": 0.94}], "places": [{"name": "bedroom", "p": 0.2}]},
        {"region": 9, "mean": [0.0, 0.0], "covariance": np.eye(2), "concept": 3,
         "names": [{"name": "kitchen", "p": 0.7}], "places": []},  # `where` finds no place here
    ]
    message = marker_array(regions, n_concepts=15, frame="map")
    markers = message["markers"]
    assert markers[0]["action"] == 3 and len(markers) == 1 + 3 * len(regions) - 1  # DELETEALL first
    by_kind = {ns: [m for m in markers[1:] if m["ns"] == ns] for ns in MARKER_NAMESPACES.values()}
    assert [m["id"] for m in by_kind["spco/regions"]] == [4, 7, 9]
    for region, outline, fill in zip(regions, by_kind["spco/regions"], by_kind["spco/fill"], strict=True):
        cov = np.asarray(region["covariance"], dtype=float)[:2, :2]
        mean = np.asarray(region["mean"], dtype=float)[:2]
        points = np.array([[p["x"], p["y"]] for p in outline["points"]]) - mean
        d2 = np.einsum("ni,ij,nj->n", points, np.linalg.inv(cov), points)
        assert np.allclose(d2, CHI2_95_2D)  # every point on the 95 % ellipse
        major, minor, angle = ellipse_axes(cov)
        assert fill["scale"]["x"] == pytest.approx(2 * major)
        assert fill["scale"]["y"] == pytest.approx(2 * minor)
        assert yaw_from_quaternion(fill["pose"]["orientation"]) == pytest.approx(angle)
        assert outline["color"] == {**fill["color"], "a": 1.0} and fill["color"]["a"] == 0.25
        assert all(m["header"]["frame_id"] == "map" for m in (outline, fill))
    # the labels are `where`'s places with p(region | name), never the names `what` answers there
    assert [m["id"] for m in by_kind["spco/names"]] == [4, 7]
    assert [m["text"] for m in by_kind["spco/names"]] == ["kitchen 0.64\ndining room 0.05", "bedroom 0.20"]
    assert places_text(regions[0], top=1) == "kitchen 0.64" and places_text(regions[2]) == ""
    assert by_kind["spco/regions"][0]["color"] != by_kind["spco/regions"][1]["color"]


def test_goal_message() -> None:
    goal = goal_message(1.0, -2.0, math.pi / 2, "map")
    assert goal["header"] == {"frame_id": "map"}  # stamp 0: the latest transform
    assert yaw_from_quaternion(goal["pose"]["orientation"]) == pytest.approx(math.pi / 2)
    stamped = goal_message(0, 0, 0, stamp=2.5, ros_version=2)
    assert stamped["header"]["stamp"] == {"sec": 2, "nanosec": 500_000_000}


def test_every_image_path_checks_the_header_before_decoding(tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """A PNG or JPEG whose header claims more pixels than allowed is refused without decoding, whether
    it comes as a ROS message, bytes, a file or a view; a small one that decodes differently from its
    header is refused as broken."""
    from spco.features import read_image
    from spco.features.pixels import ImageError, ImageTooLargeError, decode_image, encoded_size

    png = cv2.imencode(".png", _frame(32, 40))[1].tobytes()
    jpeg = cv2.imencode(".jpg", _frame(32, 40))[1].tobytes()
    assert encoded_size(png) == ("png", 40, 32) and encoded_size(jpeg) == ("jpeg", 40, 32)
    decoded: list[int] = []
    real = cv2.imdecode
    monkeypatch.setattr(cv2, "imdecode", lambda raw, flags: decoded.append(len(raw)) or real(raw, flags))
    frame = frame_from_message({"format": "jpeg", "data": base64.b64encode(jpeg).decode()})
    with pytest.raises(ImageTooLargeError, match=r"40×32 pixels is more than the 1000 accepted"):
        frame.pixels(max_pixels=1000)
    with pytest.raises(ImageTooLargeError):
        decode_compressed(png, max_pixels=1000)
    (tmp_path / "big.png").write_bytes(png)
    with pytest.raises(ImageTooLargeError, match=r"big\.png: 40×32 pixels is more than"):
        read_image(tmp_path / "big.png", max_pixels=1000)
    with pytest.raises(ImageTooLargeError, match=r"^image: 40×32"):
        decode_image(jpeg, max_pixels=1000)
    with pytest.raises(ImageTooLargeError):
        decode_image(_frame(32, 40).tobytes(), "bgr8", width=40, height=32, max_pixels=1000)
    assert decoded == []
    assert frame.pixels()[0].shape == (32, 40, 3) and len(decoded) == 1
    # a header that lies about the size: refused after decoding, as broken
    lying = png[:16] + (41).to_bytes(4, "big") + png[20:]
    with pytest.raises(ImageError, match=r"broken PNG \(41×32 in its header"):
        decode_compressed(lying)
    with pytest.raises(ImageError, match="too small"):
        decode_compressed(cv2.imencode(".png", _frame(4, 4))[1].tobytes())
    # every view comes out BGR, grey and raw pixels included
    grey = np.arange(64, dtype=np.uint8).reshape(8, 8)
    assert np.array_equal(decode_image(grey.tobytes(), "mono8", width=8, height=8),
                          np.repeat(grey[:, :, None], 3, axis=2))
    with pytest.raises(ImageError, match=r"^image: 3 bytes of mono8 pixels, but 8×8×1 = 64 expected"):
        decode_image(b"abc", "mono8", width=8, height=8)
