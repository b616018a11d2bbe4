"""Latency and load of ``spco serve`` measured with real HTTP clients over loopback.

The served home is adapted from a 16-home SIGVerse knowledge fitted on the camera images with the
default extractor (colour-hog): ``spco fit`` on the paper's 16 experienced homes, ``spco adapt``
for 3LDK_9 (its bedrooms taught at 40 %). Both are built once into ``--dir`` (about 30 s) and the
commands are printed. Each figure starts ``spco serve`` on a fresh copy of the home; the clients
are ``spco.service.client.Client`` (``http.client``, one keep-alive connection each), in processes of their
own where there are several.

- ``what`` by pose, one client: p50/p99 over ``--n`` requests at random poses on the map;
- ``where``, one client (the home's names in turn);
- ``what`` with a 640 × 480 JPEG (a SIGVerse view resized, quality 90, base64 in ``POST /what``);
- ``teach`` by sample id, one client (sentences "this is the <name>" in turn), and by pose with the
  same JPEG (a new observation);
- ``what`` by pose with 8 client processes in closed loops: answers per second, p50/p99;
- ``what`` p99 during a burst of teachings (one reader, two teaching clients back to back), with the
  writer in a process of its own (the default) and, for comparison, in a thread of the server;
- a soak at ``--rate`` requests/s for ``--soak`` seconds (60 % what, 30 % where, 10 % teach by id;
  4 client processes sending on a fixed schedule): errors, server memory (the server's and its
  writer's resident memory, sampled each second) at the start and end, and — apart — the cost of a
  new observation: resident memory and home file bytes per observation taught.

Prints a Markdown table with the load averages before and after each figure; ``--json FILE`` keeps
the numbers.

    python benchmarks/serve_latency.py --dir /tmp/serve-bench
"""

from __future__ import annotations

import argparse
import contextlib
import json
import multiprocessing as mp
import os
import queue
import re
import shutil
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

HOMES16 = ("3LDK_1,1LDK_8,2LDK_8,1LDK_7,2LDK_7,1LDK_6,2LDK_6,1LDK_5,2LDK_5,1LDK_4,2LDK_4,1LDK_3,2LDK_3,"
           "1LDK_2,2LDK_2,1LDK_1")
DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def run(command: list[str]) -> None:
    print("$ " + " ".join(command), flush=True)
    subprocess.run(command, check=True)


def build(folder: Path, sigverse: Path, images: Path) -> Path:
    """The knowledge and the home (once); returns the home file."""
    folder.mkdir(parents=True, exist_ok=True)
    knowledge, home = folder / "k16.spco", folder / "home_3LDK_9.spco"
    if not knowledge.exists():
        run(["spco", "fit", "--data", str(sigverse), "--homes", HOMES16, "--images", str(images),
             "--seed", "0", "--out", str(knowledge)])
    if not home.exists():
        run(["spco", "adapt", str(knowledge), "--home", str(sigverse / "3LDK_9"), "--images", str(images),
             "-r", "40", "--seed", "0", "--out", str(home)])
    return home


class Served:
    """``spco serve`` on a fresh copy of the home, on a free loopback port."""

    def __init__(self, home: Path, folder: Path, writer: str = "process") -> None:
        self.file = folder / "served.spco"
        for suffix in ("", ".journal", ".lock"):
            Path(str(self.file) + suffix).unlink(missing_ok=True)
        shutil.copyfile(home, self.file)
        from spco.service.client import Client, ServeProcess

        server = ServeProcess(self.file, "--port", "0", "--seed", "0", "--writer", writer)
        self.process, self.url = server.process, server.url
        self.writer_pid = Client(self.url).health()["writer"]["pid"]

    def rss_mb(self) -> tuple[float, float]:
        """Resident memory of the server process and of its writer process, MB."""
        sizes = []
        for pid in (self.process.pid, self.writer_pid):
            text = Path(f"/proc/{pid}/status").read_text()
            sizes.append(int(re.search(r"VmRSS:\s+(\d+) kB", text).group(1)) / 1024)  # type: ignore[union-attr]
        return sizes[0], sizes[1]

    def stop(self) -> None:
        self.process.send_signal(signal.SIGINT)
        self.process.wait(60)


def percentiles(values: list[float]) -> dict[str, float]:
    ms = np.asarray(values) * 1000
    return {"n": int(ms.size), "p50_ms": float(np.percentile(ms, 50)), "p99_ms": float(np.percentile(ms, 99)),
            "max_ms": float(ms.max())}


def poses(regions: dict[str, Any], n: int, seed: int) -> list[tuple[float, float, float]]:
    x0, x1, y0, y1 = regions["extent"]
    rng = np.random.default_rng(seed)
    return [(float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)), float(rng.uniform(-3.1, 3.1)))
            for _ in range(n)]


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` so far (``/proc/PID/stat``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def timed(call: Any, items: list[Any], warm: int = 20, served: Served | None = None
          ) -> tuple[list[float], dict[str, float]]:
    """Latencies of ``call`` on each item (after ``warm`` unmeasured calls), and the CPU time the
    server and its writer spent per call (ms): less sensitive to other programs' load than the wall
    time."""
    for item in items[:warm]:
        call(item)
    out = []
    cpu = (cpu_seconds(served.process.pid), cpu_seconds(served.writer_pid)) if served else (0.0, 0.0)
    for item in items:
        start = time.perf_counter()
        call(item)
        out.append(time.perf_counter() - start)
    extra = {}
    if served is not None:
        extra = {"server_cpu_ms_per_call": 1000 * (cpu_seconds(served.process.pid) - cpu[0]) / len(items),
                 "writer_cpu_ms_per_call": 1000 * (cpu_seconds(served.writer_pid) - cpu[1]) / len(items)}
    return out, extra


def measured(call: Any, items: list[Any], served: Served, warm: int = 20) -> dict[str, float]:
    """:func:`timed` as the fields of a figure: percentiles and CPU per call."""
    latencies, extra = timed(call, items, warm, served)
    return {**percentiles(latencies), **extra}


# ------------------------------------------------------------------------------ client processes
def _what_loop(url: str, extent: list[float], seconds: float, seed: int, results: Any) -> None:
    from spco.service.client import Client

    client = Client(url)
    rng = np.random.default_rng(seed)
    x0, x1, y0, y1 = extent
    latencies, errors = [], 0
    client.what(0.0, 0.0, 0.0)
    end = time.perf_counter() + seconds
    while (now := time.perf_counter()) < end:
        try:
            client.what(float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)), 0.0)
        except Exception:
            errors += 1
        latencies.append(time.perf_counter() - now)
    results.put((latencies, errors))


def _teach_burst(url: str, ids: list[int], names: list[str], teachers: int, each: int, results: Any) -> None:
    """``teachers`` clients (threads of this process) teaching ``each`` times back to back."""
    from spco.service.client import Client

    taught: list[float] = []

    def teach(offset: int) -> None:
        client = Client(url)
        for k in range(offset, offset + each):
            t = time.perf_counter()
            client.teach(id=int(ids[(7 * k) % len(ids)]), sentence=f"this is the {names[k % len(names)]}")
            taught.append(time.perf_counter() - t)

    threads = [threading.Thread(target=teach, args=(1000 * i,)) for i in range(teachers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    results.put(taught)


def _soak_worker(url: str, regions: dict[str, Any], labels: dict[int, str], rate: float, seconds: float,
                 seed: int, results: Any, threads: int = 8) -> None:
    """Requests at ``rate`` per second for ``seconds`` on a fixed schedule (request k at k / rate),
    sent by ``threads`` clients in turn, so that slow answers do not slow the schedule down."""
    from spco.service.client import Client

    x0, x1, y0, y1 = regions["extent"]
    ids, names = list(labels), list(labels.values())
    usable = sorted(set(names))
    latencies: dict[str, list[float]] = {"what": [], "where": [], "teach": []}
    errors: list[str] = []
    total = int(rate * seconds)
    start = time.perf_counter() + 0.5
    guard = threading.Lock()

    def run(offset: int) -> None:
        client = Client(url)
        rng = np.random.default_rng([seed, offset])
        for k in range(offset, total, threads):
            pause = start + k / rate - time.perf_counter()
            if pause > 0:
                time.sleep(pause)
            roll = rng.random()
            t = time.perf_counter()
            try:
                if roll < 0.6:
                    kind = "what"
                    client.what(float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)), 0.0)
                elif roll < 0.9:
                    kind = "where"
                    client.where(usable[int(rng.integers(len(usable)))], n=10)
                else:  # a person confirms the name of the place a sample is at (as the home answers it)
                    kind = "teach"
                    sample = int(rng.integers(len(ids)))
                    client.teach(id=ids[sample], sentence=f"this is the {names[sample]}")
            except Exception as exc:
                with guard:
                    errors.append(f"{type(exc).__name__}: {exc}")
            with guard:
                latencies[kind].append(time.perf_counter() - t)

    workers = [threading.Thread(target=run, args=(i,)) for i in range(threads)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    results.put((latencies, errors, total))


class _Figures:
    """The figures measured, each printed as a JSON line as it is recorded."""

    def __init__(self, only: str | None) -> None:
        self.only = None if only is None else set(only.split(","))
        self.rows: list[dict[str, Any]] = []

    def wanted(self, name: str) -> bool:
        return self.only is None or name in self.only

    def record(self, figure: str, before: str, **values: Any) -> None:
        row = {"figure": figure, "load_before": before, "load_after": load(), **values}
        self.rows.append(row)
        print(json.dumps(row), flush=True)

    def print_table(self) -> None:
        print("\n| figure | p50 ms | p99 ms | other | load before → after |\n|---|---|---|---|---|")
        for row in self.rows:
            other = {k: (round(v, 2) if isinstance(v, float) else v) for k, v in row.items()
                     if k not in ("figure", "p50_ms", "p99_ms", "load_before", "load_after", "max_ms",
                                  "first_errors")}
            p50 = f"{row['p50_ms']:.2f}" if "p50_ms" in row else "-"
            p99 = f"{row['p99_ms']:.2f}" if "p99_ms" in row else "-"
            print(f"| {row['figure']} | {p50} | {p99} | {json.dumps(other)} | {row['load_before']} → "
                  f"{row['load_after']} |")


def _one_client(figures: _Figures, client: Any, served: Served, regions: dict[str, Any], n: int,
                jpeg: bytes) -> None:
    """what, where, what with an image, teach by id and by a new observation: one client, in turn."""
    names = regions["names"]
    ids = [s["id"] for s in regions["samples"]]
    if figures.wanted("what"):
        before = load()
        items = poses(regions, n, 1)
        figures.record("what by pose, 1 client", before, **measured(lambda p: client.what(*p), items, served))
    if figures.wanted("where"):
        before = load()
        items = [names[k % len(names)] for k in range(n)]
        figures.record("where (n=10), 1 client", before, **measured(lambda m: client.where(m), items, served))
    if figures.wanted("image"):
        before = load()
        items = poses(regions, max(n // 4, 50), 2)
        figures.record("what with a 640x480 JPEG, 1 client", before, bytes=len(jpeg),
                       **measured(lambda p: client.what(*p, image=jpeg), items, served, warm=5))
    if figures.wanted("teach"):
        before = load()
        items = [(ids[(7 * k) % len(ids)], f"this is the {names[k % len(names)]}") for k in range(200)]
        figures.record("teach by sample id, 1 client", before,
                       **measured(lambda t: client.teach(id=t[0], sentence=t[1]), items, served, warm=5))
        before = load()
        items = poses(regions, 100, 3)
        figures.record("teach a new observation with a 640x480 JPEG, 1 client", before,
                       **measured(lambda p: client.teach(x=p[0], y=p[1], theta=p[2], image=jpeg,
                                                         sentence="this is the study"), items, served,
                                  warm=3))


def _many_clients(figures: _Figures, served: Served, regions: dict[str, Any], clients: int,
                  seconds: float) -> None:
    """what by pose from ``clients`` processes for ``seconds``."""
    before = load()
    ctx = mp.get_context("spawn")
    results = ctx.Queue()
    workers = [ctx.Process(target=_what_loop, args=(served.url, regions["extent"], seconds, k, results))
               for k in range(clients)]
    for w in workers:
        w.start()
    gathered = [results.get(timeout=seconds + 120) for _ in workers]
    for w in workers:
        w.join()
    latencies = [v for lat, _ in gathered for v in lat]
    figures.record(f"what by pose, {clients} client processes", before,
                   answers_per_second=len(latencies) / seconds,
                   errors=sum(e for _, e in gathered), **percentiles(latencies))


def _burst(figures: _Figures, home: Path, folder: Path, regions: dict[str, Any]) -> None:
    """what by pose while two processes teach 100 sentences each, with each writer."""
    from spco.service.client import Client

    names = regions["names"]
    ids = [s["id"] for s in regions["samples"]]
    for writer in ("process", "thread"):
        served = Served(home, folder, writer=writer)
        before = load()
        reader = Client(served.url)
        items = poses(regions, 100000, 4)
        for p in items[:50]:
            reader.what(*p)
        ctx = mp.get_context("spawn")
        results = ctx.Queue()
        burst = ctx.Process(target=_teach_burst, args=(served.url, ids, names, 2, 100, results))
        burst.start()
        latencies = []
        k = 0
        while results.empty():  # the reader asks while the teachers teach
            t0 = time.perf_counter()
            reader.what(*items[k % len(items)])
            latencies.append(time.perf_counter() - t0)
            k += 1
        taught = results.get()
        burst.join()
        figures.record(f"what during a burst of teachings (writer: {writer})", before, teachings=len(taught),
                       teach_p50_ms=float(np.percentile(np.asarray(taught) * 1000, 50)),
                       **percentiles(latencies))
        served.stop()


def _soak(figures: _Figures, served: Served, client: Any, regions: dict[str, Any], rate: float,
          seconds: float) -> None:
    """``rate`` requests a second (60 % what, 30 % where, 10 % teach) from 4 processes for ``seconds``,
    the served processes' memory each second."""
    # each sample's name as the home answers it at the sample's pose: what the soak's people confirm
    labels = {s["id"]: client.what(s["x"], s["y"], s["theta"])["names"][0]["name"]
              for s in regions["samples"]}
    served_rss = served.rss_mb()
    before = load()
    ctx = mp.get_context("spawn")
    results = ctx.Queue()
    workers = [ctx.Process(target=_soak_worker, args=(served.url, regions, labels, rate / 4,
                                                      seconds, k, results)) for k in range(4)]
    for w in workers:
        w.start()
    memory = []
    gathered = []
    start = time.perf_counter()
    while len(gathered) < len(workers):  # memory each second until every worker has reported
        if time.perf_counter() - start > seconds + 600:
            served.stop()
            raise SystemExit("the soak's clients did not finish")
        memory.append(served.rss_mb())
        with contextlib.suppress(queue.Empty):
            gathered.append(results.get(timeout=1.0))
    for w in workers:
        w.join()
    errors = [e for _, errs, _ in gathered for e in errs]
    sent = sum(k for _, _, k in gathered)
    by_kind = {kind: [v for lat, _, _ in gathered for v in lat[kind]]
               for kind in ("what", "where", "teach")}
    total = [a + b for a, b in memory]
    warm = total[min(10, len(total) - 1)]
    figure = f"soak: {rate:g} requests/s for {seconds:g} s (60 % what, 30 % where, 10 % teach)"
    figures.record(figure, before, requests=sent, rate=sent / seconds, errors=len(errors),
                   first_errors=errors[:3], rss_mb_served=sum(served_rss), rss_mb_at_10s=warm,
                   rss_mb_end=total[-1], rss_mb_max=max(total),
                   rss_growth_percent=100 * (total[-1] - warm) / warm,
                   rss_mb_server_start_10s_end=[served_rss[0], memory[min(10, len(memory) - 1)][0],
                                                memory[-1][0]],
                   rss_mb_writer_start_10s_end=[served_rss[1], memory[min(10, len(memory) - 1)][1],
                                                memory[-1][1]],
                   teachings=client.health()["teachings"],
                   **{f"{kind}_{k}": v for kind, lat in by_kind.items() for k, v in percentiles(lat).items()})


def _observation_cost(figures: _Figures, served: Served, client: Any, regions: dict[str, Any],
                      jpeg: bytes) -> None:
    """The memory and file bytes of 200 new observations (the home grows by design)."""
    before = load()
    rss0, size0 = sum(served.rss_mb()), served.file.stat().st_size
    samples0 = client.health()["samples"]
    for p in poses(regions, 200, 5):
        client.teach(x=p[0], y=p[1], theta=p[2], image=jpeg, sentence="this is the study")
    time.sleep(4)  # compacted when idle
    rss1, size1 = sum(served.rss_mb()), served.file.stat().st_size
    added = client.health()["samples"] - samples0
    figures.record("cost of a new observation (640x480 JPEG view)", before, observations=added,
                   rss_kb_per_observation=1024 * (rss1 - rss0) / added,
                   file_bytes_per_observation=(size1 - size0) / added, rss_mb=rss1, file_mb=size1 / 1e6)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--dir", type=Path, default=Path("/tmp/spco-serve-bench"))
    parser.add_argument("--sigverse", type=Path, default=DATA / "sigverse")
    parser.add_argument("--images", type=Path, default=DATA / "sigverse_images")
    parser.add_argument("--n", type=int, default=2000, help="requests per single-client figure")
    parser.add_argument("--clients", type=int, default=8)
    parser.add_argument("--seconds", type=float, default=10.0, help="length of the 8-client run")
    parser.add_argument("--soak", type=float, default=60.0, help="length of the soak, seconds")
    parser.add_argument("--rate", type=float, default=200.0, help="requests per second in the soak")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--only", default=None, help="comma-separated figures to run (default: all)")
    args = parser.parse_args()
    from spco.service.client import Client

    home = build(args.dir, args.sigverse.resolve(), args.images.resolve())
    import cv2

    view = cv2.resize(cv2.imread(str(args.images / "3LDK_9" / "0.jpg")), (640, 480))
    jpeg = cv2.imencode(".jpg", view, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()
    figures = _Figures(args.only)
    served = Served(home, args.dir)
    client = Client(served.url)
    regions = client.regions()
    try:
        _one_client(figures, client, served, regions, args.n, jpeg)
        if figures.wanted("clients"):
            _many_clients(figures, served, regions, args.clients, args.seconds)
    finally:
        served.stop()
    if figures.wanted("burst"):
        _burst(figures, home, args.dir, regions)
    if figures.wanted("soak"):
        served = Served(home, args.dir)
        client = Client(served.url)
        _soak(figures, served, client, regions, args.rate, args.soak)
        _observation_cost(figures, served, client, regions, jpeg)
        served.stop()
    figures.print_table()
    if args.json is not None:
        args.json.write_text(json.dumps(figures.rows, indent=1))


if __name__ == "__main__":
    main()
