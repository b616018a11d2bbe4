"""Label-swap moves: Metropolis–Hastings steps that exchange two concept labels within one home.

Why: with ~7,000 visual and S^w = 5000 word counts per sample, a Gibbs sweep cannot move a whole
place from one concept to another; each home quickly settles into its own labelling, and homes
that call the kitchen "concept 3" and "concept 7" never agree, so the shared φ^w, φ^v mix places
and nothing transfers. Swapping the labels of concepts a and b inside home e — its samples' C_t,
θ^v_{e,·}, θ^w_{e,·}, G_e and π_{e,·} together — leaves the likelihood and the symmetric priors of
C and π unchanged, so the acceptance ratio involves only

    log Dir(θ_{e,b} | δ φ_a) + log Dir(θ_{e,a} | δ φ_b) − log Dir(θ_{e,a} | δ φ_a) − log Dir(θ_{e,b} | δ φ_b)
    + (γ G_{0,a} − γ G_{0,b}) (log G_{e,b} − log G_{e,a})

(visual and word terms alike). The proposal (a uniformly ordered pass over all pairs) is
symmetric and the move is a permutation (Jacobian 1), so each accepted or rejected swap is an
exact Metropolis–Hastings step: the sampler stays a valid MCMC for the model as written.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spco.model.observations import LOG_FLOOR


def _scores(log_theta: np.ndarray, log_phi: np.ndarray, delta: float) -> np.ndarray:
    """S[e, i, j] = δ Σ_k φ_{i,k} log θ_{e,j,k}: θ of concept j scored under the prior of concept i.

    The −1 of the Dirichlet exponent and the normalisers cancel in every swap ratio."""
    phi = np.exp(log_phi)  # (L, D)
    theta = np.maximum(log_theta, LOG_FLOOR)  # (E, L, D)
    return delta * np.einsum("id,ejd->eij", phi, theta)


@njit(cache=True)
def _swap_pass(scores: np.ndarray, g_term: np.ndarray, log_g: np.ndarray, pairs: np.ndarray,
               log_u: np.ndarray) -> np.ndarray:
    n_homes, n_concepts = log_g.shape
    perms = np.empty((n_homes, n_concepts), dtype=np.int64)
    for e in range(n_homes):
        # slot j currently holds the parameters of old concept perm[j]
        perm = np.arange(n_concepts)
        for p in range(pairs.shape[1]):
            a = pairs[e, p, 0]
            b = pairs[e, p, 1]
            ca = perm[a]
            cb = perm[b]
            delta = (scores[e, a, cb] + scores[e, b, ca] - scores[e, a, ca] - scores[e, b, cb]
                     + (g_term[a] - g_term[b]) * (log_g[e, cb] - log_g[e, ca]))
            if log_u[e, p] < delta:
                perm[a] = cb
                perm[b] = ca
        perms[e] = perm
    return perms


def concept_swap_step(log_theta_v: np.ndarray, log_phi_v: np.ndarray, delta_v: float,
                      log_theta_w: np.ndarray, log_phi_w: np.ndarray, delta_w: float,
                      log_g: np.ndarray, log_g0: np.ndarray, gamma: float, word_mask: np.ndarray,
                      rng: np.random.Generator) -> np.ndarray:
    """One pass of pairwise label-swap proposals in every home.

    Shapes: log_theta_v (E, L, D), log_phi_v (L, D), log_theta_w (E, L, V), log_phi_w (L, V),
    log_g (E, L), log_g0 (L,), word_mask (V,).

    Returns
    -------
    perms: (E, L) int; after the pass, concept slot j of home e holds what was concept perms[e, j].
    """
    n_homes, n_concepts = log_g.shape
    scores = _scores(log_theta_v, log_phi_v, delta_v)
    if word_mask.any():
        scores += _scores(log_theta_w[:, :, word_mask], log_phi_w[:, word_mask], delta_w)
    g_term = gamma * np.exp(log_g0)
    first, second = np.triu_indices(n_concepts, 1)
    all_pairs = np.stack([first, second], axis=1)
    order = np.argsort(rng.random((n_homes, all_pairs.shape[0])), axis=1)
    pairs = all_pairs[order]  # (E, P, 2), an independent random order per home
    log_u = np.log(rng.random((n_homes, all_pairs.shape[0])))
    return _swap_pass(scores, g_term, log_g, np.ascontiguousarray(pairs, dtype=np.int64), log_u)
