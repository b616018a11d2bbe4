"""``spco serve`` under attack, over loopback: slow connections, idle subscribers, image bombs.

The server runs with the open-file limit set to 1,024 (``RLIMIT_NOFILE``, set by this script in
the server process before it starts) and its default limits; the attacking clients raise their
own limit to the hard one. The served home is that of ``serve_latency.py`` (a 16-home SIGVerse
knowledge fitted on camera images, adapted to 3LDK_9; built once into ``--dir``), or with
``--synthetic`` a small synthetic home fitted on images (seconds to build).

1. **Slow connections**: an attacker holds ``--slow`` (1,100) connections that each sent ``GET
   /hea`` and nothing more, opening new ones every 0.5 s for those the server closed (the server
   keeps at most its connection limit, 960 at 1,024 files, closing the oldest); meanwhile a fresh
   client sends ``GET /health`` on a new connection every 100 ms: p50/p95/max latency, and
   whether every one was answered (target: ≤ 100 ms).
2. **Idle subscribers**: ``--subscribers`` (500) clients open ``/events`` and never read (the
   server accepts up to its limit and refuses the rest with 503); one keep-alive client asks
   ``what`` at random poses: p50/p99 beside the same without subscribers (target: p50 ≤ 2 ms).
3. **Image bombs**: 8 clients at once send ``POST /what`` with a 4096 × 4096 PNG of a few tens of
   kB (refused from its header), then 8 at once with the largest image the server decodes
   (2048 × 2048 PNG), for ``--bomb-seconds``; the server's and its writer's resident memory is
   sampled every 20 ms: growth of the peak over the start, the start taken after the server has
   answered three 640 × 480 camera views (its extractor loaded) (target: ≤ 100 MB).

Prints a Markdown table and the load averages; ``--json FILE`` keeps the numbers.

    python benchmarks/serve_attack.py --dir /tmp/serve-bench
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import re
import resource
import shutil
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from serve_latency import DATA, build, load  # noqa: E402

SERVER_NOFILE = 1024


def _limit_files() -> None:
    resource.setrlimit(resource.RLIMIT_NOFILE, (SERVER_NOFILE, SERVER_NOFILE))


class Served:
    """``spco serve`` on a fresh copy of ``home`` with ``RLIMIT_NOFILE`` = 1,024."""

    def __init__(self, home: Path, folder: Path, *args: str) -> None:
        self.file = folder / "attacked.spco"
        for suffix in ("", ".journal", ".lock"):
            Path(str(self.file) + suffix).unlink(missing_ok=True)
        shutil.copyfile(home, self.file)
        from spco.service.client import ServeProcess

        server = ServeProcess(self.file, "--port", "0", "--seed", "0", *args, preexec_fn=_limit_files)
        self.process, self.url = server.process, server.url
        host, port = self.url[len("http://"):].rsplit(":", 1)
        self.address = (host, int(port))
        limit = Path(f"/proc/{self.process.pid}/limits").read_text()
        self.nofile = int(re.search(r"Max open files\s+(\d+)", limit).group(1))  # type: ignore[union-attr]

    def rss(self) -> int:
        """Resident bytes of the server and its children (the writer)."""
        total = 0
        pids = [self.process.pid]
        children = Path(f"/proc/{self.process.pid}/task/{self.process.pid}/children")
        if children.exists():
            pids += [int(p) for p in children.read_text().split()]
        for pid in pids:
            try:
                for line in Path(f"/proc/{pid}/status").read_text().splitlines():
                    if line.startswith("VmRSS:"):
                        total += int(line.split()[1]) * 1024
            except OSError:
                pass
        return total

    def cpu_seconds(self) -> float:
        """CPU time (user + system) of the server process so far."""
        fields = Path(f"/proc/{self.process.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def stop(self) -> None:
        self.process.send_signal(2)
        try:
            self.process.wait(60)
        except subprocess.TimeoutExpired:
            self.process.kill()


def _request(method: str, path: str, body: bytes = b"", keep: bool = False, **headers: str) -> bytes:
    connection = "keep-alive" if keep else "close"
    lines = [f"{method} {path} HTTP/1.1", "Host: 127.0.0.1", f"Connection: {connection}",
             *(f"{k.replace('_', '-')}: {v}" for k, v in headers.items())]
    if body or method == "POST":
        lines.append(f"Content-Length: {len(body)}")
    return ("\r\n".join(lines) + "\r\n\r\n").encode() + body


def _exchange(address: tuple[str, int], data: bytes, timeout: float = 10.0) -> tuple[int, float]:
    """Status and seconds of one request on a new connection (0 for no answer)."""
    started = time.perf_counter()
    try:
        with socket.create_connection(address, timeout=timeout) as sock:
            sock.sendall(data)
            answer = b""
            while b"\r\n" not in answer:
                chunk = sock.recv(65536)
                if not chunk:
                    break
                answer += chunk
    except OSError:
        return 0, time.perf_counter() - started
    match = re.match(rb"HTTP/1.1 (\d{3})", answer)
    return (int(match.group(1)) if match else 0), time.perf_counter() - started


def _percentiles(seconds: list[float]) -> dict[str, float]:
    ms = np.asarray(seconds) * 1000
    return {"p50": float(np.percentile(ms, 50)), "p95": float(np.percentile(ms, 95)),
            "p99": float(np.percentile(ms, 99)), "max": float(ms.max()), "n": len(ms)}


# ----------------------------------------------------------------------------- 1. slow connections
def slow_connections(served: Served, count: int, seconds: float) -> dict[str, Any]:
    stop = threading.Event()
    opened = [0]
    held: list[socket.socket] = []

    def attacker() -> None:
        while not stop.is_set():
            alive = []
            for sock in held:  # keep those the server has not closed
                try:
                    sock.setblocking(False)
                    if sock.recv(1, socket.MSG_PEEK) == b"":
                        sock.close()
                        continue
                    sock.close()  # it answered (408): closed by the server next
                    continue
                except BlockingIOError:
                    alive.append(sock)
                except OSError:
                    sock.close()
            held[:] = alive
            while len(held) < count and not stop.is_set():
                try:
                    sock = socket.create_connection(served.address, timeout=2)
                    sock.sendall(b"GET /hea")
                    held.append(sock)
                    opened[0] += 1
                except OSError:
                    break
            stop.wait(0.5)

    thread = threading.Thread(target=attacker, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while len(held) < count and time.monotonic() < deadline:
        time.sleep(0.1)
    times, statuses = [], []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        status, took = _exchange(served.address, _request("GET", "/health"))
        statuses.append(status)
        times.append(took)
        time.sleep(0.1)
    held_at_end = len(held)
    stop.set()
    thread.join(10)
    for sock in held:
        sock.close()
    return {"health": _percentiles(times), "answered": sum(s == 200 for s in statuses),
            "asked": len(statuses), "connections_opened": opened[0], "held_at_end": held_at_end}


# ----------------------------------------------------------------------------- 2. idle subscribers
def _what_latency(served: Served, n: int, extent: list[float]) -> dict[str, float]:
    rng = np.random.default_rng(0)
    sock = socket.create_connection(served.address, timeout=10)
    times = []
    cpu = served.cpu_seconds()
    try:
        for _ in range(n):
            x, y = rng.uniform(extent[0], extent[1]), rng.uniform(extent[2], extent[3])
            data = _request("GET", f"/what?x={x:.3f}&y={y:.3f}&theta=0.5", keep=True)
            started = time.perf_counter()
            sock.sendall(data)
            answer = b""
            while True:
                answer += sock.recv(65536)
                head, _, body = answer.partition(b"\r\n\r\n")
                length = re.search(rb"content-length: (\d+)", head, re.I)
                if length and len(body) >= int(length.group(1)):
                    break
            times.append(time.perf_counter() - started)
    finally:
        sock.close()
    return {**_percentiles(times), "server_cpu_ms": (served.cpu_seconds() - cpu) * 1000 / n}


def idle_subscribers(served: Served, count: int, n: int) -> dict[str, Any]:
    with socket.create_connection(served.address, timeout=10) as sock:
        sock.sendall(_request("GET", "/regions"))
        data = b""
        while chunk := sock.recv(1 << 20):
            data += chunk
    extent = json.loads(data.partition(b"\r\n\r\n")[2])["extent"]
    _what_latency(served, 50, extent)  # warm
    before = _what_latency(served, n, extent)
    subscribers, refused = [], 0
    for _ in range(count):
        sock = socket.create_connection(served.address, timeout=10)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        sock.sendall(_request("GET", "/events", keep=True))
        head = sock.recv(256)
        if head.startswith(b"HTTP/1.1 200"):
            subscribers.append(sock)  # and never read again
        else:
            refused += 1
            sock.close()
    during = _what_latency(served, n, extent)
    for sock in subscribers:
        sock.close()
    return {"without": before, "with": during, "accepted": len(subscribers), "refused": refused}


# ----------------------------------------------------------------------------- 3. image bombs
def _png(width: int, height: int) -> bytes:
    import cv2

    image = np.zeros((height, width, 3), dtype=np.uint8)
    image[::64, :, 1] = 255  # a little structure; compresses to tens of kB
    ok, data = cv2.imencode(".png", image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    assert ok
    return data.tobytes()


def image_bombs(served: Served, clients: int, seconds: float) -> dict[str, Any]:
    import cv2

    view = np.random.default_rng(0).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    _, jpeg = cv2.imencode(".jpg", view)
    warm = json.dumps({"x": 0.0, "y": 0.0, "theta": 0.0, "image": base64.b64encode(jpeg.tobytes()).decode()})
    for _ in range(3):  # a server that has answered a camera view (its extractor and buffers in place)
        assert _exchange(served.address, _request("POST", "/what", warm.encode(),
                                                  Content_Type="application/json"), timeout=60)[0] == 200
    time.sleep(1)
    peak = [served.rss()]
    start_rss = peak[0]
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            peak[0] = max(peak[0], served.rss())
            stop.wait(0.02)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    results: dict[str, Any] = {}
    for label, (width, height) in (("4096x4096", (4096, 4096)), ("2048x2048", (2048, 2048))):
        png = _png(width, height)
        image = base64.b64encode(png).decode()
        body = json.dumps({"x": 0.0, "y": 0.0, "theta": 0.0, "image": image}).encode()
        request = _request("POST", "/what", body, Content_Type="application/json")
        statuses: list[int] = []
        end = time.monotonic() + seconds

        def bomber() -> None:
            while time.monotonic() < end:  # noqa: B023
                statuses.append(_exchange(served.address, request, timeout=60)[0])  # noqa: B023

        threads = [threading.Thread(target=bomber) for _ in range(clients)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        counts: dict[str, int] = {}
        for status in statuses:
            counts[str(status)] = counts.get(str(status), 0) + 1
        results[label] = {"png_bytes": len(png), "statuses": counts}
    stop.set()
    sampler.join()
    results.update(start_mb=start_rss / 1e6, peak_mb=peak[0] / 1e6, growth_mb=(peak[0] - start_rss) / 1e6)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--dir", type=Path, default=Path("/tmp/serve-bench"))
    parser.add_argument("--data", type=Path, default=DATA, help="the datasets folder (shared/datasets)")
    parser.add_argument("--synthetic", action="store_true", help="a small synthetic home instead of SIGVerse")
    parser.add_argument("--slow", type=int, default=1100)
    parser.add_argument("--slow-seconds", type=float, default=20.0)
    parser.add_argument("--subscribers", type=int, default=500)
    parser.add_argument("--n", type=int, default=2000, help="what requests per latency figure")
    parser.add_argument("--bomb-seconds", type=float, default=10.0)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--only", choices=("slow", "subscribers", "bombs"), default=None)
    args = parser.parse_args()
    _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))  # the attackers need more than 1,024
    if args.synthetic:
        sys.path.insert(0, str(HERE.parent / "tests"))
        from serve_helpers import build_home

        args.dir.mkdir(parents=True, exist_ok=True)
        home = args.dir / "home.spco"
        if not home.exists():
            home = build_home(args.dir)
    else:
        home = build(args.dir, args.data / "sigverse", args.data / "sigverse_images")
    report: dict[str, Any] = {"home": str(home), "server_nofile": None}
    rows = []
    for name, run in (("slow", lambda s: slow_connections(s, args.slow, args.slow_seconds)),
                      ("subscribers", lambda s: idle_subscribers(s, args.subscribers, args.n)),
                      ("bombs", lambda s: image_bombs(s, 8, args.bomb_seconds))):
        if args.only not in (None, name):
            continue
        before = load()
        served = Served(home, args.dir)
        report["server_nofile"] = served.nofile
        try:
            result = run(served)
        finally:
            served.stop()
        result["load"] = [before, load()]
        report[name] = result
        print(json.dumps({name: result}), flush=True)
    if args.only is not None:
        return
    slow, subs, bombs = report["slow"], report["subscribers"], report["bombs"]
    rows = [
        ("fresh GET /health under slow connections (ms)",
         f"p50 {slow['health']['p50']:.1f}, p95 {slow['health']['p95']:.1f}, "
         f"max {slow['health']['max']:.1f}; "
         f"{slow['answered']}/{slow['asked']} answered; {slow['held_at_end']} held, "
         f"{slow['connections_opened']} opened", "≤ 100", slow["health"]["max"] <= 100
         and slow["answered"] == slow["asked"]),
        ("what with idle subscribers (ms)",
         f"p50 {subs['with']['p50']:.2f}, p99 {subs['with']['p99']:.2f}, server CPU "
         f"{subs['with']['server_cpu_ms']:.2f} ms a request (without: p50 {subs['without']['p50']:.2f}, CPU "
         f"{subs['without']['server_cpu_ms']:.2f}); {subs['accepted']} accepted, {subs['refused']} refused",
         "p50 ≤ 2", subs["with"]["p50"] <= 2),
        ("memory under 8 concurrent image bombs (MB)",
         f"growth {bombs['growth_mb']:.1f} (start {bombs['start_mb']:.0f}, peak {bombs['peak_mb']:.0f}); "
         f"4096²: {bombs['4096x4096']['statuses']}, 2048²: {bombs['2048x2048']['statuses']}", "≤ 100",
         bombs["growth_mb"] <= 100),
    ]
    print(f"\nserver RLIMIT_NOFILE {report['server_nofile']}; home {home}\n")
    print("| figure | measured | target | met |\n|---|---|---|---|")
    for label, text, target, met in rows:
        print(f"| {label} | {text} | {target} | {'yes' if met else 'NO'} |")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
