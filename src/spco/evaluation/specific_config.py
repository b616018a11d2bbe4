"""The home-specific experiment on a configuration file: personal room names in any home.

The paper's home-specific experiment has one home (3LDK_9) and the sentences its authors recorded.
A *configuration file* (``benchmarks/heldout/specific_heldout.json``,
``benchmarks/development/specific_dev.json``; format ``heldout-specific/1``, documented in the
file's own ``_schema``) describes others: for each configuration a new home, the rooms that get a
personal name ("kenta's room", "the piano room"), their train and test sample ids, the phrases
accepted as each room's name, teaching templates, teaching rates and seeds.

One *run* is (configuration, rate, seed, model):

1. **Teaching.** The taught samples and their sentences are drawn as the file's ``selection_rule``
   says: ``rng = numpy.random.default_rng(seed)``; for each room in the listed order
   ``rng.choice(train_ids, size=k, replace=False)``, then for each drawn id in that order a
   template index ``rng.integers(len(pool))``, ``pool`` = the templates (+ the possessive ones for
   a room with an owner). ``k`` is the room's ``taught_count`` at the rate. Nothing else in the
   new home is taught (its own ``sentence/`` folders are not used); the experienced homes are
   taught at rate 100 with their own sentences.
2. **Split.** The rooms' test ids are test samples (never learnt from). With ``test_source``
   ``"defined-here"`` they are made test samples here; otherwise they must already be test samples
   of the home's published list.
3. **Vocabulary, per run.** The words of the experienced homes' sentences and of the sentences
   taught in this run (:meth:`~spco.data.language.Vocabulary.from_sentences`): a run at 20 % has
   no column for a word taught only at 100 %, or by another seed's draw.
4. **Model.** A model of :data:`~spco.evaluation.experiments.MODELS` learns the experienced homes
   (the configuration's list, default the file's) and the new home, last (SpCoA: the new home
   alone), with ``random_state = trial_seed(seed, 0)``.
5. **Scores** (:func:`score_rooms`). A_n of a room: the share of its test samples whose predicted
   name (the top word of :func:`~spco.model.prediction.predict_names`, with the model's weighting) is
   one of the room's accepted phrases after :func:`normalize_phrase`. A_p of a room with a region:
   the share of positions drawn for the room's name (``where <name>``) inside the region, both
   ways: ``argmax`` — all from the most probable region's Gaussian (as the authors' code), and
   ``mixture`` — each from a region drawn from p(region | name), i.e. from the whole mixture
   p(x | name) (as the paper's text describes it).

Summaries (:func:`summarise`): per configuration, room, rate and model the mean A_n over seeds with a
95 % bootstrap interval over seeds and test samples (each resample draws the seeds and, apart, the
room's test samples; 2,000 resamples, fixed seed); means over a configuration's rooms and over every
room of the file (each room counts once) with an interval that resamples the rooms as well; A_p
means (both ways) over seeds.

Output folder: ``config.json`` (what was run, with a fingerprint), ``runs.jsonl`` (one line per run,
appended as it finishes: ``--resume`` continues), ``results.json`` (format
:data:`RESULTS_FORMAT`, version :data:`RESULTS_VERSION`: ``config``, ``runs``, ``summary``,
``overall``) and ``tables.md``. Every file is written atomically.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import multiprocessing
import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.environment import Corpus, Environment, make_ground_truth
from spco.data.language import Vocabulary
from spco.data.regions import PlaceRegions
from spco.errors import ConfigurationError, DataFormatError
from spco.evaluation.specific_file import (
    CONFIG_FORMAT,
    Room,
    SpecificConfigFile,
    SpecificConfiguration,
    load_specific_config,
    normalize_phrase,
    taught_count,
    teaching_sentences,
)
from spco.model.answer_settings import AnswerSettings

__all__ = [
    "CONFIG_FORMAT",
    "RESULTS_FORMAT",
    "RESULTS_VERSION",
    "ConfiguredData",
    "ConfiguredRun",
    "Room",
    "RoomScores",
    "SpecificConfigFile",
    "SpecificConfiguration",
    "bootstrap_interval",
    "execute_configured_run",
    "load_specific_config",
    "normalize_phrase",
    "run_specific_config",
    "score_rooms",
    "summarise",
    "taught_count",
    "teaching_sentences",
]

RESULTS_FORMAT = "spco-specific-config-results"
RESULTS_VERSION = 1
#: Bootstrap resamples and level of the intervals.
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_LEVEL = 0.95
#: Positions drawn per room and run for A_p.
DEFAULT_POSITIONS = 20
#: A_p modes: all positions from the most probable region; each from a region drawn from p(m | name).
POSITION_MODES = ("argmax", "mixture")

_CONFIG_FILE = "config.json"
_RUNS_FILE = "runs.jsonl"
_RESULTS_FILE = "results.json"
_TABLES_FILE = "tables.md"


# ------------------------------------------------------------------------------------ the homes
@dataclass
class ConfiguredData:
    """The homes of a configuration file, read once: experienced homes taught at rate 100 and the
    configurations' new homes untaught, checked against the file's ids.

    Parameters
    ----------
    file: the configuration file.
    source: the data set (a SIGVerse folder, a folder of homes, an ``spco import`` cache).
    configurations: the configurations to run (default: all).
    """

    file: SpecificConfigFile
    source: str
    configurations: tuple[SpecificConfiguration, ...] = ()
    _experienced: dict[str, Environment] = field(default_factory=dict, repr=False)
    _new: dict[str, Environment] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        from spco.data.loading import read_records

        if not self.configurations:
            self.configurations = self.file.configurations
        experienced = list(dict.fromkeys(h for c in self.configurations for h in c.experienced_homes))
        new = list(dict.fromkeys(c.home for c in self.configurations))
        names = list(dict.fromkeys([*experienced, *new]))
        records = dict(zip(names, read_records(self.source, names=names), strict=True))
        for name in experienced:
            self._experienced[name] = records[name].at_rate(100)
        for name in new:
            self._new[name] = records[name].at_rate(0)
        for conf in self.configurations:
            self._check(conf)

    def _check(self, conf: SpecificConfiguration) -> None:
        env = self._new[conf.home]
        where = env.source or self.source
        rows = {int(i): r for r, i in enumerate(env.ids)}
        index = next(i for i, c in enumerate(self.file.configurations) if c.id == conf.id)
        for j, room in enumerate(conf.rooms):
            field_of = f"configs[{index}].rooms[{j}]"
            for kind, ids in (("train_ids", room.train_ids), ("test_ids", room.test_ids)):
                missing = [i for i in ids if i not in rows]
                if missing:
                    raise DataFormatError(self.file.path, f"{field_of}.{kind}: home {conf.home!r} "
                                          f"({where}) has no sample {missing[0]}")
            in_test = [i for i in room.train_ids if env.is_test[rows[i]]]
            if in_test:
                raise DataFormatError(self.file.path, f"{field_of}.train_ids: {in_test[0]} is a test "
                                      f"sample of home {conf.home!r} ({where})")
            if conf.test_source != "defined-here":
                not_test = [i for i in room.test_ids if not env.is_test[rows[i]]]
                if not_test:
                    raise DataFormatError(self.file.path, f"{field_of}.test_ids: {not_test[0]} is not a "
                                          f"test sample of home {conf.home!r} ({where}); with "
                                          f"test_source {conf.test_source!r} the ids must be its "
                                          "published test samples")

    def experienced(self, conf: SpecificConfiguration) -> list[Environment]:
        """The configuration's experienced homes, taught at rate 100, in order."""
        return [self._experienced[h] for h in conf.experienced_homes]

    def new_home(self, conf: SpecificConfiguration, sentences: Mapping[int, str]) -> Environment:
        """The configuration's new home: the rooms' test ids are test samples, ``sentences`` (id ->
        sentence) the only taught sentences; the ground truth holds the rooms' labels and test
        samples (``specific_labels``, ``specific_test``), their regions and accepted names."""
        env = self._new[conf.home]
        rows = {int(i): r for r, i in enumerate(env.ids)}
        is_test = np.array(env.is_test, dtype=bool)
        taught: list[str | None] = [None] * env.n_samples
        for sid, sentence in sentences.items():
            taught[rows[sid]] = sentence
        labels: list[str | None] = [None] * env.n_samples
        scored = np.zeros(env.n_samples, dtype=bool)
        places: dict[str, tuple] = {}
        for room in conf.rooms:
            for sid in room.test_ids:
                is_test[rows[sid]] = True
                scored[rows[sid]] = True
                labels[rows[sid]] = room.name
            for sid in room.train_ids:
                labels[rows[sid]] = room.name
            if room.region is not None:
                places.update(room.region.places)
        gt = env.ground_truth
        truth = make_ground_truth(labels=None if gt is None else gt.labels, specific_labels=labels,
                                  specific_test=scored, regions=PlaceRegions(places) if places else None,
                                  accepted_names={r.name: r.accepted for r in conf.rooms})
        return replace(env, sentences=tuple(taught), is_test=is_test, ground_truth=truth)


# ------------------------------------------------------------------------------------ scoring
@dataclass(frozen=True)
class RoomScores:
    """One room's result in one run.

    Attributes
    ----------
    correct: (T,) bool, the room's test samples in the file's order: predicted name accepted.
    predicted: (T,) the predicted name of each test sample (``None``: no word survived).
    position_accuracy: mode (``argmax``, ``mixture``) -> A_p, or ``None`` (no region).
    """

    correct: np.ndarray
    predicted: tuple[str | None, ...]
    position_accuracy: dict[str, float | None]

    @property
    def name_accuracy(self) -> float:
        """A_n: the share of test samples named right."""
        return float(np.mean(self.correct))


def score_rooms(params: Any, e: int, env: Environment, vocabulary: Vocabulary,
                rooms: Sequence[Room], weighting: str = "mi", n_positions: int = DEFAULT_POSITIONS,
                rng: np.random.Generator | int | None = None,
                view_counts: float | None = None,
                answer_params: Any = None, answer_rooms: Any = None,
                settings: AnswerSettings | None = None) -> dict[str, RoomScores]:
    """A_n and A_p (both ways) of each room in home ``e`` of a fitted model.

    Parameters
    ----------
    params: the model's :class:`~spco.model.parameters.ConceptParameters`.
    e: the index of ``env`` among the model's homes; env: the new home (its ids locate the rooms'
        test samples).
    vocabulary: the model's vocabulary; rooms: the rooms to score.
    weighting: name weighting of :func:`~spco.model.prediction.predict_names`.
    n_positions: positions drawn per room and mode; rng: Generator or seed of the draws.
    view_counts: the model's view weight w (``model.settings_.view_counts``).
    answer_params: the parameters the robot answers names with
        (:func:`spco.model.confidence.model_answer_parameters`; ``None``: ``params``); names come
        from the robot's own function, :func:`spco.model.confidence.answer_names`.
    answer_rooms: the home's rooms as the robot's answer reads them
        (:func:`spco.model.rooms.model_rooms`; ``None``: names from each sample's own view and pose).
    settings: the model's answer settings
        (:meth:`~spco.model.hyperparameters.TransferHyperparameters.answer_settings`; ``None``: the
        defaults).

    Returns
    -------
    room name -> :class:`RoomScores`. A room whose name has no usable word gets A_p 0.
    """
    from spco.model.confidence import answer_names
    from spco.model.position_prediction import predict_positions
    from spco.model.prediction import UnknownNameError

    rows = {int(i): r for r, i in enumerate(env.ids)}
    gen = np.random.default_rng(rng)
    out: dict[str, RoomScores] = {}
    for room in rooms:
        test = np.array([rows[i] for i in room.test_ids], dtype=np.int64)
        prediction = answer_names(params if answer_params is None else answer_params, e, vocabulary,
                                  env.positions[test], env.visual[test], top_k=1,
                                  weighting=weighting,  # type: ignore[arg-type]
                                  view_counts=view_counts, rooms=answer_rooms,
                                  settings=AnswerSettings() if settings is None else settings)
        predicted = tuple(str(w) for w in prediction.words[:, 0]) if prediction.words.shape[1] else \
            (None,) * test.size
        correct = np.array([room.is_accepted(w) for w in predicted], dtype=bool)
        positions: dict[str, float | None] = {}
        for mode in POSITION_MODES:
            if room.region is None:
                positions[mode] = None
                continue
            try:
                # the robot's where: its answer's parameters and rooms (as evaluate_home)
                pred = predict_positions(params if answer_params is None else answer_params, e, vocabulary,
                                         room.name, n=n_positions, rng=gen, mode=mode,  # type: ignore[arg-type]
                                         rooms=answer_rooms, view_counts=view_counts, lookup=params.word_mask)
            except UnknownNameError:
                positions[mode] = 0.0
                continue
            positions[mode] = float(room.region.contains(room.name, pred.samples[:, :2]).mean())
        out[room.name] = RoomScores(correct, predicted, positions)
    return out


# ------------------------------------------------------------------------------------ runs
@dataclass(frozen=True, order=True)
class ConfiguredRun:
    """One run: a model fitted for one configuration, teaching rate and seed."""

    configuration: str
    rate: int
    seed: int
    model: str


def _vocabulary(homes: Iterable[Environment]) -> Vocabulary:
    return Vocabulary.from_sentences(s for env in homes for s in env.training_data().sentences)


def execute_configured_run(data: ConfiguredData, key: ConfiguredRun, iterations: int, n_positions: int,
                           fingerprint: str = "", hyperparameters: Any = None) -> dict[str, Any]:
    """Fit and score one run; returns its record (a line of ``runs.jsonl``). ``hyperparameters``: the
    transfer models' (``TransferHyperparameters``; ``None``: the model's defaults)."""
    from spco.evaluation.config import trial_seed
    from spco.evaluation.models import MODELS

    start = time.perf_counter()
    conf = data.file.configuration(key.configuration)
    sentences = teaching_sentences(data.file, conf, key.rate, key.seed)
    new = data.new_home(conf, sentences)
    experienced = data.experienced(conf)
    homes = [*experienced, new]
    vocabulary = _vocabulary(homes)  # per run: this rate's (and draw's) sentences only
    spec = MODELS[key.model]
    random_state = trial_seed(key.seed, 0)
    model = spec.build(iterations, random_state, hyperparameters, False)
    corpus = Corpus([new] if spec.single_home else homes, vocabulary=vocabulary)
    model.fit(corpus)
    e = len(corpus) - 1
    answer_params, answer_rooms, weighting = model.answer_inputs(e)  # what the robot answers with
    scores = score_rooms(model.parameters_, e, new, model.vocabulary_, conf.rooms, weighting,  # type: ignore[arg-type]
                         n_positions, np.random.default_rng([key.seed, 1]), model.settings_.view_counts,
                         answer_params, answer_rooms, settings=model.hyperparameters_.answer_settings())
    return {
        "fingerprint": fingerprint,
        "configuration": key.configuration,
        "home": conf.home,
        "rate": key.rate,
        "seed": key.seed,
        "model": key.model,
        "random_state": random_state,
        "iterations": iterations,
        "taught": len(sentences),
        "vocabulary_size": len(vocabulary),
        "wall_seconds": round(time.perf_counter() - start, 3),
        "rooms": {name: {"correct": [int(c) for c in s.correct], "predicted": list(s.predicted),
                         "name_accuracy": round(s.name_accuracy, 6),
                         "position_accuracy": s.position_accuracy}
                  for name, s in scores.items()},
    }


# -------------------------------------------------------------------------- worker processes
_WORKER: tuple[ConfiguredData, int, int, str, Any] | None = None


def _init_worker(file: SpecificConfigFile, source: str, names: tuple[str, ...], iterations: int,
                 n_positions: int, fingerprint: str, hyperparameters: Any = None) -> None:
    global _WORKER
    with contextlib.suppress(Exception):  # numba may lack a threading layer; runs still work
        import numba

        numba.set_num_threads(1)
    data = ConfiguredData(file, source, file.select(names))
    _WORKER = (data, iterations, n_positions, fingerprint, hyperparameters)


def _worker_run(key: ConfiguredRun) -> dict[str, Any]:
    if _WORKER is None:  # pragma: no cover - the initializer always runs first
        raise RuntimeError("worker not initialised")
    data, iterations, n_positions, fingerprint, hyperparameters = _WORKER
    return execute_configured_run(data, key, iterations, n_positions, fingerprint, hyperparameters)


# ------------------------------------------------------------------------------------ summary
def bootstrap_interval(per_room: Sequence[np.ndarray], resamples: int = BOOTSTRAP_RESAMPLES,
                       level: float = BOOTSTRAP_LEVEL, seed: int = 0,
                       rooms: bool = False) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean over rooms of each room's mean accuracy, over seeds
    **and** test samples (and rooms, with ``rooms``).

    Parameters
    ----------
    per_room: one array per room of each test sample's accuracy, (S_r, T_r) — one row per seed —
        or (T_r,) for one seed. A resample draws the room's seeds with replacement and, apart, its
        test samples (so a seed at 0.00 widens the interval instead of being averaged away).
    resamples, level, seed: number of resamples, coverage, and the seed of the resampling.
    rooms: also resample the rooms (for a mean over rooms: the rooms are a sample too).

    Returns
    -------
    (low, high); without ``rooms`` every room weighs the same in the mean.
    """
    rng = np.random.default_rng(seed)
    arrays = [np.atleast_2d(np.asarray(v, dtype=np.float64)) for v in per_room]
    means = np.zeros((resamples, len(arrays)))
    for r, a in enumerate(arrays):
        n_seeds, n_samples = a.shape
        by_seed = a[:, rng.integers(0, n_samples, size=(resamples, n_samples))].mean(axis=2)  # (S, B)
        chosen = rng.integers(0, n_seeds, size=(resamples, n_seeds))
        means[:, r] = np.take_along_axis(by_seed.T, chosen, axis=1).mean(axis=1)
    if rooms and len(arrays) > 1:
        picked = rng.integers(0, len(arrays), size=(resamples, len(arrays)))
        total = np.take_along_axis(means, picked, axis=1).mean(axis=1)
    else:
        total = means.mean(axis=1) if arrays else np.zeros(resamples)
    tail = (1.0 - level) / 2.0
    return float(np.quantile(total, tail)), float(np.quantile(total, 1.0 - tail))


def _mean(values: Iterable[float | None]) -> float | None:
    kept = [v for v in values if v is not None]
    return float(np.mean(kept)) if kept else None


def summarise(records: Sequence[Mapping[str, Any]], file: SpecificConfigFile) -> dict[str, Any]:
    """Per configuration, rate and model: each room's mean A_n over seeds with its bootstrap
    interval, A_p both ways, and the configuration's mean; ``overall``: every room of the file.

    Returns ``{"summary": [...], "overall": [...]}`` (see :func:`run_specific_config`)."""
    groups: dict[tuple[str, int, str], list[Mapping[str, Any]]] = {}
    for rec in records:
        groups.setdefault((rec["configuration"], int(rec["rate"]), rec["model"]), []).append(rec)
    order = {c.id: i for i, c in enumerate(file.configurations)}
    summary = []
    pooled: dict[tuple[int, str], list[tuple[np.ndarray, dict[str, Any]]]] = {}
    for (cid, rate, model), recs in sorted(groups.items(), key=lambda kv: (order.get(kv[0][0], 0),
                                                                           kv[0][1], kv[0][2])):
        recs = sorted(recs, key=lambda r: r["seed"])
        conf = file.configuration(cid)
        rooms = []
        samples = []
        for room in conf.rooms:
            correct = np.array([r["rooms"][room.name]["correct"] for r in recs], dtype=np.float64)
            per_sample = correct.mean(axis=0)
            samples.append(correct)
            per_seed = correct.mean(axis=1)
            low, high = bootstrap_interval([correct])
            row = {
                "room": room.name, "form": room.form, "replaces": room.replaces,
                "name_accuracy": float(per_sample.mean()), "interval": [low, high],
                "seed_std": float(per_seed.std(ddof=1)) if per_seed.size > 1 else None,
                "seed_min": float(per_seed.min()),
                "position_accuracy": {m: _mean(r["rooms"][room.name]["position_accuracy"][m] for r in recs)
                                      for m in POSITION_MODES},
                "n_test": int(per_sample.size),
            }
            rooms.append(row)
            pooled.setdefault((rate, model), []).append((correct, row))
        low, high = bootstrap_interval(samples, rooms=True)
        summary.append({
            "configuration": cid, "home": conf.home, "rate": rate, "model": model, "seeds": len(recs),
            "seed_list": [int(r["seed"]) for r in recs],
            "mean_name_accuracy": float(np.mean([r["name_accuracy"] for r in rooms])),
            "interval": [low, high],
            "mean_position_accuracy": {m: _mean(r["position_accuracy"][m] for r in rooms)
                                       for m in POSITION_MODES},
            "rooms": rooms,
        })
    overall = []
    for (rate, model), items in sorted(pooled.items()):
        low, high = bootstrap_interval([s for s, _ in items], rooms=True)
        rows = [row for _, row in items]
        overall.append({
            "rate": rate, "model": model, "rooms": len(rows),
            "mean_name_accuracy": float(np.mean([r["name_accuracy"] for r in rows])),
            "interval": [low, high],
            "min_room_name_accuracy": float(min(r["name_accuracy"] for r in rows)),
            "mean_position_accuracy": {m: _mean(r["position_accuracy"][m] for r in rows)
                                       for m in POSITION_MODES},
        })
    return {"summary": summary, "overall": overall}


def _f(value: float | None, digits: int = 3) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def tables(results: Mapping[str, Any]) -> str:
    """Markdown tables of a results mapping (per room and overall)."""
    lines = ["| configuration | room | rate | model | seeds | A_n | 95 % interval | worst seed | "
             "A_p (argmax) | A_p (mixture) |", "|---|---|---:|---|---:|---:|---|---:|---:|---:|"]
    for group in results["summary"]:
        for row in group["rooms"]:
            lo, hi = row["interval"]
            lines.append(f"| {group['configuration']} | {row['room']} | {group['rate']} | {group['model']} | "
                         f"{group['seeds']} | {_f(row['name_accuracy'])} | {_f(lo)}–{_f(hi)} | "
                         f"{_f(row['seed_min'])} | {_f(row['position_accuracy']['argmax'])} | "
                         f"{_f(row['position_accuracy']['mixture'])} |")
        lo, hi = group["interval"]
        lines.append(f"| {group['configuration']} | **mean** | {group['rate']} | {group['model']} | "
                     f"{group['seeds']} | **{_f(group['mean_name_accuracy'])}** | {_f(lo)}–{_f(hi)} | | "
                     f"{_f(group['mean_position_accuracy']['argmax'])} | "
                     f"{_f(group['mean_position_accuracy']['mixture'])} |")
    lines += ["", "| rate | model | rooms | mean A_n | 95 % interval | worst room | A_p (argmax) | "
              "A_p (mixture) |", "|---:|---|---:|---:|---|---:|---:|---:|"]
    for row in results["overall"]:
        lo, hi = row["interval"]
        lines.append(f"| {row['rate']} | {row['model']} | {row['rooms']} | {_f(row['mean_name_accuracy'])} | "
                     f"{_f(lo)}–{_f(hi)} | {_f(row['min_room_name_accuracy'])} | "
                     f"{_f(row['mean_position_accuracy']['argmax'])} | "
                     f"{_f(row['mean_position_accuracy']['mixture'])} |")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------ driver
def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def _read_runs(path: Path, fingerprint: str) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    out = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            rec = json.loads(line)
        except ValueError:  # a half-written last line of an interrupted run
            continue
        if isinstance(rec, dict) and rec.get("fingerprint") == fingerprint:
            out.append(rec)
    return out


def _checked_run_settings(file: SpecificConfigFile, rates: Sequence[int] | None, seeds: Sequence[int] | None,
                          iterations: int, n_positions: int, jobs: int, resume: bool,
                          force: bool) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The teaching rates and seeds to run (default the file's), with the other settings checked."""
    rates = tuple(sorted(dict.fromkeys(rates))) if rates else file.rates
    bad = [r for r in rates if isinstance(r, bool) or not isinstance(r, int) or not 0 < r <= 100]
    if bad:
        raise ConfigurationError(f"teaching rates must be percentages 1..100, got {bad}")
    seeds = tuple(dict.fromkeys(seeds)) if seeds else file.seeds
    foreign = [s for s in seeds if s not in file.seeds]
    if foreign:
        raise ConfigurationError(f"seed(s) {', '.join(map(str, foreign))} are not seeds of {file.path} "
                                 f"({file.seeds[0]}..{file.seeds[-1]})")
    for name, value, low in (("iterations", iterations, 1), ("positions", n_positions, 1), ("jobs", jobs, 1)):
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ConfigurationError(f"{name} must be an integer >= {low}, got {value!r}")
    if resume and force:
        raise ConfigurationError("choose one of --resume (continue) and --force (start over)")
    return rates, seeds


def _prepare_out_dir(out_dir: Path, fingerprint: str, resume: bool, force: bool) -> None:
    """``out_dir`` made ready: empty or absent; emptied of an earlier experiment (``force``); or
    holding this same experiment (``resume``)."""
    if out_dir.is_dir() and any(out_dir.iterdir()) and not (resume or force):
        raise ConfigurationError(f"{out_dir} is not empty: pass --resume to continue the experiment in "
                                 "it, --force to start over, or another --out")
    out_dir.mkdir(parents=True, exist_ok=True)
    if force:
        for name in (_CONFIG_FILE, _RUNS_FILE, _RESULTS_FILE, _TABLES_FILE):
            with contextlib.suppress(FileNotFoundError):
                (out_dir / name).unlink()
    elif resume:
        _check_same_experiment(out_dir, fingerprint)


def _check_same_experiment(out_dir: Path, fingerprint: str) -> None:
    """``--resume``: the experiment in ``out_dir`` (if any) must be this one."""
    if not (out_dir / _CONFIG_FILE).is_file():
        return
    try:
        stored = json.loads((out_dir / _CONFIG_FILE).read_text(encoding="utf-8"))["fingerprint"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DataFormatError(out_dir / _CONFIG_FILE, f"not a readable experiment configuration "
                              f"({exc}); use --force or another --out") from None
    if stored != fingerprint:
        raise ConfigurationError(f"{out_dir} holds a run of another configuration file, number of "
                                 "iterations or positions; refusing to mix results (use --force)")


def run_specific_config(
    config: str | os.PathLike[str] | SpecificConfigFile,
    data: str | os.PathLike[str],
    out: str | os.PathLike[str],
    configurations: Sequence[str] | None = None,
    rates: Sequence[int] | None = None,
    seeds: Sequence[int] | None = None,
    models: Sequence[str] = ("spcotransfer+mi", "spcoa"),
    iterations: int = 200,
    n_positions: int = DEFAULT_POSITIONS,
    jobs: int = 1,
    resume: bool = False,
    force: bool = False,
    progress: Callable[[dict[str, Any], int, int], None] | None = None,
    hyperparameters: Any = None,
) -> dict[str, Any]:
    """Run the home-specific experiment of a configuration file and write its results in ``out``.

    Parameters
    ----------
    config: the configuration file (path or loaded).
    data: the data set holding the homes (e.g. the SIGVerse folder).
    out: output folder (``config.json``, ``runs.jsonl``, ``results.json``, ``tables.md``).
    configurations: configuration ids to run (default: all of the file).
    rates, seeds: default the file's; the seeds must be among the file's.
    models: names of :data:`~spco.evaluation.experiments.MODELS`.
    iterations: Gibbs sweeps per fit; n_positions: positions per room and A_p mode.
    jobs: worker processes (results do not depend on it).
    resume: continue an experiment in ``out`` with the same configuration; force: start over.
    progress: called with each finished record, the number done and the total.
    hyperparameters: the transfer models' (a ``TransferHyperparameters``, e.g. of ``--set``; ``None``:
        each model's defaults); part of the experiment's identity when given.

    Returns
    -------
    The results mapping written to ``results.json``: ``format``, ``version``, ``config``,
    ``runs`` (the records), ``summary`` and ``overall`` (:func:`summarise`).
    """
    from spco.evaluation.config import parse_models

    file = config if isinstance(config, SpecificConfigFile) else load_specific_config(config)
    chosen = file.select(configurations)
    model_names = parse_models(list(models))
    rates, seeds = _checked_run_settings(file, rates, seeds, iterations, n_positions, jobs, resume, force)
    source = Path(data).expanduser()
    if not source.exists():
        raise DataFormatError(source, "no such data folder or file (--data)")
    out_dir = Path(out)
    if out_dir.exists() and not out_dir.is_dir():
        raise ConfigurationError(f"{out_dir}: exists and is not a folder (--out)")
    identity = {"config_sha256": file.sha256, "iterations": iterations, "positions": n_positions,
                "vocabulary": "per run", "format": RESULTS_VERSION}
    if hyperparameters is not None:  # (identities without it, of runs with the defaults, unchanged)
        identity["hyperparameters"] = hyperparameters.to_dict()
    fingerprint = hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()
    runs_file = out_dir / _RUNS_FILE
    _prepare_out_dir(out_dir, fingerprint, resume, force)
    _write_atomic(out_dir / _CONFIG_FILE, json.dumps({
        "format": RESULTS_FORMAT, "version": RESULTS_VERSION, "fingerprint": fingerprint,
        "identity": identity, "config": str(file.path)}, indent=1) + "\n")
    keys = [ConfiguredRun(c.id, r, s, m) for c in chosen for r in rates for s in seeds for m in model_names]
    done = {ConfiguredRun(r["configuration"], int(r["rate"]), int(r["seed"]), r["model"]): r
            for r in _read_runs(runs_file, fingerprint)}
    pending = [k for k in keys if k not in done]
    finished = [done[k] for k in keys if k in done]

    def store(record: dict[str, Any]) -> None:
        with runs_file.open("a", encoding="utf-8") as fh:
            fh.write(json.dumps(record, allow_nan=False) + "\n")
            fh.flush()
        finished.append(record)
        if progress is not None:
            progress(record, len(finished), len(keys))

    if pending:
        if jobs == 1 or len(pending) == 1:
            loaded = ConfiguredData(file, str(source), chosen)
            for key in pending:
                store(execute_configured_run(loaded, key, iterations, n_positions, fingerprint,
                                             hyperparameters))
        else:
            ids = tuple(c.id for c in chosen)
            with ProcessPoolExecutor(min(jobs, len(pending)), mp_context=multiprocessing.get_context("spawn"),
                                     initializer=_init_worker,
                                     initargs=(file, str(source), ids, iterations, n_positions,
                                               fingerprint, hyperparameters)) as pool:
                futures: set[Future[dict[str, Any]]] = {pool.submit(_worker_run, k) for k in pending}
                try:
                    while futures:
                        complete, futures = wait(futures, return_when=FIRST_COMPLETED)
                        for fut in complete:
                            store(fut.result())
                except BaseException:
                    for fut in futures:
                        fut.cancel()
                    raise
    finished.sort(key=lambda r: (r["configuration"], r["rate"], r["seed"], r["model"]))
    results = {"format": RESULTS_FORMAT, "version": RESULTS_VERSION,
               "config": {"file": str(file.path), "sha256": file.sha256,
                          "configurations": [c.id for c in chosen], "rates": list(rates),
                          "seeds": list(seeds), "models": list(model_names), "iterations": iterations,
                          "positions": n_positions, "data": str(data),
                          **({"hyperparameters": hyperparameters.to_dict()} if hyperparameters is not None
                             else {})},
               "runs": finished, **summarise(finished, file)}
    _write_atomic(out_dir / _RESULTS_FILE, json.dumps(results, indent=1, allow_nan=False) + "\n")
    _write_atomic(out_dir / _TABLES_FILE, tables(results))
    return results
