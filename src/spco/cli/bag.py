"""``spco import-bag``: a home folder (plain format) from a robot's ROS bags; see :mod:`spco.data.rosbag`.

Registered in :mod:`spco.cli.main`.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import click

from spco.cli.errors import friendly_errors

__all__ = ["import_bag"]


@click.command(name="import-bag")
@click.argument("bags", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--out",
    "-o",
    required=True,
    type=click.Path(path_type=Path),
    help="The home folder to write (plain format: samples.csv, images/<id>.jpg, home.json).",
)
@click.option(
    "--pose-topic",
    default=None,
    help="The robot's pose on the map: a PoseWithCovarianceStamped, PoseStamped or Odometry topic, "
    "or /tf (then --map-frame → --robot-frame). Default: the only pose topic, else /tf.",
)
@click.option("--map-frame", default="map", show_default=True, help="The map's tf frame.")
@click.option(
    "--robot-frame",
    default="base_footprint",
    show_default=True,
    help="The robot's tf frame (with --pose-topic /tf).",
)
@click.option(
    "--image-topic",
    default=None,
    help="sensor_msgs/Image (rgb8, bgr8, mono8) or CompressedImage (JPEG, PNG). "
    "Default: the only image topic.",
)
@click.option(
    "--speech-topic",
    default=None,
    help="std_msgs/String: what people said (each utterance makes a taught sample). "
    "Default: none (nothing taught).",
)
@click.option(
    "--visual-topic",
    default=None,
    help="Ready-made visual features (std_msgs/Float32MultiArray & co.), written to visual.npz.",
)
@click.option(
    "--visual-scale",
    type=float,
    default=None,
    help="With --visual-topic: real-valued features become counts floor(max(f, 0) × scale).",
)
@click.option(
    "--at",
    "at",
    default="auto",
    show_default=True,
    type=click.Choice(["auto", "travel", "images", "utterances"]),
    help="Where untaught samples are made besides the utterances: along the way (travel: every "
    "--every-metres / --every-seconds), at each camera image (images: a throttled camera, a robot that "
    "stops to look), or nowhere (utterances). auto: along the way when most of those samples find a "
    "camera image within --tolerance, else at each image.",
)
@click.option(
    "--every-seconds",
    default=0.0,
    show_default=True,
    type=float,
    help="With --at travel: an untaught sample every N seconds along the way (0: off).",
)
@click.option(
    "--every-metres",
    default=0.5,
    show_default=True,
    type=float,
    help="With --at travel: an untaught sample every M metres of travel (0: off).",
)
@click.option(
    "--tolerance",
    default=0.5,
    show_default=True,
    type=float,
    help="Seconds within which each modality is taken, nearest in time.",
)
@click.option(
    "--clock",
    default="header",
    show_default=True,
    type=click.Choice(["header", "bag"]),
    help="Message times: header stamps (record time for messages without one), or record times.",
)
@click.option(
    "--image-format",
    default="jpg",
    show_default=True,
    type=click.Choice(["jpg", "png"]),
    help="How raw sensor_msgs/Image views are written (compressed ones are copied as they are).",
)
@click.option("--name", default=None, help="The home's name (default: the folder's name).")
@click.option("--keep-without-image", is_flag=True,
              help="Keep an utterance with no image (or features) within --tolerance as a sample without "
                   "a view, learnt from its pose and words (default: skip it).")
@click.option("--force", is_flag=True, help="Replace the home folder --out if it holds one.")
@friendly_errors
def import_bag(
    bags: Sequence[Path],
    out: Path,
    pose_topic: str | None,
    map_frame: str,
    robot_frame: str,
    image_topic: str | None,
    speech_topic: str | None,
    visual_topic: str | None,
    visual_scale: float | None,
    every_seconds: float,
    every_metres: float,
    at: str,
    tolerance: float,
    clock: str,
    image_format: str,
    name: str | None,
    keep_without_image: bool,
    force: bool,
) -> None:
    """Make a home folder from ROS bags (ROS 1 .bag files, or one ROS 2 bag folder / .db3 / .mcap each).

    \b
    spco import-bag tour.bag --out my_home --pose-topic /global_pose \\
        --image-topic /hsrb/head_rgbd_sensor/rgb/image_rect_color/compressed --speech-topic /speech

    A sample at every utterance (taught) and, untaught, every --every-metres / --every-seconds along
    the way or at each camera image (--at; by default chosen from the data: at each image for a
    camera throttled to a frame every few seconds); pose, view and speech each nearest in time within
    --tolerance. Samples missing one are skipped and counted (the summary lists the utterances
    lost; import.json every skip). Bags whose clocks overlap on the same topics are separate tours,
    read one after the other. The folder, and any missing folder above it, is written whole or not
    at all.
    """
    from spco.data.rosbag import BagImportSettings, import_bags

    settings = BagImportSettings(
        pose_topic=pose_topic,
        map_frame=map_frame,
        robot_frame=robot_frame,
        image_topic=image_topic,
        speech_topic=speech_topic,
        visual_topic=visual_topic,
        visual_scale=visual_scale,
        every_seconds=every_seconds,
        every_metres=every_metres,
        at=at,
        tolerance=tolerance,
        clock=clock,
        image_format=image_format,
        name=name,
        keep_without_image=keep_without_image,
    )
    summary = import_bags(bags, out, settings, overwrite=force, progress=sys.stderr.isatty())
    click.echo(summary.format())
