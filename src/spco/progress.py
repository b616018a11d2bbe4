"""Progress bars on standard error for long runs (fit, adapt, experiments, reading homes and bags).

A thin wrapper around `tqdm` that every long loop of spco uses, so that a bar is drawn the same
way everywhere: on standard error, and with a width even when the terminal reports none. A
pseudo-terminal that was never given a size (a terminal multiplexer before its first resize, a
CI runner, ``script``) reports 0 columns; tqdm then draws nothing at all, and a long ``spco fit``
looked as if it had hung. Such a terminal gets :data:`FALLBACK_COLUMNS` columns instead.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable
from typing import IO, Any

#: (columns, lines) given to a bar on a terminal that reports no size.
FALLBACK_SIZE = (80, 24)


def terminal_size(stream: IO[str] | None = None) -> tuple[int, int]:
    """(columns, lines) of the terminal behind ``stream`` (default: standard error); (0, 0) when
    ``stream`` is not a terminal."""
    stream = sys.stderr if stream is None else stream
    try:
        size = os.get_terminal_size(stream.fileno())
    except (AttributeError, OSError, ValueError):
        return 0, 0
    return size.columns, size.lines


def progress_bar(iterable: Iterable[Any] | None = None, *, file: IO[str] | None = None,
                 **options: Any) -> Any:
    """A ``tqdm`` bar on ``file`` (default: standard error), ``options`` passed to tqdm as they are.

    On a terminal that reports its size the bar follows it (and its resizes); otherwise it is drawn
    for a terminal of :data:`FALLBACK_SIZE`. ``disable=None`` (tqdm's "only on a terminal") works as in tqdm.
    Returns the tqdm object (iterate over it, or call ``update``/``close``).
    """
    from tqdm import tqdm

    stream = sys.stderr if file is None else file
    if not {"ncols", "nrows", "dynamic_ncols"} & options.keys():
        if min(terminal_size(stream)) > 0:
            options["dynamic_ncols"] = True
        else:
            options["ncols"], options["nrows"] = FALLBACK_SIZE
    return tqdm(iterable, file=stream, **options)
