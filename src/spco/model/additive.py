"""Statistics that add up over homes: a shard's sums are the sum of its homes', the fit's the sum of
its shards', exactly: integer counts, and floats rounded to :data:`SUM_GRID` first."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Self

import numpy as np
import scipy.sparse as sp

__all__ = ["SUM_GRID", "AdditiveCounts", "PooledCounts", "on_sum_grid"]

#: Float statistics a home sends to be summed over homes (the naming rule's expected pairs and
#: log-likelihoods, the synonyms' overlaps) are rounded to multiples of this grid first: sums of
#: such values are exact, hence the same whatever the order and grouping of the homes, as long as
#: every partial sum stays below 2^33 in magnitude (8.6·10^9; a home contributes tens to thousands).
SUM_GRID = 2.0 ** -20


def on_sum_grid(values):
    """``values`` (an array, or a sparse matrix) rounded to multiples of :data:`SUM_GRID`."""
    if sp.issparse(values):
        out = sp.csr_array(values, dtype=np.float64, copy=True)
        out.data = np.round(out.data / SUM_GRID) * SUM_GRID
        return out
    return np.round(np.asarray(values, dtype=np.float64) / SUM_GRID) * SUM_GRID


@dataclass
class AdditiveCounts:
    """A dataclass of count arrays that add field by field: ``a + b`` is a new one of the same class
    whose every array is the sum of ``a``'s and ``b``'s (each a token or sample counted once)."""

    def __add__(self, other: Self) -> Self:
        if type(other) is not type(self):
            return NotImplemented
        return type(self)(*(getattr(self, f.name) + getattr(other, f.name) for f in fields(self)))

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays."""
        return sum(getattr(self, f.name).nbytes for f in fields(self))


@dataclass
class PooledCounts(AdditiveCounts):
    """The authors' sampler's statistics of a shard, summed over its homes: visual (L, D) and word
    (L, V) counts per concept, concept counts (L,)."""

    visual: np.ndarray
    words: np.ndarray
    concepts: np.ndarray
