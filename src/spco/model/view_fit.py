"""How well a set of visual distributions explains a home's views: the numbers behind the
knowledge's view-fit diagnostics (:mod:`spco.knowledge.diagnostics`), computed where the homes are
(a shard scores its own homes, :meth:`spco.model.shard.HomeShard.held_out_view_fits`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.model.state import PreparedData

__all__ = ["concept_visual_totals", "held_out_view_fits", "view_fit"]


def view_fit(log_phi_visual: np.ndarray, log_g0: np.ndarray, visual: Any) -> float | None:
    """How well a knowledge's visual distributions explain a home's views:
    :data:`spco.knowledge.diagnostics.VIEW_FIT_MEASURE`.

    Parameters
    ----------
    log_phi_visual: (L, D) log φ^v; log_g0: (L,) log G_0; visual: (n, D) counts (sparse or dense).

    Returns the median over the views with at least one count of their per-count log-likelihood under
    the mixture Σ_l G_0,l Mult(v | φ^v_l) (without the multinomial coefficient), plus log D; ``None``
    if no view has a count. About 0.6–0.8 (synthetic homes) and 0.9–1.4 (SIGVerse fc7) for homes
    like the experienced ones; negative for views from another feature extractor or distribution.
    """
    counts = sp.csr_array(visual, dtype=np.float64)
    totals = np.asarray(counts.sum(axis=1)).ravel()
    seen = totals > 0
    if not seen.any():
        return None
    log_phi = np.maximum(np.asarray(log_phi_visual, dtype=np.float64), np.log(np.finfo(float).tiny))
    per_concept = np.asarray(counts[seen] @ log_phi.T)  # (n, L): Σ_d v_d log φ_l,d
    mixture = logsumexp(per_concept + np.asarray(log_g0, dtype=np.float64)[None, :], axis=1)
    return float(np.median(mixture / totals[seen]) + math.log(log_phi.shape[1]))


def _home_concept_counts(data: PreparedData, concepts: np.ndarray, e: int,
                         n_concepts: int) -> np.ndarray:
    """Home ``e``'s visual counts by concept, (L, D) n_{e,l,d}."""
    rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
    n = rows.stop - rows.start
    onehot = sp.csr_array((np.ones(n), (concepts[rows], np.arange(n))), shape=(n_concepts, n))
    return np.asarray((onehot @ sp.csr_array(data.visual[rows], dtype=np.float64)).todense())


def concept_visual_totals(data: PreparedData, concepts: np.ndarray, n_concepts: int) -> np.ndarray:
    """The visual counts of each concept summed over the homes of ``data``, (L,) N_l (summed over
    shards, the totals of all homes: integers, so the sum is exact in any order)."""
    return sum((_home_concept_counts(data, concepts, e, n_concepts).sum(1) for e in range(data.n_homes)),
               np.zeros(n_concepts))


def held_out_view_fits(log_phi_v: np.ndarray, log_g0: np.ndarray, totals: np.ndarray,
                       data: PreparedData, concepts: np.ndarray) -> list[float | None]:
    """The held-out :func:`view_fit` of every home of ``data``, ``totals`` the (L,) visual counts by
    concept of all homes of the fit.

    A home's views helped to learn φ^v, so their fit under φ^v itself flatters them. Each home is
    scored instead under φ^v without its own counts: φ^v_l × (N_l + D) − n_{e,l} (N_l the counts
    of concept l over all homes, n_{e,l} home e's, with the concepts of the chain's last sweep, to
    which φ^v is aligned), floored at 1 % of φ^v_l × (N_l + D) and renormalised.
    """
    L, D = log_phi_v.shape
    mass = np.exp(log_phi_v) * (totals + D)[:, None]
    fits = []
    for e in range(data.n_homes):  # a loop over homes, each scored as a whole
        held_out = np.maximum(mass - _home_concept_counts(data, concepts, e, L), 0.01 * mass)
        log_held_out = np.log(held_out / held_out.sum(1, keepdims=True))
        rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
        fits.append(view_fit(log_held_out, log_g0, data.visual[rows]))
    return fits
