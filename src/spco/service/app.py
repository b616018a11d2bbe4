"""The HTTP app of ``spco serve``: a :class:`~spco.service.LiveHome` over HTTP + JSON (FastAPI, ASGI).

Endpoints (JSON unless said; the OpenAPI description is at ``/openapi.json``):

``GET /health``
    ``{"status": "ok", "home", "samples", "taught", "teachings", "seq", …}``.
``GET /where?name=NAME&n=N``
    the JSON of ``spco where HOME NAME -n N --json``.
``GET /what?x=&y=&theta=&top=K`` and ``POST /what``
    the JSON of ``spco what HOME … --json``; the POST body is ``{"x", "y", "theta", "top"}`` with an
    optional view: ``"image"`` (base64 of a JPEG or PNG file, or of raw pixels with ``"encoding"``:
    ``rgb8``, ``bgr8`` or ``mono8`` and ``"width"``, ``"height"``), or ``"visual"`` (counts).
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
``GET /login?token=…`` / ``POST /login``
    with a token: sets the session cookie of the page (HttpOnly, SameSite=Strict), then to ``/``.

Errors are one JSON object ``{"error": message, "status": code}``: 400 malformed JSON, 401 no or
wrong token, 404 unknown name, sample or seq, 409 a conflicting teaching or undo, 413 a body or
image too large, 415 not JSON, 422 a well-formed request with wrong values (types, NaN, a pose off
the map, a broken image), 503 the writer gone. Never a 5xx for bad input.

With a token (``spco serve --token-file``) every endpoint but ``/login`` needs ``Authorization:
Bearer TOKEN`` or the session cookie (compared in constant time, :func:`hmac.compare_digest`);
without one the server binds loopback only and accepts only loopback host names (``Host:``), so
that a web page elsewhere cannot reach it through DNS rebinding.
"""

from __future__ import annotations

import asyncio
import base64
import binascii
import contextlib
import hashlib
import hmac
import json
import math
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import FastAPI, Query, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, RedirectResponse, Response
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.responses import StreamingResponse

from spco.errors import SpcoError, TeachingRateError
from spco.prediction import UnknownNameError
from spco.service.images import ImageError, ImageTooLargeError, encoded_size
from spco.service.live import MAX_POSES, MAX_QUESTIONS, MAX_TOP, LiveHome
from spco.service.teaching import MAX_SENTENCE_CHARS, ConflictError, NotFoundError
from spco.service.writer import WriterUnavailableError

__all__ = ["DEFAULT_MAX_BODY", "LOOPBACK_HOSTS", "SESSION_COOKIE", "create_app", "session_value"]

#: The largest request body accepted, in bytes (a 1920×1080 rgb8 view in base64 is 8.3 MB).
DEFAULT_MAX_BODY = 16 * 1024 * 1024
#: The host names a server without a token accepts.
LOOPBACK_HOSTS = ["127.0.0.1", "localhost", "::1", "[::1]"]
#: The page's session cookie.
SESSION_COOKIE = "spco_session"
PAGE = Path(__file__).with_name("page")
#: What a server with a token answers without it: the sign-in page and its style.
_OPEN_PATHS = frozenset({"/login", "/page/style.css"})

Finite = Annotated[float, Field(strict=True, allow_inf_nan=False)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


class View(_Strict):
    """The optional camera view of a request."""

    image: str | None = Field(None, description="base64 of a JPEG or PNG file, or of raw pixels with "
                              "encoding, width and height")
    encoding: Literal["rgb8", "bgr8", "mono8"] | None = Field(
        None, description="raw pixels (ROS sensor_msgs/Image names); none for JPEG/PNG")
    width: int | None = Field(None, ge=1, le=65535)
    height: int | None = Field(None, ge=1, le=65535)
    visual: list[Annotated[int, Field(ge=0)]] | None = Field(
        None, description="the view's visual counts (the knowledge's dimension) instead of an image")


class WhatRequest(View):
    """``POST /what``: a pose (metres, radians) and an optional view."""

    x: Finite
    y: Finite
    theta: Finite
    top: int = Field(3, ge=1, le=MAX_TOP)


class TeachRequest(View):
    """``POST /teach``: ``{"id", "sentence"}`` for a known sample, or a pose ``{"x", "y", "theta",
    "sentence"}`` (+ an optional view) for a new observation."""

    sentence: str | None = Field(None, max_length=MAX_SENTENCE_CHARS)
    id: int | None = Field(None, ge=-(2**62), le=2**62)
    x: Finite | None = None
    y: Finite | None = None
    theta: Finite | None = None


class Position(BaseModel):
    x: float
    y: float
    theta: float
    probability: float


class WhereAnswer(BaseModel):
    """The answer of ``GET /where`` (as ``spco where --json``)."""

    home: str
    name: str
    region: int
    region_probability: float
    learnt: bool
    support: float
    positions: list[Position]


class NameScore(BaseModel):
    name: str
    probability: float
    score: float
    score_share: float


class WhatAnswer(BaseModel):
    """The answer of ``/what`` (as ``spco what --json``); ``warning`` for a pose off the map."""

    home: str
    pose: dict[str, float]
    vision: bool
    ranked_by: str
    names: list[NameScore]
    warning: str | None = None


class Question(BaseModel):
    """A place to ask "what is this place?" (``spco ask --json``)."""

    id: int
    x: float
    y: float
    theta: float
    gain: float
    reason: str
    names: list[dict[str, Any]]
    unknown: float
    confidence: float
    worth_asking: bool


class AskAnswer(BaseModel):
    """The answer of ``GET /ask`` (as ``spco ask --json``)."""

    home: str
    gain: str
    questions: list[Question]


class TeachAnswer(BaseModel):
    """The answer of ``POST /teach`` and ``DELETE /teach/{seq}``."""

    model_config = ConfigDict(extra="allow")
    seq: int
    op: str
    teachings: int
    samples: int
    taught: int


class ErrorAnswer(BaseModel):
    """Every error: one message."""

    error: str
    status: int


_ERRORS = {code: {"model": ErrorAnswer} for code in (400, 401, 404, 409, 413, 415, 422, 429, 503)}


def session_value(token: str) -> str:
    """The session cookie's value for ``token``: an HMAC of it (the token itself never goes in a cookie)."""
    return hmac.new(token.encode("utf-8"), b"spco-serve-session", hashlib.sha256).hexdigest()


def _status_of(exc: BaseException) -> int:
    if isinstance(exc, UnknownNameError | NotFoundError):
        return 404
    if isinstance(exc, ConflictError):
        return 409
    if isinstance(exc, ImageTooLargeError):
        return 413
    if isinstance(exc, WriterUnavailableError):
        return 503
    if isinstance(exc, TeachingRateError):
        return 429
    return 422


def _error(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": message, "status": status}, status_code=status)


def _decode_base64(text: str | None) -> bytes | None:
    if text is None:
        return None
    try:
        return base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError):
        raise ImageError("image: not valid base64") from None


def _json(content: Any) -> Response:
    return Response(json.dumps(content, ensure_ascii=False, allow_nan=False), media_type="application/json")


class _Guard:
    """Pure ASGI middleware: the token (bearer or session cookie) and the body size limit."""

    def __init__(self, app: Any, token: str | None, max_body: int) -> None:
        self.app = app
        self.token = token
        self.session = None if token is None else session_value(token)
        self.max_body = max_body

    def _authorised(self, scope: dict[str, Any]) -> bool:
        if self.token is None:
            return True
        headers = dict(scope.get("headers") or [])
        auth = headers.get(b"authorization", b"").decode("latin-1")
        given = auth[7:].strip().encode() if auth[:7].lower() == "bearer " else None
        if given is not None and hmac.compare_digest(given, self.token.encode()):
            return True
        for part in headers.get(b"cookie", b"").decode("latin-1").split(";"):
            name, _, value = part.strip().partition("=")
            if name == SESSION_COOKIE and self.session is not None \
                    and hmac.compare_digest(value.encode(), self.session.encode()):
                return True
        return False

    async def __call__(self, scope: dict[str, Any], receive: Callable[[], Awaitable[dict[str, Any]]],
                       send: Callable[[dict[str, Any]], Awaitable[None]]) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if scope["path"] not in _OPEN_PATHS and not self._authorised(scope):
            if scope["method"] == "GET" and scope["path"] == "/":
                response: Response = HTMLResponse((PAGE / "login.html").read_text(encoding="utf-8"),
                                                  status_code=401)
            else:
                response = _error(401, "this server needs its token: Authorization: Bearer TOKEN (the "
                                       "content of the server's --token-file) or the page's session (/login)")
            response.headers["WWW-Authenticate"] = "Bearer"
            await response(scope, receive, send)
            return
        length = dict(scope.get("headers") or []).get(b"content-length")
        if length is not None and (not length.isdigit() or int(length) > self.max_body):
            await _error(413, f"request body too large (at most {self.max_body} bytes)")(scope, receive, send)
            return
        if scope["method"] in ("GET", "HEAD", "DELETE") and length is None:
            await self.app(scope, receive, send)
            return
        chunks, size = [], 0  # read the body here, within the limit, then hand it on
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                return
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.max_body:
                await _error(413, f"request body too large (at most {self.max_body} bytes)")(
                    scope, receive, send)
                return
            chunks.append(chunk)
            if not message.get("more_body"):
                break
        body = b"".join(chunks)
        sent = False

        async def replay() -> dict[str, Any]:
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)


def create_app(live: LiveHome, *, token: str | None = None, map_image: str | Path | None = None,
               map_extent: tuple[float, float, float, float] | None = None, max_body: int = DEFAULT_MAX_BODY,
               allowed_hosts: list[str] | None = None) -> Any:
    """The ASGI app serving ``live``.

    Parameters
    ----------
    live: the served home.
    token: the bearer token every request needs (``None``: none; bind loopback only then).
    map_image: a PNG/JPEG floor plan shown under the page's regions; map_extent: the metres it
        covers ``(x_min, x_max, y_min, y_max)`` (default: the home's map extent).
    max_body: the largest request body, bytes.
    allowed_hosts: the ``Host`` names accepted (default: any with a token, loopback names without).

    Returns the ASGI application (FastAPI wrapped in the token and body-size guard).
    """
    app = FastAPI(title="spco serve", version="1", docs_url=None, redoc_url=None,
                  description="A learnt home answering where/what and taking teachings while the robot runs.")
    if map_image is not None:
        map_image = Path(map_image)
        try:
            encoded_size(map_image.read_bytes()[:65536])
        except (OSError, ImageError) as exc:
            raise SpcoError(f"{map_image}: not a readable PNG or JPEG map image ({exc})") from None
        if map_extent is None:
            map_extent = live.home.extent
        if map_extent is None:
            raise SpcoError("the home has no map extent: give the extent the map image covers")

    @app.exception_handler(SpcoError)
    async def spco_error(request: Request, exc: SpcoError) -> JSONResponse:
        return _error(_status_of(exc), str(exc))

    @app.exception_handler(RequestValidationError)
    async def invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        problems = exc.errors()
        first = problems[0] if problems else {}
        if first.get("type") == "json_invalid":
            return _error(400, f"malformed JSON: {first.get('ctx', {}).get('error', 'cannot parse it')}")
        where = ".".join(str(p) for p in first.get("loc", ()) if p not in ("body", "query", "path"))
        if first.get("type") == "model_attributes_type" or (not where and first.get("type") == "missing"):
            content_type = request.headers.get("content-type", "")
            if not content_type.startswith("application/json"):
                return _error(415, f"expected a JSON body (Content-Type: application/json), got "
                                   f"{content_type or 'none'!r}")
            return _error(422, "expected a JSON object")
        more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
        return _error(422, f"{where or 'request'}: {first.get('msg', 'invalid')}{more}")

    @app.exception_handler(Exception)
    async def failed(request: Request, exc: Exception) -> JSONResponse:  # a bug: say so, keep serving
        return _error(500, f"internal error: {type(exc).__name__}: {exc}")

    @app.get("/health", summary="Status of the served home")
    async def health() -> Response:
        return _json(live.health())

    @app.get("/where", summary="Poses for a place name (spco where --json)",
             responses={200: {"model": WhereAnswer}, **_ERRORS})
    async def where(name: Annotated[str, Query(min_length=1, max_length=200)],
                    n: Annotated[int, Query(ge=1, le=MAX_POSES)] = 10,
                    seed: Annotated[int, Query(ge=0, le=2**63 - 1)] = 0) -> Response:
        return _json(live.where(name, n, seed=seed))

    @app.get("/what", summary="Place names at a pose (spco what --json), from the position alone",
             responses={200: {"model": WhatAnswer}, **_ERRORS})
    async def what(x: Annotated[float, Query(allow_inf_nan=False)],
                   y: Annotated[float, Query(allow_inf_nan=False)],
                   theta: Annotated[float, Query(allow_inf_nan=False)],
                   top: Annotated[int, Query(ge=1, le=MAX_TOP)] = 3) -> Response:
        return _json(live.what(x, y, theta, top=top))

    @app.get("/ask", summary="Where to ask \"what is this place?\" next (spco ask --json)",
             responses={200: {"model": AskAnswer}, **_ERRORS})
    async def ask(n: Annotated[int, Query(ge=1, le=MAX_QUESTIONS)] = 5,
                  unsure_only: bool = False) -> Response:
        return _json(live.ask(n, unsure_only=unsure_only))

    def _counts(view: View) -> Any:
        image = _decode_base64(view.image)
        if image is None and (view.encoding or view.width or view.height):
            raise ImageError("encoding, width and height describe an image; give the image too")
        return live.view_counts(image, view.encoding, view.visual, view.width, view.height)

    @app.post("/what", summary="Place names at a pose, with an optional camera view",
              responses={200: {"model": WhatAnswer}, **_ERRORS})
    async def what_with_view(body: WhatRequest) -> Response:
        if body.image is None:
            return _json(live.what(body.x, body.y, body.theta, visual=body.visual, top=body.top))
        from spco.service.answers import check_pose

        check_pose(live.home, body.x, body.y, body.theta)  # before decoding the image
        counts = await run_in_threadpool(_counts, body)  # decoding and extracting release the GIL
        return _json(live.what(body.x, body.y, body.theta, visual=counts, top=body.top))

    @app.post("/teach", summary="Teach: a sentence for a sample, or a new observation",
              responses={200: {"model": TeachAnswer}, **_ERRORS})
    async def teach(body: TeachRequest) -> Response:
        counts = None
        if body.image is not None:
            if body.id is not None:
                raise SpcoError("an image goes with a new observation (x, y, theta), not with an id")
            counts = await run_in_threadpool(_counts, body)
        elif body.visual is not None or body.encoding or body.width or body.height:
            counts = _counts(body)
        future = live.submit_teach(sentence=body.sentence, id=body.id, x=body.x, y=body.y, theta=body.theta,
                                   visual=counts)
        return _json(await asyncio.wrap_future(future))

    @app.delete("/teach/{seq}", summary="Undo a teaching", responses={200: {"model": TeachAnswer}, **_ERRORS})
    async def undo(seq: int) -> Response:
        return _json(await asyncio.wrap_future(live.submit_undo(seq)))

    @app.get("/regions", summary="The learnt regions, concepts and samples, for drawing")
    async def regions() -> Response:
        answer = dict(live.regions())
        answer["map"] = None if map_image is None else {"url": "/map", "extent": list(map_extent or ())}
        return _json(answer)

    @app.get("/map", summary="The map image under the page", responses={404: {"model": ErrorAnswer}})
    async def map_file() -> Response:
        if map_image is None:
            return _error(404, "this server has no map image (spco serve --map IMAGE)")
        return FileResponse(map_image)

    @app.get("/events", summary="Server-Sent Events: taught, undone, answer")
    async def events(request: Request, types: Annotated[str | None, Query(max_length=100)] = None
                     ) -> StreamingResponse:
        wanted = None
        if types is not None:
            wanted = {t.strip() for t in types.split(",") if t.strip()}
            unknown = wanted - {"taught", "undone", "answer"}
            if unknown:
                raise SpcoError(f"types: unknown event types {', '.join(sorted(unknown))} (taught, undone, "
                                "answer)")
        loop = asyncio.get_running_loop()
        pending: asyncio.Queue[dict[str, Any]] = asyncio.Queue(maxsize=1000)

        def put(event: dict[str, Any]) -> None:
            if pending.full():  # a slow page: drop the oldest
                pending.get_nowait()
            pending.put_nowait(event)

        subscription = live.subscribe(lambda event: loop.call_soon_threadsafe(put, event), types=wanted)

        async def stream() -> Any:
            try:
                yield "retry: 2000\n: connected\n\n"
                while True:
                    try:
                        event = await asyncio.wait_for(pending.get(), timeout=15)
                    except TimeoutError:
                        yield ": keep-alive\n\n"
                        continue
                    yield f"event: {event['type']}\ndata: {json.dumps(event, default=_plain)}\n\n"
            finally:
                subscription.close()

        return StreamingResponse(stream(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})

    @app.get("/", include_in_schema=False)
    async def page() -> Response:
        return FileResponse(PAGE / "index.html", headers={"Cache-Control": "no-cache"})

    @app.get("/page/{name}", include_in_schema=False)
    async def page_file(name: str) -> Response:
        if name not in ("app.js", "style.css"):
            return _error(404, f"no such page file {name!r}")
        return FileResponse(PAGE / name, headers={"Cache-Control": "no-cache"})

    @app.get("/login", include_in_schema=False)
    async def login_get(token: str = "") -> Response:
        return _login(token)

    @app.post("/login", include_in_schema=False)
    async def login_post(request: Request) -> Response:
        from urllib.parse import parse_qs

        form = parse_qs((await request.body()).decode("utf-8", "replace"))
        return _login((form.get("token") or [""])[0])

    def _login(given: str) -> Response:
        if token is None:
            return RedirectResponse("/", status_code=303)
        if not hmac.compare_digest(given.strip().encode(), token.encode()):
            return HTMLResponse((PAGE / "login.html").read_text(encoding="utf-8").replace(
                "<!--message-->", "<p class=error>Wrong token.</p>"), status_code=401)
        response = RedirectResponse("/", status_code=303)
        response.set_cookie(SESSION_COOKIE, session_value(token), httponly=True, samesite="strict", path="/")
        return response

    app.add_middleware(_Guard, token=token, max_body=max_body)
    hosts = allowed_hosts if allowed_hosts is not None else (None if token is not None else LOOPBACK_HOSTS)
    if hosts is not None:  # added last: outermost, a foreign Host is turned away first
        app.add_middleware(TrustedHostMiddleware, allowed_hosts=hosts)
    return app


def _plain(value: Any) -> Any:
    """JSON for NumPy scalars in events."""
    with contextlib.suppress(TypeError, ValueError):
        number = float(value)
        return number if math.isfinite(number) else None
    return str(value)
