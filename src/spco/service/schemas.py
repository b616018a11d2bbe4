"""The JSON of ``spco serve``: request bodies that build :mod:`spco.knowledge.requests`, and answers.

The request models are strict (no extra fields, no strings for numbers, no NaN); each has
``to_request()``, which builds the library's checked request (:class:`~spco.knowledge.requests.What`,
:class:`~spco.knowledge.requests.Teach`): what the routes hand to the home. The answer models
document the answers in the OpenAPI schema (``/openapi.json``); the routes write the answers'
JSON themselves (a millisecond matters on ``what``).
"""

from __future__ import annotations

import base64
import binascii
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from spco.features.pixels import ImageError
from spco.knowledge.requests import MAX_ID, MAX_SENTENCE_CHARS, MAX_TOP, Pose, Teach, View, What

__all__ = ["AskAnswer", "ErrorAnswer", "HealthAnswer", "RegionsAnswer", "RevokedAnswer", "TeachAnswer",
           "TeachBody", "ViewBody", "WhatAnswer", "WhatBody", "WhereAnswer"]

Finite = Annotated[float, Field(strict=True, allow_inf_nan=False)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


def _decode_base64(text: str) -> bytes:
    try:
        return base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError):
        raise ImageError("image", "not valid base64") from None


class ViewBody(_Strict):
    """The optional camera view of a request: ``image`` (with ``encoding``, ``width``, ``height`` for
    raw pixels) or ``visual``."""

    image: str | None = Field(None, description="base64 of a JPEG or PNG file, or of raw pixels with "
                              "encoding, width and height")
    encoding: Literal["rgb8", "bgr8", "mono8"] | None = Field(
        None, description="raw pixels (ROS sensor_msgs/Image names); none for JPEG/PNG")
    width: int | None = Field(None, ge=1, le=65535)
    height: int | None = Field(None, ge=1, le=65535)
    visual: list[Annotated[int, Field(ge=0)]] | None = Field(
        None, description="the view's visual counts (the knowledge's dimension) instead of an image")

    def view(self) -> View | None:
        """The :class:`~spco.knowledge.requests.View` (``None`` for none); the image's base64 decoded."""
        if self.image is None and self.visual is None and self.encoding is None and self.width is None \
                and self.height is None:
            return None
        image = None if self.image is None else _decode_base64(self.image)
        return View(image=image, encoding=self.encoding, width=self.width, height=self.height,
                    visual=self.visual)


class WhatBody(ViewBody):
    """``POST /what``: a pose (metres, radians) and an optional view."""

    x: Finite
    y: Finite
    theta: Finite
    top: int = Field(3, ge=1, le=MAX_TOP)

    def to_request(self) -> What:
        """The checked :class:`~spco.knowledge.requests.What`."""
        return What(Pose(self.x, self.y, self.theta), self.view(), self.top)


class TeachBody(ViewBody):
    """``POST /teach``: ``{"id", "sentence"}`` for a known sample, or a pose ``{"x", "y", "theta",
    "sentence"}`` (+ an optional view) for a new observation."""

    sentence: str | None = Field(None, max_length=MAX_SENTENCE_CHARS)
    id: int | None = Field(None, ge=-MAX_ID, le=MAX_ID)
    x: Finite | None = None
    y: Finite | None = None
    theta: Finite | None = None

    def to_request(self) -> Teach:
        """The checked :class:`~spco.knowledge.requests.Teach`."""
        from spco.errors import ConfigurationError

        pose_given = [v is not None for v in (self.x, self.y, self.theta)]
        view = self.view()
        if self.id is not None:
            if any(pose_given) or view is not None:
                raise ConfigurationError("give either id and sentence (a known sample) or a pose x, y, theta "
                                         "with an optional view (a new observation), not both")
            return Teach(sentence=self.sentence, id=self.id)
        if any(pose_given) and not all(pose_given):
            raise ConfigurationError("a new observation needs all of x, y and theta")
        pose = Pose(self.x, self.y, self.theta) if all(pose_given) else None  # type: ignore[arg-type]
        return Teach(sentence=self.sentence, pose=pose, view=view)


class Position(BaseModel):
    x: float
    y: float
    theta: float
    probability: float


class WhereAnswer(BaseModel):
    """The answer of ``GET /where`` (as ``spco where --json``)."""

    home: str
    name: str = Field(description="the known name answered (a synonym's, for a name never said)")
    asked: str
    via: str | None = Field(None, description="how an unheard name was resolved (synonym, gloss, …)")
    region: int
    region_probability: float
    learnt: bool
    support: float
    called: str | None = Field(None, description="for a name not learnt: what `what` answers at the centre "
                               "of the answer region (the home's own name for that place)")
    positions: list[Position]


class NameScore(BaseModel):
    name: str
    probability: float
    score: float
    score_share: float


class WhatAnswer(BaseModel):
    """The answer of ``/what`` (as ``spco what --json``); ``warning`` for a pose off the map."""

    home: str
    pose: dict[str, float]
    vision: bool
    ranked_by: str
    answer: str | None
    confidence: float
    unsure: bool
    unsure_below: float
    names: list[NameScore]
    warning: str | None = None


class QuestionJSON(BaseModel):
    """A place to ask "what is this place?" on the wire: the JSON of
    :meth:`spco.knowledge.Question.to_dict` (as ``spco ask --json`` prints it)."""

    id: int
    x: float
    y: float
    theta: float
    gain: float
    reason: str
    names: list[dict[str, Any]]
    unknown: float
    confidence: float
    worth_asking: bool
    own_name: float = Field(0.0, description="the probability that the room has a name of its own")


class AskAnswer(BaseModel):
    """The answer of ``GET /ask`` (as ``spco ask --json``)."""

    home: str
    gain: str
    questions: list[QuestionJSON]


class TeachAnswer(BaseModel):
    """The answer of ``POST /teach`` and ``DELETE /teach/{seq}``."""

    model_config = ConfigDict(extra="allow")
    seq: int
    op: str
    teachings: int
    samples: int
    taught: int


class HealthAnswer(BaseModel):
    """The answer of ``GET /health``."""

    status: Literal["ok", "degraded"] = Field(description="degraded: the writer is gone (answers go on, "
                                                          "teachings are refused)")
    home: str
    samples: int
    taught: int
    teachings: int
    seq: int
    names: int
    writer: dict[str, Any]
    uptime_seconds: float


class RegionsAnswer(BaseModel):
    """The answer of ``GET /regions``: the learnt regions, concepts and samples, for drawing."""

    model_config = ConfigDict(extra="allow")
    home: str
    extent: list[float]
    names: list[str]
    concepts: list[dict[str, Any]]
    regions: list[dict[str, Any]]
    samples: list[dict[str, Any]]
    teachings: int
    seq: int
    map: dict[str, Any] | None


class RevokedAnswer(BaseModel):
    """``DELETE /sessions``: how many of the page's sessions were signed out."""

    revoked: int


class ErrorAnswer(BaseModel):
    """Every error: one message and the HTTP status."""

    error: str
    status: int
