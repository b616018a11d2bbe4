"""From a robot's ROS bags to a home folder in the plain format (``spco import-bag``).

Reads ROS 1 ``.bag`` files and ROS 2 bags (sqlite3 or mcap; the bag folder, or its ``.db3`` /
``.mcap`` file) with `rosbags <https://gitlab.com/ternaris/rosbags>`_ — pure Python, no ROS
installation. Three streams make a home:

- the robot's **pose** on the map: a topic of ``geometry_msgs/PoseWithCovarianceStamped``,
  ``geometry_msgs/PoseStamped`` or ``nav_msgs/Odometry``, or the transform from ``map_frame`` to
  ``robot_frame`` on ``/tf`` (+ ``/tf_static``), composed along the tree (e.g. map → odom →
  base_footprint), each transform taken nearest in time;
- the **view**: ``sensor_msgs/Image`` (rgb8, bgr8, mono8) or ``sensor_msgs/CompressedImage``
  (JPEG, PNG), written as ``images/<id>.jpg|png`` (compressed images are copied byte for byte once
  OpenCV has decoded them; raw ones are encoded as ``image_format``); or, with ``visual_topic``, a
  ready-made feature vector (``std_msgs/Float32MultiArray`` & co.) written to ``visual.npz``;
- **speech** as text: ``std_msgs/String``.

A sample is made at every utterance (taught: its sentence is what was said) and, untaught, where
``at`` says (:data:`SAMPLING_RULES`): along the way (``"travel"``: every ``every_seconds`` seconds or
``every_metres`` metres of travel, whichever comes first), at each camera image (``"images"``), or
nowhere else (``"utterances"``). ``"auto"`` (the default) chooses from the data (:func:`_auto_rule`):
at each image when the camera records fewer images than there would be samples along the way, or
most of those samples find no image within the tolerance — a camera throttled to one frame every few
seconds, a robot that stops to look at each place — else along the way. At each image, an utterance
takes the image nearest to it up to :data:`UTTERANCE_IMAGE_SHARE` of the camera's interval away
(the tolerance, if larger). Each
modality is taken nearest in time to the sample within ``tolerance`` seconds; a sample missing one
is skipped and counted by reason (the summary shows the utterances lost; ``import.json`` all), as is
an untaught sample that would repeat another sample's camera image. Times are the messages' header
stamps (``clock="header"``; a zero stamp and messages without a header, such as ``std_msgs/String``,
use the bag's record time) or the bag's record times throughout (``clock="bag"``). A message whose
time goes backwards on its topic (or tf edge) is dropped and counted.

Several bags are several **tours** when their clocks overlap (:func:`_tours`): a bag that starts
before a bag of the tour so far has ended, and records one of the same topics, is a recording of
its own whose clock started again (simulated time from 0 at each run, a robot whose clock was
reset). Each tour is read on its own time line: its times are shifted to start
:data:`TOUR_GAP_SECONDS` after the previous tour's last time, so nothing of one tour is matched with
another's or dropped as going backwards. Bags that follow one another (a recording split into files)
or record other topics at the same time (the camera in one bag, the poses in another) are one tour.

The home folder is written into a temporary folder beside ``out`` and renamed into place; an
existing non-empty ``out`` is replaced only with ``overwrite`` and only if it is a home folder.
Every problem with a bag (missing, truncated, an unknown or unsupported message type, a missing
topic, an unsupported image encoding) raises :class:`~spco.errors.DataFormatError` naming the bag.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
import uuid
from collections import Counter
from collections.abc import Sequence
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from spco.data import tf
from spco.data.bagreading import (
    _HEADER_OFFSET_WARNING_S,
    _NS,
    IMAGE_TYPES,
    POSE_TYPES,
    SPEECH_TYPES,
    TF_TYPES,
    TOUR_GAP_SECONDS,
    VISUAL_TYPES,
    _Bag,
    _nearest,
    _periodic_indices,
    _pose_trajectory,
    _raw_stamp,
    _Sample,
    _Series,
    _stamp,
    _Streams,
    _tf_trajectory,
    _TfTree,
    _Trajectory,
    _version,
)
from spco.data.bagwriting import (
    _check_out,
    _drop_failed_images,
    _move_into_place,
    _write_home_files,
    _write_images,
)
from spco.errors import ConfigurationError, DataFormatError

__all__ = ["SAMPLING_RULES", "BagImportSettings", "BagImportSummary", "import_bags"]

#: Where untaught samples are made (``--at``): chosen from the data, along the way, at each camera
#: image, or nowhere (only utterances).
SAMPLING_RULES = ("auto", "travel", "images", "utterances")
#: At each camera image: an utterance takes the nearest image up to this share of the camera's median
#: interval away (or the tolerance, if that is larger): a sentence said between two pictures names
#: the nearer one.
UTTERANCE_IMAGE_SHARE = 0.6
#: With ``at="auto"``: samples along the way only if at least this share of them find a camera image.
TRAVEL_IMAGE_SHARE = 0.5

@dataclass(frozen=True)
class BagImportSettings:
    """What to read from the bags and how to make samples (see the module docstring).

    A topic left ``None`` is found by its type when the bags hold exactly one candidate (pose:
    one pose topic, else ``/tf``; image: one image topic); speech is never guessed (a robot's own
    text-to-speech is a ``String`` too): without ``speech_topic`` nothing is taught.
    """

    pose_topic: str | None = None
    map_frame: str = "map"
    robot_frame: str = "base_footprint"
    image_topic: str | None = None
    speech_topic: str | None = None
    visual_topic: str | None = None
    visual_scale: float | None = None
    every_seconds: float = 0.0
    every_metres: float = 0.5
    at: str = "auto"
    tolerance: float = 0.5
    clock: str = "header"
    image_format: str = "jpg"
    name: str | None = None
    keep_without_image: bool = False  # an utterance without a view in tolerance: a sample without a view

    def check(self) -> None:
        """Raise :class:`ConfigurationError` for an out-of-range setting."""
        for label, value in (("--every-seconds", self.every_seconds), ("--every-metres", self.every_metres)):
            if not (math.isfinite(value) and value >= 0):
                raise ConfigurationError(f"{label} must be ≥ 0 (0: off), got {value}")
        if not (math.isfinite(self.tolerance) and self.tolerance > 0):
            raise ConfigurationError(f"--tolerance must be > 0 seconds, got {self.tolerance}")
        if self.clock not in ("header", "bag"):
            raise ConfigurationError(f"--clock must be header or bag, got {self.clock!r}")
        if self.image_format not in ("jpg", "png"):
            raise ConfigurationError(f"--image-format must be jpg or png, got {self.image_format!r}")
        if self.visual_scale is not None and not (math.isfinite(self.visual_scale) and self.visual_scale > 0):
            raise ConfigurationError(f"--visual-scale must be > 0, got {self.visual_scale}")
        if self.at not in SAMPLING_RULES:
            raise ConfigurationError(f"--at must be one of {', '.join(SAMPLING_RULES)}, got {self.at!r}")
        if self.at == "utterances" and not self.speech_topic:
            raise ConfigurationError("--at utterances makes samples only where people speak: give "
                                     "--speech-topic")
        no_travel = self.every_seconds == 0 and self.every_metres == 0
        if self.at == "travel" and no_travel and not self.speech_topic:
            raise ConfigurationError(
                "no sample to make: give --speech-topic, --every-seconds or --every-metres"
            )
        if not self.map_frame.strip("/") or not self.robot_frame.strip("/"):
            raise ConfigurationError("--map-frame and --robot-frame must name frames")


@dataclass
class BagImportSummary:
    """What an import read and wrote (also saved as ``import.json`` in the home folder)."""

    bags: list[str]
    out: str
    topics: dict[str, str]  # role -> topic ("pose", "image", "speech", …)
    messages: int = 0  # messages read on those topics
    tours: int = 1  # recordings whose clocks overlap, read one after the other
    seconds: float = 0.0
    samples: int = 0
    taught: int = 0
    utterances: int = 0
    periodic: int = 0  # untaught samples considered (along the way, or at camera images)
    sampling: str = "travel"  # where the untaught samples were made: travel, images or utterances
    image_interval: float | None = None  # median seconds between camera images
    utterance_image_within: float | None = None  # at images: how far an utterance's image may be (s)
    skipped: dict[str, int] = field(default_factory=dict)  # "utterance: no image within 0.5 s" -> n
    without_view: int = 0  # utterances kept without a view (keep_without_image)
    dropped: dict[str, int] = field(default_factory=dict)  # "/topic: time went backwards" -> n
    warnings: list[str] = field(default_factory=list)

    @property
    def messages_per_second(self) -> float:
        """Messages read per second of the whole import (reading, decoding, writing)."""
        return self.messages / self.seconds if self.seconds > 0 else float("inf")

    def format(self) -> str:
        """A few lines for people."""
        bags = f"{len(self.bags)} bag{'s' if len(self.bags) != 1 else ''}"
        if self.tours > 1:
            bags += f" ({self.tours} tours whose clocks overlap, read one after the other)"
        lines = [
            f"Read {bags}: {self.messages:,} messages in {self.seconds:.1f} s "
            f"({self.messages_per_second:,.0f} messages/s)"
        ]
        lines += [f"  {role:<7} {topic}" for role, topic in self.topics.items()]
        lines.append(f"Wrote {self.samples} samples ({self.taught} taught) to {self.out}: {self.rule()}")
        if self.without_view:
            lines.append(f"  {_count(self.without_view, 'utterance')} without a view kept as samples "
                         "without one")
        lost = {why: n for why, n in self.skipped.items() if why.startswith("utterance:")}
        if lost:  # a lost utterance is a lost teaching; untaught samples left out are in import.json
            lines.append(f"Not taught: {_count(sum(lost.values()), 'utterance')}:")
            lines += [f"  {n:>6}  {why}" for why, n in sorted(lost.items(), key=lambda kv: -kv[1])]
            hint = _tolerance_hint(self.image_interval, lost)
            if hint:
                lines.append(f"  ({hint})")
        blind = sum(n for why, n in self.skipped.items() if why.startswith("along the way: no image"))
        if self.sampling == "travel" and blind > 0.25 * self.periodic:
            every = (f" (the camera records one every {self.image_interval:.1f} s)" if self.image_interval
                     else "")
            lines.append(f"{blind} of {self.periodic} samples along the way found no camera image{every}: "
                         "--at images makes a sample at each image")
        if self.dropped:
            lines.append("Dropped messages:")
            lines += [f"  {n:>6}  {why}" for why, n in sorted(self.dropped.items(), key=lambda kv: -kv[1])]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


    def rule(self) -> str:
        """Where the samples were made, in words."""
        said = (f"{_count(self.utterances, 'utterance')} heard" if "speech" in self.topics
                else "no speech topic")
        if self.sampling == "images":
            every = f" (one every {self.image_interval:.1f} s)" if self.image_interval else ""
            nearest = (f"; an utterance takes the nearest image up to {self.utterance_image_within:.1f} s "
                       "away" if self.utterance_image_within and "speech" in self.topics else "")
            return f"{said}; a sample at each camera image{every}{nearest}"
        if self.sampling == "utterances":
            return f"{said}; samples only where people spoke (--at utterances)"
        return f"{said}; a sample along the way as the robot travelled"


def _count(n: int, noun: str) -> str:
    return f"{n:,} {noun}{'' if n == 1 else 's'}"


def _tolerance_hint(interval: float | None, skipped: dict[str, int]) -> str | None:
    """What to change when samples found no camera image within the tolerance, or ``None``."""
    if interval is None or not any("no image within" in why for why in skipped):
        return None
    needed = math.ceil(interval / 2 * 10) / 10  # the nearest image is at most half an interval away
    return (f"the camera records one image every {interval:.1f} s: --tolerance {needed:g} takes the nearest "
            "one")


# ------------------------------------------------------------------------------------ the import
def _choose(
    bags: list[_Bag], given: str | None, types: Sequence[str], role: str, option: str, required: bool
) -> str | None:
    """The topic for ``role``: the one given (checked), else the only one of ``types``."""
    names = ", ".join(str(b.path) for b in bags)
    seen: dict[str, str] = {}
    for bag in bags:
        seen.update(bag.topics)
    listing = "; ".join(f"{t} ({m})" for t, m in sorted(seen.items())) or "none"
    if given is not None:
        if given not in seen:
            raise DataFormatError(names, f"no topic {given} ({option}); the bag holds: {listing}")
        msgtype = seen[given]
        if msgtype not in types:
            raise DataFormatError(
                names,
                f"{given} carries {msgtype or 'an unknown message type'}, which is not a "
                f"{role} message spco reads; expected {', '.join(types)}",
            )
        return given
    candidates = sorted(t for t, m in seen.items() if m in types)
    if len(candidates) == 1:
        return candidates[0]
    if not required:
        return None
    if not candidates:
        raise DataFormatError(names, f"no {role} topic ({', '.join(types)}); the bag holds: {listing}")
    raise DataFormatError(names, f"several {role} topics: {', '.join(candidates)}; choose one with {option}")


def _pose_source(bags: list[_Bag], settings: BagImportSettings) -> str:
    """The pose topic: the one given, else the only pose topic, else ``/tf``."""
    if settings.pose_topic is None:
        candidates = {t for b in bags for t, m in b.topics.items() if m in POSE_TYPES}
        if not candidates and any(b.topics.get("/tf") in TF_TYPES for b in bags):
            return "/tf"
        types = tuple(POSE_TYPES) if candidates else (*POSE_TYPES, *TF_TYPES)
    else:
        types = (*POSE_TYPES, *TF_TYPES)
    return _required(bags, settings.pose_topic, types, "pose", "--pose-topic")


def _required(bags: list[_Bag], given: str | None, types: Sequence[str], role: str, option: str) -> str:
    """:func:`_choose` for a stream that must be found."""
    topic = _choose(bags, given, types, role, option, required=True)
    assert topic is not None  # _choose raises when a required topic is not found
    return topic


def _tours(bags: Sequence[_Bag], topics: Sequence[str]) -> list[int]:
    """The tour of each bag (bags sorted by start time): a bag that starts before a bag of the
    current tour has ended and records one of ``topics`` that bag records too starts a new tour
    (its clock started again); otherwise it continues the current tour (a recording split into files,
    or other topics recorded at the same time)."""
    wanted = set(topics)
    tours: list[int] = []
    current: list[_Bag] = []
    for bag in bags:
        mine = wanted & set(bag.topics)
        if any(other.end > bag.start and mine & set(other.topics) for other in current):
            current = []
        tours.append(tours[-1] + (not current) if tours else 0)
        current.append(bag)
    return tours


def _reading_bar() -> Any:
    """The progress bar of the first pass over the bags (messages read)."""
    from spco.progress import progress_bar

    return progress_bar(desc="reading", unit=" msg", leave=False)


def _add_utterance(speech: _Series, dropped: Counter[str], topic: str, text: str, time_ns: int) -> None:
    """An utterance at ``time_ns``, stripped; an empty one is dropped and counted."""
    text = text.strip()
    if text:
        speech.add(time_ns, text)
    else:
        dropped[f"{topic}: empty utterance"] += 1


def _pose_value(bag: _Bag, connection: Any, msg: Any, frame: str) -> tuple[float, float, float] | None:
    """(x, y, yaw) of a pose message in the map ``frame`` (``None`` if not finite); a pose in another
    frame is refused."""
    source = tf.frame_name(msg.header.frame_id)
    if source and source != frame:
        raise DataFormatError(
            bag.path,
            f"{connection.topic}: poses are in frame {source!r}, not the map frame "
            f"{frame!r}; pass --map-frame {source} if that is the map",
        )
    pose = POSE_TYPES[connection.msgtype](msg)
    p, q = pose.position, pose.orientation
    value = (float(p.x), float(p.y), float(tf.yaw(np.array([q.x, q.y, q.z, q.w]))))
    return value if all(math.isfinite(v) for v in value) else None


def _read_streams(
    bags: list[_Bag],
    topics: dict[str, str],
    settings: BagImportSettings,
    dropped: Counter[str],
    progress: bool,
) -> tuple[_Streams, int]:
    """First pass: poses, transforms, speech, image times and feature vectors; returns the message count."""
    streams = _Streams(
        pose=_Series(topics["pose"], dropped),
        tf=_TfTree(dropped),
        speech=_Series(topics.get("speech", "speech"), dropped),
        images=_Series(topics.get("image", "image"), dropped),
        visual=_Series(topics.get("visual", "visual"), dropped),
    )
    pose_topic = topics["pose"]
    tf_mode = any(b.topics.get(pose_topic) in TF_TYPES for b in bags)
    wanted = [*topics.values(), *(["/tf_static"] if tf_mode and any("/tf_static" in b.topics for b in bags)
                                  else [])]
    use_header = settings.clock == "header"
    frame = tf.frame_name(settings.map_frame)
    bar = _reading_bar() if progress else None
    count = 0
    tour_of = _tours(bags, wanted)
    shift, latest = 0, None  # the current tour's shift onto the import's time line; its last time
    for index, bag in enumerate(bags):
        if index > 0 and tour_of[index] != tour_of[index - 1] and latest is not None:
            # bags are in order of start time, so a tour starts at its first bag's start
            shift = latest + round(TOUR_GAP_SECONDS * _NS) - bag.start
        ordinal = 0
        for connection, record_time, raw in bag.messages(wanted):
            count += 1
            if bar is not None:
                bar.update()
            bag_time = record_time + shift
            latest = bag_time if latest is None else max(latest, bag_time)
            topic = connection.topic
            if topic == topics.get("image"):
                stamp = _raw_stamp(raw, bag.is2) if use_header else 0
                if stamp:
                    streams.header_offsets[topic].append(record_time - stamp)
                streams.images.add(stamp + shift if stamp else bag_time, (index, ordinal))
                ordinal += 1
                continue
            msg = bag.deserialize(raw, connection)
            if topic == pose_topic and not tf_mode:
                stamp = _stamp(msg.header) if use_header else 0
                if stamp:
                    streams.header_offsets[topic].append(record_time - stamp)
                value = _pose_value(bag, connection, msg, frame)
                if value is None:
                    dropped[f"{topic}: pose not finite"] += 1
                    continue
                streams.pose.add(stamp + shift if stamp else bag_time, value)
            elif topic in (pose_topic, "/tf_static") and tf_mode:
                static = topic == "/tf_static"
                for transform in msg.transforms:
                    stamp = _stamp(transform.header) if use_header else 0
                    streams.tf.add(transform, stamp + shift if stamp else bag_time, static)
            elif topic == topics.get("speech"):
                _add_utterance(streams.speech, dropped, topic, str(msg.data), bag_time)
            elif topic == topics.get("visual"):
                streams.visual.add(bag_time, np.asarray(msg.data, dtype=np.float64).ravel())
    if bar is not None:
        bar.close()
    streams.tours = tour_of[-1] + 1 if tour_of else 1
    return streams, count


def _import_topics(bags: list[_Bag], settings: BagImportSettings) -> dict[str, str]:
    """The topics to read, by role (``pose``, and ``speech``, ``visual``, ``image`` when used)."""
    topics: dict[str, str] = {"pose": _pose_source(bags, settings)}
    if settings.speech_topic is not None:
        topics["speech"] = _required(bags, settings.speech_topic, SPEECH_TYPES, "speech", "--speech-topic")
    if settings.visual_topic is not None:
        topics["visual"] = _required(
            bags, settings.visual_topic, VISUAL_TYPES, "visual features", "--visual-topic"
        )
    if settings.image_topic is not None or settings.visual_topic is None:
        # with ready-made features, views are read only from a topic given
        topics["image"] = _required(bags, settings.image_topic, IMAGE_TYPES, "image", "--image-topic")
    return topics


def _write_import_record(folder: Path, summary: BagImportSummary, settings: BagImportSettings) -> None:
    """``import.json``: what was read and written, with the settings and spco's version."""
    record = {**asdict(summary), "settings": asdict(settings), "spco_version": _version()}
    (folder / "import.json").write_text(json.dumps(record, indent=1, ensure_ascii=False) + "\n",
                                        encoding="utf-8")


def import_bags(
    bags: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str],
    settings: BagImportSettings | None = None,
    overwrite: bool = False,
    progress: bool = False,
) -> BagImportSummary:
    """Make a plain-format home folder ``out`` from ROS bags; returns what was read and written.

    See the module docstring for what is read and how samples are made. Raises
    :class:`~spco.errors.DataFormatError` (a bag's problem, naming it) or
    :class:`~spco.errors.ConfigurationError` (a setting, or ``out`` cannot be written).
    """
    settings = settings or BagImportSettings()
    settings.check()
    start = time.perf_counter()
    paths = [Path(b).expanduser() for b in bags]
    if not paths:
        raise ConfigurationError("give at least one bag")
    target = Path(out).expanduser()
    _check_out(target, paths, overwrite)
    tolerance_ns = round(settings.tolerance * _NS)
    dropped: Counter[str] = Counter()
    with ExitStack() as stack:
        opened = sorted((_Bag(p, stack) for p in paths), key=lambda b: b.start)
        topics = _import_topics(opened, settings)
        where = ", ".join(str(b.path) for b in opened)
        streams, n_messages = _read_streams(opened, topics, settings, dropped, progress)
        tf_mode = any(b.topics.get(topics["pose"]) in TF_TYPES for b in opened)
        traj = (
            _tf_trajectory(streams.tf, settings.map_frame, settings.robot_frame, tolerance_ns, where)
            if tf_mode
            else _pose_trajectory(streams.pose, tolerance_ns)
        )
        if traj.times.size == 0:
            raise DataFormatError(where, f"no usable pose on {topics['pose']}")
        summary = BagImportSummary(
            bags=[str(p) for p in paths], out=str(target), topics=topics, messages=n_messages,
            tours=streams.tours,
        )
        samples = _make_samples(traj, streams, topics, settings, tolerance_ns, summary)
        if not samples:
            raise DataFormatError(where, _nothing_to_write(summary))
        try:
            target.resolve().parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigurationError(f"cannot write {target}: cannot make its folder ({exc.strerror})") \
                from None
        tmp = target.resolve().parent / f".{target.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp"
        tmp.mkdir()
        try:
            if "image" in topics:
                failures = _write_images(
                    opened, topics["image"], streams, samples, tmp, settings.image_format
                )
                samples = _drop_failed_images(samples, failures, tmp, summary)
                if not samples:
                    raise DataFormatError(
                        where,
                        "no image could be used: "
                        + "; ".join(f"{n} {why}" for why, n in summary.skipped.items()),
                    )
            _write_home_files(tmp, samples, streams, settings, target, summary, where)
            summary.samples = len(samples)
            summary.taught = sum(s.sentence is not None for s in samples)
            _add_clock_warnings(streams, summary)
            summary.dropped = dict(dropped)
            summary.seconds = time.perf_counter() - start
            _write_import_record(tmp, summary, settings)
            _move_into_place(tmp, target)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
    summary.seconds = time.perf_counter() - start
    return summary


def _make_samples(
    traj: _Trajectory,
    streams: _Streams,
    topics: dict[str, str],
    settings: BagImportSettings,
    tolerance_ns: int,
    summary: BagImportSummary,
) -> list[_Sample]:
    """Utterance samples and untaught ones (along the way or at camera images: ``settings.at``) with every
    modality, in time order (skips counted in ``summary``)."""
    skipped: Counter[str] = Counter()
    tol = f"{settings.tolerance:g} s"
    speech_t = streams.speech.array()
    image_t = streams.images.array() if "image" in topics else np.zeros(0, dtype=np.int64)
    if image_t.size >= 2:
        summary.image_interval = float(np.median(np.diff(image_t))) / _NS
    rule = settings.at
    travel = (_periodic_indices(traj, settings.every_seconds, settings.every_metres)
              if rule in ("auto", "travel") else np.zeros(0, dtype=np.int64))
    if rule == "auto":
        rule = _auto_rule(image_t, traj.times[travel], tolerance_ns)
    if rule == "images" and "image" not in topics:
        raise ConfigurationError("--at images makes a sample at each camera image: give --image-topic")
    summary.sampling = rule
    # candidates: utterances (kind 0), then the untaught samples (kind 1)
    speech_tol = _utterance_image_tolerance(rule, tolerance_ns, summary)
    at_times, at_xy, at_yaw, at_valid, at_image = _untaught_candidates(rule, traj, travel, image_t,
                                                                       "image" in topics, tolerance_ns)
    summary.utterances, summary.periodic = int(speech_t.size), int(at_times.size)
    valid, xy, yaw = (
        traj.lookup(speech_t) if speech_t.size else (np.zeros(0, bool), np.zeros((0, 2)), np.zeros(0))
    )
    times = np.concatenate([speech_t, at_times])
    kinds = np.concatenate([np.zeros(speech_t.size, np.int8), np.ones(at_times.size, np.int8)])
    poses = np.concatenate([np.column_stack([xy, yaw]), np.column_stack([at_xy, at_yaw])])
    has_pose = np.concatenate([valid, at_valid])
    image_idx = np.concatenate([
        _nearest(image_t, speech_t, speech_tol) if "image" in topics else np.full(speech_t.size, -1),
        at_image,
    ]).astype(np.int64)
    visual_idx = (
        _nearest(streams.visual.array(), times, tolerance_ns)
        if "visual" in topics
        else np.full(times.size, -1)
    )
    label = {"travel": "along the way", "images": "at a camera image"}.get(rule, "")
    used_images: set[int] = set()
    samples: list[_Sample] = []
    # utterances first (an untaught sample never takes an utterance's view), then in time order
    for row in np.lexsort((times, kinds)):
        kind = "utterance" if kinds[row] == 0 else label
        if not has_pose[row]:
            skipped[f"{kind}: no pose within {tol}"] += 1
            continue
        no_image = "image" in topics and image_idx[row] < 0
        no_features = "visual" in topics and visual_idx[row] < 0
        if (no_image or no_features) and kinds[row] == 0 and settings.keep_without_image:
            summary.without_view += 1  # a sample without a view (its image or features: none)
            image_idx[row] = visual_idx[row] = -1
        elif no_image or no_features:
            within = tol if kinds[row] == 1 else f"{speech_tol / _NS:g} s"
            skipped[f"{kind}: no image within {within}" if no_image
                    else f"{kind}: no visual features within {tol}"] += 1
            continue
        if "image" in topics and image_idx[row] >= 0:
            if kinds[row] == 1 and int(image_idx[row]) in used_images:
                skipped[f"{kind}: same camera image as another sample"] += 1
                continue
            used_images.add(int(image_idx[row]))
        sentence = streams.speech.values[row] if kinds[row] == 0 else None
        x, y, theta = (float(v) for v in poses[row])
        samples.append(
            _Sample(int(times[row]), x, y, theta, sentence, int(image_idx[row]), int(visual_idx[row]))
        )
    samples.sort(key=lambda sample: sample.time)  # stable: an utterance stays before a sample at its time
    summary.skipped = dict(skipped)
    return samples


def _utterance_image_tolerance(rule: str, tolerance_ns: int, summary: BagImportSummary) -> int:
    """How far from an utterance its image may be (ns): the tolerance, or with ``--at images`` and a
    sparse camera up to about half the interval between images (recorded in ``summary``)."""
    if rule != "images" or not summary.image_interval:
        return tolerance_ns
    # an utterance takes the image nearest to it, up to about half the interval between images away
    # (60 %, for the jitter of a throttled camera)
    speech_tol = max(tolerance_ns, round(UTTERANCE_IMAGE_SHARE * summary.image_interval * _NS))
    summary.utterance_image_within = speech_tol / _NS
    return speech_tol


def _untaught_candidates(rule: str, traj: _Trajectory, travel: np.ndarray, image_t: np.ndarray,
                         has_images: bool, tolerance_ns: int) -> tuple[np.ndarray, ...]:
    """Where untaught samples may be made under ``rule``: (times, xy, yaw, whether a pose was found,
    index of the image each takes, -1 for none) — at each camera image, along the way, or nowhere."""
    if rule == "images":
        at_valid, at_xy, at_yaw = traj.lookup(image_t)
        return image_t, at_xy, at_yaw, at_valid, np.arange(image_t.size)
    if rule == "travel":
        at_times = traj.times[travel]
        at_image = _nearest(image_t, at_times, tolerance_ns) if has_images else np.full(travel.size, -1)
        return at_times, traj.xy[travel], traj.yaw[travel], np.ones(travel.size, bool), at_image
    return np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0), np.zeros(0, bool), np.zeros(0, np.int64)


def _auto_rule(image_t: np.ndarray, travel_t: np.ndarray, tolerance_ns: int) -> str:
    """``"images"`` when the camera is sparse — it records fewer images than the samples along the way
    would be (a longer median interval), or fewer than :data:`TRAVEL_IMAGE_SHARE` of those samples
    find an image within the tolerance (a robot that stops to look), or the robot never travels —
    else ``"travel"``. Without images: ``"travel"``."""
    if image_t.size == 0:
        return "travel"
    if travel_t.size < 2 or image_t.size < 2:
        return "images"
    if np.median(np.diff(image_t)) > np.median(np.diff(travel_t)):
        return "images"
    found = _nearest(image_t, travel_t, tolerance_ns) >= 0
    return "images" if found.mean() < TRAVEL_IMAGE_SHARE else "travel"


def _nothing_to_write(summary: BagImportSummary) -> str:
    """Why no sample could be made, and what to change."""
    reasons = "; ".join(f"{n} {why}" for why, n in summary.skipped.items()) or "nothing to sample"
    hints = []
    if any("no pose within" in why for why in summary.skipped):
        hints.append("check --pose-topic (and --map-frame / --robot-frame for /tf); if the poses' header "
                     "stamps come from another clock than the camera's, try --clock bag")
    tolerance = _tolerance_hint(summary.image_interval, summary.skipped)
    if tolerance:
        hints.append(tolerance)
    if summary.sampling == "travel" and summary.image_interval and any(
            "along the way: no image" in why for why in summary.skipped):
        hints.append("--at images makes a sample at each camera image")
    if not summary.skipped and summary.sampling == "utterances":
        hints.append("no utterance on the speech topic: choose --at travel or --at images")
    return "no sample has every modality: " + reasons + ("; " + "; ".join(hints) if hints else "")


def _add_clock_warnings(streams: _Streams, summary: BagImportSummary) -> None:
    for topic, offsets in streams.header_offsets.items():
        if offsets:
            median = float(np.median(np.asarray(offsets, dtype=np.float64))) / _NS
            if abs(median) > _HEADER_OFFSET_WARNING_S:
                summary.warnings.append(
                    f"{topic}: header stamps are {median:+.1f} s away from the bag's record times (a clock "
                    "not synchronised with the recorder, or simulated time?); if samples are skipped for a "
                    "missing modality, try --clock bag"
                )
