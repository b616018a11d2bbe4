"""The command-line options of a served home's teaching limits and undo (``spco serve``, ``spco ros``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

__all__ = ["limits_from_options", "teaching_limit_options"]


def teaching_limit_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """Add ``--undo-limit`` and the :class:`spco.knowledge.TeachingLimits` options to ``command``."""
    from spco.knowledge.limits import DEFAULT_LIMITS
    from spco.service.teaching import DEFAULT_UNDO_LIMIT

    options = [
        click.option("--undo-limit", default=DEFAULT_UNDO_LIMIT, show_default=True, type=click.IntRange(0),
                     help="How many of the last teachings can be undone exactly (the home before them is "
                          "kept in HOME.undo)."),
        click.option("--max-sentence-words", default=DEFAULT_LIMITS.max_sentence_words, show_default=True,
                     type=click.IntRange(1), help="Words one taught sentence may have."),
        click.option("--max-new-words", default=DEFAULT_LIMITS.max_new_words, show_default=True,
                     type=click.IntRange(0), help="Words the home never heard that one teaching may bring."),
        click.option("--max-home-words", default=DEFAULT_LIMITS.max_home_words, show_default=True,
                     type=click.IntRange(0),
                     help="Words of its own (beyond the knowledge's) the home may hold."),
        click.option("--max-observations-per-minute", default=DEFAULT_LIMITS.max_observations_per_minute,
                     show_default=True, type=click.IntRange(0),
                     help="New observations (poses taught) the home takes a minute."),
    ]
    for option in reversed(options):
        command = option(command)
    return command


def limits_from_options(options: dict[str, Any]) -> Any:
    """The :class:`spco.knowledge.TeachingLimits` of the options :func:`teaching_limit_options` added
    (removed from ``options``)."""
    from spco.knowledge.limits import TeachingLimits

    return TeachingLimits(
        max_sentence_words=options.pop("max_sentence_words"), max_new_words=options.pop("max_new_words"),
        max_home_words=options.pop("max_home_words"),
        max_observations_per_minute=options.pop("max_observations_per_minute"))
