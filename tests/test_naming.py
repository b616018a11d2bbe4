"""The naming rule (what counts as a place name) and the start that gives a home's own names
concepts of their own: brute force on tiny problems and small synthetic homes (seconds)."""

from __future__ import annotations

import itertools

import numpy as np
import scipy.sparse as sp

from spco.data import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes, teach
from spco.model import SpCoTransfer, TransferHyperparameters, gibbs
from spco.model.pruning import NAME, NOT_A_NAME, UNDECIDED, Colocation, colocation, judge_names


def _brute_colocation(words: np.ndarray, homes: np.ndarray, regions: np.ndarray) -> tuple:
    """pairs, same, expected by enumerating every pair of samples of every home."""
    v = words.shape[1]
    pairs, same, expected = np.zeros(v), np.zeros(v), np.zeros(v)
    for e in np.unique(homes):
        rows = np.flatnonzero((homes == e) & (words.sum(axis=1) > 0))  # the home's taught samples
        all_pairs = list(itertools.combinations(rows, 2))
        q = np.mean([regions[a] == regions[b] for a, b in all_pairs]) if all_pairs else 1.0
        for k in range(v):
            uses = [t for t in rows if words[t, k] > 0]
            for a, b in itertools.combinations(uses, 2):
                pairs[k] += 1
                same[k] += regions[a] == regions[b]
            expected[k] += q * len(uses) * (len(uses) - 1) / 2
    return pairs, same, expected


def test_colocation_matches_brute_force() -> None:
    rng = np.random.default_rng(0)
    n, v, n_homes, n_regions = 40, 6, 3, 4
    words = rng.integers(0, 2, size=(n, v)) * rng.integers(1, 4, size=(n, v)) * 5000
    words[rng.random(n) < 0.3] = 0  # untaught samples
    homes = np.sort(rng.integers(0, n_homes, size=n))
    regions = rng.integers(0, n_regions, size=n)
    stats = colocation(sp.csr_array(words), homes, regions, n_homes, n_regions)
    pairs, same, expected = _brute_colocation(words, homes, regions)
    assert np.array_equal(stats.pairs, pairs) and np.array_equal(stats.same, same)
    assert np.allclose(stats.expected, expected)


def test_verdicts() -> None:
    stats = Colocation(pairs=np.array([40.0, 400.0, 18.0, 0.0, 1.0, 3.0, 18.0, 10.0]),
                       same=np.array([20.0, 30.0, 2.0, 0.0, 1.0, 1.0, 4.0, 10.0]),
                       expected=np.array([3.0, 30.0, 1.2, 0.0, 0.07, 0.2, 1.23, 10.0]))
    # a name; a word said like any sentence; a small excess on few pairs; a word said once; a word
    # said twice at one place; three uses at two places; an excess of 0.17 on 18 pairs (tail 0.036);
    # a home taught in one region only (chance splits no pair: nothing to tell)
    assert judge_names(stats).tolist() == [NAME, NOT_A_NAME, NOT_A_NAME, UNDECIDED, UNDECIDED, UNDECIDED,
                                           UNDECIDED, UNDECIDED]


def test_template_words_are_no_names_and_place_names_are() -> None:
    """On synthetic homes taught at 20 %, fitted with pruning: every place name is kept (none was
    lost for the run as with the earlier one-off test), no template word is."""
    corpus = generate_homes(6, seed=1, config=SyntheticConfig(n_features=64), teaching_rate=20,
                            specific_rooms=False)
    model = SpCoTransfer(prune_words=True, n_iterations=15, random_state=0, record_log_joint=False)
    model.fit(corpus)
    kept = {w for w, k in zip(corpus.vocabulary.words, model.parameters_.word_mask, strict=True) if k}
    places = {lab for env in corpus for lab in env.labels() if lab}
    assert places <= kept
    assert not {"this", "is", "the", "here", "place", "location"} & kept


def test_a_new_homes_own_names_start_in_free_concepts() -> None:
    """A home that starts from the transferred knowledge (taught below half) keeps its own names'
    samples together, in concepts no other home uses, instead of in other places' concepts."""
    config = SyntheticConfig(n_features=64)
    corpus = generate_homes(5, seed=2, config=config, new_homes=1)
    new = corpus[-1]
    places = sorted({lab for lab in new.labels(True) if lab} - {lab for lab in new.labels() if lab})
    assert places, "the synthetic new home has home-specific rooms"
    taught = teach(new, 40, places=places, seed=0)
    homes = Corpus([*list(corpus)[:-1], taught])
    data = SpCoTransfer._prepare(homes, 1.0)
    hyper = TransferHyperparameters()
    settings = gibbs.SamplerSettings.create("exact", prune=True)
    state = gibbs.initialize(data, len(homes.vocabulary), hyper, settings, np.random.default_rng(0))
    e = data.n_homes - 1
    rows = np.arange(data.offsets[e], data.offsets[e + 1])
    others = np.unique(state.concepts[data.homes != e])
    sentences = taught.training_data().sentences
    for place in places:
        column = homes.vocabulary.index(place)
        said = rows[np.asarray(data.words[rows][:, [column]].toarray()).ravel() > 0]
        assert said.size and len(sentences) == rows.size
        concepts = np.unique(state.concepts[said])
        assert concepts.size == 1, (place, concepts)
        assert concepts[0] not in others, (place, concepts, others)


def _collapsed_log_joint(tables: tuple, alphas: tuple, counts: np.ndarray, g_term: np.ndarray) -> float:
    """log p(tables, concept counts | G_0) with φ, G_e integrated, written out term by term over
    every concept (the factors a relabelling leaves alone included: they must cancel)."""
    from scipy.special import gammaln

    total = 0.0
    for m, alpha in zip(tables, alphas, strict=True):
        pooled = alpha + m.sum(axis=0)  # (L, D)
        prior = np.full(m.shape[2], alpha)
        total += float((gammaln(pooled).sum(1) - gammaln(pooled.sum(1))).sum())
        total -= m.shape[1] * float(gammaln(prior).sum() - gammaln(prior.sum()))
    gamma = g_term.sum()
    for n_e in counts:
        total += float(gammaln(gamma) - gammaln(gamma + n_e.sum()))
        total += float((gammaln(g_term + n_e) - gammaln(g_term)).sum())
    return total


def test_realign_swap_ratio_matches_the_collapsed_joint() -> None:
    """Brute force: the re-alignment move's log acceptance ratio equals the change of the collapsed
    joint (φ and G_e integrated out) when two labels of one home are swapped."""
    from spco.model.moves import swap_log_ratio

    rng = np.random.default_rng(3)
    homes, concepts, dims, words = 3, 4, 5, 3
    tables = (rng.integers(0, 6, size=(homes, concepts, dims)),
              rng.integers(0, 4, size=(homes, concepts, words)))
    counts = rng.integers(0, 9, size=(homes, concepts)).astype(float)
    alphas, g_term = (0.7, 0.05), rng.gamma(1.0, size=concepts) * 3
    before = _collapsed_log_joint(tables, alphas, counts, g_term)
    for e, a, b in [(0, 0, 1), (1, 2, 3), (2, 0, 3)]:
        totals = tuple(m.sum(axis=0).astype(float) for m in tables)
        ratio = swap_log_ratio(totals, (tables[0][e], tables[1][e]), alphas, counts[e], g_term, a, b)
        swapped = tuple(m.copy() for m in tables)
        for m in swapped:
            m[e, [a, b]] = m[e, [b, a]]
        swapped_counts = counts.copy()
        swapped_counts[e, [a, b]] = swapped_counts[e, [b, a]]
        after = _collapsed_log_joint(swapped, alphas, swapped_counts, g_term)
        assert np.isclose(ratio, after - before, rtol=1e-10, atol=1e-9)


def test_realign_moves_a_place_to_the_label_the_other_homes_use() -> None:
    """Two homes call one place by label 0, a third by label 2 (its label 0 holds another place):
    with φ integrated out the move relabels the third home, which the φ-fixed swap cannot."""
    from spco.model.moves import realign_step

    profile_a, profile_b = np.array([30, 0, 0, 0]), np.array([0, 0, 30, 0])
    tables_v = np.zeros((3, 3, 4), dtype=np.int64)
    tables_v[0, 0] = tables_v[1, 0] = profile_a
    tables_v[0, 1] = tables_v[1, 1] = profile_b
    tables_v[2, 2], tables_v[2, 1] = profile_a, profile_b
    counts = np.array([[10, 10, 0], [10, 10, 0], [0, 10, 10]])
    moved = 0
    for seed in range(20):
        perms = realign_step(tables_v.copy(), np.zeros((3, 3, 0), dtype=np.int64), counts, 0.5, 0.01,
                             np.full(3, 10.0 / 3), np.random.default_rng(seed))
        moved += int(perms[2, 0] == 2)
    assert moved >= 5  # proposed (0, 2) in about a third of the passes, accepted when proposed
