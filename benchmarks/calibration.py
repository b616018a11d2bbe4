"""Is `what` as sure as it is right? Calibration on development and held-out SIGVerse test views.

The configurations are fixed in ``benchmarks/calibration/SPLIT.md`` (decided before the fix):
development = the test views of 1DK_8 and 3LDK_9 with 4 and 8 experienced homes, seeds 0–4;
held-out = the test views of 1LDK_9 and 2LDK_9 with 4, 8 and 16 experienced homes, seeds
100–109. For each view kind (``colour-hog`` from the camera images, the authors' ``fc7``) and
each experienced-home set and seed: ``fit_knowledge`` on the experienced homes (every sample
taught), ``adapt`` each new home (nothing taught; same seed), then the names at every test view
(position, heading and view) two ways:

- ``before``: the model's p(w | x, v) as `what` gave it before the fix (every visual count a draw,
  free concepts' word distributions as averaged);
- ``after``: ``spco.knowledge.what`` as it is (``spco.model.confidence.answer_names``, the room
  account ``spco.model.rooms``: the pose's room, its training views pooled, and the view, each counted
  as the model's view weight w), where a ``development-new`` view — a training sample of its home —
  is answered with itself left out of its room's views (:func:`_answer_left_out`), as a new view
  would be; with ``--view-by-view`` the view and the pose against the home's π and θ^v instead
  (``spco.knowledge.name_prediction(by_room=False)``: what ``what`` answered before the room account
  was the default), for a comparison on the same models.

Printed per set and configuration, pooled over new homes and seeds: ECE (10 equal-width bins of
the answer's probability), accuracy of the answer, mean confidence, the share of wrong answers given
at p ≥ 0.99, the share flagged unsure, the log loss of the right name; 95 % intervals from a
bootstrap over test views (a view is resampled with all its seeds; 1,000 resamples). Writes
``predictions.jsonl`` (one row per view and seed), ``summary.json``, ``tables.md`` and one
reliability diagram per configuration, ``reliability_<features>_<n>.png``, to ``--out``.

    python benchmarks/calibration.py --data ../shared/datasets/sigverse \\
        --images ../shared/datasets/sigverse_images --out results/calibration
    python benchmarks/calibration.py … --sets development        # only what may be looked at

Knowledge and home files are kept in ``--out``/models and reused by a re-run (``--force`` refits).

``--fit-view-counts`` prints instead a diagnostic (how the former ``what``-only constant n_eff was
chosen, before issue 29 made the model's w the one weight): the log loss of the right names on the
**development** views (only; held-out views are never read) if a test view were weighed as n_eff =
1 … 12 by 0.5 and 14, 16, 20, 24, 32 draws instead of w, colour-hog and fc7 pooled, and the minimum;
beside each value, its difference from the least with a 95 % paired bootstrap interval over
development views ("within noise" when the interval reaches 0).

Figures over seeds: each configuration's ECE, accuracy and share of wrong answers at p ≥ 0.99 per
seed, their mean and a 95 % t interval over the seeds (each seed its own knowledge fit and adapt),
and the view weights w the seeds' models used.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import warnings
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from split_seeds import refuse_other_seeds

from spco.evaluation.config import PAPER_EXPERIENCED_HOMES

#: The split of benchmarks/calibration/SPLIT.md.
SETS: dict[str, dict[str, Any]] = {
    "development": {"homes": ("1DK_8", "3LDK_9"), "sizes": (4, 8), "seeds": tuple(range(5))},
    # issue 29, decided before it was run: the development views above are nearly all answered right
    # (fc7: all), too easy to compare methods on; two experienced homes outside the first 6 of the
    # paper's list held out as new homes (SPLIT.md: development configurations may), scored at every
    # sample (they have no test split), 4 and 6 homes; 8 and 16 added for issue 29's view weight (the
    # knowledge of "16" is the paper's 16 without these two: 14 homes)
    "development-new": {"homes": ("2LDK_3", "1LDK_3"), "sizes": (4, 6, 8, 16), "seeds": tuple(range(3))},
    # issue 29 (branch calib20), decided 2026-12-07 before it was run: "development" and "development-new"
    # pass with the room account, the held-out colour-hog 4-home configuration does not; four more
    # experienced homes outside the first 6 of the paper's list held out as new homes (scored at every
    # sample), 4 and 6 homes, the session's calibration seeds 200-219 (--seeds chooses among them)
    "development-probe": {"homes": ("2LDK_6", "1LDK_5", "2LDK_5", "1LDK_4"), "sizes": (4, 6),
                          "seeds": tuple(range(200, 220))},
    # 6 added 2026-12-06 (issue 29's configurations: 4, 6, 8, 16), before a held-out view was scored
    # with it (calibration/SPLIT.md, Log)
    "held-out": {"homes": ("1LDK_9", "2LDK_9"), "sizes": (4, 6, 8, 16), "seeds": tuple(range(100, 110))},
}
FEATURES = ("colour-hog", "fc7")
N_BINS = 10
SURE = 0.99
N_BOOTSTRAP = 1000


@dataclass(frozen=True)
class Task:
    """One knowledge fit and the new homes adapted with it."""

    features: str
    size: int
    seed: int
    homes: tuple[str, ...]
    set_name: str
    settings: tuple[str, ...] = ()  # ``--set NAME=VALUE`` of the knowledge's hyperparameters
    view_by_view: bool = False  # ``--view-by-view``: after = name_prediction(by_room=False), to compare
    view_in_room: bool = False  # ``--view-in-room``: after = the room account, the view drawn from its room
    room_typical: bool = False  # ``--room-typical``: after = the room account, rooms atypical now and then


def _load(data: Path, images: Path | None, names: Sequence[str], features: str, rate: int) -> list[Any]:
    from spco.data.loading import load_homes
    from spco.features import build_extractor

    if features == "fc7":
        return load_homes(data, names=list(names), teaching_rate=rate)
    if images is None:
        raise SystemExit("error: --images is needed for colour-hog views")
    extractor = build_extractor(features)
    return load_homes(data, names=list(names), teaching_rate=rate, extractor=extractor, images=images)


def _knowledge(task: Task, data: Path, images: Path | None, models: Path, force: bool) -> Any:
    import spco.knowledge as kn
    from spco.data.environment import Corpus
    from spco.features import build_extractor

    k_file = models / f"knowledge_{task.features}_{task.size}_{task.seed}.spco"
    if k_file.exists() and not force:
        return kn.load_knowledge(k_file)
    experienced = [h for h in PAPER_EXPERIENCED_HOMES[: task.size] if h not in task.homes]
    homes = _load(data, images, experienced, task.features, 100)
    extractor = None if task.features == "fc7" else build_extractor(task.features)
    hyper = None
    if task.settings:  # the defaults' prior (fit_knowledge's prior="places", as without settings: κ0, L, K
        # and Ψ0 from the homes), then the settings, as `spco fit --set` does
        from spco.knowledge.fit import default_hyperparameters

        hyper = default_hyperparameters(Corpus(homes), psi0=True).with_settings(list(task.settings))
    knowledge = kn.fit_knowledge(Corpus(homes), random_state=task.seed, extractor=extractor,
                                 hyperparameters=hyper)
    knowledge.save(k_file, overwrite=True)
    return knowledge


def home_models(task: Task, data: Path, images: Path | None, models: Path, force: bool
                ) -> Iterator[tuple[Any, Any]]:
    """(new home, its adapted HomeModel) for each new home of ``task``: fitted and adapted, or read
    from ``models`` where a previous run kept them."""
    import spco.knowledge as kn

    warnings.filterwarnings("ignore")
    knowledge = None
    for name in task.homes:
        home = _load(data, images, [name], task.features, 0)[0]
        h_file = models / f"home_{task.features}_{task.size}_{task.seed}_{name}.spco"
        if h_file.exists() and not force:
            yield home, kn.load_home_model(h_file)
            continue
        if knowledge is None:
            knowledge = _knowledge(task, data, images, models, force)
        model = kn.adapt(knowledge, home, random_state=task.seed)
        model.save(h_file, overwrite=True)
        yield home, model


def scored_views(home: Any) -> tuple[np.ndarray, Any, list[str], np.ndarray]:
    """(positions, views, labels, ids) scored in ``home``: its test views; an experienced home held
    out as a new one (no test split: ``test_num.txt`` is 999) is scored at every sample, none of
    which was taught (``development-new``)."""
    scored = home.is_test if home.is_test.any() else np.ones(home.n_samples, dtype=bool)
    labels = [lab for lab, t in zip(home.labels(), scored, strict=True) if t]
    return home.positions[scored], home.visual[scored], labels, home.ids[scored]


def _view_weight(hyper: Any) -> float | None:
    """The model's view weight w (a model file from before ``view_weight``: its ``view_counts``)."""
    weight = getattr(hyper, "view_weight", None)
    return weight() if callable(weight) else hyper.view_counts


def _answer_left_out(model: Any, sample: int, pose: np.ndarray, view: Any, settings: Any = None) -> Any:
    """The answer at ``pose`` with ``view`` with training sample ``sample`` (an id; ``-1``: none) left
    out of its room's views, so that a development-new view (a training sample of its home) is not
    counted twice: the answer a new view at that pose would get, with the model's answer settings or
    the override ``settings`` (an :class:`~spco.model.hyperparameters.AnswerSettings`: ``--view-in-room``,
    ``--room-typical``)."""
    from spco.knowledge.queries import answer_parameters, home_rooms
    from spco.model.confidence import answer_names

    rooms = home_rooms(model)
    keep = np.asarray(model.ids) != sample
    return answer_names(answer_parameters(model), 0, model.vocabulary, pose, view, top_k=1,
                        weighting=model.weighting, view_counts=model.hyperparameters.view_weight(),
                        rooms=rooms.subset(keep),
                        settings=model.hyperparameters.answer_settings() if settings is None else settings)


def typicality_of(model: Any, data: Path, images: Path | None, features: str) -> float:
    """ρ, how often a room looks like its concept, learnt from the experienced homes of ``model``'s
    knowledge at the model's w (opt-in, ``--room-typical``): :func:`spco.knowledge.fit.learnt_typicality`,
    as ``spco fit --set typical=learn`` learns it; 1 (the room account) when there is nothing to learn
    from."""
    from spco.knowledge.fit import learnt_typicality

    knowledge = model.knowledge
    homes = _load(data, images, list(knowledge.provenance["homes"]), features, 100)
    rho, _ = learnt_typicality(homes, knowledge.log_phi_words, knowledge.log_g0,
                               list(knowledge.vocabulary.words), model.hyperparameters)
    return rho


def run_task(task: Task, data: Path, images: Path | None, models: Path, force: bool) -> list[dict[str, Any]]:
    """Fit (or reuse) the knowledge of ``task``, adapt its homes, and score every test view."""
    import spco.knowledge as kn
    from spco.model.answer_settings import AnswerSettings
    from spco.model.prediction import predict_names

    rows = []
    typical = None  # --room-typical: learnt once per knowledge (homes share it)
    override = None  # --view-in-room, --room-typical: the answer settings the opt-in scores with
    for home, model in home_models(task, data, images, models, force):
        name = home.name
        if task.room_typical and typical is None:
            typical = typicality_of(model, data, images, task.features)
        if task.view_in_room or task.room_typical:
            override = AnswerSettings(view_in_room=task.view_in_room, typical=typical)
        positions, visual, labels, ids = scored_views(home)
        before = predict_names(model.parameters, 0, model.vocabulary, positions, visual, top_k=1,
                               weighting=model.weighting)  # type: ignore[arg-type]
        vocabulary = list(model.vocabulary.words)
        for i, label in enumerate(labels):
            theta = math.atan2(positions[i, 2], positions[i, 3])
            if task.view_by_view:  # the comparison: each of a room's views independent evidence
                after = kn.name_prediction(model, positions[[i]], visual[[i]], top_k=1, by_room=False)
            elif override is not None and home.is_test.any():  # an opt-in
                after = _answer_left_out(model, -1, positions[[i]], visual[[i]], override)
            elif home.is_test.any():  # what the robot answers (the room account)
                after = kn.what(model, float(positions[i, 0]), float(positions[i, 1]), theta,
                                visual=visual[[i]].toarray()[0], top_k=1)
            else:  # a training sample scored (development-new): left out of its room, as a new view is
                after = _answer_left_out(model, int(ids[i]), positions[[i]], visual[[i]], override)
            k = vocabulary.index(label) if label in vocabulary else None
            rows.append({
                "set": task.set_name, "features": task.features, "size": task.size, "seed": task.seed,
                "home": name, "view": int(ids[i]), "label": label,
                "before": before.best[i], "p_before": float(before.confidence[i]),
                "p_true_before": float(before.word_probabilities[i, k]) if k is not None else 0.0,
                "after": after.best[0], "p_after": float(after.confidence[0]),
                "p_true_after": float(after.word_probabilities[0, k]) if k is not None else 0.0,
                "unsure": bool(after.unsure[0]),
                "view_counts": _view_weight(model.hyperparameters),
                **({} if typical is None else {"typical": typical}),
            })
    return rows


def view_counts_log_loss(data: Path, images: Path | None, models: Path, features: Sequence[str],
                         grid: np.ndarray, force: bool) -> tuple[np.ndarray, list[tuple[str, int]]]:
    """−log p(right name | pose, view) of every development answer, for each number of draws a view
    is worth; the development models are fitted (or reused) first.

    Returns
    -------
    losses: (n, len(grid)) one row per answer (development test view × view kind × set × seed);
    views: (n,) the (home, view id) of each row, for a bootstrap over views.
    """
    from spco.model.confidence import answer_names, answer_parameters

    dev = SETS["development"]
    losses: list[np.ndarray] = []
    views: list[tuple[str, int]] = []
    for f in features:
        for size in dev["sizes"]:
            for seed in dev["seeds"]:
                task = Task(f, size, seed, dev["homes"], "development")
                for home, model in home_models(task, data, images, models, force):
                    positions, visual = home.test_observations()
                    labels = [lab for lab, t in zip(home.labels(), home.is_test, strict=True) if t]
                    words = list(model.vocabulary.words)
                    rows = np.arange(len(labels))
                    columns = np.array([words.index(lab) for lab in labels])
                    named = answer_parameters(model.parameters, 0, model.data.words, model.state.concepts,
                                              model.knowledge.log_g0, model.hyperparameters.alpha_word)
                    mine = np.zeros((len(labels), len(grid)))
                    for j, value in enumerate(grid):
                        pred = answer_names(named, 0, model.vocabulary, positions, visual, top_k=1,
                                            weighting=model.weighting,  # type: ignore[arg-type]
                                            view_counts=float(value),
                                            settings=model.hyperparameters.answer_settings())
                        mine[:, j] = -np.log(np.maximum(pred.word_probabilities[rows, columns], 1e-12))
                    losses.append(mine)
                    views += [(home.name, int(i)) for i in home.ids[home.is_test]]
    return np.concatenate(losses), views


def paired_difference_interval(losses: np.ndarray, views: Sequence[tuple[str, int]], best: int,
                               rng: np.random.Generator, n_resamples: int = N_BOOTSTRAP) -> np.ndarray:
    """95 % bootstrap interval of mean loss(grid value) − mean loss(``best``), paired, over views.

    Parameters
    ----------
    losses: (n, G) the loss of each answer at each grid value; views: (n,) the view of each answer
        (a view is resampled with all its answers: seeds, view kinds, experienced-home sets).
    best: the column compared with.

    Returns
    -------
    (G, 2) the 2.5 % and 97.5 % quantiles of the difference of the mean losses.
    """
    index: dict[tuple[str, int], int] = {}
    cluster = np.array([index.setdefault(v, len(index)) for v in views])
    differences = losses - losses[:, [best]]
    sums = np.zeros((len(index), losses.shape[1]))
    np.add.at(sums, cluster, differences)
    sizes = np.bincount(cluster, minlength=len(index)).astype(float)
    draws = np.empty((n_resamples, losses.shape[1]))
    for r in range(n_resamples):
        pick = rng.integers(0, len(index), len(index))
        draws[r] = sums[pick].sum(axis=0) / sizes[pick].sum()
    return np.quantile(draws, [0.025, 0.975], axis=0).T


# ----------------------------------------------------------------------------------------- figures
def ece(confidence: np.ndarray, right: np.ndarray, n_bins: int = N_BINS) -> float:
    """Expected calibration error: Σ_b (n_b / n) |accuracy_b − mean confidence_b| over ``n_bins``
    equal-width bins of the confidence (the last bin includes 1).

    Parameters
    ----------
    confidence: (n,) probabilities of the answers; right: (n,) bool.

    Returns
    -------
    The ECE (0 for no answers).
    """
    if confidence.size == 0:
        return 0.0
    bins = np.minimum((confidence * n_bins).astype(int), n_bins - 1)
    total = 0.0
    for b in range(n_bins):
        inside = bins == b
        if inside.any():
            total += inside.mean() * abs(right[inside].mean() - confidence[inside].mean())
    return float(total)


def figures(confidence: np.ndarray, right: np.ndarray, p_true: np.ndarray, unsure: np.ndarray | None
            ) -> dict[str, float]:
    """ECE, accuracy, mean confidence, share of the wrong answers at p ≥ 0.99, unsure share, log loss."""
    wrong = ~right
    out = {"ece": ece(confidence, right), "accuracy": float(right.mean()),
           "confidence": float(confidence.mean()),
           "wrong_sure": float((confidence[wrong] >= SURE).mean()) if wrong.any() else 0.0,
           "log_loss": float(-np.log(np.maximum(p_true, 1e-12)).mean())}
    if unsure is not None:
        out["unsure"] = float(unsure.mean())
    return out


def summarise(rows: list[dict[str, Any]], rng: np.random.Generator) -> dict[str, Any]:
    """Figures with bootstrap intervals over test views (each view with all its seeds)."""
    keys = [(r["home"], r["view"]) for r in rows]
    clusters: dict[tuple[str, int], list[int]] = {}
    for i, key in enumerate(keys):
        clusters.setdefault(key, []).append(i)
    groups = [np.array(v) for v in clusters.values()]
    out: dict[str, Any] = {"views": len(groups), "answers": len(rows)}
    for way in ("before", "after"):
        conf = np.array([r[f"p_{way}"] for r in rows])
        right = np.array([r[way] == r["label"] for r in rows])
        p_true = np.array([r[f"p_true_{way}"] for r in rows])
        unsure = np.array([r["unsure"] for r in rows]) if way == "after" else None
        point = figures(conf, right, p_true, unsure)
        draws: dict[str, list[float]] = {k: [] for k in point}
        for _ in range(N_BOOTSTRAP):
            pick = np.concatenate([groups[j] for j in rng.integers(0, len(groups), len(groups))])
            for k, v in figures(conf[pick], right[pick], p_true[pick],
                                None if unsure is None else unsure[pick]).items():
                draws[k].append(v)
        out[way] = {k: {"value": v, "low": float(np.quantile(draws[k], 0.025)),
                        "high": float(np.quantile(draws[k], 0.975))} for k, v in point.items()}
        out[way]["wrong"] = int((~right).sum())
    out["seeds"] = over_seeds(rows)
    return out


def over_seeds(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The figures of ``after`` per seed, and their mean with a 95 % t interval over the seeds (each
    seed a new knowledge fit and adapt: the interval a user refitting would see); and the view
    weights w the seeds' models used."""
    from scipy import stats

    seeds = sorted({r["seed"] for r in rows})
    per: dict[str, list[float]] = {"ece": [], "accuracy": [], "wrong_sure": []}
    for seed in seeds:
        mine = [r for r in rows if r["seed"] == seed]
        conf = np.array([r["p_after"] for r in mine])
        right = np.array([r["after"] == r["label"] for r in mine])
        f = figures(conf, right, np.array([r["p_true_after"] for r in mine]), None)
        for k in per:
            per[k].append(f[k])
    out: dict[str, Any] = {"seeds": seeds,
                           "view_counts": sorted({r.get("view_counts") for r in rows}, key=str)}
    for k, values in per.items():
        v = np.array(values)
        half = (float(stats.t.ppf(0.975, v.size - 1) * v.std(ddof=1) / math.sqrt(v.size))
                if v.size > 1 else 0.0)
        out[k] = {"per_seed": [round(x, 4) for x in values], "mean": float(v.mean()),
                  "low": float(v.mean() - half), "high": float(v.mean() + half)}
    return out


def reliability_png(path: Path, panels: dict[str, list[dict[str, Any]]], title: str) -> None:
    """Reliability diagram: accuracy against confidence in 10 bins, before and after, per set."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.8), squeeze=False)
    edges = np.linspace(0, 1, N_BINS + 1)
    for ax, (set_name, rows) in zip(axes[0], panels.items(), strict=True):
        ax.plot([0, 1], [0, 1], color="0.6", lw=1, ls="--", label="calibrated")
        for way, colour in (("before", "tab:red"), ("after", "tab:blue")):
            conf = np.array([r[f"p_{way}"] for r in rows])
            right = np.array([r[way] == r["label"] for r in rows])
            bins = np.minimum((conf * N_BINS).astype(int), N_BINS - 1)
            xs, ys, ns = [], [], []
            for b in range(N_BINS):
                inside = bins == b
                if inside.any():
                    xs.append(conf[inside].mean())
                    ys.append(right[inside].mean())
                    ns.append(int(inside.sum()))
            sizes = 15 + 200 * np.sqrt(np.array(ns) / max(1, len(rows)))
            ax.plot(xs, ys, color=colour, lw=1.2)
            ax.scatter(xs, ys, s=sizes, color=colour, alpha=0.8,
                       label=f"{way}: ECE {ece(conf, right):.3f}")
        ax.bar(edges[:-1], np.histogram([r["p_after"] for r in rows], edges)[0] / max(1, len(rows)),
               width=0.1, align="edge", color="tab:blue", alpha=0.12, label="share of answers (after)")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1.02)
        ax.set_xlabel("confidence (p of the answer)")
        ax.set_ylabel("accuracy")
        ax.set_title(f"{set_name} ({len(rows)} answers)")
        ax.legend(loc="upper left", fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _fmt(cell: dict[str, float], digits: int = 3) -> str:
    return f"{cell['value']:.{digits}f} [{cell['low']:.{digits}f}, {cell['high']:.{digits}f}]"


def _configurations(rows: list[dict[str, Any]]) -> Iterator[tuple[str, str, str, list[dict[str, Any]]]]:
    for set_name in SETS:
        for features in FEATURES:
            mine = [r for r in rows if r["set"] == set_name and r["features"] == features]
            if not mine:
                continue
            for size in sorted({r["size"] for r in mine}):
                yield set_name, features, str(size), [r for r in mine if r["size"] == size]
            yield set_name, features, "all", mine


def _arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="the SIGVerse homes (sigverse/)")
    parser.add_argument("--images", type=Path, default=None, help="their camera images (sigverse_images/)")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--sets", default="development,held-out")
    parser.add_argument("--features", default=",".join(FEATURES))
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0, help="seed of the bootstrap")
    parser.add_argument("--force", action="store_true", help="refit the models kept in --out/models")
    parser.add_argument("--fit-view-counts", action="store_true",
                        help="print the development log loss against a test view's weight n_eff "
                             "(a diagnostic; what uses the model's w)")
    parser.add_argument("--first-seeds", type=int, default=None,
                        help="only the first N seeds of each set (a quick development look)")
    parser.add_argument("--seeds", type=int, nargs="+", default=None,
                        help="these seeds instead of each set's own (development seeds only: "
                             "benchmarks/SPLIT.md; held-out seeds are refused)")
    parser.add_argument("--sizes", default=None, help="only these experienced-home set sizes, e.g. 4,8")
    parser.add_argument("--view-by-view", action="store_true",
                        help="after = the view and the pose against the home's π and θ^v "
                             "(spco.knowledge.name_prediction(by_room=False), what `what` answered before "
                             "the room account) instead of what, to compare on the same models")
    parser.add_argument("--view-in-room", action="store_true",
                        help="after = the room account with the observation's view drawn from its room's "
                             "own distribution (opt-in: spco.model.rooms.concepts_by_room(view_in_room))")
    parser.add_argument("--room-typical", action="store_true",
                        help="after = the room account with rooms that look like another concept now and "
                             "then, how often learnt from the experienced homes (opt-in: "
                             "spco.model.view_fit.room_typicality)")
    parser.add_argument("--set", dest="settings", action="append", default=[], metavar="NAME=VALUE",
                        help="a hyperparameter of the knowledge fits, as `spco fit --set` (e.g. "
                             "view_counts=estimate); use a fresh --out: kept models are not checked")
    args = parser.parse_args(argv)
    args.sets = [s for s in args.sets.split(",") if s]
    if args.seeds is not None:
        refuse_other_seeds(parser, args.seeds)
        if "held-out" in args.sets:
            parser.error("--seeds: the held-out set is run with its own seeds only (benchmarks/SPLIT.md)")
    args.features = [f for f in args.features.split(",") if f]
    for s in args.sets:
        if s not in SETS:
            parser.error(f"--sets: unknown set {s!r}; choose from {', '.join(SETS)}")
    for f in args.features:
        if f not in FEATURES:
            parser.error(f"--features: unknown {f!r}; choose from {', '.join(FEATURES)}")
    if args.settings:
        from spco.errors import SpcoError
        from spco.model.hyperparameters import TransferHyperparameters

        try:
            TransferHyperparameters().with_settings(list(args.settings))
        except SpcoError as err:
            parser.error(f"--set: {err}")
    return args


def _print_view_counts_fit(args: argparse.Namespace, models: Path) -> None:
    """The development log loss against a test view's weight n_eff, with paired intervals."""
    grid = np.concatenate([np.arange(1.0, 12.01, 0.5), [14.0, 16.0, 20.0, 24.0, 32.0]])
    losses, views = view_counts_log_loss(args.data, args.images, models, args.features, grid, args.force)
    mean = losses.mean(axis=0)
    best = int(np.argmin(mean))
    interval = paired_difference_interval(losses, views, best, np.random.default_rng(args.seed))
    for value, loss, (low, high) in zip(grid, mean, interval, strict=True):
        noise = "  within noise of the least" if low <= 0.0 else ""
        print(f"n_eff {value:4.1f}: development log loss {loss:.4f}, minus the least "
              f"{loss - mean[best]:+.4f} [{low:+.4f}, {high:+.4f}]{noise}")
    print(f"least log loss at n_eff = {grid[best]:g} ({len(losses)} answers, {len(set(views))} views; "
          f"[ ]: 95 % paired bootstrap over views, {N_BOOTSTRAP} resamples, seed {args.seed})")


def _predictions(args: argparse.Namespace, models: Path, start: float) -> list[dict[str, Any]]:
    """Every configuration's answers (``args.jobs`` processes), also written to predictions.jsonl."""
    tasks = [Task(f, size, seed, SETS[s]["homes"], s, tuple(args.settings), args.view_by_view,
                  args.view_in_room, args.room_typical)
             for s in args.sets for f in args.features
             for size in SETS[s]["sizes"] if args.sizes is None or str(size) in args.sizes.split(",")
             for seed in (SETS[s]["seeds"] if args.seeds is None else args.seeds)[: args.first_seeds]]
    rows: list[dict[str, Any]] = []
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            futures = [pool.submit(run_task, t, args.data, args.images, models, args.force) for t in tasks]
            for i, fut in enumerate(futures, 1):
                rows += fut.result()
                print(f"[{i}/{len(tasks)}] {time.perf_counter() - start:.0f} s", file=sys.stderr, flush=True)
    else:
        for i, task in enumerate(tasks, 1):
            rows += run_task(task, args.data, args.images, models, args.force)
            print(f"[{i}/{len(tasks)}] {task.set_name} {task.features} n={task.size} seed={task.seed}: "
                  f"{time.perf_counter() - start:.0f} s", file=sys.stderr, flush=True)
    tmp = args.out / "predictions.jsonl.tmp"
    tmp.write_text("".join(json.dumps(r) + "\n" for r in rows))
    os.replace(tmp, args.out / "predictions.jsonl")
    return rows


def _tables(rows: list[dict[str, Any]], rng: np.random.Generator) -> tuple[str, list[dict[str, Any]]]:
    """The Markdown tables (per configuration and way; over seeds) and the summary rows."""
    summary = []
    lines = ["| set | views from | experienced homes | way | ECE | accuracy | mean confidence | "
             "wrong at p ≥ 0.99 | unsure | log loss |", "|---|---|---|---|---|---|---|---|---|---|"]
    seed_lines = ["| set | views from | experienced homes | w | seeds | ECE mean [95 % over seeds] "
                  "(per seed) | accuracy | wrong at p ≥ 0.99 |", "|---|---|---|---|---|---|---|---|"]
    for set_name, feats, size, mine in _configurations(rows):
        s = summarise(mine, rng)
        summary.append({"set": set_name, "features": feats, "size": size, **s})
        for way in ("before", "after"):
            f = s[way]
            wrong = f"{_fmt(f['wrong_sure'], 2)} of {f['wrong']}"
            lines.append(f"| {set_name} | {feats} | {size} | {way} | {_fmt(f['ece'])} | "
                         f"{_fmt(f['accuracy'])} | {_fmt(f['confidence'])} | {wrong} | "
                         f"{_fmt(f['unsure'], 2) if 'unsure' in f else '—'} | {_fmt(f['log_loss'])} |")
        o = s["seeds"]
        cells = [f"{o[k]['mean']:.3f} [{o[k]['low']:.3f}, {o[k]['high']:.3f}] "
                 f"({', '.join(f'{x:.3f}' for x in o[k]['per_seed'])})"
                 for k in ("ece", "accuracy", "wrong_sure")]
        weights = ", ".join("every count" if w is None else f"{w:.3g}" for w in o["view_counts"])
        seed_lines.append(f"| {set_name} | {feats} | {size} | {weights} | {len(o['seeds'])} | "
                          + " | ".join(cells) + " |")
    table = ("\n".join(lines) + "\n\nOver seeds (after; t interval over the seeds' figures):\n\n"
             + "\n".join(seed_lines))
    return table, summary


def main(argv: Sequence[str] | None = None) -> None:
    """Run the configurations, print the table and write the files."""
    args = _arguments(argv)
    models = args.out / "models"
    models.mkdir(parents=True, exist_ok=True)
    if args.fit_view_counts:
        _print_view_counts_fit(args, models)
        return
    start = time.perf_counter()
    rows = _predictions(args, models, start)
    table, summary = _tables(rows, np.random.default_rng(args.seed))
    for feats in args.features:
        for size in sorted({r["size"] for r in rows if r["features"] == feats}):
            panels = {s: [r for r in rows if r["set"] == s and r["features"] == feats and r["size"] == size]
                      for s in args.sets}
            panels = {k: v for k, v in panels.items() if v}
            reliability_png(args.out / f"reliability_{feats}_{size}.png", panels,
                            f"what on new SIGVerse homes: {feats} views, {size} experienced homes")
    (args.out / "tables.md").write_text(table + "\n")
    (args.out / "summary.json").write_text(json.dumps(
        {"split": "benchmarks/calibration/SPLIT.md", "bootstrap": N_BOOTSTRAP, "seed": args.seed,
         "summary": summary}, indent=1))
    print(table)
    print(f"{len(rows)} answers in {time.perf_counter() - start:.0f} s; files in {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
