"""The answer's settings (issue 29, "One predictor"): the hyperparameters that only the answers read —
``view_in_room`` and ``typical`` (:class:`AnswerSettings`) and ``name_answer`` — held by the model
(:class:`~spco.model.hyperparameters.TransferHyperparameters`) and read from it by every answer about
names (:func:`spco.model.confidence.answer_names`): ``spco what``, ``ask``'s question scores, the service,
the ROS node and the experiments."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from spco.errors import ConfigurationError

__all__ = ["ANSWER_ONLY", "LEARN", "AnswerSettings", "check_answer_settings", "with_answer_settings"]

#: ``TransferHyperparameters.typical`` of a model whose ρ is learnt from its experienced homes at fit time
#: (:func:`spco.knowledge.fit.learnt_typicality`); the fitted model holds the number.
LEARN = "learn"

#: The hyperparameters read by the answers only, never by a fit: set on a fitted knowledge's home
#: (``spco adapt --set``, :func:`with_answer_settings`).
ANSWER_ONLY = ("name_answer", "view_in_room", "typical")


def check_answer_settings(view_in_room: Any, typical: Any, learn: bool) -> None:
    """Raise :class:`~spco.errors.ConfigurationError` naming the field unless ``view_in_room`` is a
    bool and ``typical`` is ``None``, a number within (0, 1] or (with ``learn``) :data:`LEARN`, and not
    both ``view_in_room`` and ``typical`` (:func:`spco.model.rooms.concepts_by_room` answers one at a
    time)."""
    if not isinstance(view_in_room, bool | np.bool_):
        raise ConfigurationError(f"view_in_room must be true or false, got {view_in_room!r}")
    if typical is None:
        return
    if view_in_room:
        raise ConfigurationError(f"typical={typical!r} is not with view_in_room=true (one opt-in at a time)")
    if learn and typical == LEARN:
        return
    if isinstance(typical, bool | np.bool_) or not isinstance(typical, int | float | np.number) \
            or not 0.0 < float(typical) <= 1.0:
        allowed = "off, a number within (0, 1] or 'learn'" if learn else "off or a number within (0, 1]"
        raise ConfigurationError(f"typical must be {allowed}, got {typical!r}")


@dataclass(frozen=True)
class AnswerSettings:
    """The answer's opt-in settings, read from the model
    (:meth:`~spco.model.hyperparameters.TransferHyperparameters.answer_settings`) by every answer about
    names; an experiment that scores one fit two ways passes one explicitly (the override of
    :func:`spco.evaluation.metrics.evaluate_answers`).

    Attributes
    ----------
    view_in_room: the observation's view as a draw of its room's own distribution
        (:func:`spco.model.rooms.concepts_by_room`'s ``view_in_room``); default ``False``.
    typical: ρ within (0, 1], how often a room looks like its concept
        (:func:`spco.model.rooms.concepts_by_room`'s ``typical``); ``None`` (default): off.
    """

    view_in_room: bool = False
    typical: float | None = None

    def __post_init__(self) -> None:
        check_answer_settings(self.view_in_room, self.typical, learn=False)
        object.__setattr__(self, "view_in_room", bool(self.view_in_room))
        if self.typical is not None:
            object.__setattr__(self, "typical", float(self.typical))


def with_answer_settings(hyperparameters: Any, settings: Sequence[str]) -> Any:
    """A copy of ``hyperparameters`` (a :class:`~spco.model.hyperparameters.TransferHyperparameters`)
    with ``NAME=VALUE`` settings of the answer only (:data:`ANSWER_ONLY`; ``spco adapt --set``), which
    change no fit (:meth:`~spco.model.hyperparameters.TransferHyperparameters.with_settings`);
    ``typical=learn`` is learnt at fit time. Raises :class:`~spco.errors.ConfigurationError` naming the
    setting otherwise."""
    for setting in settings:
        name, _, text = (part.strip() for part in setting.partition("="))
        if name not in ANSWER_ONLY:
            raise ConfigurationError(f"hyperparameter setting {setting!r}: only the answer's settings "
                                     f"({', '.join(ANSWER_ONLY)}) are set after the fit")
        if name == "typical" and text.lower() == LEARN:
            raise ConfigurationError(f"hyperparameter setting {setting!r}: ρ is learnt from the "
                                     "experienced homes when the knowledge is fitted (spco fit --set "
                                     "typical=learn)")
    return hyperparameters.with_settings(settings)
