"""Categorical draws: one per row of a log-probability matrix, and the joint (C, R) draw.

:func:`sample_categorical_log` and :func:`sample_joint_assignment` (every sample's concept and
region at once, p ∝ G π N(x | R) p(v, w | C)).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spco.model.kernels.dispatch import _PARALLEL_MIN, _call_in_parts
from spco.model.kernels.special import _scaled_exp


@njit(cache=True)
def _draw_log(log_p: np.ndarray, u: float) -> int:
    """Index drawn from unnormalised log-probabilities ``log_p`` (1-D) with the uniform ``u``;
    overwrites ``log_p`` with the shifted weights."""
    width = log_p.size
    top = -np.inf
    for j in range(width):
        if log_p[j] > top:
            top = log_p[j]
    total = 0.0
    for j in range(width):
        log_p[j] = np.exp(log_p[j] - top)
        total += log_p[j]
    target = u * total
    acc = 0.0
    for j in range(width):
        acc += log_p[j]
        if acc > target:
            return j
    return width - 1


@njit(cache=True, nogil=True)
def _categorical_rows(log_p: np.ndarray, u: np.ndarray, out: np.ndarray, first: int, stop: int) -> None:
    """Rows first..stop−1 of :func:`sample_categorical_log` into ``out`` (:func:`_call_in_parts`)."""
    for t in range(first, stop):
        out[t] = _draw_log(log_p[t].copy(), u[t])


def sample_categorical_log(log_p: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One draw per row from unnormalised log-probabilities ``log_p`` of shape (n, J).

    Subtracts the row maximum before exponentiating, so gaps of thousands of nats are safe. Rows
    must hold at least one finite entry. Returns int64 indices of shape (n,).
    """
    u = rng.random(log_p.shape[0])
    out = np.empty(log_p.shape[0], dtype=np.int64)
    log_p = np.ascontiguousarray(log_p, dtype=np.float64)
    _call_in_parts(_categorical_rows, (log_p, u, out), log_p.shape[0], parallel=log_p.size >= _PARALLEL_MIN)
    return out


#: Samples per task of :func:`_joint_assignment` (scratch arrays are allocated once per task).
_ASSIGNMENT_CHUNK = 64


def _joint_assignment(log_g: np.ndarray, log_pi: np.ndarray, pi_scaled: np.ndarray, pi_row_max: np.ndarray,
                      homes: np.ndarray, concept_ll: np.ndarray, region_ll: np.ndarray, u_concept: np.ndarray,
                      u_region: np.ndarray) -> np.ndarray:
    """The flat C·K + R draw of every sample (:func:`_joint_assignment_chunks` over all chunks of
    :data:`_ASSIGNMENT_CHUNK` samples, on Numba's thread count when the samples' (C, R) pairs
    number at least 16 × :data:`~spco.model.kernels.dispatch._PARALLEL_MIN`, ~1,700 samples at
    L = 15, K = 20: one home's ~160 samples run on this thread, where the pool cost twice their CPU)."""
    n = homes.size
    out = np.empty(n, dtype=np.int64)
    args = (log_g, log_pi, pi_scaled, pi_row_max, homes, concept_ll, region_ll, u_concept, u_region, out)
    n_chunks = (n + _ASSIGNMENT_CHUNK - 1) // _ASSIGNMENT_CHUNK
    _call_in_parts(_joint_assignment_chunks, args, n_chunks,
                   parallel=n * log_pi.shape[1] * log_pi.shape[2] >= 16 * _PARALLEL_MIN)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _joint_assignment_chunks(log_g: np.ndarray, log_pi: np.ndarray, pi_scaled: np.ndarray,
                             pi_row_max: np.ndarray, homes: np.ndarray, concept_ll: np.ndarray,
                             region_ll: np.ndarray, u_concept: np.ndarray, u_region: np.ndarray,
                             out: np.ndarray, first: int, stop: int) -> None:
    # the samples of chunks first..stop-1 into out; pi_scaled: (E, K, L), regions before concepts,
    # so that the sums over regions run for all concepts side by side (vector lanes); each sum
    # still adds its terms in region order
    n = homes.size
    n_concepts = log_pi.shape[1]
    n_regions = log_pi.shape[2]
    for chunk in range(first, stop):
        first = chunk * _ASSIGNMENT_CHUNK
        size = min(n, first + _ASSIGNMENT_CHUNK) - first
        # the chunk's exp(region log-likelihood − its row maximum), in one vectorised pass
        shifted = np.empty(size * max(n_regions, n_concepts))
        r = np.empty(size * n_regions)
        powers = np.empty(shifted.size)
        r_max = np.empty(size)
        for i in range(size):
            top = -np.inf
            for m in range(n_regions):
                top = max(top, region_ll[first + i, m])
            r_max[i] = top
            for m in range(n_regions):
                shifted[i * n_regions + m] = region_ll[first + i, m] - top
        _scaled_exp(shifted[:size * n_regions], 1.0, r, powers[:size * n_regions])
        # marginal of C: G · lik · Σ_m π_{c,m} N(x | m), the sum over regions a dot product
        sums = np.zeros(size * n_concepts)
        log_c = np.empty(size * n_concepts)
        tops = np.empty(size)
        linear = np.empty(size, dtype=np.bool_)
        for i in range(size):
            t = first + i
            e = homes[t]
            s = sums[i * n_concepts:(i + 1) * n_concepts]
            for m in range(n_regions):
                rm = r[i * n_regions + m]
                row = pi_scaled[e, m]
                for c in range(n_concepts):
                    s[c] += row[c] * rm
            top = -np.inf
            ok = True
            for c in range(n_concepts):
                ok &= s[c] > 1e-250
                value = log_g[e, c] + concept_ll[t, c] + pi_row_max[e, c]
                log_c[i * n_concepts + c] = value
                top = max(top, value)
            tops[i] = top
            linear[i] = ok
            for c in range(n_concepts):
                shifted[i * n_concepts + c] = log_c[i * n_concepts + c] - top
        weights_c = np.empty(size * n_concepts)
        _scaled_exp(shifted[:size * n_concepts], 1.0, weights_c, powers[:size * n_concepts])
        weights = np.empty(n_regions)
        for i in range(size):
            t = first + i
            e = homes[t]
            s = sums[i * n_concepts:(i + 1) * n_concepts]
            w = weights_c[i * n_concepts:(i + 1) * n_concepts]
            lc = log_c[i * n_concepts:(i + 1) * n_concepts]
            if linear[i]:  # weights exp(log G + loglik + max log π − top) · sum: no logarithm
                acc = 0.0  # (the largest weight is ≥ 1e-250 times the largest sum: no underflow)
                for c in range(n_concepts):
                    w[c] *= s[c]
                    acc += w[c]
                chosen = _draw_linear(w, acc, u_concept[t])
            else:  # some sum too small for the dot product: exact log-sum-exps
                for c in range(n_concepts):
                    if s[c] > 1e-250:
                        log_sum = np.log(s[c])
                    else:
                        for m in range(n_regions):  # (the weights array is free until R | C)
                            weights[m] = log_pi[e, c, m] - pi_row_max[e, c] + region_ll[t, m] - r_max[i]
                        inner_top = weights.max()
                        inner = 0.0
                        for m in range(n_regions):
                            inner += np.exp(weights[m] - inner_top)
                        log_sum = inner_top + np.log(inner)
                    lc[c] += log_sum
                chosen = _draw_log(lc, u_concept[t])
            # R | C: the weights π_{C,m} N(x | m) of the dot product above, or in log space when it
            # underflowed
            if s[chosen] > 1e-250:
                for m in range(n_regions):
                    weights[m] = pi_scaled[e, m, chosen] * r[i * n_regions + m]
                region = _draw_linear(weights, s[chosen], u_region[t])
            else:
                for m in range(n_regions):
                    weights[m] = log_pi[e, chosen, m] + region_ll[t, m]
                region = _draw_log(weights, u_region[t])
            out[t] = chosen * n_regions + region


@njit(cache=True)
def _draw_linear(weights: np.ndarray, total: float, u: float) -> int:
    """Index drawn from non-negative ``weights`` summing to ``total`` with the uniform ``u``
    (never an index of weight 0)."""
    target = u * total
    acc = 0.0
    last = 0
    for j in range(weights.size):
        if weights[j] > 0.0:
            acc += weights[j]
            last = j
            if acc > target:
                return j
    return last


def sample_joint_assignment(log_g: np.ndarray, log_pi: np.ndarray, homes: np.ndarray,
                            concept_ll: np.ndarray, region_ll: np.ndarray,
                            rng: np.random.Generator) -> np.ndarray:
    """Flat index C·K + R of one draw per sample from
    p(C=l, R=m) ∝ exp(log_g[e,l] + log_pi[e,l,m] + concept_ll[t,l] + region_ll[t,m]), e = homes[t].

    Shapes: log_g (E, L), log_pi (E, L, K), homes (N,), concept_ll (N, L), region_ll (N, K).
    Drawn as C from its marginal (Σ over regions), then R | C, row by row without materialising
    the (N, L, K) table; the sum over regions is a dot product of exp-scaled factors, with an
    exact log-sum-exp wherever that product would underflow.
    """
    u = rng.random((2, homes.shape[0]))
    log_pi = np.ascontiguousarray(log_pi, dtype=np.float64)
    pi_row_max = log_pi.max(axis=2)
    pi_scaled = np.ascontiguousarray(np.swapaxes(np.exp(log_pi - pi_row_max[:, :, None]), 1, 2))
    return _joint_assignment(np.ascontiguousarray(log_g, dtype=np.float64), log_pi, pi_scaled, pi_row_max,
                             np.ascontiguousarray(homes, dtype=np.int64),
                             np.ascontiguousarray(concept_ll, dtype=np.float64),
                             np.ascontiguousarray(region_ll, dtype=np.float64), u[0], u[1])
