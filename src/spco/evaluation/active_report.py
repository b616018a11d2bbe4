"""The summaries, tables and figures of ``spco experiment active`` (:mod:`spco.evaluation.active`):
learning curves with bootstrap intervals over trials, the first number of questions that reaches the
target, "ask only when unsure", ranking times and where the questions went."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["STOP_THRESHOLDS", "figures", "first_k", "ranking_time", "stop_rule_summary", "summarise",
           "tables"]

#: The confidence thresholds of "ask only when unsure" reported.
STOP_THRESHOLDS = (0.5, 0.6, 0.7, 0.8, 0.9)
_BOOTSTRAP = 2000
_TARGET = 0.9


# ------------------------------------------------------------------------------------ summaries
def _interval(values: Sequence[float], rng: np.random.Generator) -> tuple[float, float, float]:
    """Mean and 95 % percentile bootstrap interval of the mean."""
    x = np.asarray(values, dtype=np.float64)
    if x.size == 1:
        return float(x[0]), float(x[0]), float(x[0])
    means = x[rng.integers(0, x.size, size=(_BOOTSTRAP, x.size))].mean(axis=1)
    low, high = np.percentile(means, [2.5, 97.5])
    return float(x.mean()), float(low), float(high)


_MEASURES = ("specific_n", "specific_p", "general_n", "general_p", "all_n", "all_p")


def summarise(records: Sequence[Mapping[str, Any]], strategies: Sequence[str]) -> list[dict[str, Any]]:
    """Mean and 95 % interval over trials of every measure, per home, strategy and k."""
    rng = np.random.default_rng(0)
    rows = []
    homes = list(dict.fromkeys(r["home"] for r in records))
    for home in homes:
        runs = [r for r in records if r["home"] == home]
        for strategy in strategies:
            n_steps = min(len(r["curves"][strategy]) for r in runs)
            for k in range(n_steps):
                row: dict[str, Any] = {"home": home, "strategy": strategy, "k": k, "n": len(runs)}
                for m in _MEASURES:
                    values = [r["curves"][strategy][k][m] for r in runs
                              if r["curves"][strategy][k][m] is not None]
                    if values:
                        mean, low, high = _interval(values, rng)
                        row[m] = {"mean": round(mean, 4), "low": round(low, 4), "high": round(high, 4)}
                    else:
                        row[m] = None
                rows.append(row)
        for rate in sorted({ref["rate"] for r in runs for ref in r["references"]}):
            refs = [ref for r in runs for ref in r["references"] if ref["rate"] == rate]
            row = {"home": home, "strategy": f"paper rate {rate} %", "n": len(refs), "rate": rate,
                   "k": int(np.mean([f["k"] for f in refs]))}
            for m in _MEASURES:
                values = [f[m] for f in refs if f[m] is not None]
                row[m] = None
                if values:
                    mean, low, high = _interval(values, rng)
                    row[m] = {"mean": round(mean, 4), "low": round(low, 4), "high": round(high, 4)}
            rows.append(row)
    return rows


def first_k(summary: Sequence[Mapping[str, Any]], measure: str = "specific_n",
            target: float = _TARGET) -> dict[str, dict[str, int | None]]:
    """The first k at which each strategy's mean reaches ``target`` on ``measure``, per home
    (``None``: not within the questions asked)."""
    out: dict[str, dict[str, int | None]] = {}
    for row in summary:
        if row["strategy"].startswith("paper") or row.get(measure) is None:
            continue
        slot = out.setdefault(row["home"], {}).setdefault(row["strategy"], None)
        if slot is None and row[measure]["mean"] >= target - 1e-12:
            out[row["home"]][row["strategy"]] = int(row["k"])
    return out


def stop_rule_summary(records: Sequence[Mapping[str, Any]], strategy: str = "information",
                      thresholds: Sequence[float] = STOP_THRESHOLDS, measure: str = "all_n",
                      confidence: str = "confidence") -> list[dict[str, Any]]:
    """"Ask only when unsure": a robot asking in ``strategy``'s order stops at the first question
    whose place's ``confidence`` (``"confidence"``: the criterion's; ``"what_confidence"``) is at least
    τ. Per home and τ: the mean number of questions asked, the mean ``measure`` at the stop and that
    of the robot that asks them all (k = the last), and the questions saved."""
    out = []
    for home in dict.fromkeys(r["home"] for r in records):
        runs = [r["curves"][strategy] for r in records if r["home"] == home and strategy in r["curves"]]
        if not runs:
            continue
        last = len(runs[0]) - 1
        for tau in thresholds:
            asked, at_stop, specific_at_stop = [], [], []
            for steps in runs:
                k = next((s["k"] for s in steps[:-1]
                          if s[confidence] is not None and s[confidence] >= tau), last)
                asked.append(k)
                at_stop.append(steps[k][measure])
                specific_at_stop.append(steps[k]["specific_n"])
            full = [steps[last][measure] for steps in runs]

            def mean(values: list[Any]) -> float | None:
                clean = [v for v in values if v is not None]
                return round(float(np.mean(clean)), 4) if clean else None

            out.append({"home": home, "strategy": strategy, "confidence": confidence, "threshold": tau,
                        "questions": round(float(np.mean(asked)), 2),
                        "saved": round(last - float(np.mean(asked)), 2),
                        f"{measure}_at_stop": mean(at_stop), f"{measure}_all_questions": mean(full),
                        "specific_n_at_stop": mean(specific_at_stop),
                        "specific_n_all_questions": mean([steps[last]["specific_n"] for steps in runs])})
    return out


def ranking_time(records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Seconds to rank a home's samples by the criterion (every question of every run)."""
    times = [s["rank_seconds"] for r in records for name in ("information", "errors")
             for s in r["curves"].get(name, []) if "rank_seconds" in s]
    if not times:
        return {}
    return {"questions": len(times), "median": round(float(np.median(times)), 4),
            "p95": round(float(np.percentile(times, 95)), 4), "max": round(float(np.max(times)), 4)}


def _asked_places(records: Sequence[Mapping[str, Any]], strategies: Sequence[str], first: int = 6
                  ) -> dict[str, dict[str, dict[str, float]]]:
    """Per home and strategy: the share of the first ``first`` questions asked at each place."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for home in dict.fromkeys(r["home"] for r in records):
        for strategy in strategies:
            counts: dict[str, int] = {}
            total = 0
            for r in records:
                if r["home"] != home:
                    continue
                for s in r["curves"][strategy][:first]:
                    if "next_place" in s:
                        counts[str(s["next_place"])] = counts.get(str(s["next_place"]), 0) + 1
                        total += 1
            out.setdefault(home, {})[strategy] = {p: round(c / max(total, 1), 3) for p, c in
                                                  sorted(counts.items(), key=lambda kv: -kv[1])}
    return out


# ------------------------------------------------------------------------------------ report
def _cell(value: Mapping[str, float] | None) -> str:
    if value is None:
        return "–"
    return f"{value['mean']:.3f} [{value['low']:.2f}, {value['high']:.2f}]"


def tables(results: Mapping[str, Any]) -> str:
    """The experiment's results as Markdown."""
    config = results["config"]
    strategies = config["strategies"]
    known = (f"Knowledge: {len(config['experienced_homes'])} experienced homes, {config['fit_iterations']} "
             f"sweeps, seed {config['seed']}" if config.get("experienced_homes")
             else f"Knowledge: the file given (checksum {str(config.get('knowledge_checksum'))[:12]})")
    lines = ["# A robot that asks: accuracy of new homes vs. questions answered", "",
             f"{known}; seed {config['seed']}; adapt {config['adapt_iterations']} sweeps, teach "
             f"{config['teach_sweeps']} sweeps per answer; {config['trials']} trials per home. Cells: mean "
             "[95 % bootstrap interval] over trials. `specific`: the home-specific rooms (their own "
             "names); `general`: the other places; `all`: every place.", ""]
    summary = results["summary"]
    for home in dict.fromkeys(r["home"] for r in summary):
        rows = [r for r in summary if r["home"] == home]
        measures = [m for m in _MEASURES if any(r.get(m) is not None for r in rows)]
        for measure in measures:
            lines += [f"## {home}: {measure.replace('_n', ' A_n').replace('_p', ' A_p')}", "",
                      "| k | " + " | ".join(strategies) + " |", "|---|" + "---|" * len(strategies)]
            ks = sorted({r["k"] for r in rows if not r["strategy"].startswith("paper")})
            for k in ks:
                cells = []
                for s in strategies:
                    row = next((r for r in rows if r["strategy"] == s and r["k"] == k), None)
                    cells.append(_cell(None if row is None else row.get(measure)))
                lines.append(f"| {k} | " + " | ".join(cells) + " |")
            for r in rows:
                if r["strategy"].startswith("paper") and r.get(measure) is not None:
                    lines.append(f"| {r['k']} ({r['strategy']}) | " + _cell(r[measure]) + " |"
                                 + " |" * (len(strategies) - 1))
            lines.append("")
    lines += ["## First k with mean home-specific A_n >= 0.9", "",
              "| home | " + " | ".join(strategies) + " |", "|---|" + "---|" * len(strategies)]
    for home, by in results["first_k_specific"].items():
        lines.append(f"| {home} | " + " | ".join("not reached" if by.get(s) is None else str(by[s])
                                                  for s in strategies) + " |")
    lines += ["", "## Ask only when unsure (stop when the best question's confidence >= τ)", "",
              "| home | confidence | τ | questions | saved | all A_n at stop | all A_n, all questions | "
              "specific A_n at stop | specific A_n, all questions |", "|---|---|---|---|---|---|---|---|---|"]
    for r in results["stop_rule"]:
        lines.append(f"| {r['home']} | {r['confidence']} | {r['threshold']} | {r['questions']} | "
                     f"{r['saved']} | {r['all_n_at_stop']} | {r['all_n_all_questions']} | "
                     f"{r['specific_n_at_stop']} | {r['specific_n_all_questions']} |")
    timing = results["ranking_seconds"]
    if timing:
        lines += ["", f"Ranking a home's samples by the criterion: median {timing['median'] * 1000:.1f} ms, "
                  f"95th percentile {timing['p95'] * 1000:.1f} ms, max {timing['max'] * 1000:.1f} ms over "
                  f"{timing['questions']} questions."]
    lines += ["", "## Where the first 6 questions went (share of questions per place)", ""]
    for home, by in results["asked_places"].items():
        for s, shares in by.items():
            lines.append(f"- {home}, {s}: " + ", ".join(f"{p} {v:.2f}" for p, v in list(shares.items())[:8]))
    return "\n".join(lines) + "\n"


def figures(out: Path, results: Mapping[str, Any]) -> list[Path]:
    """One figure per home: A_n and A_p per k and strategy (95 % intervals), reference rates as points."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    summary = results["summary"]
    colours = {"information": "tab:blue", "errors": "tab:green", "uncertainty": "tab:orange",
               "random": "tab:grey"}
    for home in dict.fromkeys(r["home"] for r in summary):
        rows = [r for r in summary if r["home"] == home]
        has_specific = any(r.get("specific_n") is not None for r in rows)
        panels = ([("specific_n", "home-specific rooms: A_n"), ("specific_p", "home-specific rooms: A_p")]
                  if has_specific else [])
        panels += [("general_n", "general places: A_n"), ("all_p", "all places: A_p")]
        columns = 2
        rows_of_panels = math.ceil(len(panels) / columns)
        fig, axes = plt.subplots(rows_of_panels, columns, figsize=(10, 3.8 * rows_of_panels), squeeze=False)
        for ax in axes.ravel()[len(panels):]:
            ax.set_visible(False)
        for ax, (measure, title) in zip(axes.ravel(), panels, strict=False):
            for strategy in results["config"]["strategies"]:
                pts = [(r["k"], r[measure]) for r in rows if r["strategy"] == strategy and r.get(measure)]
                if not pts:
                    continue
                k = [p[0] for p in pts]
                ax.plot(k, [p[1]["mean"] for p in pts], marker="o", ms=3, label=strategy,
                        color=colours.get(strategy))
                ax.fill_between(k, [p[1]["low"] for p in pts], [p[1]["high"] for p in pts], alpha=0.2,
                                color=colours.get(strategy))
            refs = [r for r in rows if r["strategy"].startswith("paper") and r.get(measure)]
            for r in refs:
                value = r[measure]
                ax.errorbar([r["k"]], [value["mean"]],
                            yerr=[[value["mean"] - value["low"]], [value["high"] - value["mean"]]],
                            fmt="s", color="black", ms=4, capsize=3)
                ax.annotate(f"{r['rate']} %", (r["k"], r[measure]["mean"]), textcoords="offset points",
                            xytext=(4, -10), fontsize=7)
            if measure.endswith("_n") and measure.startswith("specific"):
                ax.axhline(_TARGET, color="tab:red", lw=0.8, ls="--")
            ax.set_title(title, fontsize=10)
            ax.set_xlabel("questions answered k (squares: the paper's random teaching, k = samples taught)",
                          fontsize=8)
            ax.set_ylim(-0.02, 1.02)
            ax.grid(alpha=0.3)
        axes[0][0].legend(fontsize=8, loc="lower right")
        fig.suptitle(f"{home}: asking one question at a time", fontsize=10)
        fig.tight_layout()
        path = out / f"active_{home.replace('/', '_')}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written
