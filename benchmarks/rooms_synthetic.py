"""The room account on synthetic homes: what it answers beside the view-by-view answer, on the same fits.

Issue 29 ("A room's evidence", docs/model.md). The synthetic general experiment of
``tests/test_experiments.py`` (2 experienced homes, 10 sweeps, 2 runs) scored A_n 0.208 with the room
account as first built against the view-by-view answer's 0.250 (main ``9d6fc22``; the test's bound).
This script measures where the two answers differ, over more new homes, trials, experienced homes
and sweeps: every run fits the model once (exactly as ``spco experiment general`` does, the run's seed
:func:`~spco.evaluation.config.trial_seed`), then scores the new home's test samples with each answer
of ``--answers`` through :func:`spco.evaluation.metrics.evaluate_home` (A_n as the experiment reports
it) and per test sample (accuracy, ECE, wrong answers at p ≥ 0.99).

Per disagreement (a test sample one answer names right and the other wrong) it records why, from
the fit's state: the share of the pose's most probable region's training samples that are of the
sample's own place (``purity``), whether the sampler put most of that region's training samples in
the concept the room account chose, and whether the view alone (against φ^v at the view weight w)
prefers the room account's concept.

Synthetic homes are development data (benchmarks/SPLIT.md). Run (small first)::

    nice -n 5 python benchmarks/rooms_synthetic.py --settings 2 --trials 2 --iterations 10
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.environment import Corpus
from spco.data.language import normalize_name
from spco.evaluation.config import trial_seed
from spco.evaluation.experiments import ExperimentConfig, load_experiment_data
from spco.evaluation.metrics import evaluate_home, mean_over_places, name_accuracy
from spco.evaluation.models import MODELS
from spco.model.confidence import model_answer_parameters
from spco.model.prediction import concept_posterior, predict_names
from spco.model.rooms import concepts_by_room, model_rooms, room_concepts


def _by_regions(rooms: Any) -> Any:
    """``rooms`` with a room = a region (no concepts), as the room account was first built."""
    from spco.model.rooms import HomeRooms

    return HomeRooms.of(rooms.regions, rooms.visual, rooms.words, None)


def _by_region(params: Any, e: int, positions: np.ndarray, visual: Any, rooms: Any, w: float | None
               ) -> np.ndarray:
    """The room account as first built (calib3, 0db7a18): P(l | x, v) = Σ_k p(k | x) p(l | room k, v),
    the region chosen by the pose alone — the view does not weigh in on which room the pose is in."""
    rooms = _by_regions(rooms)
    from scipy.special import logsumexp

    from spco.model.prediction import _visual_log_likelihood, gaussian_log_density

    counts, room_post = room_concepts(params, e, rooms, w)
    log_k = np.where(counts[None, :] > 0, gaussian_log_density(positions, params.region_means[e],
                                                               params.region_covariances[e])
                     + np.log(np.maximum(counts, 1e-300))[None, :], -np.inf)
    p_k = np.exp(log_k - logsumexp(log_k, axis=1, keepdims=True))
    view_log = _visual_log_likelihood(np.asarray(params.shared_visual_probabilities), visual, w)
    out = np.zeros(view_log.shape)
    for k in np.flatnonzero(counts > 0):
        joint = np.log(np.maximum(room_post[k], 1e-300))[None, :] + view_log
        out += p_k[:, [k]] * np.exp(joint - logsumexp(joint, axis=1, keepdims=True))
    return out


def _by_region_concept(params: Any, e: int, positions: np.ndarray, visual: Any, rooms: Any, w: float | None,
                       concepts: np.ndarray) -> np.ndarray:
    """The room account with a room = the training samples sharing a region *and* a concept in the
    sampler's state (a region that holds two places holds two rooms), each at its region's Gaussian:
    built by hand here (each pair as a region of its own), as ``spco.model.rooms`` now builds it."""
    rooms = _by_regions(rooms)
    from dataclasses import replace

    from spco.model.rooms import HomeRooms

    pairs, groups = np.unique(np.stack([rooms.regions, concepts]), axis=1, return_inverse=True)
    region_of = pairs[0]
    E = np.shape(params.region_means)[0]
    means = np.repeat(np.asarray(params.region_means)[e][region_of][None], E, axis=0)
    covs = np.repeat(np.asarray(params.region_covariances)[e][region_of][None], E, axis=0)
    grouped = replace(params, region_means=means, region_covariances=covs)
    grouped_rooms = HomeRooms.of(groups.ravel(), rooms.visual, rooms.words)
    return concepts_by_room(grouped, e, positions, visual, grouped_rooms, w)


#: The answers compared (``default``: the view and the pose against the home's parameters).
ANSWERS = {"rooms": concepts_by_room, "by-region": _by_region}


def _ece(confidence: np.ndarray, right: np.ndarray, bins: int = 10) -> float:
    index = np.minimum((confidence * bins).astype(int), bins - 1)
    return float(sum(abs(right[index == b].mean() - confidence[index == b].mean()) * (index == b).sum()
                     for b in range(bins) if (index == b).any()) / max(confidence.size, 1))


def _interval(values: list[float]) -> str:
    from scipy import stats

    arr = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if arr.size == 0:
        return "-"
    if arr.size < 2:
        return f"{arr.mean():.3f}"
    half = float(stats.t.ppf(0.975, arr.size - 1) * arr.std(ddof=1) / math.sqrt(arr.size))
    return f"{arr.mean():.3f} [{arr.mean() - half:.3f}, {arr.mean() + half:.3f}]"


def one_run(data: Any, model_name: str, setting: int, trial: int, home: str, iterations: int,
            answers: tuple[str, ...]) -> dict[str, Any]:
    """Fit one run and score its new home with every answer of ``answers``."""
    spec = MODELS[model_name]
    seed = trial_seed(0, trial)
    homes = data.homes_for(setting, home)
    model = spec.build(iterations, seed, None, False)
    model.fit(Corpus(homes, vocabulary=data.vocabulary_for(setting)))
    e = len(homes) - 1
    env = homes[-1]
    params = model_answer_parameters(model, e)
    w = model.settings_.view_counts
    rooms = model_rooms(model, e)
    test = np.flatnonzero(env.is_test)
    labels = [env.labels(False)[i] for i in test]
    vocabulary = model.vocabulary_
    out: dict[str, Any] = {"model": model_name, "setting": setting, "trial": trial, "home": home,
                           "iterations": iterations, "view_weight": w, "answers": {}}
    picked: dict[str, np.ndarray] = {}
    positions, visual = env.positions[test], env.visual[test]
    places = list(dict.fromkeys(lab for lab in env.labels(False) if lab is not None))
    accepted = {place: env.ground_truth.accepted(place) for place in places}
    for answer in answers:
        if answer == "default":
            concepts = None
        elif answer == "region-concept":
            concepts = _by_region_concept(params, e, positions, visual, rooms, w,
                                          np.asarray(model.concepts_[e]))
        else:
            concepts = ANSWERS[answer](params, e, positions, visual, rooms, w)
        pred = predict_names(params, e, vocabulary, positions, visual, top_k=1, weighting=spec.weighting,
                             view_counts=w, name_prior=model.hyperparameters_.name_prior, concepts=concepts)
        best = list(pred.best)
        conf = np.asarray(pred.probabilities, dtype=float)[:, 0]
        right = np.array([b is not None and normalize_name(b) in accepted[normalize_name(lab)]
                          for b, lab in zip(best, labels, strict=True)])
        picked[answer] = right
        per_place = name_accuracy(best, labels, places, accepted)
        out["answers"][answer] = {
            "A_n": mean_over_places(per_place), "per_place": per_place,
            "accuracy": float(right.mean()), "ece": _ece(conf, right),
            "wrong": int((~right).sum()), "wrong_sure": int(((~right) & (conf >= 0.99)).sum()),
        }
        if answer in ("default", "rooms"):  # the experiment's own scoring agrees
            scores = evaluate_home(model.parameters_, e, env, vocabulary,
                                   rng=np.random.default_rng([seed, 1]), weighting=spec.weighting,
                                   view_counts=w, answer_params=params,
                                   answer_rooms=rooms if answer == "rooms" else None,
                                   name_prior=model.hyperparameters_.name_prior, n_positions=1)
            assert abs(scores.mean_name_accuracy - out["answers"][answer]["A_n"]) < 1e-12, answer
    if {"default", "rooms"} <= set(answers):
        out["disagreements"] = _disagreements(model, e, env, params, rooms, w, test, labels,
                                              picked["default"], picked["rooms"])
    return out


def _disagreements(model: Any, e: int, env: Any, params: Any, rooms: Any, w: float | None,
                   test: np.ndarray, labels: list[str], default_right: np.ndarray,
                   rooms_right: np.ndarray) -> list[dict[str, Any]]:
    """Why each test sample answered right by one account and wrong by the other is so (by region)."""
    rooms = _by_regions(rooms)
    from spco.model.prediction import _visual_log_likelihood, gaussian_log_density

    state_regions = rooms.regions
    train_labels = np.array([env.labels(False)[i] for i in np.flatnonzero(~env.is_test)], dtype=object)
    concepts = np.asarray(model.concepts_[e])
    counts, room_post = room_concepts(params, e, rooms, w)
    log_n = gaussian_log_density(env.positions[test], params.region_means[e], params.region_covariances[e])
    log_k = np.where(counts[None, :] > 0, log_n + np.log(np.maximum(counts, 1e-300))[None, :], -np.inf)
    region = np.argmax(log_k, axis=1)
    p_region = np.exp(log_k.max(axis=1) - np.logaddexp.reduce(log_k, axis=1))
    default_concept = np.argmax(concept_posterior(params, e, env.positions[test], env.visual[test],
                                                  view_counts=w), axis=1)
    phi_v = np.asarray(params.shared_visual_probabilities, dtype=np.float64)
    view_alone = np.argmax(_visual_log_likelihood(phi_v, env.visual[test], w), axis=1)
    out = []
    for j in np.flatnonzero(default_right != rooms_right):
        k = int(region[j])
        members = np.flatnonzero(state_regions == k)
        own = train_labels[members] == labels[j]
        room_concept = int(np.argmax(room_post[k]))
        majority = Counter(concepts[members].tolist()).most_common(1)[0][0] if members.size else -1
        out.append({
            "label": labels[j], "rooms_right": bool(rooms_right[j]), "region": k,
            "p_region": round(float(p_region[j]), 3), "region_size": int(members.size),
            "purity": round(float(own.mean()), 3) if members.size else None,
            "region_labels": dict(Counter(train_labels[members].tolist())),
            "room_concept": room_concept, "room_concept_p": round(float(room_post[k, room_concept]), 3),
            "sampler_majority": int(majority), "default_concept": int(default_concept[j]),
            "view_alone": int(view_alone[j]),
        })
    return out


def main(argv: list[str] | None = None) -> int:
    """Command line: see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--settings", type=int, nargs="+", default=[2], help="experienced homes")
    parser.add_argument("--trials", type=int, default=2)
    parser.add_argument("--iterations", type=int, nargs="+", default=[10], help="sweeps of each fit")
    parser.add_argument("--models", default="spcotransfer", help="comma-separated, as spco experiment")
    parser.add_argument("--new-homes", default=None,
                        help="comma-separated (default: every synthetic new home)")
    parser.add_argument("--answers", default="default,rooms",
                        help="default (view by view: the robot's answer before the room account was made the "
                        "default), rooms (the room account, the robot's answer), by-region (the room account "
                             "as first built: the region by the pose alone), region-concept (a room = a "
                             "region and a sampler concept)")
    parser.add_argument("--out", type=Path, default=None, help="write every run's record here (JSON lines)")
    args = parser.parse_args(argv)
    answers = tuple(args.answers.split(","))
    config = ExperimentConfig(experiment="general", settings=(0, *args.settings), trials=args.trials,
                              iterations=max(args.iterations), models=tuple(args.models.split(",")))
    data = load_experiment_data(config)
    new_homes = args.new_homes.split(",") if args.new_homes else list(data.new_homes)
    records = []
    start = time.process_time()
    for model_name in args.models.split(","):
        for iterations in args.iterations:
            for setting in args.settings:
                for trial in range(args.trials):
                    for home in new_homes:
                        rec = one_run(data, model_name, setting, trial, home, iterations, answers)
                        records.append(rec)
                        keys = ("model", "setting", "trial", "home", "iterations")
                        scored = " ".join(f"{a}={rec['answers'][a]['A_n']:.3f}" for a in answers)
                        print(json.dumps({k: rec[k] for k in keys}) + " " + scored,
                              flush=True)
                        if args.out is not None:
                            with args.out.open("a") as fh:
                                fh.write(json.dumps(rec, default=float) + "\n")
    print(f"\nCPU {time.process_time() - start:.0f} s\n")
    groups: dict[tuple, list[dict[str, Any]]] = defaultdict(list)
    for rec in records:
        groups[(rec["model"], rec["iterations"], rec["setting"])].append(rec)
    print("| model | sweeps | experienced homes | runs | " + " | ".join(
        f"{a}: A_n (95 % over runs) / accuracy / ECE / wrong at p ≥ 0.99" for a in answers) + " |")
    print("|---|---|---|---|" + "---|" * len(answers))
    for (model_name, iterations, setting), recs in sorted(groups.items()):
        cells = []
        for a in answers:
            rows = [r["answers"][a] for r in recs]
            cells.append(f"{_interval([r['A_n'] for r in rows])} / "
                         f"{np.mean([r['accuracy'] for r in rows]):.3f}"
                         f" / {np.mean([r['ece'] for r in rows]):.3f} / "
                         f"{sum(r['wrong_sure'] for r in rows)} of {sum(r['wrong'] for r in rows)}")
        print(f"| {model_name} | {iterations} | {setting} | {len(recs)} | " + " | ".join(cells) + " |")
    flips = [d for r in records for d in r.get("disagreements", [])]
    if flips:
        print(f"\ndisagreements: {len(flips)}; rooms right in {sum(d['rooms_right'] for d in flips)}")
        for side in (True, False):
            part = [d for d in flips if d["rooms_right"] == side]
            if not part:
                continue
            same = {key: sum(d["room_concept"] == d[key] for d in part)
                    for key in ("sampler_majority", "default_concept", "view_alone")}
            purity = np.median([d["purity"] for d in part if d["purity"] is not None])
            print(f"  rooms {'right' if side else 'wrong'} ({len(part)}): median purity of the pose's region "
                  f"{purity:.2f}, room concept = sampler's majority in {same['sampler_majority']}, "
                  f"= default's concept in {same['default_concept']}, = view alone in {same['view_alone']}, "
                  f"default = view alone in {sum(d['default_concept'] == d['view_alone'] for d in part)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
