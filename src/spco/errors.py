"""Exceptions that carry a message meant for the person who runs spco.

Every error a user can cause by what they pass in (a file, a folder, an argument) is raised as a
subclass of :class:`SpcoError`; the command line prints its message and exits with status 2, without
a traceback.
"""

from __future__ import annotations

from os import PathLike


class SpcoError(Exception):
    """Base class of the errors spco raises for bad input or bad configuration."""


class DataFormatError(SpcoError, ValueError):
    """A data file or folder is missing or malformed.

    Parameters
    ----------
    path:
        The file or folder at fault (shown first in the message).
    problem:
        What is wrong, and where possible what to do about it.
    """

    def __init__(self, path: str | PathLike[str] | None, problem: str) -> None:
        self.path = None if path is None else str(path)
        self.problem = problem
        super().__init__(problem if path is None else f"{path}: {problem}")


class ConfigurationError(SpcoError, ValueError):
    """An argument or hyperparameter is out of its valid range."""


class NotFoundError(ConfigurationError, LookupError):
    """A sample id or teaching seq the home does not have (HTTP 404)."""


class ConflictError(ConfigurationError):
    """A request that contradicts the home's current state (HTTP 409): an id taken, an undo of a
    teaching that a later one changed or that was undone already."""


class TeachingLimitError(SpcoError, ValueError):
    """A teaching beyond one of the home's limits (too long a sentence, too many new words in it
    or in the home, too many observations a minute). ``limit`` names the limit (its option, e.g.
    ``"max_new_words"``), ``value`` what the teaching would reach and ``allowed`` the limit."""

    http_status = 422

    def __init__(self, message: str, limit: str, value: int, allowed: int) -> None:
        self.limit, self.value, self.allowed = limit, value, allowed
        super().__init__(message)


class TeachingRateError(TeachingLimitError):
    """Teachings coming faster than the home's limit per minute (HTTP 429)."""

    http_status = 429


class ModelFileError(SpcoError, ValueError):
    """A saved model or knowledge file cannot be read (truncated, edited, wrong version)."""

    def __init__(self, path: str | PathLike[str], problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")
