"""The requests a home answers, checked once where they enter: a pose, a view, and the four questions.

Every way into a home — HTTP (``spco serve``), ROS, the command line, the library's
:class:`~spco.service.LiveHome` — builds one of these frozen objects from what it received, and
the code below trusts it. Building one checks everything that can be checked without the home
(types, finiteness, ranges, which fields go together) and raises
:class:`~spco.errors.ConfigurationError` naming the field; what needs the home (a pose on its
map, a view of its dimension, a known sample) is checked where the home is at hand.

- :class:`Pose`: ``x``, ``y`` (metres), ``theta`` (radians, ``|θ| ≤ 2π``), finite numbers.
- :class:`View`: a camera view — an image (JPEG/PNG bytes, or raw pixels with ``encoding``,
  ``width`` and ``height``, or a uint8 array) or the view's visual counts (``visual``).
- :class:`Where`, :class:`What`, :class:`Teach`, :class:`Ask`, :class:`Undo`: the questions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from spco.errors import ConfigurationError
from spco.features.pixels import RAW_ENCODINGS

__all__ = ["ENCODINGS", "MAX_POSES", "MAX_QUESTIONS", "MAX_SENTENCE_CHARS", "MAX_TOP", "Ask", "Pose",
           "Teach", "Undo", "View", "What", "Where", "clean_sentence"]

#: Raw pixel encodings of a served view (ROS ``sensor_msgs/Image`` names) and their channels: those of
#: :data:`spco.features.pixels.RAW_ENCODINGS` without an alpha channel.
ENCODINGS = {name: channels for name, channels in RAW_ENCODINGS.items() if name in ("rgb8", "bgr8", "mono8")}
#: The most poses a ``where`` draws.
MAX_POSES = 1000
#: The most names a ``what`` lists.
MAX_TOP = 100
#: The most questions an ``ask`` lists.
MAX_QUESTIONS = 1000
#: The longest sentence a teaching may carry, in characters.
MAX_SENTENCE_CHARS = 1000
#: The longest place name asked for, in characters.
MAX_NAME_CHARS = 200
#: Sample ids and teaching seqs: integers of at most this magnitude.
MAX_ID = 2**62


def _number(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ConfigurationError(f"{name}: expected a number, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise ConfigurationError(f"{name}: expected a finite number, got {value!r}")
    return number


def _whole(name: str, value: object, low: int, high: int, what: str = "a whole number") -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise ConfigurationError(f"{name}: expected {what} from {low} to {high}, got {value!r}")
    if not low <= int(value) <= high:
        raise ConfigurationError(f"{name}: expected {what} from {low} to {high}, got {value!r}")
    return int(value)


def _set(obj: object, name: str, value: object) -> None:
    object.__setattr__(obj, name, value)


@dataclass(frozen=True, slots=True)
class Pose:
    """A robot's pose on the home's map: ``x``, ``y`` in metres, ``theta`` in radians (``|θ| ≤ 2π``).

    Raises :class:`ConfigurationError` for a value that is not a finite number, or a heading of more
    than a full turn (degrees given for radians). Whether the pose lies on a home's map is the
    home's to say (:func:`spco.knowledge.pose_outside_map`).
    """

    x: float
    y: float
    theta: float

    def __post_init__(self) -> None:
        for name in ("x", "y", "theta"):
            _set(self, name, _number(name, getattr(self, name)))
        if abs(self.theta) > 2 * math.pi + 1e-9:
            degrees = f"{self.theta:g}° = {math.radians(self.theta):.4f} rad"
            raise ConfigurationError(f"theta = {self.theta:g} is more than a full turn: the heading is in "
                                     f"radians (degrees? {degrees})")

    def row(self) -> np.ndarray:
        """The pose as the model's position features ``[x, y, sin θ, cos θ]`` (float64)."""
        return np.array([self.x, self.y, math.sin(self.theta), math.cos(self.theta)], dtype=np.float64)


@dataclass(frozen=True, slots=True)
class View:
    """A camera view: ``image`` or ``visual``, not both.

    ``image``: JPEG/PNG bytes (no ``encoding``); raw pixel bytes with ``encoding`` (``rgb8``,
    ``bgr8``, ``mono8``) and ``width``, ``height``; or a uint8 array (H, W, 3) or (H, W), whose
    ``encoding`` defaults to ``bgr8`` / ``mono8``. ``visual``: the view's visual counts (a vector of
    whole numbers ≥ 0; its length is the home's to check). ``encoding``, ``width`` and ``height``
    describe an image and are refused without one.
    """

    image: bytes | np.ndarray | None = None
    encoding: str | None = None
    width: int | None = None
    height: int | None = None
    visual: Any = None

    def __post_init__(self) -> None:
        if self.image is None and (self.encoding is not None or self.width is not None
                                   or self.height is not None):
            raise ConfigurationError("encoding, width and height describe an image; give the image too")
        if self.image is None and self.visual is None:
            raise ConfigurationError("a view needs an image or its visual counts (visual)")
        if self.image is not None and self.visual is not None:
            raise ConfigurationError("give the view either as visual counts or as an image, not both")
        if self.encoding is not None and self.encoding not in ENCODINGS:
            raise ConfigurationError(f"encoding: expected one of {', '.join(ENCODINGS)} (or none for "
                                     f"JPEG/PNG bytes), got {self.encoding!r}")
        for name in ("width", "height"):
            value = getattr(self, name)
            if value is not None:
                _set(self, name, _whole(name, value, 1, 65535, "a number of pixels"))
        image = self.image
        if isinstance(image, bytearray | memoryview):
            _set(self, "image", image := bytes(image))
        if isinstance(image, bytes):
            if self.encoding is None and (self.width is not None or self.height is not None):
                raise ConfigurationError("width and height go with raw pixels: give their encoding too (JPEG "
                                         "and PNG files carry their own size)")
            if self.encoding is not None and (self.width is None or self.height is None):
                raise ConfigurationError(f"image: raw {self.encoding} pixels need their width and height")
        elif image is not None and not isinstance(image, np.ndarray):
            raise ConfigurationError(f"image: expected JPEG/PNG bytes, raw pixel bytes or a uint8 array, got "
                                     f"{type(image).__name__}")

    @property
    def pixels(self) -> int | None:
        """Width × height when the view says them before its image is decoded (raw bytes, an array)."""
        if isinstance(self.image, np.ndarray) and self.image.ndim >= 2:
            return int(self.image.shape[0]) * int(self.image.shape[1])
        if self.width is not None and self.height is not None:
            return self.width * self.height
        return None


def clean_sentence(sentence: object, max_chars: int | None = MAX_SENTENCE_CHARS) -> str | None:
    """A taught sentence as a home keeps it: stripped of surrounding white space, ``None`` for no
    sentence (``None``, or nothing but white space). Raises :class:`~spco.errors.ConfigurationError`
    for anything but a string or ``None`` (null), and for a string longer than ``max_chars``
    (``None``: no limit)."""
    if sentence is None:
        return None
    if not isinstance(sentence, str):
        raise ConfigurationError(f"sentence: expected a string or null, got {type(sentence).__name__}")
    if max_chars is not None and len(sentence) > max_chars:
        raise ConfigurationError(f"sentence: {len(sentence)} characters; at most {max_chars}")
    return sentence.strip() or None


@dataclass(frozen=True, slots=True)
class Where:
    """Where is the place ``name``? ``n`` poses (1…:data:`MAX_POSES`) drawn with ``seed``."""

    name: str
    n: int = 10
    seed: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ConfigurationError("name: expected a place name")
        if len(self.name) > MAX_NAME_CHARS:
            raise ConfigurationError(f"name: {len(self.name)} characters; at most {MAX_NAME_CHARS}")
        _set(self, "n", _whole("n", self.n, 1, MAX_POSES, "a number of poses"))
        _set(self, "seed", _whole("seed", self.seed, 0, 2**63 - 1, "a seed"))


@dataclass(frozen=True, slots=True)
class What:
    """What is this place? The ``top`` names (1…:data:`MAX_TOP`) at ``pose``, with an optional ``view``."""

    pose: Pose
    view: View | None = None
    top: int = 3

    def __post_init__(self) -> None:
        if not isinstance(self.pose, Pose):
            raise ConfigurationError("pose: expected a Pose (x, y, theta)")
        if self.view is not None and not isinstance(self.view, View):
            raise ConfigurationError("view: expected a View")
        _set(self, "top", _whole("top", self.top, 1, MAX_TOP, "a number of names"))


@dataclass(frozen=True, slots=True)
class Teach:
    """A teaching: a ``sentence`` for the known sample ``id`` (no ``pose``), or a new observation at
    ``pose`` with an optional ``view`` and ``sentence`` (and ``id``: the new sample's id, which must
    be new to the home; without it the home gives the next free one). A sentence is stripped (empty:
    ``None``, which forgets a sample's sentence) and at most :data:`MAX_SENTENCE_CHARS` characters."""

    sentence: str | None = None
    id: int | None = None
    pose: Pose | None = None
    view: View | None = None

    def __post_init__(self) -> None:
        _set(self, "sentence", clean_sentence(self.sentence))
        if self.id is not None:
            _set(self, "id", _whole("id", self.id, -MAX_ID, MAX_ID, "an integer sample id"))
        if self.pose is None:
            if self.id is None:
                raise ConfigurationError("a teaching needs id and sentence (a known sample) or x, y and "
                                         "theta (a new observation)")
            if self.view is not None:
                raise ConfigurationError("a view goes with a new observation: give its pose x, y, theta too")
        elif not isinstance(self.pose, Pose):
            raise ConfigurationError("pose: expected a Pose (x, y, theta)")
        if self.view is not None and not isinstance(self.view, View):
            raise ConfigurationError("view: expected a View")

    @property
    def observation(self) -> bool:
        """Whether this is a new observation (a pose), not a sentence for a known sample."""
        return self.pose is not None


@dataclass(frozen=True, slots=True)
class Ask:
    """Where should the robot ask "what is this place?" — ``n`` questions (1…:data:`MAX_QUESTIONS`),
    only those worth asking with ``unsure_only``; ``criterion`` that of :func:`spco.knowledge.ask`
    (``None``: its default)."""

    n: int = 5
    unsure_only: bool = False
    criterion: str | None = field(default=None)

    def __post_init__(self) -> None:
        _set(self, "n", _whole("n", self.n, 1, MAX_QUESTIONS, "a number of questions"))
        if not isinstance(self.unsure_only, bool | np.bool_):
            raise ConfigurationError(f"unsure_only: expected true or false, got {self.unsure_only!r}")
        _set(self, "unsure_only", bool(self.unsure_only))
        if self.criterion is not None and self.criterion not in ("errors", "information"):
            raise ConfigurationError(f"criterion: expected 'errors' or 'information', got {self.criterion!r}")


@dataclass(frozen=True, slots=True)
class Undo:
    """Undo the teaching ``seq``."""

    seq: int

    def __post_init__(self) -> None:
        _set(self, "seq", _whole("seq", self.seq, 0, MAX_ID, "a teaching's seq"))
