"""A small rosbridge (protocol v2) server written for the tests: no rosbridge server can be installed
here, so this one stands in for the robot's.

It speaks the part of the protocol a client of topics uses — ``advertise``, ``unadvertise``,
``publish``, ``subscribe``, ``unsubscribe`` — over a real WebSocket (the ``websockets`` package),
routes messages between its clients and the test (which publishes as the robot's topics would),
and keeps the last message of latched topics for late subscribers, as rosbridge does. It checks
nothing about message types: it is not ROS, and what passes here was not run against a real ROS 2
system.
"""

from __future__ import annotations

import asyncio
import json
import threading
import time
from collections import defaultdict
from typing import Any

import websockets
from ros_harness import Mailbox
from websockets.asyncio.server import ServerConnection, serve


class FakeRosbridge(Mailbox):
    """A rosbridge v2 server on ``127.0.0.1:port`` in a thread of its own (``close()`` stops it)."""

    def __init__(self, port: int) -> None:
        super().__init__()
        self.port = port
        self.url = f"ws://127.0.0.1:{port}"
        self._loop = asyncio.new_event_loop()
        self.subscribers: dict[str, dict[ServerConnection, str | None]] = defaultdict(dict)
        self.advertised: dict[str, dict[str, Any]] = {}
        self.latched: dict[str, dict[str, Any]] = {}
        self.published: dict[str, list[tuple[float, dict[str, Any]]]] = defaultdict(list)
        self.errors: list[str] = []
        self._started = threading.Event()
        self._stop: asyncio.Event | None = None
        self._thread = threading.Thread(target=self._run, name="fake-rosbridge", daemon=True)
        self._thread.start()
        if not self._started.wait(10):
            raise RuntimeError("the fake rosbridge server did not start")

    # ------------------------------------------------------------------ server
    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        self._loop.run_until_complete(self._serve())

    async def _serve(self) -> None:
        self._stop = asyncio.Event()
        async with serve(self._client, "127.0.0.1", self.port, max_size=2**26):
            self._started.set()
            await self._stop.wait()

    async def _client(self, ws: ServerConnection) -> None:
        try:
            async for text in ws:
                await self._handle(ws, json.loads(text))
        except websockets.ConnectionClosed:
            pass
        finally:
            with self._lock:
                for subs in self.subscribers.values():
                    subs.pop(ws, None)

    async def _handle(self, ws: ServerConnection, message: dict[str, Any]) -> None:
        op, topic = message.get("op"), message.get("topic")
        if op == "advertise":
            with self._lock:
                self.advertised[topic] = {"type": message.get("type"), "latch": bool(message.get("latch"))}
                self._lock.notify_all()
        elif op == "unadvertise":
            with self._lock:
                self.advertised.pop(topic, None)
        elif op == "subscribe":
            with self._lock:
                self.subscribers[topic][ws] = message.get("type")
                latched = self.latched.get(topic)
                self._lock.notify_all()
            if latched is not None:
                await ws.send(json.dumps({"op": "publish", "topic": topic, "msg": latched}))
        elif op == "unsubscribe":
            with self._lock:
                self.subscribers[topic].pop(ws, None)
        elif op == "publish":
            msg = message.get("msg")
            with self._lock:
                self.published[topic].append((time.perf_counter(), msg))
                if self.advertised.get(topic, {}).get("latch") or message.get("latch"):
                    self.latched[topic] = msg
                self._lock.notify_all()
            await self._forward(topic, msg, exclude=ws)
        else:
            with self._lock:
                self.errors.append(f"unknown op {op!r}")
            await ws.send(json.dumps({"op": "status", "level": "error", "msg": f"unknown op {op!r}"}))

    async def _forward(self, topic: str, msg: Any, exclude: ServerConnection | None = None) -> None:
        with self._lock:
            targets = [ws for ws in self.subscribers.get(topic, {}) if ws is not exclude]
        text = json.dumps({"op": "publish", "topic": topic, "msg": msg})
        for ws in targets:
            try:
                await ws.send(text)
            except websockets.ConnectionClosed:
                pass

    # ------------------------------------------------------------------ the test's side
    def publish(self, topic: str, msg: dict[str, Any]) -> None:
        """Publish ``msg`` on ``topic`` to the subscribed clients, as the robot's node would."""
        asyncio.run_coroutine_threadsafe(self._forward(topic, msg), self._loop).result(10)

    def messages(self, topic: str) -> list[dict[str, Any]]:
        """Every message published on ``topic`` so far, oldest first."""
        with self._lock:
            return [m for _, m in self.published.get(topic, [])]

    def close(self) -> None:
        """Stop the server and its thread."""
        if self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(10)
