"""An experiment's configuration (:class:`ExperimentConfig`): which experiment, homes, models,
settings, trials and seed; the paper's homes and settings."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from spco.errors import ConfigurationError
from spco.evaluation.models import MODELS
from spco.model.hyperparameters import TransferHyperparameters

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
    views_missing: percentage (0–100) of the new home's views removed at random in each run (its
        samples then have no view, train and test alike; a camera that drops frames, or none at
        all at 100); drawn from the trial's seed, so every model and setting of a trial loses the
        same views.
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
    views_missing: float = 0.0

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
        numeric = int | float | np.integer | np.floating
        if isinstance(self.views_missing, bool) or not isinstance(self.views_missing, numeric) \
                or not 0 <= float(self.views_missing) <= 100:
            raise ConfigurationError(f"views_missing must be a percentage within 0..100, got "
                                     f"{self.views_missing!r}")
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
