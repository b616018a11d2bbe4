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
from scipy.special import gammainc


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
#: (Poisson upper tail below NAME_P_VALUE). It is *no name* when it stays below that with enough pairs
#: to tell — at least NAME_MIN_EVIDENCE same-region pairs expected by chance and as many pairs chance
#: would split — and *undecided* otherwise (kept: a name taught once must be usable, and a name with a
#: high excess on few pairs is not refused on thin evidence).
NAME_MIN_EXCESS = 0.1
NAME_P_VALUE = 0.01
NAME_MIN_EVIDENCE = 1.0

#: Verdicts of :func:`judge_names`.
NOT_A_NAME, UNDECIDED, NAME = 0, 1, 2


@dataclass(frozen=True)
class Colocation:
    """How often pairs of a word's uses, said in the same home, fall in the same region; (V,) each.

    pairs: Σ_e n_e(n_e − 1)/2 over the homes, n_e the taught samples of home e whose sentence holds
    the word; same: those pairs in the same region; expected: the same-region pairs expected if the
    word were said like any sentence of the home (Σ_e pairs_e · q_e, q_e the chance that two taught
    samples of home e share a region: in a home taught in its bedrooms only, "is" is said in the
    bedrooms only too, which tells nothing)."""

    pairs: np.ndarray
    same: np.ndarray
    expected: np.ndarray

    def __add__(self, other: Colocation) -> Colocation:
        """The statistics of two sets of homes together (each count is a sum over homes)."""
        return Colocation(self.pairs + other.pairs, self.same + other.same, self.expected + other.expected)

    @property
    def nbytes(self) -> int:
        """Bytes of the three arrays (what a shard sends)."""
        return self.pairs.nbytes + self.same.nbytes + self.expected.nbytes

    @property
    def excess(self) -> np.ndarray:
        """(same − expected) / (pairs − expected): the share of the pairs that chance would put in
        different regions that the word puts in the same one (a chance-corrected agreement, like
        Cohen's κ): 1 for a word said at one place only, 0 for a word said like any sentence; NaN
        when chance leaves no such pair (a home taught in one region only)."""
        room = self.pairs - self.expected
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(room > 0, (self.same - self.expected) / np.where(room > 0, room, 1.0), np.nan)

    @property
    def lift(self) -> np.ndarray:
        """same / expected (1 for a word said everywhere alike; NaN without pairs)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.expected > 0, self.same / np.where(self.expected > 0, self.expected, 1.0),
                            np.nan)


def colocation(words: sp.csr_array, homes: np.ndarray, regions: np.ndarray, n_homes: int,
               n_regions: int) -> Colocation:
    """:class:`Colocation` of every word: ``words`` (N, V) counts (empty rows: untaught samples),
    ``homes`` (N,), ``regions`` (N,) the samples' current regions. Two sparse products, no loop."""
    n_words = words.shape[1]
    taught = np.flatnonzero(np.diff(words.indptr) > 0)
    if taught.size == 0:
        zeros = np.zeros(n_words)
        return Colocation(zeros, zeros.copy(), zeros.copy())
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
    expected = np.bincount(in_home.col, weights=home_pairs * q[in_home.row], minlength=n_words)
    return Colocation(pairs=pairs, same=same, expected=expected)


def judge_names(stats: Colocation, min_excess: float = NAME_MIN_EXCESS, p_value: float = NAME_P_VALUE,
                min_evidence: float = NAME_MIN_EVIDENCE) -> np.ndarray:
    """Verdict of every word, (V,) int8: :data:`NAME` (said mostly at one place: its excess
    co-location reaches ``min_excess`` and the Poisson upper tail of its same-region pairs is below
    ``p_value``), :data:`NOT_A_NAME` (below ``min_excess`` with at least ``min_evidence`` same-region
    pairs expected by chance and as many split by chance: enough evidence that it is said like any
    sentence), or :data:`UNDECIDED` (too few uses to tell — a word said once or twice per home, or a
    home taught in one place only — or above the excess without significance: kept)."""
    excess = stats.excess
    tail = np.ones(stats.same.shape)
    hit = stats.same > 0
    tail[hit] = gammainc(stats.same[hit], stats.expected[hit])  # P(X >= same), X ~ Poisson(expected)
    high = np.nan_to_num(excess, nan=0.0) >= min_excess
    evidence = (stats.expected >= min_evidence) & (stats.pairs - stats.expected >= min_evidence)
    verdict = np.full(stats.pairs.shape, UNDECIDED, dtype=np.int8)
    verdict[evidence & ~high] = NOT_A_NAME
    verdict[hit & high & (tail < p_value)] = NAME
    return verdict
