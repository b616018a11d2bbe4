"""The endpoints of ``spco serve``, as module-level FastAPI routers (see :mod:`spco.service.app`).

Each route is a thin adapter: it builds the checked request of :mod:`spco.knowledge.requests`
(from the query, or from a body model of :mod:`spco.service.schemas`) and hands it to the served
:class:`~spco.service.LiveHome` (``request.app.state.live``): :meth:`~spco.service.LiveHome.answer`
for ``where``/``what``/``ask``, :meth:`~spco.service.LiveHome.submit` for ``teach``/undo. Errors
are raised, and turned into answers by the one error map (:mod:`spco.service.errors`).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import threading
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Query, Request
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse, Response
from starlette.concurrency import run_in_threadpool
from starlette.responses import StreamingResponse

from spco.errors import ConfigurationError
from spco.knowledge.requests import (
    MAX_NAME_CHARS,
    MAX_POSES,
    MAX_QUESTIONS,
    MAX_TOP,
    Ask,
    Pose,
    Undo,
    What,
    Where,
)
from spco.service.errors import LimitError, error_response
from spco.service.live import LiveHome
from spco.service.schemas import (
    AskAnswer,
    ErrorAnswer,
    HealthAnswer,
    RegionsAnswer,
    RevokedAnswer,
    TeachAnswer,
    TeachBody,
    WhatAnswer,
    WhatBody,
    WhereAnswer,
)
from spco.service.security import PAGE, SESSION_COOKIE, login_html

__all__ = ["EventHub", "api", "page"]

_ERRORS: dict[int | str, dict[str, Any]] = {
    code: {"model": ErrorAnswer} for code in (400, 401, 403, 404, 408, 409, 413, 415, 422, 503)}

#: The JSON API (in the OpenAPI schema).
api = APIRouter(responses=_ERRORS)
#: The page, its files and signing in (not in the schema).
page = APIRouter(include_in_schema=False)


def _live(request: Request) -> LiveHome:
    return request.app.state.live  # type: ignore[no-any-return]


Live = Annotated[LiveHome, Depends(_live)]


def _json(content: Any) -> Response:
    return Response(json.dumps(content, ensure_ascii=False, allow_nan=False), media_type="application/json")


async def _decoded(request: Request, build: Any) -> Any:
    """Run ``build`` (decoding a view's image and extracting its features) in a worker thread, at
    most ``decode_concurrency`` at once; more waiting than ``decode_queue`` are refused (503)."""
    settings = request.app.state.settings
    gate: asyncio.Semaphore = request.app.state.decodes
    in_flight: list[int] = request.app.state.decode_waiting
    if in_flight[0] >= settings.decode_concurrency + settings.decode_queue:
        raise LimitError(f"the server is decoding {settings.decode_concurrency} images with "
                         f"{in_flight[0] - settings.decode_concurrency} waiting; try again shortly")
    in_flight[0] += 1
    try:
        async with gate:
            return await run_in_threadpool(build)
    finally:
        in_flight[0] -= 1


@api.get("/health", summary="Status of the served home", response_model=HealthAnswer)
async def health(live: Live) -> Response:
    status = live.health()
    writer = status["writer"]
    public = {k: v for k, v in status.items() if k != "file"}  # no paths and no pids to clients
    public["writer"] = {"alive": writer["alive"], "kind": writer["kind"]}
    return _json(public)


@api.get("/where", summary="Poses for a place name (spco where --json)", response_model=WhereAnswer)
async def where(live: Live, name: Annotated[str, Query(min_length=1, max_length=MAX_NAME_CHARS)],
                n: Annotated[int, Query(ge=1, le=MAX_POSES)] = 10,
                seed: Annotated[int, Query(ge=0, le=2**63 - 1)] = 0) -> Response:
    return _json(live.answer(Where(name, n, seed)))


@api.get("/what", summary="Place names at a pose (spco what --json), from the position alone",
         response_model=WhatAnswer)
async def what(live: Live, x: Annotated[float, Query(allow_inf_nan=False)],
               y: Annotated[float, Query(allow_inf_nan=False)],
               theta: Annotated[float, Query(allow_inf_nan=False)],
               top: Annotated[int, Query(ge=1, le=MAX_TOP)] = 3) -> Response:
    return _json(live.answer(What(Pose(x, y, theta), None, top)))


@api.post("/what", summary="Place names at a pose, with an optional camera view", response_model=WhatAnswer)
async def what_with_view(live: Live, request: Request, body: WhatBody) -> Response:
    if body.image is None:
        return _json(live.answer(body.to_request()))
    return _json(await _decoded(request, lambda: live.answer(body.to_request())))


@api.get("/ask", summary="Where to ask \"what is this place?\" next (spco ask --json)",
         response_model=AskAnswer)
async def ask(live: Live, n: Annotated[int, Query(ge=1, le=MAX_QUESTIONS)] = 5,
              unsure_only: bool = False) -> Response:
    return _json(live.answer(Ask(n, unsure_only)))


@api.post("/teach", summary="Teach: a sentence for a sample, or a new observation",
          response_model=TeachAnswer)
async def teach(live: Live, request: Request, body: TeachBody) -> Response:
    if body.image is not None:
        if body.id is not None:
            raise ConfigurationError("an image goes with a new observation (x, y, theta), not with an id")
        future = await _decoded(request, lambda: live.submit(body.to_request()))
    else:
        future = live.submit(body.to_request())
    return _json(await asyncio.wrap_future(future))


@api.delete("/teach/{seq}", summary="Undo a teaching", response_model=TeachAnswer)
async def undo(live: Live, seq: int) -> Response:
    return _json(await asyncio.wrap_future(live.submit(Undo(seq))))


@api.get("/regions", summary="The learnt regions, concepts and samples, for drawing",
         response_model=RegionsAnswer)
async def regions(live: Live, request: Request) -> Response:
    settings = request.app.state.settings
    answer = dict(live.regions())
    answer["map"] = (None if settings.map_image is None
                     else {"url": "/map", "extent": list(settings.map_extent or ())})
    return _json(answer)


@api.get("/map", summary="The map image under the page", response_class=FileResponse,
         responses={200: {"content": {"image/png": {}, "image/jpeg": {}}, "description": "the map image"}})
async def map_file(request: Request) -> Response:
    settings = request.app.state.settings
    if settings.map_image is None:
        return error_response(404, "this server has no map image (spco serve --map IMAGE)")
    return FileResponse(settings.map_image)


class EventHub:
    """The event streams of one app: one subscription to the home whatever the number of streams
    (for the union of the types they want), each event written as text once and handed to every
    stream that wants it. A stream whose queue is full (a consumer that does not keep up) is
    dropped: its connection is closed."""

    def __init__(self, live: LiveHome) -> None:
        self.live = live
        self.streams: dict[int, tuple[frozenset[str] | None, Any]] = {}  # id -> (types, drop-or-put)
        self.subscription: Any = None
        self.loop: asyncio.AbstractEventLoop | None = None
        self.loop_thread = 0

    def add(self, types: frozenset[str] | None, put: Any) -> int:
        """A new stream; its ``put(text)`` returns ``False`` when it must be dropped."""
        if self.loop is None:
            self.loop, self.loop_thread = asyncio.get_running_loop(), threading.get_ident()
        key = id(put)
        self.streams[key] = (types, put)
        self._resubscribe()
        return key

    def remove(self, key: int) -> None:
        if self.streams.pop(key, None) is not None:
            self._resubscribe()

    def _resubscribe(self) -> None:
        wanted: set[str] | None = set()
        for types, _ in self.streams.values():
            if types is None:
                wanted = None
                break
            wanted |= types  # type: ignore[operator]
        if self.subscription is not None:
            self.subscription.close()
            self.subscription = None
        if self.streams:
            self.subscription = self.live.subscribe(self._deliver, types=wanted)

    def _deliver(self, event: dict[str, Any]) -> None:  # in the thread that publishes
        assert self.loop is not None
        if threading.get_ident() == self.loop_thread:
            self._fan_out(event)
        else:
            self.loop.call_soon_threadsafe(self._fan_out, event)

    def _fan_out(self, event: dict[str, Any]) -> None:
        text = f"event: {event['type']}\ndata: {json.dumps(event, default=_plain)}\n\n"
        for key, (types, put) in list(self.streams.items()):
            if (types is None or event["type"] in types) and not put(text):
                self.remove(key)


@api.get("/events", summary="Server-Sent Events: taught, undone, answer", response_class=StreamingResponse,
         responses={200: {"content": {"text/event-stream": {}},
                          "description": "event: taught|undone|answer, data: the event's JSON"}})
async def events(request: Request, types: Annotated[str | None, Query(max_length=100)] = None
                 ) -> StreamingResponse:
    settings = request.app.state.settings
    wanted = None
    if types is not None:
        wanted = frozenset(t.strip() for t in types.split(",") if t.strip())
        unknown = wanted - {"taught", "undone", "answer"}
        if unknown:
            raise ConfigurationError(f"types: unknown event types {', '.join(sorted(unknown))} (taught, "
                                     "undone, answer)")
    hub: EventHub = request.app.state.events
    if len(hub.streams) >= settings.max_subscribers:
        raise LimitError(f"the server has {settings.max_subscribers} event streams open, its limit "
                         "(spco serve --max-subscribers)")
    pending: asyncio.Queue[str | None] = asyncio.Queue(maxsize=settings.subscriber_queue)
    client = request.scope.get("client")
    connections = request.app.state.connections

    def put(text: str) -> bool:
        if pending.full():  # a consumer that does not keep up is dropped, not waited for
            with contextlib.suppress(asyncio.QueueEmpty):
                pending.get_nowait()
            pending.put_nowait(None)
            if connections is not None and client:
                connections.abort(tuple(client))
            return False
        pending.put_nowait(text)
        return True

    key = hub.add(wanted, put)

    async def stream() -> Any:
        try:
            yield "retry: 2000\n: connected\n\n"
            while True:
                try:
                    text = await asyncio.wait_for(pending.get(), timeout=settings.keepalive_comment)
                except TimeoutError:
                    yield ": keep-alive\n\n"
                    continue
                if text is None:
                    return
                yield text
        finally:
            hub.remove(key)

    return StreamingResponse(stream(), media_type="text/event-stream",
                             headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})


# ---------------------------------------------------------------------------- the page and signing in
@page.get("/")
async def index() -> Response:
    return FileResponse(PAGE / "index.html", headers={"Cache-Control": "no-cache"})


@page.get("/page/{name}")
async def page_file(name: str) -> Response:
    if name not in ("app.js", "style.css"):
        return error_response(404, "no such page file")
    return FileResponse(PAGE / name, headers={"Cache-Control": "no-cache"})


@page.get("/login")
async def login_page(request: Request) -> Response:
    if "token" in request.query_params:
        return error_response(400, "the token never goes in a URL (proxies and browsers log URLs): sign in "
                                   "with the form (POST /login, token in the body)")
    return HTMLResponse(login_html(), status_code=200)


@page.post("/login")
async def login(request: Request) -> Response:
    from urllib.parse import parse_qs

    sessions = request.app.state.sessions
    if sessions is None:
        return RedirectResponse("/", status_code=303)
    form = parse_qs((await request.body()).decode("utf-8", "replace"))
    given = (form.get("token") or [""])[0]
    if not sessions.check_token(given):
        return HTMLResponse(login_html("Wrong token."), status_code=401)
    response = RedirectResponse("/", status_code=303)
    response.set_cookie(SESSION_COOKIE, sessions.create(), max_age=int(sessions.lifetime), httponly=True,
                        samesite="strict", path="/", secure=request.url.scheme == "https")
    return response


@page.post("/logout")
async def logout(request: Request) -> Response:
    sessions = request.app.state.sessions
    if sessions is not None:
        sessions.revoke(request.cookies.get(SESSION_COOKIE, ""))
    response = RedirectResponse("/login", status_code=303)
    response.delete_cookie(SESSION_COOKIE, path="/", httponly=True, samesite="strict",
                           secure=request.url.scheme == "https")
    return response


@api.delete("/sessions", summary="Sign every page out (revoke all sessions)", response_model=RevokedAnswer)
async def revoke_sessions(request: Request) -> Response:
    sessions = request.app.state.sessions
    if sessions is None:
        return error_response(404, "this server has no token, so no sessions (spco serve --token-file)")
    return _json({"revoked": sessions.revoke_all()})


def _plain(value: Any) -> Any:
    """JSON for NumPy scalars in events."""
    with contextlib.suppress(TypeError, ValueError):
        number = float(value)
        return number if math.isfinite(number) else None
    return str(value)
