"""The word channels' per-token sums (:mod:`spco.model.word_channels`): one pass over the tokens.

Each token's log Σ_c p(z = c | k) p(k | c, l) over the three channels is a log-sum-exp of three
numbers, computed here with the arithmetic of :func:`scipy.special.logsumexp` (the maximum taken
out, the others' exponentials summed, divided by the number of maxima, ``log1p``), so the results
are those of the NumPy formulation bit for bit, without its (tokens, concepts, 3) temporaries.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _log_sum_exp3(a: float, b: float, c: float) -> float:
    """log(e^a + e^b + e^c) as :func:`scipy.special.logsumexp` computes it."""
    top = max(a, max(b, c))
    n_top = 0.0
    total = 0.0
    if a == top:
        n_top += 1.0
    else:
        total += math.exp(a - top)
    if b == top:
        n_top += 1.0
    else:
        total += math.exp(b - top)
    if c == top:
        n_top += 1.0
    else:
        total += math.exp(c - top)
    if n_top == 1.0:  # (log 1 = 0 added: the same number, one log call fewer)
        return math.log1p(total) + top
    if total != 0.0:
        total = total / n_top
    return math.log1p(total) + math.log(n_top) + top


@njit(cache=True)
def _mixture_rows(indptr: np.ndarray, indices: np.ndarray, counts: np.ndarray, homes: np.ndarray,
                  log_theta_w: np.ndarray, log_place: np.ndarray, log_background: np.ndarray,
                  log_prior: np.ndarray, out: np.ndarray) -> None:
    """out[t, l] += c_ti · log Σ_c p(z = c | k) p(k | c, l) over the tokens i of every sample t (rows
    of the CSR ``indptr``/``indices``/``counts``) and every concept l: the switches marginalised.
    ``log_theta_w`` (E, L, V), ``log_place`` (E, L, V) a home's ψ_{e,l} (or (1, L, V): ψ_l for every
    home), ``log_background`` (V,), ``log_prior`` (V, 3).

    A token's term depends on its home, word and concept only, so it is computed once per (home,
    word) met in a run of samples of one home and read for the word's other tokens: the same
    numbers added in the same order as computing it per token."""
    n_concepts = out.shape[1]
    per_home = log_place.shape[0] > 1
    terms = np.empty((log_prior.shape[0], n_concepts))
    term_home = np.full(log_prior.shape[0], -1, dtype=np.int64)  # whose terms row k holds
    for t in range(indptr.size - 1):
        e = homes[t]
        for j in range(indptr[t], indptr[t + 1]):
            k = indices[j]
            if term_home[k] != e:
                pe = e if per_home else 0
                p_name, p_place = log_prior[k, 0], log_prior[k, 1]
                background = log_background[k] + log_prior[k, 2]
                for concept in range(n_concepts):
                    terms[k, concept] = _log_sum_exp3(log_theta_w[e, concept, k] + p_name,
                                                      log_place[pe, concept, k] + p_place, background)
                term_home[k] = e
            weight = counts[j]
            for concept in range(n_concepts):
                out[t, concept] += weight * terms[k, concept]


@njit(cache=True)
def _switch_rows(indptr: np.ndarray, indices: np.ndarray, homes: np.ndarray, concepts: np.ndarray,
                 log_theta_w: np.ndarray, log_place: np.ndarray, log_background: np.ndarray,
                 log_prior: np.ndarray, out: np.ndarray) -> None:
    """out[j] = p(z_j = c | C_t, w_j) of every token j (rows t of ``indptr``/``indices``), each token
    counted once: the three channels' terms normalised by their log-sum-exp. ``out`` (nnz, 3);
    ``log_place`` (E, L, V) or (1, L, V), as :func:`_mixture_rows`'s."""
    first = indptr[0]
    per_home = log_place.shape[0] > 1
    for t in range(indptr.size - 1):
        e, concept = homes[t], concepts[t]
        pe = e if per_home else 0
        for j in range(indptr[t], indptr[t + 1]):
            k = indices[j]
            a = log_theta_w[e, concept, k] + log_prior[k, 0]
            b = log_place[pe, concept, k] + log_prior[k, 1]
            c = log_background[k] + log_prior[k, 2]
            norm = _log_sum_exp3(a, b, c)
            out[j - first, 0] = math.exp(a - norm)
            out[j - first, 1] = math.exp(b - norm)
            out[j - first, 2] = math.exp(c - norm)


def mixture_rows(words, homes: np.ndarray, log_theta_w: np.ndarray, log_place: np.ndarray,
                 log_background: np.ndarray, log_prior: np.ndarray) -> np.ndarray:
    """Σ_i c_ti log Σ_c p(z = c | k) p(k | c, l) of every sample t of the CSR ``words`` (N, V) and
    every concept l of its home: (N, L). ``log_place``: ψ (L, V), or a home's ψ_{e,l} (E, L, V)."""
    out = np.zeros((words.shape[0], log_theta_w.shape[1]))
    _mixture_rows(np.asarray(words.indptr, dtype=np.int64), np.asarray(words.indices, dtype=np.int64),
                  np.asarray(words.data, dtype=np.float64), np.asarray(homes, dtype=np.int64),
                  np.ascontiguousarray(log_theta_w, dtype=np.float64),
                  _homes_place(log_place),
                  np.ascontiguousarray(log_background, dtype=np.float64),
                  np.ascontiguousarray(log_prior, dtype=np.float64), out)
    return out


def switch_rows(words, homes: np.ndarray, concepts: np.ndarray, log_theta_w: np.ndarray,
                log_place: np.ndarray, log_background: np.ndarray, log_prior: np.ndarray) -> np.ndarray:
    """p(z = c | C_t, w) of every token (stored entry) of the CSR ``words``: (nnz, 3). ``log_place``: ψ
    (L, V), or a home's ψ_{e,l} (E, L, V)."""
    out = np.empty((int(words.indptr[-1] - words.indptr[0]), 3))
    _switch_rows(np.asarray(words.indptr, dtype=np.int64), np.asarray(words.indices, dtype=np.int64),
                 np.asarray(homes, dtype=np.int64), np.asarray(concepts, dtype=np.int64),
                 np.ascontiguousarray(log_theta_w, dtype=np.float64),
                 _homes_place(log_place),
                 np.ascontiguousarray(log_background, dtype=np.float64),
                 np.ascontiguousarray(log_prior, dtype=np.float64), out)
    return out


def _homes_place(log_place: np.ndarray) -> np.ndarray:
    """ψ as the kernels read it, (E, L, V) or (1, L, V) (a shared ψ (L, V), without a copy)."""
    log_place = np.ascontiguousarray(log_place, dtype=np.float64)
    return log_place if log_place.ndim == 3 else log_place[None]
