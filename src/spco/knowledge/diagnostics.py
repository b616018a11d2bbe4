"""How well a knowledge fits a home's views: the experienced homes' view fits recorded at fit
time, and the warning for a new home whose views the knowledge explains much worse
(:func:`check_view_fit`). The numbers come from :mod:`spco.model.view_fit`."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from spco.model.view_fit import view_fit

if TYPE_CHECKING:
    from spco.knowledge.knowledge import Knowledge

#: What :func:`view_fit` measures (stored with the figures in knowledge and home files).
VIEW_FIT_MEASURE = ("median over a home's views v of log(Σ_l G_0,l Π_d φ^v_l,d ^ v_d) / Σ_d v_d + log D: "
                    "nats per count by which the knowledge's visual mixture explains the views better "
                    "than a uniform guess")

#: A home whose :func:`view_fit` is below this fraction of the lowest of the experienced homes' is
#: warned about: the knowledge has lost more than half its advantage over a uniform guess there.
VIEW_FIT_WARN_FRACTION = 0.5


class ExperiencedHomeWarning(UserWarning):
    """A home given to :func:`adapt` has the name of one of the knowledge's experienced homes."""


class KnowledgeMismatchWarning(UserWarning):
    """The knowledge explains a home's views much worse than its experienced homes' (:func:`view_fit`)."""



def _view_fit_record(homes: dict[str, float | None]) -> dict[str, Any]:
    """The provenance record of the experienced homes' view fits (home name -> fit)."""
    values = [v for v in homes.values() if v is not None]
    return {"measure": VIEW_FIT_MEASURE,
            "homes": {name: None if v is None else round(v, 4) for name, v in homes.items()},
            "warn_below": round(VIEW_FIT_WARN_FRACTION * min(values), 4) if values else None}


def check_view_fit(knowledge: Knowledge, visual: Any, home_name: str) -> dict[str, Any] | None:
    """The home's :func:`view_fit` against the experienced homes' (``None`` if the knowledge file
    predates the measure or the home has no view with a count); warns with
    :class:`KnowledgeMismatchWarning` when it is below the level recorded at fit time."""
    recorded = knowledge.provenance.get("view_fit")
    if not isinstance(recorded, Mapping) or recorded.get("warn_below") is None:
        return None
    value = view_fit(knowledge.log_phi_visual, knowledge.log_g0, visual)
    if value is None:  # no view (a home without a camera, or knowledge learnt without views)
        return None
    experienced = [float(v) for v in (recorded.get("homes") or {}).values() if v is not None]
    warn_below = float(recorded["warn_below"])
    fits = value is not None and value >= warn_below
    result = {"value": None if value is None else round(value, 4), "warn_below": warn_below,
              "experienced_range": [min(experienced), max(experienced)] if experienced else None,
              "fits": bool(fits)}
    if not fits:
        warnings.warn(view_fit_warning(home_name, result), KnowledgeMismatchWarning, stacklevel=3)
    return result


def fit_range_text(values: Any) -> str:
    """The experienced homes' view fits as the messages print them: ``"0.42…0.65"``, or one number
    when they all print the same (one experienced home, or homes that fit alike): never
    ``"2.55…2.55"``."""
    finite = [float(v) for v in (values or []) if v is not None and np.isfinite(float(v))]
    if not finite:
        return "unknown"
    low, high = f"{min(finite):.2f}", f"{max(finite):.2f}"
    return low if low == high else f"{low}…{high}"


def view_fit_warning(home_name: str, result: Mapping[str, Any]) -> str:
    """The sentence that says a knowledge does not fit a home (``result``: :func:`check_view_fit`)."""
    value = "no view has a count" if result.get("value") is None else f"{result['value']:.2f}"
    span = fit_range_text(result.get("experienced_range"))
    return (f"the knowledge does not fit home {home_name!r}: it explains its views by {value} nats per "
            f"count better than a uniform guess, against {span} in its experienced homes (warned below "
            f"{result['warn_below']:.2f}); the views probably come from another feature extractor or "
            f"another kind of place, and answers here may be confidently wrong")
