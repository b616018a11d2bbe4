"""Region block moves: all samples of one home in one region and one concept change concept together.

Why: a one-sample Gibbs step cannot move a whole room. A room's samples sit in one region k of their
home and one concept l; for any one of them, another concept l' would need π_{e,l',k} — a draw from
Dir(β/K + n_{e,l',·}), essentially 0 for a concept without samples in region k — and G_{e,l'}, both
drawn given the room's other samples in l. So `adapt` keeps a room wherever its first sweeps put it,
e.g. a washroom inside the kitchen's concept (docs/model.md, "A room's evidence").

The move. For a block B = {t in home e : R_t = k, C_t = l} of n samples, the candidates are A = {l} ∪
{l' : no sample of home e is in region k with concept l'} (a concept of the home used elsewhere, or
one it does not use). With G_e and π_e integrated out (their Dirichlet priors Dir(γ G_0), Dir(β/K)
are conjugate to the assignments) and every other variable fixed — θ^v, θ^w, the word channels, the
regions' Gaussians and the other samples' assignments — the block is drawn from its exact
conditional over A:

    p(B → l' | rest) ∝ Π_{t ∈ B} f_t(l') · Γ(g_{l'} + N_{l'} + n) / Γ(g_{l'} + N_{l'})
                                        · Γ(β + N_{l'}) / Γ(β + N_{l'} + n),

with f_t(l') the sample's concept likelihood of the one-sample conditional (its view tempered to the
view weight, Mult(v_t | θ^v_{e,l'})^{ω_t}, times its words under θ^w_{e,l'} or the word channels),
N_{l'} the home's samples in l' outside B, g = γ G_0 (the transfer model; γ/L for SpCoA), and β the
regions' concentration (π_{e,l} ~ Dir(β/K)). The factors Γ(β/K + n)/Γ(β/K) of the block's own cell
are the same for every candidate (the cell (l', k) is empty before the move and (l, k) after it) and
cancel. The region likelihoods do not change (R_t is kept).

Why it is an exact step. The block is identified by its samples, not by its label: it is the set of
samples sharing region and concept with its lowest-numbered sample, and a move among A relabels the
block without changing which samples form it or what the other blocks are (a block never joins
another, since it moves only to a concept empty in its region). So each step is a Gibbs update of
C_B within the set {B in one concept of A}, which is the same from every state it reaches: the
kernel is reversible for p(C, R | θ, data) with G_e, π_e integrated out. The sweep visits every
block once, by its lowest sample, in the order of those samples. G_e and π_e are then redrawn from
their conditionals given the new assignments — the sampler's next home step, which follows the local
step; in between only steps that integrate G_e out (the CRT tables of G_0) or do not use it run —
so the whole is a partially collapsed Gibbs step of (C, G_e, π_e), as valid as the label swaps
(:mod:`spco.model.moves`). θ is conditioned on as in the one-sample conditionals; a concept the home
does not use has θ_{e,l'} drawn from its prior Dir(δ φ_{l'}) in every home step, so it is in the
state like any other.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.special import gammaln

__all__ = ["region_block_step", "region_blocks"]


def region_blocks(homes: np.ndarray, concepts: np.ndarray, regions: np.ndarray, n_concepts: int,
                  n_regions: int) -> tuple[np.ndarray, np.ndarray]:
    """The blocks (home, region, concept) of the samples, in the order of each block's lowest sample.

    Returns ``block`` (N,): each sample's block number, and ``first`` (B,): each block's lowest
    sample (increasing)."""
    key = (homes.astype(np.int64) * n_regions + regions) * n_concepts + concepts
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return rank[inverse.ravel()], first[order]


def region_block_step(homes: np.ndarray, concepts: np.ndarray, regions: np.ndarray, concept_ll: np.ndarray,
                      concept_prior: np.ndarray, beta: float, n_homes: int, n_regions: int,
                      rng: np.random.Generator) -> np.ndarray:
    """One pass of region block moves over every home (see the module docstring); returns the new
    concepts (N,).

    Shapes: homes, concepts, regions (N,); concept_ll (N, L) the samples' concept log-likelihoods of
    the one-sample conditional (tempered views + words, as the local step computes them);
    concept_prior (L,) or (E, L) the Dirichlet concentration of G_e (γ G_0, or γ/L for SpCoA);
    ``beta``: the regions' concentration β (π ~ Dir(β/K)). Draws one uniform per block from ``rng``.
    The homes are independent given the fixed parameters and are moved together, one block of each
    per step (vectorised over homes and concepts)."""
    n_samples, n_concepts = concept_ll.shape
    if n_samples == 0:
        return concepts.copy()
    block, first = region_blocks(homes, concepts, regions, n_concepts, n_regions)
    n_blocks = first.size
    indicator = sp.csr_array((np.ones(n_samples), (block, np.arange(n_samples))), shape=(n_blocks, n_samples))
    block_ll = indicator @ concept_ll  # (B, L): Σ_{t ∈ B} f_t(l')
    block_home, block_region = homes[first], regions[first]
    block_concept = concepts[first].astype(np.int64)
    block_size = np.bincount(block, minlength=n_blocks)
    counts = np.zeros((n_homes, n_concepts), dtype=np.int64)
    np.add.at(counts, (block_home, block_concept), block_size)
    occupied = np.zeros((n_homes, n_regions, n_concepts), dtype=bool)
    occupied[block_home, block_region, block_concept] = True
    prior = np.broadcast_to(np.asarray(concept_prior, dtype=np.float64), (n_homes, n_concepts))
    position = _rank_within(block_home)  # the j-th block of each home moves at step j
    u = rng.random(n_blocks)
    columns = np.arange(n_concepts)
    for j in range(int(position.max()) + 1):
        b = np.flatnonzero(position == j)
        e, k, now, n = block_home[b], block_region[b], block_concept[b], block_size[b][:, None]
        others = counts[e] - n * (columns[None, :] == now[:, None])  # N_{l'} outside B
        g = prior[e]
        with np.errstate(divide="ignore", invalid="ignore"):
            weights = np.where(g + others > 0, gammaln(g + others + n) - gammaln(g + others), -np.inf)
        score = block_ll[b] + weights - gammaln(beta + others + n) + gammaln(beta + others)
        allowed = ~occupied[e, k]
        allowed[np.arange(b.size), now] = True
        score = np.where(allowed & ~np.isnan(score), score, -np.inf)
        top = score.max(axis=1, keepdims=True)
        finite = np.isfinite(top[:, 0])
        prob = np.exp(score - np.where(np.isfinite(top), top, 0.0))
        cumulative = np.cumsum(prob, axis=1)
        target = u[b] * cumulative[:, -1]
        new = np.minimum((cumulative <= target[:, None]).sum(axis=1), n_concepts - 1)
        new = np.where(finite & allowed[np.arange(b.size), new], new, now)
        moved = new != now
        if moved.any():
            em, km, lm, nm, newm = e[moved], k[moved], now[moved], n[moved, 0], new[moved]
            counts[em, lm] -= nm
            counts[em, newm] += nm
            occupied[em, km, lm] = False
            occupied[em, km, newm] = True
            block_concept[b[moved]] = newm
    return block_concept[block].astype(concepts.dtype, copy=False)


def _rank_within(groups: np.ndarray) -> np.ndarray:
    """Each entry's rank among the entries of its group, in array order."""
    order = np.argsort(groups, kind="stable")
    sorted_groups = groups[order]
    starts = np.flatnonzero(np.r_[True, sorted_groups[1:] != sorted_groups[:-1]])
    run_start = np.repeat(starts, np.diff(np.r_[starts, sorted_groups.size]))
    rank = np.empty(groups.size, dtype=np.int64)
    rank[order] = np.arange(groups.size) - run_start
    return rank
