"""``spco show``: draw what a home knows (its regions, names and teachings) as a PNG over its floor
plan, or write them to an MCAP file for Foxglove.

Registered in :mod:`spco.cli.main`. Heavy imports happen when the command runs, so ``spco --help``
stays fast; spco's errors are reported by the command line's ``_friendly_errors``.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import click

from spco.cli.common import check_out, load_home, parse_extent
from spco.cli.errors import friendly_errors

__all__ = ["show"]

_friendly = friendly_errors


@click.command(name="show")
@click.argument("home_file", metavar="HOME", type=click.Path(path_type=Path))
@click.option("--out", "-o", default=None, type=click.Path(path_type=Path), help="The PNG to write.")
@click.option("--mcap", "mcap_file", default=None, type=click.Path(path_type=Path),
              help="Also (or instead) write the home's regions, names and teachings to this MCAP file, as "
              "foxglove.SceneUpdate entities on /spco/scene and /spco/teachings (frame map), for Foxglove "
              "(needs spco[foxglove]).")
@click.option("--map", "map_image", type=click.Path(path_type=Path), default=None,
              help="Floor plan drawn under the concepts: a ROS map (map.yaml: its image, origin and "
                   "resolution give the extent) or an image (PNG, JPEG, PGM; grey drawn in grey).")
@click.option("--extent", default=None,
              help="x_min,x_max,y_min,y_max in metres covered by a --map image (default: the home's map "
                   "extent; a map.yaml gives its own).")
@click.option("--name", "names", multiple=True, help="Also draw positions for this place name (repeatable).")
@click.option("--regions", "regions_file", type=click.Path(path_type=Path), default=None,
              help="Room outlines to draw: a plain home's regions.json, or a file of every home's "
                   "(sigverse_regions.json). Default: the regions.json of the home folder adapted from.")
@click.option("--regions-home", default=None, metavar="KEY",
              help="The home of --regions to draw, when its key differs from the home's name.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0), help="Random seed.")
@click.option("--force", is_flag=True, help="Replace --out (and --mcap) if it exists.")
@_friendly
def show(home_file: Path, out: Path | None, mcap_file: Path | None, map_image: Path | None,
         extent: str | None, names: Sequence[str], regions_file: Path | None, regions_home: str | None,
         seed: int, force: bool) -> None:
    """Draw the home's concepts on its floor plan: regions (95 % ellipses coloured by concept)
    labelled on the map with the names that describe them, the room outlines when the home has
    regions, the home's samples, and positions for the names given. --map takes a ROS map.yaml
    (its image placed by its origin and resolution). --mcap writes the regions for Foxglove."""
    if out is None and mcap_file is None:
        raise click.UsageError("give --out PNG, --mcap FILE, or both")
    if mcap_file is not None:
        check_out(mcap_file, force)
        from spco.ros.foxglove import require_foxglove

        require_foxglove()  # a missing foxglove-sdk is one clear error, before any work
    if out is None:
        assert mcap_file is not None
        _write_mcap(load_home(home_file), mcap_file)
        return
    check_out(out, force)
    floor_plan, bounds = _floor_plan(map_image, extent)
    home = load_home(home_file)
    predicted = _predicted_positions(home, names, seed)
    _draw_home(home, out, floor_plan, bounds, map_image, predicted, regions_file, regions_home)
    click.echo(f"Wrote {out}")
    if mcap_file is not None:
        _write_mcap(home, mcap_file)


def _floor_plan(map_image: Path | None, extent: str | None) -> tuple[Any, Any]:
    """What ``spco show`` draws under the concepts and where: the --map image (a path; a ROS
    map.yaml's image array placed by its origin and resolution; a PGM as a grey array) and the
    extent in metres (--extent, the map.yaml's, or ``None``: the home's)."""
    from spco.data.rosmap import MAP_YAML_SUFFIXES, read_ros_map
    from spco.errors import ConfigurationError

    if map_image is not None and not Path(map_image).is_file():
        raise ConfigurationError(f"{map_image}: no such map image (--map)")
    bounds = parse_extent(extent)
    floor_plan: Any = map_image
    if map_image is not None and Path(map_image).suffix.lower() in MAP_YAML_SUFFIXES:
        if bounds is not None:
            raise ConfigurationError("--extent is given by the map.yaml of --map (origin and resolution); "
                                     "leave --extent out")
        ros_map = read_ros_map(map_image)
        floor_plan, bounds = ros_map.image, ros_map.extent
    elif map_image is not None and Path(map_image).suffix.lower() == ".pgm":
        floor_plan = _grey_image(Path(map_image))
    return floor_plan, bounds


def _predicted_positions(home: Any, names: Sequence[str], seed: int) -> dict[str, Any]:
    """Ten drawn positions for each of ``names`` (by the name the home knows it as), each name on
    its own seed drawn from ``seed``; a name taught but not usable yet is left out with a warning."""
    import numpy as np

    from spco.knowledge import unused_word_hint
    from spco.knowledge import where as where_name
    from spco.model.prediction import UnknownNameError

    rng = np.random.default_rng(seed)
    predicted = {}
    for name in names:
        seed_of_name = int(rng.integers(2**63 - 1))  # (a Generator passed on would be copied, not advanced)
        try:
            pred = where_name(home, name, n=10, random_state=seed_of_name)
        except UnknownNameError as exc:  # a name taught but not usable yet: draw the map without it
            if unused_word_hint(home, name) is None:
                raise
            click.echo(f"warning: no positions drawn for {name!r}: {exc}", err=True)
            continue
        predicted[pred.name] = pred.samples
    return predicted


def _draw_home(home: Any, out: Path, floor_plan: Any, bounds: Any, map_image: Path | None,
               predicted: dict[str, Any], regions_file: Path | None, regions_home: str | None) -> None:
    """The home's map (:func:`spco.plots.plot_home_map`) with its room outlines, if any, written
    to ``out``; an unreadable --map image is a :class:`~spco.errors.ConfigurationError`."""
    from spco import plots
    from spco.errors import ConfigurationError

    if bounds is None and map_image is not None and home.extent is None:
        raise ConfigurationError("the home has no map extent: give --extent x_min,x_max,y_min,y_max "
                                 "for --map")
    environment = home.environment()
    if regions_home is not None and regions_file is None:
        raise ConfigurationError("--regions-home chooses a home of --regions: give --regions too")
    rooms = _room_outlines(home, regions_file, regions_home)
    if rooms is not None:
        from dataclasses import replace

        from spco.data.environment import make_ground_truth

        environment = replace(environment, ground_truth=make_ground_truth(regions=rooms))
    try:
        fig = plots.plot_home_map(home.parameters, 0, environment, home.vocabulary,
                                  map_image=floor_plan, map_extent=bounds, label_regions=True,
                                  place_labels=_place_labels(home),
                                  predicted_positions=predicted or None, show_ground_truth=rooms is not None,
                                  title=f"{home.name}: {home.n_samples} samples, {home.n_taught} taught")
    except (OSError, ValueError, SyntaxError) as exc:  # an unreadable image
        if isinstance(exc, ConfigurationError):
            raise
        raise ConfigurationError(f"{map_image}: cannot draw the map image ({exc})") from None
    _save_png(fig, out)


def _place_labels(home: Any) -> dict[str, tuple[int, float]]:
    """Each learnt place's label: the region ``where`` goes for it, with p(region | name)
    (:func:`spco.knowledge.places`), as the page of ``spco serve`` and the ROS markers label it."""
    from spco.knowledge import places

    return {name: (int(pred.region), float(pred.region_probabilities[pred.region]))
            for name, pred in places(home).items() if pred.learnt}


def _write_mcap(home: Any, path: Path) -> None:
    """The home's regions and teachings as Foxglove scene updates in the MCAP file ``path``."""
    from spco.ros.foxglove import write_mcap
    from spco.service.answers import regions_answer

    regions = regions_answer(home)
    write_mcap(regions, home.knowledge.n_concepts, path)
    click.echo(f"Wrote {path} ({len(regions['regions'])} regions, "
               f"{sum(1 for s in regions['samples'] if s.get('sentence'))} teachings)")


def _grey_image(path: Path) -> Any:
    """A PGM (or other grey) image as a (H, W) uint8 array (matplotlib reads only PNG itself)."""
    import numpy as np

    from spco.errors import ConfigurationError
    from spco.features.pixels import ImageError, decode_grey

    try:
        return decode_grey(np.fromfile(path, dtype=np.uint8))
    except (OSError, ImageError):
        raise ConfigurationError(f"{path}: not a readable map image (--map)") from None


def _room_outlines(home: Any, regions_file: Path | None, key: str | None = None) -> Any:
    """The home's room rectangles (:class:`~spco.data.regions.PlaceRegions`) from ``--regions`` (the
    entry ``key``, default the home's name, of a file of every home's), or from the regions.json of the
    home folder it was adapted from; ``None`` if there are none."""
    from spco.data.plain import REGIONS_JSON, _read_regions
    from spco.data.regions import load_region_file
    from spco.errors import ConfigurationError

    if regions_file is None:
        folder = home.provenance.get("home_path")
        candidate = Path(folder) / REGIONS_JSON if folder else None
        return _read_regions(candidate) if candidate is not None and candidate.is_file() else None
    if not Path(regions_file).is_file():
        raise ConfigurationError(f"{regions_file}: no such region file (--regions)")
    if '"homes"' in Path(regions_file).read_text(encoding="utf-8", errors="replace")[:4096]:
        every = load_region_file(regions_file)
        wanted = key or home.name
        if wanted not in every:
            raise ConfigurationError(f"{regions_file}: no regions for home {wanted!r} (it has "
                                     f"{', '.join(sorted(every)[:8])}{', …' if len(every) > 8 else ''}); "
                                     "choose one with --regions-home")
        return every[wanted]
    return _read_regions(Path(regions_file))


def _save_png(fig: Any, out: Path) -> None:
    """Save a figure atomically (temporary file in the same folder, then renamed)."""
    folder = out.expanduser().resolve().parent
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{out.name}.", suffix=".png")
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=120, format="png")
        from spco.model.archive import file_mode

        os.chmod(tmp, file_mode(out))
        os.replace(tmp, out)
        tmp = ""
    finally:
        if tmp:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


#: The commands to register in :mod:`spco.cli.main`.
