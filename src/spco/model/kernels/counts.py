"""Statistics of sparse counts: stacking rows, per-group moments, per-group row sums and moving
rows between groups (the sampler's incremental visual counts).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit

from spco.model.kernels.dispatch import _PARALLEL_MIN, _as, _call_in_parts, _index_array, _value_array

#: Counts up to this value are exact in float32 (2^24), the value type of :func:`stack_counts`.
FLOAT32_EXACT = 2**24


def stack_counts(*blocks) -> sp.csr_array:
    """The row blocks ``blocks`` (sparse or dense counts with equal numbers of columns) stacked
    into one CSR array in the compact layout of the compiled kernels: float32 values (whole
    numbers below 2^24, exact in float32; larger counts keep float64), int32 column indices,
    int64 row pointers. The kernels multiply in float64, so the layout changes no result; it
    halves the memory of the visual counts of a fit (2.4 M non-zeros for 16 + 1 SIGVerse homes).

    Each output array is allocated once at its final size and filled block by block: no stacked
    intermediate, no second converted copy. The result shares no memory with the blocks, which are
    not modified.
    """
    blocks_csr = [b if isinstance(b, sp.csr_array) else sp.csr_array(b) for b in blocks]
    n_columns = blocks_csr[0].shape[1]
    if any(b.shape[1] != n_columns for b in blocks_csr):
        raise ValueError("the blocks of counts have different numbers of columns")
    n_rows = sum(b.shape[0] for b in blocks_csr)
    nnz = sum(int(b.indptr[-1]) for b in blocks_csr)
    largest = max((float(np.abs(b.data).max()) for b in blocks_csr if b.nnz), default=0.0)
    data = np.empty(nnz, dtype=np.float32 if largest < FLOAT32_EXACT else np.float64)
    indices = np.empty(nnz, dtype=np.int32 if n_columns < 2**31 else np.int64)
    indptr = np.empty(n_rows + 1, dtype=np.int64)
    indptr[0] = row = start = 0
    for b in blocks_csr:
        n, stop = b.shape[0], start + int(b.indptr[-1])
        data[start:stop] = b.data[: stop - start]
        indices[start:stop] = b.indices[: stop - start]
        np.add(b.indptr[1:], start, out=indptr[row + 1: row + 1 + n])
        row, start = row + n, stop
    out = sp.csr_array((n_rows, n_columns), dtype=data.dtype)  # empty; its arrays are replaced (the
    out.data, out.indices, out.indptr = data, indices, indptr  # constructor would choose the types)
    return out


def csr_rows(matrix: sp.csr_array, first: int, stop: int) -> sp.csr_array:
    """Rows first..stop − 1 of a CSR array in its own index and value types, its values and column
    indices views of ``matrix``'s (no copy: the sampler never writes its counts; the row pointers
    are new). Slicing with SciPy copies and turns int32 column indices into int64 (twice their
    memory, and another compiled specialisation of every kernel that takes them)."""
    begin, end = int(matrix.indptr[first]), int(matrix.indptr[stop])
    out = sp.csr_array((stop - first, matrix.shape[1]), dtype=matrix.dtype)  # its arrays replaced below
    out.data = matrix.data[begin:end]
    out.indices = matrix.indices[begin:end]
    out.indptr = matrix.indptr[first:stop + 1] - begin
    return out


@njit(cache=True)
def _grouped_moments(x: np.ndarray, groups: np.ndarray, count: np.ndarray, total: np.ndarray,
                     scatter: np.ndarray) -> None:
    for t in range(x.shape[0]):
        g = groups[t]
        count[g] += 1.0
        for i in range(x.shape[1]):
            total[g, i] += x[t, i]
            for j in range(x.shape[1]):
                scatter[g, i, j] += x[t, i] * x[t, j]


def grouped_moments(x: np.ndarray, groups: np.ndarray,
                    n_groups: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Count, Σ x and Σ x xᵀ of the rows of ``x`` (n, d) in each group (``groups`` (n,) in
    0..n_groups−1): shapes (G,), (G, d), (G, d, d); summed in row order, one pass."""
    x = _as(x, np.float64)
    count = np.zeros(n_groups)
    total = np.zeros((n_groups, x.shape[1]))
    scatter = np.zeros((n_groups, x.shape[1], x.shape[1]))
    _grouped_moments(x, _as(groups, np.int64), count, total, scatter)
    return count, total, scatter


@njit(cache=True, nogil=True)
def _grouped_row_sums(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray,
                      chunks: np.ndarray, out: np.ndarray, first: int, stop: int) -> None:
    """Rows chunks[first]:chunks[stop] added into ``out`` by group. Rows chunks[i]:chunks[i+1] write
    to groups no other chunk writes to, so parts of the chunks run at once (:func:`_call_in_parts`)."""
    _add_rows(indptr, indices, data, groups, chunks[first], chunks[stop], out)


@njit(cache=True, inline="always")
def _add_rows(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, groups: np.ndarray, first: int,
              stop: int, out: np.ndarray) -> None:
    for t in range(first, stop):
        g = groups[t]
        for p in range(indptr[t], indptr[t + 1]):
            out[g, indices[p]] += np.int64(data[p])


def grouped_row_sums(matrix, groups: np.ndarray, n_groups: int,
                     blocks: np.ndarray | None = None) -> np.ndarray:
    """Sum of the rows of a CSR ``matrix`` (n, D) within each group: returns (n_groups, D) int64.

    Used for the count statistics n^v_{e,l,·} and n^w_{e,l,·} (group = e·L + l). ``blocks``
    (optional, (n,) non-decreasing) splits the rows into runs such that no two runs share a group
    (e.g. the home of each row, rows sorted by home); the runs are summed in parallel.
    """
    out = np.zeros((n_groups, matrix.shape[1]), dtype=np.int64)
    n = matrix.shape[0]
    parallel = matrix.nnz >= _PARALLEL_MIN
    if parallel and blocks is not None and n > 1 and np.all(blocks[1:] >= blocks[:-1]):
        chunks = np.concatenate([[0], np.flatnonzero(blocks[1:] != blocks[:-1]) + 1, [n]]).astype(np.int64)
    else:
        chunks = np.array([0, n], dtype=np.int64)
    args = (_as(matrix.indptr, np.int64), _index_array(matrix.indices), _value_array(matrix.data),
            _as(groups, np.int64), chunks, out)
    _call_in_parts(_grouped_row_sums, args, chunks.size - 1, parallel=parallel)
    return out


@njit(cache=True)
def _grouped_weighted_row_sums(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, weights: np.ndarray,
                               groups: np.ndarray, out: np.ndarray) -> None:
    for t in range(indptr.size - 1):
        g = groups[t]
        w = weights[t]
        for p in range(indptr[t], indptr[t + 1]):
            out[g, indices[p]] += w * np.float64(data[p])


def grouped_weighted_row_sums(matrix, weights: np.ndarray, groups: np.ndarray, n_groups: int) -> np.ndarray:
    """Σ_t weights[t] · row t of a CSR ``matrix`` (n, D) within each group (``groups`` (n,) in
    0..n_groups−1): (n_groups, D) float64, each entry summed in row order (the order of SciPy's
    product of a one-hot weight matrix with ``matrix``, so the same numbers), one pass, one thread."""
    out = np.zeros((n_groups, matrix.shape[1]))
    _grouped_weighted_row_sums(_as(matrix.indptr, np.int64), _index_array(matrix.indices),
                               _value_array(matrix.data), _as(weights, np.float64), _as(groups, np.int64),
                               out)
    return out


@njit(cache=True)
def move_rows(n: np.ndarray, indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, rows: np.ndarray,
              homes: np.ndarray, old: np.ndarray, new: np.ndarray) -> None:
    """n[homes[i], old[i], :] −= row rows[i] of a CSR matrix and n[homes[i], new[i], :] += it, for
    every i (integer counts, exact). ``n`` has shape (E, L, D), int64."""
    for i in range(rows.size):
        t, e, a, b = rows[i], homes[i], old[i], new[i]
        if a == b:
            continue
        for p in range(indptr[t], indptr[t + 1]):
            k = indices[p]
            v = np.int64(data[p])
            n[e, a, k] -= v
            n[e, b, k] += v
