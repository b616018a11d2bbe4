"""The exact remainder of the power target's φ^v proposal: Σ over fractional counts of
ln Γ(a + n) − ln Γ(a + ⌊n⌋) − [⌊n⌋ = 0] n ln a, a = δ φ (see
:meth:`spco.model.observations.HierarchicalMultinomial.fractional_log_weight`), per concept and
dimension, in one pass over the counts (the blocked φ^v step weighs a block by the sum over its
dimensions, the whole weight is the sum over all of them).

The counts may come as several groups of homes (a worker's one-home shards): each group's terms
are summed over its homes in order, as one call per group would sum them, and the groups' sums are
added in order, as the shards' answers are (:func:`spco.model.shard_group._sum`), so the result is
the same to the bit. What depends on a dimension's a only — a = exp(ln δ + ln φ) and ln Γ(a), the
second term of every count below 1 — is computed once per concept and dimension for every home
(most fractional counts are below 1: the views' weights are powers s < 1 of small counts).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba.typed import List


@njit(cache=True, error_model="numpy")
def _fractional_log_weights_grouped(groups, log_phi: np.ndarray, log_delta: float,
                                    out: np.ndarray) -> None:
    """out[l, k] = Σ over the groups in order of (Σ_e over the group's homes in order whose
    n[e, l, k] (E_g, L, D) has a fractional part of ln Γ(a + n) − ln Γ(a + ⌊n⌋) − [⌊n⌋ = 0] n ln a,
    a = exp(log_delta + log_phi[l, k]), starting from 0; −inf where such an entry's a underflows to 0)."""
    n_concepts, n_dims = log_phi.shape
    log_a = np.empty(n_dims)
    a = np.empty(n_dims)
    log_gamma_a = np.empty(n_dims)
    state = np.zeros(n_dims, dtype=np.int8)  # 0: nothing computed; 1: a; 2: a and ln Γ(a)
    group_sum = np.empty(n_dims)
    for c in range(n_concepts):
        state[:] = 0
        for g in range(len(groups)):
            n = groups[g]
            for k in range(n_dims):
                group_sum[k] = 0.0
            for e in range(n.shape[0]):
                for k in range(n_dims):
                    x = n[e, c, k]
                    whole = math.floor(x)
                    if x == whole:
                        continue
                    if state[k] == 0:
                        log_a[k] = log_delta + log_phi[c, k]
                        a[k] = math.exp(log_a[k])
                        state[k] = 1
                    if a[k] > 0.0:
                        if whole == 0.0:
                            if state[k] == 1:
                                log_gamma_a[k] = math.lgamma(a[k] + whole)
                                state[k] = 2
                            group_sum[k] += math.lgamma(a[k] + x) - log_gamma_a[k] - x * log_a[k]
                        else:
                            group_sum[k] += math.lgamma(a[k] + x) - math.lgamma(a[k] + whole) - 0.0 * log_a[k]
                    else:
                        group_sum[k] = -math.inf
            if g == 0:
                for k in range(n_dims):
                    out[c, k] = group_sum[k]
            else:
                for k in range(n_dims):
                    out[c, k] = out[c, k] + group_sum[k]


def fractional_log_weights_grouped(groups: list[np.ndarray], log_phi: np.ndarray, delta: float) -> np.ndarray:
    """(L, D): the terms of the weight at one φ (L, D) for the real counts of each group of homes
    in ``groups`` (each (E_g, L, D)) and concentration ``delta`` > 0, summed over each group's homes
    and then over the groups, in order, but kept per dimension: bit for bit the sum of
    :func:`fractional_log_weights_by_dimension` over the groups (what the blocked φ^v step needs: a
    block's weight is the sum over its dimensions; the whole weight, the sum over all)."""
    if not groups:
        raise ValueError("fractional_log_weights_grouped: no group of counts")
    log_phi = np.ascontiguousarray(log_phi, dtype=np.float64)
    typed = List()
    for n in groups:
        n = np.ascontiguousarray(n, dtype=np.float64)
        if n.ndim != 3 or n.shape[1:] != log_phi.shape:
            raise ValueError(f"fractional_log_weights_grouped: counts of shape {n.shape} for φ of shape "
                             f"{log_phi.shape}; (E, L, D) expected")
        typed.append(n)
    out = np.empty(log_phi.shape)
    _fractional_log_weights_grouped(typed, log_phi, math.log(delta), out)
    return out


def fractional_log_weights_by_dimension(n: np.ndarray, log_phi: np.ndarray, delta: float) -> np.ndarray:
    """(L, D): the terms of the weight at one φ (L, D) for the real counts ``n`` (E, L, D) and
    concentration ``delta`` > 0, summed over homes but kept per dimension (what the blocked φ^v step
    needs: a block's weight is the sum over its dimensions; the whole weight, the sum over all)."""
    return fractional_log_weights_grouped([n], log_phi, delta)
