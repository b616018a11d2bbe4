"""One run of an experiment (:func:`execute_run`: one model, setting and trial fitted and scored on
the new homes), its map figures, and running many in worker processes or on Ray."""

from __future__ import annotations

import contextlib
import json
import multiprocessing
import os
import shutil
import signal
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.environment import Environment
from spco.data.regions import PlaceRegions
from spco.errors import ConfigurationError, DataFormatError
from spco.evaluation.config import _POSES_ON_MAP, MAPS_DIR, ExperimentConfig, trial_seed
from spco.evaluation.homes import ExperimentData, _build_data, _DataSpec
from spco.evaluation.metrics import HomeScores, evaluate_answers
from spco.evaluation.models import MODELS
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.transfer import SpatialConceptModel


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
def without_views(home: Environment, percent: float, seed: int) -> Environment:
    """``home`` with ``percent`` % of its samples' views removed, chosen at random from ``seed``
    (the same seed removes the same views; a higher percentage removes a superset)."""
    order = np.random.default_rng([seed, 2]).permutation(home.n_samples)
    missing = np.zeros(home.n_samples, dtype=bool)
    missing[order[:round(home.n_samples * percent / 100.0)]] = True
    return home.with_views_missing(missing)


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
    views_missing: float = 0.0  # percent of the new home's views removed (ExperimentConfig)


def execute_run(data: ExperimentData, ctx: _RunContext, key: RunKey) -> dict[str, Any]:
    """Fit one model for one run, score it and return its record (a line of ``runs.jsonl``)."""
    spec = MODELS[key.model]
    seed = trial_seed(ctx.seed, key.trial)
    traced = key.trial == 0 and key.setting == ctx.map_setting
    start = time.perf_counter()
    homes = data.homes_for(key.setting, key.home)
    if ctx.views_missing > 0:
        homes[-1] = without_views(homes[-1], ctx.views_missing, seed)
    from spco.data.environment import Corpus

    model = spec.build(ctx.iterations, seed, ctx.hyperparameters, traced)
    vocabulary = data.vocabulary_for(key.setting)
    if spec.single_home:
        corpus = Corpus([homes[-1]], vocabulary=vocabulary)
    else:
        corpus = Corpus(homes, vocabulary=vocabulary)
    model.fit(corpus)
    e = len(corpus) - 1
    env = homes[-1]
    specific = ctx.experiment == "specific"
    # what the robot answers (a home adapted from a knowledge: the answer's parameters, the room
    # account, its weighting), as the model's own predict_names and predict_positions answer
    scores = evaluate_answers(model, e, env, specific=specific, n_positions=ctx.n_positions,
                              rng=np.random.default_rng([seed, 1]))
    wall = time.perf_counter() - start
    if traced:
        path = map_path(Path(ctx.out), ctx.experiment, key.model, key.setting, key.home)
        what = "experienced homes" if ctx.experiment == "general" else "% taught"
        _draw_map(model, e, env, scores, path, ctx.maps,
                  f"{key.home}: {key.model}, {key.setting} {what}, trial 0")

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
        **{k: v for k, v in scores.summary().items() if k != "home"},  # the scores (metrics.json_score)
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
