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

from spco.cli.common import settings_hyperparameters
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
        click.option("--name-prior", default="off", show_default=True, type=click.Choice(["off", "wordnet"]),
                     help="wordnet: the transfer models order the words said at each concept by how "
                          "name-like they are (sentence positions and WordNet) when names are predicted. "
                          "Off by default: it lowered A_n on the held-out speech set (docs/model.md)."),
        click.option("--views-missing", default=0.0, show_default=True, type=click.FloatRange(0, 100),
                     help="Percentage of the new home's views removed at random in each run (a camera "
                          "that drops frames; 100: no camera)."),
        click.option("--text-language", default="auto", show_default=True,
                     type=click.Choice(["auto", "ja", "zh", "spaced"]),
                     help="Japanese or Chinese written without spaces: segment it into words (ja: "
                          "pip install 'spco[ja]', zh: 'spco[zh]'), decide from the text (auto), or "
                          "never (spaced: the words are separated by spaces)."),
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
    from spco.model.precompile import precompile_if_cold

    kwargs = dict(config_kwargs)
    name_prior = kwargs.pop("name_prior", "off")
    if name_prior != "off":
        from spco.model.hyperparameters import TransferHyperparameters

        kwargs["hyperparameters"] = TransferHyperparameters(name_prior=name_prior)
    config = ExperimentConfig(**kwargs)
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
            force: bool, quiet: bool, images: Path | None, extractor: str | None, name_prior: str,
            views_missing: float, text_language: str, envs: str, experienced_homes: str | None,
            new_homes: str | None) -> None:
    """General places: accuracy in new homes, taught nothing, vs. number of experienced homes."""
    from spco.evaluation.experiments import parse_int_list

    _run({"experiment": "general", "settings": parse_int_list(envs, "--envs", 0), "data": data,
          "regions": regions, "maps": maps, "trials": trials, "models": models, "iterations": iterations,
          "seed": seed, "jobs": jobs, "engine": engine, "address": address,
          "experienced_homes": _split(experienced_homes),
          "new_homes": _split(new_homes), "language": language, "images": images, "extractor": extractor,
          "name_prior": name_prior, "text_language": text_language, "views_missing": views_missing},
         out, resume, force, quiet)


@experiment.command()
@_common
@click.option("--rates", default="0,20,40,60,80,100", show_default=True,
              help="Teaching rates (percent) of the home-specific rooms of the new home.")
@click.option("--experienced-homes", default=None,
              help="Comma-separated experienced homes (default: the paper's 16).")
@click.option("--new-home", default=None,
              help="The new home with home-specific rooms (default: 3LDK_9, or the synthetic one).")
@click.option("--config", "config_file", type=click.Path(path_type=Path), default=None,
              help="A configuration file of named rooms in other homes (format heldout-specific/1, e.g. "
                   "benchmarks/heldout/specific_heldout.json): teach each room's name by the file's "
                   "templates and draw, score A_n per room on the file's test ids, A_p both ways, with "
                   "bootstrap intervals. Seeds, rates and homes come from the file.")
@click.option("--configuration", "configurations", default=None,
              help="With --config: comma-separated configuration ids to run (default: all).")
@click.option("--seeds", default=None,
              help="With --config: comma-separated seeds of the file to run (default: the file's, or its "
                   "first --trials).")
@click.option("--positions", default=None, type=click.IntRange(1),
              help="With --config: positions drawn per room and A_p mode (default 20).")
@click.option("--set", "settings", multiple=True, metavar="NAME=VALUE",
              help="With --config: a hyperparameter of the transfer models, on top of their defaults, as "
                   "`spco fit --set` (repeatable; e.g. --set target=power --set word_prior=estimate). "
                   "Recorded in results.json and part of the experiment's identity.")
@_friendly
def specific(data: str, language: str, regions: Path | None, maps: Path | None, trials: int, models: str,
             iterations: int, seed: int, jobs: int, engine: str, address: str | None, out: Path, resume: bool,
             force: bool, quiet: bool, images: Path | None, extractor: str | None, name_prior: str,
             views_missing: float, text_language: str, rates: str, experienced_homes: str | None,
             new_home: str | None, config_file: Path | None, configurations: str | None, seeds: str | None,
             positions: int | None, settings: tuple[str, ...]) -> None:
    """Home-specific places: accuracy on the new home's own room names vs. their teaching rate."""
    from spco.evaluation.experiments import parse_int_list

    ctx = click.get_current_context()

    def given(name: str) -> bool:
        return ctx.get_parameter_source(name) not in (click.core.ParameterSource.DEFAULT, None)

    if config_file is not None:
        _run_config(config_file, data, out, configurations, seeds, rates if given("rates") else None,
                    trials if given("trials") else None, models if given("models") else None, iterations,
                    positions, jobs, resume, force, quiet,
                    [f"--{n.replace('_', '-')}" for n in ("language", "regions", "maps", "seed",
                                                          "experienced_homes", "new_home", "images",
                                                          "extractor", "address", "name_prior")
                                                          if given(n)]
                    + (["--engine ray"] if engine != "local" else []), settings)
        return
    unused = [f"--{n}" for n in ("configuration", "seeds", "positions") if given(n)] + \
        (["--set"] if settings else [])
    if unused:
        raise click.UsageError(f"{', '.join(unused)} only apply with --config")
    _run({"experiment": "specific", "settings": parse_int_list(rates, "--rates", 0, 100), "data": data,
          "regions": regions, "maps": maps, "trials": trials, "models": models, "iterations": iterations,
          "seed": seed, "jobs": jobs, "engine": engine, "address": address,
          "experienced_homes": _split(experienced_homes),
          "specific_home": new_home.strip() if new_home else None, "language": language, "images": images,
          "extractor": extractor, "name_prior": name_prior, "text_language": text_language,
          "views_missing": views_missing},
         out, resume, force, quiet)


def _run_config(config_file: Path, data: str, out: Path, configurations: str | None, seeds: str | None,
                rates: str | None, trials: int | None, models: str | None, iterations: int,
                positions: int | None, jobs: int, resume: bool, force: bool, quiet: bool,
                unused: list[str], settings: tuple[str, ...] = ()) -> None:
    """``specific --config``: the home-specific experiment of a configuration file (``settings``:
    ``--set NAME=VALUE`` of the transfer models' hyperparameters, on the paper's)."""
    from spco.evaluation.experiments import parse_int_list
    from spco.evaluation.specific_config import DEFAULT_POSITIONS, load_specific_config, run_specific_config

    if unused:
        raise click.UsageError(f"{', '.join(unused)} cannot be used with --config (the configuration "
                               "file gives the homes, teaching, seeds and regions)")
    if data == "synthetic":
        raise click.UsageError("--config needs --data: the data set holding the file's homes "
                               "(e.g. the SIGVerse folder)")
    hyper = settings_hyperparameters(settings)
    file = load_specific_config(config_file)
    chosen = _split(configurations)
    if seeds is not None:
        picked: tuple[int, ...] | None = tuple(parse_int_list(seeds, "--seeds", 0))
    elif trials is not None:
        picked = file.seeds[:trials]
    else:
        picked = None
    chosen_rates = parse_int_list(rates, "--rates", 1, 100) if rates is not None else None
    names = ("spcotransfer+mi", "spcoa") if models is None else tuple(p.strip() for p in models.split(","))
    if names == ("all",):
        names = _MODEL_NAMES

    def progress(record: dict, done: int, total: int) -> None:
        if not quiet:
            rooms = ", ".join(f"{k} {v['name_accuracy']:.2f}" for k, v in record["rooms"].items())
            click.echo(f"[{done}/{total}] {record['configuration']} {record['rate']} % seed {record['seed']} "
                       f"{record['model']}: {rooms} ({record['wall_seconds']:.0f} s)", err=True)

    start = time.perf_counter()
    results = run_specific_config(file, data, out, configurations=chosen, rates=chosen_rates, seeds=picked,
                                  models=names, iterations=iterations,
                                  n_positions=positions or DEFAULT_POSITIONS, jobs=jobs, resume=resume,
                                  force=force, progress=progress, hyperparameters=hyper)
    if not quiet:
        click.echo((out / "tables.md").read_text(encoding="utf-8"))
    click.echo(f"{len(results['runs'])} runs in {time.perf_counter() - start:.1f} s; wrote "
               f"{out / 'results.json'} and {out / 'tables.md'}")


@experiment.command(name="models")
def list_models() -> None:
    """List the models an experiment can compare (--models)."""
    from spco.evaluation.experiments import describe_models

    click.echo(describe_models())
