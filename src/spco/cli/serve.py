"""``spco serve``: a home held in memory, answering over HTTP while the robot runs.

Registered in :mod:`spco.cli.main`; the web stack is imported when the command runs (``pip install
'spco[serve]'``).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

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
@click.option("--allowed-host", "allowed_hosts", multiple=True, metavar="NAME",
              help="A Host name the server answers to besides loopback and --host (repeat; e.g. the robot's "
                   "name behind a proxy). Others are refused (DNS rebinding).")
@click.option("--allowed-origin", "allowed_origins", multiple=True, metavar="URL",
              help="An origin (https://robot.example) whose pages may teach, besides the server's own.")
@click.option("--header-timeout", default=10.0, show_default=True, type=click.FloatRange(0.1),
              help="Seconds a connection has to send a request's headers.")
@click.option("--body-timeout", default=30.0, show_default=True, type=click.FloatRange(0.1),
              help="Seconds a request has to send its whole body.")
@click.option("--send-timeout", default=30.0, show_default=True, type=click.FloatRange(0.1),
              help="Seconds a client may leave an answer unread before its connection is closed.")
@click.option("--keep-alive", default=5.0, show_default=True, type=click.FloatRange(0.1),
              help="Seconds an idle kept-alive connection stays open.")
@click.option("--max-connections", default=None, type=click.IntRange(16),
              help="Connections open at once [default: the open-file limit less 64, at most 4096]; at the "
                   "limit the oldest connection still sending headers is closed.")
@click.option("--max-body", default=None, type=click.IntRange(1024),
              help="A cap on any request body, bytes [default: each endpoint's own, from the home: its "
                   "largest view].")
@click.option("--max-pixels", default=2048 * 2048, show_default=True, type=click.IntRange(64),
              help="The largest image accepted (width × height), checked from its header before decoding.")
@click.option("--decode-concurrency", default=2, show_default=True, type=click.IntRange(1),
              help="Images decoded at once (one 2048² decode is about 13 MB).")
@click.option("--max-subscribers", default=8, show_default=True, type=click.IntRange(1),
              help="Event streams (/events) open at once; a stream 256 events behind is closed.")
@click.option("--session-hours", default=168.0, show_default=True, type=click.FloatRange(0.01),
              help="How long a page's sign-in lasts.")
@click.option("--foxglove", "foxglove_port", default=None, type=click.IntRange(0, 65535), metavar="PORT",
              help="Also stream the home to Foxglove over its WebSocket protocol on this port (not serve's "
                   "own; Foxglove's default 8765 is serve's): the regions, names, teachings and answers as "
                   "SceneUpdate entities (needs spco[foxglove]).")
@click.option("--foxglove-host", default="127.0.0.1", show_default=True,
              help="Address of the Foxglove stream; it is read-only and has no token: anything but loopback "
                   "shows the home to whoever reaches the port.")
@teaching_limit_options
@friendly_errors
def serve(home_file: Path, host: str, port: int, token_file: Path | None, map_image: Path | None,
          extent: str | None, seed: int | None, writer: str, allowed_hosts: tuple[str, ...],
          allowed_origins: tuple[str, ...], header_timeout: float, body_timeout: float, send_timeout: float,
          keep_alive: float,
          max_connections: int | None, max_body: int | None, max_pixels: int, decode_concurrency: int,
          max_subscribers: int, session_hours: float, foxglove_port: int | None, foxglove_host: str,
          undo_limit: int, **limit_options: int) -> None:
    """Serve the home of HOME over HTTP: where, what and teach in milliseconds, and a page at /.

    \b
    spco serve home.spco                      # http://127.0.0.1:8765/ (the page)
    curl 'http://127.0.0.1:8765/what?x=1.2&y=-0.4&theta=1.57'
    curl 'http://127.0.0.1:8765/where?name=kitchen&n=5'
    curl -X POST http://127.0.0.1:8765/teach -H 'Content-Type: application/json' \\
         -d '{"id": 12, "sentence": "this is the study"}'

    Teachings are kept in HOME.journal (fsync'd before they are acknowledged) and compacted into
    HOME; while it is served, `spco teach HOME` is refused and the read-only commands replay the
    journal. Every connection, body, image and event stream has a limit (the options below; see
    docs/security.md). A teaching beyond a limit (--max-…-words, --max-observations-per-minute) is
    refused with HTTP 422 (429 for too many observations a minute) naming the limit; DELETE
    /teach/SEQ undoes one of the last --undo-limit teachings exactly.
    """
    try:
        import fastapi  # noqa: F401
        import uvicorn  # noqa: F401
    except ImportError:
        raise click.UsageError("spco serve needs the web stack: pip install 'spco[serve]'") from None
    from spco.cli.common import parse_extent
    from spco.service.server import serve as run

    attach = None
    if foxglove_port is not None:
        attach = _foxglove_attach(foxglove_port, foxglove_host, port)
    run(home_file, host=host, port=port, token_file=None if token_file is None else str(token_file),
        map_image=None if map_image is None else str(map_image), map_extent=parse_extent(extent), seed=seed,
        writer=writer, say=lambda text: click.echo(text, err=True), header_timeout=header_timeout,
        keep_alive=keep_alive, max_connections=max_connections, allowed_hosts=allowed_hosts,
        allowed_origins=list(allowed_origins), body_timeout=body_timeout, send_timeout=send_timeout,
        max_body=max_body,
        max_pixels=max_pixels, decode_concurrency=decode_concurrency, max_subscribers=max_subscribers,
        session_hours=session_hours, undo_limit=undo_limit, limits=limits_from_options(limit_options),
        attach=attach)


def _foxglove_attach(port: int, host: str, serve_port: int) -> Callable[[Any], Callable[[], None]]:
    """What starts the Foxglove stream on the served home (checked before the home is opened)."""
    from spco.errors import ConfigurationError
    from spco.ros.foxglove import FoxgloveStream, require_foxglove
    from spco.service.server import is_loopback

    if port != 0 and port == serve_port:
        raise ConfigurationError(f"--foxglove {port} is serve's own port (--port): give another, e.g. 8766")
    require_foxglove()
    if not is_loopback(host):
        click.echo(f"warning: the Foxglove stream on {host}:{port} has no token: whoever reaches it sees the "
                   "home (read-only)", err=True)

    def attach(live: Any) -> Callable[[], None]:
        stream = FoxgloveStream(live, port, host=host)
        click.echo(f"Foxglove: ws://{host}:{stream.port} (topics /spco/scene, /spco/teachings, "
                   "/spco/answers, /spco/log; frame map)", err=True)
        return stream.close

    return attach
