"""The power target's view evidence with θ^v and φ^v integrated out given the other homes (issue 29):
what the φ^v-marginal block move (:mod:`spco.model.phi_moves`) weighs a home's assignments by.

For a concept l, a home e's weighted view counts n (D,) (Σ_t ω_t v_t of its samples in l) and the
other homes' counts n_{−e,l} (E', D), with θ^v_{e,l} ~ Dir(δ φ_l) integrated exactly,

    p(n | n_{−e}) = E_{φ_l | n_{−e,l}} [ B(δ φ_l + n) / B(δ φ_l) ]

(up to the multinomial coefficients, the same for every assignment). Given the table counts M of
the other homes' whole parts (the CRT tables of ⌊n_{−e}⌋, drawn by the φ^v step) φ_l's conditional
is Dir(α + M + F) · w(φ) / Z: F the fractions below one (what the φ^v step's proposal counts), w the
fractional weight of its Metropolis–Hastings test (over the other homes' real counts). So
E[H | M] = E_q[H w] / E_q[w] with q = Dir(α + M + F), exact for real counts (:class:`ConceptGrid`).

Each Dirichlet expectation of a product over dimensions is a saddlepoint over independent gammas
conditioned on their sum (φ = g / Σ g, g_d ~ Gamma(a_d, r), φ independent of S = Σ g): for every r,
E_Dir[Π h] = Π_d m_d(r) · f̃_S(1) / f_S(1), m_d(r) = E_r h_d(g_d) by a one-dimensional quadrature in
ln g (:mod:`spco.model.kernels.phi_quadrature`), f̃_S the density of S when each g_d is tilted by
h_d, f_S = Gamma(A, r); at the saddle r̂ (Σ_d Ẽ g_d = 1) f̃_S(1) is its normal density with the
Edgeworth term. Checked against brute force in tests/test_phi_marginal_evidence.py (errors ≤ 10⁻³
nats on the 3-simplex, 2·10⁻³ at D = 400) and benchmarks/phi_marginal_evidence.py ``check``.
"""

from __future__ import annotations

import numpy as np
from scipy.special import gammaln

from spco.model.kernels.phi_quadrature import _add_fractional_weight, _saddlepoint, _with_dm_factor

__all__ = ["ConceptGrid", "log_dirichlet_expectation", "log_h_dm", "log_h_power"]

#: Newton's tolerance on the tilted sum's mean (1).
TOLERANCE = 1e-12


def log_h_dm(g: np.ndarray, n: np.ndarray, delta: float) -> np.ndarray:
    """ln Γ(δ g + n) − ln Γ(δ g): one dimension's Dirichlet–multinomial factor (θ integrated out)."""
    x = delta * g
    return gammaln(x + n) - gammaln(x)


def log_h_power(g: np.ndarray, n: np.ndarray, delta: float) -> np.ndarray:
    """n ln g: the factor whose Dirichlet expectation is B(a + n) / B(a) exactly (a check's case)."""
    return n * np.log(g)


def quadrature_grid(a: np.ndarray, n: np.ndarray, r_lo: float, r_hi: float,
                    points_per_sd: float = 2.5, max_points: int = 6000) -> tuple[np.ndarray, np.ndarray]:
    """Per dimension a uniform grid in u = ln g wide enough for the tilted density
    ∝ g^a e^{−r g} h(g) for every rate r in [r_lo, r_hi]: up to ln g_hi + 0.5,
    g_hi = (a + n + 1 + 12 √(a + n + 1) + 30) / r_lo, and down 8 + ln(r_hi / r_lo) + 60 / (a + 1)
    (the left tail decays as e^{(a + 1) u}); spacing at most 1 / (points_per_sd √(a + n + 1))
    (the density's spread in u). Returns (u (Q, K), step (Q,))."""
    s = a + n + 1.0
    top = np.log((s + 12.0 * np.sqrt(s) + 30.0) / r_lo) + 0.5
    width = 8.5 + np.log(r_hi / r_lo) + 60.0 / (a + 1.0)
    k = int(min(max_points, max(64, np.ceil(np.max(width * points_per_sd * np.sqrt(s))))))
    steps = width / (k - 1)
    u = top[:, None] - width[:, None] + steps[:, None] * np.arange(k)[None, :]
    return u, steps


def saddle(rows: np.ndarray, g: np.ndarray, a: np.ndarray, a_0: float, big_a: float,
           r0: float) -> dict[str, float]:
    """ln E_{Dir(a)} Π_d h_d(φ_d) from the quadrature ``rows`` (Q, K) = a_d ln g − ln Γ(a_d)
    + ln h_d(g) + ln(step) at nodes g (Q, K) of the dimensions whose h_d ≠ 1 (the others, of total
    parameter a_0, plain gammas): the value, the Edgeworth term's log, the saddle's rate and the
    grid's largest end mass. Raises RuntimeError if Newton's iteration does not converge."""
    out = np.empty(5)
    _saddlepoint(np.ascontiguousarray(rows, dtype=np.float64), np.ascontiguousarray(g, dtype=np.float64),
                 np.ascontiguousarray(a, dtype=np.float64), float(a_0), float(big_a), float(r0), TOLERANCE,
                 out)
    if out[4] != 1.0:
        raise RuntimeError(f"saddlepoint did not converge (rate {out[2]:.6g})")
    return {"value": float(out[0]), "edgeworth": float(out[1]), "rate": float(out[2]),
            "grid_end_mass": float(out[3])}


def log_dirichlet_expectation(a: np.ndarray, n: np.ndarray, delta: float, log_h=log_h_dm,
                              points_per_sd: float = 2.5) -> dict[str, float]:
    """ln E_{φ ~ Dir(a)} [Π_d h_d(φ_d)], h_d = exp(log_h(φ_d, n_d, δ)) (h_d = 1 where n_d = 0), by the
    saddlepoint (module docstring). Returns the value, the Edgeworth term's log, r̂ and the grid's
    largest end mass."""
    a = np.asarray(a, dtype=float)
    n = np.asarray(n, dtype=float)
    q = n > 0
    a_q, n_q = a[q], n[q]
    big_a = a.sum()
    u, step = quadrature_grid(a_q, n_q, big_a, big_a + n_q.sum() + 1.0, points_per_sd)
    g = np.exp(u)
    rows = a_q[:, None] * u - gammaln(a_q)[:, None] + log_h(g, n_q[:, None], delta) + np.log(step)[:, None]
    return saddle(rows, g, a_q, float(a[~q].sum()), big_a, big_a)


class ConceptGrid:
    """E_{φ | M, n_{−e}}[Π_d Γ(δφ_d + n_d)/Γ(δφ_d)] for one concept and one table draw, exact for real
    counts (module docstring): ``a`` (D,) = α + M + F, ``others`` (E', D) the other homes' real counts
    of the concept (for w), ``n_bound`` (D,) the largest counts :meth:`log_expectation` is asked for
    (the grid is made wide enough for them)."""

    def __init__(self, a: np.ndarray, others: np.ndarray, delta: float, n_bound: np.ndarray,
                 points_per_sd: float = 2.5) -> None:
        a = np.ascontiguousarray(a, dtype=np.float64)
        others = np.ascontiguousarray(others, dtype=np.float64).reshape(-1, a.shape[0])
        self.a, self.delta = a, float(delta)
        fractional = others != np.floor(others)
        self.big_a = float(a.sum())
        spread = np.asarray(n_bound, dtype=np.float64) + fractional.sum(0)
        r_hi = self.big_a + float(np.sum(n_bound)) + 1.0 + spread.sum()
        u, step = quadrature_grid(a, spread, self.big_a, r_hi, points_per_sd)
        self.g = np.ascontiguousarray(np.exp(u))
        base = a[:, None] * u - gammaln(a)[:, None] + np.log(step)[:, None]
        _add_fractional_weight(self.g, others, self.delta, base)
        self.base = base
        self._scratch = np.empty_like(base)
        self.denominator = saddle(self.base, self.g, a, 0.0, self.big_a, self.big_a)

    def log_expectation(self, n: np.ndarray) -> dict[str, float]:
        """ln E[Π_d Γ(δφ_d + n_d)/Γ(δφ_d) | M, n_{−e}] for a home's counts n (D,): the value and the
        grid's largest end mass."""
        n = np.ascontiguousarray(n, dtype=np.float64)
        if not n.sum() > 0:
            return {"value": 0.0, "grid_end_mass": 0.0}
        _with_dm_factor(self.base, self.g, n, self.delta, self._scratch)
        num = saddle(self._scratch, self.g, self.a, 0.0, self.big_a, self.big_a)
        return {"value": num["value"] - self.denominator["value"],
                "grid_end_mass": max(num["grid_end_mass"], self.denominator["grid_end_mass"])}

    def log_predictive(self, n: np.ndarray) -> float:
        """ln p(n | M, n_{−e}) of a home's counts n (D,) in this concept, θ integrated out:
        :meth:`log_expectation` + ln Γ(δ) − ln Γ(δ + Σ n) (0 for no counts)."""
        total = float(np.sum(n))
        if not total > 0:
            return 0.0
        return self.log_expectation(n)["value"] + float(gammaln(self.delta) - gammaln(self.delta + total))
