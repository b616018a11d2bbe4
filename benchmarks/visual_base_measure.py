"""A base measure for the power target's φ^v prior, tried (issue 29, item 1; branch phi10): any benchmark run
with φ^v_l ~ Dir(A m) instead of Dir(α^v 1).

Under ``target="power"`` with ``visual_prior="estimate"`` the symmetric α^v comes out far below one per
dimension (colour-hog ≈ 0.016, fc7 ≈ 0.23), a concept's φ^v draws are near zero on most dimensions and the
new home of a joint fit gathers in one or two concepts (benchmarks/README.md, "… why the power target loses
general places"). This driver replaces the prior of every concept's φ^v by a Dirichlet around the
experienced homes' pooled view proportions,

    m = (Σ_t p_t + 1/D) / (N + 1)       (the taught views' proportions p_t, one uniform view added so that
                                         no dimension has no mass),
    A + 1 = Σ_d m_d (1 − m_d) / mean_l Σ_d (φ̂_l,d − m_d)²   (method of moments: E φ_l = m,
                                         E Σ_d (φ_l,d − m_d)² = Σ_d m_d (1 − m_d) / (A + 1)),

φ̂_l the mean over homes of each home's mean proportions in concept l, on the concepts of the start (the
views and concepts of :func:`spco.model.visual_prior.home_view_moments`, as the symmetric estimate). δ^v is
estimated as before. ``--scale S`` multiplies A (a prior S times stronger than the moments say), ``--floor F``
adds F to every dimension's parameter (A m_d + F). The conditionals are those of docs/model.md with the
prior's parameter a vector: the φ^v step's proposal Dir(A m + tables + fractional parts) and its
Metropolis–Hastings test are unchanged (the test's ratio does not involve the prior), so the chain is exact
for this prior too.

It is a one-off driver (a patch of :meth:`spco.model.driver.ShardedRun._estimate_visual_prior` in this
process; run the benchmark with ``--jobs 1``), not a library option: on development it did not make the
power target reach the cut (benchmarks/README.md, "Issue 29: a base measure for the power target's φ^v
prior"). Usage::

    python benchmarks/visual_base_measure.py [--scale S] [--floor F] -- benchmarks/general_places.py \\
        --seeds 0 --answers rooms --set target=power --set visual_prior=estimate
    python benchmarks/visual_base_measure.py -- -m spco experiment specific ...
"""

from __future__ import annotations

import argparse
import dataclasses
import runpy
import sys

import numpy as np


def base_measure(m: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, float | None]:
    """(m (D,), A) from the homes' view moments of :func:`spco.model.visual_prior.home_view_moments`
    (m (E, L) views, s (E, L, D) sums of their proportions): the pooled proportions with one uniform view
    added, and the method-of-moments concentration around them (``None``: no concept with a view, or the
    concepts do not spread)."""
    m = np.asarray(m, dtype=np.float64)
    s = np.asarray(s, dtype=np.float64)
    D = s.shape[-1]
    pooled = (s.sum(axis=(0, 1)) + 1.0 / D) / (m.sum() + 1.0)
    phis = [(s[m[:, col] > 0, col] / m[m[:, col] > 0, col, None]).mean(axis=0)
            for col in range(m.shape[1]) if (m[:, col] > 0).any()]
    if not phis:
        return pooled, None
    dev = float(np.mean([((phi - pooled) ** 2).sum() for phi in phis]))
    if dev <= 0:
        return pooled, None
    value = float((pooled * (1.0 - pooled)).sum() / dev - 1.0)
    return pooled, (value if value > 0 and np.isfinite(value) else None)


def install(scale: float, floor: float) -> None:
    """Patch this process: every fit's φ^v prior becomes A·scale·m + floor (a vector) once δ^v and α^v
    are estimated; ``TransferHyperparameters`` accepts the vector (its checks see its mean)."""
    from spco.model import driver
    from spco.model.hyperparameters import TransferHyperparameters

    check = TransferHyperparameters.__post_init__

    def post_init(self) -> None:
        alpha = self.alpha_visual
        if isinstance(alpha, np.ndarray):
            object.__setattr__(self, "alpha_visual", float(alpha.mean()))
            check(self)
            object.__setattr__(self, "alpha_visual", alpha)
        else:
            check(self)

    TransferHyperparameters.__post_init__ = post_init
    to_dict, from_dict = TransferHyperparameters.to_dict, TransferHyperparameters.from_dict

    def to_json(self) -> dict:
        data = to_dict(self)
        if isinstance(data["alpha_visual"], np.ndarray):  # the knowledge file carries the vector
            data["alpha_visual"] = [float(x) for x in data["alpha_visual"]]
        return data

    def from_json(cls, data: dict) -> TransferHyperparameters:
        data = dict(data)
        if isinstance(data.get("alpha_visual"), list):
            data["alpha_visual"] = np.asarray(data["alpha_visual"], dtype=np.float64)
        return from_dict.__func__(cls, data)

    TransferHyperparameters.to_dict = to_json
    TransferHyperparameters.from_dict = classmethod(from_json)
    estimate = driver.ShardedRun._estimate_visual_prior

    def estimate_with_base(self) -> None:
        estimate(self)
        parts = [home for part in self.call("visual_prior_moments") for home in part]
        m, s, _ = (np.concatenate(arrays, axis=0) for arrays in zip(*parts, strict=True))
        base, concentration = base_measure(m, s)
        if concentration is None:
            return
        prior = concentration * scale * base + floor
        print(f"[visual_base_measure] delta_visual={self.hyper.delta_visual:.1f} symmetric "
              f"alpha_visual={self.hyper.alpha_visual:.4f} A={concentration:.1f} scale={scale:g} "
              f"floor={floor:g} D={base.size} share of parameters < 1: {(prior < 1).mean():.3f}",
              file=sys.stderr)
        hyper = dataclasses.replace(self.hyper, alpha_visual=prior)
        self.hyper = hyper
        self.global_step.hyper = hyper
        self.visual_prior = {**(self.visual_prior or {}), "base_concentration": concentration,
                             "base_scale": scale, "base_floor": floor}

    driver.ShardedRun._estimate_visual_prior = estimate_with_base


def main(argv: list[str] | None = None) -> int:
    """Parse ``[--scale S] [--floor F] -- COMMAND...`` and run COMMAND (a script or ``-m module``) here."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--" not in argv:
        raise SystemExit("usage: visual_base_measure.py [--scale S] [--floor F] -- SCRIPT|-m MODULE ARGS...")
    cut = argv.index("--")
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=float, default=1.0, help="multiply the estimated A")
    parser.add_argument("--floor", type=float, default=0.0, help="add to every dimension's parameter")
    args = parser.parse_args(argv[:cut])
    command = argv[cut + 1:]
    install(args.scale, args.floor)
    if command[0] == "-m":
        sys.argv = [command[1], *command[2:]]
        runpy.run_module(command[1], run_name="__main__", alter_sys=True)
    else:
        sys.argv = command
        runpy.run_path(command[0], run_name="__main__")
    return 0


if __name__ == "__main__":
    sys.exit(main())
