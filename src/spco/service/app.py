"""The HTTP app of ``spco serve``: a :class:`~spco.service.LiveHome` over HTTP + JSON (FastAPI, ASGI).

Endpoints (JSON unless said; the OpenAPI description is at ``/openapi.json``; the routes are in
:mod:`spco.service.routes`, the JSON in :mod:`spco.service.schemas`):

``GET /health``
    ``{"status": "ok", "home", "samples", "taught", "teachings", "seq", …}``.
``GET /where?name=NAME&n=N``
    the JSON of ``spco where HOME NAME -n N --json``.
``GET /what?x=&y=&theta=&top=K`` and ``POST /what``
    the JSON of ``spco what HOME … --json``; the POST body is ``{"x", "y", "theta", "top"}`` with an
    optional view: ``"image"`` (base64 of a JPEG or PNG file, or of raw pixels with ``"encoding"``:
    ``rgb8``, ``bgr8`` or ``mono8`` and ``"width"``, ``"height"``), or ``"visual"`` (counts).
``GET /ask?n=N``
    the JSON of ``spco ask HOME --n N --json``.
``POST /teach``
    ``{"x", "y", "theta", "sentence"}`` (+ an optional view, as for ``/what``) teaches a new
    observation, ``{"id", "sentence"}`` a sentence for a known sample; answers ``{"seq",
    "teachings", …}`` once the teaching is in the journal on disk.
``DELETE /teach/{seq}``
    undoes teaching ``seq`` (durably).
``GET /regions``
    the learnt regions, concepts and samples, for drawing (the page uses it).
``GET /events``
    Server-Sent Events: ``taught``, ``undone`` and ``answer`` events (``?types=taught,undone``
    picks some), a comment every 15 s to keep the connection open.
``GET /``
    the page (static HTML/JS/SVG, ``spco/service/page``); ``GET /map`` the map image, if any.
``GET /login`` / ``POST /login`` / ``POST /logout`` / ``DELETE /sessions``
    with a token: the sign-in form; signing in (the token in the form's body, never in a URL) sets
    the page's session cookie (HttpOnly, SameSite=Strict, an expiry, Secure over TLS); signing out
    ends that session, ``DELETE /sessions`` every session.

Errors are one JSON object ``{"error": message, "status": code}`` (:mod:`spco.service.errors`),
the framework's own included. What is checked before an endpoint runs — the ``Host``, the token,
cross-site requests, body sizes and times — is :mod:`spco.service.security`; connection limits and
header timeouts are :mod:`spco.service.connections`. ``docs/security.md`` is the threat model.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.responses import JSONResponse

from spco.errors import SpcoError
from spco.features.pixels import SERVED_MAX_PIXELS, ImageError, encoded_size
from spco.service.errors import FRAMEWORK_MESSAGES, answer_for, error_response, validation_answer
from spco.service.live import LiveHome
from spco.service.routes import EventHub, api, page
from spco.service.security import LOOPBACK_HOSTS, PAGE, SESSION_COOKIE, Guard, Sessions, login_html

__all__ = ["LOOPBACK_HOSTS", "PAGE", "SESSION_COOKIE", "ServeSettings", "create_app", "login_html"]

#: Bytes of a request body besides its view (the pose, the sentence, JSON's punctuation).
BODY_OVERHEAD = 8 * 1024
#: The longest text of one visual count in JSON, with its comma and a space.
_COUNT_CHARS = 22


@dataclass
class ServeSettings:
    """The limits and options of ``spco serve`` (the CLI's options; see ``docs/security.md``).

    Attributes
    ----------
    max_body: a cap on any request body, bytes (``None``: each endpoint's own limit, from the
        home: a view's largest image or visual vector).
    body_timeout: seconds to receive a whole request body.
    send_timeout: seconds a client may leave a part of an answer unread (its buffers full) before
        its connection is closed (an event stream that stops reading too).
    max_buffered: bytes of request bodies held at once across all requests.
    max_pixels: the largest image (width × height) accepted, checked from its header.
    decode_concurrency: images decoded at once; decode_queue: more waiting for that (else 503).
    max_subscribers: event streams open at once; subscriber_queue: events a stream may fall
        behind before its consumer is dropped; keepalive_comment: seconds between keep-alive
        comments of an idle stream.
    session_hours: how long a page's sign-in lasts.
    allowed_hosts: the ``Host`` names accepted (``None``: any; ``["*"]`` the same).
    allowed_origins: origins besides the server's own whose pages may change state (e.g. the
        address of a TLS proxy that rewrites ``Host``).
    map_image, map_extent: the page's floor plan and the metres it covers.
    """

    max_body: int | None = None
    body_timeout: float = 30.0
    send_timeout: float = 30.0
    max_buffered: int = 64 * 1024 * 1024
    max_pixels: int = SERVED_MAX_PIXELS
    decode_concurrency: int = 2
    decode_queue: int = 8
    max_subscribers: int = 8
    subscriber_queue: int = 256
    keepalive_comment: float = 15.0
    session_hours: float = 168.0
    allowed_hosts: list[str] | None = field(default_factory=lambda: list(LOOPBACK_HOSTS))
    allowed_origins: list[str] = field(default_factory=list)
    map_image: Path | None = None
    map_extent: tuple[float, float, float, float] | None = None


def view_body_limit(live: LiveHome, settings: ServeSettings) -> int:
    """The largest body of ``POST /what`` and ``POST /teach``: the home's largest view in JSON —
    base64 raw pixels of ``max_pixels`` × 3 for a knowledge fitted on images, the visual vector of
    its dimension otherwise — plus :data:`BODY_OVERHEAD`, capped by ``settings.max_body``."""
    knowledge = live.home.knowledge
    if knowledge.fitted_on_images:
        view = 4 * ((settings.max_pixels * 3 + 2) // 3)
    else:
        view = knowledge.n_features * _COUNT_CHARS
    limit = view + BODY_OVERHEAD
    return limit if settings.max_body is None else min(limit, settings.max_body)


def create_app(live: LiveHome, *, token: str | None = None, settings: ServeSettings | None = None,
               connections: Any = None, **options: Any) -> Any:
    """The ASGI app serving ``live``.

    Parameters
    ----------
    live: the served home.
    token: the bearer token every request needs (``None``: none; serve loopback only then).
    settings: limits and options (:class:`ServeSettings`); ``options`` set its fields instead
        (``max_body=…``, ``map_image=…``, ``allowed_hosts=…``; ``allowed_hosts=None`` with a token
        accepts any ``Host``).
    connections: the server's :class:`~spco.service.connections.ConnectionGuard`, if any (told
        when requests start and end; event streams that fall behind are closed through it).

    Returns the ASGI application: FastAPI behind :class:`~spco.service.security.Guard`.
    """
    if settings is None:
        settings = ServeSettings(allowed_hosts=None if token is not None else list(LOOPBACK_HOSTS))
    for key, value in options.items():
        if not hasattr(settings, key):
            raise TypeError(f"create_app: unknown option {key!r}")
        setattr(settings, key, value)
    if settings.map_image is not None:
        settings.map_image = Path(settings.map_image)
        try:
            encoded_size(settings.map_image.read_bytes()[:65536])
        except (OSError, ImageError) as exc:
            raise SpcoError(f"{settings.map_image}: not a readable PNG or JPEG map image ({exc})") from None
        if settings.map_extent is None:
            settings.map_extent = live.home.extent
        if settings.map_extent is None:
            raise SpcoError("the home has no map extent: give the extent the map image covers")
    live.max_pixels = settings.max_pixels
    app = FastAPI(title="spco serve", version="1", docs_url=None, redoc_url=None,
                  description="A learnt home answering where/what/ask and taking teachings while the robot "
                              "runs. Every error is {\"error\": message, \"status\": code}.")
    app.state.live = live
    app.state.settings = settings
    app.state.sessions = None if token is None else Sessions(token, lifetime=settings.session_hours * 3600)
    app.state.connections = connections
    app.state.decodes = asyncio.Semaphore(settings.decode_concurrency)
    app.state.decode_waiting = [0]
    app.state.events = EventHub(live)
    app.include_router(api)
    app.include_router(page)
    _error_handlers(app)
    view_limit = view_body_limit(live, settings)

    def body_limit(method: str, path: str) -> int:
        if method in ("POST", "PUT", "PATCH") and path in ("/what", "/teach"):
            return view_limit
        if path in ("/login", "/logout"):
            return 4096
        return 1024

    app.state.view_body_limit = view_limit
    visual_limit = live.home.knowledge.n_features * _COUNT_CHARS + BODY_OVERHEAD
    return Guard(app, settings=settings, sessions=app.state.sessions, token=token, body_limit=body_limit,
                 connections=connections, visual_limit=visual_limit)


def _error_handlers(app: FastAPI) -> None:
    """Every error through the one error map (:mod:`spco.service.errors`)."""

    @app.exception_handler(SpcoError)
    async def spco_error(request: Request, exc: SpcoError) -> JSONResponse:
        return answer_for(exc, f"{request.method} {request.url.path}")

    @app.exception_handler(RequestValidationError)
    async def invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        return validation_answer(list(exc.errors()), request.headers.get("content-type", ""))

    @app.exception_handler(StarletteHTTPException)
    async def framework(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        status = exc.status_code
        detail = exc.detail if isinstance(exc.detail, str) and status < 500 else "error"
        message = FRAMEWORK_MESSAGES.get(status) or detail
        return error_response(status, message, headers=getattr(exc, "headers", None))

    @app.exception_handler(Exception)
    async def failed(request: Request, exc: Exception) -> JSONResponse:  # a bug: logged, said in general
        return answer_for(exc, f"{request.method} {request.url.path}")
