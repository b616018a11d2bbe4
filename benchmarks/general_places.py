"""General places on new SIGVerse homes taught nothing, with intervals over seeds (issue 29, point 5).

The paper's first experiment, on the homes of ``benchmarks/SPLIT.md``, "General places from
2026-12-06":

- **development** (``--side development``, seeds 0–99): new home ``3LDK_9`` taught nothing, scored on
  its test block (A_n against ``name_label``; A_p: positions drawn for each place's name fall in the
  place's rectangle of ``sigverse_regions.json``, most probable region / whole mixture);
- **held-out** (``--side heldout``, seeds 100–119): new homes ``2LDK_10`` and ``1LDK_10`` taught
  nothing. They have no test block and no rectangles: every third sample (2, 5, 8, …; about 7 of
  each place's 20) is made a test sample, never learnt from, and scored for A_n against
  ``name_label``; A_p is not measured (no rectangles). Their views never informed a constant: they
  entered the work only as home-specific held-out rooms, reported once per frozen method and never
  used to change it.

Knowledge: the paper's 16 experienced homes taught every sample (``sentence/per_100``). Each seed
fits the default model exactly as ``spco experiment general --models spcotransfer+mi`` does
(:data:`spco.evaluation.models.MODELS`, the run's seed :func:`~spco.evaluation.config.trial_seed`
(seed, index of the new home), names scored with the model's own view weight and name prior).
Figures: per new home and over homes, the mean over seeds with a 95 % Student-t interval over
seeds; per place the mean over seeds.

Run (development, small)::

    nice -n 5 python benchmarks/general_places.py --seeds 0 1 --sweeps 200

``--set NAME=VALUE`` (repeatable, as ``spco fit --set``) fits with the model's default
hyperparameters changed, e.g. the power target: ``--set target=power --set visual_prior=estimate``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from data_paths import SIGVERSE
from split_seeds import SEEDS, refuse_other_seeds

from spco.data import Corpus, Environment
from spco.data.loading import load
from spco.data.regions import load_region_file
from spco.errors import ConfigurationError
from spco.evaluation import evaluate_answers, evaluate_home
from spco.evaluation.config import PAPER_EXPERIENCED_HOMES, trial_seed
from spco.evaluation.models import MODELS
from spco.model.answer_settings import AnswerSettings
from spco.model.hyperparameters import TransferHyperparameters

#: The split of benchmarks/SPLIT.md, "General places from 2026-12-06".
SIDES: dict[str, dict[str, Any]] = {
    "development": {"new": ("3LDK_9",), "seeds": SEEDS["development"],
                    "every_third": False},
    "heldout": {"new": ("2LDK_10", "1LDK_10"), "seeds": SEEDS["heldout"],
                "every_third": True},
}
MODEL = "spcotransfer+mi"


def seed_interval(values: list[float] | np.ndarray) -> tuple[float, float, float]:
    """Mean and 95 % Student-t interval of the mean over ``values`` (one per seed), clipped to
    [0, 1]; the interval is the mean itself for fewer than two finite values."""
    from scipy import stats

    arr = np.asarray(values, dtype=float)
    arr = arr[np.isfinite(arr)]
    if arr.size == 0:
        return math.nan, math.nan, math.nan
    mean = float(arr.mean())
    if arr.size < 2:
        return mean, mean, mean
    half = float(stats.t.ppf(0.975, arr.size - 1) * arr.std(ddof=1) / math.sqrt(arr.size))
    return mean, max(0.0, mean - half), min(1.0, mean + half)


def new_home(sigverse: Path, regions_file: Path, name: str, every_third: bool) -> Environment:
    """A new home taught nothing, with its rectangles where the region file has them. A home without
    a test block (``every_third``) gets one: its samples 2, 5, 8, … (every third, about 7 per place
    of 20) are test samples, never learnt from and scored; the others are learnt untaught."""
    env = load(sigverse / name)[name]
    env = env.with_sentences((None,) * env.n_samples)
    regions = load_region_file(regions_file).get(name) if regions_file.is_file() else None
    if regions is not None and env.ground_truth is not None:
        env = replace(env, ground_truth=replace(env.ground_truth, regions=regions))
    if every_third:
        if env.n_test:
            raise SystemExit(f"error: {sigverse / name}: has its own test block; not a home of this side")
        return replace(env, is_test=np.arange(env.n_samples) % 3 == 2)
    if env.n_test == 0:
        raise SystemExit(f"error: {sigverse / name}: new home has no test samples (test_num.txt)")
    return env


def model_hyperparameters(settings: list[str] | tuple[str, ...]) -> TransferHyperparameters | None:
    """The hyperparameters the fits use: ``None`` (the model's own defaults, as ``spco experiment
    general``) without settings, else :class:`TransferHyperparameters`'s defaults with the
    ``NAME=VALUE`` settings applied (:meth:`TransferHyperparameters.with_settings`; raises
    :class:`~spco.errors.ConfigurationError` naming a bad setting)."""
    return TransferHyperparameters().with_settings(list(settings)) if settings else None


def run(sigverse: Path, regions_file: Path, side: str, seeds: list[int], sweeps: int,
        answers: tuple[str, ...] = (), settings: tuple[str, ...] = ()) -> dict[str, Any]:
    """Fit and score every (seed, new home) of ``side``; returns the figures (see the docstring).
    ``answers``: also score names from each fit's answer parameters
    (:func:`spco.model.confidence.model_answer_parameters`) two ways (``"view"``: the view-by-view answer,
    the robot's before the room account was the default; ``"rooms"``: the room account,
    :func:`spco.model.rooms.model_rooms`, what the robot answers; ``"view_in_room"``: the room account
    with the observation's view as a draw of its room, the opt-in of docs/model.md; ``"listener"``), from
    the same fit, as ``A_n_<answer>`` and ``A_p_<answer>``.
    ``settings``: ``NAME=VALUE`` hyperparameter settings (:func:`model_hyperparameters`)."""
    from spco.model.confidence import model_answer_parameters

    spec = MODELS[MODEL]
    hyper = model_hyperparameters(settings)
    conf = SIDES[side]
    knowledge = [load(sigverse / h)[h] for h in PAPER_EXPERIENCED_HOMES]
    homes = [new_home(sigverse, regions_file, h, conf["every_third"]) for h in conf["new"]]
    runs: list[dict[str, Any]] = []
    started = time.perf_counter()
    for seed in seeds:
        for index, env in enumerate(homes):
            run_seed = trial_seed(seed, index)
            model = spec.build(sweeps, run_seed, hyper, False)
            corpus = Corpus([*knowledge, env])
            model.fit(corpus)
            scores = evaluate_home(model.parameters_, len(corpus) - 1, env, model.vocabulary_,
                                   rng=np.random.default_rng([run_seed, 1]), weighting=spec.weighting,
                                   name_prior=model.hyperparameters_.name_prior,
                                   view_counts=model.settings_.view_counts)
            has_regions = env.ground_truth is not None and env.ground_truth.regions is not None
            a_p = scores.mean_position_accuracy if has_regions else math.nan
            a_p_mix = scores.mean_position_accuracy_mixture if has_regions else math.nan
            runs.append({"seed": seed, "home": env.name, "A_n": float(scores.mean_name_accuracy),
                         "A_p": float(a_p), "A_p_mixture": float(a_p_mix),
                         "A_n_places": {p: float(v) for p, v in scores.name_accuracy.items()}})
            e = len(corpus) - 1
            for answer in answers:  # the same fit, names from the answer parameters
                if answer == "rooms":  # the robot's answer (evaluate_answers: its rooms and weighting)
                    answered = evaluate_answers(model, e, env, rng=np.random.default_rng([run_seed, 1]))
                elif answer == "view_in_room":  # the room account, the view as a draw of its room
                    answered = evaluate_answers(model, e, env, rng=np.random.default_rng([run_seed, 1]),
                                                settings=AnswerSettings(view_in_room=True))
                elif answer in ("listener", "looks"):  # the robot's answer with name_answer=answer, same fit
                    answered = _listener_answers(model, e, env, np.random.default_rng([run_seed, 1]), answer)
                else:
                    answered = evaluate_home(model.parameters_, e, env, model.vocabulary_,
                                             rng=np.random.default_rng([run_seed, 1]),
                                             weighting=spec.weighting,
                                             name_prior=model.hyperparameters_.name_prior,
                                             view_counts=model.settings_.view_counts,
                                             answer_params=model_answer_parameters(model, e))
                runs[-1][f"A_n_{answer}"] = float(answered.mean_name_accuracy)
                # positions as the robot's where finds them from the same answer (one p(pose | name))
                a_p_answer = answered.mean_position_accuracy if has_regions else math.nan
                runs[-1][f"A_p_{answer}"] = float(a_p_answer)
            print(f"seed {seed} {env.name}: A_n {scores.mean_name_accuracy:.3f} A_p {a_p:.3f} "
                  + "".join(f"A_n ({a}) {runs[-1][f'A_n_{a}']:.3f} A_p ({a}) {runs[-1][f'A_p_{a}']:.3f} "
                            for a in answers)
                  + f"({time.perf_counter() - started:.0f} s)", flush=True)
    return summarise(side, seeds, sweeps, [h.name for h in homes], runs, answers, settings)


def _listener_answers(model: Any, e: int, env: Environment, rng: np.random.Generator,
                      name_answer: str = "listener") -> Any:
    """``evaluate_answers`` of ``model`` answering with ``name_answer`` (``"listener"`` or ``"looks"``;
    the fit does not read it: the same fit, its hyperparameters restored after)."""
    fitted = model.hyperparameters_
    model.hyperparameters_ = replace(fitted, name_answer=name_answer)
    model.__dict__.pop("_answers", None)
    try:
        return evaluate_answers(model, e, env, rng=rng)
    finally:
        model.hyperparameters_ = fitted
        model.__dict__.pop("_answers", None)


def summarise(side: str, seeds: list[int], sweeps: int, homes: list[str], runs: list[dict[str, Any]],
              answers: tuple[str, ...] = (), settings: tuple[str, ...] = ()) -> dict[str, Any]:
    """Means over seeds with 95 % intervals over seeds, per new home and over the new homes (each
    seed's mean over homes is one value); ``settings`` are recorded (written only when given)."""
    out: dict[str, Any] = {"format": "spco-general-places/1", "side": side, "seeds": seeds, "sweeps": sweeps,
                           "model": MODEL, "homes": homes, "runs": runs}
    if settings:
        out["settings"] = list(settings)
    for key in ("A_n", "A_p", "A_p_mixture", *(f"A_{x}_{a}" for a in answers for x in "np")):
        per_seed = [float(np.nanmean([r[key] for r in runs if r["seed"] == s]))
                    if any(np.isfinite(r[key]) for r in runs if r["seed"] == s) else math.nan for s in seeds]
        mean, low, high = seed_interval(per_seed)
        out[key] = None if math.isnan(mean) else {"mean": mean, "low": low, "high": high,
                                                   "seeds": per_seed}
        for home in homes:
            values = [r[key] for r in runs if r["home"] == home]
            m, lo, hi = seed_interval(values)
            out.setdefault("per_home", {}).setdefault(home, {})[key] = (
                None if math.isnan(m) else {"mean": m, "low": lo, "high": hi})
    places: dict[str, list[float]] = defaultdict(list)
    for r in runs:
        for p, v in r["A_n_places"].items():
            places[f"{r['home']} {p}"].append(v)
    out["A_n_per_place"] = {k: round(float(np.mean(v)), 3) for k, v in sorted(places.items())}
    return out


def _cell(fig: dict[str, float] | None) -> str:
    return "–" if fig is None else f"{fig['mean']:.3f} [{fig['low']:.3f}, {fig['high']:.3f}]"


def main(argv: list[str] | None = None) -> int:
    """Parse the command line, run, print the table and write ``--json``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sigverse", type=Path, default=SIGVERSE)
    parser.add_argument("--regions", type=Path, default=None,
                        help="region file (default: sigverse_regions.json beside --sigverse)")
    parser.add_argument("--side", choices=tuple(SIDES), default="development")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--sweeps", type=int, default=200, help="Gibbs sweeps (spco experiment's default)")
    parser.add_argument("--json", type=Path, default=None, help="write every figure to this file")
    parser.add_argument("--answers", default="", help="also score answers from the same fits: view (view by "
                        "view), rooms (the room account, the robot's answer), view_in_room (rooms with "
                        "the view as a draw of its room, opt-in), listener (rooms with "
                        "name_answer=listener), looks (rooms with name_answer=looks), comma-separated")
    parser.add_argument("--set", dest="settings", action="append", default=[], metavar="NAME=VALUE",
                        help="a hyperparameter of the fits, as `spco fit --set` (repeatable; e.g. "
                        "--set target=power --set visual_prior=estimate); default: the model's own")
    args = parser.parse_args(argv)
    try:
        model_hyperparameters(args.settings)
    except (ConfigurationError, ValueError) as err:
        parser.error(f"--set: {err}")
    answers = tuple(a for a in args.answers.split(",") if a)
    if set(answers) - {"view", "rooms", "view_in_room", "listener", "looks"}:
        parser.error(f"--answers: choose from view, rooms, view_in_room, listener, looks, "
                     f"got {args.answers!r}")
    refuse_other_seeds(parser, args.seeds, args.side)
    if len(set(args.seeds)) != len(args.seeds):
        parser.error("--seeds: each seed once")
    if args.sweeps < 1:
        parser.error("--sweeps: at least 1")
    if not (args.sigverse / "3LDK_1").is_dir():
        parser.error(f"--sigverse {args.sigverse}: not the SIGVerse data set (no 3LDK_1)")
    regions = args.regions or args.sigverse.parent / "sigverse_regions.json"
    summary = run(args.sigverse, regions, args.side, args.seeds, args.sweeps, answers, tuple(args.settings))
    print("\n| side | new homes | seeds | A_n [95 % over seeds] | A_p [95 % over seeds] |")
    print("|---|---|---:|---|---|")
    print(f"| {args.side} | {', '.join(summary['homes'])} | {len(args.seeds)} | {_cell(summary['A_n'])} | "
          f"{_cell(summary['A_p'])} |")
    for home, figs in summary["per_home"].items():
        print(f"| {args.side}, {home} | | | {_cell(figs['A_n'])} | {_cell(figs['A_p'])} |")
    for answer in answers:
        print(f"A_n, answer {answer}: {_cell(summary[f'A_n_{answer}'])}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        tmp = args.json.with_name(args.json.name + ".tmp")
        tmp.write_text(json.dumps(summary, indent=1), encoding="utf-8")
        os.replace(tmp, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
