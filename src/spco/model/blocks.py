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

import math

import numpy as np
from numba import njit

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
    ``beta``: the regions' concentration β (π ~ Dir(β/K)). Draws one uniform per block from ``rng``
    (the blocks in the order of their lowest samples; the homes' blocks are independent given the
    fixed parameters, so one loop over all blocks in that order is each home's scan)."""
    n_samples, n_concepts = concept_ll.shape
    if n_samples == 0:
        return concepts.copy()
    block, first = region_blocks(homes, concepts, regions, n_concepts, n_regions)
    prior = np.ascontiguousarray(np.broadcast_to(np.asarray(concept_prior, dtype=np.float64),
                                                 (n_homes, n_concepts)))
    u = rng.random(first.size)
    block_concept = _block_pass(np.ascontiguousarray(concept_ll, dtype=np.float64), block.astype(np.int64),
                                first.astype(np.int64), homes.astype(np.int64), regions.astype(np.int64),
                                concepts.astype(np.int64), prior, float(beta), n_homes, n_regions, u)
    return block_concept[block].astype(concepts.dtype, copy=False)


@njit(cache=True, error_model="numpy")
def _block_pass(concept_ll: np.ndarray, block: np.ndarray, first: np.ndarray, homes: np.ndarray,
                regions: np.ndarray, concepts: np.ndarray, prior: np.ndarray, beta: float, n_homes: int,
                n_regions: int, u: np.ndarray) -> np.ndarray:
    """The blocks' new concepts (B,): each block in turn drawn from its conditional (module
    docstring), with the home's concept counts and the region's occupied concepts updated after
    each move."""
    n_samples, n_concepts = concept_ll.shape
    n_blocks = first.size
    block_ll = np.zeros((n_blocks, n_concepts))
    size = np.zeros(n_blocks, dtype=np.int64)
    for t in range(n_samples):
        b = block[t]
        size[b] += 1
        for c in range(n_concepts):
            block_ll[b, c] += concept_ll[t, c]
    counts = np.zeros((n_homes, n_concepts), dtype=np.int64)
    occupied = np.zeros((n_homes, n_regions, n_concepts), dtype=np.bool_)
    block_concept = np.empty(n_blocks, dtype=np.int64)
    for b in range(n_blocks):
        t = first[b]
        block_concept[b] = concepts[t]
        counts[homes[t], concepts[t]] += size[b]
        occupied[homes[t], regions[t], concepts[t]] = True
    score = np.empty(n_concepts)
    for b in range(n_blocks):
        t = first[b]
        e, k, now, n = homes[t], regions[t], block_concept[b], size[b]
        top = -np.inf
        for c in range(n_concepts):
            others = counts[e, c] - (n if c == now else 0)  # N_{l'} outside the block
            g = prior[e, c]
            if (c != now and occupied[e, k, c]) or not g + others > 0.0:
                score[c] = -np.inf
                continue
            value = (block_ll[b, c] + math.lgamma(g + others + n) - math.lgamma(g + others)
                     - math.lgamma(beta + others + n) + math.lgamma(beta + others))
            if not value > -np.inf:  # NaN or −inf: not a candidate
                value = -np.inf
            score[c] = value
            if value > top:
                top = value
        if not top > -np.inf or top == np.inf:
            continue
        total = 0.0
        for c in range(n_concepts):
            score[c] = math.exp(score[c] - top) if score[c] > -np.inf else 0.0
            total += score[c]
        target = u[b] * total
        new = now
        cumulative = 0.0
        for c in range(n_concepts):
            if score[c] > 0.0:
                new = c  # (the last candidate if rounding leaves the target above the sum)
                cumulative += score[c]
                if cumulative > target:
                    break
        if new != now:
            counts[e, now] -= n
            counts[e, new] += n
            occupied[e, k, now] = False
            occupied[e, k, new] = True
            block_concept[b] = new
    return block_concept
