"""The visual prior in the units of the views' proportions: δ^v and α^v estimated from the homes.

The paper's α^v = 3 per dimension and δ^v = 3·10^5 are set against raw counts (a SIGVerse fc7 view
holds ~7,000): with every count a draw they are swamped by the data and hardly matter. Under the
power likelihood (``TransferHyperparameters.target="power"``) a view counts w = 16 draws, and the
same constants decide: φ^v stays near its uniform prior and θ^v near φ^v (benchmarks/README.md,
"Issue 29: the power target against the cut sampler"). A Dirichlet's concentration is a statement
about the spread of proportions, which needs no unit, so both are estimated from the homes by the
method of moments (an empirical-Bayes estimate), on the concepts of the sampler's start:

- δ^v: θ^v_{e,l} ~ Dir(δ^v φ^v_l) says Σ_d Var_e θ_{e,l,d} = Σ_d φ_{l,d}(1 − φ_{l,d}) / (δ^v + 1).
  The homes' mean proportions M_{e,l} of their views in concept l estimate θ_{e,l} with a sampling
  variance W_{e,l} = Σ_t ||p_t − M_{e,l}||² / (m (m − 1)) (m views); the spread between homes less
  that variance estimates the left-hand side, pooled over concepts:
  δ̂^v + 1 = Σ_l Σ_d φ̂_{l,d}(1 − φ̂_{l,d}) / Σ_l max(B_l, 0), B_l = Σ_d Var_e M_{e,l,d} − mean_e W_{e,l}.
- α^v: φ^v_l ~ Dir(α^v 1) (D dimensions) says E Σ_d (φ_{l,d} − 1/D)² = (1 − 1/D) / (α^v D + 1);
  the concepts' φ̂_l (the mean of their homes' M_{e,l}) give α̂^v.

Only concepts with views in two homes or more (each with two views or more) enter δ̂^v; only
concepts with a view enter α̂^v. ``None`` where there is nothing to estimate from.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from spco.model.state import PreparedData

__all__ = ["estimate_visual_prior", "home_view_moments"]


def home_view_moments(data: PreparedData, concepts: np.ndarray, n_concepts: int
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each home's taught views by concept, as proportions: (m (E, L) views, S (E, L, D) the sum of
    their proportions p_t = v_t / Σ_d v_{t,d}, Q (E, L) the sum of ||p_t||²). Samples without a view
    (no count) or without a word are left out: the start's concept of an untaught sample is a guess
    (a new home in a joint fit: its views spread over the concepts would read as homes that differ)."""
    E, D = data.n_homes, data.visual.shape[1]
    m = np.zeros((E, n_concepts))
    s = np.zeros((E, n_concepts, D))
    q = np.zeros((E, n_concepts))
    visual = sp.csr_array(data.visual, dtype=np.float64)
    totals = np.asarray(visual.sum(axis=1)).ravel()
    taught = np.diff(sp.csr_array(data.words).indptr) > 0
    for e in range(E):
        rows = np.arange(int(data.offsets[e]), int(data.offsets[e + 1]))
        rows = rows[(totals[rows] > 0) & taught[rows]]
        if not rows.size:
            continue
        props = sp.diags_array(1.0 / totals[rows]) @ visual[rows]
        c = np.asarray(concepts, dtype=np.int64)[rows]
        onehot = sp.csr_array((np.ones(rows.size), (c, np.arange(rows.size))), shape=(n_concepts, rows.size))
        m[e] = np.bincount(c, minlength=n_concepts)
        s[e] = np.asarray((onehot @ props).todense())
        q[e] = np.bincount(c, weights=np.asarray(props.multiply(props).sum(axis=1)).ravel(),
                           minlength=n_concepts)
    return m, s, q


def estimate_visual_prior(m: np.ndarray, s: np.ndarray, q: np.ndarray) -> tuple[float | None, float | None]:
    """(δ̂^v, α̂^v) from the homes' view moments of :func:`home_view_moments` (all homes': m (E, L),
    s (E, L, D), q (E, L)), by the method of moments of the module docstring; either ``None`` when
    nothing estimates it (no concept with views in two homes; no view) or the spread is not
    positive."""
    m = np.asarray(m, dtype=np.float64)
    s = np.asarray(s, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    D = s.shape[-1]
    spread_sum = between_sum = 0.0
    used = 0
    phis = []
    for col in range(m.shape[1]):
        seen = m[:, col] > 0
        if seen.any():
            phis.append((s[seen, col] / m[seen, col, None]).mean(axis=0))
        homes = m[:, col] >= 2
        if homes.sum() < 2:
            continue
        k = m[homes, col]
        means = s[homes, col] / k[:, None]  # (H, D)
        within = (q[homes, col] - k * (means * means).sum(axis=1)) / (k * (k - 1.0))
        between = float(means.var(axis=0, ddof=1).sum() - np.maximum(within, 0.0).mean())
        phi = means.mean(axis=0)
        spread_sum += float((phi * (1.0 - phi)).sum())
        between_sum += max(between, 0.0)
        used += 1
    delta = None
    if used and between_sum > 0:
        value = spread_sum / between_sum - 1.0
        delta = value if value > 0 and np.isfinite(value) else None
    alpha = None
    if phis:
        dev = float(np.mean([((phi - 1.0 / D) ** 2).sum() for phi in phis]))
        if dev > 0:
            value = ((1.0 - 1.0 / D) / dev - 1.0) / D
            alpha = value if value > 0 and np.isfinite(value) else None
    return delta, alpha
