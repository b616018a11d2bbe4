"""Free speech on SIGVerse: the paper's general experiment taught with sentences of a speech set.

Protocol (docs/model.md "What counts as a name"; benchmarks/README "Free speech on SIGVerse"):

- the paper's 16 experienced homes (:data:`~spco.evaluation.experiments.PAPER_EXPERIENCED_HOMES`)
  are taught every training sample, each with a sentence of the sample's ground-truth place drawn
  (with replacement) from the speech set, by seed: ``default_rng([seed, home index])``, so the
  speakers of one home are mixed;
- the new homes 1LDK_9, 2LDK_9 and 3LDK_9 are untaught, each fitted with the 16 (SpCoTransfer+MI,
  as ``spco experiment general --models spcotransfer+mi``, 200 sweeps, trial seed
  :func:`~spco.evaluation.experiments.trial_seed`) and scored on its test samples;
- A_n: a test view's predicted name is right when it is one of its place's accepted names
  (``--accepted``, a JSON object place -> names; keys starting with ``_`` are notes);
- A_p: for each place, the mean over the place's accepted names that the learnt vocabulary holds
  as one token (the place label itself only if it was said) of the share of 10 positions drawn for
  the name that fall inside the place's region (argmax region, as ``spco experiment``); A_p
  (mixture): the same with the positions drawn from the whole mixture p(x | name), the paper's
  text (``HomeScores.position_accuracy_mixture``); A_p (main name): argmax region, for the place's
  *main name* only, its accepted name said in most of the taught sentences (:func:`main_names`);
- names are answered as the robot answers them (:func:`spco.evaluation.evaluate_answers`: the
  model's view weight, its name weighting, the answer's parameters and the home's rooms), as
  ``spco experiment``;
- intervals: 95 % percentile bootstrap (2,000 resamples) over the test views (A_n; resampled within
  each home and place) and over the seeds' position scores of each (home, place) (A_p).

Run (development set, on the development home 3LDK_9 only: 1LDK_9 and 2LDK_9 are held-out homes,
benchmarks/SPLIT.md)::

    nice -n 10 python benchmarks/free_speech.py --speech benchmarks/development/speech_dev.csv \\
        --accepted benchmarks/development/accepted_names_dev.json --homes 3LDK_9 --seeds 0 1 2

The held-out set of the independent writer (seeds 100–109; ``benchmarks/heldout_report.py --parts
speech2`` runs it with the development set beside)::

    python benchmarks/free_speech.py --speech benchmarks/heldout/speech2/speech.csv \\
        --accepted benchmarks/heldout/speech2/accepted_names.json \\
        --unheard benchmarks/heldout/speech2/unheard_names.json \\
        --seeds 100 101 102 103 104 105 106 107 108 109

``--unheard FILE.json`` also measures ``where`` with names nobody said (A_p of the place found via
the lexicon, :func:`spco.model.unheard.resolve_name`; a refused query counts 0 and is counted in
``unheard_refused`` of ``unheard_queries``). A name of that list that a sentence of ``--speech`` says
is left out (``unheard_said_left_out``): never heard means never said by the speech taught.

``--view-counts N|none`` (a diagnostic) fits and predicts with that view weight instead of the
model's default (``TransferHyperparameters.view_counts``).

``--name-prior`` chooses how names are predicted: ``off`` (the default, as ``spco experiment``),
``wordnet`` (the opt-in ordering of each concept's words by the name prior,
``TransferHyperparameters.name_prior``) or ``both``: each fit scored both ways (only A_n can differ:
positions do not use the ordering); the figures of ``off`` are then the top-level ones and those
of ``wordnet`` are under ``name_prior_wordnet``. With ``off`` the script passes no ``name_prior``
argument, so it also runs on code from before the option (``PYTHONPATH=<other src>``).
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from data_paths import SIGVERSE

from spco.data import Corpus, Environment
from spco.data.language import normalize_name
from spco.data.loading import load
from spco.data.regions import load_region_file
from spco.evaluation import evaluate_answers
from spco.evaluation.experiments import PAPER_EXPERIENCED_HOMES, trial_seed
from spco.evaluation.metrics import position_accuracy
from spco.model import SpCoTransfer
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.position_prediction import predict_positions
from spco.model.prediction import UnknownNameError

NEW_HOMES = ("1LDK_9", "2LDK_9", "3LDK_9")


def read_speech(path: Path) -> dict[str, list[str]]:
    """place (normalised) -> its sentences, from a ``place,speaker,sentence`` CSV."""
    out: dict[str, list[str]] = defaultdict(list)
    with open(path, encoding="utf-8", newline="") as fh:
        for row in csv.DictReader(fh):
            out[normalize_name(row["place"])].append(row["sentence"])
    return dict(out)


def read_names(path: Path) -> dict[str, tuple[str, ...]]:
    """place (normalised) -> names (normalised), from a JSON object; ``_`` keys are notes."""
    raw = json.loads(Path(path).read_text(encoding="utf-8"))
    return {normalize_name(k): tuple(normalize_name(n) for n in v) for k, v in raw.items()
            if not k.startswith("_")}


def taught_homes(sigverse: Path, speech: dict[str, list[str]], seed: int) -> list[Environment]:
    """The 16 experienced homes, each taught sample given a sentence of its place drawn by seed."""
    homes = []
    for index, name in enumerate(PAPER_EXPERIENCED_HOMES):
        env = load(sigverse / name)[name]
        labels = env.ground_truth.labels  # type: ignore[union-attr]
        rng = np.random.default_rng([seed, index])
        sentences = []
        for label, old in zip(labels, env.sentences, strict=True):
            pool = speech.get(normalize_name(label)) if label is not None else None
            sentences.append(str(pool[rng.integers(len(pool))]) if old is not None and pool else None)
        homes.append(env.with_sentences(sentences))
    return homes


def new_home(sigverse: Path, regions_file: Path, name: str,
             accepted: dict[str, tuple[str, ...]]) -> Environment:
    """A new home, untaught, with its regions and the accepted names."""
    env = load(sigverse / name)[name]
    gt = env.ground_truth
    assert gt is not None
    regions = load_region_file(regions_file)[name]
    env = env.with_sentences((None,) * env.n_samples)
    return replace(env, ground_truth=replace(gt, regions=regions, accepted_names=accepted))


def bootstrap(groups: dict[tuple, list[float]], rng: np.random.Generator,
              n: int = 2000) -> tuple[float, float]:
    """95 % percentile interval of the mean over groups of the groups' means, each group resampled."""
    arrays = [np.asarray(v, dtype=float) for v in groups.values() if v]
    means = np.empty(n)
    for b in range(n):
        means[b] = np.mean([a[rng.integers(a.size, size=a.size)].mean() for a in arrays])
    return float(np.quantile(means, 0.025)), float(np.quantile(means, 0.975))


def _arguments() -> tuple[argparse.Namespace, Any]:
    """The command line, and the hyperparameters of ``--view-counts`` and ``--set`` (``None``: the
    model's)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sigverse", type=Path, default=SIGVERSE)
    parser.add_argument("--regions", type=Path, default=None,
                        help="region file (default: sigverse_regions.json beside --sigverse)")
    parser.add_argument("--speech", type=Path, required=True)
    parser.add_argument("--accepted", type=Path, required=True)
    parser.add_argument("--unheard", type=Path, default=None)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--sweeps", type=int, default=200)
    parser.add_argument("--homes", nargs="+", default=list(NEW_HOMES))
    parser.add_argument("--json", type=Path, default=None, help="write every figure to this file")
    parser.add_argument("--name-prior", choices=("off", "wordnet", "both"), default="off",
                        help="name prediction: off (default), the opt-in wordnet ordering, or both")
    parser.add_argument("--view-counts", default=None,
                        help="a diagnostic: the exact model's view weight (TransferHyperparameters."
                             "view_counts) in the fit and in prediction, a number or 'none' (every count "
                             "a draw); default: the model's default")
    parser.add_argument("--set", nargs="+", action="extend", default=[], metavar="NAME=VALUE",
                        help="hyperparameters of the fit (as spco fit --set), e.g. word_counts=none")
    args = parser.parse_args()
    from spco.errors import ConfigurationError

    hyper = None
    if args.view_counts is not None:
        text = args.view_counts.strip().lower()
        try:
            hyper = TransferHyperparameters(view_counts=None if text == "none" else float(text))
        except (ValueError, ConfigurationError):
            parser.error(f"--view-counts: a positive number or 'none', got {args.view_counts!r}")
    try:
        hyper = settings_hyperparameters(args.set, hyper)
    except ConfigurationError as exc:
        parser.error(f"--set: {exc}")
    return args, hyper


@dataclass
class _Tally:
    """The figures over seeds, per name-prior setting where the setting matters; keys (home, place)."""

    settings: list[str]
    names_right: dict[str, dict[tuple, list[float]]] = field(init=False)  # 0/1 per test view
    wrong: dict[str, Counter] = field(init=False)  # the wrong names
    main_positions: dict[tuple, list[float]] = field(  # the main name's A_p
        default_factory=lambda: defaultdict(list))
    positions: dict[tuple, list[float]] = field(default_factory=lambda: defaultdict(list))  # A_p per seed
    positions_mixture: dict[tuple, list[float]] = field(  # the same, drawn from p(x | name)
        default_factory=lambda: defaultdict(list))
    unheard_scores: dict[tuple, list[float]] = field(default_factory=lambda: defaultdict(list))
    resolved_as: dict[str, Counter] = field(default_factory=lambda: defaultdict(Counter))
    per_seed: list[dict[str, Any]] = field(default_factory=list)
    unheard_seeds: dict[int, float] = field(default_factory=dict)  # seed -> mean of its unheard A_p

    def __post_init__(self) -> None:
        self.names_right = {s: defaultdict(list) for s in self.settings}
        self.wrong = {s: Counter() for s in self.settings}


def settings_hyperparameters(settings: Sequence[str], hyper: TransferHyperparameters | None = None
                             ) -> TransferHyperparameters | None:
    """The hyperparameters of ``--set NAME=VALUE ...`` (as ``spco fit --set``) over ``hyper`` (default:
    the model's own); without settings ``hyper`` itself (``None``: the model's own)."""
    if not settings:
        return hyper
    return (hyper or TransferHyperparameters()).with_settings(list(settings))


def fit_speech(corpus: Corpus, hyper: Any, sweeps: int, random_state: int) -> SpCoTransfer:
    """The fit the speech benchmarks score: SpCoTransfer+MI (the exact variant, words pruned by their
    mutual information) of ``corpus`` (the new home last) for ``sweeps`` sweeps."""
    return SpCoTransfer(hyper, variant="exact", prune_words=True, n_iterations=sweeps,
                        random_state=random_state).fit(corpus)


def fit_new_home(experienced: list[Environment], env: Environment, hyper: Any, sweeps: int, seed: int,
                 h: int) -> tuple[SpCoTransfer, Corpus]:
    """The fit this script scores (:func:`fit_speech`) of the experienced homes and the new home
    ``env`` (the last home of the returned corpus), ``sweeps`` sweeps, the trial seed of ``seed`` and
    the new home's index ``h``."""
    corpus = Corpus([*experienced, env])
    return fit_speech(corpus, hyper, sweeps, trial_seed(seed, h)), corpus


def _score_home(tally: _Tally, args: argparse.Namespace, hyper: Any, seed: int, h: int, home: str,
                experienced: list[Environment], env: Environment, accepted: dict[str, tuple[str, ...]],
                unheard: dict[str, tuple[str, ...]], seed_unheard: dict[tuple, list[float]],
                started: float) -> None:
    """Fit the new home ``env`` with the experienced homes; its names, positions, main names' and
    unheard names' positions into ``tally``."""
    model, corpus = fit_new_home(experienced, env, hyper, args.sweeps, seed, h)
    e = len(corpus) - 1
    gt = env.ground_truth
    for setting in tally.settings:  # the same draws of positions: only the names can differ
        # as the robot answers (the answer's parameters, rooms, weighting and view weight)
        scores = evaluate_answers(model, e, env, rng=seed, name_prior=setting)
        tally.per_seed.append({"seed": seed, "home": home, "name_prior": setting,
                               "A_n": scores.mean_name_accuracy, "A_p": scores.mean_position_accuracy,
                               "A_n_places": scores.name_accuracy, "A_p_places": scores.position_accuracy})
        for label, name in zip(scores.labels, scores.predicted_names, strict=True):
            right = name in gt.accepted(label)  # type: ignore[union-attr]
            tally.names_right[setting][(home, label)].append(float(right))
            if not right:
                tally.wrong[setting][f"{label} -> {name}"] += 1
        print(f"seed {seed} {home} name prior {setting}: A_n {scores.mean_name_accuracy:.3f} "
              f"A_p {scores.mean_position_accuracy:.3f} ({time.perf_counter() - started:.0f} s)",
              flush=True)
    for place, value in scores.position_accuracy.items():
        tally.positions[(home, place)].append(value)
    for place, value in getattr(scores, "position_accuracy_mixture", {}).items():
        tally.positions_mixture[(home, place)].append(value)
    answer, rooms, _ = model.answer_inputs(e)
    for place, name in main_names(experienced, accepted).items():  # A_p of the main name
        if place in gt.regions.places:  # type: ignore[union-attr]
            try:
                pred = predict_positions(answer, e, corpus.vocabulary, name, n=10, rng=seed,
                                         rooms=rooms, view_counts=model.settings_.view_counts,
                                         lookup=model.parameters_.word_mask)
                hit = position_accuracy({place: pred.samples}, gt.regions)[place]  # type: ignore
            except UnknownNameError:
                hit = 0.0
            tally.main_positions[(home, place)].append(hit)
    if unheard:
        _score_unheard(model.parameters_, e, corpus.vocabulary, env, unheard, seed, seed_unheard,
                       tally.resolved_as)


def _summary(args: argparse.Namespace, tally: _Tally, unheard: bool) -> dict[str, object]:
    """The pooled figures with 95 % intervals over (home, place) groups, and every run."""
    settings, names_right, wrong = tally.settings, tally.names_right, tally.wrong
    positions, positions_mixture = tally.positions, tally.positions_mixture
    main_positions = tally.main_positions
    rng = np.random.default_rng(0)
    first = settings[0]
    a_n = float(np.mean([np.mean(v) for v in names_right[first].values()]))
    a_p = float(np.mean([np.mean(v) for v in positions.values()]))
    summary: dict[str, object] = {
        "seeds": args.seeds, "homes": args.homes, "speech": str(args.speech), "accepted": str(args.accepted),
        "name_prior": first,
        "A_n": a_n, "A_n_interval": bootstrap(names_right[first], rng),
        "A_p": a_p, "A_p_interval": bootstrap(positions, rng),
        **({"A_p_mixture": float(np.mean([np.mean(v) for v in positions_mixture.values()])),
            "A_p_mixture_interval": bootstrap(positions_mixture, rng),
            "A_p_mixture_per_place": _per_place(positions_mixture)} if positions_mixture else {}),
        "A_p_main_name": float(np.mean([np.mean(v) for v in main_positions.values()])),
        "A_p_main_name_interval": bootstrap(main_positions, rng),
        "A_n_per_place": _per_place(names_right[first]), "A_p_per_place": _per_place(positions),
        "A_p_main_name_per_place": _per_place(main_positions),
        "wrong": dict(wrong[first].most_common(25)), "runs": tally.per_seed,
    }
    for setting in settings[1:]:  # the other way of predicting names, from the same fits
        summary[f"name_prior_{setting}"] = {
            "A_n": float(np.mean([np.mean(v) for v in names_right[setting].values()])),
            "A_n_interval": bootstrap(names_right[setting], np.random.default_rng(0)),
            "A_n_per_place": _per_place(names_right[setting]),
            "wrong": dict(wrong[setting].most_common(25))}
    if unheard:
        summary["unheard_A_p"] = float(np.mean([np.mean(v) for v in tally.unheard_scores.values()]))
        summary["unheard_A_p_interval"] = bootstrap(tally.unheard_scores, rng)
        summary["unheard_A_p_per_place"] = _per_place(tally.unheard_scores)
        summary["unheard_A_p_seeds"] = tally.unheard_seeds
        summary["unheard_resolved_as"] = {k: dict(v) for k, v in tally.resolved_as.items()}
    return summary


def main() -> None:
    """Fit, score and print per seed, home and place, then the pooled figures with intervals."""
    args, hyper = _arguments()
    settings = ["off", "wordnet"] if args.name_prior == "both" else [args.name_prior]
    regions_file = args.regions or args.sigverse.parent / "sigverse_regions.json"
    speech = read_speech(args.speech)
    accepted = read_names(args.accepted)
    unheard = read_names(args.unheard) if args.unheard else {}
    unheard, said_unheard = never_heard(unheard, speech)
    if said_unheard:
        print(f"left out of the unheard names (said by {args.speech.name}): {', '.join(said_unheard)}")
    tally = _Tally(settings)
    started = time.perf_counter()
    for seed in args.seeds:
        experienced = taught_homes(args.sigverse, speech, seed)
        seed_unheard: dict[tuple, list[float]] = defaultdict(list)
        for h, home in enumerate(args.homes):
            env = new_home(args.sigverse, regions_file, home, accepted)
            _score_home(tally, args, hyper, seed, h, home, experienced, env, accepted, unheard, seed_unheard,
                        started)
        for key, values in seed_unheard.items():
            tally.unheard_scores[key].extend(values)
        if seed_unheard:
            tally.unheard_seeds[seed] = float(np.mean([np.mean(v) for v in seed_unheard.values()]))
    summary = _summary(args, tally, bool(unheard))
    if unheard:
        summary["unheard_refused"] = int(sum(v.get("(none)", 0) for v in tally.resolved_as.values()))
        summary["unheard_queries"] = int(sum(sum(v.values()) for v in tally.resolved_as.values()))
        summary["unheard_said_left_out"] = said_unheard
    print(json.dumps({k: v for k, v in summary.items() if k != "runs"}, indent=1, default=str))
    if args.json:
        args.json.write_text(json.dumps(summary, indent=1, default=str), encoding="utf-8")


def never_heard(unheard: dict[str, tuple[str, ...]], speech: dict[str, list[str]]
                ) -> tuple[dict[str, tuple[str, ...]], list[str]]:
    """The unheard names that no sentence of the teaching speech says (as whole tokens after
    :func:`~spco.data.language.normalize_name`, the check of tests/test_unheard_lists.py), and the
    names left out because a sentence says them: a name never heard is one the speech it is scored
    with never says."""
    said = [f" {normalize_name(s)} " for sentences in speech.values() for s in sentences]
    kept: dict[str, tuple[str, ...]] = {}
    left_out: list[str] = []
    for place, names in unheard.items():
        heard = [n for n in names if any(f" {n} " in sentence for sentence in said)]
        left_out += heard
        kept[place] = tuple(n for n in names if n not in heard)
    return kept, left_out


def main_names(homes: list[Environment], accepted: dict[str, tuple[str, ...]]) -> dict[str, str]:
    """Each place's main name: its accepted name said in most taught sentences of ``homes`` (as a
    whole token after :func:`~spco.data.language.tokenize`-style normalisation of the sentence)."""
    counts: dict[str, Counter] = defaultdict(Counter)
    for env in homes:
        for label, sentence in zip(env.ground_truth.labels, env.sentences, strict=True):  # type: ignore[union-attr]
            if sentence is None or label is None:
                continue
            text = f" {' '.join(normalize_name(sentence).split())} "
            place = normalize_name(label)
            for name in accepted.get(place, ()):
                if f" {name} " in text:
                    counts[place][name] += 1
    return {place: c.most_common(1)[0][0] for place, c in counts.items() if c}


def _per_place(groups: dict[tuple, list[float]]) -> dict[str, float]:
    by_place: dict[str, list[float]] = defaultdict(list)
    for key, values in groups.items():
        by_place[key[1]].append(float(np.mean(values)))
    return {p: round(float(np.mean(v)), 3) for p, v in sorted(by_place.items())}


def _score_unheard(params, e, vocabulary, env, unheard, seed, out, resolved_as) -> None:
    """A_p of ``where`` for every unheard name of the home's places (through the lexicon)."""
    regions = env.ground_truth.regions
    for place, names in unheard.items():
        if place not in regions.places:
            continue
        for name in names:
            try:
                pred = predict_positions(params, e, vocabulary, name, n=10, rng=seed, unheard=True)
            except UnknownNameError:
                out[(env.name, place)].append(0.0)
                resolved_as[name]["(none)"] += 1
                continue
            value = position_accuracy({place: pred.samples}, regions)[place]
            out[(env.name, place)].append(value)
            resolved_as[name][pred.name] += 1


if __name__ == "__main__":
    main()
