"""Word pruning by mutual information (models "+MI"), a heuristic outside the posterior.

After each sweep, word k is kept only if it is informative about some concept: with P(c) the
concept weights and P(k | c) the word distributions, the score of (k, l) is the mutual information
of the 2×2 table {word = k, word ≠ k} × {concept = l, concept ≠ l} (``"mi"``, the exact variant), or
the authors' KL(Bern(φ_{l,k}) ‖ Bern(Σ_c G_{0,c} φ_{c,k})) (``"kl"``, the reference variant). Words
whose score is below ε for every concept are removed.
"""

from __future__ import annotations

import numpy as np


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
