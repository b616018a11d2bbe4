"""The command-line options of a served home's teaching limits and undo (``spco serve``, ``spco ros``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

__all__ = ["LibraryDefault", "limits_from_options", "teaching_limit_options"]


class LibraryDefault(click.Option):
    """An option whose default is a constant of the library, read (importing its module) when the
    command's help is shown or the command runs, not when the command is registered: registering
    ``spco serve`` and ``spco ros`` imports neither :mod:`spco.knowledge` nor Numba.

    ``library_default``: returns the default (called each time it is needed; the module is imported
    once)."""

    def __init__(self, *args: Any, library_default: Callable[[], Any], **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.library_default = library_default

    def get_default(self, ctx: click.Context, call: bool = True) -> Any:
        """The library's default (``ctx`` and ``call`` as :meth:`click.Option.get_default`'s)."""
        return self.library_default()


def _undo_limit() -> int:
    from spco.service.teaching import DEFAULT_UNDO_LIMIT

    return DEFAULT_UNDO_LIMIT


def _limit(name: str) -> Callable[[], int | None]:
    def default() -> int | None:
        from spco.knowledge.limits import DEFAULT_LIMITS

        return getattr(DEFAULT_LIMITS, name)

    return default


def teaching_limit_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """Add ``--undo-limit`` and the :class:`spco.knowledge.TeachingLimits` options to ``command``
    (their defaults the library's: :data:`spco.service.teaching.DEFAULT_UNDO_LIMIT`,
    :data:`spco.knowledge.DEFAULT_LIMITS`)."""
    options = [
        click.option("--undo-limit", cls=LibraryDefault, library_default=_undo_limit, show_default=True,
                     type=click.IntRange(0),
                     help="How many of the last teachings can be undone exactly (the home before them is "
                          "kept in HOME.undo)."),
        click.option("--max-sentence-words", cls=LibraryDefault, library_default=_limit("max_sentence_words"),
                     show_default=True, type=click.IntRange(1), help="Words one taught sentence may have."),
        click.option("--max-new-words", cls=LibraryDefault, library_default=_limit("max_new_words"),
                     show_default=True, type=click.IntRange(0),
                     help="Words the home never heard that one teaching may bring."),
        click.option("--max-home-words", cls=LibraryDefault, library_default=_limit("max_home_words"),
                     show_default=True, type=click.IntRange(0),
                     help="Words of its own (beyond the knowledge's) the home may hold."),
        click.option("--max-observations-per-minute", cls=LibraryDefault,
                     library_default=_limit("max_observations_per_minute"), show_default=True,
                     type=click.IntRange(0), help="New observations (poses taught) the home takes a minute."),
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
