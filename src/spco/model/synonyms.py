"""Synonyms: names that one home says at the same place start as one concept.

People call one place by several names ("bath", "bathroom", "shower"; "front door" and
"entrance"), often in the same home (two people, or one person's moods). The sampler's start
(:func:`spco.model.gibbs.concepts_by_name`) gives every place name of a home a concept of its own,
which is right for two rooms with two names (Emma's and mother's bedrooms) but splits one place
into one concept per synonym. The split then lasts — a sample said "bath" keeps to the concept
whose θ^w gives "bath" the most, with S^w = 5000 counts per word — and the homes' labels are
aligned per name, so the bath becomes three concepts across all homes. A new home's bath views go
to one of them, and ``where`` for the synonyms the others carry lands anywhere (measured on the
free-form synthetic homes: "bath" in concept 8 in 14 homes, "bathroom" in concept 7 in 14 homes,
"bathtub" in concept 14 in 12 homes; a new home's bath in concept 7 only).

The rule (:func:`same_place_names`): the overlap of two names in one home is
o_e(a, b) = Σ_m min(p_a(m), p_b(m)), p_a the distribution over the home's regions of the samples
that stand for name a (1: said at the same spots, 0: apart). It is pooled over the homes that say
both, weighted by the fewer uses of the two (:func:`pooled_overlaps`): the start's regions are
k-means clusters, a room spans two or three of them, a name said once overlaps its synonym by
chance, and an open-plan kitchen-diner puts two places in one region; pooled, a pair is judged on
every home that says both. Two names said in one home whose pooled overlap exceeds ``min_overlap``
are one place there; names linked so (transitively) are one group, which starts as one concept.
Words said at the same spots of the homes are names of the same place; names of different rooms
are said in different regions and stay apart. No list of synonyms is used; a name said in one home
only (Emma's room) is judged on that home; homes may group their names differently, and the labels
are then aligned by their words.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

__all__ = ["MIN_OVERLAP", "NameOverlaps", "name_overlaps", "name_region_overlaps", "pooled_overlaps",
           "same_place_names"]

#: Pooled region overlap above which two names are one place (see :func:`same_place_names`; chosen
#: by ``benchmarks/synonyms.py``, docs/model.md "Synonyms").
MIN_OVERLAP = 0.4


def _home_region_profiles(names: np.ndarray, regions: np.ndarray, rows: np.ndarray,
                          n_regions: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The names said in one home (``rows``), their sample counts and their region distributions:
    (n,) names, (n,) counts, (n, K) rows summing to 1."""
    named = rows[names[rows] >= 0]
    used, column = np.unique(names[named], return_inverse=True)
    counts = sp.csr_array((np.ones(named.size), (column, regions[named])),
                          shape=(used.size, n_regions)).toarray()
    totals = counts.sum(axis=1)
    return used, totals, counts / np.maximum(totals, 1.0)[:, None]


def name_region_overlaps(names: np.ndarray, regions: np.ndarray, offsets: np.ndarray,
                         n_regions: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per home (rows offsets[e]:offsets[e+1]): (n,) names said there, (n,) samples standing for
    each, and the (n, n) overlaps Σ_m min(p_a(m), p_b(m)) of their region distributions (1 on the
    diagonal)."""
    out = []
    for e in range(offsets.size - 1):  # a loop over homes; each step is vectorised
        rows = np.arange(offsets[e], offsets[e + 1])
        used, totals, profile = _home_region_profiles(names, regions, rows, n_regions)
        overlap = np.minimum(profile[:, None, :], profile[None, :, :]).sum(axis=2)
        out.append((used, totals, overlap))
    return out


@dataclass(frozen=True)
class NameOverlaps:
    """The sums behind :func:`pooled_overlaps`, which add up over sets of homes (shards):
    ``weighted`` Σ_e min(n_ea, n_eb) o_e(a, b) and ``weights`` Σ_e min(n_ea, n_eb), (V, V) sparse,
    one entry per pair a < b said together in some home."""

    weighted: sp.csr_array
    weights: sp.csr_array

    def __add__(self, other: NameOverlaps) -> NameOverlaps:
        """The sums of two sets of homes together."""
        return NameOverlaps(self.weighted + other.weighted, self.weights + other.weights)

    @property
    def nbytes(self) -> int:
        """Bytes of the two sparse matrices (what a shard sends)."""
        return sum(m.data.nbytes + m.indices.nbytes + m.indptr.nbytes for m in (self.weighted, self.weights))

    def pooled(self) -> sp.csr_array:
        """(V, V) symmetric pooled overlaps Σ_e min(n_ea, n_eb) o_e(a, b) / Σ_e min(n_ea, n_eb)."""
        weights = sp.csr_array(self.weights, copy=True)  # (arrays from Ray's object store are read-only)
        weights.sum_duplicates()
        weights.eliminate_zeros()  # a pair said together has weight ≥ 1 (its rarer name's uses)
        # a pair of overlap 0 may be stored or not in ``weighted`` (sums drop zeros): 0 either way
        pooled = sp.csr_array(self.weighted, copy=True).multiply(weights.power(-1.0))
        return sp.csr_array(pooled + pooled.T)


def name_overlaps(per_home: list[tuple[np.ndarray, np.ndarray, np.ndarray]], n_words: int) -> NameOverlaps:
    """:class:`NameOverlaps` of the homes of ``per_home`` (from :func:`name_region_overlaps`)."""
    rows, cols, weighted, weights = [], [], [], []
    for used, totals, overlap in per_home:  # a loop over homes; each step is vectorised
        a, b = np.triu_indices(used.size, k=1)
        w = np.minimum(totals[a], totals[b])
        rows.append(used[a])
        cols.append(used[b])
        weighted.append(w * overlap[a, b])
        weights.append(w)
    shape = (n_words, n_words)
    if not rows or not sum(r.size for r in rows):
        return NameOverlaps(sp.csr_array(shape), sp.csr_array(shape))
    r, c = np.concatenate(rows), np.concatenate(cols)
    return NameOverlaps(sp.csr_array((np.concatenate(weighted), (r, c)), shape=shape),
                        sp.csr_array((np.concatenate(weights), (r, c)), shape=shape))


def pooled_overlaps(per_home: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                    n_words: int) -> sp.csr_array:
    """(V, V) the overlap of every pair of names pooled over the homes that say both, weighted by
    the fewer uses of the two in each home: Σ_e min(n_ea, n_eb) o_e(a, b) / Σ_e min(n_ea, n_eb)
    (``per_home`` from :func:`name_region_overlaps`; pairs said in no home together are absent)."""
    return name_overlaps(per_home, n_words).pooled()


def same_place_names(names: np.ndarray, regions: np.ndarray, offsets: np.ndarray, n_regions: int,
                     n_words: int, min_overlap: float = MIN_OVERLAP,
                     overlaps: NameOverlaps | None = None) -> np.ndarray:
    """Each sample's name replaced by the name of its home's group of names said at one place.

    Parameters
    ----------
    names: (N,) vocabulary column of the name each sample stands for, −1 for none
        (:func:`spco.model.gibbs.sample_names`).
    regions: (N,) region of each sample; offsets: (E+1,), home e holds rows offsets[e]:offsets[e+1]
        (the sampler's :class:`~spco.model.gibbs.PreparedData` layout); n_regions K; n_words V.
    min_overlap: two names said in one home are one place there when their region overlap pooled
        over the homes that say both (:func:`pooled_overlaps`) exceeds this; groups are the
        connected components of that relation among the home's names.
    overlaps: the sums pooled over every home of the fit (:func:`name_overlaps`, added up over
        the shards) when these are only some of them; default: pooled over these homes.

    Returns (N,) int64: the group's most said name in that home (ties: the lowest column), −1
    where ``names`` is −1. A name alone in its group is kept as it is.
    """
    names = np.asarray(names, dtype=np.int64)
    out = names.copy()
    per_home = name_region_overlaps(names, regions, offsets, n_regions)
    if overlaps is None:
        overlaps = name_overlaps(per_home, n_words)
    same_place = overlaps.pooled() > min_overlap  # (V, V) sparse bool
    for e, (used, totals, _) in enumerate(per_home):
        if used.size < 2:
            continue
        linked = same_place[used][:, used]
        n_groups, group = connected_components(linked, directed=False)
        if n_groups == used.size:
            continue
        # representative of each group: its most said name, the lowest column among ties
        order = np.lexsort((used, -totals))  # last key first: most said first, then lowest column
        representative = np.empty(n_groups, dtype=np.int64)
        representative[group[order[::-1]]] = used[order[::-1]]  # the first in `order` writes last
        rows = np.arange(offsets[e], offsets[e + 1])
        rows = rows[names[rows] >= 0]
        out[rows] = representative[group[np.searchsorted(used, names[rows])]]
    return out
