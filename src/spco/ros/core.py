"""The node's logic, independent of the transport (rospy or rosbridge): what it keeps of the robot's
streams, how an utterance becomes a teaching, and how a query becomes an answer.

**Teaching.** An utterance (a ``std_msgs/String`` on the speech topic) is taught at the robot's pose
and camera frame nearest to it in time, each within ``tolerance`` seconds — the rule ``spco
import-bag`` uses. A frame taken just after the utterance may still be on its way, so the node
waits for one for at most ``image_wait`` seconds (default: the tolerance): it decides as soon as a
frame stamped at or after the utterance has arrived (a later one could only be farther), or as soon
as no later frame could be nearer than the last one before it, else when the wait is over. An
utterance with no pose or no frame within the tolerance is not taught: the node answers on the
answer topic with what is missing and what to change (a throttled camera needs a larger
``--tolerance``). Teachings run one after the other on a worker thread, through
:meth:`LiveHome.teach <spco.service.live.LiveHome.teach>`, which saves each durably (the journal of
``spco serve``) before it is acknowledged; the markers are published again after each.

**Times.** ``clock="receive"`` (the default) stamps every message with the time it reached the node
(ROS time: simulated time under ``use_sim_time``): a ``std_msgs/String`` has no stamp of its own,
and a companion computer's clock need not agree with the robot's. ``clock="header"`` uses the pose
and image messages' header stamps (when non-zero) — only for clocks kept in step (chrony, or a
bag played with ``--clock``).

**Queries** are JSON objects on the query topic; every answer echoes the query's ``id``:

- ``{"id": 7, "op": "where", "name": "kitchen", "n": 10, "goal": true}`` → the JSON of ``spco
  where --json``; with ``"goal": true`` (or the node's ``goal`` setting) the best pose is also
  published as a ``geometry_msgs/PoseStamped`` on the goal topic, for move_base or Nav2 — never
  by default;
- ``{"id": 8, "op": "what", "top": 3}`` → the JSON of ``spco what --json`` at the robot's current
  pose and view (``"x"``, ``"y"``, ``"theta"`` to ask about another pose; ``"view": false`` for the
  position alone);
- anything malformed → ``{"id": …, "error": "…"}`` naming the problem; the node stays up.
"""

from __future__ import annotations

import bisect
import json
import logging
import math
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from spco.errors import ConfigurationError, SpcoError
from spco.knowledge.requests import Pose, Teach, View, What, Where
from spco.ros.messages import (
    PoseReading,
    TfBuffer,
    frame_from_message,
    goal_message,
    marker_array,
    pose_array_message,
    pose_from_message,
)
from spco.service.live import LiveHome

__all__ = ["ANSWER_TOPIC", "GOAL_TOPIC", "MARKER_TOPIC", "QUERY_TOPIC", "WHERE_TOPIC", "NodeCore",
           "NodeSettings", "QueryError", "Topics"]

#: spco's own topics, the same on every transport (the robot's are options: :class:`Topics`).
QUERY_TOPIC = "/spco/query"
ANSWER_TOPIC = "/spco/answer"
GOAL_TOPIC = "/spco/goal"
MARKER_TOPIC = "/spco/markers"
WHERE_TOPIC = "/spco/where"


@dataclass(frozen=True)
class Topics:
    """The robot's topics: pose (a pose topic, or ``/tf``), camera (``None``: no camera) and speech
    (``None``: the node only answers queries)."""

    pose: str = "/tf"
    image: str | None = None
    speech: str | None = None

log = logging.getLogger("spco.ros")

#: Seconds of poses and frames kept (the longest tolerance or wait that makes sense).
HISTORY_SECONDS = 30.0
#: Ops a query may ask for.
QUERY_OPS = ("where", "what")


class QueryError(SpcoError, ValueError):
    """A query the node cannot answer; its message goes back on the answer topic."""


@dataclass(frozen=True)
class NodeSettings:
    """How the node matches utterances with poses and frames, and answers.

    tolerance: seconds an utterance's pose and frame may be from it (as ``import-bag --tolerance``).
    image_wait: seconds the node waits after an utterance for a frame (``None``: the tolerance).
    clock: ``receive`` (arrival times, the default) or ``header`` (header stamps).
    max_age: seconds after which the last pose and frame no longer count as "current" for ``what``.
    goal: publish a goal with every ``where`` answer (default: only when the query asks).
    map_frame: the frame of the map (poses in another frame are refused; the goal's frame).
    robot_frame: the robot's frame, for poses from tf.
    n: poses a ``where`` answers with by default; top: names a ``what`` answers with by default.
    """

    tolerance: float = 0.5
    image_wait: float | None = None
    clock: str = "receive"
    max_age: float = 2.0
    goal: bool = False
    map_frame: str = "map"
    robot_frame: str = "base_footprint"
    n: int = 10
    top: int = 3

    def __post_init__(self) -> None:
        if not (math.isfinite(self.tolerance) and self.tolerance > 0):
            raise ConfigurationError(f"--tolerance must be > 0 seconds, got {self.tolerance}")
        if self.image_wait is not None and not (math.isfinite(self.image_wait) and self.image_wait >= 0):
            raise ConfigurationError(f"--image-wait must be ≥ 0 seconds, got {self.image_wait}")
        if self.clock not in ("receive", "header"):
            raise ConfigurationError(f"--clock must be receive or header, got {self.clock!r}")
        if not (math.isfinite(self.max_age) and self.max_age > 0):
            raise ConfigurationError(f"--max-age must be > 0 seconds, got {self.max_age}")
        if self.n < 1 or self.top < 1:
            raise ConfigurationError("n and top must be at least 1")

    @property
    def wait(self) -> float:
        """Seconds to wait for a frame after an utterance."""
        return self.tolerance if self.image_wait is None else self.image_wait


class _Timeline:
    """Values in time order (seconds), the last :data:`HISTORY_SECONDS` of them."""

    def __init__(self) -> None:
        self.times: deque[float] = deque()
        self.values: deque[Any] = deque()
        self.lock = threading.Lock()

    def add(self, t: float, value: Any) -> None:
        with self.lock:
            if self.times and t < self.times[-1]:  # out of order: keep the line sorted
                index = bisect.bisect(list(self.times), t)
                self.times.insert(index, t)
                self.values.insert(index, value)
            else:
                self.times.append(t)
                self.values.append(value)
            while self.times and self.times[0] < self.times[-1] - HISTORY_SECONDS:
                self.times.popleft()
                self.values.popleft()

    def nearest(self, t: float) -> tuple[float, Any] | None:
        """``(time, value)`` nearest to ``t``, or ``None`` when empty."""
        with self.lock:
            if not self.times:
                return None
            times = list(self.times)
            i = bisect.bisect_left(times, t)
            best = min((k for k in (i - 1, i) if 0 <= k < len(times)), key=lambda k: abs(times[k] - t))
            return times[best], self.values[best]

    def last(self) -> tuple[float, Any] | None:
        with self.lock:
            return (self.times[-1], self.values[-1]) if self.times else None

    def has_at_or_after(self, t: float) -> bool:
        with self.lock:
            return bool(self.times) and self.times[-1] >= t


@dataclass(frozen=True)
class _Utterance:
    time: float
    sentence: str


class NodeCore:
    """The node: keeps the streams, teaches utterances, answers queries, publishes markers.

    Parameters
    ----------
    home: the resident home (:class:`~spco.service.live.LiveHome`).
    settings: :class:`NodeSettings`.
    publish_answer, publish_goal, publish_markers: send a message (as a dict: ``{"data": text}`` for
        the answer, a ``PoseStamped`` and a ``MarkerArray``) on the transport.
    publish_poses: send a ``where`` answer's positions as a ``geometry_msgs/PoseArray`` (a dict; most
        probable first), or ``None`` for a transport without one.
    now: the transport's clock (seconds; ROS time for rospy).
    uses_images: whether the home's views are images (else teachings cannot take a view from the
        camera, and ``what`` answers from the position).
    n_concepts: the number of concepts of the home's knowledge (chooses the markers' palette, as
        ``spco show`` does).
    """

    def __init__(self, home: LiveHome, settings: NodeSettings, *,
                 publish_answer: Callable[[dict[str, Any]], None],
                 publish_goal: Callable[[dict[str, Any]], None],
                 publish_markers: Callable[[dict[str, Any]], None],
                 publish_poses: Callable[[dict[str, Any]], None] | None = None,
                 now: Callable[[], float] = time.time, uses_images: bool = True,
                 n_concepts: int = 10) -> None:
        self.home = home
        self.settings = settings
        self._publish_answer = publish_answer
        self._publish_goal = publish_goal
        self._publish_markers = publish_markers
        self._publish_poses = publish_poses
        self.now = now
        self.uses_images = uses_images
        self.n_concepts = n_concepts
        self.poses = _Timeline()
        self.frames = _Timeline()
        self.tf = TfBuffer()
        self._utterances: queue.Queue[_Utterance | None] = queue.Queue()
        self._frame_arrived = threading.Condition()
        self._worker: threading.Thread | None = None
        self._home_lock = threading.Lock()  # one home operation at a time
        self.taught = 0
        self.answered = 0
        self.pose_frames_refused: set[str] = set()

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> None:
        """Publish the markers of the home as it is, and start the teaching worker."""
        self.publish_markers()
        self._worker = threading.Thread(target=self._teach_loop, name="spco-teach", daemon=True)
        self._worker.start()

    def stop(self, timeout: float = 10.0) -> None:
        """Finish the utterances already heard, then stop the worker."""
        if self._worker is not None:
            self._utterances.put(None)
            with self._frame_arrived:
                self._frame_arrived.notify_all()
            self._worker.join(timeout)
            self._worker = None

    # ------------------------------------------------------------------ streams
    def _time(self, stamp: float | None, received: float | None) -> float:
        if self.settings.clock == "header" and stamp is not None:
            return stamp
        return self.now() if received is None else received

    def on_pose(self, msg: Mapping[str, Any], received: float | None = None) -> None:
        """A pose message (PoseStamped, PoseWithCovarianceStamped or Odometry, as a dict)."""
        try:
            pose = pose_from_message(msg)
        except SpcoError as exc:
            log.warning("pose message ignored: %s", exc)
            return
        if pose.frame and pose.frame != self.settings.map_frame.lstrip("/"):
            if pose.frame not in self.pose_frames_refused:
                self.pose_frames_refused.add(pose.frame)
                log.warning("poses in frame %r ignored: the map frame is %r (--map-frame)", pose.frame,
                            self.settings.map_frame)
            return
        self.poses.add(self._time(pose.stamp, received), pose)

    def on_tf(self, msg: Mapping[str, Any], static: bool = False, received: float | None = None) -> None:
        """A ``tf2_msgs/TFMessage`` (from ``/tf``, or ``/tf_static`` with ``static``)."""
        self.tf.add(msg, static=static)
        pose = self.tf.lookup(self.settings.map_frame, self.settings.robot_frame)
        if pose is not None:
            self.poses.add(self._time(pose.stamp, received), pose)

    def on_image(self, msg: Mapping[str, Any], received: float | None = None) -> None:
        """An Image or CompressedImage (as a dict); decoded only if it is used."""
        try:
            frame = frame_from_message(msg)
        except SpcoError as exc:
            log.warning("image message ignored: %s", exc)
            return
        self.frames.add(self._time(frame.stamp, received), frame)
        with self._frame_arrived:
            self._frame_arrived.notify_all()

    def on_speech(self, text: str, received: float | None = None) -> None:
        """An utterance: queued to be taught at the pose and frame nearest to its time."""
        sentence = (text or "").strip()
        if sentence:
            self._utterances.put(_Utterance(self.now() if received is None else received, sentence))

    # ------------------------------------------------------------------ teaching
    def _teach_loop(self) -> None:
        while True:
            utterance = self._utterances.get()
            if utterance is None:
                return
            try:
                started = time.perf_counter()
                self._wait_for_frame(utterance.time)
                answer = self.teach_utterance(utterance.time, utterance.sentence,
                                              waited=time.perf_counter() - started)
                if "error" in answer:
                    log.warning("%s", answer["error"])
                self.answer(answer)
            except Exception as exc:  # the node stays up whatever one teaching does
                log.exception("teaching %r failed", utterance.sentence)
                self.answer({"id": None, "op": "teach", "sentence": utterance.sentence,
                             "error": f"internal error: {exc}"})

    def _wait_for_frame(self, t: float) -> None:
        """Wait until the frame nearest to time ``t`` is known: a frame at or after ``t`` has come, or no
        later frame could be nearer than the last one before ``t``, or the wait is over."""
        if not self.uses_images:
            return
        wait = self.settings.wait
        before = self.frames.nearest(t)
        if before is not None and before[0] <= t:  # a later frame is nearer only until t + (t - before)
            wait = min(wait, t - before[0])
        deadline = time.monotonic() + max(0.0, t + wait - self.now())
        with self._frame_arrived:
            while not self.frames.has_at_or_after(t):
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return
                self._frame_arrived.wait(min(remaining, 0.05))

    def teach_utterance(self, t: float, sentence: str, waited: float = 0.0) -> dict[str, Any]:
        """Teach ``sentence`` heard at time ``t`` at the nearest pose and frame; return the answer, with
        ``node_seconds``: the time the node spent waiting for the frame (``waited``), decoding it,
        teaching (``LiveHome.teach``: the view's features, the writer, the journal) and publishing
        the markers."""
        started = time.perf_counter()
        tol = self.settings.tolerance
        base: dict[str, Any] = {"id": None, "op": "teach", "sentence": sentence}
        pose_entry = self.poses.nearest(t)
        if pose_entry is None or abs(pose_entry[0] - t) > tol:
            got = ("no pose received yet" if pose_entry is None
                   else f"the nearest pose is {abs(pose_entry[0] - t):.2f} s away")
            return {**base, "error": f"not taught: no pose within {tol:g} s of the utterance ({got}); "
                    "check the pose topic, or raise --tolerance"}
        pose: PoseReading = pose_entry[1]
        view = None
        if self.uses_images:
            frame_entry = self.frames.nearest(t)
            if frame_entry is None or abs(frame_entry[0] - t) > tol:
                got = ("no camera frame received yet" if frame_entry is None
                       else f"the nearest frame is {abs(frame_entry[0] - t):.2f} s away")
                return {**base, "error": f"not taught: no camera frame within {tol:g} s of the utterance "
                        f"({got}); a throttled camera (one frame every 2 s) needs --tolerance 1 or more"}
            try:
                pixels, encoding = frame_entry[1].pixels()
            except SpcoError as exc:
                return {**base, "error": f"not taught: the camera frame cannot be read: {exc}"}
            view = View(image=pixels, encoding=encoding)
        decoded = time.perf_counter()
        try:
            request = Teach(sentence=sentence, pose=Pose(pose.x, pose.y, pose.theta), view=view)
            with self._home_lock:
                result = self.home.submit(request).result()
        except SpcoError as exc:
            return {**base, "error": f"not taught: {exc}"}
        self.taught += 1
        taught = time.perf_counter()
        self.publish_markers()
        timing = {"frame_wait": waited, "decode": decoded - started, "teach": taught - decoded,
                  "markers": time.perf_counter() - taught}
        log.info("taught %r at (%.2f, %.2f, %.2f): sample %s, seq %s", sentence, pose.x, pose.y, pose.theta,
                 result.get("id"), result.get("seq"))
        extra = {k: v for k, v in result.items() if k not in ("id", "op", "sentence")}
        return {**base, "sample": result.get("id"), **extra, "x": pose.x, "y": pose.y, "theta": pose.theta,
                "node_seconds": {k: round(v, 4) for k, v in timing.items()}}

    # ------------------------------------------------------------------ queries
    def on_query(self, text: str) -> dict[str, Any]:
        """Answer one query (the text of a String); publishes and returns the answer."""
        request_id: Any = None
        op: Any = None
        try:
            try:
                request = json.loads(text)
            except (TypeError, ValueError) as exc:
                raise QueryError(f"the query is not JSON ({exc}); expected e.g. "
                                 '{"id": 7, "op": "where", "name": "kitchen"}') from None
            if not isinstance(request, dict):
                raise QueryError(f"the query must be a JSON object, got {type(request).__name__}")
            request_id, op = request.get("id"), request.get("op")
            if op not in QUERY_OPS:
                raise QueryError(f"unknown op {op!r}: expected one of {', '.join(QUERY_OPS)}")
            answer = self._where(request) if op == "where" else self._what(request)
            answer = {"id": request_id, "op": op, **answer}
        except SpcoError as exc:
            answer = {"id": request_id, "op": op, "error": str(exc)}
        except Exception as exc:  # the node stays up whatever one query does
            log.exception("query %r failed", text)
            answer = {"id": request_id, "op": op, "error": f"internal error: {exc}"}
        self.answer(answer)
        return answer

    @staticmethod
    def _field(request: Mapping[str, Any], key: str, kind: type | tuple[type, ...], default: Any = None,
               required: bool = False) -> Any:
        if key not in request or request[key] is None:
            if required:
                raise QueryError(f"the query has no {key!r}")
            return default
        value = request[key]
        if isinstance(value, bool) and bool not in (kind if isinstance(kind, tuple) else (kind,)):
            raise QueryError(f"{key!r} must be {_kind_name(kind)}, got {value!r}")
        if not isinstance(value, kind):
            raise QueryError(f"{key!r} must be {_kind_name(kind)}, got {value!r}")
        if isinstance(value, float) and not math.isfinite(value):
            raise QueryError(f"{key!r} must be a finite number, got {value!r}")
        return value

    def _where(self, request: Mapping[str, Any]) -> dict[str, Any]:
        name = self._field(request, "name", str, required=True)
        n = self._field(request, "n", int, self.settings.n)
        if n < 1:
            raise QueryError(f"'n' must be at least 1, got {n}")
        goal = self._field(request, "goal", bool, self.settings.goal)
        with self._home_lock:
            answer = self.home.answer(Where(name, n))
        if self._publish_poses is not None:
            self._publish_poses(pose_array_message(answer.get("positions") or [], self.settings.map_frame))
        if goal:
            best = max(answer.get("positions") or [], key=lambda p: p.get("probability", 0.0), default=None)
            if best is None:
                raise QueryError(f"no pose to go to for {name!r}")
            self._publish_goal(goal_message(best["x"], best["y"], best["theta"], self.settings.map_frame))
            answer = {**answer, "goal": {"x": best["x"], "y": best["y"], "theta": best["theta"],
                                         "frame": self.settings.map_frame}}
        return answer

    def _what(self, request: Mapping[str, Any]) -> dict[str, Any]:
        top = self._field(request, "top", int, self.settings.top)
        if top < 1:
            raise QueryError(f"'top' must be at least 1, got {top}")
        use_view = self._field(request, "view", bool, True)
        number = (int, float)
        given = [k for k in ("x", "y", "theta") if request.get(k) is not None]
        now = self.now()
        if given:
            if len(given) < 3:
                raise QueryError("give all of 'x', 'y' and 'theta', or none for the robot's current pose")
            x, y, theta = (float(self._field(request, k, number)) for k in ("x", "y", "theta"))
        else:
            last = self.poses.last()
            if last is None:
                raise QueryError("no pose received yet: the robot's current pose is unknown (give 'x', 'y', "
                                 "'theta', or check the pose topic)")
            if self.settings.clock == "receive" and now - last[0] > self.settings.max_age:
                raise QueryError(f"the last pose is {now - last[0]:.1f} s old (more than --max-age "
                                 f"{self.settings.max_age:g} s): is the pose topic still published?")
            x, y, theta = last[1].x, last[1].y, last[1].theta
        view = None
        view_age = None
        if use_view and self.uses_images:
            frame = self.frames.last()
            if frame is not None and (self.settings.clock != "receive"
                                      or now - frame[0] <= self.settings.max_age):
                pixels, encoding = frame[1].pixels()
                view = View(image=pixels, encoding=encoding)
                view_age = round(now - frame[0], 3) if self.settings.clock == "receive" else None
        with self._home_lock:
            answer = self.home.answer(What(Pose(x, y, theta), view, top))
        return {**answer, "pose": {"x": x, "y": y, "theta": theta}, "view_age": view_age}

    # ------------------------------------------------------------------ output
    def answer(self, answer: Mapping[str, Any]) -> None:
        """Publish an answer (a JSON text in a String)."""
        log.debug("answer %s", answer)
        self.answered += 1
        self._publish_answer({"data": json.dumps(answer, ensure_ascii=False, default=_json_default)})

    def publish_markers(self) -> dict[str, Any]:
        """Publish the home's learnt regions as a MarkerArray; return it."""
        with self._home_lock:
            regions = self.home.regions()
        message = marker_array(regions["regions"], self.n_concepts, self.settings.map_frame)
        self._publish_markers(message)
        return message


def _kind_name(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    names = {int: "an integer", float: "a number", str: "a string", bool: "true or false"}
    return " or ".join(names.get(k, k.__name__) for k in kinds)


def _json_default(value: Any) -> Any:
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")

