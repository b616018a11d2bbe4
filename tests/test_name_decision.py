"""Which words are names with the word channels (:func:`spco.model.home_shard.name_words`): the
posterior of a word's channel against enumeration on tiny problems, the switches' expected counts
against their conditionals, and the same verdict over seeds for the same data."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse as sp
from numpy.testing import assert_allclose
from scipy.special import logsumexp

from spco.model.home_shard import name_words, word_channel_log_posterior
from spco.model.word_channels import NAME, WordChannels, expected_tokens, switch_probabilities


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


@pytest.mark.parametrize("seed", range(8))
def test_word_channel_posterior_against_enumeration(seed: int) -> None:
    """A word said n times at one concept of one home: the posterior of its channel (all its uses
    from one channel, the switch's prior as the channel's prior) from the switches' expected counts
    equals the enumeration p(c | uses) ∝ p(z = c | k) Π_i p(w_i | c); the name verdict is its argmax."""
    rng = np.random.default_rng(100 + seed)
    V, L, n = 3, 2, int(rng.integers(1, 7))
    channels = _channels(rng, V, L)
    log_theta = np.log(rng.dirichlet(np.ones(V) * 0.5, size=(1, L)))
    k, concept = int(rng.integers(V)), int(rng.integers(L))
    dense = np.zeros((n, V))
    dense[:, k] = 5000.0
    words = sp.csr_array(dense)
    tokens = expected_tokens(words, np.zeros(n, dtype=np.int64), np.full(n, concept), log_theta, channels)
    prior = np.exp(channels.log_prior()[k])
    like = _likelihoods(log_theta, channels, 0, concept, k)
    brute = np.array([prior[c] * like[c] ** n for c in range(3)])
    brute /= brute.sum()
    post = word_channel_log_posterior(tokens, channels.log_prior())[k]
    assert_allclose(np.exp(post - logsumexp(post)), brute, rtol=1e-8, atol=1e-300)
    assert bool(name_words(tokens, channels.log_prior())[k]) == (int(np.argmax(brute)) == NAME)
    # the same from every configuration of the uses' likelihoods enumerated (each use from channel c)
    configs = np.array(list(itertools.product(range(3), repeat=n)))
    like_all = np.prod(like[configs], axis=1)
    same = np.array([prior[c] * like_all[(configs == c).all(axis=1)].sum() for c in range(3)])
    assert_allclose(same / same.sum(), brute, rtol=1e-8, atol=1e-300)


def test_a_word_without_telling_uses_is_its_priors_channel() -> None:
    """A word whose uses carry no likelihood that tells the channels apart (its switch posterior is
    its prior: a word first heard in a home) is a name exactly when the prior's most probable channel
    is the names, however often it is said; a word never said is no name; a word whose uses the
    background explains is none, however name-like its prior."""
    prior = np.array([[0.69, 0.28, 0.03], [0.22, 0.75, 0.03], [0.5, 0.3, 0.2], [0.9, 0.05, 0.05]])
    tokens = prior * np.array([[1.0], [3.0], [0.0], [1.0]])
    tokens[3] = [0.0, 0.0, 40.0]
    assert name_words(tokens, np.log(prior)).tolist() == [True, False, False, False]


def test_the_verdict_follows_the_uses_not_a_share() -> None:
    """The prior counts once, each use once: a word whose uses are slightly more often names than its
    prior says becomes a name once said often enough, and one whose uses are fewer names than the prior
    never does (no share threshold: 4 % of uses as names is a name when the prior says 1 %)."""
    log_prior = np.log(np.array([[0.27, 0.61, 0.12]]))
    share = np.array([[0.42, 0.58, 0.0]])  # "bath" in the synthetic templates
    assert not name_words(share * 1, log_prior)[0]
    assert name_words(share * 30, log_prior)[0]
    assert not name_words(np.array([[0.2, 0.8, 0.0]]) * 500, log_prior)[0]
    rare = np.log(np.array([[0.01, 0.49, 0.5]]))
    assert name_words(np.array([[0.04, 0.5, 0.46]]) * 200, rare)[0]


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
    expected counts averaged over the averaged sweeps, then the word's most probable channel) are the
    same set in every seed, "bath" (a vessel in WordNet, said at one place) included; no template word
    is among them."""
    verdicts = []
    for corpus, model in template_fits:
        words = corpus.vocabulary.words
        assert model.channel_tokens_ is not None and model.channel_tokens_.shape == (len(words), 3)
        names = name_words(model.channel_tokens_, model.state_.channels.log_prior())
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
