"""The place channel's home level (``place_channel="home"``, :mod:`spco.model.home_place`): every
conditional against brute force on tiny problems.

(a) the switch of each token and the concept's word likelihood read the home's ψ_{e,l}: enumeration
    of the joint p(z, w | C) of a sentence with ψ_{e,l} in place of ψ_l (cut and power);
(b) ψ_{e,l} | ψ_l, tokens ~ Dir(δ^p ψ_l + n_{e,l}): the draws' moments against quadrature of the
    conditional density (V = 2);
(c) ψ_l | the homes' tokens, ψ_{e,l} integrated out: the CRT-table chain's ψ_l against quadrature of
    Dir(ψ_l | α^p) Π_e DM(n_e | δ^p ψ_l) (V = 2);
(d) the label swap's place term: Dirichlet–multinomials by quadrature, and the swap's acceptance rate;
(e) the hyperparameters (validation naming the field, written only when not the default, ``--set``);
(f) a sharded fit with the setting: each home holds its own ψ_{e,l}, the shards send tables, the
    same seed gives the same result.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import random_word_channels
from numpy.testing import assert_allclose
from scipy import integrate
from scipy.special import logsumexp

from spco.errors import ConfigurationError
from spco.model import moves
from spco.model.home_place import (
    draw_home_place,
    home_place_counts,
    log_dirichlet_multinomial,
    place_tables,
    swap_place_terms,
)
from spco.model.hyperparameters import DELTA_PLACE, TransferHyperparameters
from spco.model.word_channels import PLACE, channel_counts, mixture_log_likelihood, switch_probabilities


def _problem(seed: int, n_samples: int = 4, n_words: int = 4, n_concepts: int = 3, n_homes: int = 2):
    rng = np.random.default_rng(seed)
    dense = (rng.random((n_samples, n_words)) < 0.6).astype(float)
    dense[:, 0] = 1.0
    words = sp.csr_array(dense)
    homes = np.arange(n_samples) % n_homes
    log_theta = np.log(rng.dirichlet(np.ones(n_words), size=(n_homes, n_concepts)))
    channels = random_word_channels(rng, n_words, n_concepts)
    home_psi = np.log(rng.dirichlet(np.ones(n_words), size=(n_homes, n_concepts)))
    return words, homes, log_theta, replace(channels, log_place_home=home_psi)


def _token_joint(k: int, z: int, home: int, concept: int, log_theta, channels) -> float:
    """log p(z, w = k | C = concept) of one token of ``home``, written out with ψ_{e,l}."""
    prior = np.exp(channels.log_prior()[k])
    like = (np.exp(log_theta[home, concept, k]), np.exp(channels.log_place_home[home, concept, k]),
            np.exp(channels.log_background[k]))[z]
    return float(np.log(prior[z] * like))


@pytest.mark.parametrize("seed", range(4))
def test_switch_and_concept_read_the_homes_place_words(seed: int) -> None:
    words, homes, log_theta, channels = _problem(seed)
    concepts = np.random.default_rng(seed + 50).integers(0, 3, size=words.shape[0])
    p = switch_probabilities(words, homes, concepts, log_theta, channels)
    got = mixture_log_likelihood(words, homes, log_theta, channels)
    dense = words.toarray()
    j = 0
    for t in range(words.shape[0]):
        ks = np.flatnonzero(dense[t])
        table = {zs: sum(_token_joint(k, z, homes[t], concepts[t], log_theta, channels)
                         for k, z in zip(ks, zs, strict=True))
                 for zs in itertools.product(range(3), repeat=ks.size)}
        norm = logsumexp(list(table.values()))
        for i in range(ks.size):
            marginal = [np.exp(logsumexp([v for zs, v in table.items() if zs[i] == z]) - norm)
                        for z in range(3)]
            assert_allclose(p[j], marginal, rtol=1e-10)
            j += 1
        for concept in range(3):
            marginal = logsumexp([sum(_token_joint(k, z, homes[t], concept, log_theta, channels)
                                      for k, z in zip(ks, zs, strict=True))
                                  for zs in itertools.product(range(3), repeat=ks.size)])
            assert_allclose(got[t, concept], marginal, rtol=1e-10)
    # a home's ψ_{e,l} changes the answer: not read from ψ_l
    shared = replace(channels, log_place_home=None)
    assert not np.allclose(switch_probabilities(words, homes, concepts, log_theta, shared), p)
    # one row of ψ_{e,l} serves every home (a shard of one home); ψ_l itself as that row: as without it
    one = replace(channels, log_place_home=channels.log_place[None].copy())
    assert_allclose(switch_probabilities(words, homes, concepts, log_theta, one),
                    switch_probabilities(words, homes, concepts, log_theta, shared), rtol=0, atol=0)


def test_power_target_reads_the_homes_place_words() -> None:
    """Under the power target each token's channel likelihood is raised to s_ti, with ψ_{e,l}."""
    words, homes, log_theta, channels = _problem(3)
    channels = replace(channels, power=True, token_weight=2.0)
    concepts = np.array([0, 1, 2, 1])
    p = switch_probabilities(words, homes, concepts, log_theta, channels)
    got = mixture_log_likelihood(words, homes, log_theta, channels)
    rows = np.repeat(np.arange(words.shape[0]), np.diff(words.indptr))
    for j, (t, k) in enumerate(zip(rows, words.indices, strict=True)):
        e = homes[t]
        likes = np.array([log_theta[e, :, k], channels.log_place_home[e, :, k],
                          np.full(3, channels.log_background[k])])  # (3, L)
        logits = channels.log_prior()[k][:, None] + 2.0 * likes
        assert_allclose(p[j], np.exp(logits[:, concepts[t]] - logsumexp(logits[:, concepts[t]])), rtol=1e-10)
    expected = np.zeros((words.shape[0], 3))
    for t, k in zip(rows, words.indices, strict=True):
        e = homes[t]
        likes = np.array([log_theta[e, :, k], channels.log_place_home[e, :, k],
                          np.full(3, channels.log_background[k])])
        expected[t] += logsumexp(channels.log_prior()[k][:, None] + 2.0 * likes, axis=0)
    assert_allclose(got, expected, rtol=1e-10)


def _beta_moments(a: float, b: float) -> tuple[float, float]:
    """Mean and variance of x ∝ x^(a−1) (1−x)^(b−1) by quadrature (the brute force)."""
    dens = lambda x: np.exp((a - 1) * np.log(x) + (b - 1) * np.log1p(-x))  # noqa: E731
    z = integrate.quad(dens, 0, 1, limit=200)[0]
    m = integrate.quad(lambda x: x * dens(x), 0, 1, limit=200)[0] / z
    m2 = integrate.quad(lambda x: x * x * dens(x), 0, 1, limit=200)[0] / z
    return m, m2 - m * m


def test_home_place_words_given_the_shared_and_the_tokens() -> None:
    """ψ_{e,l} | ψ_l, n ~ Dir(δ^p ψ_l + n_{e,l}): moments of the draws against quadrature (V = 2)."""
    rng = np.random.default_rng(0)
    psi = np.array([[0.3, 0.7], [0.8, 0.2]])
    channels = random_word_channels(rng, 2, 2)
    channels = replace(channels, log_place=np.log(psi))
    counts = np.array([[[4, 1], [0, 0]], [[0, 6], [2, 3]]])  # (E, L, V)
    delta = 3.0
    draws = np.array([np.exp(draw_home_place(channels, counts, delta, rng).log_place_home)
                      for _ in range(6000)])  # (S, E, L, V)
    for e, c in itertools.product(range(2), range(2)):
        a = delta * psi[c] + counts[e, c]
        mean, var = _beta_moments(a[0], a[1])
        x = draws[:, e, c, 0]
        assert abs(x.mean() - mean) < 4.5 * np.sqrt(var / x.size)
        assert abs(x.var() - var) < 0.15 * var
    # only the homes asked for are redrawn; the others keep theirs
    first = draw_home_place(channels, counts, delta, rng)
    again = draw_home_place(first, counts, delta, rng, homes=np.array([1]))
    assert_allclose(again.log_place_home[0], first.log_place_home[0], rtol=0, atol=0)
    assert not np.allclose(again.log_place_home[1], first.log_place_home[1])


def test_shared_place_words_by_tables_with_the_homes_integrated_out() -> None:
    """The chain t ~ CRT(n_e, δ^p ψ_l), ψ_l ~ Dir(α^p + Σ_e t_e) keeps p(ψ_l | n) ∝ Dir(ψ_l | α^p)
    Π_e DM(n_e | δ^p ψ_l): its ψ_l against quadrature of that density (V = 2, three homes)."""
    from spco.model.kernels.dirichlet import log_dirichlet

    rng = np.random.default_rng(1)
    alpha, delta = 0.5, 2.0
    counts = np.array([[[5, 0]], [[1, 3]], [[0, 2]]], dtype=np.int64)  # (E, 1, V): three homes, one concept

    def log_post(x: float) -> float:
        conc = delta * np.array([x, 1 - x])
        return float((alpha - 1) * (np.log(x) + np.log1p(-x))
                     + log_dirichlet_multinomial(counts[:, 0], conc).sum())

    z = integrate.quad(lambda x: np.exp(log_post(x)), 0, 1, limit=200)[0]
    mean = integrate.quad(lambda x: x * np.exp(log_post(x)), 0, 1, limit=200)[0] / z
    below = integrate.quad(lambda x: np.exp(log_post(x)), 0, 0.5, limit=200)[0] / z
    log_psi = np.log(np.array([[0.5, 0.5]]))
    xs = []
    for step in range(24000):
        tables = place_tables(counts, log_psi, delta, rng)
        log_psi = log_dirichlet(alpha + tables.astype(np.float64), rng)
        if step >= 1000:
            xs.append(np.exp(log_psi[0, 0]))
    xs = np.array(xs)
    batches = xs.reshape(46, -1).mean(axis=1)  # batch means: the chain's autocorrelation
    se = batches.std(ddof=1) / np.sqrt(batches.size)
    assert abs(xs.mean() - mean) < 4.0 * se + 1e-3, (xs.mean(), mean, se)
    share = (xs < 0.5).reshape(46, -1).mean(axis=1)
    assert abs(share.mean() - below) < 4.0 * share.std(ddof=1) / np.sqrt(share.size) + 1e-3
    # a wrong step (the homes' counts pooled, as with one ψ for every home) is told apart
    pooled = (alpha + counts.sum(axis=0)[0]).astype(np.float64)
    assert abs(pooled[0] / pooled.sum() - mean) > 8.0 * se


def _dm_by_quadrature(n: np.ndarray, a: np.ndarray) -> float:
    """log ∫ x^n0 (1−x)^n1 Beta(x | a0, a1) dx (V = 2)."""
    from scipy.special import betaln

    value = integrate.quad(lambda x: np.exp(n[0] * np.log(x) + n[1] * np.log1p(-x)
                                            + (a[0] - 1) * np.log(x) + (a[1] - 1) * np.log1p(-x)
                                            - betaln(a[0], a[1])), 0, 1, limit=200)[0]
    return float(np.log(value))


def test_label_swap_integrates_the_homes_place_words() -> None:
    """The swap's place term is the change of Σ_l log DM(n_{e,l} | δ^p ψ_l), each DM by quadrature; and
    the swap is accepted at the rate min(1, e^Δ) when nothing else tells the labels apart."""
    counts = np.array([[[3, 1], [0, 2]]], dtype=np.int64)  # (E, L, V)
    psi = np.array([[0.6, 0.4], [0.45, 0.55]])
    delta = 2.5
    pairs = np.array([[[0, 1]]])
    a = delta * psi
    expected = (_dm_by_quadrature(counts[0, 0], a[1]) + _dm_by_quadrature(counts[0, 1], a[0])
                - _dm_by_quadrature(counts[0, 0], a[0]) - _dm_by_quadrature(counts[0, 1], a[1]))
    got = swap_place_terms(counts, np.log(psi), delta, pairs)
    assert got.shape == (1, 1)
    assert_allclose(got[0, 0], expected, atol=1e-8)
    assert expected < 0  # the labels as they are fit the tokens better
    # the acceptance rate of concept_swap_step, everything else uninformative
    rng = np.random.default_rng(3)
    E, L, D, V = 1, 2, 3, 2
    visual = np.zeros((E, L, D), dtype=np.int64)
    visual[0, :, 0] = 10
    words = np.zeros((E, L, V), dtype=np.int64)
    log_phi_v, log_phi_w = np.log(np.full((L, D), 1 / D)), np.log(np.full((L, V), 1 / V))
    log_g, log_g0 = np.log(np.full((E, L), 0.5)), np.log(np.full(L, 0.5))
    mask = np.ones(V, dtype=bool)
    taken = np.mean([moves.concept_swap_step(visual, log_phi_v, 1.0, words, log_phi_w, 1.0, log_g, log_g0,
                                             1.0, mask, rng,
                                             place_home=(counts, np.log(psi), delta))[0, 0] == 1
                     for _ in range(4000)])
    rate = np.exp(expected)
    assert abs(taken - rate) < 4.5 * np.sqrt(rate * (1 - rate) / 4000)


def test_home_place_counts_add_up_to_the_channel_counts() -> None:
    words, homes, _, _ = _problem(5, n_samples=6)
    rng = np.random.default_rng(5)
    concepts = rng.integers(0, 3, size=6)
    switches = rng.integers(0, 3, size=words.nnz).astype(np.int8)
    by_home = home_place_counts(words, homes, concepts, switches, 2, 3)
    assert_allclose(by_home.sum(axis=0), channel_counts(words, concepts, switches, 3).place)
    scales = np.full(words.nnz, 4.0)
    assert_allclose(home_place_counts(words, homes, concepts, switches, 2, 3, scales), 4 * by_home)
    assert by_home.sum() == int((switches == PLACE).sum())


def test_dirichlet_multinomial_by_quadrature() -> None:
    for n, a in ((np.array([0, 0]), np.array([0.3, 2.0])), (np.array([4, 1]), np.array([0.05, 1.5])),
                 (np.array([2, 7]), np.array([3.0, 0.2]))):
        assert_allclose(log_dirichlet_multinomial(n, a), _dm_by_quadrature(n, a), atol=1e-7)


def test_hyperparameters_of_the_place_channel() -> None:
    default = TransferHyperparameters()
    assert default.place_channel == "shared" and default.delta_place == DELTA_PLACE
    assert "place_channel" not in default.to_dict() and "delta_place" not in default.to_dict()
    home = default.with_settings(["place_channel=home", "delta_place=4"])
    assert home.place_channel == "home" and home.delta_place == 4.0
    assert home.to_dict()["place_channel"] == "home" and home.to_dict()["delta_place"] == 4.0
    assert TransferHyperparameters.from_dict(home.to_dict()) == home
    assert TransferHyperparameters.from_dict(default.to_dict()) == default
    with pytest.raises(ConfigurationError, match="place_channel"):
        default.with_settings(["place_channel=homes"])
    with pytest.raises(ConfigurationError, match="delta_place"):
        default.with_settings(["delta_place=0"])
    with pytest.raises(ConfigurationError, match="delta_place"):
        TransferHyperparameters(delta_place=float("nan"))


def test_a_sharded_fit_holds_each_homes_place_words() -> None:
    """A fit with the setting through the shards (``spco fit``'s driver): the homes draw their own
    ψ_{e,l} around ψ_l, the shards send tables (never more than the tokens), the same seed gives the
    same knowledge, and a new home adapted from it draws its own around the knowledge's ψ_l."""
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.knowledge.fit import fit_knowledge
    from spco.model.driver import ShardedRun  # noqa: F401  (the driver the fit runs)

    corpus = generate_homes(4, seed=1, new_homes=1, specific_rooms=False,
                            config=SyntheticConfig(n_features=32, language="free"))
    hyper = TransferHyperparameters().with_settings(["place_channel=home"])
    first = fit_knowledge(corpus, n_iterations=6, random_state=2, hyperparameters=hyper)
    again = fit_knowledge(corpus, n_iterations=6, random_state=2, hyperparameters=hyper)
    assert first.hyperparameters.place_channel == "home"
    assert_allclose(first.channels.channels.log_place, again.channels.channels.log_place, rtol=0, atol=0)
    assert_allclose(first.log_phi_words, again.log_phi_words, rtol=0, atol=0)
    assert first.channels.channels.log_place_home is None  # the knowledge keeps the shared part
    plain = fit_knowledge(corpus, n_iterations=6, random_state=2)
    assert (plain.channels.channels.log_place.shape != first.channels.channels.log_place.shape
            or not np.allclose(plain.channels.channels.log_place, first.channels.channels.log_place))


def test_the_single_process_sampler_holds_each_homes_place_words() -> None:
    """:class:`~spco.model.SpCoTransfer` with the setting: ψ_{e,l} of every home (E, L, V), drawn
    around ψ_l, different between homes; the tables a home sends never exceed its place tokens."""
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.model import SpCoTransfer

    corpus = generate_homes(4, seed=1, new_homes=1, specific_rooms=False,
                            config=SyntheticConfig(n_features=32, language="free"))
    hyper = TransferHyperparameters().with_settings(["place_channel=home"])
    model = SpCoTransfer(hyper, n_iterations=6, random_state=0, prune_words=True).fit(corpus)
    state, data = model.state_, model.data_
    home_psi = state.channels.log_place_home
    assert home_psi is not None and home_psi.shape == (data.n_homes, *state.channels.log_place.shape)
    assert_allclose(np.exp(home_psi).sum(axis=-1), 1.0, atol=1e-9)
    assert not np.allclose(home_psi[0], home_psi[1])
    switches = np.random.default_rng(0).integers(0, 3, size=data.words.nnz).astype(np.int8)
    counts = home_place_counts(data.words, data.homes, state.concepts, switches, data.n_homes,
                               home_psi.shape[1])
    tables = place_tables(counts, state.channels.log_place, 10.0, np.random.default_rng(1))
    assert (tables <= counts.sum(axis=0)).all() and (tables >= (counts > 0).sum(axis=0)).all()


def test_a_new_home_draws_its_own_place_words_around_the_knowledge() -> None:
    """``adapt`` (one home's shard, the shared part fixed): the new home's state holds its own ψ_{e,l}
    (one row), drawn around the knowledge's ψ_l; both adapt modes run with the setting."""
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.knowledge.adapting import adapt
    from spco.knowledge.fit import fit_knowledge

    corpus = generate_homes(4, seed=1, new_homes=1, specific_rooms=False,
                            config=SyntheticConfig(n_features=32, language="free"))
    hyper = TransferHyperparameters().with_settings(["place_channel=home"])
    knowledge = fit_knowledge(corpus, n_iterations=6, random_state=2, hyperparameters=hyper)
    env = list(corpus)[-1]
    for joint in (False, True):
        home = adapt(knowledge, env, n_iterations=3, random_state=0, joint=joint)
        channels = home.state.channels
        assert channels is not None and channels.log_place_home is not None
        assert channels.log_place_home.shape == (1, *channels.log_place.shape)
        assert_allclose(np.exp(channels.log_place_home).sum(axis=-1), 1.0, atol=1e-9)
        assert not np.allclose(channels.log_place_home[0], channels.log_place)
