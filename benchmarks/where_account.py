"""p(pose | name): the robot's ``where`` (the room account) beside the fit's π·G account, on one fit.

Development data only (benchmarks/SPLIT.md). Each configuration is fitted once, as the script it comes
from fits it (same corpus, sweeps and trial seed), and A_p is scored twice on the same draws' seed:

- **fit**: p(m | w) ∝ Σ_l π_{e,l,m} θ^w_{e,l,w} G_{e,l} of the fit's parameters (``evaluate_home``
  without the answer's parameters and rooms: the experiments' A_p before issue 29's one predictor);
- **names**: the same π·G account with the names ``what`` answers (``model_answer_parameters``'s θ^w,
  no rooms): which concept a name means as ``what`` says, which regions a concept holds as the fit says;
- **robot**: p(m | w) ∝ Σ_l p(w | l) p(l, m | home), p(w | l) the names ``what`` answers and
  p(l, m | home) the room account (``evaluate_home`` with ``model_answer_parameters`` and
  ``model_rooms``: what ``spco.knowledge.where`` answers, and the experiments' A_p now), drawn from the
  argmax region (the paper's A_p) and, as **robot's draw**, as the robot's ``where`` draws them (every
  region at least half as probable as the best, ``position_mode="answer"``).

A_n is the robot's (the same both ways). Sets:

- ``natural``: ``speech_errors.py``'s development configurations (the development homes' people's
  sentences; 3LDK_9 untaught; ``--leave-one-out`` adds each development experienced home held out);
- ``written``: ``free_speech.py`` with ``--speech`` (e.g. ``benchmarks/development/speech_dev.csv``)
  on 3LDK_9.

Run::

    nice -n 5 python benchmarks/where_account.py natural --seeds 0 1 --sweeps 60
    nice -n 5 python benchmarks/where_account.py written --seeds 0 --sweeps 200 \\
        --speech benchmarks/development/speech_dev.csv
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from data_paths import SIGVERSE
from free_speech import fit_new_home, new_home, read_names, read_speech, taught_homes
from natural_speech import configurations, fitted_runs
from split_seeds import refuse_other_seeds

from spco.evaluation import evaluate_home
from spco.model.confidence import model_answer_parameters
from spco.model.rooms import model_rooms

HERE = Path(__file__).resolve().parent
DRAW = "A_p robot's draw"


def _score(model, e: int, env, vocabulary, seed: int) -> dict[str, float]:
    """A_n (robot) and A_p both ways (argmax region, as ``spco experiment``) of one fit."""
    view_counts = model.settings_.view_counts
    fit = evaluate_home(model.parameters_, e, env, vocabulary, rng=seed, view_counts=view_counts)
    answer = model_answer_parameters(model, e)
    names = evaluate_home(model.parameters_, e, env, vocabulary, rng=seed, view_counts=view_counts,
                          answer_params=answer)
    robot = evaluate_home(model.parameters_, e, env, vocabulary, rng=seed, view_counts=view_counts,
                          answer_params=answer, answer_rooms=model_rooms(model, e))
    drawn = evaluate_home(model.parameters_, e, env, vocabulary, rng=seed, view_counts=view_counts,
                          answer_params=answer, answer_rooms=model_rooms(model, e), position_mode="answer")
    return {"A_p robot's draw": drawn.mean_position_accuracy, "A_n": robot.mean_name_accuracy,
            "A_p fit": fit.mean_position_accuracy,
            "A_p names": names.mean_position_accuracy, "A_p robot": robot.mean_position_accuracy,
            "places": {p: (fit.position_accuracy.get(p), names.position_accuracy.get(p),
                           robot.position_accuracy.get(p))
                       for p in robot.places}}


def _fits(args: argparse.Namespace, accepted: dict[str, tuple[str, ...]]) -> Iterator[tuple]:
    """Each seed's fits of the set, as the script it comes from fits them, in the seeds' and then the
    configurations' order: (seed, label, new home, corpus, model, the new home's index, what is scored),
    as :func:`natural_speech.fitted_runs`."""
    if args.set == "natural":
        _, configs = configurations(args.sigverse, accepted, args.leave_one_out)
        labels = [c[0] for c in configs]
        chosen = [c for c in configs if not args.homes or c[0].split()[0] in args.homes]
        yield from fitted_runs(chosen, labels, args.seeds, sweeps=args.sweeps)
        return
    env = new_home(args.sigverse, args.sigverse.parent / "sigverse_regions.json", "3LDK_9", accepted)
    for seed in args.seeds:
        experienced = taught_homes(args.sigverse, read_speech(args.speech), seed)
        model, corpus = fit_new_home(experienced, env, None, args.sweeps, seed, 0)
        yield seed, "3LDK_9", env, corpus, model, len(corpus) - 1, env


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("set", choices=("natural", "written"))
    parser.add_argument("--sigverse", type=Path, default=SIGVERSE)
    parser.add_argument("--accepted", type=Path, default=HERE / "development" / "accepted_names_dev.json")
    parser.add_argument("--speech", type=Path, default=HERE / "development" / "speech_dev.csv")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--sweeps", type=int, default=60)
    parser.add_argument("--leave-one-out", action="store_true")
    parser.add_argument("--homes", nargs="*", default=None)
    args = parser.parse_args()
    refuse_other_seeds(parser, args.seeds)
    accepted = read_names(args.accepted)
    runs = []
    started = time.perf_counter()
    for seed, label, _, corpus, model, e, scored in _fits(args, accepted):
        row = _score(model, e, scored, corpus.vocabulary, seed)
        runs.append(row)
        print(f"seed {seed} {label}: A_n {row['A_n']:.3f}  A_p fit {row['A_p fit']:.3f}  A_p names "
              f"{row['A_p names']:.3f}  A_p robot {row['A_p robot']:.3f}  A_p robot's draw "
              f"{row[DRAW]:.3f}  "
              f"({time.perf_counter() - started:.0f} s)", flush=True)
        for place, values in row["places"].items():
            print(f"    {place}: " + " / ".join(f"{v:.2f}" for v in values))
    for key in ("A_n", "A_p fit", "A_p names", "A_p robot", "A_p robot's draw"):
        values = np.array([r[key] for r in runs], dtype=float)
        print(f"{key}: mean {np.nanmean(values):.3f} over {values.size} fits")


if __name__ == "__main__":
    main()
