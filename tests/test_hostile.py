"""spco serve under attack (loopback only, bounded in time): slow and idle connections, connection
floods, slow and endless bodies, oversized bodies and images, event streams, browser-borne
requests (cross-site teaching, DNS rebinding, framing), error shapes and leaks, sign-in, and the
cross-site teaching refused with the oldest framework versions pyproject.toml allows."""

from __future__ import annotations

import base64
import json
import os
import re
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from serve_helpers import Server, build_home, copy_home

pytest.importorskip("fastapi", reason="spco serve needs its extra: pip install -e '.[serve]'")
from fastapi.testclient import TestClient

import spco
from spco.service import LiveHome
from spco.service.app import create_app

ROOT = Path(__file__).resolve().parents[1]
SRC = str(Path(spco.__file__).resolve().parents[1])
LIMITS = ("--header-timeout", "1", "--keep-alive", "1", "--body-timeout", "1", "--send-timeout", "1",
          "--max-connections", "40",
          "--max-subscribers", "2", "--writer", "thread")


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_home(tmp_path_factory.mktemp("hostile"))


@pytest.fixture(scope="module")
def server(built: Path, tmp_path_factory: pytest.TempPathFactory):
    home = copy_home(built, tmp_path_factory.mktemp("served"))
    running = Server(home, *LIMITS)
    try:
        yield running
    finally:
        running.stop()


def _address(server: Server) -> tuple[str, int]:
    host, port = server.url[len("http://"):].rsplit(":", 1)
    return host, int(port)


def _raw(server: Server, data: bytes, wait: float = 5.0) -> bytes:
    """Send ``data`` on a new connection; everything the server answers until it closes (or ``wait`` s)."""
    with socket.create_connection(_address(server), timeout=wait) as sock:
        sock.sendall(data)
        chunks = []
        deadline = time.monotonic() + wait
        while time.monotonic() < deadline:
            try:
                chunk = sock.recv(65536)
            except (TimeoutError, ConnectionResetError):
                break
            if not chunk:
                break
            chunks.append(chunk)
        return b"".join(chunks)


def _request(method: str, path: str, body: bytes = b"", **headers: str) -> bytes:
    lines = [f"{method} {path} HTTP/1.1", "Host: 127.0.0.1", "Connection: close",
             *(f"{k.replace('_', '-')}: {v}" for k, v in headers.items())]
    if body or method in ("POST", "PUT"):
        lines.append(f"Content-Length: {len(body)}")
    return ("\r\n".join(lines) + "\r\n\r\n").encode() + body


def _status(answer: bytes) -> int:
    match = re.match(rb"HTTP/1.1 (\d{3})", answer)
    assert match, answer[:200]
    return int(match.group(1))


def _json(answer: bytes) -> dict:
    return json.loads(answer.split(b"\r\n\r\n", 1)[1])


def _health(server: Server, timeout: float = 10.0) -> tuple[int, float]:
    started = time.perf_counter()
    answer = _raw(server, _request("GET", "/health"), wait=timeout)
    return _status(answer), time.perf_counter() - started


# ----------------------------------------------------------------------------- connections
def test_half_sent_headers_and_idle_connections_are_closed(server: Server) -> None:
    started = time.monotonic()
    answer = _raw(server, b"GET /hea", wait=8)  # never finishes its headers
    assert _status(answer) == 408 and time.monotonic() - started < 6
    started = time.monotonic()
    assert _raw(server, b"", wait=8) == b""  # connects and says nothing: closed, silently
    assert time.monotonic() - started < 6
    with socket.create_connection(_address(server), timeout=8) as sock:  # kept alive, then idle
        sock.sendall(_request("GET", "/health").replace(b"Connection: close", b"Connection: keep-alive"))
        first = sock.recv(65536)
        assert _status(first) == 200
        started = time.monotonic()
        while sock.recv(65536):
            pass
        assert time.monotonic() - started < 6


def test_a_client_that_does_not_read_its_answers_is_closed(server: Server) -> None:
    with socket.socket() as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        sock.connect(_address(server))
        request = _request("GET", "/regions").replace(b"Connection: close", b"Connection: keep-alive")
        sock.settimeout(0.5)
        sent = 0
        deadline = time.monotonic() + 20
        try:
            while sent < 5000 and time.monotonic() < deadline:  # pipelined, never read
                sock.sendall(request)
                sent += 1
        except OSError:
            pass  # the server stopped reading, or closed
        time.sleep(3)  # more than the send timeout
        sock.settimeout(10)
        received, closed = 0, False
        try:
            while chunk := sock.recv(1 << 20):
                received += chunk.count(b"HTTP/1.1 200")
            closed = True
        except ConnectionResetError:
            closed = True
        except TimeoutError:
            pass
        assert closed and received < sent, (closed, received, sent)


def test_headers_too_long_are_refused(server: Server) -> None:
    answer = _raw(server, b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Pad: " + b"a" * 70_000)
    assert _status(answer) == 431


def test_a_flood_of_slow_connections_does_not_stop_a_fresh_health(server: Server) -> None:
    sockets = []
    try:
        for _ in range(120):  # three times the connection limit, each sending part of its headers
            sock = socket.create_connection(_address(server), timeout=5)
            sock.sendall(b"GET /hea")
            sockets.append(sock)
        status, seconds = _health(server)
        assert status == 200 and seconds < 5
    finally:
        for sock in sockets:
            sock.close()


def test_slow_short_and_endless_bodies(server: Server) -> None:
    short = _request("POST", "/teach", b'{"id": 1', Content_Type="application/json")
    short = short.replace(b"Content-Length: 8", b"Content-Length: 100")  # promises more than it sends
    started = time.monotonic()
    answer = _raw(server, short, wait=8)
    assert _status(answer) == 408 and time.monotonic() - started < 6
    assert set(_json(answer)) == {"error", "status"}
    with socket.create_connection(_address(server), timeout=8) as sock:  # an endless chunked body
        sock.sendall(b"POST /teach HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                     b"Transfer-Encoding: chunked\r\n\r\n")
        answer = b""
        deadline = time.monotonic() + 8
        try:
            while time.monotonic() < deadline:
                sock.sendall(b"10000\r\n" + b" " * 0x10000 + b"\r\n")
        except OSError:
            pass  # the server answered and closed
        sock.settimeout(3)
        try:
            while chunk := sock.recv(65536):
                answer += chunk
        except OSError:
            pass
    assert answer and _status(answer) in (408, 413)


def test_bodies_over_the_endpoints_limit_are_refused_before_parsing(server: Server) -> None:
    answer = _raw(server, _request("POST", "/what", Content_Type="application/json").replace(
        b"Content-Length: 0", b"Content-Length: 99999999999"))
    assert _status(answer) == 413
    visual = b'{"x": 0, "y": 0, "theta": 0, "visual": [' + b"1, " * 3_000_000 + b"1]}"  # 9 MB of counts
    answer = _raw(server, _request("POST", "/what", visual, Content_Type="application/json"), wait=20)
    assert _status(answer) == 413 and "too large" in _json(answer)["error"]
    assert _health(server)[0] == 200
    for path in ("/health", "/teach/1"):  # endpoints without a body take almost none
        answer = _raw(server, _request("DELETE" if "teach" in path else "GET", path, b" " * 5000,
                                       Content_Type="application/json"))
        assert _status(answer) == 413


def _png_header(width: int, height: int) -> bytes:
    return (b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR" + width.to_bytes(4, "big") + height.to_bytes(4, "big")
            + b"\x08\x02\0\0\0" + b"\0" * 64)


def test_image_bombs_are_refused_from_their_header(server: Server) -> None:
    bomb = base64.b64encode(_png_header(4096, 4096)).decode()
    body = json.dumps({"x": 0.1, "y": 0.1, "theta": 0.0, "image": bomb}).encode()
    for path in ("/what", "/teach"):
        answer = _raw(server, _request("POST", path, body, Content_Type="application/json"))
        assert _status(answer) == 413 and "pixels" in _json(answer)["error"]
    raw = json.dumps({"x": 0.1, "y": 0.1, "theta": 0.0, "image": "AAAA", "encoding": "rgb8", "width": 4096,
                      "height": 4096}).encode()
    answer = _raw(server, _request("POST", "/what", raw, Content_Type="application/json"))
    assert _status(answer) in (413, 422)


def test_event_streams_are_bounded(server: Server) -> None:
    streams = []
    try:
        for _ in range(2):
            sock = socket.create_connection(_address(server), timeout=5)
            sock.sendall(_request("GET", "/events").replace(b"Connection: close", b"Connection: keep-alive"))
            assert _status(sock.recv(65536)) == 200
            streams.append(sock)
        answer = _raw(server, _request("GET", "/events"))
        assert _status(answer) == 503 and "event streams" in _json(answer)["error"]
    finally:
        for sock in streams:
            sock.close()
    deadline = time.monotonic() + 5
    while _status(_raw(server, _request("GET", "/events"), wait=0.5)) != 200:  # freed when they close
        assert time.monotonic() < deadline
        time.sleep(0.1)


def test_an_event_consumer_that_does_not_read_is_dropped(built: Path, tmp_path: Path) -> None:
    import threading

    import uvicorn

    from spco.service.app import ServeSettings
    from spco.service.connections import ConnectionGuard

    home = copy_home(built, tmp_path)
    with LiveHome(home, writer="thread", seed=0) as live:
        guard = ConnectionGuard(header_timeout=5, keep_alive=5, max_connections=32)
        app = create_app(live, settings=ServeSettings(subscriber_queue=4), connections=guard)
        listener = socket.socket()
        listener.bind(("127.0.0.1", 0))
        listener.listen(64)
        server = uvicorn.Server(uvicorn.Config(app, http=guard.protocol(), log_level="error", lifespan="off"))
        thread = threading.Thread(target=server.run, kwargs={"sockets": [listener]}, daemon=True)
        thread.start()
        try:
            deadline = time.monotonic() + 30
            while not server.started:
                assert time.monotonic() < deadline
                time.sleep(0.05)
            sock = socket.socket()
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            sock.connect(listener.getsockname())
            sock.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            assert sock.recv(12).startswith(b"HTTP/1.1 200")  # then never reads
            deadline = time.monotonic() + 30
            while app.app.state.events.streams and time.monotonic() < deadline:
                live._publish({"type": "answer", "kind": "what", "pad": "x" * 200_000})  # 200 kB each
                time.sleep(0.01)
            assert not app.app.state.events.streams  # dropped, its stream freed
            sock.close()
        finally:
            server.should_exit = True
            thread.join(10)


# ----------------------------------------------------------------------------- browser-borne requests
def test_cross_site_requests_cannot_teach(server: Server) -> None:
    teach = json.dumps({"id": 1, "sentence": "this is the evil room"}).encode()
    refused = {
        "foreign origin": _request("POST", "/teach", teach, Content_Type="application/json",
                                   Origin="http://evil.example"),
        "no content type": _request("POST", "/teach", teach),
        "text/plain": _request("POST", "/teach", teach, Content_Type="text/plain"),
        "form": _request("POST", "/teach", teach, Content_Type="application/x-www-form-urlencoded"),
        "null origin": _request("POST", "/teach", teach, Content_Type="application/json", Origin="null"),
        "sec-fetch-site": _request("POST", "/teach", teach, Content_Type="application/json",
                                   Sec_Fetch_Site="cross-site"),
        "undo": _request("DELETE", "/teach/1", Origin="http://evil.example"),
    }
    for label, request in refused.items():
        answer = _raw(server, request)
        assert _status(answer) in (403, 415), (label, answer[:300])
    before = _json(_raw(server, _request("GET", "/health")))["teachings"]
    assert before == 0
    own = f"http://127.0.0.1:{_address(server)[1]}"
    request = _request("POST", "/teach", teach, Content_Type="application/json", Origin=own)
    answer = _raw(server, request.replace(b"Host: 127.0.0.1", f"Host: {own[7:]}".encode()), wait=120)
    assert _status(answer) == 200, answer  # the server's own page (a browser's Host has the port)
    rebound = _raw(server, _request("GET", "/health").replace(b"Host: 127.0.0.1", b"Host: evil.example"))
    assert _status(rebound) == 400  # DNS rebinding


def test_the_page_cannot_be_framed(server: Server) -> None:
    for path in ("/", "/health", "/nope"):
        answer = _raw(server, _request("GET", path))
        head = answer.split(b"\r\n\r\n", 1)[0].lower()
        assert b"x-frame-options: deny" in head and b"frame-ancestors 'none'" in head, path


# ----------------------------------------------------------------------------- errors and leaks
def test_every_error_has_one_shape_and_no_leaks(server: Server) -> None:
    cases = {
        "unknown path": (_request("GET", "/nope"), 404),
        "wrong method": (_request("PUT", "/health", Content_Type="application/json"), 405),
        "malformed": (_request("POST", "/teach", b'{"id": ', Content_Type="application/json"), 400),
        "wrong value": (_request("GET", "/what?x=nan&y=0&theta=0"), 422),
        "not found": (_request("GET", "/where?name=xqzzyvw"), 404),
        "encoding without image": (_request("POST", "/what", json.dumps(
            {"x": 0, "y": 0, "theta": 0, "encoding": "rgb8", "width": 8}).encode(),
            Content_Type="application/json"), 422),
    }
    for label, (request, status) in cases.items():
        answer = _raw(server, request, wait=30)
        assert answer and _status(answer) == status, (label, answer[:300])
        body = _json(answer)
        assert set(body) == {"error", "status"} and body["status"] == status, (label, body)
    for path in ("/what", "/teach"):  # the same rule for both: encoding and width go with an image
        answer = _raw(server, _request("POST", path, json.dumps(
            {"x": 0, "y": 0, "theta": 0, "encoding": "rgb8", "width": 8}).encode(),
            Content_Type="application/json"), wait=30)
        assert _status(answer) == 422 and "give the image too" in _json(answer)["error"], (path, answer)
    health = _json(_raw(server, _request("GET", "/health")))
    text = json.dumps(health)
    assert "file" not in health and "pid" not in text and str(server.home) not in text


def test_internal_errors_and_a_gone_writer_say_nothing_of_the_server(built: Path, tmp_path: Path) -> None:
    home = copy_home(built, tmp_path)
    live = LiveHome(home, writer="thread", seed=0)
    try:
        app = create_app(live)
        with TestClient(app, base_url="http://127.0.0.1", raise_server_exceptions=False) as client:
            def broken(request: object) -> dict:
                raise RuntimeError(f"secret state in {home}")

            live.answer = broken  # type: ignore[method-assign]
            answer = client.get("/where", params={"name": "kitchen"})
            assert answer.status_code == 500 and "secret" not in answer.text and str(home) not in answer.text
            assert answer.json()["status"] == 500
            del live.answer
            live._writer.close()  # the writer gone: 503 without the journal's path
            answer = client.post("/teach", json={"id": int(live.home.ids[0]), "sentence": "hello"})
            assert answer.status_code == 503 and str(tmp_path) not in answer.text
    finally:
        live.close()


# ----------------------------------------------------------------------------- signing in
def test_sign_in_keeps_the_token_out_of_urls_and_sessions_expire_and_revoke(built: Path,
                                                                            tmp_path: Path) -> None:
    token = "s3cret-token-of-the-robot"
    home = copy_home(built, tmp_path)
    with LiveHome(home, writer="thread") as live:
        app = create_app(live, token=token, session_hours=1.0)
        with TestClient(app, base_url="https://robot.local") as client:
            assert client.get("/login", params={"token": token}).status_code == 400
            signed = client.post("/login", data={"token": token}, follow_redirects=False)
            cookie = signed.headers["set-cookie"].lower()
            assert signed.status_code == 303 and "max-age=3600" in cookie and "secure" in cookie
            session = client.cookies.get("spco_session")
            assert session and token not in session
            assert client.get("/health").status_code == 200
            assert client.post("/logout", headers={"Content-Type": "application/x-www-form-urlencoded"},
                               follow_redirects=False).status_code == 303
            client.cookies.set("spco_session", session, domain="robot.local")
            assert client.get("/health").status_code == 401  # that session is over
            client.cookies.clear()
            client.post("/login", data={"token": token}, follow_redirects=False)
            bearer = {"Authorization": f"Bearer {token}"}
            assert client.delete("/sessions", headers=bearer).json()["revoked"] >= 1
            assert client.get("/health").status_code == 401


# ----------------------------------------------------------------------------- the oldest frameworks
_OLDEST_CHECK = r"""
import json, sys, threading, time, socket, urllib.request
import fastapi, starlette, uvicorn
from spco.service import LiveHome
from spco.service.app import create_app
from spco.service.connections import ConnectionGuard
versions = {"fastapi": fastapi.__version__, "starlette": starlette.__version__,
            "uvicorn": uvicorn.__version__}
live = LiveHome(sys.argv[1], writer="thread", seed=0)
guard = ConnectionGuard(header_timeout=1, keep_alive=1, max_connections=20)
config = uvicorn.Config(create_app(live, connections=guard), host="127.0.0.1", port=0, http=guard.protocol(),
                        log_level="error", lifespan="off")
server = uvicorn.Server(config)
sock = socket.socket(); sock.bind(("127.0.0.1", 0)); sock.listen(256)
port = sock.getsockname()[1]
thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True); thread.start()
while not server.started: time.sleep(0.05)
def send(data):
    with socket.create_connection(("127.0.0.1", port), timeout=5) as c:
        c.sendall(data); out = b""
        try:
            while chunk := c.recv(65536): out += chunk
        except OSError: pass
        return out
body = json.dumps({"id": int(live.home.ids[0]), "sentence": "this is the evil room"}).encode()
head = ("POST /teach HTTP/1.1\r\nHost: 127.0.0.1\r\nOrigin: http://evil.example\r\nConnection: close\r\n"
        f"Content-Type: application/json\r\nContent-Length: {len(body)}\r\n\r\n")
cross = send(head.encode() + body)
slow = [socket.create_connection(("127.0.0.1", port)) for _ in range(50)]
for c in slow: c.sendall(b"GET /hea")
health = send(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")
timed = send(b"GET /hea")
from fastapi.testclient import TestClient
from pydantic import BaseModel
class Body(BaseModel):
    id: int
bare = fastapi.FastAPI()
@bare.post("/teach")
def bare_teach(body: Body) -> dict:
    return {"taught": body.id}
framework = TestClient(bare).post("/teach", content=b'{"id": 1}').status_code  # no Content-Type
print(json.dumps({"versions": versions, "cross": cross[:12].decode(), "teachings": live.health()["teachings"],
                  "health": health[:12].decode(), "slow": timed[:12].decode(), "framework": framework}))
server.should_exit = True; thread.join(10); live.close()
"""


def _minimum(requirement: str) -> str:
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    match = re.search(rf'"{requirement}(?:\[[a-z]+\])?>=([0-9.]+)[",]', text)
    assert match, f"pyproject.toml has no minimum for {requirement}"
    return match.group(1)


def test_cross_site_teaching_is_refused_with_the_oldest_frameworks_allowed(built: Path,
                                                                           tmp_path: Path) -> None:
    fastapi_min, uvicorn_min = _minimum("fastapi"), _minimum("uvicorn")
    target = tmp_path / "oldest"

    def install(*packages: str) -> None:
        installed = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target",
                                    str(target), *packages], capture_output=True, text=True, timeout=300)
        if installed.returncode != 0:
            if os.environ.get("CI") == "true":
                raise AssertionError(f"cannot install {packages}:\n{installed.stderr[-2000:]}")
            pytest.skip(f"cannot install {packages} (offline?): {installed.stderr.strip()[-300:]}")

    install(f"fastapi=={fastapi_min}", f"uvicorn=={uvicorn_min}")
    metadata = next(target.glob("fastapi-*.dist-info")).joinpath("METADATA").read_text(encoding="utf-8")
    starlette_min = re.search(r"Requires-Dist: starlette[^\n]*>=([0-9.]+)", metadata)
    assert starlette_min, "fastapi's metadata names no starlette minimum"
    install(f"starlette=={starlette_min.group(1)}")  # the oldest starlette that fastapi allows
    home = copy_home(built, tmp_path / "home")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(target), SRC]))
    ran = subprocess.run([sys.executable, "-c", _OLDEST_CHECK, str(home)], capture_output=True, text=True,
                         timeout=300, env=env)
    assert ran.returncode == 0, ran.stderr[-3000:]
    result = json.loads(ran.stdout.strip().splitlines()[-1])
    from packaging.version import Version

    assert Version(result["versions"]["fastapi"]) == Version(fastapi_min), result
    assert Version(result["versions"]["uvicorn"]) == Version(uvicorn_min), result
    assert result["cross"].endswith("403") and result["teachings"] == 0
    assert result["health"].endswith("200")  # under 50 slow connections and a limit of 20
    assert result["slow"].endswith("408")  # the header timer works on the oldest uvicorn
    assert result["framework"] == 422, result  # FastAPI's own protection: no JSON without Content-Type
