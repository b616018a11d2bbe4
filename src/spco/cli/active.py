"""``spco experiment active``: a robot that asks, measured (:mod:`spco.evaluation.active`).

Registered in :mod:`spco.cli.main` as a command of the ``experiment`` group.
"""

from __future__ import annotations

import time
from pathlib import Path

import click

from spco.cli.errors import friendly_errors

__all__ = ["active"]


def _split(text: str | None) -> tuple[str, ...]:
    return tuple(p.strip() for p in (text or "").split(",") if p.strip())


@click.command(name="active")
@click.option("--data", required=True, type=click.Path(path_type=Path),
              help="The folder of SIGVerse homes (its sentence_label/ folders are the oracle).")
@click.option("--regions", required=True, type=click.Path(path_type=Path),
              help="Ground-truth place regions of the new homes (sigverse_regions.json).")
@click.option("--homes", default="1LDK_9,2LDK_9,3LDK_9", show_default=True,
              help="Comma-separated new homes ('' for none).")
@click.option("--heldout", type=click.Path(path_type=Path), default=None,
              help="A home-specific configuration file (benchmarks/heldout/specific_heldout.json).")
@click.option("--heldout-config", "heldout_configs", default=None,
              help="Comma-separated configuration ids of --heldout to run (e.g. 2LDK_9-kenta-nursery-piano).")
@click.option("--strategies", default="errors,information,uncertainty,random", show_default=True,
              help="Where to ask: information (expected information gain), errors (expected wrong answers "
                   "corrected), uncertainty (entropy of what), random.")
@click.option("--questions", default=15, show_default=True, type=click.IntRange(0),
              help="Questions per run: k = 0 … this.")
@click.option("--rates", default="20,40", show_default=True,
              help="The paper's teaching rates of the home-specific rooms, for reference ('' for none).")
@click.option("--trials", default=20, show_default=True, type=click.IntRange(1), help="Trials per home.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0),
              help="Master seed: the knowledge's fit, trial seeds, random choices.")
@click.option("--jobs", "-j", default=1, show_default=True, type=click.IntRange(1),
              help="Runs in parallel (worker processes; results do not depend on it).")
@click.option("--fit-iterations", default=200, show_default=True, type=click.IntRange(1),
              help="Gibbs sweeps of the knowledge's fit (once per seed).")
@click.option("--adapt-iterations", default=100, show_default=True, type=click.IntRange(1),
              help="Gibbs sweeps of adapt.")
@click.option("--teach-sweeps", default=10, show_default=True, type=click.IntRange(0),
              help="Gibbs sweeps of each teach.")
@click.option("--knowledge", "knowledge_file", type=click.Path(path_type=Path), default=None,
              help="Use this knowledge file instead of fitting one on the 16 homes.")
@click.option("--out", "-o", required=True, type=click.Path(path_type=Path),
              help="Output folder: results.json, runs.jsonl, tables.md, active_<home>.png, the knowledge.")
@click.option("--resume", is_flag=True,
              help="Continue the experiment in --out (same options; --trials may grow).")
@click.option("--force", is_flag=True, help="Delete a previous experiment's outputs in --out.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar and no tables on stdout.")
@friendly_errors
def active(data: Path, regions: Path, homes: str, heldout: Path | None, heldout_configs: str | None,
           strategies: str, questions: int, rates: str, trials: int, seed: int, jobs: int,
           fit_iterations: int, adapt_iterations: int, teach_sweeps: int, knowledge_file: Path | None,
           out: Path, resume: bool, force: bool, quiet: bool) -> None:
    """A robot that asks: accuracy of new homes vs. questions answered, per strategy.

    Fits the knowledge on the paper's 16 homes once (seed --seed), adapts each new home taught
    nothing, then asks --questions questions one at a time (each answered by the data set's sentence
    for that sample and taught before the next), for each strategy; the paper's random teaching
    rates of the home-specific rooms are scored for reference.
    """
    from spco.errors import ConfigurationError
    from spco.evaluation.active import ActiveConfig, run_active_experiment
    from spco.model.precompile import precompile_if_cold

    try:
        rate_list = tuple(int(r) for r in _split(rates))
    except ValueError:
        raise ConfigurationError(f"--rates must be comma-separated percentages, got {rates!r}") from None
    config = ActiveConfig(data=str(data), regions=str(regions), homes=_split(homes),
                          heldout=None if heldout is None else str(heldout),
                          heldout_configs=_split(heldout_configs) or None, strategies=_split(strategies),
                          questions=questions, trials=trials, seed=seed, jobs=jobs, rates=rate_list,
                          fit_iterations=fit_iterations, adapt_iterations=adapt_iterations,
                          teach_sweeps=teach_sweeps,
                          knowledge=None if knowledge_file is None else str(knowledge_file))
    precompile_if_cold(lambda text: click.echo(text, err=True))
    start = time.perf_counter()
    result = run_active_experiment(config, out, resume=resume, force=force, progress=not quiet,
                                   log=lambda msg: click.echo(msg, err=True))
    if not quiet:
        click.echo(result.tables)
    click.echo(f"{result.results['timing']['runs']} runs in {time.perf_counter() - start:.1f} s; wrote "
               f"{out / 'results.json'}, {out / 'tables.md'} and {len(result.figures)} figures")
