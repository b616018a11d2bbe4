"""Word pruning (models "+MI"), a heuristic outside the posterior: the naming rule (exact sampler,
:func:`judge_names`, at the end of this module) and the mutual-information rules below.

After each sweep, word k is kept only if it is informative about some concept: with P(c) the
concept weights and P(k | c) the word distributions, the score of (k, l) is the mutual information
of the 2×2 table {word = k, word ≠ k} × {concept = l, concept ≠ l} (``"mi"``, the exact variant), or
the authors' KL(Bern(φ_{l,k}) ‖ Bern(Σ_c G_{0,c} φ_{c,k})) (``"kl"``, the reference variant). Words
whose score is below ε for every concept are removed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.special import gammainc, gammaln, logsumexp


def _xlogy_ratio(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """p log(p/q), 0 where p = 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(p > 0, p * (np.log(np.where(p > 0, p, 1.0)) - np.log(np.where(q > 0, q, 1.0))), 0.0)
    return out


def concept_word_mutual_information(word_probabilities: np.ndarray,
                                    concept_weights: np.ndarray) -> np.ndarray:
    """MI of the indicator pair (word = k, concept = l) for every concept and word.

    Parameters
    ----------
    word_probabilities: (L, V) P(k | c).
    concept_weights: (L,) P(c), summing to 1.

    Returns
    -------
    (L, V) mutual information in nats, ≥ 0.
    """
    p_c = concept_weights[:, None]
    p_kl = word_probabilities * p_c  # P(k, l)
    p_k = p_kl.sum(axis=0, keepdims=True)  # P(k)
    p_k_notl = p_k - p_kl  # P(k, ¬l)
    p_notk_l = (1.0 - word_probabilities) * p_c  # P(¬k, l)
    p_notk_notl = (1.0 - p_k) - p_notk_l  # P(¬k, ¬l)
    p_l = p_c
    p_notl = 1.0 - p_c
    p_notk = 1.0 - p_k
    mi = (_xlogy_ratio(p_kl, p_k * p_l) + _xlogy_ratio(np.clip(p_k_notl, 0, None), p_k * p_notl)
          + _xlogy_ratio(np.clip(p_notk_l, 0, None), p_notk * p_l)
          + _xlogy_ratio(np.clip(p_notk_notl, 0, None), p_notk * p_notl))
    return np.maximum(mi, 0.0)


def word_concept_mutual_information(word_probabilities: np.ndarray,
                                    concept_weights: np.ndarray) -> np.ndarray:
    """I(1[word = k]; C): MI between the indicator of word k and the whole concept variable; (V,).

    Used to weight name predictions so that words that carry no place information ("the", "is")
    are not predicted. ``word_probabilities`` (L, V) = P(k | c), ``concept_weights`` (L,) = P(c).
    """
    p_c = concept_weights[:, None]
    p_k_given_c = word_probabilities
    p_k = (p_k_given_c * p_c).sum(axis=0)
    joint_yes = p_k_given_c * p_c
    joint_no = (1.0 - p_k_given_c) * p_c
    return np.maximum((_xlogy_ratio(joint_yes, p_k[None, :] * p_c)
                       + _xlogy_ratio(np.clip(joint_no, 0, None), (1.0 - p_k)[None, :] * p_c)).sum(0), 0.0)


def bernoulli_kl_scores(word_probabilities: np.ndarray, concept_weights: np.ndarray) -> np.ndarray:
    """The authors' score KL(Bern(φ_{l,k}) ‖ Bern(Σ_c G_c φ_{c,k})) for every concept and word; (L, V)."""
    p = np.clip(word_probabilities, 0.0, 1.0)
    q = np.clip(concept_weights @ p, 0.0, 1.0)[None, :]
    return np.maximum(_xlogy_ratio(p, q) + _xlogy_ratio(1.0 - p, 1.0 - q), 0.0)


def words_to_keep(word_probabilities: np.ndarray, concept_weights: np.ndarray, threshold: float,
                  score: str = "mi") -> np.ndarray:
    """Boolean mask (V,): True for words whose score with some concept reaches ``threshold``."""
    if score == "mi":
        scores = concept_word_mutual_information(word_probabilities, concept_weights)
    elif score == "kl":
        scores = bernoulli_kl_scores(word_probabilities, concept_weights)
    else:  # pragma: no cover - validated by the caller
        raise ValueError(f"unknown pruning score {score!r}")
    return scores.max(axis=0) >= threshold


# ----------------------------------------------------------------------------- the naming rule

#: The naming rule's thresholds (``docs/model.md``, "What counts as a name"; chosen with
#: ``benchmarks/naming_rule.py``). A word is a *name* when, of the pairs of its uses said in the same
#: home that chance (the home's taught samples) would put in different regions, at least
#: NAME_MIN_EXCESS fall in the same region (:attr:`Colocation.excess`), more than chance explains
#: (Poisson upper tail below NAME_P_VALUE). It is *no name* when it stays below that excess and its
#: uses favour "said like any sentence" over "a name" by a Bayes factor of at least
#: NAME_BAYES_FACTOR (:meth:`Colocation.log_bayes_factor`: each home's uses fall in its regions as
#: a Pólya urn of excess κ, κ < NAME_MIN_EXCESS against κ ≥ NAME_MIN_EXCESS). It is *undecided*
#: otherwise (kept): a word said once per home has a Bayes factor of exactly 1, so a name taught once
#: is usable at once, while a word said at many places of a home ("we" at six places of seven uses)
#: is judged on that evidence however few pairs of its uses chance would put in one region.
NAME_MIN_EXCESS = 0.1
NAME_P_VALUE = 0.01
NAME_BAYES_FACTOR = 5.0

#: Verdicts of :func:`judge_names`.
NOT_A_NAME, UNDECIDED, NAME = 0, 1, 2

#: The grid of excess values κ on which each word's likelihood is kept: midpoints of 50 bins of
#: width 0.02 on [0, 1] (NAME_MIN_EXCESS is a bin edge), κ = 0 and 1 left out (α = ∞, 0).
EXCESS_GRID = (np.arange(50) + 0.5) / 50


@dataclass(frozen=True)
class Colocation:
    """How a word's uses said in the same home are spread over the home's regions; (V,) each, and
    the word's log-likelihood on :data:`EXCESS_GRID`, (V, G).

    pairs: Σ_e n_e(n_e − 1)/2 over the homes, n_e the taught samples of home e whose sentence holds
    the word; same: those pairs in the same region; expected: the same-region pairs expected if the
    word were said like any sentence of the home (Σ_e pairs_e · q_e, q_e the chance that two taught
    samples of home e share a region: in a home taught in its bedrooms only, "is" is said in the
    bedrooms only too, which tells nothing). log_likelihood[w, j]: log p(regions of w's uses |
    κ = EXCESS_GRID[j]) under the Pólya urn of :func:`colocation`, summed over the homes (up to a
    constant per word)."""

    pairs: np.ndarray
    same: np.ndarray
    expected: np.ndarray
    log_likelihood: np.ndarray

    def __add__(self, other: Colocation) -> Colocation:
        """The statistics of two sets of homes together (each is a sum over homes)."""
        return Colocation(self.pairs + other.pairs, self.same + other.same, self.expected + other.expected,
                          self.log_likelihood + other.log_likelihood)

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays (what a shard sends)."""
        return self.pairs.nbytes + self.same.nbytes + self.expected.nbytes + self.log_likelihood.nbytes

    @property
    def excess(self) -> np.ndarray:
        """(same − expected) / (pairs − expected): the share of the pairs that chance would put in
        different regions that the word puts in the same one (a chance-corrected agreement, like
        Cohen's κ; the moment estimate of the urn's κ): 1 for a word said at one place only, 0 for
        a word said like any sentence; NaN when chance leaves no such pair (a home taught in one
        region only)."""
        room = self.pairs - self.expected
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(room > 0, (self.same - self.expected) / np.where(room > 0, room, 1.0), np.nan)

    @property
    def lift(self) -> np.ndarray:
        """same / expected (1 for a word said everywhere alike; NaN without pairs)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.expected > 0, self.same / np.where(self.expected > 0, self.expected, 1.0),
                            np.nan)

    def log_bayes_factor(self, min_excess: float = NAME_MIN_EXCESS) -> np.ndarray:
        """log p(uses | κ ≥ min_excess) − log p(uses | κ < min_excess), (V,), κ uniform within each
        hypothesis (on :data:`EXCESS_GRID`): > 0 when the uses say "name", < 0 when they say "said
        like any sentence", exactly 0 for a word said at most once per home (nothing to tell)."""
        above = EXCESS_GRID >= min_excess
        if above.all() or not above.any():
            raise ValueError(f"min_excess must lie inside (0, 1), got {min_excess}")
        ll = self.log_likelihood
        ll = ll - ll.max(axis=1, keepdims=True) if ll.size else ll
        return (logsumexp(ll[:, above], axis=1) - np.log(above.sum())
                - logsumexp(ll[:, ~above], axis=1) + np.log((~above).sum()))


def colocation(words: sp.csr_array, homes: np.ndarray, regions: np.ndarray, n_homes: int,
               n_regions: int, grid: float | None = None) -> Colocation:
    """:class:`Colocation` of every word: ``words`` (N, V) counts (empty rows: untaught samples),
    ``homes`` (N,), ``regions`` (N,) the samples' current regions. Sparse products, no loop.

    The likelihood: in home e, with s_{e,m} its share of taught samples in region m, the uses of a
    word fall in the regions as a Pólya urn (Dirichlet-multinomial) with base s_e and concentration
    α = (1 − κ)/κ, so that a second use lands in the first one's region with probability
    κ + (1 − κ) s_{e,m}::

        log p = Σ_e [ln Γ(α) − ln Γ(α + n_e) + Σ_m (ln Γ(α s_{e,m} + n_{e,m}) − ln Γ(α s_{e,m}))]

    (n_{e,m}: the word's uses in region m of home e). Homes where the word is said once contribute
    a constant (s_{e,m}) and are left out.

    ``grid``: round every home's part of ``expected`` and ``log_likelihood`` (each (home, word)) to
    a multiple of ``grid`` before summing over homes; sums of such values are exact, so any set of
    homes gives the sum of its homes' own statistics, bit for bit (the shards' statistics then add
    up to the same whatever the grouping; :data:`spco.model.additive.SUM_GRID`)."""

    def on_grid(values: np.ndarray) -> np.ndarray:
        return values if grid is None else np.round(values / grid) * grid

    n_words = words.shape[1]
    taught = np.flatnonzero(np.diff(words.indptr) > 0)
    if taught.size == 0:
        zeros = np.zeros(n_words)
        return Colocation(zeros, zeros.copy(), zeros.copy(), np.zeros((n_words, EXCESS_GRID.size)))
    present = sp.csr_array(words[taught] > 0, dtype=np.float64)
    cell = homes[taught] * n_regions + regions[taught]
    ones = np.ones(taught.size)
    by_cell = sp.csr_array((ones, (cell, np.arange(taught.size))), shape=(n_homes * n_regions, taught.size))
    by_home = sp.csr_array((ones, (homes[taught], np.arange(taught.size))), shape=(n_homes, taught.size))
    in_cell = (by_cell @ present).tocoo()  # (E·K, V) uses per home and region
    same = np.bincount(in_cell.col, weights=in_cell.data * (in_cell.data - 1) / 2, minlength=n_words)
    in_home = (by_home @ present).tocoo()  # (E, V) uses per home
    home_pairs = in_home.data * (in_home.data - 1) / 2
    pairs = np.bincount(in_home.col, weights=home_pairs, minlength=n_words)
    cell_sizes = np.bincount(cell, minlength=n_homes * n_regions).reshape(n_homes, n_regions).astype(float)
    sizes = cell_sizes.sum(1)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(sizes > 1, (cell_sizes * (cell_sizes - 1)).sum(1) / (sizes * (sizes - 1)), 1.0)
    expected = np.bincount(in_home.col, weights=on_grid(home_pairs * q[in_home.row]), minlength=n_words)
    # the urn's likelihood on the grid of κ, from the (home, word) pairs said at least twice; each
    # term depends on the word only through its counts (and the cell's share), so it is evaluated
    # once per distinct value and summed per word with a sparse product
    alpha = (1.0 - EXCESS_GRID) / EXCESS_GRID  # (G,)
    repeated = in_home.data >= 2
    n_e = in_home.data[repeated].astype(np.int64)
    if n_e.size == 0:
        return Colocation(pairs=pairs, same=same, expected=expected,
                          log_likelihood=np.zeros((n_words, EXCESS_GRID.size)))
    uses = np.arange(n_e.max() + 1)
    per_home = gammaln(alpha)[None, :] - gammaln(alpha[None, :] + uses[:, None])  # (max n_e + 1, G)
    if grid is None:
        by_count = sp.csr_array((np.ones(n_e.size), (in_home.col[repeated], n_e)),
                                shape=(n_words, uses.size))
        log_likelihood = by_count @ per_home
    counted = sp.csr_array((np.ones(n_e.size), (in_home.row[repeated], in_home.col[repeated])),
                           shape=(n_homes, n_words))
    keep = np.asarray(counted[in_cell.row // n_regions, in_cell.col]).ravel() > 0
    in_region = cell_sizes.ravel().astype(np.int64)[in_cell.row[keep]]  # c_{e,m}
    in_home_all = sizes.astype(np.int64)[in_cell.row[keep] // n_regions]  # c_e
    count = in_cell.data[keep].astype(np.int64)  # n_{e,m}
    top = int(sizes.max()) + 1
    key = (in_region * top + in_home_all) * top + count  # one integer per (share, count)
    values, which = np.unique(key, return_inverse=True)
    share = (values // top // top) / ((values // top) % top)  # s_{e,m} = c_{e,m} / c_e
    a_s = alpha[None, :] * share[:, None]
    per_cell = gammaln(a_s + (values % top)[:, None]) - gammaln(a_s)  # (distinct (share, count), G)
    if grid is None:
        by_value = sp.csr_array((np.ones(which.size), (in_cell.col[keep], which.ravel())),
                                shape=(n_words, values.size))
        log_likelihood = log_likelihood + by_value @ per_cell
        return Colocation(pairs=pairs, same=same, expected=expected, log_likelihood=log_likelihood)
    # each (home, word) said at least twice: its count term, then its cells' terms in region order,
    # rounded to the grid; then summed over homes (exactly)
    per_pair = _per_pair_terms(in_home, in_cell, repeated, keep, per_home[n_e], per_cell[which.ravel()],
                               n_homes, n_words, n_regions)
    log_likelihood = np.zeros((n_words, EXCESS_GRID.size))
    np.add.at(log_likelihood, in_home.col[repeated], on_grid(per_pair))
    return Colocation(pairs=pairs, same=same, expected=expected, log_likelihood=log_likelihood)


def _per_pair_terms(in_home: sp.coo_array, in_cell: sp.coo_array, repeated: np.ndarray, keep: np.ndarray,
                    count_terms: np.ndarray, cell_terms: np.ndarray, n_homes: int, n_words: int,
                    n_regions: int) -> np.ndarray:
    """The urn's log-likelihood on the grid of κ of each (home, word) said at least twice, (pairs, G):
    its count term (``count_terms``), plus its cells' terms (``cell_terms``, one per kept cell)
    added in region order."""
    pair_homes, pair_words = in_home.row[repeated], in_home.col[repeated]
    pair_of = np.full(n_homes * n_words, -1, dtype=np.int64)
    pair_of[pair_homes * n_words + pair_words] = np.arange(pair_homes.size)
    per_pair = count_terms.copy()  # (pairs, G)
    cell_pairs = pair_of[(in_cell.row[keep] // n_regions) * n_words + in_cell.col[keep]]
    order = np.argsort(in_cell.row[keep], kind="stable")  # region order within each (home, word)
    np.add.at(per_pair, cell_pairs[order], cell_terms[order])
    return per_pair


def judge_names(stats: Colocation, min_excess: float = NAME_MIN_EXCESS, p_value: float = NAME_P_VALUE,
                bayes_factor: float = NAME_BAYES_FACTOR) -> np.ndarray:
    """Verdict of every word, (V,) int8: :data:`NAME` (said mostly at one place: its excess
    co-location reaches ``min_excess`` and the Poisson upper tail of its same-region pairs is below
    ``p_value``), :data:`NOT_A_NAME` (its excess stays below ``min_excess`` and its uses favour an
    urn excess κ < ``min_excess`` over κ ≥ ``min_excess`` by a Bayes factor of at least
    ``bayes_factor``: enough evidence that it is said like any sentence), or :data:`UNDECIDED` (too
    few uses to tell — a word said once per home, a name taught at one, two or three places, a home
    taught in one place only — or above the excess without significance: kept)."""
    if bayes_factor <= 1:
        raise ValueError(f"bayes_factor must be > 1, got {bayes_factor}")
    excess = np.nan_to_num(stats.excess, nan=0.0)
    tail = np.ones(stats.same.shape)
    hit = stats.same > 0
    tail[hit] = gammainc(stats.same[hit], stats.expected[hit])  # P(X >= same), X ~ Poisson(expected)
    high = excess >= min_excess
    spread = stats.log_bayes_factor(min_excess) <= -np.log(bayes_factor)
    verdict = np.full(stats.pairs.shape, UNDECIDED, dtype=np.int8)
    verdict[spread & ~high] = NOT_A_NAME
    verdict[hit & high & (tail < p_value)] = NAME
    return verdict
