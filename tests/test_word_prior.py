"""The word prior estimated from the homes (``word_prior="estimate"``): δ^w and α^w by the method of
moments of the homes' name-token proportions (``spco.model.word_prior``), each token weighed by the
switch's prior p(z = name | word), used from the first sweep of the chain on and carried by the
knowledge."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import fit_twice_and_adapt

from spco.errors import ConfigurationError
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.state import PreparedData
from spco.model.word_prior import estimate_word_prior, home_name_moments


def _data(words: np.ndarray, homes: np.ndarray, n_homes: int) -> PreparedData:
    n = words.shape[0]
    offsets = np.searchsorted(homes, np.arange(n_homes + 1))
    return PreparedData(positions=np.zeros((n, 4)), homes=homes, visual=sp.csr_array((n, 0), dtype=np.int64),
                        words=sp.csr_array(words), n_homes=n_homes, offsets=offsets, position_scale=1.0,
                        map_centres=np.zeros((n_homes, 4)))


def _homes(rng: np.random.Generator, delta: float, alpha: float, n_homes: int = 30, L: int = 20,
           V: int = 60, n_tokens: int = 40) -> tuple[PreparedData, np.ndarray]:
    """Homes drawn from the model: φ^w_l ~ Dir(α 1), θ^w_{e,l} ~ Dir(δ φ_l), ``n_tokens`` name tokens per
    home and concept, each a sentence of one word (S^w = 5 counts: a token is one draw whatever S^w)."""
    phi = rng.dirichlet(np.full(V, alpha), size=L)
    rows, homes, concepts = [], [], []
    for e in range(n_homes):
        for c in range(L):
            theta = rng.dirichlet(delta * phi[c] + 1e-12)
            for k in rng.choice(V, size=n_tokens, p=theta):
                row = np.zeros(V, dtype=np.int64)
                row[k] = 5
                rows.append(row)
                homes.append(e)
                concepts.append(c)
    return _data(np.array(rows), np.array(homes), n_homes), np.array(concepts)


@pytest.mark.parametrize(("delta", "alpha"), [(2.0, 0.05), (30.0, 0.3), (300.0, 1.0)])
def test_the_estimate_recovers_the_model_s_concentrations(delta: float, alpha: float) -> None:
    """Homes' names drawn at a known δ^w and α^w: the estimates land within a factor 1.5 of them (the
    tokens' own multinomial noise, 40 per home and concept, taken out of the homes' spread) and move
    with them."""
    data, concepts = _homes(np.random.default_rng(1), delta, alpha)
    m, s, q = home_name_moments(data, concepts, 20, np.ones(60))
    assert m.sum() == data.n_samples and np.allclose(s.sum(axis=-1), m)
    d_hat, a_hat = estimate_word_prior(m, s, q)
    assert d_hat is not None and a_hat is not None
    assert delta / 1.5 < d_hat < delta * 1.5, d_hat
    assert alpha / 1.5 < a_hat < alpha * 1.5, a_hat


def test_the_moments_brute_force() -> None:
    """:func:`home_name_moments` against a loop over every token of two small homes, each weighed by
    its word's name prior (a word said twice in a sentence is one token; an untaught sample none)."""
    rng = np.random.default_rng(0)
    words = rng.integers(0, 3, size=(7, 5)) * 4
    words[4] = 0  # untaught
    homes = np.array([0, 0, 0, 1, 1, 1, 1])
    concepts = np.array([1, 0, 1, 2, 2, 0, 2])
    prior = rng.random(5)
    m, s, q = home_name_moments(_data(words, homes, 2), concepts, 3, prior)
    m2, s2 = np.zeros((2, 3)), np.zeros((2, 3, 5))
    for t in range(7):
        for k in range(5):
            if words[t, k]:
                m2[homes[t], concepts[t]] += prior[k]
                s2[homes[t], concepts[t], k] += prior[k]
    np.testing.assert_allclose(m, m2)
    np.testing.assert_allclose(s, s2)
    np.testing.assert_allclose(q, m2)
    with pytest.raises(ValueError, match="name_prior"):
        home_name_moments(_data(words, homes, 2), concepts, 3, prior[:4])


def test_the_home_spread_decides() -> None:
    """Homes that name a concept alike give a large δ̂^w; homes that each name it their own way (Emma's
    room, the den, the study) a small one: a home's own names then outweigh the shared φ^w."""
    rng = np.random.default_rng(4)
    alike, _ = _homes(rng, 1000.0, 0.1, n_homes=10, L=5, V=30)
    own, concepts = _homes(rng, 0.5, 0.1, n_homes=10, L=5, V=30)
    d_alike, _ = estimate_word_prior(*home_name_moments(alike, concepts, 5, np.ones(30)))
    d_own, _ = estimate_word_prior(*home_name_moments(own, concepts, 5, np.ones(30)))
    assert d_alike is not None and d_own is not None and d_own < 2.0 < 100.0 < d_alike


def test_nothing_to_estimate_from() -> None:
    """One home (no spread between homes): no δ^w; no name token at all: neither."""
    data, concepts = _homes(np.random.default_rng(2), 10.0, 0.5, n_homes=1, L=3)
    delta, alpha = estimate_word_prior(*home_name_moments(data, concepts, 3, np.ones(60)))
    assert delta is None and alpha is not None and alpha > 0
    assert estimate_word_prior(*home_name_moments(data, concepts, 3, np.zeros(60))) == (None, None)


def test_the_setting_reads_and_is_written_only_when_estimated() -> None:
    hyper = TransferHyperparameters()
    assert hyper.word_prior == "given" and "word_prior" not in hyper.to_dict()
    estimate = hyper.with_settings(["word_prior=estimate"])
    assert TransferHyperparameters.from_dict(estimate.to_dict()).word_prior == "estimate"
    assert TransferHyperparameters.from_dict(hyper.to_dict()).word_prior == "given"  # files from before it
    with pytest.raises(ConfigurationError, match="word_prior"):
        TransferHyperparameters(word_prior="sometimes")  # type: ignore[arg-type]


def test_the_given_delta_in_the_token_s_units() -> None:
    """Where nothing estimates δ^w, the given one counts in θ^w's units: times W^w / S^w under the power
    target (the same number of a home's tokens outweigh the shared names), unchanged under the cut."""
    from spco.model.word_channels import WordChannels
    from spco.model.word_prior import given_delta_word

    power = WordChannels.initial(np.full(3, 0.5), 2, token_weight=16 / 5000, power=True)
    cut = WordChannels.initial(np.full(3, 0.5), 2, token_weight=16 / 5000, power=False)
    assert given_delta_word(1e4, power) == pytest.approx(32.0)
    assert given_delta_word(1e4, cut) == 1e4


def test_the_answers_count_a_name_token_as_the_chain_did() -> None:
    """The answers update a concept's names by a home's name tokens in θ^w's units: W^w per token
    under the power target, S^w under the cut. So the power target with δ^w in its units (× W^w / S^w)
    answers the cut's names exactly, by :func:`place_named_parameters` as by the rooms' δ."""
    from spco.model.confidence import place_named_parameters
    from spco.model.parameters import ConceptParameters
    from spco.model.word_channels import name_token_counts, rooms_concentration

    cut = TransferHyperparameters()
    power = TransferHyperparameters(target="power", delta_word=1e4 * 16 / 5000)
    assert name_token_counts(cut, 5000) == 5000 and name_token_counts(power, 5000) == 16
    assert rooms_concentration(cut, 5000) == 1e4 and rooms_concentration(power, 5000) == pytest.approx(1e4)
    rng = np.random.default_rng(3)
    L, V = 3, 6
    params = ConceptParameters(
        concept_weights=np.full((2, L), 1.0 / L), region_weights=np.full((2, L, 1), 1.0),
        region_means=np.zeros((2, 1, 4)), region_covariances=np.tile(np.eye(4), (2, 1, 1, 1)),
        word_probabilities=rng.dirichlet(np.ones(V), size=(2, L)),
        visual_probabilities=np.full((2, L, 2), 0.5),
        shared_word_probabilities=np.full((L, V), 1.0 / V), shared_visual_probabilities=np.full((L, 2), 0.5),
        global_concept_weights=np.full(L, 1.0 / L), word_mask=np.ones(V, dtype=bool),
        region_counts=np.full((2, 1), 20), concept_counts=np.full((2, L), 20.0))
    at_places, own = rng.random((L, V)), rng.random((L, V)) * 3
    a = place_named_parameters(params, 1, at_places, own, cut.delta_word, name_token_counts(cut, 5000))
    b = place_named_parameters(params, 1, at_places, own, power.delta_word, name_token_counts(power, 5000))
    np.testing.assert_allclose(a.word_probabilities, b.word_probabilities, rtol=1e-12)


@pytest.mark.parametrize("target", ["power", "cut"])
def test_the_knowledge_carries_the_estimate(target: str, tmp_path) -> None:
    """A fit of synthetic English homes with ``word_prior="estimate"``: the knowledge's δ^w and α^w are
    those the provenance records; the homes name every place alike (templates), so δ^w is the given
    one in θ^w's units (× W^w / S^w under the power target) and α^w is estimated; the same seed gives
    the same numbers; a home adapted from it keeps them."""
    import spco.knowledge as kn

    hyper = TransferHyperparameters(word_prior="estimate", target=target)  # type: ignore[arg-type]
    experienced, fits, home = fit_twice_and_adapt(hyper)
    knowledge = fits[0]
    record = knowledge.provenance["word_prior"]
    assert not record["delta_word_estimated"] and record["alpha_word_estimated"]
    got = knowledge.hyperparameters
    assert (got.delta_word, got.alpha_word) == (record["delta_word"], record["alpha_word"])
    scale = hyper.word_counts / experienced.word_increment if target == "power" else 1.0
    assert got.delta_word == pytest.approx(hyper.delta_word * scale)
    assert got.alpha_word != hyper.alpha_word
    assert fits[1].provenance["word_prior"] == record
    assert (home.hyperparameters.delta_word, home.hyperparameters.alpha_word) == (got.delta_word,
                                                                                  got.alpha_word)
    knowledge.save(tmp_path / "k.spco")  # the file keeps the numbers and the setting
    assert kn.load_knowledge(tmp_path / "k.spco").hyperparameters == got
