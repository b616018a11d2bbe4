"""Natural speech on SIGVerse: knowledge taught with what people really typed (issue 28).

The configurations are fixed in ``benchmarks/SPLIT.md``, "Natural speech (issue 28)":

- **development** (``--side development``, seeds 0–99): the 8 development homes (1LDK_1,3,5,7,
  2LDK_1,3,5,7), each training sample taught with its subject's sentence
  (``sigverse_subject/<home>/per_100/sentence<i>.txt``, in place of ``sentence/per_100``);
  new home ``3LDK_9`` taught nothing, scored on its test block (A_n against its general labels with
  the accepted names, A_p of every accepted name the vocabulary holds); and (``--leave-one-out``)
  each development home in turn held out of the knowledge as a new home, taught nothing, its
  training samples scored against ``name_label`` (A_n only: no regions are drawn for these homes);
- **held-out** (``--side heldout``, seeds 100–119): the 8 held-out homes with their subject speech;
  new homes 1LDK_9, 2LDK_9, 3LDK_9 taught nothing. Reported only, once per frozen method: the script
  refuses to run it unless the checked-out commit's message starts with ``WORDS FROZEN:`` (or
  ``--i-know-the-method-is-frozen`` is given for a worktree without git).

Each seed fits SpCoTransfer+MI (the default exact model) for ``--sweeps`` sweeps with
:func:`~spco.evaluation.experiments.trial_seed` (seed, index of the new home); names are predicted
as the robot answers them (:func:`spco.evaluation.evaluate_answers`: the model's view weight, its
name weighting, the answer's parameters and the home's rooms), as ``spco experiment``. Figures: the mean
over seeds with a 95 % interval over seeds (normal approximation, ``japanese.mean_interval``), A_n
per place and the wrong answers most often given; ``--json`` writes every figure.

Run (development, small)::

    nice -n 5 python benchmarks/natural_speech.py --seeds 0 1 --sweeps 60
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from collections import Counter, defaultdict
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from free_speech import new_home, read_names
from japanese import mean_interval

from spco.data import Corpus, Environment
from spco.data.loading import load
from spco.data.sigverse import read_indexed_texts
from spco.evaluation import evaluate_answers
from spco.evaluation.experiments import trial_seed
from spco.model import SpCoTransfer
from spco.model.hyperparameters import TransferHyperparameters

SIDES = {
    "development": {"knowledge": ("1LDK_1", "1LDK_3", "1LDK_5", "1LDK_7",
                                  "2LDK_1", "2LDK_3", "2LDK_5", "2LDK_7"),
                    "new": ("3LDK_9",), "seeds": (*range(0, 100), *range(200, 300)),
                    "seed_text": "0-99 and 200-299"},
    "heldout": {"knowledge": ("1LDK_2", "1LDK_4", "1LDK_6", "1LDK_8",
                              "2LDK_2", "2LDK_4", "2LDK_6", "2LDK_8"),
                "new": ("1LDK_9", "2LDK_9", "3LDK_9"), "seeds": range(100, 120), "seed_text": "100-119"},
}


def subject_home(sigverse: Path, subject: Path, name: str) -> Environment:
    """A SIGVerse home whose taught sentences are its subjects' (every training sample)."""
    env = load(sigverse / name)[name]
    texts = read_indexed_texts(subject / name / "per_100", "sentence", env.n_samples, strict=False)
    sentences = [None if t else s for s, t in zip(texts, env.is_test, strict=True)]
    return env.with_sentences(sentences)


def untaught_subject_home(sigverse: Path, name: str) -> Environment:
    """A development home held out of the knowledge: taught nothing (its training samples are
    learnt untaught and scored: :func:`scored_as_test`)."""
    env = load(sigverse / name)[name]
    return env.with_sentences((None,) * env.n_samples)


def scored_as_test(env: Environment) -> Environment:
    """``env`` with every sample a test sample, to score the training samples of an untaught home
    (the fit learns ``env`` itself, whose samples are training samples)."""
    return replace(env, is_test=np.ones(env.n_samples, dtype=bool))


def frozen() -> bool:
    """Whether the checked-out commit's message starts with ``WORDS FROZEN:``."""
    try:
        message = subprocess.run(["git", "log", "-1", "--format=%s"], capture_output=True, text=True,
                                 check=True, cwd=Path(__file__).resolve().parent).stdout
    except (OSError, subprocess.CalledProcessError):
        return False
    return message.startswith("WORDS FROZEN:")


def _parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sigverse", type=Path, default=Path("/work/shared/datasets/sigverse"))
    parser.add_argument("--subject", type=Path, default=None,
                        help="subject speech (default: sigverse_subject beside --sigverse)")
    parser.add_argument("--regions", type=Path, default=None,
                        help="region file (default: sigverse_regions.json beside --sigverse)")
    parser.add_argument("--accepted", type=Path,
                        default=Path(__file__).resolve().parent / "development" / "accepted_names_dev.json")
    parser.add_argument("--side", choices=tuple(SIDES), default="development")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--sweeps", type=int, default=200)
    parser.add_argument("--leave-one-out", action="store_true",
                        help="development: also hold each development home out of the knowledge in turn")
    parser.add_argument("--i-know-the-method-is-frozen", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--set", nargs="+", action="extend", default=[], metavar="NAME=VALUE",
                        help="hyperparameter settings, as spco fit --set (development runs of the ablation)")
    return parser


def _summarise(args: argparse.Namespace, configs: list, runs: list[dict], wrong: dict,
               per_place: dict) -> dict[str, object]:
    """Print the table of means over seeds and the wrong answers; returns the figures."""
    summary: dict[str, object] = {"side": args.side, "seeds": args.seeds, "sweeps": args.sweeps}
    print("\n| configuration | seeds | A_n | A_p |\n|---|---:|---:|---:|")
    for label, *_ in configs:
        a_n = np.array([r["A_n"] for r in runs if r["home"] == label])
        a_p = np.array([r["A_p"] for r in runs if r["home"] == label])
        print(f"| {label} | {a_n.size} | {mean_interval(a_n)} | "
              f"{mean_interval(a_p) if np.isfinite(a_p).any() else '–'} |")
        summary[label] = {"A_n": float(a_n.mean()), "A_p": float(np.nanmean(a_p)) if np.isfinite(a_p).any()
                          else None, "A_n_seeds": a_n.tolist(), "A_p_seeds": a_p.tolist(),
                          "A_n_per_place": {p: round(float(np.mean(v)), 3) for (h, p), v in per_place.items()
                                            if h == label},
                          "wrong": dict(wrong[label].most_common(15))}
    if len(configs) > 1:  # per seed, the mean over configurations
        per_seed = np.array([np.mean([r["A_n"] for r in runs if r["seed"] == s]) for s in args.seeds])
        print(f"| all (mean per seed) | {per_seed.size} | {mean_interval(per_seed)} | |")
        summary["all_A_n"] = float(per_seed.mean())
    print("(mean ± half-width of the 95 % interval over seeds)")
    for label, *_ in configs:
        print(f"{label} wrong: {dict(wrong[label].most_common(8))}")
    return summary


def main() -> None:
    """Fit, score and print per seed and home, then the means over seeds with intervals."""
    parser = _parser()
    args = parser.parse_args()
    side = SIDES[args.side]
    bad = [s for s in args.seeds if s not in side["seeds"]]
    if bad:
        parser.error(f"--seeds {bad}: the {args.side} side's seeds are {side['seed_text']} "
                     "(benchmarks/SPLIT.md)")
    if args.side == "heldout" and not (frozen() or args.i_know_the_method_is_frozen):
        parser.error("the held-out configuration runs only on a frozen method (a commit whose message "
                     "starts with 'WORDS FROZEN:'), once; see benchmarks/SPLIT.md")
    if args.side == "heldout" and args.leave_one_out:
        parser.error("--leave-one-out is a development configuration")
    subject = args.subject or args.sigverse.parent / "sigverse_subject"
    regions_file = args.regions or args.sigverse.parent / "sigverse_regions.json"
    accepted = read_names(args.accepted)
    knowledge = [subject_home(args.sigverse, subject, h) for h in side["knowledge"]]
    configs: list[tuple[str, list[Environment], Environment]] = [
        (h, knowledge, new_home(args.sigverse, regions_file, h, accepted)) for h in side["new"]]
    if args.leave_one_out:
        for i, h in enumerate(side["knowledge"]):
            env = untaught_subject_home(args.sigverse, h)
            gt = env.ground_truth
            env = replace(env, ground_truth=replace(gt, accepted_names=accepted))
            configs.append((f"{h} (out)", knowledge[:i] + knowledge[i + 1:], env))
    hyper = TransferHyperparameters().with_settings(args.set) if args.set else None
    runs: list[dict] = []
    wrong: dict[str, Counter] = defaultdict(Counter)
    per_place: dict[tuple[str, str], list[float]] = defaultdict(list)
    started = time.perf_counter()
    for seed in args.seeds:
        for index, (label, homes, env) in enumerate(configs):
            corpus = Corpus([*homes, env])
            model = SpCoTransfer(hyper, variant="exact", prune_words=True, n_iterations=args.sweeps,
                                 random_state=trial_seed(seed, index)).fit(corpus)
            scored = scored_as_test(env) if label.endswith("(out)") else env
            e = len(corpus) - 1
            scores = evaluate_answers(model, e, scored, rng=seed)  # as the robot answers
            gt = env.ground_truth
            for place, name in zip(scores.labels, scores.predicted_names, strict=True):
                if name not in gt.accepted(place):
                    wrong[label][f"{place} -> {name}"] += 1
            for place, value in scores.name_accuracy.items():
                per_place[(label, place)].append(value)
            a_p = scores.mean_position_accuracy if gt.regions is not None else float("nan")
            runs.append({"seed": seed, "home": label, "A_n": scores.mean_name_accuracy, "A_p": a_p,
                         "A_n_places": scores.name_accuracy,
                         "A_p_places": scores.position_accuracy if gt.regions is not None else {}})
            print(f"seed {seed} {label}: A_n {scores.mean_name_accuracy:.3f} A_p {a_p:.3f} "
                  f"({time.perf_counter() - started:.0f} s)", flush=True)
    summary = _summarise(args, configs, runs, wrong, per_place)
    summary["runs"] = runs
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(summary, indent=1, default=str), encoding="utf-8")


if __name__ == "__main__":
    main()
