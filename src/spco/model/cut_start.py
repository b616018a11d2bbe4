"""The power target's chain started from the cut sampler's state (issue 29;
``TransferHyperparameters.cut_start``).

Why. Under the power target (``target="power"``) a new home's places gather in a few concepts in the
chain's first sweeps and single-sample steps then almost never leave that state, while the cut
sampler's first sweeps split the home by rooms (benchmarks/README.md, "Issue 29: why the power target
gathers a new home in natural speech"). A chain may start anywhere: started from the cut's state, the
power target's sweeps still target the power posterior, as long as every sweep that is kept is one of
them.

How (:class:`spco.model.driver.ShardedRun`). With ``cut_start = k > 0`` the fit starts and runs its
sweeps 0..k − 1 with :func:`cut_phase`'s hyperparameters and settings — the cut sampler's, the given
δ^v and α^v: the same chain, draw for draw, as ``target="cut"`` for the same seed. Before sweep k the
assignments, regions and word switches are kept, every home recounts its statistics as the power
target weighs views and tokens, and every parameter is drawn from the power target's conditionals (φ^v,
φ^w, G_0 and the word channels' ψ, β, λ from the homes' tables, then each home's θ, G_e, π, μ, Σ); the
sweeps k.. are the power target's. The estimates of ``visual_prior="estimate"`` and
``word_prior="estimate"`` are made as the power target makes them (on the concepts of the start, the
word channels weighed as the power target weighs them) and take effect with the first power sweep.
:func:`check_cut_start` refuses a k past the first averaged sweep.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

from spco.errors import ConfigurationError
from spco.model.hyperparameters import PHI_PASSES, TransferHyperparameters
from spco.model.state import SamplerSettings

__all__ = ["check_cut_start", "cut_phase", "cut_sweeps"]


def cut_sweeps(hyper: TransferHyperparameters) -> int:
    """The sweeps of the cut sampler before the power target's chain: ``hyper.cut_start`` under
    ``target="power"``, else 0."""
    if getattr(hyper, "target", "cut") != "power":
        return 0
    return int(getattr(hyper, "cut_start", 0))


def cut_phase(hyper: TransferHyperparameters, settings: SamplerSettings
              ) -> tuple[TransferHyperparameters, SamplerSettings]:
    """The hyperparameters and sampler settings of a cut start's first sweeps: ``hyper`` and
    ``settings`` as the cut sampler has them (``target="cut"``, δ^v, α^v, δ^w and α^w as given, no
    φ^v-marginal moves, the default passes of the φ^v step, which the cut's whole counts do not
    run), everything else as they are."""
    cut = replace(hyper, target="cut", visual_prior="given", word_prior="given", cut_start=0,
                  block_moves="off" if hyper.block_moves == "phi" else hyper.block_moves,
                  phi_every=1, phi_until=None, phi_passes=PHI_PASSES)
    return cut, replace(settings, power=False, phi_moves=False)


def check_cut_start(hyper: TransferHyperparameters, kept: Iterable[int]) -> None:
    """Raise :class:`~spco.errors.ConfigurationError` (naming ``cut_start``) when the cut's sweeps
    of ``hyper`` would reach past the first of the ``kept`` (averaged) sweeps: every kept draw must
    be a power sweep."""
    k = cut_sweeps(hyper)
    kept = sorted(int(i) for i in kept)
    if k and kept and k > kept[0]:
        raise ConfigurationError(f"cut_start={k} must be at most the first averaged sweep ({kept[0]}, "
                                 f"0-based): every kept draw must be a power sweep; use fewer cut sweeps "
                                 f"or more sweeps")
