"""Label-swap moves: Metropolis–Hastings steps that exchange two concept labels within one home.

Why: with ~7,000 visual and S^w = 5000 word counts per sample, a Gibbs sweep cannot move a whole
place from one concept to another; each home keeps the labelling it settles into early, and homes
that call the kitchen "concept 3" and "concept 7" never agree, so the shared φ^w, φ^v mix places
and nothing transfers.

The move proposes, for a pair of concept slots (a, b) of home e, to exchange everything that
belongs to them in that home: the samples' C_t, G_{e,a} ↔ G_{e,b} and π_{e,a} ↔ π_{e,b}, with the
home's θ^v, θ^w integrated out (they are redrawn from their conditional afterwards). The
likelihood of the data given the concepts is then a product of Dirichlet–multinomials
DM(n_{e,l} | δ φ_l), whose normalisers Γ(δ)/Γ(δ + N) do not change under a swap; the priors of C
given G and of R given π are unchanged, and so is the symmetric prior of π. The log acceptance
ratio is therefore

    F(b ← data of a) + F(a ← data of b) − F(a ← a) − F(b ← b)
    + (γ G_{0,a} − γ G_{0,b}) (log G_{e,b} − log G_{e,a}),

with F(i ← data of j) = Σ_k [ln Γ(δ φ_{i,k} + n_{e,j,k}) − ln Γ(δ φ_{i,k})] over visual and word
dimensions. Every proposal of a pass (the slots paired by a random perfect matching) is a symmetric
Metropolis–Hastings step on (C, G_e, π_e) with θ_e marginalised, followed by a draw of θ_e from
its conditional: together an exact block update of (C, G_e, π_e, θ_e), so the sampler stays a
valid MCMC for the model as written.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from scipy.special import logsumexp


@njit(cache=True, inline="always")
def _lgamma(x: float) -> float:
    # Stirling series after shifting x above 8: accurate to ~1e-12 for x > 0
    shift = 0.0
    while x < 8.0:
        shift -= math.log(x)
        x += 1.0
    inv = 1.0 / x
    inv2 = inv * inv
    return (shift + (x - 0.5) * math.log(x) - x + 0.9189385332046727
            + inv * (1.0 / 12 - inv2 * (1.0 / 360 - inv2 * (1.0 / 1260 - inv2 / 1680))))


@njit(parallel=True, cache=True)
def _dm_scores(alpha: np.ndarray, counts: np.ndarray, used: np.ndarray) -> np.ndarray:
    """F[e, i, j] = Σ_k lnΓ(α_{i,k} + n_{e,j,k}) − lnΓ(α_{i,k}) for used concepts j (else 0)."""
    n_homes, n_concepts, dim = counts.shape
    out = np.zeros((n_homes, n_concepts, n_concepts))
    lg_alpha = np.empty((n_concepts, dim))
    for i in range(n_concepts):
        for k in range(dim):
            lg_alpha[i, k] = _lgamma(alpha[i, k]) if alpha[i, k] > 0 else 0.0
    for job in prange(n_homes * n_concepts):
        e = job // n_concepts
        j = job % n_concepts
        if not used[e, j]:
            continue
        for k in range(dim):
            n = counts[e, j, k]
            if n == 0:
                continue
            for i in range(n_concepts):
                a = alpha[i, k]
                if a > 0:
                    out[e, i, j] += _lgamma(a + n) - lg_alpha[i, k]
                else:  # a concept that gives this dimension probability 0 cannot hold these data
                    out[e, i, j] += -1e300
    return out


@njit(cache=True)
def _lgamma_table(alpha: np.ndarray) -> np.ndarray:
    out = np.zeros(alpha.shape)
    for i in range(alpha.shape[0]):
        for k in range(alpha.shape[1]):
            if alpha[i, k] > 0:
                out[i, k] = _lgamma(alpha[i, k])
    return out


@njit(cache=True, inline="always")
def _dm_score(alpha: np.ndarray, lg_alpha: np.ndarray, counts: np.ndarray, e: int, prior: int,
              data: int) -> float:
    """Σ_k lnΓ(α_{prior,k} + n_{e,data,k}) − lnΓ(α_{prior,k}) over the non-zero counts."""
    total = 0.0
    for k in range(counts.shape[2]):
        n = counts[e, data, k]
        if n == 0:
            continue
        a = alpha[prior, k]
        if a > 0:
            total += _lgamma(a + n) - lg_alpha[prior, k]
        else:  # a concept that gives this dimension probability 0 cannot hold these data
            total -= 1e300
    return total


@njit(parallel=True, cache=True)
def _matching_pass(alpha_v: np.ndarray, counts_v: np.ndarray, alpha_w: np.ndarray, counts_w: np.ndarray,
                   g_term: np.ndarray, log_g: np.ndarray, pairs: np.ndarray, log_u: np.ndarray) -> np.ndarray:
    n_homes, n_concepts = log_g.shape
    lg_v = _lgamma_table(alpha_v)
    lg_w = _lgamma_table(alpha_w)
    perms = np.empty((n_homes, n_concepts), dtype=np.int64)
    for e in prange(n_homes):
        perm = np.arange(n_concepts)
        used = np.empty(n_concepts, dtype=np.bool_)
        for j in range(n_concepts):
            used[j] = counts_v[e, j].sum() > 0 or counts_w[e, j].sum() > 0
        for p in range(pairs.shape[1]):
            a = pairs[e, p, 0]
            b = pairs[e, p, 1]
            if not used[a] and not used[b]:
                continue  # swapping two empty concepts changes nothing but G_e
            delta = (g_term[a] - g_term[b]) * (log_g[e, b] - log_g[e, a])
            for data, stay, move in ((a, a, b), (b, b, a)):
                if used[data]:
                    delta += (_dm_score(alpha_v, lg_v, counts_v, e, move, data)
                              - _dm_score(alpha_v, lg_v, counts_v, e, stay, data)
                              + _dm_score(alpha_w, lg_w, counts_w, e, move, data)
                              - _dm_score(alpha_w, lg_w, counts_w, e, stay, data))
            if log_u[e, p] < delta:
                perm[a] = b
                perm[b] = a
        perms[e] = perm
    return perms


def collapsed_scores(counts: np.ndarray, log_phi: np.ndarray, delta: float) -> np.ndarray:
    """F[e, i, j]: log Dirichlet–multinomial weight (up to swap-invariant terms) of the counts of
    concept j of home e under the prior Dir(δ φ_i). Shapes: counts (E, L, D), log_phi (L, D);
    returns (E, L, L)."""
    used = counts.sum(axis=2) > 0
    alpha = delta * np.exp(log_phi)
    return _dm_scores(np.ascontiguousarray(alpha), np.ascontiguousarray(counts, dtype=np.int64), used)


def concept_swap_step(visual_counts: np.ndarray, log_phi_v: np.ndarray, delta_v: float,
                      word_counts: np.ndarray, log_phi_w: np.ndarray, delta_w: float,
                      log_g: np.ndarray, log_g0: np.ndarray, gamma: float, word_mask: np.ndarray,
                      rng: np.random.Generator) -> np.ndarray:
    """One pass of label-swap proposals in every home (θ marginalised).

    The proposals of a pass pair the home's concept slots by a uniformly random perfect matching,
    so they touch disjoint slots and are independent symmetric Metropolis–Hastings steps; each
    needs only the Dirichlet–multinomial scores of its two concepts' data under their two priors.

    Shapes: visual_counts (E, L, D) and word_counts (E, L, V) per home and concept, log_phi_v
    (L, D), log_phi_w (L, V), log_g (E, L), log_g0 (L,), word_mask (V,).

    Returns
    -------
    perms: (E, L) int; after the pass, concept slot j of home e holds what was concept perms[e, j].
    """
    n_homes, n_concepts = log_g.shape
    alpha_v = delta_v * np.exp(log_phi_v)
    if word_mask.any():
        log_phi = log_phi_w[:, word_mask]
        alpha_w = delta_w * np.exp(log_phi - logsumexp(log_phi, axis=1, keepdims=True))
        counts_w = word_counts[:, :, word_mask]
    else:
        alpha_w = np.zeros((n_concepts, 0))
        counts_w = np.zeros((n_homes, n_concepts, 0), dtype=np.int64)
    g_term = gamma * np.exp(log_g0)
    order = np.argsort(rng.random((n_homes, n_concepts)), axis=1)  # a random matching per home
    n_pairs = n_concepts // 2
    pairs = order[:, : 2 * n_pairs].reshape(n_homes, n_pairs, 2)
    log_u = np.log(rng.random((n_homes, n_pairs)))
    return _matching_pass(np.ascontiguousarray(alpha_v), np.ascontiguousarray(visual_counts, dtype=np.int64),
                          np.ascontiguousarray(alpha_w), np.ascontiguousarray(counts_w, dtype=np.int64),
                          g_term, np.ascontiguousarray(log_g), np.ascontiguousarray(pairs, dtype=np.int64),
                          log_u)
