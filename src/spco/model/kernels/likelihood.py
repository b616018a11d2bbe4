"""Counts · log θᵀ for every sample and concept of its home: the multinomial likelihoods.

Row by row (:func:`likelihood_table`, :func:`blocked_sparse_dot`, :func:`grouped_sparse_dot`) or
home by home and dimension by dimension (:func:`dimension_major`, :func:`dimension_major_dot`, the
sampler's visual likelihood; the same sums bit for bit).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from numba import get_num_threads, njit

from spco.model.kernels.dispatch import (
    _PARALLEL_MIN,
    _as,
    _call_in_parts,
    _index_array,
    _value_array,
)

#: Columns of a likelihood table are processed in blocks of this many lanes (4 AVX2 registers).
LANES = 16


@njit(cache=True, nogil=True)
def _blocked_sparse_rows(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray,
                         table: np.ndarray, width: int, out: np.ndarray, first: int, stop: int) -> None:
    """Rows first..stop−1 of :func:`blocked_sparse_dot` into ``out`` (:func:`_call_in_parts`)."""
    for t in range(first, stop):
        _blocked_sparse_row(indptr, indices, data, groups, table, width, t, out)


@njit(cache=True, inline="always")
def _blocked_sparse_row(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray,
                        table: np.ndarray, width: int, t: int, out: np.ndarray) -> None:
    # table (G, B, D, 16): sixteen independent accumulators per block of columns, each summed in
    # the order of the row's entries (the same sums as a column-by-column loop, bit for bit);
    # written out lane by lane so that LLVM's SLP vectoriser turns them into 4-wide operations
    g = groups[t]
    for b in range(table.shape[1]):
        block = table[g, b]
        a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
        a8 = a9 = a10 = a11 = a12 = a13 = a14 = a15 = 0.0
        for p in range(indptr[t], indptr[t + 1]):
            row = block[indices[p]]
            v = np.float64(data[p])
            a0 += v * row[0]
            a1 += v * row[1]
            a2 += v * row[2]
            a3 += v * row[3]
            a4 += v * row[4]
            a5 += v * row[5]
            a6 += v * row[6]
            a7 += v * row[7]
            a8 += v * row[8]
            a9 += v * row[9]
            a10 += v * row[10]
            a11 += v * row[11]
            a12 += v * row[12]
            a13 += v * row[13]
            a14 += v * row[14]
            a15 += v * row[15]
        sums = (a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12, a13, a14, a15)
        for c in range(LANES):
            if b * LANES + c < width:
                out[t, b * LANES + c] = sums[c]


@njit(cache=True, nogil=True)
def _likelihood_table_blocks(values: np.ndarray, floor: float, out: np.ndarray, first: int,
                             stop: int) -> None:
    """Blocks first..stop−1 (block i = group i // ⌈R/16⌉, rows block i % ⌈R/16⌉) of
    :func:`likelihood_table` into ``out`` (:func:`_call_in_parts`)."""
    for i in range(first, stop):
        _table_block(values, floor, out, i)


@njit(cache=True, inline="always")
def _table_block(values: np.ndarray, floor: float, out: np.ndarray, i: int) -> None:
    n_blocks = out.shape[1]
    g, b = i // n_blocks, i % n_blocks
    _fill_table_block(values, floor, g, b, out[g, b])


@njit(cache=True, inline="always")
def _fill_table_block(values: np.ndarray, floor: float, g: int, b: int, block: np.ndarray) -> None:
    # block (W, 16) ← rows 16b..16b+15 of values[g] (R, W), transposed, clipped below at the floor,
    # zero past the last row: one block of the likelihood table
    rows, width = values.shape[1], values.shape[2]
    for k in range(width):
        for lane in range(LANES):
            r = b * LANES + lane
            if r < rows:
                v = values[g, r, k]
                block[k, lane] = v if v > floor else floor
            else:
                block[k, lane] = 0.0


def likelihood_table(log_probabilities: np.ndarray, floor: float) -> np.ndarray:
    """The table :func:`blocked_sparse_dot` reads, from log-probabilities of shape (G, R, W) (log θ
    of shape (E, L, D)): entries clipped below at ``floor``, the last two axes swapped, and the R
    rows split into blocks of :data:`LANES` (zero-padded): shape (G, ⌈R/16⌉, W, 16)."""
    values = np.ascontiguousarray(log_probabilities, dtype=np.float64)
    groups, rows, width = values.shape
    n_blocks = (rows + LANES - 1) // LANES
    out = np.empty((groups, n_blocks, width, LANES))
    _call_in_parts(_likelihood_table_blocks, (values, float(floor), out), groups * n_blocks,
                   parallel=values.size >= _PARALLEL_MIN)
    return out


def blocked_sparse_dot(matrix, groups: np.ndarray, table: np.ndarray, width: int) -> np.ndarray:
    """Row t of a CSR ``matrix`` (n, D) times the table of its group, for every row: (n, ``width``).

    ``table`` comes from :func:`likelihood_table` (``width`` its number of rows R). This is the
    visual and word log-likelihood of every sample under every concept of its own home:
    counts · log θᵀ, in float64."""
    args = (_as(matrix.indptr, np.int64), _index_array(matrix.indices), _value_array(matrix.data),
            _as(groups, np.int64), np.ascontiguousarray(table, dtype=np.float64), int(width))
    out = np.empty((matrix.shape[0], int(width)))
    _call_in_parts(_blocked_sparse_rows, (*args, out), matrix.shape[0], parallel=matrix.nnz >= _PARALLEL_MIN,
                   vectorised=True)
    return out


@dataclass(frozen=True, eq=False)
class DimensionMajorCounts:
    """A CSR count matrix whose rows come in blocks (the homes: block e holds rows
    offsets[e]:offsets[e+1]) regrouped by block and then by column: the entries of column k in
    block e are ``rows``/``values``[colptr[e, k]:colptr[e, k + 1]], rows ascending and numbered
    within their block (row offsets[e] + rows[p] of the matrix). The layout of
    :func:`dimension_major_dot`; built once per fit by :func:`dimension_major`."""

    colptr: np.ndarray  # (E, D + 1) int64, positions in rows/values
    rows: np.ndarray  # (nnz,) row numbers within the block: uint16 (blocks below 65,536 rows) or int64
    values: np.ndarray  # (nnz,) the counts, float32 (exact below 2^24) or float64 as in the CSR
    offsets: np.ndarray  # (E + 1,) int64

    @property
    def n_rows(self) -> int:
        """The number of rows of the matrix."""
        return int(self.offsets[-1])

    @cached_property
    def _parts_by_count(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        return {}

    def parts(self, n_parts: int) -> tuple[np.ndarray, np.ndarray]:
        """The blocks split into ``n_parts`` parts of nearly equal non-zeros
        (:func:`_balanced_parts`), computed once per number of parts."""
        if n_parts not in self._parts_by_count:
            self._parts_by_count[n_parts] = _balanced_parts(self.colptr[:, -1] - self.colptr[:, 0], n_parts)
        return self._parts_by_count[n_parts]


@njit(cache=True)
def _dimension_major(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, offsets: np.ndarray,
                     colptr: np.ndarray, rows: np.ndarray, values: np.ndarray) -> None:
    n_blocks = offsets.size - 1
    width = colptr.shape[1] - 1
    for e in range(n_blocks):  # entries per (block, column)
        for t in range(offsets[e], offsets[e + 1]):
            for p in range(indptr[t], indptr[t + 1]):
                colptr[e, indices[p] + 1] += 1
    running = 0
    for e in range(n_blocks):  # positions: blocks one after the other, columns within each
        colptr[e, 0] = running
        for k in range(width):
            running += colptr[e, k + 1]
            colptr[e, k + 1] = running
    free = colptr[:, :width].copy()
    for e in range(n_blocks):  # rows in increasing order: ascending within every column
        for t in range(offsets[e], offsets[e + 1]):
            for p in range(indptr[t], indptr[t + 1]):
                k = indices[p]
                q = free[e, k]
                rows[q] = t - offsets[e]
                values[q] = data[p]
                free[e, k] = q + 1


def dimension_major(matrix: sp.csr_array, offsets: np.ndarray) -> DimensionMajorCounts:
    """The :class:`DimensionMajorCounts` of a CSR ``matrix`` (n, D) whose rows are in blocks
    ``offsets`` (E + 1 increasing row numbers from 0 to n). The values keep the matrix's type
    (float32 from :func:`stack_counts`); the row numbers, within each block, take two bytes when
    every block has fewer than 65,536 rows: 6 bytes per non-zero with float32 counts (14 MB for
    the 2.4 M visual non-zeros of 16 + 1 SIGVerse homes)."""
    offsets = _as(offsets, np.int64)
    n, width = matrix.shape
    if offsets.ndim != 1 or offsets.size < 1 or offsets[0] != 0 or offsets[-1] != n or np.any(
            np.diff(offsets) < 0):
        raise ValueError(f"offsets must rise from 0 to the matrix's {n} rows")
    values_in = _value_array(matrix.data)
    nnz = int(matrix.indptr[-1])
    colptr = np.zeros((offsets.size - 1, width + 1), dtype=np.int64)
    largest_block = int(np.diff(offsets).max()) if offsets.size > 1 else 0
    rows = np.empty(nnz, dtype=np.uint16 if largest_block <= np.iinfo(np.uint16).max + 1 else np.int64)
    values = np.empty(nnz, dtype=values_in.dtype)
    _dimension_major(_as(matrix.indptr, np.int64), _index_array(matrix.indices), values_in, offsets, colptr,
                     rows, values)
    return DimensionMajorCounts(colptr=colptr, rows=rows, values=values, offsets=offsets)


@njit(cache=True, nogil=True)
def _dimension_major_dot(colptr: np.ndarray, rows: np.ndarray, values: np.ndarray, offsets: np.ndarray,
                         log_p: np.ndarray, floor: float, home_order: np.ndarray, part_starts: np.ndarray,
                         out: np.ndarray, first: int, stop: int) -> None:
    # home by home, in parallel: the home's log-probabilities (R, D) are first laid out as a
    # table of sixteen lanes per column (clipped at the floor, zero-padded; what
    # likelihood_table builds for all homes, here one home at a time in the thread's cache);
    # then, for each column, its table row is read once and added, times each entry's count, to
    # that entry's row of sixteen accumulators (a home's accumulators stay in the L1 cache). Each
    # sum runs over the row's entries in column order, as in _blocked_sparse_rows: the same
    # results, bit for bit.
    # (parts first..stop-1 here: one part per thread, homes balanced by non-zeros)
    n_rows = log_p.shape[1]
    n_blocks = (n_rows + LANES - 1) // LANES
    for part in range(first, stop):
        for position in range(part_starts[part], part_starts[part + 1]):
            _dimension_major_home(colptr, rows, values, offsets, log_p, floor, home_order[position], n_blocks,
                                  out)


@njit(cache=True, inline="always")
def _dimension_major_home(colptr: np.ndarray, rows: np.ndarray, values: np.ndarray, offsets: np.ndarray,
                          log_p: np.ndarray, floor: float, e: int, n_blocks: int, out: np.ndarray) -> None:
    # one home: its table of sixteen lanes per column, then the column-by-column accumulation
    n_rows, n_columns = log_p.shape[1], log_p.shape[2]
    start = offsets[e]
    acc = np.empty((offsets[e + 1] - start, LANES))
    block = np.empty((n_columns, LANES))
    for b in range(n_blocks):
        _fill_table_block(log_p, floor, e, b, block)
        acc[:] = 0.0
        for k in range(n_columns):
            row = block[k]
            r0, r1, r2, r3 = row[0], row[1], row[2], row[3]
            r4, r5, r6, r7 = row[4], row[5], row[6], row[7]
            r8, r9, r10, r11 = row[8], row[9], row[10], row[11]
            r12, r13, r14, r15 = row[12], row[13], row[14], row[15]
            for p in range(colptr[e, k], colptr[e, k + 1]):
                o = acc[np.int64(rows[p])]
                v = np.float64(values[p])
                o[0] += v * r0
                o[1] += v * r1
                o[2] += v * r2
                o[3] += v * r3
                o[4] += v * r4
                o[5] += v * r5
                o[6] += v * r6
                o[7] += v * r7
                o[8] += v * r8
                o[9] += v * r9
                o[10] += v * r10
                o[11] += v * r11
                o[12] += v * r12
                o[13] += v * r13
                o[14] += v * r14
                o[15] += v * r15
        for t in range(acc.shape[0]):
            for c in range(LANES):
                if b * LANES + c < n_rows:
                    out[start + t, b * LANES + c] = acc[t, c]


def _balanced_parts(loads: np.ndarray, n_parts: int) -> tuple[np.ndarray, np.ndarray]:
    """Items split into ``n_parts`` parts of nearly equal total load (largest first, each to the
    least loaded part): the items in part order and the parts' start positions."""
    n_parts = max(1, min(n_parts, loads.size))
    totals = np.zeros(n_parts)
    members: list[list[int]] = [[] for _ in range(n_parts)]
    for item in np.argsort(-loads, kind="stable"):
        part = int(np.argmin(totals))
        members[part].append(int(item))
        totals[part] += loads[item]
    order = np.array([i for m in members for i in sorted(m)], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum([len(m) for m in members])]).astype(np.int64)
    return order, starts


def dimension_major_dot(counts: DimensionMajorCounts, log_probabilities: np.ndarray,
                        floor: float) -> np.ndarray:
    """Row t of the counts times the log-probabilities of its block (home), clipped below at
    ``floor``, for every row: (n, R) from ``log_probabilities`` (E, R, D) — what
    :func:`blocked_sparse_dot` computes from :func:`likelihood_table`, bit for bit, from the
    :class:`DimensionMajorCounts` layout: each home's table is built in the thread's cache and
    each of its rows read once per home instead of once per entry."""
    log_p = np.ascontiguousarray(log_probabilities, dtype=np.float64)
    n_blocks, n_columns = counts.colptr.shape[0], counts.colptr.shape[1] - 1
    if log_p.ndim != 3 or log_p.shape[0] != n_blocks or log_p.shape[2] != n_columns:
        raise ValueError(f"log-probabilities of shape {log_p.shape} do not fit counts of {n_blocks} blocks "
                         f"and {n_columns} columns")
    order, starts = counts.parts(get_num_threads())
    out = np.empty((counts.offsets[-1], log_p.shape[1]))
    args = (counts.colptr, counts.rows, counts.values, counts.offsets, log_p, float(floor), order, starts,
            out)
    _call_in_parts(_dimension_major_dot, args, starts.size - 1, parallel=True, vectorised=True)
    return out


def grouped_sparse_dot(matrix, groups: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Row t of a CSR ``matrix`` (n, D) times ``table[groups[t]]`` (D, W), for every row: (n, W).

    ``table`` has shape (G, D, W). The same kernel as :func:`blocked_sparse_dot`, which the
    sampler calls with a table it builds once per sweep."""
    table = np.asarray(table, dtype=np.float64)
    blocked = likelihood_table(np.swapaxes(table, 1, 2), -np.inf)
    return blocked_sparse_dot(matrix, groups, blocked, table.shape[2])
