"""``spco experiment active``: a robot that asks, measured. How fast does a new home learn its
places when the robot chooses where to ask "what is this place?", one question at a time?

Protocol
--------
The knowledge is fitted once per seed on the paper's 16 experienced homes (taught at rate 100;
``knowledge-seed<S>.spco`` in the output folder, reused by ``--resume``). For each new home and trial:

1. the home, taught nothing, is adapted to the knowledge (:func:`spco.knowledge.adapt`, the trial's
   seed);
2. for each strategy, starting from that same home, ``k = 1 … questions`` questions are asked one at a
   time: the strategy picks an untaught training sample, an *oracle* answers with the data set's
   sentence for it, and :func:`spco.knowledge.teach` updates the home (an incremental update) before
   the next question. After every answer (and at k = 0) the home is scored on its test samples;
3. for reference, the paper's protocol: the home adapted at once with its home-specific rooms taught
   at random at ``rates`` percent (SIGVerse ``sentence/per_<rate>``; a held-out configuration's own
   selection rule), scored the same way, at k = the number of taught samples.

Strategies: ``information`` (:func:`spco.knowledge.asking.ask`: the expected information of the answer
about the names of the home's places), ``errors`` (the same model, ranked by the expected number of
wrong answers the question corrects), ``uncertainty`` (the sample whose ``what`` answer has the largest
entropy over the usable names; ties at random), ``random`` (a uniformly random untaught sample).

The oracle's sentence for a sample is its home-specific sentence where the data set has one (3LDK_9's
``sentence/per_100`` for its three bedrooms; a held-out configuration's templates for its rooms,
drawn from the trial's seed), else the place's template sentence from ``sentence_label``.

Scores (as the robot answers: names ranked like ``spco what``, positions from
:func:`spco.knowledge.where`, 10 per name): A_n and A_p on the **home-specific** rooms (their own
names), on the **general** places (the other places), and on **all** places, per k. Intervals: 95 %
percentile bootstrap over trials of the mean (2,000 resamples, fixed seed).

"Ask only when unsure": every step records the confidence of the chosen question's place (the
criterion's: the probability of its most probable name, a name of its own counted; and ``what``'s);
a robot that stops as soon as the best question's confidence is at least τ is scored on the same runs
(:func:`stop_rule_summary`).

Homes
-----
``homes``: SIGVerse homes (``1LDK_9``, ``2LDK_9``, ``3LDK_9``; a home with home-specific labels
(``name_label_specific`` and ``test_num_specific.txt``) is scored on its personal rooms) and, with
``heldout``, configurations of a ``heldout-specific/1`` file (``benchmarks/heldout/specific_heldout.json``),
named by their ``id``: their rooms replace the general places of their train and test samples.
"""

from __future__ import annotations

import hashlib
import json
import math
import multiprocessing
import os
import sys
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.environment import Corpus, Environment
from spco.data.language import Vocabulary, normalize_name
from spco.data.regions import PlaceRegions, load_region_file
from spco.data.sigverse import read_indexed_texts
from spco.errors import ConfigurationError, DataFormatError, SpcoError
from spco.evaluation.active_report import (
    _asked_places,
    figures,
    first_k,
    ranking_time,
    stop_rule_summary,
    summarise,
    tables,
)
from spco.evaluation.config import PAPER_EXPERIENCED_HOMES, PAPER_NEW_HOMES, trial_seed
from spco.evaluation.metrics import json_score, mean_over_places, name_accuracy
from spco.evaluation.results import _append_run, _prepare_out, _write_json_atomic, _write_text_atomic

__all__ = [
    "ACTIVE_FORMAT",
    "STRATEGIES",
    "ActiveConfig",
    "ActiveHome",
    "load_active_homes",
    "run_active_experiment",
    "stop_rule_summary",
]

ACTIVE_FORMAT = "spco-active-results"
_VERSION = 1
#: The strategies that choose where to ask.
STRATEGIES = ("information", "errors", "uncertainty", "random")
#: The strategies run by default.
DEFAULT_STRATEGIES = ("errors", "information", "uncertainty", "random")
_RUNS_FILE = "runs.jsonl"
_POSITIONS = 10


# ------------------------------------------------------------------------------------ config
@dataclass(frozen=True)
class ActiveConfig:
    """Everything that defines an active-learning experiment.

    Attributes
    ----------
    data: a folder of SIGVerse homes (the paper's layout: ``sentence_label/`` is the oracle).
    regions: ground-truth rectangles (``sigverse_regions.json`` format) of the new homes.
    homes: the new homes (SIGVerse names); heldout: a ``heldout-specific/1`` file or ``None``;
    heldout_configs: the ids of its configurations to run (``None``: none).
    experienced_homes: the knowledge's homes (default: the paper's 16).
    strategies: of :data:`STRATEGIES`; questions: how many questions (k = 0 … questions).
    trials, seed, jobs: trials per home, master seed, worker processes (results do not depend on it).
    rates: the paper's teaching rates of the home-specific rooms, for reference (homes without
        such rooms have none).
    fit_iterations, adapt_iterations, teach_sweeps: Gibbs sweeps of the knowledge's fit, of ``adapt``
        and of each ``teach``.
    knowledge: a knowledge file to use instead of fitting one (``experienced_homes`` and
        ``fit_iterations`` are then ignored; its checksum identifies the experiment).
    """

    data: str
    regions: str
    homes: tuple[str, ...] = PAPER_NEW_HOMES
    heldout: str | None = None
    heldout_configs: tuple[str, ...] | None = None
    experienced_homes: tuple[str, ...] = PAPER_EXPERIENCED_HOMES
    strategies: tuple[str, ...] = DEFAULT_STRATEGIES
    questions: int = 15
    trials: int = 20
    seed: int = 0
    jobs: int = 1
    rates: tuple[int, ...] = (20, 40)
    fit_iterations: int = 200
    adapt_iterations: int = 100
    teach_sweeps: int = 10
    knowledge: str | None = None

    def validated(self) -> ActiveConfig:
        """A checked copy (raises :class:`~spco.errors.ConfigurationError` naming the option)."""
        for name, low in (("questions", 0), ("trials", 1), ("jobs", 1), ("fit_iterations", 1),
                          ("adapt_iterations", 1), ("teach_sweeps", 0), ("seed", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
                raise ConfigurationError(f"{name.replace('_', '-')} must be an integer >= {low}, "
                                         f"got {value!r}")
        strategies = tuple(s.strip().lower() for s in self.strategies)
        unknown = [s for s in strategies if s not in STRATEGIES]
        if not strategies or unknown or len(set(strategies)) != len(strategies):
            raise ConfigurationError(f"strategies must be distinct names of {', '.join(STRATEGIES)}, got "
                                     f"{', '.join(self.strategies) or 'none'}")
        rates = tuple(int(r) for r in self.rates)
        if any(not 0 < r <= 100 for r in rates) or len(set(rates)) != len(rates):
            raise ConfigurationError(f"rates must be distinct percentages 1..100, got {self.rates!r}")
        homes = tuple(h.strip() for h in self.homes if h.strip())
        configs = tuple(c.strip() for c in (self.heldout_configs or ()) if c.strip())
        if configs and self.heldout is None:
            raise ConfigurationError("--heldout-config needs --heldout (the configuration file)")
        if not homes and not configs:
            raise ConfigurationError("no new home to run: give --homes and/or --heldout-config")
        overlap = set(homes) & set(self.experienced_homes)
        if overlap:
            raise ConfigurationError(f"home(s) {', '.join(sorted(overlap))} are experienced homes too")
        return replace(self, strategies=strategies, rates=tuple(sorted(rates)), homes=homes,
                       heldout_configs=configs or None, trials=int(self.trials), seed=int(self.seed),
                       questions=int(self.questions), jobs=int(self.jobs))


# ------------------------------------------------------------------------------------ homes
@dataclass
class ActiveHome:
    """A new home of the experiment, with its oracle and what it is scored on.

    Attributes
    ----------
    key: the home's name in results (a SIGVerse home, or a held-out configuration's id).
    home: the home taught nothing (its test samples marked).
    oracle: sample id -> the sentence the oracle answers there (every training sample).
    test_positions (t, 4), test_visual (t, D): the scored samples; test_labels (t,): their places
        (home-specific rooms by their own names).
    specific, general: the places of the home-specific rooms and the other places.
    accepted: place -> names counted right for it (the place's own name first).
    regions: every scored place's rectangles.
    references: rate -> ``(trial -> {id: sentence})`` builder of the paper's teaching at that rate.
    source: where the home was read.
    trial_oracle: ``trial -> oracle`` when the oracle's sentences depend on the trial.
    """

    key: str
    home: Environment
    oracle: dict[int, str]
    test_positions: np.ndarray
    test_visual: Any
    test_labels: tuple[str, ...]
    specific: tuple[str, ...]
    general: tuple[str, ...]
    accepted: dict[str, tuple[str, ...]]
    regions: PlaceRegions
    references: dict[int, Callable[[int], dict[int, str]]] = field(default_factory=dict, repr=False)
    source: str = ""
    trial_oracle: Callable[[int], dict[int, str]] | None = field(default=None, repr=False)

    def oracle_of(self, trial: int) -> dict[int, str]:
        """The oracle of a trial (a held-out configuration draws its rooms' templates per trial)."""
        return self.oracle if self.trial_oracle is None else self.trial_oracle(trial)

    @property
    def places(self) -> tuple[str, ...]:
        """Every scored place: the home-specific rooms, then the general places."""
        return self.specific + self.general

    def label_of(self, sample_id: int) -> str | None:
        """The place of a training sample, by what the oracle says there (for the report)."""
        sentence = self.oracle.get(int(sample_id))
        if sentence is None:
            return None
        for place in self.places:
            for name in self.accepted.get(place, (place,)):
                if f" {name} " in f" {normalize_name(sentence)} ":
                    return place
        return None


def _read_sentence_labels(folder: Path, n: int) -> dict[int, str]:
    """``sentence_label/sentence<i>.txt`` of a SIGVerse home: the template sentence of each sample."""
    labels = folder / "sentence_label"
    if not labels.is_dir():
        raise DataFormatError(folder, "has no sentence_label/ folder: the oracle answers with the place's "
                              "template sentence from it")
    return _sentences(labels, n)


def _rate_sentences(folder: Path, rate: int, n: int) -> dict[int, str]:
    """``sentence/per_<rate>/sentence<i>.txt`` of a SIGVerse home (empty if it has none)."""
    path = folder / "sentence" / f"per_{rate}"
    return _sentences(path, n) if path.is_dir() else {}


def _sentences(folder: Path, n: int) -> dict[int, str]:
    """sample -> ``sentence<i>.txt`` of ``folder`` for the samples 0..n-1 that have one."""
    texts = read_indexed_texts(folder, "sentence", n, strict=False)
    return {i: text for i, text in enumerate(texts) if text is not None}


def _test_set(env: Environment, rows: np.ndarray, labels: Sequence[str | None]) -> tuple[np.ndarray, Any,
                                                                                         tuple[str, ...]]:
    keep = [int(r) for r in rows if labels[int(r)] is not None]
    return (env.positions[keep], env.visual[keep], tuple(normalize_name(str(labels[r])) for r in keep))


def _sigverse_home(env: Environment, regions: PlaceRegions | None, rates: Sequence[int]) -> ActiveHome:
    folder = Path(env.source or "")
    if not folder.is_dir():
        raise DataFormatError(env.source or env.name, "the active experiment needs the home's folder (its "
                              "sentence_label/ is the oracle), not a cache file")
    gt = env.ground_truth
    if gt is None or gt.labels is None:
        raise DataFormatError(folder, "has no place labels (name_label/) to score against")
    if regions is None:
        raise DataFormatError(folder, f"no ground-truth regions for home {env.name!r} (--regions)")
    n = env.n_samples
    oracle = _read_sentence_labels(folder, n)
    top = max((int(p.name[4:]) for p in (folder / "sentence").glob("per_*") if p.name[4:].isdigit()),
              default=None) if (folder / "sentence").is_dir() else None
    specific_rows = np.zeros(n, dtype=bool)
    if gt.specific_labels is not None and gt.specific_test is not None:
        specific_rows = np.asarray(gt.specific_test, dtype=bool)
    own = _rate_sentences(folder, top, n) if top is not None and specific_rows.any() else {}
    oracle.update(own)  # the home-specific sentence where there is one
    train_ids = [int(i) for i in env.ids[~env.is_test]]
    missing = [i for i in train_ids if i not in oracle]
    if missing:
        raise DataFormatError(folder, f"no sentence for training sample(s) {missing[:5]} in sentence_label/ "
                              "or the home-specific sentences")
    labels = list(gt.labels)
    specific_places: list[str] = []
    if specific_rows.any():
        for r in np.flatnonzero(specific_rows):
            labels[r] = gt.specific_labels[r]  # type: ignore[index]
        specific_places = list(dict.fromkeys(normalize_name(str(gt.specific_labels[r]))  # type: ignore[index]
                                             for r in np.flatnonzero(specific_rows)))
    rows = np.flatnonzero(np.asarray(env.is_test, dtype=bool) | specific_rows)
    positions, visual, test_labels = _test_set(env, rows, labels)
    general = [p for p in dict.fromkeys(test_labels) if p not in specific_places]
    places = [*specific_places, *general]
    absent = [p for p in places if p not in regions.places]
    if absent:
        raise DataFormatError(folder, f"no ground-truth region for place(s) {', '.join(absent)} (--regions)")
    references: dict[int, Callable[[int], dict[int, str]]] = {}
    if specific_places:
        for rate in rates:
            taught = _rate_sentences(folder, rate, n)
            if not taught:
                raise DataFormatError(folder, f"no sentence/per_{rate}/ for the reference teaching "
                                      f"rate {rate}")
            references[rate] = lambda trial, taught=taught: dict(taught)
    accepted = {p: gt.accepted(p) for p in places}
    untaught = env.with_sentences((None,) * n)
    return ActiveHome(key=env.name, home=untaught, oracle=oracle, test_positions=positions,
                      test_visual=visual, test_labels=test_labels, specific=tuple(specific_places),
                      general=tuple(general), accepted=accepted, regions=regions, references=references,
                      source=str(folder))


def _read_heldout_rooms(env: Environment, rooms: list[Any], spec: Mapping[str, Any], index: dict[int, int],
                        labels: list[Any], accepted: dict[str, tuple[str, ...]],
                        room_regions: dict[str, Any], where: str
                        ) -> tuple[list[str], dict[int, dict[str, Any]]]:
    """The rooms of a held-out configuration, checked: their names (in order), and the room of each
    training sample; each room's test samples are labelled with it in ``labels``, its accepted
    names and region added to ``accepted`` and ``room_regions``."""
    specific: list[str] = []
    room_of: dict[int, dict[str, Any]] = {}
    for room in rooms:
        try:
            name = normalize_name(str(room["name"]))
            train = [int(i) for i in room["train_ids"]]
            test = [int(i) for i in room["test_ids"]]
        except (KeyError, TypeError, ValueError) as exc:
            raise DataFormatError(where, f"configuration {spec.get('id')!r}: a room lacks name, train_ids or "
                                  f"test_ids ({exc})") from None
        bad = [i for i in train + test if i not in index]
        if bad:
            raise DataFormatError(where, f"room {name!r}: sample id(s) {bad[:5]} not in home {env.name}")
        if not room.get("region"):
            raise DataFormatError(where, f"room {name!r} has no region to score positions against")
        specific.append(name)
        synonyms = (normalize_name(a) for a in room.get("accepted") or ())
        accepted[name] = tuple(dict.fromkeys([name, *synonyms]))
        room_regions[name] = tuple(tuple(float(v) for v in r) for r in room["region"])
        for i in train:
            room_of[i] = room
        for i in test:
            labels[index[i]] = name
    return specific, room_of


def _heldout_home(env: Environment, regions: PlaceRegions | None, spec: Mapping[str, Any],
                  rates: Sequence[int], where: str) -> ActiveHome:
    """A held-out configuration: its rooms replace the general places of their samples."""
    base = _sigverse_home(env, regions, ())
    rooms = spec.get("rooms")
    templates = spec.get("_templates")
    possessive = spec.get("_possessive_templates") or []
    seeds = spec.get("_seeds") or []
    if not isinstance(rooms, list) or not rooms or not isinstance(templates, list) or not templates:
        raise DataFormatError(where, f"configuration {spec.get('id')!r}: needs 'rooms' and the file's "
                              "'templates'")
    index = {int(i): k for k, i in enumerate(env.ids)}
    labels = list(env.ground_truth.labels)  # type: ignore[union-attr]
    room_regions = dict(base.regions.places)
    accepted = dict(base.accepted)
    specific, room_of = _read_heldout_rooms(env, rooms, spec, index, labels, accepted, room_regions, where)
    is_test = np.asarray(env.is_test, dtype=bool).copy()
    for room in rooms:
        for i in room["test_ids"]:
            is_test[index[int(i)]] = True
        for i in room["train_ids"]:
            is_test[index[int(i)]] = False
    env = replace(env, is_test=is_test)
    rows = np.flatnonzero(is_test)
    positions, visual, test_labels = _test_set(env, rows, labels)
    replaced = {normalize_name(str(r.get("replaces"))) for r in rooms}
    general = [p for p in dict.fromkeys(test_labels) if p not in specific and p not in replaced]

    def sentence(room: Mapping[str, Any], rng: np.random.Generator) -> str:
        pool = list(templates) + (list(possessive) if room.get("owner") else [])
        text = pool[int(rng.integers(len(pool)))]
        return text.replace("{name}", str(room["name"])).replace("{owner}", str(room.get("owner") or ""))

    def oracle_for(trial: int) -> dict[int, str]:
        out = dict(base.oracle)
        for i, room in room_of.items():  # each room sample's template from (trial, sample): stable
            out[i] = sentence(room, np.random.default_rng([int(trial), i]))
        return out

    def reference(rate: int) -> Callable[[int], dict[int, str]]:
        def taught(trial: int) -> dict[int, str]:  # the file's selection rule, its seeds by trial
            seed = int(seeds[trial % len(seeds)]) if seeds else trial
            rng = np.random.default_rng(seed)
            out: dict[int, str] = {}
            for room in rooms:
                train = [int(i) for i in room["train_ids"]]
                k = max(1, math.floor(rate * len(train) / 100 + 0.5))
                chosen = rng.choice(train, size=k, replace=False)
                for i in chosen:
                    out[int(i)] = sentence(room, rng)
            return out
        return taught

    home = ActiveHome(key=str(spec["id"]), home=env.with_sentences((None,) * env.n_samples),
                      oracle=oracle_for(0), test_positions=positions, test_visual=visual,
                      test_labels=test_labels, specific=tuple(specific), general=tuple(general),
                      accepted=accepted, regions=PlaceRegions(room_regions),
                      references={r: reference(r) for r in rates}, source=base.source,
                      trial_oracle=oracle_for)
    return home


def _read_heldout(path: str, ids: Sequence[str]) -> list[dict[str, Any]]:
    """The chosen configurations of a ``heldout-specific/1`` file, each with the file's templates."""
    file = Path(path).expanduser()
    try:
        raw = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataFormatError(file, f"not a readable configuration file ({exc})") from None
    if not isinstance(raw, dict) or not str(raw.get("_format", "")).startswith("heldout-specific/"):
        raise DataFormatError(file, "not a home-specific configuration file (_format heldout-specific/1)")
    configs = {str(c.get("id")): c for c in raw.get("configs") or [] if isinstance(c, dict)}
    unknown = [i for i in ids if i not in configs]
    if unknown:
        raise DataFormatError(file, f"no configuration {', '.join(map(repr, unknown))}; it has "
                              f"{', '.join(configs)}")
    return [{**configs[i], "_templates": raw.get("templates"),
             "_possessive_templates": raw.get("possessive_templates"), "_seeds": raw.get("seeds")}
            for i in ids]


def load_active_homes(config: ActiveConfig) -> tuple[list[Environment], list[ActiveHome]]:
    """The experienced homes (taught at rate 100) and the new homes of ``config``, checked.

    Raises :class:`~spco.errors.SpcoError` subclasses naming the file or option at fault.
    """
    from spco.data.loading import read_records

    config = config.validated()
    heldout = _read_heldout(config.heldout, config.heldout_configs or ()) if config.heldout else []
    fitted = () if config.knowledge is not None else config.experienced_homes
    names = list(dict.fromkeys([*fitted, *config.homes, *(c["home"] for c in heldout)]))
    data = Path(config.data).expanduser()
    if not data.is_dir():
        raise DataFormatError(data, "the active experiment reads a folder of SIGVerse homes (--data)")
    records = dict(zip(names, read_records(data, names=names), strict=True))
    region_file = Path(config.regions).expanduser()
    regions = load_region_file(region_file)
    experienced = ([] if config.knowledge is not None
                   else [records[n].at_rate(100) for n in config.experienced_homes])
    homes = [_sigverse_home(records[n].at_rate(0), regions.get(n), config.rates) for n in config.homes]
    for spec in heldout:
        name = str(spec["home"])
        homes.append(_heldout_home(records[name].at_rate(0), regions.get(name), spec, config.rates,
                                   str(config.heldout)))
    return experienced, homes


# ------------------------------------------------------------------------------------ scoring
def _names(home: Any, positions: np.ndarray, visual: Any) -> list[str | None]:
    """The robot's answer at each pose, as ``what`` answers it (honest probabilities,
    :func:`spco.knowledge.queries.name_prediction`)."""
    from spco.knowledge.queries import name_prediction

    return name_prediction(home, positions, visual, top_k=1).best


def score_home(home: Any, ah: ActiveHome, rng: np.random.Generator) -> dict[str, Any]:
    """A_n and A_p of a learnt home on ``ah``'s test samples and places.

    Returns ``{"name": {place: A_n}, "position": {place: A_p}, "specific_n", "specific_p",
    "general_n", "general_p", "all_n", "all_p"}`` (means over places), each score as
    :func:`~spco.evaluation.metrics.json_score` writes it: unrounded, ``None`` where nothing is scored.
    """
    from spco import knowledge as kn
    from spco.model.prediction import UnknownNameError

    predicted = _names(home, ah.test_positions, ah.test_visual)
    names = name_accuracy(predicted, ah.test_labels, ah.places, ah.accepted)
    positions: dict[str, float] = {}
    vocabulary: Vocabulary = home.vocabulary
    for place in ah.places:  # a handful of names
        asked = [n for i, n in enumerate(ah.accepted.get(place, (place,)))
                 if i == 0 or vocabulary.index(n) is not None]
        if len(asked) > 1 and vocabulary.index(place) is None:
            asked = asked[1:]
        scores = []
        for name in asked:
            try:
                pred = kn.where(home, name, n=_POSITIONS, random_state=rng)
            except UnknownNameError:
                scores.append(0.0)
                continue
            scores.append(float(ah.regions.contains(place, pred.samples[:, :2]).mean()))
        positions[place] = float(np.mean(scores))

    def mean(values: Mapping[str, float], places: Sequence[str]) -> float | None:
        return json_score(mean_over_places({p: values[p] for p in places}))

    return {"name": {p: json_score(v) for p, v in names.items()},
            "position": {p: json_score(v) for p, v in positions.items()},
            "specific_n": mean(names, ah.specific), "specific_p": mean(positions, ah.specific),
            "general_n": mean(names, ah.general), "general_p": mean(positions, ah.general),
            "all_n": mean(names, ah.places), "all_p": mean(positions, ah.places)}


# ------------------------------------------------------------------------------------ strategies
def _what_distribution(home: Any, rows: np.ndarray) -> np.ndarray:
    """``what``'s p(name | pose, view) over the usable names at the home's samples ``rows`` (its
    honest probabilities, :func:`spco.knowledge.queries.name_prediction`), renormalised (rows, V')."""
    from spco.knowledge.queries import name_prediction

    usable = int(np.asarray(home.parameters.word_mask, dtype=bool).sum())
    p = np.asarray(name_prediction(home, home.positions[rows], home.visual[rows],
                                   top_k=max(usable, 1)).probabilities, dtype=float)
    total = p.sum(axis=1, keepdims=True)
    return np.divide(p, total, out=np.zeros_like(p), where=total > 0)


def choose_question(strategy: str, home: Any, rng: np.random.Generator) -> dict[str, Any]:
    """The sample a strategy asks about next: ``{"row", "id", "gain", "confidence",
    "what_confidence", "seconds"}`` (``seconds``: the time to rank the home's samples)."""
    from spco.knowledge.asking import home_question_scores
    from spco.model.question_scores import entropy_rows, rank_questions

    candidates = np.flatnonzero([s is None for s in home.sentences])
    if candidates.size == 0:
        raise ConfigurationError("no untaught sample left to ask about")
    start = time.perf_counter()
    gain = math.nan
    if strategy in ("information", "errors"):
        scores = home_question_scores(home, strategy)
        rows, gains = rank_questions(scores, candidates)
        row, gain = int(rows[0]), float(gains[0])
    elif strategy == "uncertainty":
        h = entropy_rows(_what_distribution(home, candidates))
        best = np.flatnonzero(h >= h.max() - 1e-9)
        row = int(candidates[best[int(rng.integers(best.size))]])
    elif strategy == "random":
        row = int(candidates[int(rng.integers(candidates.size))])
    else:
        raise ConfigurationError(f"unknown strategy {strategy!r}")
    seconds = time.perf_counter() - start
    if strategy not in ("information", "errors"):
        scores = home_question_scores(home)
    what = _what_distribution(home, np.array([row]))[0]
    return {"row": row, "id": int(home.ids[row]), "gain": None if math.isnan(gain) else round(gain, 4),
            "confidence": round(float(scores.probabilities[row].max(initial=0.0)), 6),
            "what_confidence": round(float(what.max(initial=0.0)), 6), "seconds": round(seconds, 5)}


# ------------------------------------------------------------------------------------ runs
@dataclass(frozen=True)
class _Context:
    config: ActiveConfig
    knowledge_path: str
    fingerprint: str


def run_trial(knowledge: Any, ah: ActiveHome, trial: int, ctx: _Context) -> dict[str, Any]:
    """One trial of one home: adapt, then every strategy's questions, then the reference rates."""
    from spco import knowledge as kn

    config = ctx.config
    seed = trial_seed(config.seed, trial)
    oracle = ah.oracle_of(trial)
    started = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # own-name spread and view-fit warnings: the scores say it
        base = kn.adapt(knowledge, ah.home, n_iterations=config.adapt_iterations, random_state=seed)
        start_scores = score_home(base, ah, np.random.default_rng([seed, 0]))
        curves: dict[str, list[dict[str, Any]]] = {}
        for s_index, strategy in enumerate(config.strategies):
            home = base
            steps = [{"k": 0, **_compact(start_scores)}]
            rng = np.random.default_rng([seed, 1, s_index])
            for k in range(1, config.questions + 1):
                choice = choose_question(strategy, home, rng)
                sentence = oracle[choice["id"]]
                home = kn.teach(home, {choice["id"]: sentence}, n_sweeps=config.teach_sweeps,
                                random_state=np.random.default_rng([seed, 2, s_index, k]))
                scores = score_home(home, ah, np.random.default_rng([seed, 0, s_index, k]))
                steps[-1].update({"next": choice["id"], "next_place": ah.label_of(choice["id"]),
                                  "gain": choice["gain"], "confidence": choice["confidence"],
                                  "what_confidence": choice["what_confidence"],
                                  "rank_seconds": choice["seconds"]})
                steps.append({"k": k, **_compact(scores)})
            curves[strategy] = steps
        references = []
        for rate, taught_for in sorted(ah.references.items()):
            taught = taught_for(trial)
            env = ah.home.with_sentences(tuple(taught.get(int(i)) for i in ah.home.ids))
            home = kn.adapt(knowledge, env, n_iterations=config.adapt_iterations, random_state=seed)
            references.append({"rate": rate, "k": len(taught),
                               **_compact(score_home(home, ah, np.random.default_rng([seed, 3, rate])))})
    return {"fingerprint": ctx.fingerprint, "home": ah.key, "trial": trial, "seed": seed,
            "curves": curves, "references": references,
            "wall_seconds": round(time.perf_counter() - started, 3)}


def _compact(scores: Mapping[str, Any]) -> dict[str, Any]:
    return {k: scores[k] for k in ("specific_n", "specific_p", "general_n", "general_p", "all_n", "all_p",
                                   "name", "position")}


_WORKER: tuple[Any, dict[str, ActiveHome], _Context] | None = None


def _init_worker(ctx: _Context) -> None:
    global _WORKER
    from spco import knowledge as kn

    _, homes = load_active_homes(ctx.config)
    _WORKER = (kn.load_knowledge(ctx.knowledge_path), {h.key: h for h in homes}, ctx)


def _worker_run(key: tuple[str, int]) -> dict[str, Any]:
    if _WORKER is None:  # pragma: no cover - the initializer always runs first
        raise RuntimeError("worker not initialised")
    knowledge, homes, ctx = _WORKER
    return run_trial(knowledge, homes[key[0]], key[1], ctx)


# ------------------------------------------------------------------------------------ driver
@dataclass
class ActiveResults:
    """What :func:`run_active_experiment` wrote."""

    out: Path
    results: dict[str, Any]
    tables: str
    figures: list[Path]


def _identity(config: ActiveConfig, homes: Sequence[ActiveHome]) -> dict[str, Any]:
    fields = asdict(config)
    for key in ("trials", "jobs"):
        fields.pop(key)
    fields["data"] = str(config.data)
    fields["heldout_sha256"] = (hashlib.sha256(Path(config.heldout).expanduser().read_bytes()).hexdigest()
                                if config.heldout else None)
    fields["regions_sha256"] = hashlib.sha256(Path(config.regions).expanduser().read_bytes()).hexdigest()
    fields["new_homes"] = [h.key for h in homes]
    if config.knowledge is not None:
        from spco import knowledge as kn

        fields["knowledge_checksum"] = kn.load_knowledge(config.knowledge).checksum
        fields["experienced_homes"] = fields["fit_iterations"] = None
    from spco import __version__

    fields["spco_version"] = __version__
    return json.loads(json.dumps(fields))


def _knowledge(config: ActiveConfig, experienced: Sequence[Environment], out: Path,
               say: Callable[[str], None]) -> Path:
    """The knowledge of ``config.seed``: fitted once, then read from the output folder."""
    from spco import knowledge as kn

    if config.knowledge is not None:
        return Path(config.knowledge).expanduser()
    path = out / f"knowledge-seed{config.seed}.spco"
    if path.is_file():  # the folder's configuration (its fingerprint) is this one's: same homes, sweeps, seed
        try:
            kn.load_knowledge(path)
            return path
        except SpcoError:
            say(f"{path} is damaged: fitting it again")
    say(f"fitting the knowledge on {len(experienced)} experienced homes ({config.fit_iterations} sweeps, "
        f"seed {config.seed}) ...")
    knowledge = kn.fit_knowledge(Corpus(list(experienced)), n_iterations=config.fit_iterations,
                                 random_state=config.seed)
    knowledge.save(path, overwrite=True)
    return path


def _remove_stale_outputs(out_path: Path) -> None:
    """With ``force``: the runs, knowledge files and figures of an earlier experiment in ``out_path``."""
    stale_files = [out_path / _RUNS_FILE, *out_path.glob("knowledge-seed*.spco"),
                   *out_path.glob("active_*.png")]
    for stale in stale_files:
        if stale.is_file():
            stale.unlink()


def _runs_done(runs_file: Path, fingerprint: str) -> dict[tuple[str, int], dict[str, Any]]:
    """The runs of this experiment (same fingerprint) already in ``runs.jsonl``, by (home, trial)."""
    done: dict[tuple[str, int], dict[str, Any]] = {}
    if runs_file.is_file():
        for line in runs_file.read_text(encoding="utf-8").splitlines():
            try:
                rec = json.loads(line)
            except ValueError:
                continue  # an interrupted write: that run is done again
            if isinstance(rec, dict) and rec.get("fingerprint") == fingerprint:
                done[(rec["home"], int(rec["trial"]))] = rec
    return done


def run_active_experiment(config: ActiveConfig, out: str | os.PathLike[str], *, resume: bool = False,
                          force: bool = False, progress: bool = False,
                          log: Callable[[str], None] | None = None) -> ActiveResults:
    """Run (or continue) the active-learning experiment and write its outputs into ``out``.

    Writes ``config.json``, ``knowledge-seed<S>.spco``, ``runs.jsonl`` (one line per home and trial,
    appended as each finishes: ``resume`` continues), ``results.json``, ``tables.md`` and
    ``active_<home>.png``. Raises :class:`~spco.errors.SpcoError` subclasses for bad input.
    """
    say = log or (lambda _msg: None)
    started = time.perf_counter()
    config = config.validated()
    experienced, homes = load_active_homes(config)
    identity = _identity(config, homes)
    fingerprint = hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()
    out_path = Path(out).expanduser()
    _prepare_out(out_path, identity, fingerprint, resume, force)
    if force:
        _remove_stale_outputs(out_path)
    _write_json_atomic(out_path / "config.json", {"format": "spco-active", "version": _VERSION,
                                                   "fingerprint": fingerprint, "identity": identity,
                                                   "trials": config.trials, "jobs": config.jobs})
    knowledge_path = _knowledge(config, experienced, out_path, say)
    ctx = _Context(config, str(knowledge_path), fingerprint)
    runs_file = out_path / _RUNS_FILE
    done = _runs_done(runs_file, fingerprint)
    planned = [(h.key, t) for t in range(config.trials) for h in homes]
    pending = [key for key in planned if key not in done]
    if done:
        say(f"resuming: {len(planned) - len(pending)} of {len(planned)} runs already done")
    from tqdm import tqdm

    bar = tqdm(total=len(pending), desc="active experiment", unit="run", file=sys.stderr,
               disable=not progress or not pending, dynamic_ncols=True)

    def store(record: dict[str, Any]) -> None:
        _append_run(runs_file, record)
        done[(record["home"], int(record["trial"]))] = record
        bar.update(1)

    try:
        if config.jobs == 1 or len(pending) <= 1:
            from spco import knowledge as kn

            knowledge = kn.load_knowledge(knowledge_path)
            by_key = {h.key: h for h in homes}
            for key in pending:
                store(run_trial(knowledge, by_key[key[0]], key[1], ctx))
        else:
            with ProcessPoolExecutor(min(config.jobs, len(pending)),
                                     mp_context=multiprocessing.get_context("spawn"),
                                     initializer=_init_worker, initargs=(ctx,)) as pool:
                futures: set[Future[dict[str, Any]]] = {pool.submit(_worker_run, key) for key in pending}
                while futures:
                    finished, futures = wait(futures, return_when=FIRST_COMPLETED)
                    for fut in finished:
                        store(fut.result())
    finally:
        bar.close()
    records = [done[k] for k in planned if k in done]
    summary = summarise(records, config.strategies)
    first = next((s for s in config.strategies if s in ("information", "errors")), None)
    stop = (stop_rule_summary(records, first, measure="all_n", confidence="confidence")
            + stop_rule_summary(records, first, measure="all_n", confidence="what_confidence")
            if first else [])
    results = {
        "format": ACTIVE_FORMAT, "version": _VERSION,
        "config": {**identity, "trials": config.trials,
                   "strategies": list(config.strategies)},
        "fingerprint": fingerprint,
        "homes": {h.key: {"specific": list(h.specific), "general": list(h.general),
                          "test_samples": len(h.test_labels)} for h in homes},
        "summary": summary,
        "first_k_specific": first_k(summary, "specific_n"),
        "first_k_all": first_k(summary, "all_n"),
        "stop_rule": stop,
        "ranking_seconds": ranking_time(records),
        "asked_places": _asked_places(records, config.strategies),
        "timing": {"runs": len(records),
                   "run_wall_seconds_total": round(sum(r["wall_seconds"] for r in records), 1),
                   "session_wall_seconds": round(time.perf_counter() - started, 1)},
    }
    _write_json_atomic(out_path / "results.json", results)
    text = tables(results)
    _write_text_atomic(out_path / "tables.md", text)
    written = figures(out_path, results)
    return ActiveResults(out_path, results, text, written)
