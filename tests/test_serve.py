"""spco serve and LiveHome: answers like the CLI, durable teachings (journal, replay, compaction,
torn records, kill -9), undo, the lock against the CLI, HTTP errors, the token, and a fuzz test."""

from __future__ import annotations

import base64
import json
import os
import subprocess
import sys
import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from serve_helpers import Server, build_home, copy_home, env, wait_unlocked

from spco import knowledge as kn
from spco.cli.ask import ask as ask_command
from spco.cli.knowledge import what as what_command
from spco.cli.knowledge import where as where_command
from spco.errors import ConfigurationError
from spco.knowledge.locking import HomeServedError, locked, served_by
from spco.knowledge.requests import Pose, Teach, Undo
from spco.service import LiveHome
from spco.service.journal import (
    Journal,
    JournalError,
    TornRecordWarning,
    encode_record,
    journal_path,
    read_journal,
)
from spco.service.teaching import ConflictError, NotFoundError, load_current
from spco.service.writer import HomeWriter

pytest.importorskip("fastapi", reason="spco serve needs its extra: pip install -e '.[serve]'")
from fastapi.testclient import TestClient

from spco.service.app import create_app
from spco.service.client import Client, ClientError


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_home(tmp_path_factory.mktemp("serve"))


@pytest.fixture
def home(built: Path, tmp_path: Path) -> Path:
    return copy_home(built, tmp_path)


def _view(seed: int, shape: tuple[int, int] = (96, 128)) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (*shape, 3), dtype=np.uint8)


def _jpeg(seed: int, shape: tuple[int, int] = (96, 128)) -> bytes:
    ok, data = cv2.imencode(".jpg", _view(seed, shape))
    assert ok
    return data.tobytes()


def _state(home: kn.HomeModel) -> dict[str, np.ndarray]:
    names = ("concepts", "regions", "means", "log_pi")
    arrays = {name: np.asarray(getattr(home.state, name)) for name in names}
    arrays["ids"] = home.ids
    arrays["words"] = np.array(home.vocabulary.words)
    return arrays


def _same(a: kn.HomeModel, b: kn.HomeModel) -> bool:
    sa, sb = _state(a), _state(b)
    return a.sentences == b.sentences and all(np.array_equal(sa[k], sb[k]) for k in sa)


# ----------------------------------------------------------------------------- the library: LiveHome
#: Every operation of the JSON API and the method of spco.service.client.Client that calls it.
CLIENT_METHODS = {("get", "/health"): "health", ("get", "/where"): "where", ("get", "/what"): "what",
                  ("post", "/what"): "what", ("get", "/ask"): "ask", ("post", "/teach"): "teach",
                  ("delete", "/teach/{seq}"): "undo", ("get", "/regions"): "regions",
                  ("get", "/map"): "map_image", ("get", "/events"): "events",
                  ("delete", "/sessions"): "revoke_sessions"}


def test_the_openapi_schema_describes_every_answer_and_the_client_calls_every_operation() -> None:
    """The routers at module level make the whole schema without a home: every JSON operation's
    answer has a schema, every error the one error shape; the Python client has a method for each
    operation (a new endpoint without one fails here)."""
    from fastapi import FastAPI

    from spco.service.routes import api

    app = FastAPI()
    app.include_router(api)
    spec = app.openapi()
    operations = {(method, path): op for path, item in spec["paths"].items() for method, op in item.items()}
    assert set(operations) == set(CLIENT_METHODS)
    for (method, path), op in operations.items():
        assert callable(getattr(Client, CLIENT_METHODS[method, path]))
        ok = op["responses"]["200"]["content"]
        if path not in ("/map", "/events"):  # an image, an event stream
            assert "$ref" in ok["application/json"]["schema"], (method, path)
        error = op["responses"]["404"]["content"]["application/json"]["schema"]
        assert error["$ref"].endswith("/ErrorAnswer"), (method, path)


def test_live_home_answers_as_the_cli_and_teaches(home: Path) -> None:
    name = kn.load_home_model(home).known_names[0]
    runner = CliRunner()
    cli_where = json.loads(runner.invoke(where_command, [str(home), name, "-n", "4", "--json"]).output)
    cli_what = json.loads(runner.invoke(what_command, [str(home), "--x", "0.5", "--y", "-0.5", "--theta", "1",
                                                       "--top", "4", "--json"]).output)
    with LiveHome(home, writer="thread", seed=0) as live:
        assert live.where(name, n=4) == cli_where
        assert live.what(0.5, -0.5, 1.0, top=4) == cli_what
        assert live.health()["status"] == "ok" and live.health()["teachings"] == 0
        events = live.subscribe()
        sample = int(live.home.ids[3])
        taught = live.teach(id=sample, sentence="this is the pantry")
        assert taught["seq"] == 1 and taught["teachings"] == 1 and "pantry" in taught["new_words"]
        assert live.home.sentences[3] == "this is the pantry"  # the next answer uses it
        added = live.teach(x=0.4, y=-0.4, theta=0.5, sentence="this is the pantry", image=_jpeg(1))
        assert added["op"] == "observation" and added["id"] == int(kn.load_home_model(home).ids.max()) + 1
        assert live.home.n_samples == kn.load_home_model(home).n_samples + 1
        kinds = [events.get(timeout=5)["type"] for _ in range(2)]
        assert kinds == ["taught", "taught"]
        with_view = live.what(0.4, -0.4, 0.5, image=_view(1), encoding="bgr8")
        assert with_view["vision"] is True
        png = cv2.imencode(".png", _view(1))[1].tobytes()  # lossless: the same pixels as the array
        assert live.what(0.4, -0.4, 0.5, image=png)["names"] == with_view["names"]
        rgb = live.what(0.4, -0.4, 0.5, image=_view(1)[:, :, ::-1].copy(), encoding="rgb8")
        assert rgb["names"] == with_view["names"]
        regions = live.regions()
        ellipses = [r["ellipse"] for r in regions["regions"]]
        assert ellipses and all(e["rx"] >= e["ry"] >= 0 for e in ellipses)
        assert len(regions["samples"]) == live.home.n_samples
        with pytest.raises(NotFoundError, match="no sample with id 99999"):
            live.teach(id=99999, sentence="this is the hall")
        with pytest.raises(ConfigurationError, match="more than a full turn"):
            live.teach(x=0.0, y=0.0, theta=90.0, sentence="this is the hall")
        with pytest.raises(ConfigurationError, match="outside the map"):
            live.what(1e308, 0.0, 0.0)
        assert live.what(8.0, 0.0, 0.0)["warning"].startswith("the pose (8, 0)")  # off the map: said
        # undo: the sentence it replaced comes back, the sample it added goes
        live.undo(taught["seq"])
        assert live.home.sentences[3] is None
        live.undo(added["seq"])
        assert live.home.n_samples == kn.load_home_model(home).n_samples
        with pytest.raises(ConflictError, match="undone already"):
            live.undo(taught["seq"])
        with pytest.raises(NotFoundError, match="no teaching with seq 42"):
            live.undo(42)
        assert live.health()["teachings"] == 0 and live.health()["seq"] == 4
    assert kn.load_home_model(home).provenance["served"]["last_seq"] == 4  # compacted on close


def test_cli_teach_is_refused_at_once_while_served_and_readers_replay_the_journal(home: Path) -> None:
    with LiveHome(home, writer="thread", seed=0, holder="spco serve (pid 1) at http://127.0.0.1:9",
                  compact_idle=3600) as live:
        assert served_by(home) == "spco serve (pid 1) at http://127.0.0.1:9"
        start = time.monotonic()
        teach = subprocess.run([sys.executable, "-m", "spco", "teach", str(home), "--id", "0", "--sentence",
                                "this is the hall"], capture_output=True, text=True, env=env(), timeout=120)
        assert teach.returncode == 2 and "Traceback" not in teach.stderr
        assert "served by spco serve (pid 1) at http://127.0.0.1:9" in teach.stderr
        assert time.monotonic() - start < 30  # at once, not after the 60 s lock timeout
        refused: list[BaseException] = []

        def write() -> None:  # another thread of this process, as another library user would
            try:
                with locked(home, timeout=30):
                    pass
            except HomeServedError as exc:
                refused.append(exc)

        other = threading.Thread(target=write)
        other.start()
        other.join(60)
        assert refused and "served by spco serve (pid 1)" in str(refused[0])
        live.teach(id=int(live.home.ids[5]), sentence="this is the larder")
        # not compacted yet: the file does not know "larder"; the read-only commands replay the journal
        assert "larder" not in kn.load_home_model(home).vocabulary
        replayed, count = load_current(home)
        assert count == 1 and _same(replayed, live.home)
        out = CliRunner().invoke(where_command, [str(home), "larder", "--json"])
        assert out.exit_code == 0, out.output
        assert json.loads(out.stdout)["name"] == "larder"
        assert "1 teaching(s) not yet compacted" in out.stderr
    assert served_by(home) is None
    assert "larder" in kn.load_home_model(home).vocabulary


# ----------------------------------------------------------------------------- durability
def test_journal_replays_to_the_same_home_and_compaction_never_applies_twice(
        home: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    writer = HomeWriter(home, seed=3, compact_records=1000, compact_idle=3600)
    ids = [int(i) for i in writer.home.ids[:4]]
    results = writer.handle([Teach(sentence="this is the den", id=ids[0]),
                             Teach(sentence="this is the den", id=ids[1]),
                             Teach(sentence="the den is here", pose=Pose(0.1, 0.2, 0.3))])
    assert [r["ok"] for r in results] == [True, True, True] and results[0]["batch"] == 3
    writer.handle([Undo(2), Teach(sentence="this is the den", id=ids[2])])
    live_state = writer.home
    # a crash now (nothing compacted): the file plus its journal give the same home
    replayed, count = load_current(home)
    assert count == 5 and _same(replayed, live_state)
    # a crash in the compaction after the home file was written, before the journal was rewritten
    def crash(self: Journal, header: dict, records: list) -> None:
        raise OSError("crash")

    monkeypatch.setattr(Journal, "rewrite", crash)
    with pytest.raises(OSError, match="crash"):
        writer.compact()
    monkeypatch.undo()
    assert len(read_journal(journal_path(home)).records) == 5  # still there, and all ≤ last_seq of the file
    restarted = HomeWriter(home, seed=3)
    assert restarted.startup["replayed"] == 0  # none applied twice
    assert _same(restarted.home, live_state)
    assert restarted.home.provenance["served"]["teachings"] == 3
    assert restarted.history[2]["undone_by"] == 4


def test_torn_last_record_is_dropped_with_a_warning_and_damage_is_refused(home: Path) -> None:
    writer = HomeWriter(home, seed=1, compact_records=1000, compact_idle=3600)
    sample = int(writer.home.ids[0])
    writer.handle([Teach(sentence="this is the loft", id=sample)])
    expected = writer.home
    journal = journal_path(home)
    line = encode_record({"seq": 2, "batch": [2, 2], "seed": 5, "sweeps": 10, "op": "sentence", "id": sample,
                          "sentence": "this is the attic"})
    with open(journal, "ab") as handle:
        handle.write(line[: len(line) // 2])  # the process died while writing it
    with pytest.warns(TornRecordWarning, match="cut short"):
        contents = read_journal(journal)
    assert [r["seq"] for r in contents.records] == [1]
    with pytest.warns(TornRecordWarning), LiveHome(home, writer="thread") as live:
        assert live.startup["torn"] and live.home.sentences[0] == "this is the loft"
        assert _same(live.home, expected)
    # a damaged record followed by intact ones is not a torn write: refused, naming the line
    lines = journal.read_bytes().splitlines(keepends=True)
    header = lines[0]
    good = [encode_record({"seq": s, "batch": [s, s], "seed": 1, "sweeps": 1, "op": "sentence", "id": sample,
                           "sentence": "this is the loft"}) for s in (2, 3)]
    journal.write_bytes(header + good[0].replace(b"loft", b"lofT") + good[1])
    with pytest.raises(JournalError, match="line 2: damaged record"):
        read_journal(journal)


def test_kill_9_during_a_burst_of_200_teachings_loses_no_acknowledged_one(home: Path) -> None:
    server = Server(home)
    acknowledged: list[dict] = []
    lock = threading.Lock()
    base = kn.load_home_model(home)
    ids = [int(i) for i in base.ids]

    def teach(k: int) -> None:
        client = Client(server.url, timeout=30)
        try:
            if k % 3 == 0:
                answer = client.teach(x=float(-1 + (k % 7) * 0.3), y=float(-1 + (k % 5) * 0.3), theta=0.1,
                                      sentence=f"this is the {'hall' if k % 2 else 'study'}")
            else:
                answer = client.teach(id=ids[k % len(ids)],
                                      sentence=f"this is the {'hall' if k % 2 else 'study'}")
        except ClientError:
            return  # not acknowledged: the server died first
        with lock:
            acknowledged.append(answer)

    pool = ThreadPoolExecutor(4)
    futures = [pool.submit(teach, k) for k in range(200)]
    deadline = time.monotonic() + 120
    while len(acknowledged) < 30 and time.monotonic() < deadline:
        time.sleep(0.01)
    server.kill()  # kill -9 in the middle of the burst
    for f in futures:
        f.result()
    pool.shutdown()
    count = len(acknowledged)
    assert 30 <= count < 200, count
    wait_unlocked(home)
    restarted = Server(home)
    try:
        health = Client(restarted.url).health()
        assert health["teachings"] >= count  # every acknowledged one, and perhaps a few not yet acknowledged
        assert "Replayed" in restarted.output or health["seq"] == 0
    finally:
        assert restarted.stop() == 0
    final = kn.load_home_model(home)
    history = {int(k): v for k, v in final.provenance["served"]["history"].items()}
    for answer in acknowledged:
        entry = history[answer["seq"]]
        assert [entry[k] for k in ("op", "id", "sentence")] == [answer[k] for k in ("op", "id", "sentence")]
    observations = [a for a in acknowledged if a["op"] == "observation"]
    assert {a["id"] for a in observations} <= set(final.ids.tolist())


def test_client_mirrors_the_library_over_a_real_server(home: Path) -> None:
    library = kn.load_home_model(home)
    name = library.known_names[0]
    server = Server(home)
    try:
        robot = Client(server.url)
        assert robot.where(name, n=3) == json.loads(
            CliRunner().invoke(where_command, [str(home), name, "-n", "3", "--json"]).stdout)
        assert robot.what(0.3, -0.2, 0.4)["names"][0]["name"] in library.known_names
        assert robot.ask(2) == json.loads(CliRunner().invoke(ask_command, [str(home), "--n", "2",
                                                                           "--json"]).stdout)
        assert robot.what(0.3, -0.2, 0.4, image=_jpeg(5))["vision"] is True
        assert robot.what(0.3, -0.2, 0.4, image=_view(5), encoding="bgr8")["names"] == \
            robot.what(0.3, -0.2, 0.4, image=cv2.imencode(".png", _view(5))[1].tobytes())["names"]  # lossless
        events = robot.events(types="taught,undone")
        received: list[dict] = []
        listener = threading.Thread(target=lambda: received.extend([next(events), next(events)]), daemon=True)
        listener.start()
        time.sleep(0.3)
        taught = robot.teach(id=int(library.ids[2]), sentence="this is the snug")
        undone = robot.undo(taught["seq"])
        listener.join(30)
        assert [e["type"] for e in received] == ["taught", "undone"]
        assert received[0]["seq"] == taught["seq"]
        assert received[1]["undoes"] == taught["seq"] == undone["undoes"]
        with pytest.raises(ClientError) as error:
            robot.where("kitchn")
        assert error.value.status == 404 and "did you mean" in error.value.message
        with pytest.raises(ClientError) as error:
            robot.undo(taught["seq"])
        assert error.value.status == 409
        assert robot.health()["teachings"] == 0
    finally:
        assert server.stop() == 0, server.output


def test_concurrent_teachings_through_the_writer_process_all_come_back(home: Path) -> None:
    """Many teachings at once, observations among them (whose snapshots are larger than a socket's
    buffer): requests and snapshots cross between the server and its writer process both ways at once
    without waiting for each other."""
    with LiveHome(home, seed=0) as live:
        ids = [int(i) for i in live.home.ids[:20]]

        def teach(k: int) -> dict:
            if k % 4 == 0:
                return live.teach(x=0.1 * (k % 9), y=-0.1 * (k % 7), theta=0.2, image=_jpeg(k),
                                  sentence="this is the hall")
            return live.teach(id=ids[k % len(ids)], sentence="this is the study")

        with ThreadPoolExecutor(8) as pool:
            answers = list(pool.map(teach, range(48), timeout=300))
        assert sorted(a["seq"] for a in answers) == list(range(1, 49))
        assert live.health()["teachings"] == 48 and max(a["batch"] for a in answers) > 1  # batched
        assert live.home.n_samples == kn.load_home_model(home).n_samples + 12


def test_writer_process_survives_a_default_socket_timeout_as_rospy_sets_it(home: Path) -> None:
    """rospy's ``init_node`` calls ``socket.setdefaulttimeout(60)``: every socket made afterwards is
    non-blocking underneath. A LiveHome opened in such a process (a user's own ROS node) still starts
    its writer and gets snapshots larger than a socket's buffer back (the starting snapshot and a
    teaching with an observation)."""
    import socket

    previous = socket.getdefaulttimeout()
    socket.setdefaulttimeout(60.0)
    try:
        with LiveHome(home, seed=0) as live:
            answer = live.teach(x=0.1, y=-0.1, theta=0.2, image=_jpeg(1), sentence="this is the hall")
            assert answer["seq"] == 1 and live.home.n_samples == kn.load_home_model(home).n_samples + 1
    finally:
        socket.setdefaulttimeout(previous)


# ----------------------------------------------------------------------------- HTTP
@pytest.fixture
def app_client(home: Path):
    live = LiveHome(home, writer="thread", seed=0)
    try:
        with TestClient(create_app(live), base_url="http://127.0.0.1",
                        raise_server_exceptions=False) as client:
            yield client, live
    finally:
        live.close()


def test_http_endpoints_and_their_errors(app_client) -> None:
    client, live = app_client
    name = live.home.known_names[0]
    assert client.get("/health").json()["status"] == "ok"
    assert client.get("/where", params={"name": name, "n": 3}).json() == live.where(name, 3)
    assert client.get("/what", params={"x": 0.2, "y": 0.1, "theta": 0.5}).json() == live.what(0.2, 0.1, 0.5)
    image = base64.b64encode(_jpeg(2)).decode()
    posted = client.post("/what", json={"x": 0.2, "y": 0.1, "theta": 0.5, "image": image, "top": 2})
    assert posted.status_code == 200 and posted.json()["vision"] and len(posted.json()["names"]) == 2
    raw = _view(2, (16, 16))
    posted = client.post("/what", json={"x": 0.2, "y": 0.1, "theta": 0.5, "encoding": "rgb8", "width": 16,
                                        "height": 16, "image": base64.b64encode(raw.tobytes()).decode()})
    assert posted.status_code == 200, posted.text
    taught = client.post("/teach", json={"x": 0.3, "y": 0.3, "theta": 0.0, "sentence": "this is the nook"})
    assert taught.status_code == 200 and taught.json()["teachings"] == 1
    assert client.get("/where", params={"name": "nook"}).status_code == 200  # the next request knows it
    assert client.delete(f"/teach/{taught.json()['seq']}").json()["undoes"] == taught.json()["seq"]
    regions = client.get("/regions").json()
    assert regions["regions"] and regions["map"] is None
    assert client.get("/").headers["content-type"].startswith("text/html")
    assert client.get("/page/app.js").status_code == 200
    spec = client.get("/openapi.json").json()
    paths = {"/health", "/where", "/what", "/teach", "/teach/{seq}", "/regions", "/events"}
    assert paths <= set(spec["paths"])
    errors = {
        "unknown name": (client.get("/where", params={"name": "kitchn"}), 404, "unknown place name"),
        "huge n": (client.get("/where", params={"name": name, "n": 10**9}), 422, "n:"),
        "nan": (client.get("/what", params={"x": "nan", "y": 0, "theta": 0}), 422, "finite"),
        "1e308": (client.get("/what", params={"x": "1e308", "y": 0, "theta": 0}), 422, "outside the map"),
        "malformed": (client.post("/teach", content=b'{"id": 3,',
                                  headers={"Content-Type": "application/json"}), 400, "malformed JSON"),
        "not json": (client.post("/teach", content=b"id=3"), 415, "expected a JSON body"),
        "wrong type": (client.post("/teach", json={"id": "3", "sentence": "x"}), 422, "id"),
        "bool": (client.post("/what", json={"x": True, "y": 0, "theta": 0}), 422, "x"),
        "extra": (client.post("/what", json={"x": 0, "y": 0, "theta": 0, "z": 1}), 422, "z"),
        "broken image": (client.post("/what", json={"x": 0, "y": 0, "theta": 0,
                                                    "image": base64.b64encode(_jpeg(3)[:200]).decode()}),
                         422, "JPEG"),
        "not an image": (client.post("/what", json={"x": 0, "y": 0, "theta": 0, "image": "aGVsbG8="}), 422,
                         "not a JPEG or PNG"),
        "bad base64": (client.post("/what", json={"x": 0, "y": 0, "theta": 0, "image": "***"}), 422,
                       "base64"),
        "raw size": (client.post("/what", json={"x": 0, "y": 0, "theta": 0, "image": "AAAA",
                                                "encoding": "mono8", "width": 16, "height": 16}),
                     422, "bytes of mono8"),
        "huge image": (client.post("/what", json={"x": 0, "y": 0, "theta": 0, "image": base64.b64encode(
            b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR" + (60000).to_bytes(4, "big") * 2 + b"\x08\x02\0\0\0").decode()}),
                       413, "pixels"),
        "unknown sample": (client.post("/teach", json={"id": 99999, "sentence": "x"}), 404, "no sample"),
        "unknown seq": (client.delete("/teach/999"), 404, "no teaching with seq 999"),
        "undone twice": (client.delete(f"/teach/{taught.json()['seq']}"), 409, "undone already"),
        "nothing": (client.post("/teach", json={"sentence": "x"}), 422, "needs id and sentence"),
        "too large": (client.post("/teach", content=b"{" + b" " * (17 * 1024 * 1024) + b"}",
                                  headers={"Content-Type": "application/json"}), 413, "too large"),
    }
    for label, (response, status, text) in errors.items():
        assert response.status_code == status, (label, response.status_code, response.text)
        assert text in response.json()["error"], (label, response.text)
    # no token: loopback names only (a page elsewhere cannot reach it by DNS rebinding)
    assert client.get("/health", headers={"Host": "evil.example"}).status_code == 400


def test_token_covers_the_api_the_page_and_its_event_stream(home: Path) -> None:
    token = "s3cret-token-of-the-robot"
    with LiveHome(home, writer="thread") as live, TestClient(create_app(live, token=token),
                                                             base_url="http://robot.local") as client:
        assert client.get("/health").status_code == 401
        assert client.get("/events").status_code == 401
        wrong = {"Authorization": "Bearer wrong-token-of-the-robot"}
        assert client.get("/health", headers=wrong).status_code == 401
        assert client.get("/health", headers={"Authorization": f"Bearer {token}"}).status_code == 200
        assert "sign in" in client.get("/").text.lower()  # the page asks for the token
        assert client.get("/login", params={"token": token}, follow_redirects=False).status_code == 400
        assert client.post("/login", data={"token": "nope"}, follow_redirects=False).status_code == 401
        signed = client.post("/login", data={"token": token}, follow_redirects=False)
        assert signed.status_code == 303
        cookie = signed.headers["set-cookie"].lower()
        assert "httponly" in cookie and "samesite=strict" in cookie and "max-age=604800" in cookie
        assert token.lower() not in cookie and "secure" not in cookie  # plain HTTP: no Secure flag
        assert len(client.cookies.get("spco_session") or "") >= 40
        assert client.get("/health").status_code == 200  # the cookie now
        with client.stream("GET", "/events", params={"types": "taught"}) as stream:
            assert stream.status_code == 200
            sample = int(live.home.ids[0])
            threading.Timer(0.3, lambda: live.teach(id=sample, sentence="this is the hall")).start()
            for line in stream.iter_lines():
                if line.startswith("data:"):
                    event = json.loads(line[5:])
                    break
        assert event["type"] == "taught" and event["sentence"] == "this is the hall"


def test_serve_refuses_other_addresses_without_a_token(home: Path, tmp_path: Path) -> None:
    from spco.cli.serve import serve

    refused = CliRunner().invoke(serve, [str(home), "--host", "0.0.0.0", "--port", "0"])
    assert refused.exit_code == 2 and "refusing to serve on 0.0.0.0 without a token" in refused.output
    short = tmp_path / "token"
    short.write_text("short\n")
    refused = CliRunner().invoke(serve, [str(home), "--host", "0.0.0.0", "--port", "0", "--token-file",
                                         str(short)])
    assert refused.exit_code == 2 and "at least 16 characters" in refused.output
    assert served_by(home) is None and not journal_path(home).exists()  # refused before anything


# ----------------------------------------------------------------------------- fuzz
#: A malformed request: method, path, query string, body (``None``: none) and headers.
Malformed = tuple[str, str, str, bytes | None, dict[str, str]]


def _malformed_requests(spec: dict) -> Any:
    """A Hypothesis strategy of malformed requests to the operations of the OpenAPI description
    ``spec`` (but ``/events``): bad query values, bad JSON, wrong types and values, broken images,
    wrong methods and lying headers."""
    from hypothesis import strategies as st

    operations = [(path, method.upper()) for path, item in spec["paths"].items() for method in item
                  if path != "/events"]
    body_fields = {path: sorted(spec["components"]["schemas"][ref.split("/")[-1]]["properties"])
                   for path, item in spec["paths"].items() for op in item.values()
                   for ref in [op.get("requestBody", {}).get("content", {}).get("application/json", {})
                               .get("schema", {}).get("$ref", "")] if ref}

    @st.composite
    def malformed(draw: st.DrawFn) -> Malformed:
        path, method = draw(st.sampled_from(operations))
        if path in ("/where", "/teach/{seq}") or method == "GET":
            return _malformed_without_body(draw, method, path)
        return _malformed_body(draw, method, path, body_fields.get(path, ["x"]))

    return malformed()


_BAD_NUMBERS = ["nan", "NaN", "inf", "-Infinity", "1e308", "-1e309", "1e999", "", "x", "0x10", "true", "[]",
                "{}", "9" * 400]


def _malformed_without_body(draw: Any, method: str, path: str) -> Malformed:
    """A bad query (``/where``, ``GET /what``), a bad sequence number, or a wrong method or lying
    length on an operation without parameters."""
    from hypothesis import strategies as st

    headers = {"Content-Type": "application/json"}
    bad_numbers = st.sampled_from(_BAD_NUMBERS)
    names = st.sampled_from(["", "kitchn", "%00", "%C3%A9" * 300, "a" * 500, "%25", "unknown+place"])
    if path == "/where":
        huge = draw(st.sampled_from(["0", "-1", "1001", "10000000"]))
        query = draw(st.sampled_from([f"name={draw(names)}&n={draw(bad_numbers)}",
                                      f"n={draw(bad_numbers)}", f"name=kitchen&n={huge}"]))
        return method, path, query, None, headers
    if path == "/what":
        field = draw(st.sampled_from(["x", "y", "theta", "top"]))
        values = {"x": "0", "y": "0", "theta": "0", "top": "3"}
        bad_top = st.sampled_from(["0", "101", "-3", "x"])
        values[field] = draw(bad_numbers) if field != "top" else draw(bad_top)
        if draw(st.booleans()):
            del values[draw(st.sampled_from(["x", "y", "theta"]))]
        return method, path, "&".join(f"{k}={v}" for k, v in values.items()), None, headers
    if path == "/teach/{seq}":
        seq = draw(st.sampled_from(["x", "-1", "0", "99999", "1.5", "%00"]))
        return method, "/teach/" + seq, "", None, headers
    # no parameters to get wrong: a wrong method, or a body length that lies
    if draw(st.booleans()):
        return draw(st.sampled_from(["PUT", "PATCH"])), path, "", b"{}", headers
    return method, path, "", b"{}", {**headers, "Content-Length": draw(st.sampled_from(["-1", "x"]))}


def _malformed_body(draw: Any, method: str, path: str, fields: list[str]) -> Malformed:
    """A POST with broken JSON, the wrong content type, a field of the wrong type or value, a broken
    image, or a lying length."""
    from hypothesis import strategies as st

    headers = {"Content-Type": "application/json"}
    # wrong for every field: (a null is right for the optional ones, a string for a sentence)
    bad_json_values = st.one_of(st.sampled_from([True, [], {}, 1e308, -1e308, 10**40, [1.5]]),
                                st.lists(st.integers(), min_size=1, max_size=3).map(lambda v: {"k": v}))
    kind = draw(st.sampled_from(["json", "text", "type", "value", "image", "headers"]))
    body: dict = {"x": 0.0, "y": 0.0, "theta": 0.0}
    if kind == "json":
        raw = draw(st.sampled_from([b"{", b'{"x": }', b"[1, 2", b"\xff\xfe", b"", b"null", b"[]", b'"x"',
                                    b'{"x": NaN, "y": 0, "theta": 0}',
                                    b'{"x": 1e999, "y": 0, "theta": 0}']))
        return method, path, "", raw, headers
    if kind == "text":
        return method, path, "", b'{"x": 0}', {"Content-Type": draw(st.sampled_from(["text/plain", ""]))}
    if kind == "headers":
        headers["Content-Length"] = draw(st.sampled_from(["-1", "abc", str(64 * 1024 * 1024)]))
        return method, path, "", b"{}", headers
    if kind == "type":
        body[draw(st.sampled_from(fields))] = draw(bad_json_values)
    elif kind == "value":  # numbers of the right type, far off the map or more than a turn
        field = draw(st.sampled_from(["x", "y", "theta"]))
        turns = [7.0, -100.0] if field == "theta" else []
        body[field] = draw(st.sampled_from([1e308, -1e300, 1e10, *turns]))
    else:
        body["image"] = draw(st.sampled_from([
            "***", "aGVsbG8=", base64.b64encode(_jpeg(4)[:100]).decode(),
            base64.b64encode(b"\x89PNG\r\n\x1a\n").decode(),
            base64.b64encode(b"\xff\xd8\xff\xe0" + os.urandom(64)).decode()]))
        if draw(st.booleans()):
            body.update(encoding=draw(st.sampled_from(["rgb8", "mono8", "bgr16", "jpeg"])),
                        width=draw(st.sampled_from([0, 1, 8, 70000])), height=8)
    if path == "/teach" and kind != "type":
        body["id"] = draw(st.sampled_from([None, 99999, -5]))
        if body["id"] is None:
            body["sentence"] = draw(st.sampled_from([None, 3, ["a"], "x" * 1001]))
    return method, path, "", json.dumps(body).encode(), headers


def _send_raw(url: str, request: Malformed) -> int:
    """Send ``request`` as it is (no client-side checks) to the server at ``url``; its status."""
    import http.client
    from urllib.parse import urlsplit

    method, path, query, body, headers = request
    parts = urlsplit(url)
    connection = http.client.HTTPConnection(parts.hostname, parts.port, timeout=30)
    try:
        target = path + ("?" + query if query else "")
        connection.putrequest(method, target, skip_accept_encoding=True)
        for key, value in headers.items():
            connection.putheader(key, value)
        if body is not None and "Content-Length" not in headers:
            connection.putheader("Content-Length", str(len(body)))
        connection.endheaders(body if body is not None and "Content-Length" not in headers else None)
        response = connection.getresponse()
        response.read()
    finally:
        connection.close()
    return response.status


def test_fuzz_200_malformed_requests_get_4xx_and_change_nothing(home: Path) -> None:
    """At least 200 malformed requests, generated by Hypothesis from the server's own OpenAPI
    description, against a real server: every answer a 4xx, the server alive, the home file unchanged."""
    from hypothesis import HealthCheck, given, settings

    before = home.read_bytes()
    server = Server(home)
    client = Client(server.url)
    statuses: list[int] = []

    @settings(max_examples=240, deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
    @given(_malformed_requests(client.request("GET", "/openapi.json")))
    def send(request: Malformed) -> None:
        status = _send_raw(server.url, request)
        statuses.append(status)
        assert 400 <= status < 500, (request, status)

    try:
        send()
        assert len(statuses) >= 200
        assert client.health()["status"] == "ok"  # alive
        assert client.health()["teachings"] == 0
    finally:
        assert server.stop() == 0, server.output
    assert "Traceback" not in server.output
    assert home.read_bytes() == before  # nothing was taught, nothing rewritten


def test_warnings_of_served_answers_are_not_python_warnings(home: Path) -> None:
    with LiveHome(home, writer="thread") as live, warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "warning" in live.what(7.5, 0.0, 0.0)
