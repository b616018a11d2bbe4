"""``spco experiment general|specific``: the paper's experiments from the command line.

Registered in :mod:`spco.cli.main` with ``main.add_command(experiment)``. The heavy imports (numpy, the
model) happen only when a command runs, so ``spco --help`` stays fast; errors are reported by the
command line's ``_friendly_errors`` (one line, exit status 2).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from spco.cli.errors import friendly_errors

__all__ = ["experiment"]

_MODEL_NAMES = ("spcotransfer", "spcotransfer+mi", "spcotransfer-ref", "spcotransfer-ref+mi", "spcoa",
                "spcoa+mi")


_friendly = friendly_errors


def _common(func: Callable[..., Any]) -> Callable[..., Any]:
    """The options both experiments share."""
    options = [
        click.option("--data", "data", default="synthetic", show_default=True,
                     help="A folder of homes (SIGVerse or plain layout), an `spco import` cache file, "
                          "or 'synthetic' (homes generated from --seed)."),
        click.option("--language", type=click.Choice(["templates", "free"]), default="templates",
                     show_default=True,
                     help="Sentences of synthetic homes: the paper's five templates, or 'free' (people "
                          "talking freely: synonyms, multi-word names, objects, typos; each place has "
                          "a set of accepted names)."),
        click.option("--regions", type=click.Path(path_type=Path), default=None,
                     help="Ground-truth place regions of the new homes (sigverse_regions.json format). "
                          "Default: the regions the homes carry (synthetic homes, a "
                          "sigverse_regions.json beside the data)."),
        click.option("--maps", type=click.Path(path_type=Path), default=None,
                     help="Folder of floor plans <home>.PNG (+ extents.json) for the map figures. "
                          "Default: a maps/ folder beside the region file or the data."),
        click.option("--trials", default=20, show_default=True, type=click.IntRange(1),
                     help="Runs per model, setting and new home, each with its own seed."),
        click.option("--models", default="all", show_default=True,
                     help="Comma-separated models: " + ", ".join(_MODEL_NAMES) + " (or 'all')."),
        click.option("--iterations", default=200, show_default=True, type=click.IntRange(1),
                     help="Gibbs sweeps per fit."),
        click.option("--seed", default=0, show_default=True, type=click.IntRange(0),
                     help="Master seed: trial seeds, synthetic homes, position samples."),
        click.option("--jobs", "-j", default=1, show_default=True, type=click.IntRange(1),
                     help="Runs in parallel (worker processes; results do not depend on it)."),
        click.option("--out", "-o", required=True, type=click.Path(path_type=Path),
                     help="Output folder: results.json, runs.jsonl, tables.md, PNG figures."),
        click.option("--engine", default="local", show_default=True, type=click.Choice(["local", "ray"]),
                     help="Run the runs in worker processes (--jobs) or as Ray tasks "
                          "(pip install 'spco[ray]'); results do not depend on it."),
        click.option("--address", default=None,
                     help="With --engine ray: the Ray cluster to join (default: start Ray locally)."),
        click.option("--resume", is_flag=True,
                     help="Continue the experiment in --out (same options; --trials may grow)."),
        click.option("--force", is_flag=True, help="Delete a previous experiment's outputs in --out."),
        click.option("--quiet", "-q", is_flag=True, help="No progress bar and no tables on stdout."),
        click.option("--images", type=click.Path(path_type=Path), default=None,
                     help="Folder of the homes' camera images, <home>/<id>.jpg (e.g. sigverse_images): "
                          "compute the views from them instead of using the homes' visual counts."),
        click.option("--extractor", default=None,
                     help="Image extractor for --images (default: colour-hog; see `spco features --help`)."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


@click.group()
def experiment() -> None:
    """Reproduce the experiments of Hagiwara et al. (2021): `general` and `specific` places.

    Results go to --out: results.json (every run and the summary), runs.jsonl (one line per finished
    run, so an interrupted experiment continues with --resume), tables.md, and PNG figures.
    """


def _split(text: str | None) -> tuple[str, ...] | None:
    if text is None:
        return None
    return tuple(p.strip() for p in text.split(",") if p.strip()) or None


def _run(config_kwargs: dict[str, Any], out: Path, resume: bool, force: bool, quiet: bool) -> None:
    from spco.evaluation.experiments import ExperimentConfig, run_experiment
    from spco.model.numba_cache import precompile_if_cold

    config = ExperimentConfig(**config_kwargs)
    # on an empty kernel cache: compiled once, in 2 processes, before any run or worker needs them
    precompile_if_cold(lambda text: click.echo(text, err=True))
    start = time.perf_counter()
    result = run_experiment(config, out, resume=resume, force=force, progress=not quiet,
                            log=lambda msg: click.echo(msg, err=True))
    elapsed = time.perf_counter() - start
    if not quiet:
        click.echo(result.tables)
    timing = result.results["timing"]
    reused = f"; {timing['runs_reused']} recorded as copies of a run at another setting" \
        if timing.get("runs_reused") else ""
    click.echo(f"{timing['runs']} runs ({timing['runs_this_session']} computed this session{reused}) "
               f"in {elapsed:.1f} s "
               f"(run time {timing['run_wall_seconds_total']:.1f} s); wrote {out / 'results.json'}, "
               f"{out / 'tables.md'} and {len(result.figures)} figures")


@experiment.command()
@_common
@click.option("--envs", default="0,1,2,4,8,16", show_default=True,
              help="Numbers of experienced homes (the first n of the paper's fixed list).")
@click.option("--experienced-homes", default=None,
              help="Comma-separated experienced homes, in the order they are added (default: the "
                   "paper's 3LDK_1, 1LDK_8, 2LDK_8, …).")
@click.option("--new-homes", default=None,
              help="Comma-separated new homes (default: 1LDK_9, 2LDK_9, 3LDK_9, or the synthetic ones).")
@_friendly
def general(data: str, language: str, regions: Path | None, maps: Path | None, trials: int, models: str,
            iterations: int, seed: int, jobs: int, engine: str, address: str | None, out: Path, resume: bool,
            force: bool, quiet: bool, images: Path | None, extractor: str | None, envs: str,
            experienced_homes: str | None, new_homes: str | None) -> None:
    """General places: accuracy in new homes, taught nothing, vs. number of experienced homes."""
    from spco.evaluation.experiments import parse_int_list

    _run({"experiment": "general", "settings": parse_int_list(envs, "--envs", 0), "data": data,
          "regions": regions, "maps": maps, "trials": trials, "models": models, "iterations": iterations,
          "seed": seed, "jobs": jobs, "engine": engine, "address": address,
          "experienced_homes": _split(experienced_homes),
          "new_homes": _split(new_homes), "language": language, "images": images, "extractor": extractor},
         out, resume, force, quiet)


@experiment.command()
@_common
@click.option("--rates", default="0,20,40,60,80,100", show_default=True,
              help="Teaching rates (percent) of the home-specific rooms of the new home.")
@click.option("--experienced-homes", default=None,
              help="Comma-separated experienced homes (default: the paper's 16).")
@click.option("--new-home", default=None,
              help="The new home with home-specific rooms (default: 3LDK_9, or the synthetic one).")
@_friendly
def specific(data: str, language: str, regions: Path | None, maps: Path | None, trials: int, models: str,
             iterations: int, seed: int, jobs: int, engine: str, address: str | None, out: Path, resume: bool,
             force: bool, quiet: bool, images: Path | None, extractor: str | None, rates: str,
             experienced_homes: str | None, new_home: str | None) -> None:
    """Home-specific places: accuracy on the new home's own room names vs. their teaching rate."""
    from spco.evaluation.experiments import parse_int_list

    _run({"experiment": "specific", "settings": parse_int_list(rates, "--rates", 0, 100), "data": data,
          "regions": regions, "maps": maps, "trials": trials, "models": models, "iterations": iterations,
          "seed": seed, "jobs": jobs, "engine": engine, "address": address,
          "experienced_homes": _split(experienced_homes),
          "specific_home": new_home.strip() if new_home else None, "language": language, "images": images,
          "extractor": extractor}, out, resume, force, quiet)


@experiment.command(name="models")
def list_models() -> None:
    """List the models an experiment can compare (--models)."""
    from spco.evaluation.experiments import describe_models

    click.echo(describe_models())
