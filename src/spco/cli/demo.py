"""``spco demo``: learn from synthetic homes and transfer to a new one. Registered in
:mod:`spco.cli.main`."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import click

from spco.cli.errors import friendly_errors

__all__ = ["demo", "kernel_time"]


@click.command()
@click.option("--seed", default=0, show_default=True, type=int, help="Random seed (homes and learning).")
@click.option("--out", default="spco-demo", show_default=True, type=click.Path(path_type=Path),
              help="Folder for the map figure, the log-joint trace and results.json.")
@click.option("--homes", default=16, show_default=True, type=click.IntRange(1, 256),
              help="Number of experienced (fully taught) synthetic homes.")
@click.option("--iterations", default=100, show_default=True, type=click.IntRange(1, 100000),
              help="Gibbs sweeps.")
@friendly_errors
def demo(seed: int, out: Path, homes: int, iterations: int) -> None:
    """Learn from synthetic homes and transfer to a new home taught nothing (no dataset needed)."""
    from spco.model import numba_cache, precompile
    from spco.synthetic_transfer import format_table, run_demo

    processes = 2 if (os.cpu_count() or 1) >= 2 else 1
    cold = precompile.kernels_compiled() is False
    if cold:
        click.echo(precompile.precompile_notice(processes), err=True)
        numba_cache.mark_announced()
    click.echo(f"Generating {homes} experienced synthetic homes and 1 new home (seed {seed})...", err=True)
    result = run_demo(seed=seed, out=out, n_experienced=homes, n_iterations=iterations,
                      progress=sys.stderr.isatty(), processes=processes, compile_first=cold)
    t = result.transfer
    click.echo(f"Learnt {result.n_homes} homes ({result.n_samples} samples) in {result.fit_seconds:.1f} s "
               f"({kernel_time(cold, 0.0, result.warm_up_seconds)}).")
    click.echo(f"New home {t.home}: nothing taught there; names and positions come from the other homes.\n")
    click.echo("SpCoTransfer+MI (A_n: name accuracy, A_p: position accuracy) beside the SpCoA+MI baseline:")
    click.echo(format_table(result))
    click.echo("\nWrote " + ", ".join(str(p) for p in result.files))
    click.echo(f"\nThe robot's files ({result.robot_seconds:.1f} s): {result.knowledge_file} learnt from the "
               f"experienced homes alone, {result.home_file} adapted to the new home. Next:\n"
               f"  spco where {result.home_file} kitchen -n 3\n"
               f"  pip install -e \".[serve]\" && spco serve {result.home_file}   "
               "# then open http://127.0.0.1:8765/")


def kernel_time(compiled: bool, compile_seconds: float, load_seconds: float) -> str:
    """How long the kernels took before the demo learnt, as its "Learnt …" line says it: compiled
    for this machine first (``compiled``: ``compile_seconds`` in the processes that compiled them,
    then ``load_seconds`` to load them and compile what they left), or loaded from the cache."""
    if compiled:
        return (f"after {compile_seconds + load_seconds:.1f} s compiling the kernels for this machine, "
                "a first run only")
    return f"after {load_seconds:.1f} s loading the compiled kernels"
