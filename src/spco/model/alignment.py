"""Aligning the concept labels of homes learnt apart (the warm start of the hierarchical sampler).

One implementation for both starts: :func:`spco.model.gibbs.align_homes` (every home's counts in
memory) and the sharded start (:mod:`spco.model.shard_init`, each home's counts fetched from its
shard when its turn comes) call :func:`align_in_order`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linear_sum_assignment

#: Homes whose counts the sharded start fetches at a time.
ALIGNMENT_BATCH = 64


@dataclass
class HomeCounts:
    """One home's counts by concept: visual (L, D) sparse, words (L, V), and the samples standing
    for each name (L, V) (``None`` without the naming start)."""

    visual: sp.csr_array
    words: np.ndarray
    names: np.ndarray | None

    @property
    def nbytes(self) -> int:
        """Bytes sent."""
        v = self.visual
        return (v.data.nbytes + v.indices.nbytes + v.indptr.nbytes + self.words.nbytes
                + (0 if self.names is None else self.names.nbytes))


def align_in_order(fetch, word_totals: np.ndarray, names_said: np.ndarray | None, alpha_visual: float,
                   alpha_word: float, n_concepts: int, batch: int = ALIGNMENT_BATCH) -> np.ndarray:
    """Permutations (E, L) that make the homes' concept labels agree, with each home's counts
    fetched when its turn comes instead of all homes' (E, L, D) counts at once (the sharded start
    fetches them from the shards; :func:`spco.model.gibbs.align_homes` from memory).

    ``fetch(homes)`` returns the :class:`HomeCounts` of the global home indices ``homes`` (asked
    ``batch`` at a time, in alignment order); ``word_totals`` (E,) each home's word count (the
    order: most first, stable); ``names_said`` (E, V) bool, the names each home says (``None``
    without names). The pooled reference of the homes aligned so far is the only (L, D) array
    kept. Scoring: see :func:`spco.model.gibbs.align_homes`."""
    n_homes = word_totals.size
    order = np.argsort(-word_totals, kind="stable")
    perms = np.tile(np.arange(n_concepts), (n_homes, 1))
    homes_saying = None if names_said is None else names_said.sum(axis=0)
    pooled_v = pooled_w = seen = None
    for start in range(0, n_homes, batch):
        chunk = order[start:start + batch]
        for e, home in zip(chunk, fetch(chunk), strict=True):
            visual, words = home.visual.toarray(), home.words
            if pooled_v is None:
                pooled_v, pooled_w = visual.astype(float), words.astype(float)
                if home.names is not None:
                    seen = home.names.sum(axis=0) > 0
                continue
            log_pv = np.log(pooled_v + alpha_visual) - np.log((pooled_v + alpha_visual).sum(1, keepdims=True))
            score = visual @ log_pv.T  # (own concept, label)
            if words.shape[1]:
                log_pw = np.log(pooled_w + alpha_word) - np.log((pooled_w + alpha_word).sum(1, keepdims=True))
                by_words = words.sum(axis=1) > 0
                if home.names is not None:
                    own_names = home.names
                    synonyms = own_names[:, ~seen & (homes_saying > 1)].sum(axis=1)
                    by_words &= ~(synonyms > 0.5 * own_names.sum(axis=1))
                    seen |= own_names.sum(axis=0) > 0
                score[by_words] = words[by_words] @ log_pw.T
            own, label = linear_sum_assignment(score, maximize=True)
            perms[e, label] = own
            pooled_v += visual[perms[e]]
            pooled_w += words[perms[e]]
    return perms
