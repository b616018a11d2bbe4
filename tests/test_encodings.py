"""Arrays of pixels carry their colour order: the library, the command line and the resident home take
an ``encoding`` (rgb8, bgr8, mono8, rgba8, bgra8); an RGB frame declared rgb8 gives the names of the
same frame as BGR and of its file.

The home's kitchen is orange and its bedroom the same colour with red and blue swapped
(``ros_harness.SWAPPED_ROOM_COLOURS``): an RGB frame read as BGR is another room.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from ros_harness import SWAPPED_ROOM_COLOURS, tour_pose

from spco import knowledge as kn
from spco.cli import main
from spco.data.bagtour import view
from spco.errors import DataFormatError
from spco.features import read_image
from spco.features.pixels import UndeclaredEncodingWarning
from spco.service.live import LiveHome


def _frame(distance: float, seed: int = 0) -> tuple[tuple[float, float, float], np.ndarray]:
    pose = tour_pose(distance)
    return pose, view(*pose, (320, 240), np.random.default_rng(seed), SWAPPED_ROOM_COLOURS)


def _names(prediction: kn.NamePrediction) -> list[tuple[str, float]]:
    return [(str(w), float(p)) for w, p in zip(prediction.words[0], prediction.probabilities[0], strict=True)]


def test_read_image_takes_the_declared_colour_order(tmp_path: Path) -> None:
    _, bgr = _frame(2.0)
    rgb = np.ascontiguousarray(bgr[:, :, ::-1])
    png = tmp_path / "view.png"
    cv2.imwrite(str(png), bgr)
    assert np.array_equal(read_image(rgb, "rgb8"), bgr) and np.array_equal(read_image(bgr, "bgr8"), bgr)
    assert np.array_equal(read_image(png), bgr) and np.array_equal(read_image(png.read_bytes()), bgr)
    with pytest.warns(UndeclaredEncodingWarning):
        assert np.array_equal(read_image(rgb), rgb)  # undeclared: read as BGR
    with pytest.raises(DataFormatError, match="carries its own colour order"):
        read_image(png, "rgb8")
    with pytest.raises(DataFormatError, match="grey, colour or colour with alpha"):
        read_image(np.zeros((10, 10, 2), np.uint8))


def test_an_rgb_frame_declared_rgb8_gives_the_names_of_the_bgr_frame_and_of_its_file(tour_home_file: Path,
                                                                                    tmp_path: Path) -> None:
    home = kn.load_home_model(tour_home_file)
    changed = 0
    distances = np.arange(0.25, 24.0, 0.5)
    for k, distance in enumerate(distances):
        (x, y, theta), bgr = _frame(float(distance), seed=k)
        rgb = np.ascontiguousarray(bgr[:, :, ::-1])
        png = tmp_path / f"{k}.png"
        cv2.imwrite(str(png), bgr)
        from_file = _names(kn.what(home, x, y, theta, image=png))
        assert _names(kn.what(home, x, y, theta, image=rgb, encoding="rgb8")) == from_file
        assert _names(kn.what(home, x, y, theta, image=bgr, encoding="bgr8")) == from_file
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UndeclaredEncodingWarning)
            wrong = _names(kn.what(home, x, y, theta, image=rgb))  # the RGB frame read as BGR
        changed += wrong[0][0] != from_file[0][0]
    # undeclared, the top name changes at many poses: what the issue saw (41 of 60 poses); 32 of these
    # 48 with the view-by-view answer (main 445a282), 23 with the room account, where a room's pooled
    # views weigh as much as the frame (benchmarks/README, "Issue 29: the room account the default")
    assert changed >= len(distances) // 3, changed


def test_teach_with_an_rgb8_frame_learns_the_view_of_its_file(tour_home_file: Path, tmp_path: Path) -> None:
    home = kn.load_home_model(tour_home_file)
    (x, y, theta), bgr = _frame(6.0)
    png = tmp_path / "view.png"
    cv2.imwrite(str(png), bgr)
    taught = kn.teach(home, observations=[kn.Observation(x, y, theta, image=bgr[:, :, ::-1].copy(),
                                                         encoding="rgb8", sentence="this is the lounge")],
                      n_sweeps=1, random_state=0)
    expected = home.knowledge.image_extractor().extract(png)
    assert np.array_equal(taught.visual[[taught.n_samples - 1]].toarray()[0], expected)


def test_the_command_line_reads_a_pixel_array_in_its_encoding(tour_home_file: Path, tmp_path: Path) -> None:
    (x, y, theta), bgr = _frame(10.0, seed=3)
    png, npy = tmp_path / "view.png", tmp_path / "view.npy"
    cv2.imwrite(str(png), bgr)
    np.save(npy, bgr[:, :, ::-1])  # as PIL or cv_bridge's rgb8 give it

    def what(*image: str) -> list:
        result = CliRunner().invoke(main, ["what", str(tour_home_file), "--x", str(x), "--y", str(y),
                                           "--theta", str(theta), "--json", *image])
        assert result.exit_code == 0, result.output
        return json.loads(result.output)["names"]

    assert what("--image", str(npy), "--encoding", "rgb8") == what("--image", str(png))
    result = CliRunner().invoke(main, ["what", str(tour_home_file), "--x", "1", "--y", "1", "--theta", "0",
                                       "--image", str(png), "--encoding", "rgb8"])
    assert result.exit_code == 2 and "carries its own" in result.output


def test_the_resident_home_takes_the_encoding_too(tour_home_file: Path, tmp_path: Path) -> None:
    (x, y, theta), bgr = _frame(2.0, seed=7)
    png = tmp_path / "view.png"
    cv2.imwrite(str(png), bgr)
    home = kn.load_home_model(tour_home_file)
    from_file = [(n, p) for n, p in _names(kn.what(home, x, y, theta, image=png))][:3]
    with LiveHome(tour_home_file, writer="thread") as live:
        for pixels, encoding in ((bgr[:, :, ::-1].copy(), "rgb8"), (bgr, "bgr8"), (png.read_bytes(), None)):
            answer = live.what(x, y, theta, image=pixels, encoding=encoding)
            assert [(n["name"], pytest.approx(n["probability"])) for n in answer["names"]] == from_file
