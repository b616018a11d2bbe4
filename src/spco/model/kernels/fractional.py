"""The exact remainder of the power target's φ^v proposal: Σ over fractional counts of
ln Γ(a + n) − ln Γ(a + ⌊n⌋) − [⌊n⌋ = 0] n ln a, a = δ φ (see
:meth:`spco.model.observations.HierarchicalMultinomial.fractional_log_weight`), per concept and
dimension (the blocked φ^v step weighs a block by the sum over its dimensions, the whole weight is
the sum over all of them).

The counts may come as several groups of homes (a worker's one-home shards): each group's terms
are summed over its homes in order, as one call per group would sum them, and the groups' sums are
added in order, as the shards' answers are (:func:`spco.model.shard_group._sum`), so the result is
the same to the bit. What depends on a dimension's a only — a = exp(ln δ + ln φ) and ln Γ(a), the
second term of every count below 1 — is computed once per concept and dimension for every home
(most fractional counts are below 1: the views' weights are powers s < 1 of small counts).

The blocked φ^v step evaluates the weight at several φ for the same counts (at its start and once
a pass): :class:`FractionalCounts` gathers the counts' fractional entries once, by concept and
dimension (a worker of 8 homes at fc7's size holds 491,520 counts, about 37 % of them fractional),
and every evaluation then reads only those, one concept and dimension after another.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def _gather_fractional(n: np.ndarray, home_group: np.ndarray):  # pragma: no cover - compiled
    """The fractional entries of the counts ``n`` (E, L, D) of homes in groups ``home_group`` (E,)
    int32 (non-decreasing: the groups' homes one after another) by pair p = l·D + k: (starts
    (L·D + 1,) int64: pair p's entries are starts[p]:starts[p + 1]; their counts (F,) float64 and
    groups (F,) int32), each pair's entries in group and then home order."""
    n_homes, n_concepts, n_dims = n.shape
    n_pairs = n_concepts * n_dims
    starts = np.zeros(n_pairs + 1, dtype=np.int64)
    for e in range(n_homes):
        for c in range(n_concepts):
            for k in range(n_dims):
                x = n[e, c, k]
                if x != math.floor(x):
                    starts[c * n_dims + k + 1] += 1
    for p in range(n_pairs):
        starts[p + 1] += starts[p]
    counts = np.empty(starts[n_pairs])
    group = np.empty(starts[n_pairs], dtype=np.int32)
    fill = starts[:-1].copy()
    for e in range(n_homes):
        for c in range(n_concepts):
            for k in range(n_dims):
                x = n[e, c, k]
                if x != math.floor(x):
                    p = c * n_dims + k
                    counts[fill[p]] = x
                    group[fill[p]] = home_group[e]
                    fill[p] += 1
    return starts, counts, group


@njit(cache=True, error_model="numpy")
def _fractional_log_weights(starts: np.ndarray, counts: np.ndarray, group: np.ndarray, log_phi: np.ndarray,
                            log_delta: float, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out[l, k] = Σ over the groups in order of (Σ over the group's fractional entries n of the pair
    (l, k), in home order, of ln Γ(a + n) − ln Γ(a + ⌊n⌋) − [⌊n⌋ = 0] n ln a, starting from 0),
    a = exp(log_delta + log_phi[l, k]); −inf where such an entry's a underflows to 0, 0 where the
    pair has no fractional entry (the arrays of :func:`_gather_fractional`)."""
    n_concepts, n_dims = log_phi.shape
    for c in range(n_concepts):
        for k in range(n_dims):
            p = c * n_dims + k
            j, end = starts[p], starts[p + 1]
            total = 0.0
            if j < end:
                log_a = log_delta + log_phi[c, k]
                a = math.exp(log_a)
                log_gamma_a = 0.0
                known = False
                while j < end:
                    g = group[j]
                    group_sum = 0.0
                    while j < end and group[j] == g:
                        x = counts[j]
                        whole = math.floor(x)
                        if a > 0.0:
                            if whole == 0.0:
                                if not known:
                                    log_gamma_a = math.lgamma(a + whole)
                                    known = True
                                group_sum += math.lgamma(a + x) - log_gamma_a - x * log_a
                            else:
                                group_sum += math.lgamma(a + x) - math.lgamma(a + whole) - 0.0 * log_a
                        else:
                            group_sum = -math.inf
                        j += 1
                    total = total + group_sum
            out[c, k] = total


class FractionalCounts:
    """The fractional entries of real counts (groups of homes, each (E_g, L, D)), gathered once;
    :meth:`log_weights` evaluates the weight's terms at any φ from them — what the blocked φ^v step
    needs at its start and once a pass, for the same counts. The counts are read when it is made
    (a later change to them is not seen)."""

    def __init__(self, groups: list[np.ndarray]) -> None:
        if not groups:
            raise ValueError("FractionalCounts: no group of counts")
        arrays = [np.asarray(n, dtype=np.float64) for n in groups]
        for n in arrays:
            if n.ndim != 3 or n.shape[1:] != arrays[0].shape[1:]:
                raise ValueError(f"FractionalCounts: counts of shape {n.shape}; (E, L, D) expected, the same "
                                 f"L and D in every group")
        #: (L, D) of the counts
        self.shape: tuple[int, int] = (int(arrays[0].shape[1]), int(arrays[0].shape[2]))
        # the groups' homes one after another, each home's group beside it (one array: a typed list
        # of the groups would compile Numba's list code in every process, about 1.7 s)
        homes = np.ascontiguousarray(arrays[0] if len(arrays) == 1 else np.concatenate(arrays))
        home_group = np.repeat(np.arange(len(arrays), dtype=np.int32), [n.shape[0] for n in arrays])
        self._starts, self._counts, self._group = _gather_fractional(homes, home_group)

    @property
    def n_fractional(self) -> int:
        """How many of the counts have a fractional part."""
        return int(self._counts.size)

    def log_weights(self, log_phi: np.ndarray, delta: float) -> np.ndarray:
        """(L, D): the weight's terms at log φ (L, D) and concentration ``delta`` > 0, summed over
        each group's homes and then over the groups, in order, kept per dimension (0 where no
        count is fractional)."""
        log_phi = np.ascontiguousarray(log_phi, dtype=np.float64)
        if log_phi.shape != self.shape:
            raise ValueError(f"FractionalCounts.log_weights: counts of shape (E, {self.shape[0]}, "
                             f"{self.shape[1]}) for φ of shape {log_phi.shape}; (E, L, D) expected")
        out = np.empty(self.shape)
        _fractional_log_weights(self._starts, self._counts, self._group, log_phi, math.log(delta), out)
        return out


def fractional_log_weights_grouped(groups: list[np.ndarray], log_phi: np.ndarray, delta: float) -> np.ndarray:
    """(L, D): the terms of the weight at one φ (L, D) for the real counts of each group of homes
    in ``groups`` (each (E_g, L, D)) and concentration ``delta`` > 0, summed over each group's homes
    and then over the groups, in order, but kept per dimension: bit for bit the sum of
    :func:`fractional_log_weights_by_dimension` over the groups (what the blocked φ^v step needs: a
    block's weight is the sum over its dimensions; the whole weight, the sum over all). At several φ
    for the same counts: :class:`FractionalCounts`, made once."""
    return FractionalCounts(groups).log_weights(log_phi, delta)


def fractional_log_weights_by_dimension(n: np.ndarray, log_phi: np.ndarray, delta: float) -> np.ndarray:
    """(L, D): the terms of the weight at one φ (L, D) for the real counts ``n`` (E, L, D) and
    concentration ``delta`` > 0, summed over homes but kept per dimension (what the blocked φ^v step
    needs: a block's weight is the sum over its dimensions; the whole weight, the sum over all)."""
    return fractional_log_weights_grouped([n], log_phi, delta)
