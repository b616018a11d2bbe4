"""The prepared data of a fit (``SpatialConceptModel._prepare``): its layout, and what it costs in
memory — no copies of the corpus's visual counts beyond the one stacked array the kernels read."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp

from spco.data.environment import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.model.kernels.counts import grouped_row_sums, stack_counts
from spco.model.kernels.likelihood import grouped_sparse_dot
from spco.model.state import PreparedData


@pytest.fixture(scope="module")
def corpus() -> Corpus:
    """Two taught homes and a new one whose test samples are held out."""
    return generate_homes(3, seed=2, config=SyntheticConfig(n_features=48), new_homes=1, specific_rooms=False)


def _blocks() -> list:
    rng = np.random.default_rng(0)
    dense = [np.where(rng.random((n, 9)) < 0.3, rng.integers(1, 50, (n, 9)), 0) for n in (4, 1, 6, 3)]
    blocks = [sp.csr_array(dense[0]), sp.csr_matrix(dense[1]), sp.coo_array(dense[2]),
              sp.csr_array(sp.csr_array(dense[3]), dtype=np.int64)]
    blocks[3].indices = blocks[3].indices.astype(np.int64)
    blocks[3].indptr = blocks[3].indptr.astype(np.int64)
    return blocks


def test_stack_counts_stacks_like_vstack_in_the_compact_layout() -> None:
    blocks = _blocks()
    before = [sp.csr_array(b).copy() for b in blocks]
    out = stack_counts(*blocks)
    expected = sp.csr_array(sp.vstack(blocks, format="csr"), dtype=np.float64)
    assert isinstance(out, sp.csr_array) and out.shape == expected.shape
    assert (out.data.dtype, out.indices.dtype, out.indptr.dtype) == (np.float32, np.int32, np.int64)
    np.testing.assert_array_equal(out.data, expected.data)
    np.testing.assert_array_equal(out.indices, expected.indices)
    np.testing.assert_array_equal(out.indptr, expected.indptr)
    for block, copy in zip(blocks, before, strict=True):  # the inputs are untouched and not shared
        block = sp.csr_array(block)
        assert (block != copy).nnz == 0
        for a in (block.data, block.indices, block.indptr):
            assert not any(np.shares_memory(a, b) for b in (out.data, out.indices, out.indptr))


def test_stack_counts_of_one_matrix() -> None:
    counts = sp.csr_array(np.array([[0, 3, 0], [5000, 0, 5000]]))
    out = stack_counts(counts)
    np.testing.assert_array_equal(out.toarray(), counts.toarray())
    assert out.indices.dtype == np.int32 and out.data.dtype == np.float32
    with pytest.raises(ValueError, match="columns"):
        stack_counts(counts, sp.csr_array(np.ones((1, 4))))


def test_stack_counts_keeps_float64_for_counts_float32_cannot_hold() -> None:
    counts = sp.csr_array(np.array([[2**24 + 1, 0, 1]], dtype=np.int64))
    out = stack_counts(counts)
    assert out.data.dtype == np.float64
    assert out.data[0] == 2**24 + 1


def test_compact_layout_gives_the_same_kernel_results_bit_for_bit() -> None:
    """The kernels multiply in float64: float32 counts with int32 indices give exactly what the
    float64 / int64 layout gives (likelihoods and count statistics)."""
    rng = np.random.default_rng(3)
    dense = np.where(rng.random((40, 300)) < 0.4, rng.integers(1, 7000, (40, 300)), 0)
    compact = stack_counts(sp.csr_array(dense))
    wide = sp.csr_array(dense, dtype=np.float64)
    wide.indices, wide.indptr = wide.indices.astype(np.int64), wide.indptr.astype(np.int64)
    groups = rng.integers(0, 3, 40)
    table = np.log(rng.dirichlet(np.full(300, 0.1), size=(3, 5))).transpose(0, 2, 1).copy()
    np.testing.assert_array_equal(grouped_sparse_dot(compact, groups, table),
                                  grouped_sparse_dot(wide, groups, table))
    sums = grouped_row_sums(wide, groups, 3)
    np.testing.assert_array_equal(grouped_row_sums(compact, groups, 3), sums)
    np.testing.assert_array_equal(sums, np.stack([dense[groups == g].sum(0) for g in range(3)]))


def test_prepared_visual_counts_are_the_training_rows(corpus: Corpus) -> None:
    assert corpus[-1].n_test > 0  # one home has held-out samples, the others none
    data = PreparedData.from_corpus(corpus, 1.0)
    training = corpus.training_set()
    expected = sp.vstack([t.visual for t in training], format="csr")
    np.testing.assert_array_equal(data.visual.toarray(), expected.toarray())
    assert data.visual.indices.dtype == np.int32 and data.visual.data.dtype == np.float32
    assert data.offsets[-1] == data.n_samples == sum(e.n_train for e in corpus)


def test_training_data_copies_visual_rows_only_when_some_are_test_samples(corpus: Corpus) -> None:
    taught, new = corpus[0], corpus[-1]
    assert taught.n_test == 0 and taught.training_data().visual is taught.visual
    train = new.training_data().visual
    assert train.shape[0] == new.n_train and not np.shares_memory(train.data, new.visual.data)


def test_a_fit_does_not_import_scipy_stats() -> None:
    """scipy.stats (~24 MB of a fit's resident memory) is imported only by word pruning."""
    code = ("import sys\n"
            "from spco.data.synthetic import SyntheticConfig, generate_homes\n"
            "from spco.model.transfer import SpCoTransfer\n"
            "corpus = generate_homes(2, seed=0, config=SyntheticConfig(n_features=16), new_homes=1,"
            " specific_rooms=False)\n"
            "SpCoTransfer(n_iterations=2, random_state=0).fit(corpus)\n"
            "print('scipy.stats' in sys.modules)\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split()[-1] == "False"


def test_environment_keeps_32_bit_index_arrays(corpus: Corpus) -> None:
    from dataclasses import replace

    env = corpus[0]
    wide = sp.csr_array(env.visual)
    wide.indices, wide.indptr = wide.indices.astype(np.int64), wide.indptr.astype(np.int64)
    again = replace(env, visual=wide)
    assert again.visual.indices.dtype == np.int32 and again.visual.indptr.dtype == np.int32
    assert again.visual.data.dtype == np.int64
    np.testing.assert_array_equal(again.visual.toarray(), env.visual.toarray())
