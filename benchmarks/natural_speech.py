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
import hashlib
import json
import os
import pickle
import subprocess
import sys
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from data_paths import SIGVERSE
from free_speech import fit_speech, new_home, read_names, settings_hyperparameters
from japanese import mean_interval
from split_seeds import SEEDS, refuse_other_seeds

from spco.data import Corpus, Environment
from spco.data.language import normalize_name
from spco.data.loading import load
from spco.data.sigverse import read_indexed_texts
from spco.evaluation import evaluate_answers
from spco.evaluation.experiments import trial_seed
from spco.model import SpCoTransfer, TransferHyperparameters

SIDES = {
    "development": {"knowledge": ("1LDK_1", "1LDK_3", "1LDK_5", "1LDK_7",
                                  "2LDK_1", "2LDK_3", "2LDK_5", "2LDK_7"),
                    "new": ("3LDK_9",), "seeds": SEEDS["development"]},
    "heldout": {"knowledge": ("1LDK_2", "1LDK_4", "1LDK_6", "1LDK_8",
                              "2LDK_2", "2LDK_4", "2LDK_6", "2LDK_8"),
                "new": ("1LDK_9", "2LDK_9", "3LDK_9"), "seeds": SEEDS["heldout"]},
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


def configurations(sigverse: Path, accepted: dict[str, tuple[str, ...]], leave_one_out: bool = False,
                   side: str = "development", subject: Path | None = None, regions: Path | None = None
                   ) -> tuple[list[Environment], list[tuple[str, list[Environment], Environment]]]:
    """The knowledge homes of ``side`` (taught with their subjects' sentences) and its (label, knowledge,
    new home) configurations: each new home with every knowledge home, then (``leave_one_out``, the
    development side) each knowledge home held out in turn, labelled ``"<home> (out)"``, untaught. A
    configuration's index in this list is its trial seed's (:func:`fitted`). ``subject`` and
    ``regions`` default to ``sigverse_subject`` and ``sigverse_regions.json`` beside ``sigverse``."""
    homes = SIDES[side]
    subject = subject or sigverse.parent / "sigverse_subject"
    regions = regions or sigverse.parent / "sigverse_regions.json"
    knowledge = [subject_home(sigverse, subject, h) for h in homes["knowledge"]]
    configs = [(h, knowledge, new_home(sigverse, regions, h, accepted)) for h in homes["new"]]
    if leave_one_out:
        for i, h in enumerate(homes["knowledge"]):
            env = untaught_subject_home(sigverse, h)
            env = replace(env, ground_truth=replace(env.ground_truth, accepted_names=accepted))
            configs.append((f"{h} (out)", knowledge[:i] + knowledge[i + 1:], env))
    return knowledge, configs


def place_speech(homes: list[Environment], corpus: Corpus) -> dict[str, Counter]:
    """place (normalised) -> Counter of tokens over the place's sentences, with the number of
    sentences under the key ``""``."""
    said: dict[str, Counter] = defaultdict(Counter)
    for env in homes:
        labels = env.ground_truth.labels  # type: ignore[union-attr]
        for label, sentence in zip(labels, env.sentences, strict=True):
            if label is None or sentence is None:
                continue
            place = normalize_name(label)
            said[place][""] += 1
            said[place].update(set(corpus.vocabulary.tokenize(sentence)))
    return said


def diagnosed(parser: argparse.ArgumentParser, diagnose: Callable[..., list[dict]], what: str
              ) -> tuple[argparse.Namespace, list[dict]]:
    """The loop of the diagnoses that read this script's fits (``nameless_answers.py``,
    ``other_place_answers.py``): ``parser`` (with :func:`fit_arguments`) gains ``--leave-one-out`` and
    ``--json`` and is parsed, seeds outside the development sets refused
    (:func:`split_seeds.refuse_other_seeds`); each seed's fit of each development configuration
    (:func:`fitted_runs`) gives ``diagnose(model, corpus, e, env, scored, seed, accepted, said, home)``
    its rows (``said``: :func:`place_speech` of the knowledge homes; ``home``: the configuration's
    home), with a line of progress naming ``what`` is counted. Returns the arguments and every row."""
    parser.add_argument("--leave-one-out", action="store_true")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    refuse_other_seeds(parser, args.seeds)
    accepted = read_names(args.accepted)
    knowledge, configs = configurations(args.sigverse, accepted, args.leave_one_out)
    labels = [c[0] for c in configs]
    rows: list[dict] = []
    fits = fitted_runs(configs, labels, args.seeds, settings=args.set, sweeps=args.sweeps, cache=args.cache)
    for seed, label, env, corpus, model, e, scored in fits:
        rows += diagnose(model, corpus, e, env, scored, seed, accepted, place_speech(knowledge, corpus),
                         label.split()[0])
        print(f"seed {seed} {label}: {len(rows)} {what} views so far", flush=True)
    return args, rows


def fit_arguments(parser: argparse.ArgumentParser, seeds: Sequence[int] = (0,), sweeps: int = 60,
                  cache: bool = True) -> argparse.ArgumentParser:
    """The options that choose (and, with ``cache``, keep) the fits: ``--sigverse``, ``--accepted``,
    ``--seeds`` (default ``seeds``), ``--sweeps`` (default ``sweeps``), ``--set`` and ``--cache``; for
    this script, ``speech_errors.py`` and the diagnoses that read its fits."""
    parser.add_argument("--sigverse", type=Path, default=SIGVERSE)
    parser.add_argument("--accepted", type=Path,
                        default=Path(__file__).resolve().parent / "development" / "accepted_names_dev.json")
    parser.add_argument("--seeds", type=int, nargs="+", default=list(seeds))
    parser.add_argument("--sweeps", type=int, default=sweeps)
    parser.add_argument("--set", nargs="+", action="extend", default=[], metavar="NAME=VALUE",
                        help="hyperparameters of the fit, as spco fit --set (development runs of the "
                        "ablation)")
    if cache:
        parser.add_argument("--cache", type=Path, default=None,
                            help="keep each fitted model here (pickled, keyed by the seed, the "
                            "configuration, the sweeps and --set) and read it back instead of fitting: the "
                            "answers (what is scored from a fit) can then be changed and measured again "
                            "without fitting; stale once the fit's code changes")
    return parser


#: Hyperparameters only the answers read, not the fit: a cached fit is read for them and they are set
#: on it, so the answers of one fit can be compared.
ANSWER_SETTINGS = frozenset({"name_answer"})


def _answer_only(setting: str) -> bool:
    """Whether the ``--set`` ``setting`` (NAME=VALUE) is read by the answers only (ANSWER_SETTINGS)."""
    return setting.partition("=")[0].strip() in ANSWER_SETTINGS


def _fit_settings(settings: Sequence[str]) -> list[str]:
    """The ``--set`` settings the fit reads (those not in :data:`ANSWER_SETTINGS`)."""
    return [s for s in settings if not _answer_only(s)]


def cache_path(cache: Path, settings: Sequence[str], sweeps: int, label: str, seed: int) -> Path:
    """Where ``--cache`` keeps the fit of the configuration ``label`` for ``seed`` with ``--set``
    ``settings`` (keyed by those the fit reads) and ``sweeps`` sweeps."""
    key = hashlib.sha256(repr((sorted(_fit_settings(settings)), sweeps)).encode()).hexdigest()[:12]
    return cache / f"{key}-{label.split()[0]}-s{seed}.pkl"


def answering(model: SpCoTransfer, settings: Sequence[str]) -> SpCoTransfer:
    """``model`` answering with the answer-only ``settings`` among ``settings`` (:data:`ANSWER_SETTINGS`;
    the defaults for those not given, whatever the fit was made or cached with)."""
    answer = [s for s in settings if _answer_only(s)]
    default = TransferHyperparameters()
    hyper = replace(model.hyperparameters_, **{k: getattr(default, k) for k in ANSWER_SETTINGS})
    model.hyperparameters_ = hyper.with_settings(answer) if answer else hyper
    model.__dict__.pop("_answers", None)
    return model


def fitted(corpus: Corpus, seed: int, label: str, labels: list[str], *, settings: Sequence[str] = (),
           sweeps: int, cache: Path | None = None) -> SpCoTransfer:
    """The fit (:func:`free_speech.fit_speech`) of the configuration ``label`` (its corpus) for
    ``seed``: the hyperparameters of ``--set`` ``settings`` (the model's own without any), the trial
    seed of ``seed`` and the configuration's index in ``labels``; read from ``cache`` when it holds it
    (:func:`cache_path`), and kept there once fitted; answering with the answer-only settings
    (:func:`answering`)."""
    path = None if cache is None else cache_path(cache, settings, sweeps, label, seed)
    if path is not None and path.exists():
        with open(path, "rb") as fh:
            return answering(pickle.load(fh), settings)
    model = fit_speech(corpus, settings_hyperparameters(_fit_settings(settings)), sweeps,
                       trial_seed(seed, labels.index(label)))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        with open(tmp, "wb") as fh:
            pickle.dump(model, fh)
        os.replace(tmp, path)
    return answering(model, settings)


def fitted_runs(configs: list[tuple], labels: list[str], seeds: Sequence[int], *,
                settings: Sequence[str] = (), sweeps: int, cache: Path | None = None) -> Iterator[tuple]:
    """Each seed's fit of each configuration (:func:`fitted`), in the seeds' and then the
    configurations' order: (seed, label, new home, corpus, model, the new home's index, what is scored —
    a knowledge home held out is scored on its training samples, :func:`scored_as_test`)."""
    for seed in seeds:
        for label, homes, env in configs:
            corpus = Corpus([*homes, env])
            model = fitted(corpus, seed, label, labels, settings=settings, sweeps=sweeps, cache=cache)
            scored = scored_as_test(env) if label.endswith("(out)") else env
            yield seed, label, env, corpus, model, len(corpus) - 1, scored


def _parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = fit_arguments(argparse.ArgumentParser(description=__doc__.splitlines()[0]), seeds=(0, 1, 2),
                           sweeps=200, cache=False)
    parser.add_argument("--subject", type=Path, default=None,
                        help="subject speech (default: sigverse_subject beside --sigverse)")
    parser.add_argument("--regions", type=Path, default=None,
                        help="region file (default: sigverse_regions.json beside --sigverse)")
    parser.add_argument("--side", choices=tuple(SIDES), default="development")
    parser.add_argument("--leave-one-out", action="store_true",
                        help="development: also hold each development home out of the knowledge in turn")
    parser.add_argument("--i-know-the-method-is-frozen", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--json", type=Path, default=None)
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
    refuse_other_seeds(parser, args.seeds, args.side)
    if args.side == "heldout" and not (frozen() or args.i_know_the_method_is_frozen):
        parser.error("the held-out configuration runs only on a frozen method (a commit whose message "
                     "starts with 'WORDS FROZEN:'), once; see benchmarks/SPLIT.md")
    if args.side == "heldout" and args.leave_one_out:
        parser.error("--leave-one-out is a development configuration")
    _, configs = configurations(args.sigverse, read_names(args.accepted), args.leave_one_out, args.side,
                                args.subject, args.regions)
    runs: list[dict] = []
    wrong: dict[str, Counter] = defaultdict(Counter)
    per_place: dict[tuple[str, str], list[float]] = defaultdict(list)
    started = time.perf_counter()
    labels = [c[0] for c in configs]
    for seed, label, env, _, model, e, scored in fitted_runs(configs, labels, args.seeds, settings=args.set,
                                                            sweeps=args.sweeps):
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
