"""Which words are names with the word channels (:func:`spco.model.home_shard.name_words`): the
switches' expected counts it reads against each token's conditional, a word first heard in a home,
and the same verdict over seeds for the same data (the counts averaged over the averaged sweeps)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp
from numpy.testing import assert_allclose

from spco.model.home_shard import name_words
from spco.model.word_channels import WordChannels, expected_tokens, switch_probabilities


def _channels(rng: np.random.Generator, n_words: int, n_concepts: int) -> WordChannels:
    return WordChannels(
        log_place=np.log(rng.dirichlet(np.ones(n_words), size=n_concepts)),
        log_background=np.log(rng.dirichlet(np.ones(n_words))),
        log_shares=np.concatenate([[0.0], np.log(rng.dirichlet(np.ones(2)))]),
        log_evidence=np.log(np.column_stack([p := rng.uniform(0.05, 0.95, n_words), 1 - p, 1 - p])))


def _likelihoods(log_theta: np.ndarray, channels: WordChannels, home: int, concept: int,
                 k: int) -> np.ndarray:
    """p(word k | channel c, concept, home) for c = name, place, background."""
    return np.exp([log_theta[home, concept, k], channels.log_place[concept, k], channels.log_background[k]])


@pytest.mark.parametrize("seed", range(5))
def test_expected_tokens_are_each_tokens_switch_posterior_summed(seed: int) -> None:
    """expected_tokens against each token's switch posterior written out (prior × likelihood,
    normalised) and summed by word."""
    rng = np.random.default_rng(seed)
    n_samples, V, L, E = 6, 4, 3, 2
    dense = (rng.random((n_samples, V)) < 0.6) * 5000.0
    dense[:, 0] = 5000.0
    words = sp.csr_array(dense)
    homes, concepts = rng.integers(0, E, n_samples), rng.integers(0, L, n_samples)
    log_theta = np.log(rng.dirichlet(np.ones(V), size=(E, L)))
    channels = _channels(rng, V, L)
    prior = np.exp(channels.log_prior())
    expected = np.zeros((V, 3))
    for t in range(n_samples):
        for k in np.flatnonzero(dense[t]):
            joint = prior[k] * _likelihoods(log_theta, channels, homes[t], concepts[t], k)
            expected[k] += joint / joint.sum()  # each token once, whatever its count S^w
    assert_allclose(expected_tokens(words, homes, concepts, log_theta, channels), expected, rtol=1e-10)
    p = switch_probabilities(words, homes, concepts, log_theta, channels)
    assert_allclose(expected_tokens(words, homes, concepts, log_theta, channels).sum(), p.sum())


def test_a_word_first_heard_in_a_home_is_a_name_as_its_prior_says() -> None:
    """A word first heard in a home (its switch is its prior: no likelihood tells the channels apart)
    is a name said once when its prior makes the names channel its most probable ("this is the study
    room"), not when the prior makes it a place word ("the fridge is over here"); a word never said,
    or one whose uses the background explains, is none."""
    V = 4
    channels = WordChannels.initial(np.array([0.69, 0.22, 0.9, 0.5]), 1,
                                    content=np.array([0.95, 0.95, 0.95, 0.05]))
    channels = replace(channels, fresh=False, prior_only_from=0)
    dense = np.zeros((3, V))
    dense[0, [0, 1]] = 5000.0
    dense[1:, 3] = 5000.0
    zeros = np.zeros(3, dtype=np.int64)
    tokens = expected_tokens(sp.csr_array(dense), zeros, zeros, np.full((1, 1, V), -np.log(V)), channels)
    assert name_words(tokens).tolist() == [True, False, False, False]
    assert_allclose(tokens.sum(axis=1), [1, 1, 0, 2])


@pytest.fixture(scope="module")
def template_fits() -> list:
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.model import SpCoTransfer
    from spco.model.hyperparameters import TransferHyperparameters

    corpus = generate_homes(6, seed=1, config=SyntheticConfig(n_features=64), teaching_rate=20,
                            specific_rooms=False)
    return [(corpus, SpCoTransfer(TransferHyperparameters(word_model="channels"), prune_words=True,
                                  n_iterations=15, random_state=seed, record_log_joint=False).fit(corpus))
            for seed in range(4)]


def test_the_same_homes_give_the_same_names_over_seeds(template_fits: list) -> None:
    """Synthetic template homes fitted with four seeds: the words `what` may answer (the switches'
    expected counts averaged over the averaged sweeps, :func:`name_words`) are the
    same set in every seed, "bath" (a vessel in WordNet, said at one place) included; no template word
    is among them."""
    verdicts = []
    for corpus, model in template_fits:
        words = corpus.vocabulary.words
        assert model.channel_tokens_ is not None and model.channel_tokens_.shape == (len(words), 3)
        names = name_words(model.channel_tokens_)
        verdicts.append({w for w, keep in zip(words, names, strict=True) if keep})
    assert all(v == verdicts[0] for v in verdicts[1:]), verdicts
    assert "bath" in verdicts[0]
    assert not verdicts[0] & {"this", "is", "the", "here", "place", "location", "space"}


def test_averaged_tokens_count_every_token_once(template_fits: list) -> None:
    """The averaged expected counts hold each word's uses (tokens of the fit's homes), split over the
    three channels."""
    corpus, model = template_fits[0]
    data = model.data_
    uses = np.bincount(data.words.indices[: data.words.indptr[-1]], minlength=len(corpus.vocabulary))
    assert_allclose(model.channel_tokens_.sum(axis=1), uses, rtol=1e-9)
    assert (model.channel_tokens_ >= 0).all()
