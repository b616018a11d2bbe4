"""What ``spco serve`` checks before a request reaches an endpoint, and the page's sessions.

:class:`Guard` (pure ASGI middleware, outermost) in order:

1. ``Host`` among the accepted names (DNS rebinding: a page whose name resolves to this machine
   is refused, 400);
2. the token: ``Authorization: Bearer TOKEN`` or a live session cookie (401; the page's ``/``
   shows the sign-in form instead);
3. browser-borne requests: a state-changing request (POST, PUT, PATCH, DELETE) whose ``Origin``
   (or ``Sec-Fetch-Site: cross-site``) is not this server is refused (403), and its body must be
   ``Content-Type: application/json`` (415; only ``/login`` and ``/logout`` take the page's form);
4. the body: at most the endpoint's limit (413, from ``Content-Length`` before reading, or while
   reading; a body carrying ``"visual"`` counts at most ``visual_limit``, before it is parsed),
   read whole within ``body_timeout`` seconds (408, and the connection is closed), with all bodies
   being read at once holding at most ``max_buffered`` bytes (503).

An answer the client does not read within ``send_timeout`` seconds (its connection's buffers
full) ends the connection. Every answer gets ``X-Frame-Options: DENY``, a
``Content-Security-Policy`` (``frame-ancestors 'none'``; scripts, styles and connections from this
server only), ``X-Content-Type-Options: nosniff`` and ``Referrer-Policy: no-referrer``. When a
:class:`~spco.service.connections.ConnectionGuard` is given, it is told when a request starts and
when its answer was sent (its header timer).
"""

from __future__ import annotations

import asyncio
import hashlib
import hmac
import secrets
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from starlette.responses import HTMLResponse, Response

from spco.service.errors import error_response

__all__ = ["LOOPBACK_HOSTS", "PAGE", "SECURITY_HEADERS", "SESSION_COOKIE", "Guard", "Sessions", "login_html"]

#: The page's session cookie.
SESSION_COOKIE = "spco_session"
#: The page's files (HTML, JS, CSS).
PAGE = Path(__file__).with_name("page")
#: The host names every server answers to (``--allowed-host`` adds more).
LOOPBACK_HOSTS = ["127.0.0.1", "localhost", "[::1]", "::1"]

Scope = dict[str, Any]
Receive = Callable[[], Awaitable[dict[str, Any]]]
Send = Callable[[dict[str, Any]], Awaitable[None]]



def login_html(message: str | None = None) -> str:
    """The sign-in page (with an error ``message``)."""
    text = (PAGE / "login.html").read_text(encoding="utf-8")
    if message:
        from html import escape

        text = text.replace("<!--message-->", f"<p class=error>{escape(message)}</p>")
    return text


#: The headers every answer carries.
SECURITY_HEADERS = [
    (b"x-frame-options", b"DENY"),
    (b"content-security-policy", b"default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' "
                                 b"data:; connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; "
                                 b"form-action 'self'; object-src 'none'"),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
]
_STATE_CHANGING = frozenset({"POST", "PUT", "PATCH", "DELETE"})
#: What a server with a token answers without it: the sign-in page and its style.
OPEN_PATHS = frozenset({"/login", "/page/style.css"})
#: Endpoints that take the page's form (application/x-www-form-urlencoded) instead of JSON.
FORM_PATHS = frozenset({"/login", "/logout"})


class Sessions:
    """The page's sessions: random ids, each valid for ``lifetime`` seconds, revocable one by one
    (``POST /logout``) or all at once (``DELETE /sessions``; a restart also ends them all).

    The token is compared in constant time (:func:`hmac.compare_digest`); a session id is a random
    256-bit string that says nothing of the token. At most ``max_sessions`` live at once (the
    oldest is ended first).
    """

    def __init__(self, token: str, lifetime: float = 7 * 24 * 3600.0, max_sessions: int = 256) -> None:
        self._token = token.encode("utf-8")
        self.lifetime = float(lifetime)
        self.max_sessions = max_sessions
        self._sessions: dict[bytes, float] = {}  # sha256(session id) -> expiry (monotonic)

    def check_token(self, given: str) -> bool:
        """Whether ``given`` is the server's token (constant time)."""
        return hmac.compare_digest(given.strip().encode("utf-8"), self._token)

    def create(self) -> str:
        """A new session id, valid for :attr:`lifetime` seconds."""
        self._expire()
        while len(self._sessions) >= self.max_sessions:
            self._sessions.pop(next(iter(self._sessions)))
        session = secrets.token_urlsafe(32)
        self._sessions[hashlib.sha256(session.encode()).digest()] = time.monotonic() + self.lifetime
        return session

    def valid(self, session: str) -> bool:
        """Whether ``session`` is a live session id."""
        if not session:
            return False
        expiry = self._sessions.get(hashlib.sha256(session.encode("utf-8", "replace")).digest())
        return expiry is not None and expiry > time.monotonic()

    def revoke(self, session: str) -> bool:
        """End one session; whether it was live."""
        key = hashlib.sha256(session.encode("utf-8", "replace")).digest()
        return self._sessions.pop(key, None) is not None

    def revoke_all(self) -> int:
        """End every session; how many were live."""
        self._expire()
        count = len(self._sessions)
        self._sessions.clear()
        return count

    def _expire(self) -> None:
        now = time.monotonic()
        for key in [k for k, expiry in self._sessions.items() if expiry <= now]:
            del self._sessions[key]


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope.get("headers") or ():
        if key == name:
            return value.decode("latin-1")
    return None


def _host_name(host: str) -> str:
    """The name part of a ``Host`` value (``[::1]:8765`` → ``[::1]``, ``robot:80`` → ``robot``)."""
    host = host.strip().lower()
    if host.startswith("["):
        return host[: host.find("]") + 1] if "]" in host else host
    return host.rsplit(":", 1)[0] if host.count(":") == 1 else host


class Guard:
    """The checks before every endpoint (see the module). ``settings`` is the app's
    :class:`~spco.service.app.ServeSettings`; ``body_limit(method, path)`` the largest body of an
    endpoint, bytes; ``sessions`` ``None`` without a token."""

    def __init__(self, app: Any, *, settings: Any, sessions: Sessions | None, token: str | None,
                 body_limit: Callable[[str, str], int], connections: Any = None,
                 visual_limit: int | None = None) -> None:
        self.app = app
        self.settings = settings
        self.sessions = sessions
        self.token = None if token is None else token.encode("utf-8")
        self.body_limit = body_limit
        self.visual_limit = visual_limit
        self.connections = connections
        self.hosts = None if settings.allowed_hosts is None else {h.lower() for h in settings.allowed_hosts}
        self.buffered = 0

    # ------------------------------------------------------------------ checks
    def _host_ok(self, scope: Scope) -> bool:
        if self.hosts is None or "*" in self.hosts:
            return True
        host = _header(scope, b"host")
        return host is not None and _host_name(host) in self.hosts

    def _authorised(self, scope: Scope) -> bool:
        if self.token is None:
            return True
        auth = _header(scope, b"authorization") or ""
        if auth[:7].lower() == "bearer " and hmac.compare_digest(auth[7:].strip().encode("latin-1"),
                                                                 self.token):
            return True
        for part in (_header(scope, b"cookie") or "").split(";"):
            name, _, value = part.strip().partition("=")
            if name == SESSION_COOKIE and self.sessions is not None and self.sessions.valid(value):
                return True
        return False

    def _cross_site(self, scope: Scope) -> str | None:
        """Why a state-changing request comes from another site, or ``None``."""
        if _header(scope, b"sec-fetch-site") == "cross-site":
            return "a cross-site request (Sec-Fetch-Site: cross-site)"
        origin = _header(scope, b"origin")
        if origin is None:
            return None  # not a browser (curl, the client, ROS): nothing to check
        if origin == "null":
            return "a request from an opaque origin (Origin: null)"
        allowed = {o.lower().rstrip("/") for o in self.settings.allowed_origins}
        if origin.lower().rstrip("/") in allowed:
            return None
        host = (_header(scope, b"host") or "").lower()
        _, _, origin_host = origin.lower().partition("://")
        if origin_host and origin_host == host:
            return None  # the page of this server (behind a proxy too: the proxy keeps Host)
        return f"a cross-site request (Origin: {origin[:100]} is not this server)"

    # ------------------------------------------------------------------ ASGI
    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        client = tuple(scope["client"]) if scope.get("client") else None
        connections = self.connections
        if connections is not None and client is not None:
            connections.request_started(client)  # the headers are in

        async def send_with_headers(message: dict[str, Any]) -> None:
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []), *SECURITY_HEADERS]}
            try:
                async with asyncio.timeout(self.settings.send_timeout):  # a client that does not read
                    await send(message)
            except TimeoutError:
                if connections is not None and client is not None:
                    connections.abort(client)
                raise
            if connections is not None and client is not None and message["type"] == "http.response.body" \
                    and not message.get("more_body"):
                connections.response_sent(client)

        refusal = self._refusal(scope)
        if refusal is not None:
            await refusal(scope, receive, send_with_headers)
            return
        method = scope["method"]
        length_text = _header(scope, b"content-length")
        has_body = length_text is not None or _header(scope, b"transfer-encoding") is not None
        if not has_body:
            await self.app(scope, receive, send_with_headers)
            return
        limit = self.body_limit(method, scope["path"])
        if length_text is not None and (not length_text.strip().isdigit() or int(length_text) > limit):
            await _closing(error_response(413, f"request body too large (at most {limit} bytes here)"))(
                scope, receive, send_with_headers)
            return
        if connections is not None and client is not None:
            connections.reading_body(client)
        body, problem = await self._read_body(receive, limit)
        if connections is not None and client is not None:
            connections.request_started(client)
        if problem is not None:
            if problem != "gone":
                await problem(scope, receive, send_with_headers)
            return
        if self.visual_limit is not None and len(body) > self.visual_limit and b'"visual"' in body:
            # a body this long holds an image; its visual counts would be longer than any view's
            await _closing(error_response(413, f"request body too large for visual counts (at most "
                                               f"{self.visual_limit} bytes with them)"))(
                scope, receive, send_with_headers)
            return
        sent = False

        async def replay() -> dict[str, Any]:
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send_with_headers)

    def _refusal(self, scope: Scope) -> Response | None:
        if not self._host_ok(scope):
            return error_response(400, "this server does not answer to that Host name (spco serve "
                                       "--allowed-host NAME to add one)")
        path, method = scope["path"], scope["method"]
        if path not in OPEN_PATHS and not self._authorised(scope):
            if method == "GET" and path == "/":
                response: Response = HTMLResponse(login_html(), status_code=401)
            else:
                response = error_response(401, "this server needs its token: Authorization: Bearer TOKEN "
                                               "(the content of the server's --token-file) or the page's "
                                               "session (sign in at /login)")
            response.headers["WWW-Authenticate"] = "Bearer"
            return response
        if method in _STATE_CHANGING:
            why = self._cross_site(scope)
            if why is not None:
                return error_response(403, f"refused: {why}; a page of another site cannot teach this robot")
            length = _header(scope, b"content-length")
            if (length is not None and length.strip() != "0") or _header(scope, b"transfer-encoding"):
                kind = (_header(scope, b"content-type") or "").split(";")[0].strip().lower()
                wanted = ("application/x-www-form-urlencoded",) if path in FORM_PATHS \
                    else ("application/json",)
                if kind not in wanted:
                    return error_response(415, f"expected a JSON body (Content-Type: {wanted[0]}), got "
                                               f"{kind or 'none'!r}")
        return None

    async def _read_body(self, receive: Receive, limit: int) -> tuple[bytes, Any]:
        """The whole body within the limit and the time; ``(b"", answer)`` when refused, ``"gone"``
        for a client that left."""
        chunks: list[bytes] = []
        size = 0
        deadline = asyncio.get_running_loop().time() + self.settings.body_timeout
        try:
            while True:
                remaining = deadline - asyncio.get_running_loop().time()
                if remaining <= 0:
                    raise TimeoutError
                message = await asyncio.wait_for(receive(), remaining)
                if message["type"] == "http.disconnect":
                    return b"", "gone"
                chunk = message.get("body", b"")
                size += len(chunk)
                if size > limit:
                    return b"", _closing(error_response(413, f"request body too large (at most {limit} bytes "
                                                             "here)"))
                if self.buffered + len(chunk) > self.settings.max_buffered:
                    return b"", _closing(error_response(503, "the server is reading too many request bodies "
                                                             "at once; try again shortly"))
                self.buffered += len(chunk)
                chunks.append(chunk)
                if not message.get("more_body"):
                    break
        except TimeoutError:
            return b"", _closing(error_response(408, f"the request body did not arrive within "
                                                     f"{self.settings.body_timeout:g} s"))
        finally:
            self.buffered -= sum(len(c) for c in chunks)
        return b"".join(chunks), None


def _closing(response: Response) -> Response:
    """``response`` with ``Connection: close``: the rest of a refused body is not read."""
    response.headers["Connection"] = "close"
    return response
