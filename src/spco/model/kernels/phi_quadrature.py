"""The per-dimension quadrature of the power target's φ^v-marginal evidence
(:mod:`spco.model.phi_evidence`): the rows of a concept's grid in u = ln g (the fractional weight w
of the other homes' real counts, a home's Dirichlet–multinomial factor) and the saddlepoint over
independent gammas conditioned on their sum. Compiled: at fc7's size a grid has ~4,096 rows of
~500 nodes and each saddlepoint runs ~10 Newton steps over all of them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def _add_fractional_weight(g: np.ndarray, others: np.ndarray, delta: float, out: np.ndarray) -> None:
    """out[q, j] += Σ_e [ln Γ(x + n) − ln Γ(x + ⌊n⌋) − [⌊n⌋ = 0] n ln x], x = δ g[q, j], over the
    counts n = others[e, q] (E', Q) with a fractional part: ln w of the φ^v step's
    Metropolis–Hastings test (:meth:`~spco.model.observations.HierarchicalMultinomial.fractional_log_weight`)
    at every node. A node whose x underflows to 0 gets −inf."""
    n_rows, n_nodes = g.shape
    for q in range(n_rows):
        for e in range(others.shape[0]):
            n = others[e, q]
            whole = math.floor(n)
            if n == whole:
                continue
            tilt = n if whole == 0.0 else 0.0
            for j in range(n_nodes):
                x = delta * g[q, j]
                if x > 0.0:
                    out[q, j] += math.lgamma(x + n) - math.lgamma(x + whole) - tilt * math.log(x)
                else:
                    out[q, j] = -math.inf


@njit(cache=True, error_model="numpy")
def _with_dm_factor(base: np.ndarray, g: np.ndarray, n: np.ndarray, delta: float, out: np.ndarray) -> None:
    """out = base + ln Γ(δ g + n_q) − ln Γ(δ g) on the rows q with n_q > 0 (a home's counts n (Q,):
    θ integrated out), base elsewhere."""
    n_rows, n_nodes = g.shape
    for q in range(n_rows):
        nq = n[q]
        for j in range(n_nodes):
            value = base[q, j]
            if nq > 0.0:
                x = delta * g[q, j]
                value += math.lgamma(x + nq) - math.lgamma(x) if x > 0.0 else -math.inf
            out[q, j] = value


@njit(cache=True, error_model="numpy")
def _row_moments(rows: np.ndarray, g: np.ndarray, a: np.ndarray, r: float, order: int,
                 moments: np.ndarray) -> float:
    """For the tilted rows lf = rows − r g + a ln r: moments[q] = (ln Σ_j e^lf, mean, then central
    moments 2..order of g under p ∝ e^lf); returns the largest share of a row's mass at its first or
    last node."""
    n_rows, n_nodes = rows.shape
    log_r = math.log(r)
    ends = 0.0
    for q in range(n_rows):
        top = -math.inf
        for j in range(n_nodes):
            v = rows[q, j] - r * g[q, j]
            if v > top:
                top = v
        total = 0.0
        first = 0.0
        for j in range(n_nodes):
            total += math.exp(rows[q, j] - r * g[q, j] - top)
            first += math.exp(rows[q, j] - r * g[q, j] - top) * g[q, j]
        m1 = first / total
        moments[q, 0] = top + math.log(total) + a[q] * log_r
        moments[q, 1] = m1
        for k in range(2, order + 1):
            moments[q, k] = 0.0
        for j in range(n_nodes):
            p = math.exp(rows[q, j] - r * g[q, j] - top) / total
            c = g[q, j] - m1
            power = c
            for k in range(2, order + 1):
                power *= c
                moments[q, k] += p * power
        last = n_nodes - 1
        end = max(math.exp(rows[q, 0] - r * g[q, 0] - top),
                  math.exp(rows[q, last] - r * g[q, last] - top)) / total
        if end > ends:
            ends = end
    return ends


@njit(cache=True, error_model="numpy")
def _saddlepoint(rows: np.ndarray, g: np.ndarray, a: np.ndarray, a_0: float, big_a: float, r0: float,
                 tol: float, out: np.ndarray) -> None:
    """ln E_{Dir}[Π_d h_d(φ_d)] from the quadrature rows (Q, K) = a_d ln g − ln Γ(a_d) + ln h_d(g) +
    ln(step) at the nodes g (the other dimensions, of total parameter a_0, plain gammas): the rate r
    where the tilted sum has mean 1 (Newton), the sum's density there normal with the Edgeworth term
    1 + κ4/(8V²) − 5κ3²/(24V³). out = (value, ln of the Edgeworth term, r, the rows' largest end
    mass, converged: 1 or 0)."""
    n_rows = rows.shape[0]
    moments = np.empty((n_rows, 5))
    r = r0
    mean = var = 0.0
    converged = 0.0
    for _ in range(200):
        _row_moments(rows, g, a, r, 2, moments)
        mean = a_0 / r
        var = a_0 / (r * r)
        for q in range(n_rows):
            mean += moments[q, 1]
            var += moments[q, 2]
        if abs(mean - 1.0) < tol:
            converged = 1.0
            break
        r = max(r + (mean - 1.0) / var, 0.5 * r)
    ends = _row_moments(rows, g, a, r, 4, moments)
    log_m = 0.0
    var = a_0 / (r * r)
    k3 = 2.0 * a_0 / r**3
    k4 = 6.0 * a_0 / r**4
    for q in range(n_rows):
        log_m += moments[q, 0]
        var += moments[q, 2]
        k3 += moments[q, 3]
        k4 += moments[q, 4] - 3.0 * moments[q, 2] ** 2
    edge = 1.0 + k4 / (8.0 * var * var) - 5.0 * k3 * k3 / (24.0 * var**3)
    log_f = big_a * math.log(r) - r - math.lgamma(big_a)
    out[0] = log_m - 0.5 * math.log(2.0 * math.pi * var) + math.log(edge) - log_f
    out[1] = math.log(edge)
    out[2] = r
    out[3] = ends
    out[4] = converged
