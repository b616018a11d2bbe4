"""``spco bench``: how long a Gibbs sweep takes, per sampler step, and the peak memory of a fit.

Registered in :mod:`spco.cli.main` with ``main.add_command(bench)``. Progress goes to stderr, the result
(a table, or JSON with ``--json``) to stdout. The heavy imports happen only when the command runs.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from spco.cli.errors import friendly_errors

__all__ = ["bench", "format_result"]

_SYNTHETIC = "synthetic"


_friendly = friendly_errors


def _echo_err(message: str) -> None:
    click.echo(message, err=True)


@click.command()
@click.option("--data", "data", default=None, metavar="DIR",
              help="The SIGVerse data set (or an spco cache): benchmark the paper's largest run, 16 "
                   "experienced homes + one new home. Default (or 'synthetic'): synthetic homes of the "
                   "same size.")
@click.option("--sweeps", default=20, show_default=True, type=click.IntRange(1),
              help="Timed sweeps of spco's samplers (the mean is reported, slowest tenth dropped).")
@click.option("--warmup", default=2, show_default=True, type=click.IntRange(0),
              help="Untimed sweeps first (Numba compiles on the first call).")
@click.option("--seed", default=0, show_default=True, type=int, help="Random seed (data and samplers).")
@click.option("--new-home", default="1LDK_9", show_default=True,
              help="The new home (nothing taught) with --data.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of a table.")
@click.option("--homes", default=16, type=click.IntRange(1), hidden=True,
              help="Experienced homes (synthetic; with --data the first N of the paper's list).")
@click.option("--features", default=4096, type=click.IntRange(1), hidden=True,
              help="Visual dimension D of synthetic homes.")
@click.option("--memory/--no-memory", default=True, hidden=True,
              help="Measure the peak memory of a fit in a child process.")
@_friendly
def bench(data: str | None, sweeps: int, warmup: int, seed: int, new_home: str,
          as_json: bool, homes: int, features: int, memory: bool) -> None:
    """Time one Gibbs sweep, step by step, on the paper's largest configuration.

    Measures spco's exact sampler and its reference variant (the authors' conditionals, vectorised),
    their timed sweeps interleaved; reports the seconds per sweep of each step and the peak memory of
    a fit (whole-process RSS, measured in a child process). The speed-up over the authors' own way of
    sweeping is measured by the repository's benchmarks/reference_sampler.py.

    \b
    --json keys: sweep_seconds (spco exact, per sweep), fit_sweep_seconds (a fit's sweep: per-home
    shards), peak_memory_mb, steps (seconds per sweep of each step), configuration, machine, and
    details: spco (both variants, every sweep), fit_sweep, memory.
    """
    from spco import benchmark
    from spco.errors import ConfigurationError

    if data is None or data == _SYNTHETIC:
        _echo_err(f"generating {homes} + 1 synthetic homes with D = {features} (seed {seed})")
        corpus = benchmark.synthetic_corpus(homes, 1, n_features=features, seed=seed)
        source = _SYNTHETIC
    else:
        path = Path(data)
        if homes > len(benchmark.PAPER_EXPERIENCED_HOMES):
            raise ConfigurationError(f"--homes can be at most {len(benchmark.PAPER_EXPERIENCED_HOMES)} with "
                                     "--data (the paper's experienced homes)")
        if new_home in benchmark.PAPER_EXPERIENCED_HOMES[:homes]:
            raise ConfigurationError(f"--new-home {new_home} is one of the experienced homes")
        _echo_err(f"loading {homes} experienced homes and {new_home} from {path}")
        corpus = benchmark.paper_corpus(path, benchmark.PAPER_EXPERIENCED_HOMES[:homes], (new_home,))
        source = str(path)
    result = benchmark.run_benchmark(corpus, source, sweeps=sweeps, warmup=warmup, seed=seed, memory=memory,
                                     log=_echo_err)
    if as_json:
        click.echo(json.dumps(result, indent=1, ensure_ascii=False))
    else:
        click.echo(format_result(result))


def _ms(seconds: float | None) -> str:
    return "-" if seconds is None else f"{seconds * 1e3:,.1f}"


def format_result(result: dict[str, Any]) -> str:
    """The human-readable report of :func:`spco.benchmark.run_benchmark`'s result."""
    from spco.benchmark import iter_steps

    config, machine = result["configuration"], result["machine"]
    exact, ref_variant = result["spco"]["exact"], result["spco"]["reference"]
    new = ", ".join(config["new_homes"]) or "none"
    lines = [
        f"data: {config['data']}: {config['experienced_homes']} experienced homes + new home(s) {new}; "
        f"{config['samples']:,} training samples ({config['taught_samples']:,} taught); "
        f"D = {config['D']}, V = {config['V']}, L = {config['L']}, K = {config['K']}",
        f"machine: {machine['cores']} cores, numpy {machine['numpy']}, scipy {machine['scipy']}, "
        f"numba {machine['numba']}; load average {machine['load_average']} before, "
        f"{machine.get('load_average_after')} after",
        "",
    ]
    rows = [(name, _ms(e), _ms(r)) for name, e, r in iter_steps(result)]
    rows.append((f"total (mean of {exact['sweeps']} sweeps)", _ms(exact["sweep_seconds"]),
                 _ms(ref_variant["sweep_seconds"])))
    header = ("spco step", "exact ms/sweep", "reference-variant ms/sweep")
    widths = [max(len(header[i]), *(len(r[i]) for r in rows)) for i in range(3)]

    def fmt(row: tuple[str, str, str]) -> str:
        return f"{row[0]:<{widths[0]}}  {row[1]:>{widths[1]}}  {row[2]:>{widths[2]}}"

    lines += [fmt(header), *(fmt(r) for r in rows[:-1]), "-" * (sum(widths) + 4), fmt(rows[-1]), ""]
    fit_sweep = result.get("fit_sweep")
    if fit_sweep is not None:
        lines += [f"a fit's sweep, as `spco fit` runs it (every home its own shard and random stream), "
                  f"mean of {fit_sweep['sweeps']}: {_ms(fit_sweep['sweep_seconds'])} ms "
                  f"({_ms(fit_sweep['cpu_seconds'])} ms CPU, median): "
                  f"{fit_sweep['sweep_seconds'] / exact['sweep_seconds']:.2f}x the exact sweep above, "
                  f"{fit_sweep['cpu_seconds'] / exact['cpu_seconds']:.2f}x its CPU "
                  f"({_ms(exact['cpu_seconds'])} ms)", ""]
    reference = result.get("reference")
    if reference is not None:  # a baseline was timed too (benchmarks/reference_sampler.py)
        lines.append(f"authors'-style reference sweep (mean of {reference['sweeps']}): "
                     f"{_ms(reference['sweep_seconds'])} ms")
        ref_steps = reference["steps"]
        width = max(len(n) for n in ref_steps) if ref_steps else 0
        lines += [f"  {name:<{width}}  {_ms(s):>9} ms" for name, s in ref_steps.items()]
        lines += [
            "",
            f"speedup: {result['speedup']:.1f}x (spco exact vs. the authors'-style sweep); "
            f"{result['speedup_same_algorithm']:.1f}x for the same conditionals (spco's reference variant)",
        ]
    memory = result.get("memory")
    if memory is None:
        lines.append("peak memory: not measured")
    else:
        lines.append(f"peak memory of an exact fit ({memory['sweeps']} sweeps, whole-process RSS): "
                     f"{memory['peak_mb']:.0f} MB ({memory['before_fit_mb']:.0f} MB with spco imported "
                     f"and the data loaded, before fitting)")
    return "\n".join(lines)
