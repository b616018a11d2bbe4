"""Foxglove and MCAP: ``spco show HOME --mcap FILE`` read back with the ``mcap`` library, and ``spco serve
--foxglove PORT`` driven by a client of the Foxglove WebSocket protocol (``websockets``), with the
messages decoded by protobuf from the schemas the file and the server carry.
"""

from __future__ import annotations

import asyncio
import base64
import json
import shutil
import struct
import time
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner
from conftest import missing_tool
from serve_helpers import Server

from spco.cli.main import main


def _need_foxglove() -> None:
    try:
        import foxglove  # noqa: F401
        import mcap  # noqa: F401
    except ImportError:
        missing_tool("foxglove-sdk and mcap are not installed (pip install -e '.[foxglove]')")


def _taught_copy(source: Path, folder: Path) -> Path:
    """A copy of the tour home with one sentence taught (spco teach) at its first sample."""
    from spco.knowledge import HomeModel

    home = Path(shutil.copy2(source, folder / "home.spco"))
    sample = int(HomeModel.load(home).ids[5])
    result = CliRunner().invoke(main, ["teach", str(home), "--id", str(sample),
                                       "--sentence", "this is the pantry"])
    assert result.exit_code == 0, result.output
    return home


def test_show_mcap_writes_the_regions_names_and_teachings_and_they_read_back(tour_home_file: Path,
                                                                             tmp_path: Path) -> None:
    _need_foxglove()
    from spco.knowledge import HomeModel
    from spco.ros.foxglove import MCAP_FORMAT, read_mcap
    from spco.ros.messages import concept_colour, places_text
    from spco.service.answers import regions_answer

    home = _taught_copy(tour_home_file, tmp_path)
    out = tmp_path / "home.mcap"
    result = CliRunner().invoke(main, ["show", str(home), "--mcap", str(out)])
    assert result.exit_code == 0, result.output
    model = HomeModel.load(home)
    regions = regions_answer(model)
    assert f"Wrote {out} ({len(regions['regions'])} regions, 1 teachings)" in result.output
    back = read_mcap(out)
    assert back["metadata"]["spco"]["format"] == MCAP_FORMAT["format"]
    assert back["metadata"]["spco"]["home"] == model.name
    assert json.loads(back["metadata"]["spco"]["names"]) == list(model.known_names)
    by_topic = {m["topic"]: m for m in back["messages"]}
    assert set(by_topic) == {"/spco/scene", "/spco/teachings"}
    scene = by_topic["/spco/scene"]["message"]
    assert by_topic["/spco/scene"]["schema"] == "foxglove.SceneUpdate"
    assert len(scene.deletions) == 1 and scene.deletions[0].type == 1  # ALL: earlier entities go
    entities = {e.id: e for e in scene.entities}
    assert set(entities) == {f"region/{r['region']}" for r in regions["regions"]}
    for region in regions["regions"]:
        entity = entities[f"region/{region['region']}"]
        assert entity.frame_id == "map" and len(entity.lines[0].points) == 48
        centre = entity.cylinders[0].pose.position
        assert (centre.x, centre.y) == pytest.approx(tuple(region["mean"]))
        colour = entity.lines[0].color
        assert (colour.r, colour.g, colour.b) == pytest.approx(
            concept_colour(region["concept"], model.knowledge.n_concepts))
        # labelled with the places `where` finds there (its answer for each name), and only those
        assert [t.text for t in entity.texts] == ([places_text(region)] if region["places"] else [])
        assert json.loads(next(m.value for m in entity.metadata if m.key == "places")) == region["places"]
    for place in regions["places"]:
        if place["learnt"]:
            assert place["name"] in entities[f"region/{place['region']}"].texts[0].text
    teachings = by_topic["/spco/teachings"]["message"]
    assert [e.texts[0].text for e in teachings.entities] == ["this is the pantry"]
    # refused without --force; neither --out nor --mcap is a usage error
    again = CliRunner().invoke(main, ["show", str(home), "--mcap", str(out)])
    assert again.exit_code != 0 and "--force" in again.output
    neither = CliRunner().invoke(main, ["show", str(home)])
    assert neither.exit_code == 2 and "--mcap" in neither.output


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class FoxgloveClient:
    """A client of the Foxglove WebSocket protocol: channels from ``advertise``, subscriptions, and
    each message decoded with the protobuf schema its channel advertised."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.channels: dict[str, dict[str, Any]] = {}
        self.classes: dict[int, Any] = {}
        self.subscribed: dict[int, str] = {}
        self.server_info: dict[str, Any] = {}
        self.received: dict[str, list[Any]] = {}

    async def handshake(self) -> None:
        from spco.ros.foxglove import protobuf_class

        while len(self.channels) < 4:
            message = json.loads(await asyncio.wait_for(self.ws.recv(), 10))
            if message["op"] == "serverInfo":
                self.server_info = message
            elif message["op"] == "advertise":
                for channel in message["channels"]:
                    self.channels[channel["topic"]] = channel
                    assert channel["encoding"] == "protobuf" and channel["schemaEncoding"] == "protobuf"
                    self.classes[channel["id"]] = protobuf_class(channel["schemaName"],
                                                                 base64.b64decode(channel["schema"]))

    async def subscribe(self, *topics: str) -> None:
        subscriptions = []
        for topic in topics:
            number = len(self.subscribed) + 1
            self.subscribed[number] = topic
            subscriptions.append({"id": number, "channelId": self.channels[topic]["id"]})
        await self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))

    async def next(self, topic: str, timeout: float = 15.0, where: Any = None) -> Any:
        """The next message on ``topic`` (that satisfies ``where``), decoded; messages of other topics
        are kept for their turn."""
        deadline = time.monotonic() + timeout
        while True:
            waiting = self.received.setdefault(topic, [])
            while waiting:
                message = waiting.pop(0)
                if where is None or where(message):
                    return message
            remaining = deadline - time.monotonic()
            assert remaining > 0, f"no message on {topic} within {timeout} s"
            frame = await asyncio.wait_for(self.ws.recv(), remaining)
            if isinstance(frame, str) or frame[0] != 1:  # 1: message data
                continue
            subscription, _ = struct.unpack("<IQ", frame[1:13])
            on = self.subscribed.get(subscription)
            if on is not None:
                message = self.classes[self.channels[on]["id"]].FromString(frame[13:])
                self.received.setdefault(on, []).append(message)


async def _sees_the_scene(client: FoxgloveClient) -> None:
    """The four channels are advertised, and the scene (the regions' names) comes on subscribing."""
    await client.handshake()
    topics = {"/spco/scene", "/spco/teachings", "/spco/answers", "/spco/log"}
    assert set(client.channels) == topics
    assert client.server_info["name"].startswith("spco ")
    await client.subscribe("/spco/scene", "/spco/teachings", "/spco/answers", "/spco/log")
    scene = await client.next("/spco/scene")  # sent to a client as it subscribes
    names = "\n".join(t.text for e in scene.entities for t in e.texts)
    assert len(scene.entities) >= 3 and all(e.frame_id == "map" for e in scene.entities)
    for name in ("kitchen", "living room", "bedroom"):
        assert name in names


async def _sees_a_teaching(client: FoxgloveClient, base: str, sample: int) -> None:
    """A teaching over HTTP: the teachings again, and a log line."""
    import httpx

    answer = await asyncio.to_thread(httpx.post, f"{base}/teach", json={
        "id": sample, "sentence": "this is the pantry"}, timeout=30)
    assert answer.status_code == 200, answer.text
    taught = await client.next("/spco/teachings",
                               where=lambda m: any(e.texts and "pantry" in e.texts[0].text
                                                   for e in m.entities))
    assert taught.entities[0].id == f"teaching/{sample}"
    line = await client.next("/spco/log", where=lambda m: "taught" in m.message)
    assert "this is the pantry" in line.message


async def _sees_an_answer(client: FoxgloveClient, base: str) -> None:
    """A where over HTTP: arrows at its poses, the best first."""
    import httpx

    where = await asyncio.to_thread(httpx.get, f"{base}/where", params={"name": "bedroom", "n": 3},
                                    timeout=10)
    assert where.status_code == 200
    shown = await client.next("/spco/answers")
    entity = shown.entities[0]
    assert entity.id == "answer" and len(entity.arrows) == 3 and "bedroom" in entity.texts[0].text
    best = where.json()["positions"][0]
    assert (entity.arrows[0].pose.position.x, entity.arrows[0].pose.position.y) == pytest.approx(
        (best["x"], best["y"]))


def test_serve_foxglove_streams_the_scene_teachings_and_answers(tour_home_file: Path, tmp_path: Path) -> None:
    _need_foxglove()
    pytest.importorskip("fastapi", reason="spco serve needs spco[serve]")
    import httpx
    import websockets

    home = Path(shutil.copy2(tour_home_file, tmp_path / "served.spco"))
    fox = _free_port()
    server = Server(home, "--foxglove", str(fox), "--writer", "thread")
    try:
        base = server.url
        assert f"Foxglove: ws://127.0.0.1:{fox}" in server.output
        samples = httpx.get(f"{base}/regions", timeout=10).json()["samples"]

        async def scenario() -> None:
            async with websockets.connect(f"ws://127.0.0.1:{fox}",
                                          subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"]) as ws:
                client = FoxgloveClient(ws)
                await _sees_the_scene(client)
                await _sees_a_teaching(client, base, samples[3]["id"])
                await _sees_an_answer(client, base)

        asyncio.run(scenario())
    finally:
        server.stop()


def test_serve_refuses_foxglove_on_its_own_port(tmp_path: Path) -> None:
    _need_foxglove()
    pytest.importorskip("fastapi", reason="spco serve needs spco[serve]")
    result = CliRunner().invoke(main, ["serve", str(tmp_path / "home.spco"), "--port", "8770",
                                       "--foxglove", "8770"])
    assert result.exit_code != 0 and "serve's own port" in result.output
