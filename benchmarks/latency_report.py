"""The percentiles and the printed table of the ROS nodes' latency benchmarks (``ros_latency.py``,
``ros2_latency.py``): one way to summarise a list of latencies and to print query → answer and
utterance → markers, so that the ROS 1 and ROS 2 tables read the same."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


def percentiles(seconds: Sequence[float]) -> dict[str, float]:
    """``n``, ``p50``, ``p95``, ``p99``, ``max`` and ``mean`` of latencies given in seconds, in ms."""
    ms = np.asarray(seconds, dtype=float) * 1e3
    if ms.size == 0:
        raise ValueError("no latencies to summarise")
    return {"n": int(ms.size), "p50": float(np.percentile(ms, 50)), "p95": float(np.percentile(ms, 95)),
            "p99": float(np.percentile(ms, 99)), "max": float(ms.max()), "mean": float(ms.mean())}


def query_rows(latencies: Mapping[str, Sequence[float]]) -> dict[str, Any]:
    """Percentiles per op and over all of them: ``{"queries": {op: row}, "all_queries": row}``."""
    rows = {op: percentiles(v) for op, v in latencies.items() if len(v)}
    every = [s for v in latencies.values() for s in v]
    return {"queries": rows, "all_queries": percentiles(every) if every else None}


def print_report(result: Mapping[str, Any], title: str, teach_extra: str = "",
                 breakdown: Mapping[str, Mapping[str, float]] | None = None) -> None:
    """Print the table of a latency run and its JSON line.

    ``result``: :func:`query_rows`'s keys, ``utterance_to_markers`` and ``utterance_to_teach_answer``
    (rows or ``None``), ``node_seconds_per_teaching`` (part → row, seconds), ``first_teaching``
    (``markers_ms``, ``answer_ms``), ``errors`` and ``loadavg_start`` (``os.getloadavg()`` as the
    measurements began); the load average at the end is added here (``loadavg``).
    ``title``: the query table's heading; ``teach_extra``: appended to the utterance line;
    ``breakdown``: rows (ms) of where a query's time went (printed under the query table).
    """
    load = os.getloadavg()
    result = {**result, "loadavg": load}
    print(title)
    rows = [*result["queries"].items()]
    if result.get("all_queries"):
        rows.append(("all", result["all_queries"]))
    for op, row in rows:
        print(f"  {op:<6} p50 {row['p50']:6.2f}  p95 {row['p95']:6.2f}  p99 {row['p99']:6.2f}  "
              f"max {row['max']:7.2f}  (n={row['n']})")
    for part, row in (breakdown or {}).items():
        print(f"    {part}: p50 {row['p50']:.2f}  p95 {row['p95']:.2f}  p99 {row['p99']:.2f}  "
              f"max {row['max']:.2f}")
    markers, teach = result.get("utterance_to_markers"), result.get("utterance_to_teach_answer")
    if markers and teach:
        print(f"utterance -> updated markers (ms), {markers['n']} teachings after the first: "
              f"p50 {markers['p50']:.1f}  p95 {markers['p95']:.1f}  p99 {markers['p99']:.1f}  "
              f"max {markers['max']:.1f}; -> teach answer p50 {teach['p50']:.1f} max {teach['max']:.1f}"
              f"{teach_extra}")
        parts = result.get("node_seconds_per_teaching") or {}
        if parts:
            print("  in the node (ms, p50 / max): " + ", ".join(
                f"{part} {row['p50']:.1f} / {row['max']:.1f}" for part, row in parts.items()))
    first = result.get("first_teaching")
    if first:
        print(f"first teaching of the node: markers {first['markers_ms']:.0f} ms, answer "
              f"{first['answer_ms']:.0f} ms")
    start = result.get("loadavg_start")
    before = f" (at the start {start[0]:.2f} {start[1]:.2f} {start[2]:.2f})" if start else ""
    print(f"errors: {result.get('errors', 0)}; load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}"
          f"{before}")
    print(json.dumps({**result, "breakdown": dict(breakdown or {})}))
