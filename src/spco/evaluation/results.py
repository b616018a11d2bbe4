"""An experiment's output folder: its identity and fingerprint, the runs file (``runs.jsonl``), and
the results, tables and figures assembled from the runs."""

from __future__ import annotations

import hashlib
import json
import os
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from spco.errors import ConfigurationError, DataFormatError
from spco.evaluation import report
from spco.evaluation.config import (
    CONFIG_FILE,
    FORMAT_VERSION,
    MAPS_DIR,
    RESULTS_FILE,
    RESULTS_FORMAT,
    RUNS_FILE,
    TABLES_FILE,
    ExperimentConfig,
)
from spco.evaluation.homes import ExperimentData
from spco.evaluation.models import MODELS
from spco.evaluation.runs import _slug


# ------------------------------------------------------------------------------------ output dir
def _identity(config: ExperimentConfig, data: ExperimentData) -> dict[str, Any]:
    hyper = {m: MODELS[m].hyperparameters(config.hyperparameters).to_dict() for m in config.models or ()}
    return {
        "experiment": config.experiment,
        "models": list(config.models or ()),
        "settings": list(config.settings or ()),
        "iterations": config.iterations,
        "seed": config.seed,
        "n_positions": config.n_positions,
        "data": data.description,
        "hyperparameters": json.loads(json.dumps(hyper)),
        # (absent at 0: earlier results resume)
        **({"views_missing": float(config.views_missing)} if config.views_missing else {}),
    }


def _fingerprint(identity: Mapping[str, Any]) -> str:
    text = json.dumps(identity, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _artefacts(out: Path) -> list[Path]:
    """The files an experiment writes in ``out`` (removed by ``force``)."""
    names = [out / n for n in (CONFIG_FILE, RUNS_FILE, RESULTS_FILE, TABLES_FILE)]
    names += sorted(out.glob("general_*.png")) + sorted(out.glob("specific_*.png"))
    if (out / MAPS_DIR).is_dir():
        names += sorted((out / MAPS_DIR).glob("*.png"))
    return [p for p in names if p.is_file()]


def _short(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _differences(old: Mapping[str, Any], new: Mapping[str, Any], prefix: str = "") -> list[str]:
    """Readable ``key: old -> new`` lines; hyperparameters are compared for shared models only."""
    diffs = []
    for key in sorted(set(old) | set(new), key=lambda k: (isinstance(old.get(k, new.get(k)), dict), k)):
        a, b = old.get(key), new.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            if prefix == "" and key == "hyperparameters":
                shared = set(a) & set(b)
                a, b = ({m: v for m, v in d.items() if m in shared} for d in (a, b))
            diffs += _differences(a, b, f"{prefix}{key}.")
        elif a != b:
            diffs.append(f"{prefix}{key}: {_short(a)} -> {_short(b)}")
    return diffs


def _prepare_out(out: Path, identity: Mapping[str, Any], fingerprint: str, resume: bool,
                 force: bool) -> None:
    if resume and force:
        raise ConfigurationError("choose one of --resume (continue) and --force (start over)")
    if out.exists() and not out.is_dir():
        raise ConfigurationError(f"{out}: exists and is not a folder (--out)")
    config_file = out / CONFIG_FILE
    non_empty = out.is_dir() and any(out.iterdir())
    if force:
        for path in _artefacts(out):
            path.unlink()
    elif resume and config_file.is_file():
        try:
            stored = json.loads(config_file.read_text(encoding="utf-8"))
            old_identity = stored["identity"]
            old_print = stored["fingerprint"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise DataFormatError(config_file, f"not a readable experiment configuration ({exc}); use "
                                  "--force to start over or another --out") from None
        if old_print != fingerprint:
            diffs = _differences(old_identity, dict(identity)) or ["(fingerprint differs)"]
            raise ConfigurationError(
                f"{out} holds an experiment with another configuration, refusing to mix results: "
                + "; ".join(diffs[:6]) + ("; …" if len(diffs) > 6 else "")
                + ". Use the same options to resume, --force to start over, or another --out")
    elif resume and non_empty:
        raise ConfigurationError(f"{out} is not empty but holds no experiment ({CONFIG_FILE} missing); "
                                 "use another --out, or --force to start over")
    elif non_empty:
        raise ConfigurationError(f"{out} is not empty; use --resume to continue the experiment there, "
                                 "--force to start over, or another --out")
    out.mkdir(parents=True, exist_ok=True)


def _write_json_atomic(path: Path, payload: Any) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(payload, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def _write_text_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def read_runs(out: Path, fingerprint: str | None = None) -> list[dict[str, Any]]:
    """The finished runs recorded in ``out/runs.jsonl``.

    A damaged line (an interrupted write) is dropped and the file rewritten without it, so appending
    can continue. With ``fingerprint``, a run of another configuration is an error.
    """
    path = out / RUNS_FILE
    if not path.is_file():
        return []
    text = path.read_text(encoding="utf-8", errors="replace")
    records, dropped = [], 0
    for line in text.splitlines():
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
            if not isinstance(rec, dict) or "model" not in rec:
                raise ValueError("not a run record")
        except ValueError:
            dropped += 1
            continue
        records.append(rec)
    if dropped or (text and not text.endswith("\n")):
        _write_text_atomic(path, "".join(json.dumps(r, allow_nan=False) + "\n" for r in records))
        if dropped:
            print(f"warning: {path}: dropped {dropped} damaged line(s) (an interrupted write); "
                  "those runs are done again", file=sys.stderr)
    if fingerprint is not None:
        foreign = [r for r in records if r.get("fingerprint") != fingerprint]
        if foreign:
            raise ConfigurationError(f"{path}: {len(foreign)} run(s) were made with another "
                                     "configuration; use --force to start over or another --out")
    return records


def _append_run(path: Path, record: Mapping[str, Any]) -> None:
    line = json.dumps(record, allow_nan=False) + "\n"
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(line)
        fh.flush()
        os.fsync(fh.fileno())


# ------------------------------------------------------------------------------------ results
@dataclass
class ExperimentResults:
    """What :func:`run_experiment` wrote: the content of ``results.json`` and the files."""

    out: Path
    results: dict[str, Any]
    tables: str
    figures: list[Path]

    @property
    def runs(self) -> list[dict[str, Any]]:
        """Per-run, per-place rows."""
        return self.results["runs"]

    @property
    def summary(self) -> list[dict[str, Any]]:
        """Summary rows over new homes and trials."""
        return self.results["summary"]


def _run_rows(record: Mapping[str, Any]) -> list[dict[str, Any]]:
    base = {k: record[k] for k in ("experiment", "model", "setting", "home", "trial")}
    tail = {k: record[k] for k in ("seed", "iterations", "wall_seconds")}
    tail["reused_from_setting"] = record.get("reused_from_setting")
    places = report.place_order([*record["name_accuracy"], *record["position_accuracy"]])
    mixture = record.get("position_accuracy_mixture") or {}  # (runs recorded before it existed: None)
    rows = [{**base, "place": p, "name_accuracy": record["name_accuracy"].get(p),
             "position_accuracy": record["position_accuracy"].get(p),
             "position_accuracy_mixture": mixture.get(p), **tail} for p in places]
    rows.append({**base, "place": report.MEAN, "name_accuracy": record["mean_name_accuracy"],
                 "position_accuracy": record["mean_position_accuracy"],
                 "position_accuracy_mixture": record.get("mean_position_accuracy_mixture"), **tail})
    return rows


def _mean_of(values: Sequence[float | None]) -> float | None:
    clean = [v for v in values if v is not None]
    return float(np.mean(clean)) if clean else None


def _assemble(config: ExperimentConfig, identity: Mapping[str, Any], fingerprint: str,
              records: Sequence[Mapping[str, Any]], session_seconds: float,
              session_runs: int, maps: str | None) -> dict[str, Any]:
    from spco import __version__

    rows = [row for rec in records for row in _run_rows(rec)]
    by = ("experiment", "model", "setting", "place")
    summary = report.summarize(rows, by)
    order = {p: i for i, p in enumerate([*report.place_order(r["place"] for r in rows), report.MEAN])}
    models = {m: i for i, m in enumerate(config.models or ())}
    summary.sort(key=lambda r: (models[r["model"]], r["setting"], order[r["place"]]))
    by_home = report.summarize(rows, ("experiment", "model", "setting", "home", "place"))
    by_home.sort(key=lambda r: (models[r["model"]], r["setting"], r["home"], order[r["place"]]))
    chance_by_home: dict[str, dict[str, float | None]] = {}
    for rec in records:
        chance_by_home.setdefault(rec["home"], {"name_accuracy": rec["name_chance"],
                                                "position_accuracy": rec["position_chance"]})
    chance = {
        "name_accuracy": _mean_of([c["name_accuracy"] for c in chance_by_home.values()]),
        "position_accuracy": _mean_of([c["position_accuracy"] for c in chance_by_home.values()]),
        "position_accuracy_mixture": _mean_of([c["position_accuracy"] for c in chance_by_home.values()]),
        "by_home": chance_by_home,
    }
    return {
        "format": RESULTS_FORMAT,
        "version": FORMAT_VERSION,
        "config": {**identity, "trials": config.trials, "maps": maps, "fingerprint": fingerprint,
                   "spco_version": __version__},
        "runs": rows,
        "summary": summary,
        "summary_by_home": by_home,
        "chance": chance,
        "timing": {
            "runs": len(records),
            "runs_reused": sum(r.get("reused_from_setting") is not None for r in records),
            "runs_this_session": session_runs,
            "run_wall_seconds_total": round(sum(r["wall_seconds"] for r in records), 3),
            "session_wall_seconds": round(session_seconds, 3),
        },
    }


def _setting_label(experiment: str) -> str:
    return "experienced homes" if experiment == "general" else "teaching rate [%]"


def _figures(out: Path, config: ExperimentConfig, results: Mapping[str, Any],
             records: Sequence[Mapping[str, Any]]) -> list[Path]:
    from spco import plots

    experiment = config.experiment
    settings = list(config.settings or ())
    models = list(config.models or ())
    index = {(r["model"], r["setting"]): r for r in results["summary"] if r["place"] == report.MEAN}
    written = []
    xlabel = ("number of experienced homes" if experiment == "general"
              else "teaching rate of the home-specific rooms [%]")
    for measure, label in (("name_accuracy", "name accuracy A_n"),
                           ("position_accuracy", "position accuracy A_p")):
        means, stds = {}, {}
        for model in models:
            rows = [index.get((model, s)) for s in settings]
            means[model] = [np.nan if r is None or r[f"{measure}_mean"] is None else r[f"{measure}_mean"]
                            for r in rows]
            stds[model] = [0.0 if r is None or r[f"{measure}_std"] is None else r[f"{measure}_std"]
                           for r in rows]
        path = out / f"{experiment}_{measure}.png"
        plots.plot_accuracy_curve(settings, means, stds, results["chance"][measure], xlabel,
                                        f"{experiment} places: {label}", path=path)
        written.append(path)
    top = max(settings)
    for model in models:
        traces = {r["home"]: r["log_joint"] for r in records
                  if r["model"] == model and r["setting"] == top and r["trial"] == 0 and r.get("log_joint")}
        if traces:
            path = out / f"{experiment}_log_joint_{_slug(model)}.png"
            plots.plot_log_joint(dict(sorted(traces.items())), path=path,
                                 title=f"{model}: log joint, {top} {_setting_label(experiment)}, trial 0")
            written.append(path)
    written += sorted((out / MAPS_DIR).glob(f"{experiment}_*.png")) if (out / MAPS_DIR).is_dir() else []
    return written


def _tables(config: ExperimentConfig, results: Mapping[str, Any]) -> str:
    experiment = config.experiment
    data = results["config"]["data"]
    homes = ", ".join(data["new_homes"])
    if experiment == "general":
        title = "General places: accuracy in the new homes vs. number of experienced homes"
        scope = f"new homes {homes}, taught nothing"
    else:
        title = "Home-specific places: accuracy vs. teaching rate of the home-specific rooms"
        scope = f"new home {homes}, {len(data['experienced_homes'])} experienced homes"
    timing = results["timing"]
    note = (f"{scope}; {config.trials} trial(s) per setting and home, {config.iterations} Gibbs "
            f"iterations, seed {config.seed}, data: {data['source']}. Cells: mean (sample std) over "
            f"new homes × trials; `mean`: mean over places of each run, then over runs. Chance: "
            f"A_n 1/|V| (|V| = {len(data['vocabulary'])}), A_p 1/|places|. "
            f"{timing['runs']} runs, {timing['run_wall_seconds_total']:.0f} s of run time.")
    return report.markdown_tables(results["summary"], experiment=experiment, models=list(config.models or ()),
                                  settings=list(config.settings or ()),
                                  setting_label=_setting_label(experiment), chance=results["chance"],
                                  title=title, note=note)
