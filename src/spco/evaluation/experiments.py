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

*Word lists.* In the general experiment every run uses the same word list: the words of all
experienced homes at rate 100, so the chance level of A_n, ``1/|V|``, is the same in every setting,
and with ``n = 0`` (no word ever observed) the models still have names to choose from — at chance.
In the specific experiment each teaching rate has its own: the experienced homes' words and those
the new home was taught *at that rate* (``ExperimentData.vocabulary_for``): a run at 20 % has no
column for a name taught only at 100 %. ``data.vocabulary`` in the results is the highest rate's,
``data.vocabulary_by_rate`` each rate's.

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
                          "vocabulary": [str],
                          "vocabulary_by_rate": {rate: [str]}},   # specific experiment only
                 "hyperparameters": {model: {name: value}}, "fingerprint": str,
                 "spco_version": str},
      "runs": [   # one row per run and place, plus one row with place "mean" per run
        {"experiment": str, "model": str,
         "setting": int,          # general: number of experienced homes; specific: teaching rate
         "home": str,             # the new home
         "trial": int, "place": str,   # a normalised place name, or "mean" (mean over the places)
         "name_accuracy": float | null,       # null: not scored
         "position_accuracy": float | null,   # A_p, positions from the most probable region
                                              # (the authors' code)
         "position_accuracy_mixture": float | null,   # A_p, positions sampled from the whole
                                              # mixture p(x | name) (the paper's text)
         "seed": int,             # the run's random_state
         "iterations": int, "wall_seconds": float,   # fit + evaluation time of the run
         "reused_from_setting": int | null}   # the run was computed at that setting (see above)
      ],
      "summary": [   # over new homes and trials
        {"experiment", "model", "setting", "place",          # place "mean": mean of per-run means
         "name_accuracy_mean", "name_accuracy_std",          # std: sample std (ddof=1), null if n < 2
         "position_accuracy_mean", "position_accuracy_std",
         "position_accuracy_mixture_mean", "position_accuracy_mixture_std", "n"}   # n: number of runs
      ],
      "summary_by_home": [ same keys as "summary" plus "home" ],
      "chance": {"name_accuracy": 1/|V|, "position_accuracy": mean over new homes of 1/|places|,
                 "position_accuracy_mixture": the same,
                 "by_home": {home: {"name_accuracy": float, "position_accuracy": float}}},
      "timing": {"runs": int, "runs_reused": int, "runs_this_session": int,
                 "run_wall_seconds_total": float, "session_wall_seconds": float}
    }   # runs_this_session: runs computed by this call; runs_reused: records copied from another

Accuracies are fractions in [0, 1]; a place without scored samples (or without a ground-truth area)
is ``null`` and left out of the means.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from spco.errors import ConfigurationError
from spco.evaluation.config import (
    CONFIG_FILE,
    CONFIG_FORMAT,
    DEFAULT_RATES,
    DEFAULT_SETTINGS,
    FORMAT_VERSION,
    PAPER_EXPERIENCED_HOMES,
    PAPER_NEW_HOMES,
    PAPER_SPECIFIC_HOME,
    RESULTS_FILE,
    RUNS_FILE,
    TABLES_FILE,
    ExperimentConfig,
    parse_int_list,
    parse_models,
    trial_seed,
)
from spco.evaluation.homes import (
    ExperimentData,
    _build_data,
    _data_spec,
    load_experiment_data,
)
from spco.evaluation.models import (
    MODELS,
    ModelSpec,
    _fmt,
    describe_models,
)
from spco.evaluation.results import (
    ExperimentResults,
    _append_run,
    _assemble,
    _figures,
    _fingerprint,
    _identity,
    _prepare_out,
    _tables,
    _write_json_atomic,
    _write_text_atomic,
    read_runs,
)
from spco.evaluation.runs import (
    RunKey,
    _find_maps,
    _run_pending,
    _RunContext,
    _views_for_workers,
    execute_run,
    map_path,
)

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


def _runs_to_compute(config: ExperimentConfig, planned: list[RunKey], done: Mapping[RunKey, Any],
                     max_runs: int | None) -> tuple[list[RunKey], dict[RunKey, list[RunKey]]]:
    """The runs still to compute (at most ``max_runs``), and for each run computed, the runs recorded
    from its result (runs that would repeat it exactly, :func:`shared_runs`)."""
    sources = shared_runs(config, planned)
    pending = [k for k in planned if k not in done]
    copies: dict[RunKey, list[RunKey]] = {}  # a run to compute -> the runs recorded from its result
    for key in pending:
        if key in sources:
            copies.setdefault(sources[key], []).append(key)
    pending = [k for k in pending if k not in sources]
    if max_runs is not None:
        pending = pending[:max(0, int(max_runs))]
    return pending, copies


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
    done = {RunKey(rec["setting"], rec["trial"], rec["home"], rec["model"]): rec
            for rec in read_runs(out_path, fingerprint)}
    if done:
        say(f"resuming: {sum(k in done for k in planned)} of {len(planned)} runs already done")
    pending, copies = _runs_to_compute(config, planned, done, max_runs)
    ctx = _RunContext(config.experiment, config.iterations, config.seed, config.n_positions,
                      config.hyperparameters, fingerprint, str(out_path), maps, max(settings),
                      float(config.views_missing))
    runs_file = out_path / RUNS_FILE
    from spco.progress import progress_bar

    bar = progress_bar(total=len(pending), desc=f"{config.experiment} experiment", unit="run",
                       disable=not progress or not pending)
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
    if len(records) < len(planned) and records:
        say(f"{len(planned) - len(records)} of {len(planned)} runs still to do: continue with --resume")
    return _write_outputs(out_path, config, identity, fingerprint, records, time.perf_counter() - started,
                          finished, maps)


def _write_outputs(out_path: Path, config: ExperimentConfig, identity: Mapping[str, Any], fingerprint: str,
                   records: list[dict[str, Any]], seconds: float, finished: int,
                   maps: Any) -> ExperimentResults:
    """``results.json``, ``tables.md`` and the figures of the runs done so far."""
    if not records:
        raise ConfigurationError("no run finished, nothing to report")
    results = _assemble(config, identity, fingerprint, records, seconds, finished, maps)
    _write_json_atomic(out_path / RESULTS_FILE, results)
    tables = _tables(config, results)
    _write_text_atomic(out_path / TABLES_FILE, tables)
    figures = _figures(out_path, config, results, records)
    return ExperimentResults(out_path, results, tables, figures)


