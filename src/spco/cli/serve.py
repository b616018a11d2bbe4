"""``spco serve``: a home held in memory, answering over HTTP while the robot runs.

Registered in :mod:`spco.cli.main`; the web stack is imported when the command runs (``pip install
'spco[serve]'``).
"""

from __future__ import annotations

from pathlib import Path

import click

from spco.cli.errors import friendly_errors
from spco.cli.limits import limits_from_options, teaching_limit_options

__all__ = ["serve"]


@click.command(name="serve")
@click.argument("home_file", metavar="HOME", type=click.Path(path_type=Path))
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on; anything but loopback needs --token-file.")
@click.option("--port", default=8765, show_default=True, type=click.IntRange(0, 65535),
              help="Port (0: any free port, printed).")
@click.option("--token-file", type=click.Path(path_type=Path), default=None,
              help="A file holding the token every request needs (Authorization: Bearer TOKEN; the page "
                   "signs in with it).")
@click.option("--map", "map_image", type=click.Path(path_type=Path), default=None,
              help="A floor-plan image (PNG/JPEG) drawn under the page's regions.")
@click.option("--extent", default=None,
              help="x_min,x_max,y_min,y_max in metres covered by --map (default: the home's map extent).")
@click.option("--seed", default=None, type=click.IntRange(0),
              help="Base seed of the teachings (each is journalled with its own seed; default: random).")
@click.option("--writer", type=click.Choice(["process", "thread"]), default="process", hidden=True,
              help="Where teachings run: a writer process (default) or a thread of the server (for the "
                   "benchmark's comparison: readers then wait for Python's global lock).")
@teaching_limit_options
@friendly_errors
def serve(home_file: Path, host: str, port: int, token_file: Path | None, map_image: Path | None,
          extent: str | None, seed: int | None, writer: str, undo_limit: int, **limit_options: int) -> None:
    """Serve the home of HOME over HTTP: where, what and teach in milliseconds, and a page at /.

    \b
    spco serve home.spco                      # http://127.0.0.1:8765/ (the page)
    curl 'http://127.0.0.1:8765/what?x=1.2&y=-0.4&theta=1.57'
    curl 'http://127.0.0.1:8765/where?name=kitchen&n=5'
    curl -X POST http://127.0.0.1:8765/teach -H 'Content-Type: application/json' \\
         -d '{"id": 12, "sentence": "this is the study"}'

    Teachings are kept in HOME.journal (fsync'd before they are acknowledged) and compacted into
    HOME; while it is served, `spco teach HOME` is refused and the read-only commands replay the
    journal. A teaching beyond a limit (--max-…) is refused with HTTP 422 (429 for too many
    observations a minute) naming the limit; DELETE /teach/SEQ undoes one of the last --undo-limit
    teachings exactly. See docs/on-the-robot.md.
    """
    try:
        import fastapi  # noqa: F401
        import uvicorn  # noqa: F401
    except ImportError:
        raise click.UsageError("spco serve needs the web stack: pip install 'spco[serve]'") from None
    from spco.cli.knowledge import _extent
    from spco.service.server import serve as run

    run(home_file, host=host, port=port, token_file=None if token_file is None else str(token_file),
        map_image=None if map_image is None else str(map_image), map_extent=_extent(extent), seed=seed,
        writer=writer, say=lambda text: click.echo(text, err=True), undo_limit=undo_limit,
        limits=limits_from_options(limit_options))
