"""What several ``spco`` commands share: checking where a command will write, reading ``--extent``,
and loading a home with its journal's teachings. The command modules import this module and
:mod:`spco.cli.errors`, never each other."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import click

from spco.errors import ConfigurationError

__all__ = ["check_out", "load_home", "parse_extent", "settings_hyperparameters"]


def check_out(path: Path, force: bool) -> None:
    """Refuse early (before any long computation) to write where the user would lose a file."""
    if path.is_dir():
        raise ConfigurationError(f"{path} is a folder; give the name of the file to write (--out)")
    if not path.expanduser().resolve().parent.is_dir():
        raise ConfigurationError(f"cannot write {path}: the folder {str(path.parent)!r} does not exist")
    if path.exists() and not force:
        raise ConfigurationError(f"{path} already exists; pass --force to replace it")


def parse_extent(text: str | None) -> tuple[float, float, float, float] | None:
    """``--extent x_min,x_max,y_min,y_max`` (metres, increasing) as four floats; ``None`` when not given."""
    if text is None:
        return None

    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 4 or not all(math.isfinite(v) for v in values) or values[0] >= values[1] \
            or values[2] >= values[3]:
        raise ConfigurationError(f"--extent must be x_min,x_max,y_min,y_max in metres (increasing), "
                                 f"got {text!r}")
    return values  # type: ignore[return-value]


def settings_hyperparameters(settings: tuple[str, ...] | list[str]) -> Any:
    """The transfer models' hyperparameters of ``--set NAME=VALUE`` options on their defaults
    (:meth:`~spco.model.hyperparameters.TransferHyperparameters.with_settings`), or ``None`` when none
    is given; a bad setting is a usage error of ``--set`` naming it."""
    if not settings:
        return None
    from spco.model.hyperparameters import TransferHyperparameters

    try:
        return TransferHyperparameters().with_settings(list(settings))
    except ConfigurationError as exc:
        raise click.BadParameter(str(exc), param_hint="--set") from None


def load_home(home_file: Path) -> Any:
    """The home of ``home_file`` with the teachings of its journal (a home served by ``spco serve``,
    or one whose server stopped without compacting): what the read-only commands answer with."""
    from spco.knowledge.locking import served_by
    from spco.service.teaching import load_current

    home, replayed = load_current(home_file)
    if replayed:
        server = served_by(home_file)
        origin = f"is served by {server}" if server else "has a journal"
        click.echo(f"note: {home_file} {origin}; answered with its {replayed} teaching(s) not yet compacted "
                   "into the file (replayed from its journal)", err=True)
    return home
