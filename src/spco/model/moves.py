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
dimensions. With the views' power likelihood (``docs/samplers.md``) n^v holds the weighted counts
Σ_t s_t v_t, real numbers, and F is the same expression: ∫ Π_k θ_k^{n_k} Dir(θ | δ φ) dθ for real n.
Every proposal of a pass (the slots paired by a random perfect matching) is a symmetric
Metropolis–Hastings step on (C, G_e, π_e) with θ_e marginalised, followed by a draw of θ_e from
its conditional: together an exact block update of (C, G_e, π_e, θ_e), so the sampler stays a
valid MCMC for the model as written.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.special import logsumexp

from spco.model.kernels.dispatch import _call_in_parts
from spco.model.kernels.special import _log_minus
from spco.model.observations import shared_concentration

_HALF_LOG_2PI = 0.9189385332046727
#: Arguments at or above this are not shifted (the product of the shift would overflow near 1e38).
_NO_SHIFT = 1e30


@njit(cache=True, error_model="numpy")
def _log_gamma_values(x: np.ndarray, out: np.ndarray, work: np.ndarray) -> None:
    """out[j] ← ln Γ(x[j]) for x > 0, in vectorised passes (``work``: (3, ≥ n) scratch).

    ln Γ(x) = ln Γ(x + 8) − ln(x (x + 1) ⋯ (x + 7)), with Stirling's series at y = x + 8 ≥ 8
    (error below 1e-12 relative) and both logarithms from the vectorised log of
    :func:`spco.model.kernels.special._log_minus`: no branch and no library call per entry."""
    n = x.size
    log_y, log_p, scratch = work[0, :n], work[1, :n], work[2, :n]
    for j in range(n):
        xj = x[j]
        shifted = np.float64(xj < _NO_SHIFT)
        log_y[j] = xj + 8.0 * shifted
        p = xj * (xj + 1.0) * (xj + 2.0) * (xj + 3.0) * (xj + 4.0) * (xj + 5.0) * (xj + 6.0) * (xj + 7.0)
        log_p[j] = p * shifted + (1.0 - shifted)
    _log_minus(log_y, 0.0, scratch)
    _log_minus(log_p, 0.0, scratch)
    for j in range(n):
        y = x[j] + 8.0 * np.float64(x[j] < _NO_SHIFT)
        inv = 1.0 / y
        inv2 = inv * inv
        out[j] = ((y - 0.5) * log_y[j] - y + _HALF_LOG_2PI - log_p[j]
                  + inv * (1.0 / 12 - inv2 * (1.0 / 360 - inv2 * (1.0 / 1260 - inv2 / 1680))))
    tiny = 0
    for j in range(n):
        tiny += np.int64(x[j] < 1e-290)
    if tiny:  # the product would be subnormal: ln Γ(x) = −ln x − γ x + O(x²) there
        for j in range(n):
            if x[j] < 1e-290:
                out[j] = -np.log(x[j])


@njit(cache=True, error_model="numpy")
def _lgamma_table(alpha: np.ndarray) -> np.ndarray:
    """ln Γ(α) for every entry of a 2-D array (0 where α ≤ 0)."""
    flat = alpha.ravel()
    positive = np.empty(flat.size)  # (a loop, not np.where: its broadcasting costs ~3 s to compile)
    for j in range(flat.size):
        positive[j] = flat[j] if flat[j] > 0.0 else 1.0
    out = np.empty(flat.size)
    _log_gamma_values(positive, out, np.empty((3, flat.size)))
    for j in range(flat.size):
        if flat[j] <= 0.0:
            out[j] = 0.0
    return out.reshape(alpha.shape)


@njit(cache=True, error_model="numpy")
def _score_difference(alpha: np.ndarray, lg_alpha: np.ndarray, counts: np.ndarray, move: int, stay: int,
                      columns: np.ndarray, values: np.ndarray, work: np.ndarray) -> float:
    """F(move ← counts) − F(stay ← counts), F(i ← n) = Σ_k [ln Γ(α_{i,k} + n_k) − ln Γ(α_{i,k})] over
    the non-zero counts n_k of one concept of one home; a prior with α_{i,k} = 0 where n_k > 0
    cannot hold these data (−1e300). The non-zero columns are gathered once (without branches)
    and both sums use :func:`_log_gamma_values`. ``columns``, ``values``: scratch of size ≥ D;
    ``work``: (4, ≥ D) scratch."""
    m = 0
    for k in range(counts.size):
        columns[m] = k
        m += np.int64(counts[k] != 0)
    total = 0.0
    for side in range(2):  # (not a loop over ((move, 1.0), (stay, -1.0)): mixed tuples compile slowly)
        prior = move if side == 0 else stay
        sign = 1.0 if side == 0 else -1.0
        impossible = 0
        for j in range(m):
            k = columns[j]
            a = alpha[prior, k]
            impossible += np.int64(a <= 0.0)
            values[j] = max(a, 0.0) + counts[k]
        out = work[3, :m]
        _log_gamma_values(values[:m], out, work)
        score = 0.0
        for j in range(m):
            score += out[j] - lg_alpha[prior, columns[j]]
        if impossible:
            score = -1e300
        total += sign * score
    return total


#: The last log-gamma tables of :func:`_shared_lgamma_table`: (a copy of α, ln Γ(α)).
_LGAMMA_TABLES: list[tuple[np.ndarray, np.ndarray]] = []


def _shared_lgamma_table(alpha: np.ndarray) -> np.ndarray:
    """:func:`_lgamma_table` of ``alpha``, remembered for the same values: the homes of a shard
    propose their swaps under the same δ φ (compared with a copy: exactly the table)."""
    for values, table in _LGAMMA_TABLES:
        if values.shape == alpha.shape and np.array_equal(values, alpha):
            return table
    table = _lgamma_table(alpha)
    _LGAMMA_TABLES.insert(0, (np.array(alpha, copy=True), table))
    del _LGAMMA_TABLES[4:]
    return table


def _read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array`` (no copy): the kernels get both count arrays as the same
    Numba type, so :func:`_score_difference` is compiled once, not for read-only and writeable
    counts apart."""
    view = array.view()
    view.flags.writeable = False
    return view


def _matching_pass(alpha_v: np.ndarray, counts_v: np.ndarray, alpha_w: np.ndarray, counts_w: np.ndarray,
                   g_term: np.ndarray, log_g: np.ndarray, pairs: np.ndarray, log_u: np.ndarray) -> np.ndarray:
    """The permutation of every home after its pass of swap proposals (:func:`_matching_homes`,
    homes on Numba's thread count)."""
    n_homes, n_concepts = log_g.shape
    perms = np.empty((n_homes, n_concepts), dtype=np.int64)
    counts_v, counts_w = _read_only(counts_v), _read_only(counts_w)  # one specialisation of _score_difference
    args = (alpha_v, _shared_lgamma_table(alpha_v), counts_v, alpha_w, _shared_lgamma_table(alpha_w),
            counts_w, g_term, log_g, pairs, log_u, perms)
    _call_in_parts(_matching_homes, args, n_homes, parallel=True)
    return perms


@njit(cache=True, nogil=True)
def _matching_homes(alpha_v: np.ndarray, lg_v: np.ndarray, counts_v: np.ndarray, alpha_w: np.ndarray,
                    lg_w: np.ndarray, counts_w: np.ndarray, g_term: np.ndarray, log_g: np.ndarray,
                    pairs: np.ndarray, log_u: np.ndarray, perms: np.ndarray, first: int, stop: int) -> None:
    # homes first..stop-1 into perms; lg_v, lg_w: _lgamma_table of alpha_v, alpha_w
    n_concepts = log_g.shape[1]
    width = max(counts_v.shape[2], counts_w.shape[2], 1)
    for e in range(first, stop):
        perm = np.arange(n_concepts)
        columns = np.empty(width, dtype=np.int64)
        values = np.empty(width)
        work = np.empty((4, width))
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
                    delta += _score_difference(alpha_v, lg_v, counts_v[e, data], move, stay, columns,
                                               values, work)
                    delta += _score_difference(alpha_w, lg_w, counts_w[e, data], move, stay, columns,
                                               values, work)
            if log_u[e, p] < delta:
                perm[a] = b
                perm[b] = a
        for j in range(n_concepts):  # (element by element: an array assignment compiles its shape check)
            perms[e, j] = perm[j]


#: The last word concentrations of :func:`_word_concentration`: (log φ^w, a copy of it, of the
#: mask, δ^w, the result).
_WORD_CONCENTRATIONS: list[tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]] = []


def _word_concentration(log_phi_w: np.ndarray, word_mask: np.ndarray, delta_w: float) -> np.ndarray:
    """δ^w φ^w over the kept words, renormalised (log-sum-exp): remembered for the same φ^w and
    mask, as :func:`~spco.model.observations.shared_concentration` does for φ^v, so that the homes
    of a shard, each proposing its swaps under the same φ^w, compute it once per sweep (SciPy's
    ``logsumexp`` costs ~0.1 ms a call). A remembered value is used only for the same array
    holding the same values (compared with copies): exactly what the computation gives."""
    for source, values, mask, delta, result in _WORD_CONCENTRATIONS:
        if source is log_phi_w and delta == delta_w and values.shape == log_phi_w.shape \
                and mask.shape == word_mask.shape and np.array_equal(mask, word_mask) \
                and np.array_equal(values, log_phi_w):
            return result
    log_phi = log_phi_w[:, word_mask]
    result = delta_w * np.exp(log_phi - logsumexp(log_phi, axis=1, keepdims=True))
    _WORD_CONCENTRATIONS.insert(0, (log_phi_w, np.array(log_phi_w, copy=True), np.array(word_mask, copy=True),
                                    float(delta_w), result))
    del _WORD_CONCENTRATIONS[4:]
    return result


def _count_type(counts: np.ndarray) -> type:
    """int64 for whole counts (the cut sampler's, compiled ahead), float64 for the power target's
    weighted visual counts."""
    return np.int64 if np.asarray(counts).dtype.kind in "iub" else np.float64


def concept_swap_step(visual_counts: np.ndarray, log_phi_v: np.ndarray, delta_v: float,
                      word_counts: np.ndarray, log_phi_w: np.ndarray, delta_w: float,
                      log_g: np.ndarray, log_g0: np.ndarray, gamma: float, word_mask: np.ndarray,
                      rng: np.random.Generator,
                      place: tuple[np.ndarray, np.ndarray] | None = None,
                      place_home: tuple[np.ndarray, np.ndarray, float] | None = None) -> np.ndarray:
    """One pass of label-swap proposals in every home (θ marginalised).

    The proposals of a pass pair the home's concept slots by a uniformly random perfect matching,
    so they touch disjoint slots and are independent symmetric Metropolis–Hastings steps; each
    needs only the Dirichlet–multinomial scores of its two concepts' data under their two priors.

    Shapes: visual_counts (E, L, D) and word_counts (E, L, V) per home and concept, log_phi_v
    (L, D), log_phi_w (L, V), log_g (E, L), log_g0 (L,), word_mask (V,).

    ``place`` (optional, word channels): the place tokens per home, concept and word with their
    counts (E, L, V) and log ψ (L, V) (:mod:`spco.model.word_channels`). ψ is shared and held fixed, so
    swapping concepts a and b of home e adds Σ_k (P_{e,a,k} − P_{e,b,k})(log ψ_{b,k} − log ψ_{a,k}) to
    the log acceptance ratio (subtracted from log u here: each pair's test is log u < ratio).
    ``place_home`` (the place channel's home level, instead of ``place``): the home's place tokens
    (E, L, V) in ψ's units, log ψ_l (L, V) and δ^p; ψ_{e,l} integrated out
    (:func:`spco.model.home_place.swap_place_terms`).

    Returns
    -------
    perms: (E, L) int; after the pass, concept slot j of home e holds what was concept perms[e, j].
    """
    n_homes, n_concepts = log_g.shape
    alpha_v = shared_concentration(log_phi_v, delta_v)
    if word_mask.any():
        alpha_w = _word_concentration(log_phi_w, word_mask, delta_w)
        counts_w = word_counts[:, :, word_mask]
    else:
        alpha_w = np.zeros((n_concepts, 0))
        counts_w = np.zeros((n_homes, n_concepts, 0), dtype=np.int64)
    g_term = gamma * np.exp(log_g0)
    order = np.argsort(rng.random((n_homes, n_concepts)), axis=1)  # a random matching per home
    n_pairs = n_concepts // 2
    pairs = order[:, : 2 * n_pairs].reshape(n_homes, n_pairs, 2)
    log_u = np.log(rng.random((n_homes, n_pairs)))
    if place is not None and n_pairs:
        counts_p, log_psi = place
        a_, b_ = pairs[..., 0], pairs[..., 1]  # (E, P)
        homes = np.arange(n_homes)[:, None]
        diff_counts = counts_p[homes, a_] - counts_p[homes, b_]  # (E, P, V)
        diff_log = log_psi[b_] - log_psi[a_]  # (E, P, V)
        log_u = log_u - np.einsum("epv,epv->ep", diff_counts, diff_log)
    if place_home is not None and n_pairs:
        from spco.model.home_place import swap_place_terms

        log_u = log_u - swap_place_terms(place_home[0], place_home[1], place_home[2], pairs)
    return _matching_pass(np.ascontiguousarray(alpha_v),
                          np.ascontiguousarray(visual_counts, dtype=_count_type(visual_counts)),
                          np.ascontiguousarray(alpha_w), np.ascontiguousarray(counts_w, dtype=np.int64),
                          g_term, np.ascontiguousarray(log_g), np.ascontiguousarray(pairs, dtype=np.int64),
                          log_u)
