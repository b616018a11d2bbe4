"""`spco show --map map.yaml`: a ROS map (map_server's map.yaml + PGM) drawn where it belongs, in grey,
with the regions labelled on it, and `--regions-home` for a regions file keyed by another name."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from spco import knowledge as kn
from spco.cli import main
from spco.data.rosmap import read_ros_map
from spco.errors import DataFormatError
from spco.knowledge import load_home_model

RES = 0.05
ORIGIN = (-1.0, -0.5)


def _write_map(folder: Path, negate: int = 0) -> Path:
    """A 14 m × 5 m map at 5 cm: free (254) with unknown (205) borders, a wall (0) at x = 4 m and a
    dark block at x 0…1 m, y 3.5…4.5 m (near the map's top-left corner)."""
    height, width = 100, 280
    image = np.full((height, width), 254, dtype=np.uint8)
    image[:, :4] = image[:, -4:] = image[:4, :] = image[-4:, :] = 205
    col = round((4.0 - ORIGIN[0]) / RES)
    image[:, col - 1:col + 1] = 0
    top = ORIGIN[1] + height * RES
    rows = slice(round((top - 4.5) / RES), round((top - 3.5) / RES))
    image[rows, round((0.0 - ORIGIN[0]) / RES):round((1.0 - ORIGIN[0]) / RES)] = 0
    if negate:
        image = 255 - image
    pgm = folder / "house.pgm"
    pgm.write_bytes(f"P5\n{width} {height}\n255\n".encode() + image.tobytes())
    yaml = folder / "map.yaml"
    yaml.write_text(f"image: house.pgm\nresolution: {RES}\norigin: [{ORIGIN[0]}, {ORIGIN[1]}, 0.0]\n"
                    f"negate: {negate}\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return yaml


def test_read_ros_map(tmp_path: Path) -> None:
    ros_map = read_ros_map(_write_map(tmp_path))
    assert ros_map.extent == pytest.approx((-1.0, 13.0, -0.5, 4.5))
    assert ros_map.image.shape == (100, 280) and ros_map.image.dtype == np.uint8
    # the block at x 0…1, y 3.5…4.5 is in the top rows: row 0 is the map's largest y
    assert ros_map.image[5:20, 25:35].max() == 0 and ros_map.image[80:95, 25:35].min() == 254
    (tmp_path / "negated").mkdir()
    negated = read_ros_map(_write_map(tmp_path / "negated", negate=1))
    assert np.array_equal(negated.image, ros_map.image)
    bad = tmp_path / "bad.yaml"
    for text, message in [("image: house.pgm\nresolution: 0.05\n", "no 'origin'"),
                          ("image: house.pgm\nresolution: -1\norigin: [0, 0, 0]\n",
                           "'resolution' must be > 0"),
                          ("image: house.pgm\nresolution: 0.05\norigin: [0, 0, 0.5]\n", "the map is rotated"),
                          ("image: none.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "does not exist"),
                          ("[1, 2", "not a readable map.yaml")]:
        bad.write_text(text)
        with pytest.raises(DataFormatError, match=message):
            read_ros_map(bad)


def test_show_draws_a_ros_map_where_it_belongs_in_grey(tour_home_file: Path, tmp_path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spco import plots

    yaml = _write_map(tmp_path)
    out = tmp_path / "map.png"
    result = CliRunner().invoke(main, ["show", str(tour_home_file), "--map", str(yaml), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the figure spco show draws: the map image at its extent, grey, regions labelled with names
    home = load_home_model(tour_home_file)
    ros_map = read_ros_map(yaml)
    places = {name: (pred.region, float(pred.region_probabilities[pred.region]))
              for name, pred in kn.places(home).items() if pred.learnt}
    fig = plots.plot_home_map(home.parameters, 0, home.environment(), home.vocabulary,
                              map_image=ros_map.image, map_extent=ros_map.extent, label_regions=True,
                              place_labels=places)
    ax = fig.axes[0]
    (drawn,) = ax.images
    assert tuple(drawn.get_extent()) == pytest.approx((-1.0, 13.0, -0.5, 4.5))
    assert drawn.get_cmap().name == "gray" and np.array_equal(drawn.get_array(), ros_map.image)
    assert ax.get_xlim() == pytest.approx((-1.0, 13.0)) and ax.get_ylim() == pytest.approx((-0.5, 4.5))
    labels = [t.get_text() for t in ax.texts]
    assert {"kitchen", "living room", "bedroom"} <= {line.rsplit(" ", 1)[0] for t in labels
                                                     for line in t.split("\n")}
    for text in ax.texts:  # each place at the region `where` goes for it
        for line in text.get_text().split("\n"):
            name = line.rsplit(" ", 1)[0]
            centre = home.parameters.region_means[0, kn.where(home, name).region, :2]
            assert text.get_position() == pytest.approx(tuple(centre))
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    pixels = np.asarray(canvas.buffer_rgba())[:, :, :3].astype(int)

    def colour_at(x: float, y: float) -> np.ndarray:
        px, py = ax.transData.transform((x, y))
        return pixels[pixels.shape[0] - 1 - round(py), round(px)]

    # free space that no region's (translucent, coloured) ellipse covers
    patches = [p for p in ax.patches if hasattr(p, "contains_point")]
    free_points = [(x, y) for x in np.arange(5.0, 12.6, 0.1) for y in (0.2, 2.0, 4.2)
                   if not any(p.contains_point(ax.transData.transform((x, y)), radius=3) for p in patches)]
    assert free_points, "every free point of the map is under a region"
    block, wall, free = colour_at(0.5, 4.3), colour_at(4.0, 0.2), colour_at(*free_points[0])
    assert block.max() < 80 and wall.max() < 80  # dark, where the map puts them
    assert free.min() > 180 and np.ptp(free) < 10  # free space light grey, not viridis' colours


def test_regions_home_chooses_the_key_of_a_regions_file(tour_home_file: Path, tmp_path: Path) -> None:
    regions = tmp_path / "regions.json"
    rooms = {"kitchen": [[0, 4, 0, 4]], "hall": [[13, 15, 0, 4]]}
    regions.write_text(json.dumps({"homes": {"flat_2": rooms}}))
    out = tmp_path / "rooms.png"
    run = CliRunner().invoke
    result = run(main, ["show", str(tour_home_file), "--out", str(out), "--regions", str(regions)])
    assert result.exit_code == 2 and "no regions for home 'new_tour'" in result.output
    assert "flat_2" in result.output and "--regions-home" in result.output
    result = run(main, ["show", str(tour_home_file), "--out", str(out), "--regions", str(regions),
                        "--regions-home", "flat_2"])
    assert result.exit_code == 0, result.output
    result = run(main, ["show", str(tour_home_file), "--out", str(out), "--regions-home", "flat_2",
                        "--force"])
    assert result.exit_code == 2 and "give --regions too" in result.output
    # a room beyond the home's extent (x 12.5) is not clipped off: the axes reach it
    from spco import plots
    from spco.cli.show import _room_outlines
    from spco.data.environment import make_ground_truth

    home = load_home_model(tour_home_file)
    rooms = _room_outlines(home, regions, "flat_2")
    from dataclasses import replace

    env = replace(home.environment(), ground_truth=make_ground_truth(regions=rooms))
    fig = plots.plot_home_map(home.parameters, 0, env, home.vocabulary, show_ground_truth=True)
    assert fig.axes[0].get_xlim()[1] >= 15.0


def test_show_refuses_extent_with_a_map_yaml(tour_home_file: Path, tmp_path: Path) -> None:
    yaml = _write_map(tmp_path)
    result = CliRunner().invoke(main, ["show", str(tour_home_file), "--map", str(yaml), "--extent", "0,1,0,1",
                                       "--out", str(tmp_path / "x.png")])
    assert result.exit_code == 2 and "--extent is given by the map.yaml" in result.output
