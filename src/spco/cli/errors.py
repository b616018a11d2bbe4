"""How every ``spco`` command reports the errors a user can cause.

An :class:`~spco.errors.SpcoError` (bad file, bad argument) becomes one line ``error: ...`` on
standard error and exit status 2, without a traceback; Ctrl-C exits with 130. A warning (e.g.
knowledge that does not fit a home, a pose off the map) is one line ``warning: ...`` on standard
error. Kept apart from
:mod:`spco.cli.main` so that the command modules can use it without importing the command line.
"""

from __future__ import annotations

import functools
import sys
import warnings
from collections.abc import Callable
from typing import Any

import click

from spco.errors import SpcoError


def friendly_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Decorate a click command so that spco's own errors end it with a one-line message."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            with warnings.catch_warnings():
                warnings.filterwarnings("default", category=UserWarning)
                warnings.showwarning = _show_warning
                return func(*args, **kwargs)
        except SpcoError as exc:
            click.echo(f"error: {exc}", err=True)
            sys.exit(2)
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            sys.exit(130)

    return wrapper


def _show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                  file: Any = None, line: str | None = None) -> None:
    """Print a user warning as one line ``warning: ...`` on standard error (no source location)."""
    if issubclass(category, UserWarning):
        click.echo(f"warning: {message}", err=True)
    else:
        warnings._showwarnmsg_impl(warnings.WarningMessage(message, category, filename, lineno, file, line))
