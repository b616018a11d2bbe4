"""The power target (``TransferHyperparameters(target="power")``): the sampler is exact for the model
docs/model.md states ("The model the sampler targets"), checked by brute force on tiny problems.

The stated model raises a view's multinomial to ω_t = min(1, w / Σ_d v_td) and a word token's
channel likelihood to s_ti = W^w n_ti (n_ti its occurrences), everywhere. The visual conditionals
(θ^v, φ^v, the label swaps' visual ratio, a chain of views alone) are checked in
``tests/test_tempered.py``; here:

(a) a token's switch given its concept: the enumerated joint Π_i p(z_i | k_i) p(k_i | z_i, l)^{s_i} of a
    sentence, marginalised to each token;
(b) the concept's word likelihood, the switches marginalised: log Σ_z Π_i p(z_i | k_i) p(k_i | z_i, l)^{s_i},
    enumerated (a word said twice counts 2 W^w);
(c) the statistics θ^w, ψ and β are drawn from: s_ti per token; the switch prior's (λ's) once;
(d) the whole chain (assignments, switches, θ^v, θ^w, φ^v, φ^w, ψ, β, λ, G_0, G_e and the label
    swaps) on two homes of two samples each: the distribution of the assignments over the sweeps
    against the posterior of the stated model with every parameter integrated out (enumerated over
    assignments and switches, numerically over φ and G_0, on the grid over λ) — and the cut sampler
    (the default: θ^v from every count, θ^w S^w per name token, the switch once) fails the same
    test, so the test sees a conditional that uses another weight.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import chisquare_p, csr
from numpy.testing import assert_allclose
from scipy.special import betaln, gammaln, logsumexp
from test_tempered import log_integral

from spco.model import gibbs
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.word_channels import (
    ALPHA_BACKGROUND,
    ALPHA_PLACE,
    BACKGROUND,
    NAME,
    PLACE,
    WordChannels,
    channel_counts,
    lambda_grid,
    mixture_log_likelihood,
    name_tokens,
    switch_probabilities,
    token_scales,
)

pytestmark = pytest.mark.usefixtures("single_numba_thread")

P_MIN = 1e-3


def _channels(rng: np.random.Generator, n_words: int, n_concepts: int, token_weight: float) -> WordChannels:
    return WordChannels(
        log_place=np.log(rng.dirichlet(np.ones(n_words), size=n_concepts)),
        log_background=np.log(rng.dirichlet(np.ones(n_words))),
        log_shares=np.concatenate([[0.0], np.log(rng.dirichlet(np.ones(2)))]),
        log_evidence=np.log(np.column_stack([p := rng.uniform(0.05, 0.95, n_words), 1 - p, 1 - p])),
        token_weight=token_weight, power=True)


def _problem(seed: int, increment: float = 50.0, word_counts: float = 3.0):
    """Three sentences of four words (some said twice), two homes, three concepts; S^w = ``increment``."""
    rng = np.random.default_rng(seed)
    occurrences = (rng.random((3, 4)) < 0.6) * rng.integers(1, 3, size=(3, 4))
    occurrences[:, 0] = np.maximum(occurrences[:, 0], 1)
    words = sp.csr_array(occurrences.astype(float) * increment)
    homes = np.array([0, 1, 1])
    log_theta = np.log(rng.dirichlet(np.ones(4), size=(2, 3)))
    return words, occurrences, homes, log_theta, _channels(rng, 4, 3, word_counts / increment)


def _token_terms(k: int, home: int, concept: int, log_theta, channels) -> np.ndarray:
    """log p(z | k) + log p(k | z, concept) per channel z, written out (3,)."""
    e = np.exp(channels.log_evidence[k])
    e = e / e.sum()
    lam = np.exp(channels.log_shares)
    split = lam[1:] * e[1:] / (lam[1:] * e[1:]).sum()
    prior = np.array([e[0], (1 - e[0]) * split[0], (1 - e[0]) * split[1]])
    like = np.array([log_theta[home, concept, k], channels.log_place[concept, k], channels.log_background[k]])
    return np.log(prior), like


def _sentence_table(t: int, occurrences, homes, concept: int, log_theta, channels, word_counts: float):
    """{switches of the sentence's tokens: log p(z, w | C = concept)} under the power likelihood."""
    ks = np.flatnonzero(occurrences[t])
    table = {}
    for zs in itertools.product(range(3), repeat=ks.size):
        total = 0.0
        for k, z in zip(ks, zs, strict=True):
            log_prior, like = _token_terms(k, homes[t], concept, log_theta, channels)
            total += log_prior[z] + word_counts * occurrences[t, k] * like[z]
        table[zs] = total
    return ks, table


@pytest.mark.parametrize("seed", range(4))
def test_switch_conditional_is_the_power_joint_marginal(seed: int) -> None:
    words, occurrences, homes, log_theta, channels = _problem(seed)
    concepts = np.random.default_rng(seed + 10).integers(0, 3, size=3)
    p = switch_probabilities(words, homes, concepts, log_theta, channels)
    j = 0
    for t in range(3):
        ks, table = _sentence_table(t, occurrences, homes, concepts[t], log_theta, channels, 3.0)
        log_norm = logsumexp(list(table.values()))
        for i in range(ks.size):
            marginal = [np.exp(logsumexp([v for zs, v in table.items() if zs[i] == z]) - log_norm)
                        for z in range(3)]
            assert_allclose(p[j], marginal, rtol=1e-9, atol=1e-300)
            j += 1
    # the cut sampler's switch (each token once) is another distribution here
    cut = switch_probabilities(words, homes, concepts, log_theta, replace(channels, power=False))
    assert np.abs(cut - p).max() > 0.05


@pytest.mark.parametrize("seed", range(4))
def test_concept_likelihood_is_the_power_sentence_marginal(seed: int) -> None:
    words, occurrences, homes, log_theta, channels = _problem(seed)
    got = mixture_log_likelihood(words, homes, log_theta, channels)
    for t in range(3):
        for concept in range(3):
            _, table = _sentence_table(t, occurrences, homes, concept, log_theta, channels, 3.0)
            assert_allclose(got[t, concept], logsumexp(list(table.values())), rtol=1e-10)


def test_statistics_count_each_token_at_its_power() -> None:
    words, occurrences, _, _, channels = _problem(5, increment=50.0, word_counts=3.0)
    rng = np.random.default_rng(1)
    switches = rng.integers(0, 3, size=words.nnz).astype(np.int8)
    concepts = np.array([2, 0, 2])
    scales = token_scales(words, channels)
    assert_allclose(scales, 3.0 * occurrences[occurrences > 0])  # s = W^w n, row-major like the CSR
    counts = channel_counts(words, concepts, switches, 3, scales)
    names = name_tokens(words, switches, channels.token_weight).toarray()
    rows, cols = np.nonzero(occurrences)
    place, background = np.zeros((3, 4)), np.zeros(4)
    by_word, expected_names = np.zeros((4, 3)), np.zeros((3, 4))
    for j, (t, k) in enumerate(zip(rows, cols, strict=True)):
        s = 3 * occurrences[t, k]
        by_word[k, switches[j]] += 1  # λ | z: the switch prior, once per token
        if switches[j] == PLACE:
            place[concepts[t], k] += s
        elif switches[j] == BACKGROUND:
            background[k] += s
        else:
            assert switches[j] == NAME
            expected_names[t, k] = s
    assert_allclose(counts.place, place)
    assert_allclose(counts.background, background)
    assert_allclose(counts.by_word, by_word)
    assert_allclose(names, expected_names)
    assert names.dtype.kind == "i"  # whole counts: φ^w's CRT tables stay exact


# ----------------------------------------------------------------------------- (d) the chain

VIEWS = np.array([[28, 12], [9, 31], [30, 10], [14, 26]])
HOMES = np.array([0, 0, 1, 1])
WORDS = np.array([0, 1, 0, 1])  # one token per sentence
INCREMENT = 20.0  # S^w
W_VIEW, W_WORD = 4.0, 2.0
EVIDENCE = np.array([0.7, 0.4])  # ν of the two words
HYPER = TransferHyperparameters(n_concepts=2, n_regions=1, alpha_visual=1.0, delta_visual=3.0,
                                alpha_word=1.0, delta_word=2.0, gamma=1.5, gamma0=1.0, beta=1.0,
                                view_counts=W_VIEW, word_counts=W_WORD, target="power")


def _log_evidence() -> np.ndarray:
    return np.log(np.column_stack([EVIDENCE, 1 - EVIDENCE, 1 - EVIDENCE]))


def _label_class(concepts: np.ndarray) -> int:
    """The assignments up to a global relabelling (the model is symmetric in the two labels): 0–7."""
    c = concepts if concepts[0] == 0 else 1 - concepts
    return int(c[1] * 4 + c[2] * 2 + c[3])


def _shared_integral(cache: dict, key: tuple, alpha: float, delta: float) -> float:
    """log ∫ Beta(φ; α, α) Π_e B(δ φ + n_e) / B(δ φ) dφ for the homes' count pairs n_e in ``key``."""
    if key not in cache:
        def f(p: np.ndarray) -> np.ndarray:
            a = delta * np.stack([p, 1.0 - p], -1)
            out = (alpha - 1) * (np.log(p) + np.log1p(-p)) - betaln(alpha, alpha)
            for n in key:
                n = np.asarray(n)
                out = out + gammaln(delta) - gammaln(delta + n.sum()) + (gammaln(a + n) - gammaln(a)).sum(-1)
            return out
        cache[key] = log_integral(f)
    return cache[key]


def exact_class_probabilities() -> np.ndarray:
    """p(assignments up to relabelling | data) of the stated model, every parameter integrated out."""
    h = HYPER
    powers = np.minimum(1.0, W_VIEW / VIEWS.sum(1))
    s = W_WORD  # each token said once: s = W^w
    e = np.exp(_log_evidence())
    e = e / e.sum(1, keepdims=True)
    grid = lambda_grid()
    caches: dict[str, dict] = {"g": {}, "v": {}, "w": {}}
    log_p = np.full(8, -np.inf)
    for c in itertools.product(range(2), repeat=4):
        c = np.array(c)
        m = tuple(tuple(np.bincount(c[HOMES == home], minlength=2)) for home in range(2))
        if m not in caches["g"]:
            def concept_prior(p: np.ndarray, m: tuple = m) -> np.ndarray:
                a = h.gamma * np.stack([p, 1.0 - p], -1)
                out = (h.gamma0 / 2 - 1) * (np.log(p) + np.log1p(-p)) - betaln(h.gamma0 / 2, h.gamma0 / 2)
                for counts in m:
                    counts = np.asarray(counts)
                    out = out + gammaln(h.gamma) - gammaln(h.gamma + counts.sum()) + (
                        gammaln(a + counts) - gammaln(a)).sum(-1)
                return out
            caches["g"][m] = log_integral(concept_prior)
        base = caches["g"][m]
        for concept in range(2):
            key = tuple(tuple((powers[(c == concept) & (HOMES == home), None]
                               * VIEWS[(c == concept) & (HOMES == home)]).sum(0)) for home in range(2))
            base += _shared_integral(caches["v"], key, h.alpha_visual, h.delta_visual)
        for z in itertools.product(range(3), repeat=4):
            z = np.array(z)
            total = base
            for concept in range(2):  # names: θ^w per home around φ^w
                key = tuple(tuple(np.bincount(WORDS[(c == concept) & (HOMES == home) & (z == NAME)],
                                              minlength=2) * s) for home in range(2))
                total += _shared_integral(caches["w"], key, h.alpha_word, h.delta_word)
                place = np.bincount(WORDS[(c == concept) & (z == PLACE)], minlength=2) * s  # ψ_l, every home
                total += (gammaln(ALPHA_PLACE + place).sum() - gammaln(2 * ALPHA_PLACE + place.sum())
                          - 2 * gammaln(ALPHA_PLACE) + gammaln(2 * ALPHA_PLACE))
            background = np.bincount(WORDS[z == BACKGROUND], minlength=2) * s
            total += (gammaln(ALPHA_BACKGROUND + background).sum() - gammaln(2 * ALPHA_BACKGROUND
                                                                             + background.sum())
                      - 2 * gammaln(ALPHA_BACKGROUND) + gammaln(2 * ALPHA_BACKGROUND))
            # the switches' prior, λ uniform on the grid
            prior = np.ones(grid.shape[0])
            for k, zi in zip(WORDS, z, strict=True):
                rest = grid * e[k, 1:]
                split = rest / rest.sum(1, keepdims=True)
                prior = prior * (e[k, 0] if zi == NAME else (1 - e[k, 0]) * split[:, zi - 1])
            total += np.log(prior.mean())
            k = _label_class(c)
            log_p[k] = np.logaddexp(log_p[k], total)
    return np.exp(log_p - logsumexp(log_p))


def _chain_start(power: bool, seed: int, phi_moves: bool = False, hyper_changes: dict | None = None):
    """The two homes' data, start state, hyperparameters, settings and generator of :func:`_run_chain`."""
    n, E, L = 4, 2, 2
    rng = np.random.default_rng(seed)
    words = np.zeros((n, 2))
    words[np.arange(n), WORDS] = INCREMENT
    data = gibbs.PreparedData(
        positions=rng.normal(size=(n, 4)) * 0.3, homes=HOMES, visual=csr(VIEWS), words=csr(words),
        n_homes=E, offsets=np.array([0, 2, 4]), position_scale=1.0, map_centres=np.zeros((E, 4)))
    hyper = HYPER if power else replace(HYPER, target="cut")
    if phi_moves:
        hyper = replace(hyper, block_moves="phi", **(hyper_changes or {}))
    settings = gibbs.SamplerSettings.create("exact", prune=True, view_counts=W_VIEW, power=power,
                                            phi_moves=phi_moves)
    channels = WordChannels.initial(EVIDENCE, L, token_weight=W_WORD / INCREMENT, power=power)
    channels = replace(channels, log_evidence=_log_evidence(), fresh=False)
    state = gibbs.GibbsState(
        concepts=np.array([0, 1, 0, 1]), regions=np.zeros(n, dtype=np.int64),
        log_g=np.log(np.full((E, L), 0.5)),
        log_g0=np.log([0.5, 0.5]), log_pi=np.zeros((E, L, 1)), means=np.zeros((E, 1, 4)),
        covariances=np.tile(np.eye(4), (E, 1, 1, 1)), log_theta_v=np.log(np.full((E, L, 2), 0.5)),
        log_theta_w=np.log(np.full((E, L, 2), 0.5)), log_phi_v=np.log(np.full((L, 2), 0.5)),
        log_phi_w=np.log(np.full((L, 2), 0.5)), word_mask=np.ones(2, dtype=bool), channels=channels,
        switches=np.zeros(n, dtype=np.int8))
    return data, state, hyper, settings, rng


def _run_chain(power: bool, n_sweeps: int, seed: int, phi_moves: bool = False) -> np.ndarray:
    """Counts of the label classes over ``n_sweeps`` sweeps (thinned by 2, after 200) of the exact
    sampler on the two homes, with label swaps on every sweep: the power target or the cut sampler;
    ``phi_moves``: with the power target's φ^v-marginal block moves (``block_moves="phi"``)."""
    data, state, hyper, settings, rng = _chain_start(power, seed, phi_moves)
    seen = np.zeros(8)
    for i in range(n_sweeps + 200):
        gibbs.sweep(data, state, hyper, settings, rng, swaps=True)
        if i >= 200 and i % 2 == 0:
            seen[_label_class(state.concepts)] += 1
    return seen


def _run_sharded_chain(n_sweeps: int, seed: int, hyper_changes: dict | None = None) -> np.ndarray:
    """:func:`_run_chain` of the power target with the φ^v-marginal block moves, run as the fits run it:
    one worker per home (:class:`~spco.model.shard_group.ShardGroup`, each home with its own generator)
    and the driver's sweep (:func:`spco.model.shard.sweep`: the driver draws the moved home and the other
    homes' tables, the home's shard runs the pass); label swaps on the fits' schedule."""
    from spco.model import shard as shards_api
    from spco.model.shard_group import ShardGroup
    from spco.model.state import SharedParameters

    data, state, hyper, settings, rng = _chain_start(True, seed, True, hyper_changes)
    homes = [shards_api.HomeShard(d, s, hyper, settings, np.random.default_rng([seed, e]), n_fit_homes=2)
             for e, (d, s) in enumerate(shards_api.split(data, state, 2))]
    groups = [ShardGroup([h], first=e) for e, h in enumerate(homes)]  # the workers, one home each

    def call(method, *args):
        return [getattr(g, method)(*args) for g in groups]

    step = shards_api.GlobalStep(hyper, settings, rng)
    shared = SharedParameters.of(state)
    seen = np.zeros(8)
    for i in range(n_sweeps + 200):
        _, shared = shards_api.sweep(call, step, shared, i, shared.word_mask, shared.name_words)
        if i >= 200 and i % 2 == 0:
            seen[_label_class(np.concatenate([h.state.concepts for h in homes]))] += 1
    return seen


def test_the_chain_targets_the_stated_power_model_and_the_cut_sampler_does_not() -> None:
    exact = exact_class_probabilities()
    seen = _run_chain(power=True, n_sweeps=8_000, seed=3)
    assert chisquare_p(seen, exact) > P_MIN, (seen / seen.sum(), exact)
    cut = _run_chain(power=False, n_sweeps=8_000, seed=3)
    assert chisquare_p(cut, exact) < 1e-6, (cut / cut.sum(), exact)


def test_the_chain_with_the_phi_marginal_block_moves_keeps_the_stated_power_model(phi_passes) -> None:
    """The power target's chain with the φ^v-marginal block moves (:mod:`spco.model.phi_moves`: the
    other homes' tables, a home's blocks moved with θ^v and φ^v integrated out, then φ^v's step with
    those tables) against the same enumerated posterior; the moves are proposed and accepted often."""
    exact = exact_class_probabilities()
    seen = _run_chain(power=True, n_sweeps=8_000, seed=4, phi_moves=True)
    assert chisquare_p(seen, exact) > P_MIN, (seen / seen.sum(), exact)
    assert len(phi_passes) == 8_200
    assert sum(phi_passes) > 500, (len(phi_passes), sum(phi_passes))


def test_the_sharded_fit_s_phi_marginal_block_moves_keep_the_stated_power_model(phi_passes) -> None:
    """The sharded fit's move (:func:`spco.model.phi_moves.sharded_phi_move`, what ``SpCoTransfer.fit``
    and the experiments run) against the same enumerated posterior, on every sweep and on a schedule
    (every 3rd sweep): exact either way; the schedule runs the pass on the sweeps it names only."""
    exact = exact_class_probabilities()
    seen = _run_sharded_chain(8_000, seed=5)
    assert chisquare_p(seen, exact) > P_MIN, (seen / seen.sum(), exact)
    assert len(phi_passes) == 8_200 and sum(phi_passes) > 500, (len(phi_passes), sum(phi_passes))
    phi_passes.clear()
    seen = _run_sharded_chain(8_000, seed=6, hyper_changes={"phi_every": 3})
    assert chisquare_p(seen, exact) > P_MIN, (seen / seen.sum(), exact)
    assert len(phi_passes) == len(range(0, 8_200, 3))


def test_the_target_is_a_checked_hyperparameter_that_files_carry() -> None:
    from spco.errors import ConfigurationError

    assert TransferHyperparameters().target == "cut"
    assert "target" not in TransferHyperparameters().to_dict()  # files from before it read the same
    power = TransferHyperparameters().with_settings(["target=power"])
    assert power.target == "power"
    assert TransferHyperparameters.from_dict(power.to_dict()) == power
    with pytest.raises(ConfigurationError, match="target must be one of"):
        TransferHyperparameters(target="exact")
    with pytest.raises(ConfigurationError, match="word_counts must be a whole number"):
        TransferHyperparameters(target="power", word_counts=2.5)
    settings = gibbs.SamplerSettings.create("exact", prune=True, view_counts=16.0, power=True)
    assert settings.learning_view_counts() == 16.0
    assert gibbs.SamplerSettings.create("exact", prune=True, view_counts=16.0).learning_view_counts() is None
    assert not gibbs.SamplerSettings.create("reference", prune=True, power=True).power
