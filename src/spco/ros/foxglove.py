"""A home for Foxglove: its learnt places as ``foxglove.SceneUpdate`` entities, live over the Foxglove
WebSocket protocol (``spco serve --foxglove PORT``, ``spco ros2 --foxglove PORT``) and in MCAP files
(``spco show HOME --mcap FILE``), with ``foxglove-sdk`` (``pip install 'spco[foxglove]'``).

Topics (all in the map frame, ``map`` unless given):

- ``/spco/scene`` (``foxglove.SceneUpdate``): one entity per learnt region, ``region/<index>``: its 95 %
  ellipse (a line loop), a translucent flat cylinder of the same ellipse and its names with their
  probabilities (a text label), coloured by the region's concept as ``spco show`` and the ROS markers
  colour it; each update deletes every earlier entity first, so regions that are gone disappear;
- ``/spco/teachings`` (``foxglove.SceneUpdate``): the taught samples, ``teaching/<id>``: a sphere
  at the pose and the sentence;
- ``/spco/answers`` (``foxglove.SceneUpdate``): the last answer, entity ``answer``: a ``where``'s
  best poses as arrows with the name, a ``what``'s names at the pose;
- ``/spco/log`` (``foxglove.Log``): one line per teaching, undo and answer (live only).

The entities carry ``metadata`` (``concept``, ``samples``, ``names``; ``sentence``) for Foxglove's
inspectors. In an MCAP file every message is written at the time of writing; its ``spco`` metadata
record names the home and the format (:data:`MCAP_FORMAT`).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from spco.errors import ConfigurationError, SpcoError
from spco.ros.messages import concept_colour, ellipse_axes, places_text

__all__ = ["MCAP_FORMAT", "TOPICS", "FoxgloveStream", "FoxgloveUnavailableError", "answer_update",
           "protobuf_class", "read_mcap", "require_foxglove", "scene_update", "teachings_update",
           "write_mcap"]

#: The ``spco`` metadata record of an MCAP file written by :func:`write_mcap`.
MCAP_FORMAT = {"format": "spco-foxglove-scene", "version": "1"}
#: The channels' topics.
TOPICS = {"scene": "/spco/scene", "teachings": "/spco/teachings", "answers": "/spco/answers",
          "log": "/spco/log"}
_ELLIPSE_POINTS = 48


class FoxgloveUnavailableError(SpcoError, ImportError):
    """foxglove-sdk (or mcap, to read a file back) is not installed."""


def require_foxglove() -> Any:
    """Import foxglove-sdk; a clear :class:`FoxgloveUnavailableError` when it is missing."""
    try:
        import foxglove
        import foxglove.messages
    except ImportError:
        raise FoxgloveUnavailableError("foxglove-sdk is not installed: pip install 'spco[foxglove]' "
                                       "(or pip install foxglove-sdk mcap)") from None
    return foxglove


def _stamp(seconds: float) -> Any:
    from foxglove.messages import Timestamp

    whole = math.floor(seconds)
    return Timestamp(sec=int(whole), nsec=min(round((seconds - whole) * 1e9), 999_999_999))


def _pose(x: float, y: float, z: float = 0.0, yaw: float = 0.0) -> Any:
    from foxglove.messages import Pose, Quaternion, Vector3

    return Pose(position=Vector3(x=float(x), y=float(y), z=float(z)),
                orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0)))


def _color(rgb: Sequence[float], alpha: float) -> Any:
    from foxglove.messages import Color

    return Color(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=float(alpha))


def _deletion(now: float) -> Any:
    from foxglove.messages import SceneEntityDeletion, SceneEntityDeletionType

    return SceneEntityDeletion(timestamp=_stamp(now), type=SceneEntityDeletionType.All, id="")


def scene_update(regions: Sequence[Mapping[str, Any]], n_concepts: int, frame: str = "map",
                 now: float | None = None, top_names: int = 3) -> Any:
    """A ``foxglove.SceneUpdate`` of the learnt regions (``regions`` as
    :func:`spco.service.answers.regions_answer` lists them): first a deletion of every entity, then
    one entity per region (ellipse outline, translucent fill, and the places `where` finds there with
    p(region | name), :func:`~spco.ros.messages.places_text`; metadata: the names `what` answers at its
    centre and the places)."""
    require_foxglove()
    from foxglove.messages import (
        CylinderPrimitive,
        KeyValuePair,
        LinePrimitive,
        LinePrimitiveLineType,
        Point3,
        SceneEntity,
        SceneUpdate,
        TextPrimitive,
        Vector3,
    )

    now = time.time() if now is None else now
    entities = []
    for region in regions:
        mx, my = (float(v) for v in list(region["mean"])[:2])
        major, minor, angle = ellipse_axes(region["covariance"])
        rgb = concept_colour(int(region["concept"]), n_concepts)
        c, s = math.cos(angle), math.sin(angle)
        points = []
        for k in range(_ELLIPSE_POINTS):
            a = 2.0 * math.pi * k / _ELLIPSE_POINTS
            ex, ey = major * math.cos(a), minor * math.sin(a)
            points.append(Point3(x=mx + c * ex - s * ey, y=my + s * ex + c * ey, z=0.0))
        names = list(region.get("names") or ())[:top_names]
        label = places_text(region, top_names)  # where `where` goes for a place: its label
        entities.append(SceneEntity(
            timestamp=_stamp(now), frame_id=frame, id=f"region/{int(region['region'])}",
            lines=[LinePrimitive(type=LinePrimitiveLineType.LineLoop, pose=_pose(0.0, 0.0), thickness=0.04,
                                 scale_invariant=False, points=points, color=_color(rgb, 1.0))],
            cylinders=[CylinderPrimitive(pose=_pose(mx, my, 0.0, angle),
                                         size=Vector3(x=max(2 * major, 1e-3), y=max(2 * minor, 1e-3), z=0.01),
                                         bottom_scale=1.0, top_scale=1.0, color=_color(rgb, 0.25))],
            texts=[TextPrimitive(pose=_pose(mx, my, 0.3), billboard=True, font_size=14.0,
                                 scale_invariant=True, color=_color(rgb, 1.0), text=label)] if label else [],
            metadata=[KeyValuePair(key="concept", value=str(int(region["concept"]))),
                      KeyValuePair(key="samples", value=str(int(region.get("samples", 0)))),
                      KeyValuePair(key="names", value=json.dumps(names)),
                      KeyValuePair(key="places", value=json.dumps(list(region.get("places") or ())))]))
    return SceneUpdate(deletions=[_deletion(now)], entities=entities)


def teachings_update(samples: Sequence[Mapping[str, Any]], frame: str = "map",
                     now: float | None = None) -> Any:
    """A ``foxglove.SceneUpdate`` of the taught samples (``{"id", "x", "y", "theta", "sentence"}``; those
    without a sentence are left out): a small sphere at each and its sentence."""
    require_foxglove()
    from foxglove.messages import (
        KeyValuePair,
        SceneEntity,
        SceneUpdate,
        SpherePrimitive,
        TextPrimitive,
        Vector3,
    )

    now = time.time() if now is None else now
    entities = []
    for sample in samples:
        sentence = str(sample.get("sentence") or "").strip()
        if not sentence:
            continue
        x, y = float(sample["x"]), float(sample["y"])
        entities.append(SceneEntity(
            timestamp=_stamp(now), frame_id=frame, id=f"teaching/{int(sample['id'])}",
            spheres=[SpherePrimitive(pose=_pose(x, y, 0.05), size=Vector3(x=0.12, y=0.12, z=0.12),
                                     color=_color((1.0, 1.0, 1.0), 0.9))],
            texts=[TextPrimitive(pose=_pose(x, y, 0.2), billboard=True, font_size=11.0, scale_invariant=True,
                                 color=_color((0.9, 0.9, 0.9), 1.0), text=sentence)],
            metadata=[KeyValuePair(key="sentence", value=sentence),
                      KeyValuePair(key="theta", value=f"{float(sample.get('theta', 0.0)):.4f}")]))
    return SceneUpdate(deletions=[_deletion(now)], entities=entities)


def answer_update(event: Mapping[str, Any], frame: str = "map", now: float | None = None) -> Any:
    """A ``foxglove.SceneUpdate`` of one answer (an ``answer`` event of
    :meth:`LiveHome.subscribe <spco.service.live.LiveHome.subscribe>`): a ``where``'s poses as arrows
    and its name, a ``what``'s names at its pose. Entity ``answer`` replaces the previous one."""
    require_foxglove()
    from foxglove.messages import ArrowPrimitive, SceneEntity, SceneUpdate, TextPrimitive

    now = time.time() if now is None else now
    arrows, texts = [], []
    highlight = _color((1.0, 0.85, 0.1), 1.0)
    if event.get("kind") == "where":
        positions = list(event.get("positions") or ())
        for p in positions:
            arrows.append(ArrowPrimitive(pose=_pose(p["x"], p["y"], 0.1, p["theta"]), shaft_length=0.35,
                                         shaft_diameter=0.05, head_length=0.15, head_diameter=0.12,
                                         color=highlight))
        if positions:
            texts.append(TextPrimitive(pose=_pose(positions[0]["x"], positions[0]["y"], 0.5), billboard=True,
                                       font_size=16.0, scale_invariant=True, color=highlight,
                                       text=f"where: {event.get('name')}"))
    elif event.get("kind") == "what":
        pose = event.get("pose") or {}
        names = ", ".join(f"{n['name']} {float(n.get('probability', 0.0)):.2f}"
                          for n in event.get("names") or ())
        if "x" in pose:
            arrows.append(ArrowPrimitive(pose=_pose(pose["x"], pose["y"], 0.1, pose.get("theta", 0.0)),
                                         shaft_length=0.35, shaft_diameter=0.05, head_length=0.15,
                                         head_diameter=0.12, color=highlight))
            texts.append(TextPrimitive(pose=_pose(pose["x"], pose["y"], 0.5), billboard=True, font_size=16.0,
                                       scale_invariant=True, color=highlight, text=f"what: {names}"))
    return SceneUpdate(entities=[SceneEntity(timestamp=_stamp(now), frame_id=frame, id="answer",
                                             arrows=arrows, texts=texts)])


def _log_line(event: Mapping[str, Any]) -> str:
    kind = event.get("type")
    if kind == "taught":
        return f"taught {event.get('sentence')!r} (sample {event.get('id')}, seq {event.get('seq')})"
    if kind == "undone":
        return f"undone seq {event.get('seq')}"
    if event.get("kind") == "where":
        return f"where {event.get('name')!r}: {len(event.get('positions') or ())} poses"
    names = ", ".join(str(n.get("name")) for n in event.get("names") or ())
    return f"what at {event.get('pose')}: {names}"


def _write_atomically(path: Path, write: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(handle)
    try:
        os.unlink(temporary)  # open_mcap creates the file itself
        write(temporary)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_mcap(regions: Mapping[str, Any], n_concepts: int, path: str | os.PathLike[str], frame: str = "map",
               now: float | None = None) -> Path:
    """Write a home's learnt regions and teachings (``regions`` as
    :func:`spco.service.answers.regions_answer` returns them) to the MCAP file ``path`` (atomically):
    one ``SceneUpdate`` on ``/spco/scene`` and one on ``/spco/teachings``, and an ``spco`` metadata
    record (:data:`MCAP_FORMAT`, the home's name, its names). Returns the path."""
    foxglove = require_foxglove()
    from foxglove.channels import SceneUpdateChannel

    out = Path(path)
    if out.is_dir():
        raise ConfigurationError(f"--mcap {out}: a folder, not a file")
    now = time.time() if now is None else now
    log_time = int(now * 1e9)

    def write(target: str) -> None:
        context = foxglove.Context()
        writer = foxglove.open_mcap(target, context=context)
        try:
            scene = SceneUpdateChannel(TOPICS["scene"], context=context)
            teachings = SceneUpdateChannel(TOPICS["teachings"], context=context)
            scene.log(scene_update(regions["regions"], n_concepts, frame, now), log_time=log_time)
            teachings.log(teachings_update(regions.get("samples") or (), frame, now), log_time=log_time)
            writer.write_metadata("spco", {**MCAP_FORMAT, "home": str(regions.get("home", "")),
                                           "names": json.dumps(list(regions.get("names") or ())),
                                           "frame": frame})
        finally:
            writer.close()

    _write_atomically(out, write)
    return out


def read_mcap(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read an MCAP file of :func:`write_mcap` (or a recording of the live stream) back, with the
    ``mcap`` library and protobuf: ``{"metadata": {name: {...}}, "messages": [{"topic", "log_time",
    "schema", "message"}]}`` with each message decoded (a protobuf message object)."""
    try:
        import google.protobuf  # noqa: F401  (protobuf_class decodes with it)
        from mcap.reader import make_reader
    except ImportError:
        raise FoxgloveUnavailableError("reading MCAP needs mcap and protobuf: pip install 'spco[foxglove]'") \
            from None
    classes: dict[int, Any] = {}
    result: dict[str, Any] = {"metadata": {}, "messages": []}
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        for record in reader.iter_metadata():
            result["metadata"][record.name] = dict(record.metadata)
        for schema, channel, message in reader.iter_messages():
            if schema is None or schema.encoding != "protobuf":
                continue
            if schema.id not in classes:
                classes[schema.id] = protobuf_class(schema.name, schema.data)
            result["messages"].append({"topic": channel.topic, "log_time": message.log_time,
                                       "schema": schema.name,
                                       "message": classes[schema.id].FromString(message.data)})
    return result


def protobuf_class(name: str, file_descriptor_set: bytes) -> Any:
    """The protobuf message class ``name`` of a schema given as a serialised ``FileDescriptorSet`` (as
    MCAP schemas and the Foxglove WebSocket protocol's ``advertise`` carry them, the latter base64'd)."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(file_descriptor_set).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


class FoxgloveStream:
    """The home, live, over the Foxglove WebSocket protocol: the scene and teachings on start, again
    after every teaching or undo and to every client that subscribes; answers as they are given.

    Parameters
    ----------
    live: the resident home (:class:`~spco.service.live.LiveHome`).
    port: the WebSocket port (``0``: any free one; see :attr:`port`). host: the address to bind.
    frame: the map frame of the entities.
    """

    def __init__(self, live: Any, port: int, host: str = "127.0.0.1", frame: str = "map") -> None:
        foxglove = require_foxglove()
        from foxglove.channels import LogChannel, SceneUpdateChannel

        self.live, self.frame = live, frame
        self.n_concepts = int(live.home.knowledge.n_concepts)
        self.context = foxglove.Context()
        self.channels = {"scene": SceneUpdateChannel(TOPICS["scene"], context=self.context),
                         "teachings": SceneUpdateChannel(TOPICS["teachings"], context=self.context),
                         "answers": SceneUpdateChannel(TOPICS["answers"], context=self.context),
                         "log": LogChannel(TOPICS["log"], context=self.context)}
        self._lock = threading.Lock()
        stream = self

        class _Listener:
            def on_subscribe(self, client: Any, channel: Any) -> None:
                if channel.topic in (TOPICS["scene"], TOPICS["teachings"]):
                    threading.Thread(target=stream.publish_scene, daemon=True).start()

        try:
            self.server = foxglove.start_server(name=f"spco {live.home.name}", host=host, port=port,
                                                context=self.context, server_listener=_Listener())
        except Exception as exc:  # the SDK raises its own error for a port in use
            raise ConfigurationError(f"--foxglove {port}: cannot serve on {host}:{port} ({exc})") from None
        self.port = int(self.server.port)
        self.publish_scene()
        self._subscription = live.subscribe(self._on_event)

    def publish_scene(self) -> None:
        """Send the regions and teachings as they are now."""
        regions = self.live.regions()
        now = time.time()
        with self._lock:
            self.channels["scene"].log(scene_update(regions["regions"], self.n_concepts, self.frame, now))
            self.channels["teachings"].log(teachings_update(regions.get("samples") or (), self.frame, now))

    def _on_event(self, event: dict[str, Any]) -> None:
        from foxglove.messages import Log, LogLevel

        kind = event.get("type")
        if kind in ("taught", "undone"):
            threading.Thread(target=self.publish_scene, daemon=True).start()  # off the writer's thread
        elif kind == "answer":
            with self._lock:
                self.channels["answers"].log(answer_update(event, self.frame))
        with self._lock:
            self.channels["log"].log(Log(timestamp=_stamp(time.time()),
                                         level=LogLevel.Info, message=_log_line(event), name="spco"))

    def close(self) -> None:
        """Stop the server and stop listening to the home."""
        self._subscription.close()
        self.server.stop()
