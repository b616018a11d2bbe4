"""The JSON answers of ``where`` and ``what``, the same for ``spco where|what --json``, the library's
:class:`~spco.service.LiveHome` and ``spco serve``; and the home's learnt regions for drawing.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from spco import knowledge as kn
from spco.knowledge.requests import What
from spco.model.confidence import UNSURE_BELOW

__all__ = ["GAIN_MEANS", "RANKED_BY", "ask_answer", "regions_answer", "what_answer", "where_answer"]

#: What ``what``'s score is, per weighting of the home's model.
RANKED_BY = {"mi": "p(name | pose, view) × I(name), I = the name's mutual information with the concepts",
             "none": "p(name | pose, view)",
             "listener": "Σ_l p(l | pose, view) θ^w_l(name) L(l | name), L(l | name) ∝ G_0,l θ^w_l(name): "
                         "the name a listener takes to mean the place's concept",
             "looks": "Σ_l p(l | pose, view) θ^w_l(name) Σ_l' s(l, l') L(l' | name), s(l, l') how alike "
                      "the concepts look (the Bhattacharyya coefficient of their views to the view "
                      "weight's power)",
             "reference": "the authors' score Σ_l p(l | pose, view) θ^w_l(name) KL_l(name)"}

#: χ² quantile of 95 % in two dimensions: the regions' ellipses hold 95 % of their Gaussian.
_CHI2_95_2D = 5.991464547107979


def where_answer(home: kn.HomeModel, name: str, n: int = 10, seed: int = 0) -> dict[str, Any]:
    """Poses for the place ``name`` (:func:`spco.knowledge.where` with ``random_state=seed``), as JSON.

    Returns ``{"home", "name", "asked", "via", "region", "region_probability", "learnt", "support",
    "called", "positions"}`` (``called``: for a name not learnt, what ``what`` answers at the centre
    of ``region``, or ``None``); ``asked`` is the name as asked; for a name never said in the home
    that WordNet resolved to a known one (:mod:`spco.model.unheard`), ``name`` is the known name and
    ``via`` how it was found ("synonym", "gloss", ...), else ``via`` is ``None``. ``positions`` lists
    ``{"x", "y", "theta", "probability"}`` (metres, radians), most probable first. Raises
    :class:`~spco.model.prediction.UnknownNameError` for a name the home cannot use.
    """
    pred = kn.where(home, name, n=n, random_state=seed)
    order = sorted(range(pred.samples.shape[0]), key=lambda i: -float(pred.weights[i]))
    positions = [{"x": float(pred.samples[i, 0]), "y": float(pred.samples[i, 1]),
                  "theta": float(pred.samples[i, 2]), "probability": float(pred.weights[i])} for i in order]
    return {"home": home.name, "name": pred.name, "asked": pred.asked or pred.name, "via": pred.via,
            "region": int(pred.region),
            "region_probability": float(pred.region_probabilities[pred.region]),
            "learnt": bool(pred.learnt), "support": float(pred.support), "called": pred.called,
            "positions": positions}


def what_answer(home: kn.HomeModel, request: What, *, extractor: Callable[[], Any] | None = None,
                unsure_below: float = UNSURE_BELOW) -> dict[str, Any]:
    """The ``request.top`` place names at a pose (the home's one answer,
    :func:`spco.knowledge.what_request`, ranked as :func:`spco.knowledge.what` ranks them), as JSON.

    ``request``: a checked :class:`~spco.knowledge.requests.What` (its view: counts, or an image
    that ``extractor`` turns into counts). Returns ``{"home", "pose": {"x", "y", "theta"},
    "vision", "ranked_by", "answer", "confidence", "unsure", "unsure_below", "names"}``; ``names``
    lists ``{"name", "probability", "score", "score_share"}`` best first (``probability`` =
    p(name | pose, view) over all words, honest as :mod:`spco.model.confidence` makes it;
    ``score_share`` = the score over its sum across the usable names); ``answer`` is the best name
    (``None`` if none is known), ``confidence`` its probability, ``unsure`` whether that is below
    ``unsure_below``. A pose off the map adds ``"warning"`` (instead of a Python warning: a server
    answers many such poses); one far off it, or a view that does not fit the home, raises
    :class:`~spco.errors.ConfigurationError`.
    """
    pred, outside = kn.what_request(home, request, extractor=extractor, unsure_below=unsure_below)
    pose = request.pose
    total = float(pred.scores[0].sum())
    ranked = zip(pred.words[0], pred.probabilities[0], pred.scores[0], strict=True)
    names = [{"name": str(w), "probability": float(p), "score": float(s),
              "score_share": float(s) / total if total > 0 else 0.0} for w, p, s in ranked][:request.top]
    answer = {"home": home.name, "pose": {"x": pose.x, "y": pose.y, "theta": pose.theta},
              "vision": request.view is not None, "ranked_by": RANKED_BY[pred.weighting],
              "answer": names[0]["name"] if names else None, "confidence": float(pred.confidence[0]),
              "unsure": bool(pred.unsure[0]), "unsure_below": float(unsure_below), "names": names}
    if outside is not None:
        answer["warning"] = f"{outside}; the names are extrapolated from the nearest regions"
    return answer


#: What a question's ``gain`` is, per criterion of :func:`spco.knowledge.ask`.
GAIN_MEANS = {"errors": "expected number of the room's recorded samples whose answer the question corrects",
              "information": "expected information of the answer about the names of the home's places, nats"}


def ask_answer(home: kn.HomeModel, n: int = 5, criterion: str | None = None,
               unsure_only: bool = False) -> dict[str, Any]:
    """Where to ask "what is this place?" (:func:`spco.knowledge.ask`), as JSON.

    Returns ``{"home", "gain", "questions"}``: ``gain`` says what the gains are (:data:`GAIN_MEANS`);
    ``criterion``: that of :func:`spco.knowledge.ask` (``None``: its default); ``unsure_only``: only
    the questions worth asking. ``questions`` lists ``n`` (fewer if fewer samples are untaught, or
    worth asking) :meth:`spco.knowledge.Question.to_dict` dicts ``{"id", "x", "y", "theta", "gain",
    "reason", "names", "unknown", "confidence", "worth_asking"}``, best first. Raises
    :class:`~spco.errors.ConfigurationError` for a bad ``n``.
    """
    from spco.knowledge.asking import DEFAULT_CRITERION

    criterion = criterion or DEFAULT_CRITERION
    questions = kn.ask(home, n=n, criterion=criterion, unsure_only=unsure_only)
    return {"home": home.name, "gain": GAIN_MEANS[criterion], "questions": [q.to_dict() for q in questions]}


def _ellipse(cov: np.ndarray) -> dict[str, float]:
    """The 95 % ellipse of a 2×2 covariance: radii ``rx`` (major) and ``ry`` and the major axis's angle
    in degrees, counter-clockwise from +x."""
    cov = 0.5 * (cov + cov.T)
    values, vectors = np.linalg.eigh(cov)
    values = np.maximum(values, 0.0)
    angle = math.degrees(math.atan2(float(vectors[1, 1]), float(vectors[0, 1])))
    return {"rx": math.sqrt(_CHI2_95_2D * float(values[1])), "ry": math.sqrt(_CHI2_95_2D * float(values[0])),
            "angle": angle}


def regions_answer(home: kn.HomeModel, names_per_region: int = 3) -> dict[str, Any]:
    """The home's learnt regions for a map: what the page at ``/`` and the ROS markers draw.

    Returns ``{"home", "extent": [x_min, x_max, y_min, y_max], "names": [usable names],
    "places": [...], "concepts": [{"concept", "names": [{"name", "p"}]}], "regions": [...],
    "samples": [...]}``.

    ``places``: where each usable name is, as ``where`` answers it (:func:`spco.knowledge.places`):
    ``{"name", "region", "p", "learnt"}``, ``region`` the most probable region given the name and ``p``
    = p(region | name). A map labels a place there — the label is ``where``'s answer, not a second
    predictor's (the page, the ROS markers and Foxglove label each region with its ``places``).

    Each region in use: ``region``, ``concept`` (the concept it belongs to most, which colours it),
    ``samples`` (its samples), ``weight`` (its share of the home's samples), ``mean`` ``[x, y]``,
    ``covariance`` (2×2, m²), ``ellipse`` (95 %: ``rx``, ``ry`` in metres, ``angle`` in degrees),
    ``places``: the learnt places ``where`` goes to this region for, ``[{"name", "p"}]`` (p = p(region |
    name), most probable first; a name not learnt in this home is never a label), ``names``: the
    ``names_per_region`` names ``what`` answers at the region's centre (the pose alone; ``p`` =
    p(name | pose), :func:`spco.knowledge.names_at_regions`), and ``taught``: its samples with a
    sentence. ``concepts`` lists each drawn concept's most probable usable names (θ^w, the legend).
    ``samples`` lists ``{"id", "x", "y", "theta", "sentence", "region"}``.
    """
    params = home.parameters
    counts = np.asarray(params.region_counts[0], dtype=np.int64)
    means = np.asarray(params.region_means[0], dtype=np.float64)
    covs = np.asarray(params.region_covariances[0], dtype=np.float64)[:, :2, :2]
    joint = np.asarray(params.region_weights[0], dtype=np.float64) * np.clip(
        np.asarray(params.concept_weights[0], dtype=np.float64), 0.0, None)[:, None]  # (L, K)
    usable = np.asarray(home.name_mask, dtype=bool)  # the home's names (what `what` answers)
    theta_w = np.asarray(params.word_probabilities[0], dtype=np.float64) * usable[None, :]  # (L, V)
    words = home.vocabulary.words

    def top_names(weights: np.ndarray) -> list[dict[str, Any]]:
        p = weights @ theta_w
        if p.sum() <= 0:
            return []
        p = p / p.sum()
        order = np.argsort(-p, kind="stable")[:names_per_region]
        return [{"name": words[k], "p": float(p[k])} for k in order if p[k] > 0]

    regions = []
    total = max(int(counts.sum()), 1)
    assigned = np.asarray(home.state.regions, dtype=np.int64)
    taught = np.bincount(assigned[np.array([s is not None for s in home.sentences], dtype=bool)],
                         minlength=counts.size)
    in_use = np.flatnonzero(counts > 0)
    # the names `what` answers at each region's centre, and the places `where` finds in each region
    said = kn.names_at_regions(home, in_use, top_k=names_per_region)
    found = [{"name": name, "region": int(pred.region), "p": float(pred.region_probabilities[pred.region]),
              "learnt": bool(pred.learnt)} for name, pred in kn.places(home).items()]
    for row, m in enumerate(in_use):
        column = joint[:, m]
        here = sorted((p for p in found if p["region"] == m and p["learnt"]), key=lambda p: -p["p"])
        names = [{"name": str(w), "p": float(q)} for w, q in zip(said.words[row], said.probabilities[row],
                                                               strict=True) if q > 0]
        regions.append({"region": int(m), "concept": int(np.argmax(column)), "samples": int(counts[m]),
                        "weight": float(counts[m]) / total,
                        "mean": [float(means[m, 0]), float(means[m, 1])],
                        "covariance": covs[m].tolist(), "ellipse": _ellipse(covs[m]),
                        "places": [{"name": p["name"], "p": p["p"]} for p in here],
                        "names": names, "taught": int(taught[m])})
    concepts = sorted({r["concept"] for r in regions})
    samples = [{"id": int(i), "x": float(p[0]), "y": float(p[1]),
                "theta": math.atan2(float(p[2]), float(p[3])), "sentence": s, "region": int(r)}
               for i, p, s, r in zip(home.ids, home.positions, home.sentences, assigned, strict=True)]
    return {"home": home.name, "extent": list(kn.map_bounds(home)), "names": list(home.known_names),
            "places": found,
            "concepts": [{"concept": c, "names": top_names(np.eye(joint.shape[0])[c])} for c in concepts],
            "regions": regions, "samples": samples}
