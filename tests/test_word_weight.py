"""The word weight W^w (``TransferHyperparameters.word_counts``): a word token's evidence in its
concept's assignment, in counts, carried from the hyperparameters to the sampler, the knowledge file
and the checkpoints (docs/model.md, "A word token's evidence"). The conditional itself is checked
against enumeration in ``tests/test_word_channels.py``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from spco.engines.checkpoints import load_driver, save_driver
from spco.errors import ConfigurationError
from spco.knowledge.knowledge import KnowledgeChannels
from spco.model.hyperparameters import VIEW_COUNTS, WORD_COUNTS, TransferHyperparameters
from spco.model.state import SharedParameters
from spco.model.word_channels import WordChannels, mixture_log_likelihood, token_weight


def test_the_word_weight_is_a_hyperparameter() -> None:
    hyper = TransferHyperparameters()
    assert hyper.word_counts == WORD_COUNTS == VIEW_COUNTS  # a token weighs as one view
    assert TransferHyperparameters.from_dict(hyper.to_dict()).word_counts == WORD_COUNTS
    old = hyper.to_dict()
    del old["word_counts"]  # a file from before the word weight: S^w counts per token
    assert TransferHyperparameters.from_dict(old).word_counts is None
    assert hyper.with_settings(["word_counts=4"]).word_counts == 4.0
    assert hyper.with_settings(["word_counts=none"]).word_counts is None
    for bad in ("0", "-1", "nan", "inf"):
        with pytest.raises(ConfigurationError, match="word_counts"):
            hyper.with_settings([f"word_counts={bad}"])


def _channels(weight: float) -> WordChannels:
    rng = np.random.default_rng(0)
    return WordChannels.initial(rng.uniform(0.1, 0.9, 5), 3, content=rng.uniform(0.1, 0.9, 5),
                                token_weight=weight)


def test_the_knowledge_file_and_the_checkpoints_carry_the_token_weight(tmp_path) -> None:
    channels = replace(_channels(16 / 5000), fresh=False)
    tokens = np.zeros((5, 3))
    arrays = KnowledgeChannels(channels, tokens).arrays()
    assert KnowledgeChannels.from_arrays(arrays).channels.token_weight == pytest.approx(16 / 5000)
    # a file from before the word weight holds none: S^w counts per token
    plain = KnowledgeChannels(replace(channels, token_weight=1.0), tokens).arrays()
    assert "channels.token_weight" not in plain
    assert KnowledgeChannels.from_arrays(plain).channels.token_weight == 1.0
    with pytest.raises(ValueError, match="token_weight"):
        KnowledgeChannels.from_arrays({**arrays, "channels.token_weight": np.array([-1.0])})
    shared = SharedParameters(np.zeros((3, 2)), np.zeros((3, 5)), np.zeros(3), np.ones(5, dtype=bool),
                              None, channels)
    save_driver(tmp_path, 4, {}, shared, np.zeros(4), 0)
    _, _, back, _, _ = load_driver(tmp_path)
    assert back.channels.token_weight == pytest.approx(16 / 5000)


def test_a_token_weighs_the_word_weight_whatever_the_word_increment() -> None:
    """The same sentence encoded with S^w = 5,000 and S^w = 1 weighs the same in its concept once the
    channels carry W^w / S^w; without the weight (``None``) it weighs S^w times as much."""
    channels = _channels(1.0)
    rng = np.random.default_rng(1)
    log_theta = np.log(rng.dirichlet(np.ones(5), size=(1, 3)))
    dense = np.array([[1.0, 0, 1, 0, 0], [0, 1, 1, 1, 0]])
    homes = np.zeros(2, dtype=np.int64)
    by_one = mixture_log_likelihood(sp.csr_array(dense), homes, log_theta,
                                    replace(channels, token_weight=token_weight(16.0, 1)))
    by_many = mixture_log_likelihood(sp.csr_array(dense * 5000), homes, log_theta,
                                     replace(channels, token_weight=token_weight(16.0, 5000)))
    np.testing.assert_allclose(by_one, by_many, rtol=1e-12)
    unweighted = mixture_log_likelihood(sp.csr_array(dense * 5000), homes, log_theta,
                                        replace(channels, token_weight=token_weight(None, 5000)))
    np.testing.assert_allclose(unweighted, by_many * 5000 / 16, rtol=1e-12)
    with pytest.raises(ValueError, match="token_weight"):
        _channels(0.0)


def test_a_fit_uses_the_word_weight_of_its_hyperparameters() -> None:
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.model import SpCoTransfer

    corpus = generate_homes(3, seed=2, config=SyntheticConfig(n_features=32), teaching_rate=20,
                            specific_rooms=False)
    for word_counts, expected in ((None, 1.0), (4.0, 4.0 / corpus.word_increment)):
        model = SpCoTransfer(TransferHyperparameters(word_counts=word_counts), prune_words=True,
                             n_iterations=3, random_state=0, record_log_joint=False).fit(corpus)
        assert model.state_.channels is not None
        assert model.state_.channels.token_weight == pytest.approx(expected)
        assert model.hyperparameters_.word_counts == word_counts


def test_a_knowledge_file_and_a_home_keep_the_word_weight(tmp_path) -> None:
    """``fit_knowledge`` learns with W^w / S^w, the file keeps it, a home adapted from it (and its file)
    weighs its tokens the same."""
    import warnings

    from spco import knowledge as kn
    from spco.data import Corpus
    from spco.data.synthetic import SyntheticConfig, generate_homes

    corpus = generate_homes(3, seed=4, config=SyntheticConfig(n_features=32), new_homes=1,
                            specific_rooms=False)
    envs = list(corpus)
    knowledge = kn.fit_knowledge(Corpus(envs[:2]), n_iterations=3, random_state=0)
    expected = WORD_COUNTS / corpus.word_increment
    assert knowledge.hyperparameters.word_counts == WORD_COUNTS
    assert knowledge.channels.channels.token_weight == pytest.approx(expected)
    knowledge.save(tmp_path / "k.spco")
    loaded = kn.load_knowledge(tmp_path / "k.spco")
    assert loaded.channels.channels.token_weight == pytest.approx(expected)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        home = kn.adapt(loaded, envs[2], n_iterations=2, random_state=0)
    assert home.state.channels.token_weight == pytest.approx(expected)
    home.save(tmp_path / "h.spco")
    assert kn.load_home_model(tmp_path / "h.spco").state.channels.token_weight == pytest.approx(expected)
