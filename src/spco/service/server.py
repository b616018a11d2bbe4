"""Running ``spco serve``: the token, the address rules, uvicorn, and an orderly stop.

:func:`serve` binds the socket itself (so that ``--port 0`` can print the port it got), opens the
:class:`~spco.service.LiveHome` (taking the home's lock, naming this server's address), runs the
app (:func:`spco.service.app.create_app`) on uvicorn until Ctrl-C or SIGTERM, then closes the home
(pending teachings compacted into the file, lock released).
"""

from __future__ import annotations

import contextlib
import ipaddress
import os
import signal
import socket
import stat
import sys
import threading
from collections.abc import Callable
from os import PathLike
from pathlib import Path
from typing import Any

from spco.errors import ConfigurationError
from spco.service.security import LOOPBACK_HOSTS

__all__ = ["LOOPBACK_HOSTS", "MIN_TOKEN_CHARS", "accepted_hosts", "is_loopback", "is_wildcard", "read_token",
           "serve", "warm_requests"]

#: The shortest token accepted.
MIN_TOKEN_CHARS = 16


def is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address (127.0.0.0/8, ::1) or ``localhost``."""
    if host.strip().lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def read_token(path: str | PathLike[str], warn: Callable[[str], None] | None = None) -> str:
    """The token in the file ``path`` (its first line, stripped), at least :data:`MIN_TOKEN_CHARS`
    characters; ``warn`` is told when other users may read the file. Raises :class:`ConfigurationError`."""
    file = Path(path).expanduser()
    try:
        text = file.read_text(encoding="utf-8")
        mode = file.stat().st_mode
    except (OSError, UnicodeDecodeError) as exc:
        problem = getattr(exc, "strerror", None) or exc
        raise ConfigurationError(f"{file}: cannot read the token file ({problem})") from None
    lines = text.strip().splitlines()
    token = lines[0].strip() if lines else ""
    if len(token) < MIN_TOKEN_CHARS or any(c.isspace() for c in token):
        raise ConfigurationError(f"{file}: the token must be one line of at least {MIN_TOKEN_CHARS} "
                                 "characters without spaces (e.g. python -c 'import secrets; "
                                 f"print(secrets.token_urlsafe(32))' > {file})")
    if warn is not None and mode & (stat.S_IRGRP | stat.S_IROTH):
        warn(f"{file} can be read by other users of this machine (chmod 600 {file})")
    return token


def _bind(host: str, port: int) -> socket.socket:
    family = socket.AF_INET6 if ":" in host.strip("[]") else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host.strip("[]"), port))
    except OSError as exc:
        sock.close()
        raise ConfigurationError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    sock.listen(2048)
    sock.set_inheritable(True)
    return sock


def warm_requests(address: str, token: str | None, home: Any, timeout: float = 60.0) -> list[int]:
    """Send the requests of every route once to the server at ``address`` (``http://host:port``), so
    that the first real one of each kind does not pay for what a server does first (the HTTP stack's
    first request, each route's validation and answer schema, JSON, the page's files, the writer's
    pipe both ways): ``/health``, the page, ``where`` of a name of ``home``, ``what`` by pose and
    (when the home has views) with a view, ``ask``, ``/regions``, ``/openapi.json``, and a teaching
    and an undo that the writer refuses (a sample id the home does not have, a seq never given), so
    that nothing is taught. Returns the HTTP status of each (a request that fails is skipped: this
    is a warm-up, the server answers without it)."""
    import http.client
    import json
    from urllib.parse import quote, urlsplit

    import numpy as np

    parts = urlsplit(address)
    headers = {"Host": f"localhost:{parts.port}", "Accept": "application/json"}
    if token is not None:
        headers["Authorization"] = f"Bearer {token}"
    x, y = (float(v) for v in home.positions[0, :2])
    theta = float(np.arctan2(home.positions[0, 2], home.positions[0, 3]))
    pose = {"x": x, "y": y, "theta": theta}
    names = list(home.known_names)
    missing = int(home.ids.max()) + 1_000_000
    requests: list[tuple[str, str, dict[str, Any] | None]] = [
        ("GET", "/health", None), ("GET", "/", None), ("GET", f"/what?x={x}&y={y}&theta={theta}&top=3", None),
        ("POST", "/what", {**pose, "top": 3}), ("GET", "/ask?n=1", None), ("GET", "/regions", None),
        ("GET", "/openapi.json", None),
        ("POST", "/teach", {"id": missing, "sentence": "this is the kitchen"}),
        ("POST", "/teach", {"x": x, "y": y}), ("DELETE", f"/teach/{10**12}", None)]
    if names:
        requests.insert(2, ("GET", f"/where?name={quote(names[0])}&n=10", None))
    if home.knowledge.n_features and not bool(home.view_missing[0]):
        visual = np.asarray(home.visual[[0]].toarray()[0]).tolist()
        requests.insert(4, ("POST", "/what", {**pose, "top": 3, "visual": visual}))
    statuses = []
    connection = http.client.HTTPConnection(parts.hostname or "127.0.0.1", parts.port, timeout=timeout)
    try:
        for method, path, body in requests:  # one connection, kept alive, as a client would
            data = None if body is None else json.dumps(body).encode()
            sent = {**headers, **({"Content-Type": "application/json"} if data is not None else {})}
            try:
                connection.request(method, path, body=data, headers=sent)
                response = connection.getresponse()
                response.read()
                statuses.append(response.status)
            except (OSError, http.client.HTTPException):
                connection.close()
    finally:
        connection.close()
    return statuses


def _server_class() -> type:
    import uvicorn

    class Server(uvicorn.Server):  # type: ignore[misc]
        """uvicorn's server, stopping in order on SIGINT and SIGTERM without raising the signal again
        afterwards (uvicorn does, which would end the process before the home is closed), and
        running :attr:`when_started` (in a thread, the server answering meanwhile) once it listens."""

        when_started: Callable[[], None] | None = None

        async def startup(self, sockets: Any = None) -> None:
            import asyncio

            await super().startup(sockets=sockets)
            if self.when_started is not None and not self.should_exit:
                await asyncio.get_running_loop().run_in_executor(None, self.when_started)

        @contextlib.contextmanager
        def capture_signals(self) -> Any:
            if threading.current_thread() is not threading.main_thread():
                yield
                return
            original = {sig: signal.signal(sig, self.handle_exit) for sig in (signal.SIGINT, signal.SIGTERM)}
            try:
                yield
            finally:
                for sig, handler in original.items():
                    signal.signal(sig, handler)

    return Server


def is_wildcard(host: str) -> bool:
    """Whether ``host`` is a wildcard address (every interface)."""
    return host.strip().lower() in ("0.0.0.0", "::", "[::]", "")


def accepted_hosts(host: str, token: str | None, extra: list[str] | tuple[str, ...] = ()) -> list[str] | None:
    """The ``Host`` names a server bound to ``host`` answers to: the loopback names, ``host`` itself
    (unless a wildcard address) and ``extra``; ``None`` (any) for a wildcard address with a token and
    no ``extra`` (the token protects it then; give ``--allowed-host`` to check names too)."""
    name = host.strip().lower()
    wildcard = is_wildcard(name)
    if wildcard and token is not None and not extra:
        return None
    hosts = [*LOOPBACK_HOSTS, *(h.strip().lower() for h in extra if h.strip())]
    if not wildcard:
        hosts.append(f"[{name.strip('[]')}]" if ":" in name.strip("[]") else name)
    return sorted(set(hosts))


def _run(server: Any, sock: socket.socket, warm: Callable[[], None], announce: Callable[[], None]) -> None:
    """Run the uvicorn ``server`` on ``sock`` until Ctrl-C or SIGTERM; once it listens (requests are
    answered meanwhile), ``warm`` (:func:`warm_requests`), then ``announce`` (the line that says
    ready)."""

    def ready() -> None:
        warm()
        announce()

    server.when_started = ready
    server.run(sockets=[sock])


def serve(home: str | PathLike[str], host: str = "127.0.0.1", port: int = 8765, token_file: str | None = None,
          map_image: str | None = None, map_extent: tuple[float, float, float, float] | None = None,
          seed: int | None = None, writer: str = "process", say: Callable[[str], None] | None = None, *,
          header_timeout: float = 10.0, keep_alive: float = 5.0, max_connections: int | None = None,
          max_header_bytes: int = 64 * 1024, allowed_hosts: list[str] | tuple[str, ...] = (),
          undo_limit: int | None = None, limits: Any = "default",
          attach: Callable[[Any], Callable[[], None]] | None = None, **settings: Any) -> None:
    """Serve the home file ``home`` over HTTP until interrupted (see :mod:`spco.service.app`).

    Binds ``host`` only if it is loopback or a ``token_file`` is given (else
    :class:`ConfigurationError`); ``port`` 0 takes a free port. ``say`` prints the address and
    what start-up found (default: standard error). ``header_timeout``, ``keep_alive``,
    ``max_connections`` (default: the open-file limit less a reserve) and ``max_header_bytes``
    bound connections (:class:`~spco.service.connections.ConnectionGuard`); ``allowed_hosts``
    adds ``Host`` names (:func:`accepted_hosts`); ``settings`` are fields of
    :class:`~spco.service.app.ServeSettings` (body, image, event limits). ``undo_limit``,
    ``limits``: the teachings' (:class:`~spco.service.LiveHome`; ``"default"``:
    :data:`spco.knowledge.DEFAULT_LIMITS`). ``attach`` is called with
    the resident home (:class:`~spco.service.live.LiveHome`) once it is open and returns what to
    call before it closes (``spco serve --foxglove`` attaches its Foxglove stream so).
    """
    import uvicorn

    _Server = _server_class()
    from spco.service.app import ServeSettings, create_app
    from spco.service.connections import ConnectionGuard
    from spco.service.live import LiveHome

    say = say or (lambda text: print(text, file=sys.stderr, flush=True))
    token = None
    if token_file is not None:
        token = read_token(token_file, warn=lambda text: say(f"warning: {text}"))
    elif not is_loopback(host):
        raise ConfigurationError(f"refusing to serve on {host} without a token: other machines could read "
                                 "and teach this home; give --token-file FILE (and put TLS in front: a "
                                 "reverse proxy, see docs/on-the-robot.md), or serve on 127.0.0.1")
    sock = _bind(host, port)
    bound = sock.getsockname()[1]
    shown = f"[{host.strip('[]')}]" if ":" in host.strip("[]") else host
    address = f"http://{shown}:{bound}"
    try:
        from spco import knowledge as kn

        live = LiveHome(home, seed=seed, writer=writer, holder=f"spco serve (pid {os.getpid()}) at {address}",
                        undo_limit=undo_limit, limits=kn.DEFAULT_LIMITS if limits == "default" else limits)
    except BaseException:
        sock.close()
        raise
    try:
        if live.startup.get("replayed"):
            say(f"Replayed {live.startup['replayed']} teachings from {live.journal_path} and compacted them "
                f"into {home}.")
        detach = attach(live) if attach is not None else None
        options = ServeSettings(map_image=None if map_image is None else Path(map_image),
                                map_extent=map_extent,
                                allowed_hosts=accepted_hosts(host, token, allowed_hosts),
                                **settings)
        connections = ConnectionGuard(header_timeout=header_timeout, keep_alive=keep_alive,
                                      max_connections=max_connections, max_header_bytes=max_header_bytes)
        app = create_app(live, token=token, settings=options, connections=connections)
        config = uvicorn.Config(app, http=connections.protocol(), log_level="warning", access_log=False,
                                lifespan="off", timeout_keep_alive=max(1, round(keep_alive)),
                                timeout_graceful_shutdown=3, server_header=False, date_header=False)
        h = live.home
        local = f"http://{'[::1]' if ':' in host.strip('[]') else '127.0.0.1'}:{bound}"

        def warm() -> None:  # the warm-up's answers are nobody's: not streamed
            with live.quiet():
                warm_requests(local if is_wildcard(host) else address, token, h)

        try:
            _run(_Server(config), sock, warm,
                 lambda: say(f"Serving home {h.name} ({h.n_samples} samples, {h.n_taught} taught) from "
                             f"{home} at {address}/ (page), {address}/openapi.json (API); writer process "
                             f"{live.writer_pid}. Ctrl-C to stop."))
        finally:
            if detach is not None:
                detach()
    finally:
        live.close()
        sock.close()
        say(f"Stopped; every teaching is in {home}.")
