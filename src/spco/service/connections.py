"""Connections of ``spco serve``: a header timeout and a connection limit under uvicorn.

uvicorn reads requests with no time limit on their headers (``timeout_keep_alive`` only starts
after an answer, and any byte stops it) and its ``limit_concurrency`` answers 503 only once the
headers are parsed, so connections that never finish their headers hold the process's file
descriptors until it cannot accept any more. :class:`ConnectionGuard` wraps uvicorn's own HTTP
protocol (:func:`ConnectionGuard.protocol`, passed as uvicorn's ``http``), using nothing of it but
the asyncio protocol interface:

- a connection must complete its request's headers (``\\r\\n\\r\\n``) within ``header_timeout``
  seconds of connecting, and the next request's within ``keep_alive + header_timeout`` seconds of
  its last answer; otherwise it is closed (``408`` when it had sent part of a request);
- headers longer than ``max_header_bytes`` are refused (``431``);
- at most ``max_connections`` are open: a new one evicts the oldest connection still waiting for
  headers (the slow, the idle), and is refused (``503``) when every connection is busy with a
  request.

The body of a request has its own limits (size, time) in :class:`spco.service.security.Guard`,
which tells this guard when a request starts and when its answer was sent (by the client's
address, the ASGI ``client``).
"""

from __future__ import annotations

import asyncio
import contextlib
import resource
from collections import OrderedDict
from typing import Any

__all__ = ["ConnectionGuard", "default_max_connections"]

#: File descriptors kept for the server itself (journal, writer pipes, map image, libraries).
RESERVED_FDS = 64


def default_max_connections(limit: int | None = None) -> int:
    """The default connection limit: the open-file limit (``RLIMIT_NOFILE``, soft) less
    :data:`RESERVED_FDS`, at most 4,096 and at least 16."""
    if limit is None:
        limit = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
        if limit == resource.RLIM_INFINITY:
            limit = 65536
    return max(16, min(4096, int(limit) - RESERVED_FDS))


def _raw(status: int, reason: str, message: str) -> bytes:
    import json

    body = json.dumps({"error": message, "status": status}).encode()
    return (f"HTTP/1.1 {status} {reason}\r\ncontent-type: application/json\r\ncontent-length: {len(body)}\r\n"
            "connection: close\r\n\r\n").encode() + body


class ConnectionGuard:
    """The connections of one server (see the module).

    Parameters
    ----------
    header_timeout: seconds to complete a request's headers after connecting.
    keep_alive: seconds an idle kept-alive connection may wait for its next request (plus
        ``header_timeout`` to complete its headers).
    max_connections: the most connections open at once (:func:`default_max_connections`).
    max_header_bytes: the longest request head (request line and headers).
    """

    def __init__(self, header_timeout: float = 10.0, keep_alive: float = 5.0,
                 max_connections: int | None = None, max_header_bytes: int = 64 * 1024) -> None:
        self.header_timeout = float(header_timeout)
        self.keep_alive = float(keep_alive)
        self.max_connections = default_max_connections() if max_connections is None else int(max_connections)
        self.max_header_bytes = int(max_header_bytes)
        self.open: set[_Guarded] = set()
        self.waiting: OrderedDict[_Guarded, None] = OrderedDict()  # oldest first
        self.by_client: dict[tuple[Any, ...], _Guarded] = {}
        #: counts: connections evicted, refused, timed out, with headers too long
        self.counts = {"evicted": 0, "refused": 0, "timed_out": 0, "too_long": 0}

    def protocol(self, inner: type | None = None) -> type[asyncio.Protocol]:
        """The protocol class to give uvicorn (``uvicorn.Config(http=...)``): ``inner`` (default
        uvicorn's ``auto``: httptools if installed, else h11) behind this guard."""
        if inner is None:
            from uvicorn.protocols.http.auto import AutoHTTPProtocol

            inner = AutoHTTPProtocol
        return type("GuardedHTTPProtocol", (_Guarded,), {"guard": self, "inner_class": inner})

    # ------------------------------------------------------------------ told by the app
    def request_started(self, client: tuple[Any, ...]) -> None:
        """A request of ``client`` reached the app: it is not waiting for headers."""
        connection = self.by_client.get(client)
        if connection is not None:
            connection.busy()

    def reading_body(self, client: tuple[Any, ...]) -> None:
        """``client``'s request waits for its body (with its own time limit): evictable meanwhile."""
        connection = self.by_client.get(client)
        if connection is not None:
            connection.busy()
            self.waiting[connection] = None

    def response_sent(self, client: tuple[Any, ...]) -> None:
        """The answer to ``client`` was sent: its connection waits for the next request."""
        connection = self.by_client.get(client)
        if connection is not None:
            connection.wait(self.keep_alive + self.header_timeout, idle=True)

    def abort(self, client: tuple[Any, ...]) -> None:
        """Close ``client``'s connection at once (a slow event consumer)."""
        connection = self.by_client.get(client)
        if connection is not None and connection.transport is not None:
            connection.transport.abort()

    # ------------------------------------------------------------------ connections
    def _admit(self, connection: _Guarded) -> bool:
        while len(self.open) >= self.max_connections:
            if not self.waiting:
                self.counts["refused"] += 1
                return False
            oldest = next(iter(self.waiting))
            self.counts["evicted"] += 1
            oldest.drop()
        self.open.add(connection)
        return True

    def _forget(self, connection: _Guarded) -> None:
        self.open.discard(connection)
        self.waiting.pop(connection, None)
        if connection.client is not None and self.by_client.get(connection.client) is connection:
            del self.by_client[connection.client]


class _Guarded(asyncio.Protocol):
    """One connection: uvicorn's protocol (``inner``) behind the guard's header timer."""

    guard: ConnectionGuard
    inner_class: type

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.inner = self.inner_class(*args, **kwargs)
        self.transport: Any = None
        self.client: tuple[Any, ...] | None = None
        self.refused = False
        self.timer: asyncio.TimerHandle | None = None
        self.head_bytes = 0
        self.tail = b""
        self.idle = False

    # ------------------------------------------------------------------ the timer
    def wait(self, seconds: float, idle: bool = False) -> None:
        """Wait for a request's headers, at most ``seconds``."""
        self.cancel_timer()
        self.head_bytes, self.tail, self.idle = 0, b"", idle
        self.guard.waiting[self] = None
        self.guard.waiting.move_to_end(self)
        self.timer = asyncio.get_running_loop().call_later(seconds, self.expire)

    def busy(self) -> None:
        """A request's headers are complete."""
        self.cancel_timer()
        self.guard.waiting.pop(self, None)

    def cancel_timer(self) -> None:
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None

    def expire(self) -> None:
        self.timer = None
        if self.transport is None or self.transport.is_closing():
            return
        self.guard.counts["timed_out"] += 1
        if self.head_bytes:
            self.close_with(_raw(408, "Request Timeout", "the request's headers did not arrive in time"))
        else:
            self.drop()

    def drop(self) -> None:
        """Close at once (an idle or slow connection evicted, or timed out)."""
        self.guard._forget(self)  # not counted from now on (connection_lost comes later)
        self.cancel_timer()
        if self.transport is not None:
            self.transport.abort()

    def close_with(self, answer: bytes) -> None:
        self.guard._forget(self)
        self.cancel_timer()
        with contextlib.suppress(Exception):
            self.transport.write(answer)
        self.transport.close()

    # ------------------------------------------------------------------ asyncio.Protocol
    def connection_made(self, transport: Any) -> None:
        self.transport = transport
        peer = transport.get_extra_info("peername")
        if isinstance(peer, tuple | list) and len(peer) >= 2:
            self.client = (str(peer[0]), int(peer[1]))
        if not self.guard._admit(self):
            self.refused = True
            self.transport.write(_raw(503, "Service Unavailable", "the server has too many connections busy"))
            self.transport.close()
            return
        if self.client is not None:
            self.guard.by_client[self.client] = self
        self.wait(self.guard.header_timeout)
        self.inner.connection_made(transport)

    def data_received(self, data: bytes) -> None:
        if self.refused:
            return
        if self.timer is not None:  # waiting for headers
            self.head_bytes += len(data)
            if b"\r\n\r\n" in self.tail + data:
                self.busy()
            elif self.head_bytes > self.guard.max_header_bytes:
                self.guard.counts["too_long"] += 1
                self.close_with(_raw(431, "Request Header Fields Too Large", "the request's headers are too "
                                     "long"))
                return
            else:
                self.tail = data[-3:]
        self.inner.data_received(data)

    def eof_received(self) -> Any:
        if self.refused:
            return None
        return self.inner.eof_received()

    def connection_lost(self, exc: Exception | None) -> None:
        self.cancel_timer()
        self.guard._forget(self)
        if not self.refused:
            self.inner.connection_lost(exc)

    def pause_writing(self) -> None:
        if not self.refused:
            self.inner.pause_writing()

    def resume_writing(self) -> None:
        if not self.refused:
            self.inner.resume_writing()

    def __getattr__(self, name: str) -> Any:  # anything else uvicorn asks of its protocol
        return getattr(self.__dict__["inner"], name)
