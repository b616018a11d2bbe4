"""The exact remainder of the power target's φ^v proposal: Σ over fractional counts of
ln Γ(a + n) − ln Γ(a + ⌊n⌋) − [⌊n⌋ = 0] n ln a, a = δ φ (see
:meth:`spco.model.observations.HierarchicalMultinomial.fractional_log_weight`), per concept and
dimension, in one pass over the counts without temporaries (the blocked φ^v step weighs a block by
the sum over its dimensions, the whole weight is the sum over all of them).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def _fractional_log_weights_by_dimension(n: np.ndarray, log_phi: np.ndarray, log_delta: float,
                                         out: np.ndarray) -> None:
    """out[l, k] = Σ_e over the homes whose n[e, l, k] (E, L, D) has a fractional part of
    ln Γ(a + n) − ln Γ(a + ⌊n⌋) − [⌊n⌋ = 0] n ln a, a = exp(log_delta + log_phi[l, k]); −inf where
    such an entry's a underflows to 0. Each sum runs over the homes in order."""
    n_homes, n_concepts, n_dims = n.shape
    for c in range(n_concepts):
        for k in range(n_dims):
            out[c, k] = 0.0
        for e in range(n_homes):
            for k in range(n_dims):
                x = n[e, c, k]
                whole = math.floor(x)
                if x == whole:
                    continue
                tilt = x if whole == 0.0 else 0.0
                log_a = log_delta + log_phi[c, k]
                a = math.exp(log_a)
                if a > 0.0:
                    out[c, k] += math.lgamma(a + x) - math.lgamma(a + whole) - tilt * log_a
                else:
                    out[c, k] = -math.inf


def fractional_log_weights_by_dimension(n: np.ndarray, log_phi: np.ndarray, delta: float) -> np.ndarray:
    """(L, D): the terms of the weight at one φ (L, D) for the real counts ``n`` (E, L, D) and
    concentration ``delta`` > 0, summed over homes but kept per dimension (what the blocked φ^v step
    needs: a block's weight is the sum over its dimensions; the whole weight, the sum over all)."""
    out = np.empty(np.shape(log_phi))
    _fractional_log_weights_by_dimension(np.ascontiguousarray(n, dtype=np.float64),
                                         np.ascontiguousarray(log_phi, dtype=np.float64), math.log(delta),
                                         out)
    return out
