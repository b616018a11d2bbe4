"""Summaries and Markdown tables of experiment results (see :mod:`spco.evaluation.experiments`).

:func:`summarize` turns per-run rows into mean / sample-std rows; :func:`markdown_tables` lays the
summary out like the tables of Hagiwara et al. (2021): one table per model and measure, the settings
(number of experienced homes, or teaching rate) as rows, the places as columns, cells
``"mean (std)"``, a ``mean`` column (the mean over places of a run, averaged over runs) and a chance
row; an overview table compares the models on the mean over places.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from spco.data.language import normalize_name
from spco.data.synthetic import GENERAL_PLACES, SPECIFIC_ROOM_NAMES

__all__ = ["MEAN", "format_cell", "markdown_tables", "place_order", "summarize"]

#: The ``place`` of the rows holding a run's mean over places.
MEAN = "mean"

#: measure -> label. A_p two ways: positions from the most probable region (the authors' code) and
#: positions sampled from the whole mixture p(x | name) (the paper's text).
_MEASURES = (("name_accuracy", "name accuracy A_n"),
             ("position_accuracy", "position accuracy A_p (most probable region, as the authors' code)"),
             ("position_accuracy_mixture", "position accuracy A_p (sampled from p(x | name), as the "
                                           "paper's text)"))
_CANONICAL = [normalize_name(p) for p in (*GENERAL_PLACES, *SPECIFIC_ROOM_NAMES)]


def place_order(places: Iterable[str]) -> list[str]:
    """Places in the order of the paper's tables (the SIGVerse places first), others alphabetically;
    :data:`MEAN` is left out."""
    found = {p for p in places if p != MEAN}
    known = [p for p in _CANONICAL if p in found]
    return known + sorted(found - set(known))


def _stats(values: Sequence[float | None]) -> tuple[float | None, float | None]:
    """Mean and sample standard deviation (ddof=1) of the non-missing values; ``None`` when
    undefined (no value, or a single value for the std)."""
    arr = np.asarray([v for v in values if v is not None and not math.isnan(v)], dtype=np.float64)
    if arr.size == 0:
        return None, None
    mean = float(arr.mean())
    std = float(arr.std(ddof=1)) if arr.size >= 2 else None
    return mean, std


def summarize(rows: Iterable[Mapping[str, Any]], by: Sequence[str]) -> list[dict[str, Any]]:
    """Group ``rows`` by the keys ``by`` and average their accuracies.

    Each output row holds the ``by`` keys, ``name_accuracy_mean``, ``name_accuracy_std``,
    ``position_accuracy_mean``, ``position_accuracy_std``, ``position_accuracy_mixture_mean``,
    ``position_accuracy_mixture_std`` (sample std, ddof = 1; ``None`` when
    fewer than two values) and ``n``, the number of rows in the group. Missing accuracies (``None``
    or NaN: a place without test samples or ground-truth area) are left out of the mean and std.
    Groups keep the order of their first row.
    """
    groups: dict[tuple[Any, ...], list[Mapping[str, Any]]] = {}
    for row in rows:
        groups.setdefault(tuple(row[k] for k in by), []).append(row)
    out = []
    for key, members in groups.items():
        entry: dict[str, Any] = dict(zip(by, key, strict=True))
        for measure, _ in _MEASURES:
            mean, std = _stats([m.get(measure) for m in members])
            entry[f"{measure}_mean"] = mean
            entry[f"{measure}_std"] = std
        entry["n"] = len(members)
        out.append(entry)
    return out


def format_cell(mean: float | None, std: float | None, digits: int = 3) -> str:
    """``"0.812 (0.043)"``; ``"0.812"`` without a std; ``"-"`` without a mean."""
    if mean is None:
        return "-"
    if std is None:
        return f"{mean:.{digits}f}"
    return f"{mean:.{digits}f} ({std:.{digits}f})"


def _table(header: Sequence[str], body: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in body]
    return lines


def markdown_tables(
    summary: Sequence[Mapping[str, Any]],
    *,
    experiment: str,
    models: Sequence[str],
    settings: Sequence[int],
    setting_label: str,
    chance: Mapping[str, float | None],
    title: str | None = None,
    note: str | None = None,
) -> str:
    """The Markdown tables of one experiment.

    Parameters
    ----------
    summary: rows of :func:`summarize` grouped by ``experiment, model, setting, place``.
    experiment: which experiment's rows to show.
    models, settings: the row and table order.
    setting_label: the header of the settings column ("experienced homes", "teaching rate [%]").
    chance: ``{"name_accuracy": …, "position_accuracy": …}`` chance levels (``None``: unknown).
    title, note: a heading and a paragraph printed before the tables.
    """
    rows = [r for r in summary if r["experiment"] == experiment]
    index = {(r["model"], r["setting"], r["place"]): r for r in rows}
    places = place_order(r["place"] for r in rows)
    lines: list[str] = []
    if title:
        lines += [f"# {title}", ""]
    if note:
        lines += [note, ""]

    lines += ["## Overview: mean over places, mean (std) over runs", ""]
    for measure, label in _MEASURES:
        body = []
        for setting in settings:
            cells = [str(setting)]
            for model in models:
                r = index.get((model, setting, MEAN))
                cells.append(format_cell(r[f"{measure}_mean"], r[f"{measure}_std"]) if r else "-")
            body.append(cells)
        body.append(["chance", *(format_cell(chance.get(measure), None) for _ in models)])
        lines += [f"### {label}", ""]
        lines += _table([setting_label, *models], body)
        lines.append("")

    for model in models:
        for measure, label in _MEASURES:
            body = []
            counts = set()
            for setting in settings:
                cells = [str(setting)]
                for place in [*places, MEAN]:
                    r = index.get((model, setting, place))
                    cells.append(format_cell(r[f"{measure}_mean"], r[f"{measure}_std"]) if r else "-")
                    if r and place == MEAN:
                        counts.add(r["n"])
                body.append(cells)
            level = chance.get(measure)
            body.append(["chance", *(format_cell(level, None) for _ in [*places, MEAN])])
            runs = ", ".join(str(c) for c in sorted(counts)) or "0"
            lines += [f"## {model}: {label} (runs per setting: {runs})", ""]
            lines += _table([setting_label, *places, MEAN], body)
            lines.append("")
    return "\n".join(lines).rstrip() + "\n"
