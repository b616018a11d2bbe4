"""The naming rule (what counts as a place name) and the start that gives a home's own names
concepts of their own: brute force on tiny problems and small synthetic homes (seconds)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse as sp

from spco.data import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes, teach
from spco.model import SpCoTransfer, TransferHyperparameters, assignments, gibbs
from spco.model.driver import start_run
from spco.model.pruning import (
    EXCESS_GRID,
    NAME,
    NOT_A_NAME,
    UNDECIDED,
    Colocation,
    colocation,
    judge_names,
)
from spco.model.state import PreparedData


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


def _brute_log_likelihood(words: np.ndarray, homes: np.ndarray, regions: np.ndarray, n_regions: int
                          ) -> np.ndarray:
    """log p(regions of each word's uses | κ) on EXCESS_GRID, as the Pólya urn's sequence of draws:
    the i-th use of a home lands in region m with probability (α s_m + n_m)/(α + i), n_m the uses
    before it there, s_m the home's share of taught samples in m, α = (1 − κ)/κ."""
    alpha = (1 - EXCESS_GRID) / EXCESS_GRID
    out = np.zeros((words.shape[1], EXCESS_GRID.size))
    for e in np.unique(homes):
        rows = np.flatnonzero((homes == e) & (words.sum(axis=1) > 0))
        share = np.bincount(regions[rows], minlength=n_regions) / rows.size
        for k in range(words.shape[1]):
            seen = np.zeros(n_regions)
            for i, t in enumerate(t for t in rows if words[t, k] > 0):
                out[k] += np.log((alpha * share[regions[t]] + seen[regions[t]]) / (alpha + i))
                seen[regions[t]] += 1
    return out


def test_the_urn_likelihood_matches_brute_force() -> None:
    rng = np.random.default_rng(3)
    n, v, n_homes, n_regions = 50, 7, 3, 4
    words = rng.integers(0, 2, size=(n, v)) * 5000
    words[:, 0] = np.where(rng.random(n) < 0.5, 5000, 0) * (np.arange(n) % n_regions == 0)  # one place
    words[rng.random(n) < 0.3] = 0  # untaught samples
    homes = np.sort(rng.integers(0, n_homes, size=n))
    regions = rng.integers(0, n_regions, size=n)
    regions[np.arange(n) % n_regions == 0] = 1
    stats = colocation(sp.csr_array(words), homes, regions, n_homes, n_regions)
    brute = _brute_log_likelihood(words, homes, regions, n_regions)
    # equal up to a constant per word (homes where the word is said once are left out: a constant)
    np.testing.assert_allclose(stats.log_likelihood - stats.log_likelihood[:, :1], brute - brute[:, :1],
                               atol=1e-9)
    assert (np.ptp(brute, axis=1) > 0.1).all()  # every word is said twice in some home: the test has teeth


def _one_home(uses: list[list[int]], n_regions: int = 8, per_region: int = 5) -> Colocation:
    """A home with ``per_region`` taught samples in each region, and word k said at regions uses[k]."""
    rows, regions = [], []
    for m in range(n_regions):
        rows += [[1] + [0] * len(uses)] * per_region
        regions += [m] * per_region
    for k, places in enumerate(uses):
        for m in places:
            rows.append([1] + [int(j == k) for j in range(len(uses))])
            regions.append(m)
    regions_arr = np.array(regions)
    return colocation(sp.csr_array(np.array(rows) * 5000), np.zeros(len(rows), dtype=np.int64), regions_arr,
                      1, n_regions)


def test_verdicts() -> None:
    # column 0 is said at every sample (like "the"); then: a name said 8 times at one place; a word
    # said once; twice at one place; twice at two places and once at three (a name taught at two or
    # three places); seven uses at seven places (a pronoun); five uses at four places
    stats = _one_home([[2] * 8, [5], [3, 3], [1, 6], [0, 4, 7], [0, 1, 2, 3, 4, 5, 6], [0, 0, 1, 2, 3]])
    assert judge_names(stats).tolist() == [NOT_A_NAME, NAME, UNDECIDED, UNDECIDED, UNDECIDED, UNDECIDED,
                                           NOT_A_NAME, NOT_A_NAME]
    assert stats.log_bayes_factor()[2] == 0.0  # said once: no evidence either way
    # a home taught in one region only: chance puts every pair there, nothing to tell
    alone = colocation(sp.csr_array(np.ones((6, 1)) * 5000), np.zeros(6, dtype=np.int64), np.zeros(6, int),
                       1, 3)
    assert judge_names(alone).tolist() == [UNDECIDED]
    # the hand-written "we": five uses at four regions of one home, two at two of another; fewer
    # than one same-region pair expected by chance (the earlier rule's minimum evidence: undecided)
    rows = [[1, 0]] * 40 + [[1, 1]] * 5 + [[1, 0]] * 40 + [[1, 1]] * 2
    regions = [*(np.arange(40) % 20), 16, 3, 1, 14, 14, *(np.arange(40) % 20), 8, 2]
    homes = np.repeat([0, 1], [45, 42])
    we = colocation(sp.csr_array(np.array(rows) * 5000), homes, np.array(regions), 2, 20)
    assert we.expected[1] < 1 and judge_names(we)[1] == NOT_A_NAME
    with pytest.raises(ValueError, match="bayes_factor"):
        judge_names(stats, bayes_factor=1.0)


@pytest.mark.parametrize("word_model", ["naming-rule", pytest.param("channels", marks=pytest.mark.xfail(
    strict=True, reason="known failure of the word channels (issue 28): 'dining' (an act in WordNet, name "
    "evidence 0.10 on the templates) is a place word, not a name, in the template sentences in every seed: "
    "said at one place only, its uses are explained as well by the place channel as by the names, so the "
    "evidence decides: 0-4 % of its uses names in seeds 0-3, below NAME_SHARE (7 %). 'bath' (42-54 %) "
    "is a name "
    "since the decision reads the switches' expected counts averaged over the sweeps, not the last state. "
    "Left failing, not loosened (docs/model.md, 'Words that are not names')"))])
def test_template_words_are_no_names_and_place_names_are(word_model: str) -> None:
    """On synthetic homes taught at 20 %: with the naming rule every place name is kept (none was
    lost for the run as with the earlier one-off test), no template word is; with the word channels
    (no word is pruned) the place names are names (:func:`~spco.model.home_shard.name_words` of the
    switches' expected counts averaged over the averaged sweeps) and no template word is."""
    from spco.model.home_shard import name_words
    from spco.model.hyperparameters import TransferHyperparameters
    from spco.model.word_channels import NAME

    corpus = generate_homes(6, seed=1, config=SyntheticConfig(n_features=64), teaching_rate=20,
                            specific_rooms=False)
    model = SpCoTransfer(TransferHyperparameters(word_model=word_model), prune_words=True, n_iterations=15,
                         random_state=0, record_log_joint=False)
    model.fit(corpus)
    words = corpus.vocabulary.words
    places = {lab for env in corpus for lab in env.labels() if lab}
    template = {"this", "is", "the", "here", "place", "location"}
    if word_model == "naming-rule":
        kept = {w for w, k in zip(words, model.parameters_.word_mask, strict=True) if k}
        assert places <= kept
        assert not template & kept
        return
    tokens = model.channel_tokens_  # the switches' expected counts, averaged over the averaged sweeps
    names = name_words(tokens)
    named = {w for w, keep in zip(words, names, strict=True) if keep}
    share = tokens[:, NAME] / np.maximum(tokens.sum(axis=1), 1e-300)
    assert places <= named, {w: round(float(v), 2) for w, v in zip(words, share, strict=True)}
    assert not template & named


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
    data = PreparedData.from_corpus(homes, 1.0)
    hyper = TransferHyperparameters()
    settings = gibbs.SamplerSettings.create("exact", prune=True)
    run = start_run(None, data, len(homes.vocabulary), hyper, settings, np.random.default_rng(0))
    state = run.state()  # the state the fit's start (spco.model.shard_init) gives the first sweep
    run.close()
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


def test_align_homes_matches_a_synonym_by_its_views() -> None:
    """Home 1 calls the entrance "front door" and the bath "bathroom", names home 0 never says but
    home 2 does: matched by their words they would tie (unseen words score alike under every
    label) and may swap places; with the name counts they go by their views."""
    from spco.model.gibbs import align_homes

    n_concepts, dims = 3, 3  # places: entrance, kitchen, bath; view dimension d is place d's look
    entrance, kitchen, bath, front_door, bathroom = range(5)
    visual = np.zeros((3, n_concepts, dims))
    words = np.zeros((3, n_concepts, 5))
    # home 0 (most words, aligned first): concept l is place l, named by its name
    for place, name in ((0, entrance), (1, kitchen), (2, bath)):
        visual[0, place, place] = 20
        words[0, place, name] = 6
    # home 1: concept 0 is the bath ("bathroom"), concept 1 the kitchen, concept 2 the entrance
    for concept, place, name in ((0, 2, bathroom), (1, 1, kitchen), (2, 0, front_door)):
        visual[1, concept, place] = 20
        words[1, concept, name] = 5
    # home 2 says the synonyms too (so they are no names of home 1 alone), aligned last
    for concept, place, name in ((0, 0, front_door), (1, 1, kitchen), (2, 2, bathroom)):
        visual[2, concept, place] = 20
        words[2, concept, name] = 4
    name_counts = (words > 0).astype(float)
    perms = align_homes(visual, words, 0.1, 0.1, name_counts)
    # slot j of home 1 holds its concept perms[1, j]: the entrance slot 0 its concept 2, the bath's slot 2
    assert perms[1].tolist() == [2, 1, 0]
    assert perms[2].tolist() == [0, 1, 2]


def test_a_home_where_every_word_is_pruned_still_samples() -> None:
    """Names said at random positions are spread: the rule may prune every word; the sampler's word
    term is then empty (no word says anything), not a reduction over zero words."""
    log_theta = np.log(np.full((1, 2, 3), 1 / 3))
    kept = assignments.kept_word_log_theta(log_theta, np.zeros(3, dtype=bool))
    assert np.array_equal(kept, np.zeros_like(log_theta))
