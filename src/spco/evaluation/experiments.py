"""The experiments of Hagiwara et al. (2021): general places and home-specific places.

Protocols
---------
``general``
    For each number ``n`` of experienced homes (``settings``; the paper: 0, 1, 2, 4, 8, 16) and each
    new home (``1LDK_9``, ``2LDK_9``, ``3LDK_9``), a model learns the first ``n`` homes of the fixed
    list :data:`PAPER_EXPERIENCED_HOMES` (taught at rate 100) together with the new home, taught
    nothing and added as the *last* environment (``n = 0``: the new home alone). It then predicts
    the names of the new home's test samples from position and vision (A_n) and positions for
    each of its place names (A_p), see :func:`spco.evaluation.metrics.evaluate_home`.
``specific``
    For each teaching rate ``r`` (``settings``; the paper: 0, 20, …, 100), the 16 experienced homes
    and ``3LDK_9``, whose three bedrooms are taught at rate ``r`` (SIGVerse: its
    ``sentence/per_<r>`` folder; its general places are never taught), scored on the 30
    home-specific test samples and the three names ``Emma's-room``, ``mother's-room`` and
    ``father's-room`` (``evaluate_home(..., specific=True)``).

Each (model, setting, new home, trial) is one *run*. The trial seed is
``SeedSequence(seed, spawn_key=(trial,))`` (:func:`trial_seed`): every model, setting and home of
a trial uses the same seed, and the same ``seed`` gives the same results (with any ``jobs``).

Models (:data:`MODELS`, a registry name -> :class:`ModelSpec`): ``spcotransfer`` (exact sampler),
``spcotransfer+mi`` (with mutual-information word pruning), ``spcotransfer-ref`` and
``spcotransfer-ref+mi`` (the authors' reference sampler, names scored with their KL weighting),
``spcoa`` and ``spcoa+mi`` (SpCoA on the new home alone: in the general experiment nothing is
taught there, so they are expected near chance; their result does not depend on ``n``).

*Runs computed once.* In the general experiment a single-home model (SpCoA) learns the new home
alone, with the trial's seed, whatever the number of experienced homes: its run is the same at every
setting. It is computed once per (trial, new home), at the largest setting (where trial 0's map is
drawn), and its record is copied to the other settings with ``reused_from_setting`` set and
``wall_seconds`` 0 (:func:`shared_runs`). The paper's protocol thus costs 600 SpCoA fits fewer.

Data
----
``data="synthetic"`` (sentences: ``language``, the paper's templates or ``"free"``) generates
``max(16, n_max) + 3`` homes with
:func:`spco.data.synthetic.generate_homes` (``seed`` = the experiment's seed): the first are the
experienced homes, the last three the new homes, the very last has the home-specific bedrooms
(taught with :func:`spco.data.synthetic.teach`, the same seed). A path (a folder of homes in either
layout, or an ``spco import`` cache) uses the paper's home lists (or ``experienced_homes`` /
``new_homes``); ground-truth regions come from a region file (``regions``, the format of
``sigverse_regions.json``) or, without one, from the homes themselves.

*One vocabulary per experiment.* Every run of an experiment uses the same word list: the words of
all experienced homes at rate 100 (and, in the specific experiment, of the new home at the highest
rate). The chance level of A_n, ``1/|V|``, is therefore the same in every setting, and with
``n = 0`` (no word ever observed) the models still have names to choose from — at chance.

Outputs in ``out``
------------------
``config.json``: the configuration and its fingerprint (sha256 of everything that determines a
run's result: experiment, models, settings, iterations, seed, positions per name, data source,
home lists, region file digest, vocabulary, hyperparameters; not ``trials`` and ``jobs``: a run's
result does not depend on them, so ``--resume --trials 20`` extends a 2-trial experiment).
``runs.jsonl``: one JSON line per finished run (with the fingerprint), appended and flushed as soon
as it finishes, so an interrupted experiment continues with ``resume=True``; a half-written last
line is dropped. ``results.json`` (below), ``tables.md`` (:mod:`spco.evaluation.report`),
``<experiment>_name_accuracy.png``, ``<experiment>_position_accuracy.png`` (curves with chance
lines), ``<experiment>_log_joint_<model>.png`` (log-joint traces of trial 0 at the largest setting)
and ``maps/<experiment>_<model>_<setting>_<home>.png`` (the learnt regions of trial 0 at the largest
setting on the floor plan, ground-truth rectangles, predicted positions, a few test poses with their
top-3 names). In file names, ``+`` becomes ``_`` (``spcotransfer_mi``).

results.json schema (version 1)
-------------------------------
::

    {
      "format": "spco-experiment-results", "version": 1,
      "config": {"experiment": "general" | "specific", "models": [str], "settings": [int],
                 "trials": int, "iterations": int, "seed": int, "n_positions": int,
                 "data": {"source": "synthetic" | path as given, "language": "templates" | "free",
                          "experienced_homes": [str], "new_homes": [str], "specific_home": str | null,
                          "regions": path as given | null, "regions_sha256": str | null,
                          "maps": path as given | null,
                          "vocabulary": [str]},
                 "hyperparameters": {model: {name: value}}, "fingerprint": str,
                 "spco_version": str},
      "runs": [   # one row per run and place, plus one row with place "mean" per run
        {"experiment": str, "model": str,
         "setting": int,          # general: number of experienced homes; specific: teaching rate
         "home": str,             # the new home
         "trial": int, "place": str,   # a normalised place name, or "mean" (mean over the places)
         "name_accuracy": float | null, "position_accuracy": float | null,   # null: not scored
         "seed": int,             # the run's random_state
         "iterations": int, "wall_seconds": float,   # fit + evaluation time of the run
         "reused_from_setting": int | null}   # the run was computed at that setting (see above)
      ],
      "summary": [   # over new homes and trials
        {"experiment", "model", "setting", "place",          # place "mean": mean of per-run means
         "name_accuracy_mean", "name_accuracy_std",          # std: sample std (ddof=1), null if n < 2
         "position_accuracy_mean", "position_accuracy_std", "n"}   # n: number of runs
      ],
      "summary_by_home": [ same keys as "summary" plus "home" ],
      "chance": {"name_accuracy": 1/|V|, "position_accuracy": mean over new homes of 1/|places|,
                 "by_home": {home: {"name_accuracy": float, "position_accuracy": float}}},
      "timing": {"runs": int, "runs_reused": int, "runs_this_session": int,
                 "run_wall_seconds_total": float, "session_wall_seconds": float}
    }   # runs_this_session: runs computed by this call; runs_reused: records copied from another

Accuracies are fractions in [0, 1]; a place without scored samples (or without a ground-truth area)
is ``null`` and left out of the means.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import multiprocessing
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from spco.data.environment import Environment, make_ground_truth
from spco.data.language import Vocabulary
from spco.data.regions import PlaceRegions, load_region_file
from spco.errors import ConfigurationError, DataFormatError
from spco.evaluation import report
from spco.evaluation.metrics import HomeScores, evaluate_home
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.transfer import SpatialConceptModel, SpCoA, SpCoTransfer

__all__ = [
    "DEFAULT_RATES",
    "DEFAULT_SETTINGS",
    "MODELS",
    "PAPER_EXPERIENCED_HOMES",
    "PAPER_NEW_HOMES",
    "PAPER_SPECIFIC_HOME",
    "ExperimentConfig",
    "ExperimentData",
    "ExperimentResults",
    "ModelSpec",
    "RunKey",
    "describe_models",
    "execute_run",
    "load_experiment_data",
    "map_path",
    "parse_int_list",
    "parse_models",
    "plan_runs",
    "read_runs",
    "run_experiment",
    "shared_runs",
    "trial_seed",
]

Experiment = Literal["general", "specific"]
EXPERIMENTS: tuple[str, ...] = ("general", "specific")

#: The experienced homes of the paper, in the order they are added (the first ``n`` are used).
PAPER_EXPERIENCED_HOMES: tuple[str, ...] = (
    "3LDK_1", "1LDK_8", "2LDK_8", "1LDK_7", "2LDK_7", "1LDK_6", "2LDK_6", "1LDK_5",
    "2LDK_5", "1LDK_4", "2LDK_4", "1LDK_3", "2LDK_3", "1LDK_2", "2LDK_2", "1LDK_1",
)
#: The new homes of the general experiment.
PAPER_NEW_HOMES: tuple[str, ...] = ("1LDK_9", "2LDK_9", "3LDK_9")
#: The new home of the home-specific experiment.
PAPER_SPECIFIC_HOME = "3LDK_9"
#: Default settings: numbers of experienced homes (general), teaching rates (specific).
DEFAULT_SETTINGS: tuple[int, ...] = (0, 1, 2, 4, 8, 16)
DEFAULT_RATES: tuple[int, ...] = (0, 20, 40, 60, 80, 100)
#: Number of synthetic new homes (the last one has the home-specific bedrooms).
SYNTHETIC_NEW_HOMES = 3

RESULTS_FORMAT = "spco-experiment-results"
CONFIG_FORMAT = "spco-experiment"
FORMAT_VERSION = 1
CONFIG_FILE = "config.json"
RUNS_FILE = "runs.jsonl"
RESULTS_FILE = "results.json"
TABLES_FILE = "tables.md"
MAPS_DIR = "maps"
_POSES_ON_MAP = 4


# ------------------------------------------------------------------------------------ models
@dataclass(frozen=True)
class ModelSpec:
    """How to build and score one model of the comparison.

    Attributes
    ----------
    description: one line for help texts.
    build: ``build(n_iterations, random_state, hyperparameters, record_log_joint)`` -> an unfitted
        model; ``hyperparameters`` (``None``: the model's defaults) applies to transfer models.
    single_home: fitted on the new home alone (SpCoA) instead of all homes of the setting.
    weighting: the name weighting of prediction (``"mi"`` or the authors' ``"reference"``).
    """

    description: str
    build: Callable[[int, int, TransferHyperparameters | None, bool], SpatialConceptModel]
    single_home: bool = False
    weighting: Literal["mi", "none", "reference"] = "mi"

    def hyperparameters(self, hyper: TransferHyperparameters | None) -> TransferHyperparameters:
        """The hyperparameters the model will use."""
        model = self.build(1, 0, hyper, False)
        used = model.hyperparameters
        return used if used is not None else model._default_hyperparameters()


def _transfer(variant: str, prune: bool) -> Callable[..., SpatialConceptModel]:
    def build(n_iterations: int, random_state: int, hyper: TransferHyperparameters | None,
              record_log_joint: bool) -> SpatialConceptModel:
        return SpCoTransfer(hyper, variant=variant, prune_words=prune, n_iterations=n_iterations,
                            random_state=random_state, record_log_joint=record_log_joint)
    return build


def _spcoa(prune: bool) -> Callable[..., SpatialConceptModel]:
    def build(n_iterations: int, random_state: int, hyper: TransferHyperparameters | None,
              record_log_joint: bool) -> SpatialConceptModel:
        # SpCoA keeps its own hyperparameters (SpCoAHyperparameters); the transfer ones do not apply
        return SpCoA(prune_words=prune, n_iterations=n_iterations, random_state=random_state,
                     record_log_joint=record_log_joint)
    return build


#: The models an experiment can compare, by name. Add an entry to extend the comparison.
MODELS: dict[str, ModelSpec] = {
    "spcotransfer": ModelSpec("SpCoTransfer, exact sampler", _transfer("exact", False)),
    "spcotransfer+mi": ModelSpec("SpCoTransfer + MI word pruning", _transfer("exact", True)),
    "spcotransfer-ref": ModelSpec("SpCoTransfer, the authors' sampler and KL name scoring",
                                  _transfer("reference", False), weighting="reference"),
    "spcotransfer-ref+mi": ModelSpec("SpCoTransfer + word pruning, the authors' sampler and KL "
                                     "name scoring", _transfer("reference", True), weighting="reference"),
    "spcoa": ModelSpec("SpCoA on the new home alone", _spcoa(False), single_home=True),
    "spcoa+mi": ModelSpec("SpCoA + MI word pruning on the new home alone", _spcoa(True),
                          single_home=True),
}


# ------------------------------------------------------------------------------------ parsing
def parse_int_list(text: str | Sequence[int], what: str, low: int,
                   high: int | None = None) -> tuple[int, ...]:
    """A comma-separated list of distinct integers within ``low..high`` (e.g. ``"0,1,2,4"``).

    Raises :class:`~spco.errors.ConfigurationError` naming ``what`` on anything else.
    """
    bounds = f"{low}..{high}" if high is not None else f">= {low}"
    if isinstance(text, str):
        parts = [p.strip() for p in text.split(",")]
        if not text.strip() or any(not p for p in parts):
            raise ConfigurationError(f"{what} must be a comma-separated list of integers ({bounds}), "
                                     f"got {text!r}")
        try:
            values = [int(p) for p in parts]
        except ValueError:
            raise ConfigurationError(f"{what} must be a comma-separated list of integers ({bounds}), "
                                     f"got {text!r}") from None
    else:
        values = list(text)
        if not values or any(isinstance(v, bool) or not isinstance(v, int | np.integer) for v in values):
            raise ConfigurationError(f"{what} must be a non-empty list of integers, got {text!r}")
        values = [int(v) for v in values]
    bad = [v for v in values if v < low or (high is not None and v > high)]
    if bad:
        raise ConfigurationError(f"{what}: {', '.join(map(str, bad))} out of range ({bounds})")
    dup = sorted({v for v in values if values.count(v) > 1})
    if dup:
        raise ConfigurationError(f"{what}: repeated value(s) {', '.join(map(str, dup))}")
    return tuple(sorted(values))


def parse_models(text: str | Sequence[str] | None) -> tuple[str, ...]:
    """Model names from a comma-separated list (``None`` or ``"all"``: every model of :data:`MODELS`)."""
    if text is None:
        return tuple(MODELS)
    names = [p.strip().lower() for p in text.split(",")] if isinstance(text, str) else \
        [str(p).strip().lower() for p in text]
    if names == ["all"]:
        return tuple(MODELS)
    if not names or any(not n for n in names):
        raise ConfigurationError(f"models must be a comma-separated list of model names, got {text!r}; "
                                 f"models: {', '.join(MODELS)}")
    unknown = [n for n in names if n not in MODELS]
    if unknown:
        raise ConfigurationError(f"unknown model(s) {', '.join(map(repr, unknown))}; models: "
                                 f"{', '.join(MODELS)}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ConfigurationError(f"model(s) listed twice: {', '.join(dup)}")
    return tuple(names)


def trial_seed(seed: int, trial: int) -> int:
    """The ``random_state`` of every run of trial ``trial``: a 63-bit integer drawn from
    ``SeedSequence(seed, spawn_key=(trial,))`` (i.e. ``SeedSequence(seed).spawn(n)[trial]``)."""
    state = np.random.SeedSequence(seed, spawn_key=(trial,)).generate_state(1, np.uint64)
    return int(state[0]) & (2**63 - 1)


# ------------------------------------------------------------------------------------ config
@dataclass(frozen=True)
class ExperimentConfig:
    """Everything that defines an experiment.

    Attributes
    ----------
    experiment: ``"general"`` or ``"specific"``.
    settings: numbers of experienced homes (general) or teaching rates in percent (specific);
        ``None``: the paper's (:data:`DEFAULT_SETTINGS`, :data:`DEFAULT_RATES`).
    data: ``"synthetic"`` or a path (a folder of homes, a home layout, an ``spco import`` cache).
    regions: a region file (``sigverse_regions.json`` format) for the new homes, or ``None``.
    maps: a folder of floor plans ``<home>.PNG`` (+ ``extents.json``); ``None``: look for ``maps/``
        beside the region file and the data folder.
    trials: runs per (model, setting, new home), each with its own seed.
    models: names of :data:`MODELS` (``None``: all).
    iterations: Gibbs sweeps per fit.
    seed: the master seed (trial seeds, synthetic homes, position samples).
    jobs: parallel worker processes (results do not depend on it).
    engine: ``local`` (worker processes) or ``ray`` (every run a Ray task, on this machine or
        the cluster at ``address``; results do not depend on it).
    n_positions: positions sampled per name for A_p.
    experienced_homes, new_homes: override the home lists (names in the data); ``new_homes`` may
        also restrict the synthetic new homes.
    specific_home: override the new home of the specific experiment.
    hyperparameters: of the transfer models (``None``: the paper's); SpCoA keeps its own.
    language: sentences of synthetic homes, ``"templates"`` (the paper's) or ``"free"`` (people
        talking freely, :mod:`spco.data.speech`; their places have several accepted names).
    images: a folder ``<home>/<id>.jpg|png`` of the homes' camera images (``sigverse_images``): the
        views are then computed from them by ``extractor`` instead of read as count vectors.
    extractor: the image extractor's name (:mod:`spco.features`; default
        :data:`~spco.features.DEFAULT_EXTRACTOR` when ``images`` is given). A codebook it needs is
        learnt from the experienced homes' training images (seed ``seed``).
    text_language: how the experiment's vocabulary treats text written without spaces:
        ``"auto"`` (found from the text), ``"ja"``, ``"zh"`` (segmented) or ``"spaced"``
        (:func:`spco.data.segmentation.resolve`).
    """

    experiment: Experiment = "general"
    settings: tuple[int, ...] | None = None
    data: str | os.PathLike[str] = "synthetic"
    regions: str | os.PathLike[str] | None = None
    maps: str | os.PathLike[str] | None = None
    trials: int = 20
    models: tuple[str, ...] | None = None
    iterations: int = 200
    seed: int = 0
    jobs: int = 1
    n_positions: int = 10
    engine: str = "local"
    address: str | None = None
    experienced_homes: tuple[str, ...] | None = None
    new_homes: tuple[str, ...] | None = None
    specific_home: str | None = None
    hyperparameters: TransferHyperparameters | None = None
    language: str = "templates"
    images: str | os.PathLike[str] | None = None
    extractor: str | None = None
    text_language: str = "auto"

    def validated(self) -> ExperimentConfig:
        """A copy with defaults filled in and every field checked (raises ConfigurationError)."""
        if self.experiment not in EXPERIMENTS:
            raise ConfigurationError(f"experiment must be 'general' or 'specific', got {self.experiment!r}")
        for name, low in (("trials", 1), ("iterations", 1), ("jobs", 1), ("n_positions", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
                raise ConfigurationError(f"{name} must be an integer >= {low}, got {value!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer) or self.seed < 0:
            raise ConfigurationError(f"seed must be a non-negative integer, got {self.seed!r}")
        if self.language not in ("templates", "free"):
            raise ConfigurationError(f"language must be 'templates' or 'free', got {self.language!r}")
        from spco.data.segmentation import TEXT_LANGUAGES

        if self.text_language not in TEXT_LANGUAGES:
            raise ConfigurationError(f"text_language must be one of {', '.join(TEXT_LANGUAGES)}, got "
                                     f"{self.text_language!r}")
        if self.hyperparameters is not None and not isinstance(self.hyperparameters, TransferHyperparameters):
            raise ConfigurationError("hyperparameters must be a TransferHyperparameters instance")
        if self.engine not in ("local", "ray"):
            raise ConfigurationError(f"engine must be 'local' or 'ray', got {self.engine!r}")
        if self.settings is None:
            settings = DEFAULT_SETTINGS if self.experiment == "general" else DEFAULT_RATES
        else:
            what = "--envs (numbers of experienced homes)" if self.experiment == "general" \
                else "--rates (teaching rates)"
            high = None if self.experiment == "general" else 100
            settings = parse_int_list(self.settings, what, 0, high)
        data = str(self.data)
        if data.strip().lower() == "synthetic":
            data = "synthetic"
        lists = {}
        for name in ("experienced_homes", "new_homes"):
            value = getattr(self, name)
            if value is not None:
                value = tuple(str(v).strip() for v in ([value] if isinstance(value, str) else value))
                if not value or any(not v for v in value) or len(set(value)) != len(value):
                    raise ConfigurationError(f"{name} must be distinct, non-empty home names, "
                                             f"got {getattr(self, name)!r}")
            lists[name] = value
        return replace(self, settings=tuple(settings), models=parse_models(self.models), data=data,
                       trials=int(self.trials), iterations=int(self.iterations), seed=int(self.seed),
                       jobs=int(self.jobs), n_positions=int(self.n_positions), **lists)


# ------------------------------------------------------------------------------------ data
@dataclass(frozen=True)
class _DataSpec:
    """Picklable recipe of an :class:`ExperimentData` (rebuilt in every worker process)."""

    experiment: str
    source: str  # "synthetic" or a resolved path
    regions: str | None
    seed: int
    n_needed: int  # experienced homes the settings need
    experienced_homes: tuple[str, ...] | None
    new_homes: tuple[str, ...] | None
    specific_home: str | None
    language: str = "templates"  # sentences of synthetic homes
    shown_source: str | None = None  # --data as given (for result files; no absolute path)
    shown_regions: str | None = None  # --regions as given
    images: str | None = None
    extractor: str | None = None
    shown_images: str | None = None  # --images as given
    text_language: str = "auto"


class _HomeSource:
    """A home that can be given at any teaching rate (experienced: all places; new: as the data
    says, or the synthetic home-specific rooms taught with :func:`~spco.data.synthetic.teach`)."""

    def __init__(self, at_rate: Callable[[int], Environment]) -> None:
        self._at_rate = at_rate
        self._cache: dict[int, Environment] = {}

    def at_rate(self, rate: int) -> Environment:
        if rate not in self._cache:
            self._cache[rate] = self._at_rate(rate)
        return self._cache[rate]


def _untaught(env: Environment) -> Environment:
    return env if all(s is None for s in env.sentences) else env.with_sentences((None,) * env.n_samples)


@dataclass
class ExperimentData:
    """The homes of an experiment, ready to be combined into each run's corpus.

    Use :func:`load_experiment_data`. ``experienced`` is the ordered list of experienced homes (the
    first ``n`` are used with ``n`` homes), ``new_homes`` the evaluated homes of the general experiment,
    ``specific_home`` the new home of the specific experiment, ``vocabulary`` the experiment's word list.
    """

    experiment: str
    experienced: tuple[str, ...]
    new_homes: tuple[str, ...]
    specific_home: str | None
    sources: dict[str, _HomeSource]
    regions: dict[str, PlaceRegions] = field(default_factory=dict)
    description: dict[str, Any] = field(default_factory=dict)
    vocabulary: Vocabulary = field(default_factory=lambda: Vocabulary(()))
    #: the homes as read, when their views were computed from images (handed to worker processes as
    #: a cache file, so that the images are not read and extracted again in each of them)
    view_records: list[Any] = field(default_factory=list, repr=False)
    _evaluated: dict[tuple[str, int], Environment] = field(default_factory=dict)

    @property
    def evaluated_homes(self) -> tuple[str, ...]:
        """The new homes scored by this experiment."""
        if self.experiment == "specific":
            return (self.specific_home,) if self.specific_home else ()
        return self.new_homes

    def experienced_home(self, name: str) -> Environment:
        """An experienced home, taught at rate 100."""
        return self.sources[name].at_rate(100)

    def new_home(self, name: str, rate: int = 0) -> Environment:
        """A new home taught at ``rate`` (0 in the general experiment), with its regions attached."""
        key = (name, rate)
        if key not in self._evaluated:
            env = self.sources[name].at_rate(rate)
            regions = self.regions.get(name)
            if regions is not None:
                gt = env.ground_truth or make_ground_truth()
                env = replace(env, ground_truth=replace(gt, regions=regions))
            self._evaluated[key] = env
        return self._evaluated[key]

    def homes_for(self, setting: int, home: str) -> list[Environment]:
        """The homes of one run, new home last: ``(experienced…, new)``."""
        if self.experiment == "general":
            return [*(self.experienced_home(n) for n in self.experienced[:setting]), self.new_home(home, 0)]
        return [*(self.experienced_home(n) for n in self.experienced), self.new_home(home, setting)]


def _read_path_sources(spec: _DataSpec) -> tuple[tuple[str, ...], tuple[str, ...], str | None,
                                                     dict[str, _HomeSource], list[Any], Any]:
    """The homes of a data set on disk: experienced, new and specific home names, their sources, the
    records read and the image extractor (``None`` for count vectors)."""
    from spco.data.loading import read_records

    experienced = spec.experienced_homes or PAPER_EXPERIENCED_HOMES
    if spec.experiment == "general":
        new = spec.new_homes or PAPER_NEW_HOMES
        specific = None
    else:
        if spec.new_homes is not None and spec.specific_home is None and len(spec.new_homes) != 1:
            raise ConfigurationError("the specific experiment has one new home; pass it as "
                                     "specific_home (--new-home)")
        specific = spec.specific_home or (spec.new_homes[0] if spec.new_homes else PAPER_SPECIFIC_HOME)
        new = (specific,)
    overlap = sorted(set(experienced) & set(new))
    if overlap:
        raise ConfigurationError(f"home(s) {', '.join(overlap)} listed both as experienced and as new")
    names = list(dict.fromkeys([*experienced, *new]))
    extractor = _image_extractor(spec, experienced)
    try:
        records = read_records(spec.source, names=names, extractor=extractor, images=spec.images)
    except DataFormatError as exc:
        if "no home named" in exc.problem and spec.experienced_homes is None:
            raise DataFormatError(exc.path, f"{exc.problem}. The experiments use the homes of the "
                                  "paper's SIGVerse data set by default; for other data pass "
                                  "--experienced-homes and --new-homes") from None
        raise
    sources: dict[str, _HomeSource] = {}
    for name, rec in zip(names, records, strict=True):
        sources[name] = _HomeSource(rec.at_rate)
    return tuple(experienced), tuple(new), specific, sources, records, extractor


def _image_extractor(spec: _DataSpec, experienced: Sequence[str]) -> Any:
    """The extractor of views given as images (``None`` for count vectors); a codebook it needs is
    learnt from the experienced homes' training images."""
    if spec.images is None and spec.extractor is None:
        return None
    from spco.data.loading import training_image_files
    from spco.features import DEFAULT_EXTRACTOR, build_extractor

    extractor = build_extractor(spec.extractor or DEFAULT_EXTRACTOR)
    if extractor.needs_fit:
        files = training_image_files(spec.source, list(experienced), spec.images)
        extractor = extractor.fitted(files, random_state=spec.seed)
    return extractor


def _synthetic_sources(spec: _DataSpec) -> tuple[tuple[str, ...], tuple[str, ...], str | None,
                                                    dict[str, _HomeSource], dict[str, PlaceRegions]]:
    from spco.data.synthetic import SyntheticConfig, generate_homes, teach

    if spec.experienced_homes is not None:
        raise ConfigurationError("experienced_homes cannot be chosen for synthetic data (they are "
                                 "the first generated homes)")
    n_exp = max(len(PAPER_EXPERIENCED_HOMES), spec.n_needed)
    language = SyntheticConfig(language=spec.language)
    corpus = generate_homes(n_exp + SYNTHETIC_NEW_HOMES, seed=spec.seed, new_homes=SYNTHETIC_NEW_HOMES,
                            config=language)
    names = corpus.names
    experienced, all_new = tuple(names[:n_exp]), tuple(names[n_exp:])
    sources: dict[str, _HomeSource] = {}
    for name in experienced:
        env = corpus[name]
        sources[name] = _HomeSource(lambda rate, env=env: env if rate == 100 else
                                    env.with_teaching_rate(rate, seed=spec.seed))
    specific_home = all_new[-1]
    specific_names = None
    for name in all_new:
        env = corpus[name]
        gt = env.ground_truth
        if gt is not None and gt.specific_labels is not None and gt.specific_test is not None:
            specific_names = sorted({gt.specific_labels[i] for i in np.flatnonzero(gt.specific_test)
                                     if gt.specific_labels[i] is not None})

            def taught(rate: int, env: Environment = env, places: list[str] = specific_names) -> Environment:
                return (teach(env, rate, places=places, seed=spec.seed, config=language) if rate > 0
                        else _untaught(env))
        else:
            def taught(rate: int, env: Environment = env) -> Environment:
                return _untaught(env)
        sources[name] = _HomeSource(taught)
    if spec.experiment == "general":
        new = all_new
        if spec.new_homes is not None:
            unknown = [n for n in spec.new_homes if n not in all_new]
            if unknown:
                raise ConfigurationError(f"no synthetic new home {', '.join(map(repr, unknown))}; the "
                                         f"synthetic new homes (seed {spec.seed}): {', '.join(all_new)}")
            new = tuple(spec.new_homes)
        specific = None
    else:
        new = (specific_home,)
        specific = specific_home
        if spec.specific_home not in (None, specific_home) or spec.new_homes not in (None, new):
            raise ConfigurationError(f"the synthetic home-specific experiment uses {specific_home!r}")
    regions = {n: corpus[n].ground_truth.regions for n in all_new
               if corpus[n].ground_truth is not None and corpus[n].ground_truth.regions is not None}
    return experienced, new, specific, sources, regions


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _build_data(spec: _DataSpec, settings: Sequence[int]) -> ExperimentData:
    regions: dict[str, PlaceRegions] = {}
    records: list[Any] = []
    extractor = None
    if spec.source == "synthetic":
        experienced, new, specific, sources, regions = _synthetic_sources(spec)
    else:
        experienced, new, specific, sources, records, extractor = _read_path_sources(spec)
    if spec.regions is not None:
        regions = load_region_file(spec.regions)
    data = ExperimentData(experiment=spec.experiment, experienced=experienced, new_homes=new,
                          specific_home=specific, sources=sources)
    if spec.experiment == "general" and max(settings) > len(experienced):
        raise ConfigurationError(f"--envs asks for {max(settings)} experienced homes but the experiment "
                                 f"has {len(experienced)}: {', '.join(experienced)}")
    data.regions = _check_regions(data, regions, spec, settings)
    sentences = [s for n in experienced for s in data.experienced_home(n).training_data().sentences]
    if spec.experiment == "specific":
        sentences += data.new_home(specific, max(settings)).training_data().sentences  # type: ignore[arg-type]
    data.vocabulary = Vocabulary.from_sentences(sentences, language=spec.text_language)
    if len(data.vocabulary) == 0:
        raise DataFormatError(spec.source, "no taught sentence in any experienced home: there are no "
                              "place names to learn")
    data.description = {
        "source": spec.shown_source or spec.source,
        "language": spec.language,
        "experienced_homes": list(experienced),
        "new_homes": list(new),
        "specific_home": specific,
        "regions": spec.shown_regions or spec.regions,
        "regions_sha256": _file_digest(Path(spec.regions)) if spec.regions else None,
        "vocabulary": list(data.vocabulary.words),
    }
    if data.vocabulary.segmentation is not None:  # (absent otherwise: earlier results resume)
        data.description["segmentation"] = data.vocabulary.segmentation.to_dict()
    if spec.images is not None or spec.extractor is not None:
        from spco.features import DEFAULT_EXTRACTOR

        # the extractor's full description (version, settings, checksum of a learnt codebook): a
        # resumed experiment whose views would be computed differently is another experiment
        data.description["views"] = {"images": spec.shown_images or spec.images,
                                     "extractor": spec.extractor or DEFAULT_EXTRACTOR,
                                     "extractor_spec": extractor.spec().to_dict()}
        data.view_records = records
    return data


def _check_regions(data: ExperimentData, regions: dict[str, PlaceRegions], spec: _DataSpec,
                   settings: Sequence[int]) -> dict[str, PlaceRegions]:
    """Every evaluated home must have labels, scored samples and a region for every scored place."""
    where = spec.regions or spec.source
    out: dict[str, PlaceRegions] = {}
    specific = spec.experiment == "specific"
    for home in data.evaluated_homes:
        rates = settings if specific else (0,)
        for rate in rates:
            data.sources[home].at_rate(rate)  # a missing teaching rate fails here, before any run
        env = data.sources[home].at_rate(rates[0])
        gt = env.ground_truth
        own = regions.get(home)
        if own is None and spec.regions is None and gt is not None:
            own = gt.regions
        if own is None:
            if spec.regions is not None:
                raise DataFormatError(spec.regions, f"no regions for new home {home!r}; the file covers "
                                      f"{', '.join(regions) or 'no home'}")
            raise DataFormatError(spec.source, f"new home {home!r} has no ground-truth regions: pass a "
                                  "region file (--regions, e.g. sigverse_regions.json)")
        if gt is None or (gt.specific_labels if specific else gt.labels) is None:
            kind = "home-specific labels" if specific else "place labels"
            raise DataFormatError(env.source or spec.source, f"new home {home!r} has no {kind} to "
                                  "score predictions against")
        if specific:
            if gt.specific_test is None or not np.asarray(gt.specific_test).any():
                raise DataFormatError(env.source or spec.source, f"new home {home!r} has no "
                                      "home-specific test samples (test_num_specific.txt)")
            rows = np.flatnonzero(np.asarray(gt.specific_test, dtype=bool))
            places = {gt.specific_labels[i] for i in rows}  # type: ignore[index]
        else:
            if env.n_test == 0:
                raise DataFormatError(env.source or spec.source, f"new home {home!r} has no test samples")
            places = set(gt.labels)  # type: ignore[arg-type]
        missing = sorted(p for p in places if p is not None and p not in own.places)
        if missing:
            raise DataFormatError(where, f"the regions of new home {home!r} lack place(s) "
                                  f"{', '.join(missing)} (they have {', '.join(own.places)})")
        out[home] = own
    return out


def _data_spec(config: ExperimentConfig) -> _DataSpec:
    source = config.data
    if source != "synthetic":
        path = Path(source).expanduser()
        if not path.exists():
            raise DataFormatError(path, "no such data folder or file (--data); pass a folder of homes, "
                                  "an spco cache file, or 'synthetic'")
        source = str(path.resolve())
    regions = None
    if config.regions is not None:
        rpath = Path(config.regions).expanduser()
        if not rpath.is_file():
            raise DataFormatError(rpath, "region file not found (--regions)")
        regions = str(rpath.resolve())
    settings = config.settings or ()
    n_needed = max(settings) if config.experiment == "general" and settings else 0
    if config.language != "templates" and source != "synthetic":
        raise ConfigurationError(f"--language {config.language} applies to synthetic homes only (--data "
                                 "synthetic); a data set's sentences are what its people said")
    images = None
    if config.images is not None:
        ipath = Path(config.images).expanduser()
        if not ipath.is_dir():
            raise DataFormatError(ipath, "no such folder of images (--images)")
        images = str(ipath.resolve())
    if source == "synthetic" and (images is not None or config.extractor is not None):
        raise ConfigurationError("synthetic homes have no images; --images and --extractor need --data")
    return _DataSpec(config.experiment, source, regions, config.seed, n_needed,
                     config.experienced_homes, config.new_homes, config.specific_home, config.language,
                     shown_source=str(config.data),
                     shown_regions=None if config.regions is None else str(config.regions),
                     images=images, extractor=config.extractor,
                     shown_images=None if config.images is None else str(config.images),
                     text_language=config.text_language)


def load_experiment_data(config: ExperimentConfig) -> ExperimentData:
    """Load (or generate) the homes of ``config`` and check them: home lists, teaching rates,
    labels and ground-truth regions of the new homes. Raises :class:`~spco.errors.SpcoError`
    subclasses with a message naming the file or option at fault."""
    config = config.validated()
    return _build_data(_data_spec(config), config.settings or ())


# ------------------------------------------------------------------------------------ maps
def _find_maps(config: ExperimentConfig, spec: _DataSpec) -> str | None:
    """The folder of floor plans, written as given (or found beside --regions or --data as given),
    so that result files hold no absolute path of the machine that ran them."""
    if config.maps is not None:
        folder = Path(config.maps).expanduser()
        if not folder.is_dir():
            raise DataFormatError(folder, "no such folder of floor plans (--maps)")
        return str(config.maps)
    candidates = []
    if spec.regions is not None:
        candidates.append(Path(spec.shown_regions or spec.regions).parent / MAPS_DIR)
    if spec.source != "synthetic":
        src = Path(spec.shown_source or spec.source)
        candidates += [src / MAPS_DIR, src.parent / MAPS_DIR]
    for folder in candidates:
        if folder.expanduser().is_dir():
            return str(folder)
    return None


def _map_image(maps: str | None, home: str) -> tuple[Path | None, tuple[float, ...] | None]:
    if maps is None:
        return None, None
    folder = Path(maps).expanduser()
    image = next((folder / f"{home}{ext}" for ext in (".PNG", ".png")
                  if (folder / f"{home}{ext}").is_file()), None)
    extent = None
    extents = folder / "extents.json"
    if extents.is_file():
        with contextlib.suppress(OSError, ValueError, TypeError):
            homes = json.loads(extents.read_text(encoding="utf-8")).get("homes", {})
            if home in homes and len(homes[home]) == 4:
                extent = tuple(float(v) for v in homes[home])
    return image, extent


def _slug(text: str) -> str:
    """A file-name-safe form: ``"spcotransfer+mi"`` -> ``"spcotransfer_mi"``."""
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in text)


def map_path(out: Path, experiment: str, model: str, setting: int, home: str) -> Path:
    """Where the map figure of a run is written."""
    return out / MAPS_DIR / f"{experiment}_{_slug(model)}_{setting}_{_slug(home)}.png"


def _draw_map(model: SpatialConceptModel, e: int, env: Environment, scores: HomeScores, path: Path,
              maps: str | None, title: str) -> None:
    from spco import plots

    image, extent = _map_image(maps, env.name)
    gt = env.ground_truth
    if gt is not None and gt.regions is not None:  # outline the scored places only
        shown = PlaceRegions({p: r for p, r in gt.regions.places.items() if p in scores.places})
        env = replace(env, ground_truth=replace(gt, regions=shown))
    labels = list(scores.labels)
    order = list(dict.fromkeys(lab for lab in labels if lab is not None))
    picked = [order[int(i)] for i in np.linspace(0, len(order) - 1, min(_POSES_ON_MAP, len(order)))] \
        if order else []
    rows = [labels.index(p) for p in dict.fromkeys(picked)]
    names = scores.name_predictions
    pose_names = [list(zip(names.words[i].tolist(), names.probabilities[i].tolist(), strict=True))
                  for i in rows]
    plots.plot_home_map(model.parameters_, e, env, model.vocabulary_,
                        map_image=image, map_extent=extent,
                        predicted_positions=scores.predicted_positions,
                        poses=scores.test_positions[rows] if rows else None,
                        pose_names=pose_names if rows else None,
                        show_ground_truth=True, title=title, path=path)


# ------------------------------------------------------------------------------------ runs
@dataclass(frozen=True, order=True)
class RunKey:
    """One run: a model fitted for one setting, new home and trial."""

    setting: int
    trial: int
    home: str
    model: str


@dataclass(frozen=True)
class _RunContext:
    """What a run needs besides the data (picklable, sent to every worker)."""

    experiment: str
    iterations: int
    seed: int
    n_positions: int
    hyperparameters: TransferHyperparameters | None
    fingerprint: str
    out: str
    maps: str | None
    map_setting: int  # maps and log-joint traces: trial 0 at this setting


def execute_run(data: ExperimentData, ctx: _RunContext, key: RunKey) -> dict[str, Any]:
    """Fit one model for one run, score it and return its record (a line of ``runs.jsonl``)."""
    spec = MODELS[key.model]
    seed = trial_seed(ctx.seed, key.trial)
    traced = key.trial == 0 and key.setting == ctx.map_setting
    start = time.perf_counter()
    homes = data.homes_for(key.setting, key.home)
    from spco.data.environment import Corpus

    model = spec.build(ctx.iterations, seed, ctx.hyperparameters, traced)
    if spec.single_home:
        corpus = Corpus([homes[-1]], vocabulary=data.vocabulary)
    else:
        corpus = Corpus(homes, vocabulary=data.vocabulary)
    model.fit(corpus)
    e = len(corpus) - 1
    env = homes[-1]
    specific = ctx.experiment == "specific"
    scores = evaluate_home(model.parameters_, e, env, model.vocabulary_, specific=specific,
                           n_positions=ctx.n_positions, rng=np.random.default_rng([seed, 1]),
                           weighting=spec.weighting)
    wall = time.perf_counter() - start
    if traced:
        path = map_path(Path(ctx.out), ctx.experiment, key.model, key.setting, key.home)
        what = "experienced homes" if ctx.experiment == "general" else "% taught"
        _draw_map(model, e, env, scores, path, ctx.maps,
                  f"{key.home}: {key.model}, {key.setting} {what}, trial 0")

    def clean(v: float) -> float | None:
        return None if v is None or math.isnan(v) else float(v)

    return {
        "fingerprint": ctx.fingerprint,
        "experiment": ctx.experiment,
        "model": key.model,
        "setting": key.setting,
        "home": key.home,
        "trial": key.trial,
        "seed": seed,
        "iterations": ctx.iterations,
        "wall_seconds": round(wall, 4),
        "name_accuracy": {p: clean(v) for p, v in scores.name_accuracy.items()},
        "position_accuracy": {p: clean(v) for p, v in scores.position_accuracy.items()},
        "mean_name_accuracy": clean(scores.mean_name_accuracy),
        "mean_position_accuracy": clean(scores.mean_position_accuracy),
        "name_chance": clean(scores.name_chance),
        "position_chance": clean(scores.position_chance),
        "log_joint": [round(float(v), 3) for v in model.log_joint_] if traced else None,
    }


# -------------------------------------------------------------------------- worker processes
_WORKER: tuple[ExperimentData, _RunContext] | None = None


def _init_worker(spec: _DataSpec, settings: tuple[int, ...], ctx: _RunContext, threads: int) -> None:
    global _WORKER
    with contextlib.suppress(Exception):  # numba may be missing a threading layer; runs still work
        import numba

        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    _WORKER = (_build_data(spec, settings), ctx)


def _worker_run(key: RunKey) -> dict[str, Any]:
    if _WORKER is None:  # pragma: no cover - the initializer always runs first
        raise RuntimeError("worker not initialised")
    data, ctx = _WORKER
    return execute_run(data, ctx, key)


# numba's own thread count is set in each worker (numba.set_num_threads); NUMBA_NUM_THREADS is left
# alone, as changing it in this process after numba started its threads is an error.
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def _child_threads(threads: int) -> Iterator[None]:
    """Environment of spawned workers: ``threads`` BLAS threads each (read when numpy loads)."""
    saved = {k: os.environ.get(k) for k in _THREAD_VARIABLES}
    for k in _THREAD_VARIABLES:
        os.environ[k] = str(threads)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _ray_run(spec: _DataSpec, settings: tuple[int, ...], ctx: _RunContext, key: RunKey) -> dict[str, Any]:
    """One run in a Ray worker; the experiment's data is built once per worker process."""
    global _WORKER, _WORKER_SOURCE
    if _WORKER is None or _WORKER_SOURCE != (spec, settings):
        _init_worker(spec, settings, ctx, 1)
        _WORKER_SOURCE = (spec, settings)
    return execute_run(_WORKER[0], ctx, key)


_WORKER_SOURCE: tuple | None = None


def _run_on_ray(pending: Sequence[RunKey], spec: _DataSpec, settings: tuple[int, ...], ctx: _RunContext,
                address: str | None, on_result: Callable[[dict[str, Any]], None]) -> None:
    """Every pending run as a Ray task (one CPU each); results are stored as they arrive."""
    try:
        import ray
    except ImportError:
        raise ConfigurationError("engine 'ray' needs Ray: pip install 'spco[ray]'") from None
    if not ray.is_initialized():
        ray.init(address=address, log_to_driver=False)
    task = ray.remote(num_cpus=1, max_retries=2)(_ray_run)
    spec_ref, ctx_ref = ray.put(spec), ray.put(ctx)
    waiting = [task.remote(spec_ref, settings, ctx_ref, key) for key in pending]
    try:
        while waiting:
            done, waiting = ray.wait(waiting, num_returns=1)
            on_result(ray.get(done[0]))
    except BaseException:
        for ref in waiting:  # a stopped experiment leaves no run computing in the background
            ray.cancel(ref, force=True)
        raise


def _run_pending(pending: Sequence[RunKey], data: ExperimentData, spec: _DataSpec,
                 settings: tuple[int, ...], ctx: _RunContext, jobs: int,
                 on_result: Callable[[dict[str, Any]], None], engine: str = "local",
                 address: str | None = None) -> None:
    if engine == "ray" and pending:
        _run_on_ray(pending, spec, settings, ctx, address, on_result)
        return
    if jobs == 1 or len(pending) <= 1:
        for key in pending:
            on_result(execute_run(data, ctx, key))
        return
    jobs = min(jobs, len(pending))
    threads = max(1, (os.cpu_count() or 1) // jobs)
    with _child_threads(threads), _sigterm_as_interrupt():
        pool = ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_init_worker, initargs=(spec, settings, ctx, threads))
        try:
            futures: set[Future[dict[str, Any]]] = {pool.submit(_worker_run, key) for key in pending}
            while futures:
                done, futures = wait(futures, return_when=FIRST_COMPLETED)
                for fut in done:
                    on_result(fut.result())
        except BaseException:
            # stop the workers too: a killed experiment must not leave runs computing in the background
            workers = list((getattr(pool, "_processes", None) or {}).values())
            for process in workers:
                process.terminate()
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)


@contextlib.contextmanager
def _views_for_workers(data: ExperimentData, spec: _DataSpec, out: Path, pending: Sequence[RunKey],
                       jobs: int, engine: str) -> Iterator[_DataSpec]:
    """The recipe worker processes rebuild the data from. Views computed from images are written
    once to a cache file in a temporary folder of ``out`` (removed afterwards), so that each worker
    reads the counts instead of reading and extracting every image again (~30 s per worker on
    SIGVerse); otherwise ``spec`` itself."""
    in_workers = engine == "ray" or (jobs > 1 and len(pending) > 1)
    if not (in_workers and pending and data.view_records):
        yield spec
        return
    from spco.data.cache import write_records

    folder = Path(tempfile.mkdtemp(prefix=".views-", dir=out))
    try:
        views = folder / "views.npz"
        write_records(data.view_records, views)
        yield replace(spec, source=str(views.resolve()), images=None, extractor=None)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Treat SIGTERM (``kill``) like Ctrl-C while worker processes run, so they are stopped too."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


# ------------------------------------------------------------------------------------ output dir
def _identity(config: ExperimentConfig, data: ExperimentData) -> dict[str, Any]:
    hyper = {m: MODELS[m].hyperparameters(config.hyperparameters).to_dict() for m in config.models or ()}
    return {
        "experiment": config.experiment,
        "models": list(config.models or ()),
        "settings": list(config.settings or ()),
        "iterations": config.iterations,
        "seed": config.seed,
        "n_positions": config.n_positions,
        "data": data.description,
        "hyperparameters": json.loads(json.dumps(hyper)),
    }


def _fingerprint(identity: Mapping[str, Any]) -> str:
    text = json.dumps(identity, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _artefacts(out: Path) -> list[Path]:
    """The files an experiment writes in ``out`` (removed by ``force``)."""
    names = [out / n for n in (CONFIG_FILE, RUNS_FILE, RESULTS_FILE, TABLES_FILE)]
    names += sorted(out.glob("general_*.png")) + sorted(out.glob("specific_*.png"))
    if (out / MAPS_DIR).is_dir():
        names += sorted((out / MAPS_DIR).glob("*.png"))
    return [p for p in names if p.is_file()]


def _short(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _differences(old: Mapping[str, Any], new: Mapping[str, Any], prefix: str = "") -> list[str]:
    """Readable ``key: old -> new`` lines; hyperparameters are compared for shared models only."""
    diffs = []
    for key in sorted(set(old) | set(new), key=lambda k: (isinstance(old.get(k, new.get(k)), dict), k)):
        a, b = old.get(key), new.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            if prefix == "" and key == "hyperparameters":
                shared = set(a) & set(b)
                a, b = ({m: v for m, v in d.items() if m in shared} for d in (a, b))
            diffs += _differences(a, b, f"{prefix}{key}.")
        elif a != b:
            diffs.append(f"{prefix}{key}: {_short(a)} -> {_short(b)}")
    return diffs


def _prepare_out(out: Path, identity: Mapping[str, Any], fingerprint: str, resume: bool,
                 force: bool) -> None:
    if resume and force:
        raise ConfigurationError("choose one of --resume (continue) and --force (start over)")
    if out.exists() and not out.is_dir():
        raise ConfigurationError(f"{out}: exists and is not a folder (--out)")
    config_file = out / CONFIG_FILE
    non_empty = out.is_dir() and any(out.iterdir())
    if force:
        for path in _artefacts(out):
            path.unlink()
    elif resume and config_file.is_file():
        try:
            stored = json.loads(config_file.read_text(encoding="utf-8"))
            old_identity = stored["identity"]
            old_print = stored["fingerprint"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise DataFormatError(config_file, f"not a readable experiment configuration ({exc}); use "
                                  "--force to start over or another --out") from None
        if old_print != fingerprint:
            diffs = _differences(old_identity, dict(identity)) or ["(fingerprint differs)"]
            raise ConfigurationError(
                f"{out} holds an experiment with another configuration, refusing to mix results: "
                + "; ".join(diffs[:6]) + ("; …" if len(diffs) > 6 else "")
                + ". Use the same options to resume, --force to start over, or another --out")
    elif resume and non_empty:
        raise ConfigurationError(f"{out} is not empty but holds no experiment ({CONFIG_FILE} missing); "
                                 "use another --out, or --force to start over")
    elif non_empty:
        raise ConfigurationError(f"{out} is not empty; use --resume to continue the experiment there, "
                                 "--force to start over, or another --out")
    out.mkdir(parents=True, exist_ok=True)


def _write_json_atomic(path: Path, payload: Any) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(payload, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def _write_text_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def read_runs(out: Path, fingerprint: str | None = None) -> list[dict[str, Any]]:
    """The finished runs recorded in ``out/runs.jsonl``.

    A damaged line (an interrupted write) is dropped and the file rewritten without it, so appending
    can continue. With ``fingerprint``, a run of another configuration is an error.
    """
    path = out / RUNS_FILE
    if not path.is_file():
        return []
    text = path.read_text(encoding="utf-8", errors="replace")
    records, dropped = [], 0
    for line in text.splitlines():
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
            if not isinstance(rec, dict) or "model" not in rec:
                raise ValueError("not a run record")
        except ValueError:
            dropped += 1
            continue
        records.append(rec)
    if dropped or (text and not text.endswith("\n")):
        _write_text_atomic(path, "".join(json.dumps(r, allow_nan=False) + "\n" for r in records))
        if dropped:
            print(f"warning: {path}: dropped {dropped} damaged line(s) (an interrupted write); "
                  "those runs are done again", file=sys.stderr)
    if fingerprint is not None:
        foreign = [r for r in records if r.get("fingerprint") != fingerprint]
        if foreign:
            raise ConfigurationError(f"{path}: {len(foreign)} run(s) were made with another "
                                     "configuration; use --force to start over or another --out")
    return records


def _append_run(path: Path, record: Mapping[str, Any]) -> None:
    line = json.dumps(record, allow_nan=False) + "\n"
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(line)
        fh.flush()
        os.fsync(fh.fileno())


# ------------------------------------------------------------------------------------ results
@dataclass
class ExperimentResults:
    """What :func:`run_experiment` wrote: the content of ``results.json`` and the files."""

    out: Path
    results: dict[str, Any]
    tables: str
    figures: list[Path]

    @property
    def runs(self) -> list[dict[str, Any]]:
        """Per-run, per-place rows."""
        return self.results["runs"]

    @property
    def summary(self) -> list[dict[str, Any]]:
        """Summary rows over new homes and trials."""
        return self.results["summary"]


def _run_rows(record: Mapping[str, Any]) -> list[dict[str, Any]]:
    base = {k: record[k] for k in ("experiment", "model", "setting", "home", "trial")}
    tail = {k: record[k] for k in ("seed", "iterations", "wall_seconds")}
    tail["reused_from_setting"] = record.get("reused_from_setting")
    places = report.place_order([*record["name_accuracy"], *record["position_accuracy"]])
    rows = [{**base, "place": p, "name_accuracy": record["name_accuracy"].get(p),
             "position_accuracy": record["position_accuracy"].get(p), **tail} for p in places]
    rows.append({**base, "place": report.MEAN, "name_accuracy": record["mean_name_accuracy"],
                 "position_accuracy": record["mean_position_accuracy"], **tail})
    return rows


def _mean_of(values: Sequence[float | None]) -> float | None:
    clean = [v for v in values if v is not None]
    return float(np.mean(clean)) if clean else None


def _assemble(config: ExperimentConfig, identity: Mapping[str, Any], fingerprint: str,
              records: Sequence[Mapping[str, Any]], session_seconds: float,
              session_runs: int, maps: str | None) -> dict[str, Any]:
    from spco import __version__

    rows = [row for rec in records for row in _run_rows(rec)]
    by = ("experiment", "model", "setting", "place")
    summary = report.summarize(rows, by)
    order = {p: i for i, p in enumerate([*report.place_order(r["place"] for r in rows), report.MEAN])}
    models = {m: i for i, m in enumerate(config.models or ())}
    summary.sort(key=lambda r: (models[r["model"]], r["setting"], order[r["place"]]))
    by_home = report.summarize(rows, ("experiment", "model", "setting", "home", "place"))
    by_home.sort(key=lambda r: (models[r["model"]], r["setting"], r["home"], order[r["place"]]))
    chance_by_home: dict[str, dict[str, float | None]] = {}
    for rec in records:
        chance_by_home.setdefault(rec["home"], {"name_accuracy": rec["name_chance"],
                                                "position_accuracy": rec["position_chance"]})
    chance = {
        "name_accuracy": _mean_of([c["name_accuracy"] for c in chance_by_home.values()]),
        "position_accuracy": _mean_of([c["position_accuracy"] for c in chance_by_home.values()]),
        "by_home": chance_by_home,
    }
    return {
        "format": RESULTS_FORMAT,
        "version": FORMAT_VERSION,
        "config": {**identity, "trials": config.trials, "maps": maps, "fingerprint": fingerprint,
                   "spco_version": __version__},
        "runs": rows,
        "summary": summary,
        "summary_by_home": by_home,
        "chance": chance,
        "timing": {
            "runs": len(records),
            "runs_reused": sum(r.get("reused_from_setting") is not None for r in records),
            "runs_this_session": session_runs,
            "run_wall_seconds_total": round(sum(r["wall_seconds"] for r in records), 3),
            "session_wall_seconds": round(session_seconds, 3),
        },
    }


def _setting_label(experiment: str) -> str:
    return "experienced homes" if experiment == "general" else "teaching rate [%]"


def _figures(out: Path, config: ExperimentConfig, results: Mapping[str, Any],
             records: Sequence[Mapping[str, Any]]) -> list[Path]:
    from spco import plots

    experiment = config.experiment
    settings = list(config.settings or ())
    models = list(config.models or ())
    index = {(r["model"], r["setting"]): r for r in results["summary"] if r["place"] == report.MEAN}
    written = []
    xlabel = ("number of experienced homes" if experiment == "general"
              else "teaching rate of the home-specific rooms [%]")
    for measure, label in (("name_accuracy", "name accuracy A_n"),
                           ("position_accuracy", "position accuracy A_p")):
        means, stds = {}, {}
        for model in models:
            rows = [index.get((model, s)) for s in settings]
            means[model] = [np.nan if r is None or r[f"{measure}_mean"] is None else r[f"{measure}_mean"]
                            for r in rows]
            stds[model] = [0.0 if r is None or r[f"{measure}_std"] is None else r[f"{measure}_std"]
                           for r in rows]
        path = out / f"{experiment}_{measure}.png"
        plots.plot_accuracy_curve(settings, means, stds, results["chance"][measure], xlabel,
                                        f"{experiment} places: {label}", path=path)
        written.append(path)
    top = max(settings)
    for model in models:
        traces = {r["home"]: r["log_joint"] for r in records
                  if r["model"] == model and r["setting"] == top and r["trial"] == 0 and r.get("log_joint")}
        if traces:
            path = out / f"{experiment}_log_joint_{_slug(model)}.png"
            plots.plot_log_joint(dict(sorted(traces.items())), path=path,
                                 title=f"{model}: log joint, {top} {_setting_label(experiment)}, trial 0")
            written.append(path)
    written += sorted((out / MAPS_DIR).glob(f"{experiment}_*.png")) if (out / MAPS_DIR).is_dir() else []
    return written


def _tables(config: ExperimentConfig, results: Mapping[str, Any]) -> str:
    experiment = config.experiment
    data = results["config"]["data"]
    homes = ", ".join(data["new_homes"])
    if experiment == "general":
        title = "General places: accuracy in the new homes vs. number of experienced homes"
        scope = f"new homes {homes}, taught nothing"
    else:
        title = "Home-specific places: accuracy vs. teaching rate of the home-specific rooms"
        scope = f"new home {homes}, {len(data['experienced_homes'])} experienced homes"
    timing = results["timing"]
    note = (f"{scope}; {config.trials} trial(s) per setting and home, {config.iterations} Gibbs "
            f"iterations, seed {config.seed}, data: {data['source']}. Cells: mean (sample std) over "
            f"new homes × trials; `mean`: mean over places of each run, then over runs. Chance: "
            f"A_n 1/|V| (|V| = {len(data['vocabulary'])}), A_p 1/|places|. "
            f"{timing['runs']} runs, {timing['run_wall_seconds_total']:.0f} s of run time.")
    return report.markdown_tables(results["summary"], experiment=experiment, models=list(config.models or ()),
                                  settings=list(config.settings or ()),
                                  setting_label=_setting_label(experiment), chance=results["chance"],
                                  title=title, note=note)


def plan_runs(config: ExperimentConfig, data: ExperimentData) -> list[RunKey]:
    """Every run of the experiment, trial by trial (so early results cover all settings)."""
    config = config.validated()
    return [RunKey(setting, trial, home, model)
            for trial in range(config.trials)
            for setting in config.settings or ()
            for home in data.evaluated_homes
            for model in config.models or ()]


def shared_runs(config: ExperimentConfig, planned: Sequence[RunKey]) -> dict[RunKey, RunKey]:
    """Runs whose result is that of another run: ``{run: the run it is copied from}``.

    In the general experiment a single-home model (:attr:`ModelSpec.single_home`) fits the new
    home alone with the trial's seed, so its run at any number of experienced homes is its run at
    the largest one. Empty for the specific experiment (the teaching rate changes the new home).
    """
    config = config.validated()
    if config.experiment != "general" or not config.settings:
        return {}
    top = max(config.settings)
    return {k: replace(k, setting=top) for k in planned
            if MODELS[k.model].single_home and k.setting != top}


def _reused_record(source: Mapping[str, Any], key: RunKey) -> dict[str, Any]:
    """The record of run ``key``, copied from the record of the run it shares its result with."""
    return {**source, "setting": key.setting, "wall_seconds": 0.0, "log_joint": None,
            "reused_from_setting": source["setting"]}


def run_experiment(
    config: ExperimentConfig,
    out: str | os.PathLike[str],
    *,
    resume: bool = False,
    force: bool = False,
    progress: bool = False,
    max_runs: int | None = None,
    log: Callable[[str], None] | None = None,
) -> ExperimentResults:
    """Run (or continue) an experiment and write its outputs into folder ``out``.

    Parameters
    ----------
    config: the experiment (:class:`ExperimentConfig`).
    out: the output folder; it must be empty or absent unless ``resume`` or ``force``.
    resume: continue the experiment in ``out`` (its configuration must be the same; ``trials`` may
        differ — a run's result does not depend on the number of trials).
    force: delete the outputs of a previous experiment in ``out`` and start over.
    progress: a progress bar over runs on stderr.
    max_runs: stop after this many new runs (the rest is left for ``resume``); outputs are written
        for the runs done so far.
    log: called with short status messages (default: none).

    Raises :class:`~spco.errors.SpcoError` subclasses for bad input (unknown model, bad settings,
    missing data or regions, a foreign configuration in ``out``).
    """
    started = time.perf_counter()
    say = log or (lambda _msg: None)
    config = config.validated()
    spec = _data_spec(config)
    settings = config.settings or ()
    data = _build_data(spec, settings)
    maps = _find_maps(config, spec)
    identity = _identity(config, data)
    fingerprint = _fingerprint(identity)
    out_path = Path(out).expanduser()
    _prepare_out(out_path, identity, fingerprint, resume, force)
    from spco import __version__

    _write_json_atomic(out_path / CONFIG_FILE, {
        "format": CONFIG_FORMAT, "version": FORMAT_VERSION, "fingerprint": fingerprint,
        "identity": identity, "trials": config.trials, "jobs": config.jobs, "maps": maps,
        "spco_version": __version__,
    })
    planned = plan_runs(config, data)
    sources = shared_runs(config, planned)
    done = {}
    for rec in read_runs(out_path, fingerprint):
        done[RunKey(rec["setting"], rec["trial"], rec["home"], rec["model"])] = rec
    pending = [k for k in planned if k not in done]
    if done:
        say(f"resuming: {sum(k in done for k in planned)} of {len(planned)} runs already done")
    copies: dict[RunKey, list[RunKey]] = {}  # a run to compute -> the runs recorded from its result
    for key in pending:
        if key in sources:
            copies.setdefault(sources[key], []).append(key)
    pending = [k for k in pending if k not in sources]
    if max_runs is not None:
        pending = pending[:max(0, int(max_runs))]
    ctx = _RunContext(config.experiment, config.iterations, config.seed, config.n_positions,
                      config.hyperparameters, fingerprint, str(out_path), maps, max(settings))
    runs_file = out_path / RUNS_FILE
    from tqdm import tqdm

    bar = tqdm(total=len(pending), desc=f"{config.experiment} experiment", unit="run", file=sys.stderr,
               disable=not progress or not pending, dynamic_ncols=True)
    finished = 0

    def store(record: dict[str, Any]) -> None:
        _append_run(runs_file, record)
        key = RunKey(record["setting"], record["trial"], record["home"], record["model"])
        done[key] = record
        for copy in copies.pop(key, []):
            store(_reused_record(record, copy))

    for source in [k for k in copies if k in done]:  # computed before an interruption
        for copy in copies.pop(source):
            store(_reused_record(done[source], copy))

    def on_result(record: dict[str, Any]) -> None:
        nonlocal finished
        store(record)
        finished += 1
        bar.set_postfix_str(f"{record['model']} {record['setting']} {record['home']}: "
                            f"A_n={_fmt(record['mean_name_accuracy'])} "
                            f"A_p={_fmt(record['mean_position_accuracy'])}", refresh=False)
        bar.update(1)

    try:
        with _views_for_workers(data, spec, out_path, pending, config.jobs, config.engine) as worker_spec:
            _run_pending(pending, data, worker_spec, settings, ctx, config.jobs, on_result, config.engine,
                         config.address)
    except KeyboardInterrupt:
        bar.close()
        say(f"interrupted after {finished} run(s) of this session; they are saved in {runs_file}: "
            "continue with --resume")
        raise
    finally:
        bar.close()
    records = [done[k] for k in planned if k in done]
    if not records:
        raise ConfigurationError("no run finished, nothing to report")
    results = _assemble(config, identity, fingerprint, records, time.perf_counter() - started, finished,
                        maps)
    _write_json_atomic(out_path / RESULTS_FILE, results)
    tables = _tables(config, results)
    _write_text_atomic(out_path / TABLES_FILE, tables)
    figures = _figures(out_path, config, results, records)
    if len(records) < len(planned):
        say(f"{len(planned) - len(records)} of {len(planned)} runs still to do: continue with --resume")
    return ExperimentResults(out_path, results, tables, figures)


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def describe_models() -> str:
    """One line per model of the registry, for help texts."""
    return "\n".join(f"{name}: {spec.description}" for name, spec in MODELS.items())

