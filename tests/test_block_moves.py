"""The region block move (:mod:`spco.model.blocks`) against brute-force enumeration on tiny problems.

The target is p(C | R, θ, data) with G_e and π integrated out, written here from the model's
definition with SciPy's Dirichlet–multinomial (a sequence's probability is the pmf over its
multinomial coefficient): Σ_t f_t(C_t) + Σ_e log DM(C_e | γ G_0) + Σ_{e,l} log DM(R_{e,l} | β/K),
f_t the sample's concept log-likelihood of the one-sample conditional.

(a) the first block's draw is its exact conditional over its candidates (its concept, and every
    concept empty in its region);
(b) one pass over every block of two homes leaves the target invariant (states drawn from the
    enumerated target, one pass each, the histogram against the target), and moves;
(c) the one-sample local step with block moves uses the tempered view likelihood (the move's
    probabilities follow the view weight w).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from conftest import chisquare_p, csr
from scipy import stats
from scipy.special import gammaln, logsumexp, softmax

from spco.model import assignments, gibbs
from spco.model.blocks import region_block_step, region_blocks
from spco.model.hyperparameters import TransferHyperparameters

P_MIN = 1e-3


def log_sequence_dm(counts: np.ndarray, alpha: np.ndarray) -> float:
    """log p(a sequence with these category counts) under a Dirichlet–multinomial: SciPy's pmf of
    the counts less the log multinomial coefficient."""
    counts = np.asarray(counts, dtype=np.int64)
    n = int(counts.sum())
    if n == 0:
        return 0.0
    coefficient = gammaln(n + 1) - gammaln(counts + 1).sum()
    return float(stats.dirichlet_multinomial.logpmf(counts, alpha, n)) - coefficient


def brute_log_target(concepts: np.ndarray, homes: np.ndarray, regions: np.ndarray, concept_ll: np.ndarray,
                     g_prior: np.ndarray, beta: float, n_homes: int, n_regions: int) -> float:
    """log p(C, R | θ, data) with G_e ~ Dir(g_prior), π_{e,l} ~ Dir(β/K) integrated out, up to a
    constant."""
    n_concepts = concept_ll.shape[1]
    total = float(concept_ll[np.arange(concepts.size), concepts].sum())
    for e in range(n_homes):
        mine = homes == e
        total += log_sequence_dm(np.bincount(concepts[mine], minlength=n_concepts), g_prior)
        for c in range(n_concepts):
            cell = mine & (concepts == c)
            total += log_sequence_dm(np.bincount(regions[cell], minlength=n_regions),
                                     np.full(n_regions, beta / n_regions))
    return total


def problem(seed: int, sizes: tuple[int, ...], L: int, K: int, scale: float = 1.0) -> dict:
    rng = np.random.default_rng(seed)
    homes = np.repeat(np.arange(len(sizes)), sizes)
    return dict(homes=homes, regions=rng.integers(0, K, size=homes.size),
                concept_ll=scale * rng.normal(size=(homes.size, L)),
                g_prior=2.0 * rng.dirichlet(np.full(L, 2.0)), beta=1.5, n_homes=len(sizes), K=K, L=L)


def test_blocks_are_region_and_concept_in_order_of_lowest_sample() -> None:
    homes = np.array([0, 0, 0, 0, 1, 1])
    regions = np.array([1, 0, 1, 1, 1, 1])
    concepts = np.array([2, 2, 2, 0, 2, 2])
    block, first = region_blocks(homes, concepts, regions, 3, 2)
    assert block.tolist() == [0, 1, 0, 2, 3, 3]
    assert first.tolist() == [0, 1, 3, 4]


def test_first_block_draw_is_its_exact_conditional() -> None:
    """The block of sample 0 (region 0, concept 1: samples 0, 2, 3) moves to concept 1 (stay), 0 or
    3 — not 2, which region 0 already holds (sample 1) — with the enumerated probabilities."""
    P = problem(5, (6,), L=4, K=2)
    regions = np.array([0, 0, 0, 0, 1, 1])
    concepts = np.array([1, 2, 1, 1, 0, 1])
    args = (P["homes"], regions, P["concept_ll"], P["g_prior"], P["beta"], 1, 2)
    candidates = [1, 0, 3]
    log_p = []
    for c in candidates:
        moved = concepts.copy()
        moved[[0, 2, 3]] = c
        log_p.append(brute_log_target(moved, *args))
    probs = softmax(np.array(log_p))
    assert probs.max() < 0.9 and probs.min() > 0.02  # a non-degenerate problem
    rng = np.random.default_rng(7)
    reps = 6000
    outcome = np.empty(reps, dtype=np.int64)
    for i in range(reps):
        new = region_block_step(P["homes"], concepts, regions, P["concept_ll"], P["g_prior"], P["beta"], 1, 2,
                                rng)
        assert len(set(new[[0, 2, 3]].tolist())) == 1  # the block moves together
        assert new[0] != 2
        outcome[i] = candidates.index(int(new[0]))
    assert chisquare_p(np.bincount(outcome, minlength=3), probs) > P_MIN


@pytest.mark.parametrize("seed", [11, 12])
def test_one_pass_leaves_the_collapsed_target_invariant(seed: int) -> None:
    """Two homes of 3 samples, 3 concepts, 2 regions: all 3^6 assignments enumerated; states drawn
    from the target, one pass of block moves each, the results' histogram is the target."""
    P = problem(seed, (3, 3), L=3, K=2)
    homes, regions, ll = P["homes"], P["regions"], P["concept_ll"]
    configs = np.array(list(itertools.product(range(3), repeat=homes.size)))
    log_target = np.array([brute_log_target(c, homes, regions, ll, P["g_prior"], P["beta"], 2, 2)
                           for c in configs])
    probs = np.exp(log_target - logsumexp(log_target))
    rng = np.random.default_rng(seed + 100)
    reps = 12000
    start = rng.choice(configs.shape[0], size=reps, p=probs)
    radix = 3 ** np.arange(homes.size)[::-1]
    end = np.empty(reps, dtype=np.int64)
    for i, s in enumerate(start):
        new = region_block_step(homes, configs[s], regions, ll, P["g_prior"], P["beta"], 2, 2, rng)
        end[i] = int(new @ radix)
    assert (end != start).mean() > 0.2  # it moves
    assert chisquare_p(np.bincount(end, minlength=configs.shape[0]), probs) > P_MIN


def test_peaked_likelihoods_stay_exact() -> None:
    """Hundreds of nats between concepts (a room's tempered views): the draw is still the exact
    conditional (log-sum-exp), never NaN."""
    P = problem(9, (4,), L=3, K=1, scale=1.0)
    regions = np.zeros(4, dtype=np.int64)
    concepts = np.zeros(4, dtype=np.int64)
    ll = np.zeros((4, 3))
    ll[:, 1] = 300.0
    ll[:, 2] = 300.0 + np.log(3.0) / 4  # the block: concept 2 three times as likely as 1 (times the priors)
    rng = np.random.default_rng(3)
    log_p = []
    for c in range(3):
        log_p.append(brute_log_target(np.full(4, c), P["homes"], regions, ll, P["g_prior"], P["beta"], 1, 1))
    probs = softmax(np.array(log_p))
    step = (P["homes"], concepts, regions, ll, P["g_prior"], P["beta"], 1, 1)
    outcome = [int(region_block_step(*step, rng)[0]) for _ in range(4000)]
    assert chisquare_p(np.bincount(outcome, minlength=3), probs) > P_MIN


def test_local_step_moves_blocks_with_the_tempered_view_likelihood() -> None:
    """Through the sampler: with block moves on, the local step's one-sample draw is followed by a
    block pass whose likelihood is the one-sample conditional's (views tempered to w). A home whose
    4 samples share one region, where π and G_e make a one-sample move to concept 1 nearly
    impossible, still reaches concept 1 as a block with the probability the tempered views give."""
    from spco.model.state import GibbsState, PreparedData

    L, K = 2, 1
    visual = np.array([[40, 10, 0]] * 4)
    positions = np.zeros((4, 4))
    data = PreparedData(positions=positions, homes=np.zeros(4, dtype=np.int64), visual=csr(visual),
                        words=csr(np.zeros((4, 2))), n_homes=1, offsets=np.array([0, 4]), position_scale=1.0,
                        map_centres=np.zeros((1, 4)))
    theta_v = np.log(np.array([[[0.5, 0.25, 0.25], [0.6, 0.2, 0.2]]]))
    hyper = TransferHyperparameters(n_concepts=L, n_regions=K, gamma=1.0, beta=1.0)
    w = 4.0
    settings = gibbs.SamplerSettings.create("exact", prune=False, view_counts=w, block_moves=True)
    rng = np.random.default_rng(2)
    log_g0 = np.log(np.array([0.5, 0.5]))
    hits = 0
    reps = 3000
    for _ in range(reps):
        state = GibbsState(
            concepts=np.zeros(4, dtype=np.int64), regions=np.zeros(4, dtype=np.int64),
            log_g=np.log(np.array([[1 - 1e-12, 1e-12]])), log_g0=log_g0, log_pi=np.zeros((1, L, K)),
            means=np.zeros((1, K, 4)), covariances=np.eye(4)[None, None].repeat(K, axis=1),
            log_theta_v=theta_v, log_theta_w=np.log(np.full((1, L, 2), 0.5)),
            log_phi_v=theta_v[0], log_phi_w=np.log(np.full((L, 2), 0.5)), word_mask=np.ones(2, dtype=bool))
        assignments.local_step(data, state, settings, rng, hyper)
        assert len(set(state.concepts.tolist())) == 1  # G_{e,1} = 1e-12: only the block move reaches 1
        hits += int(state.concepts[0] == 1)
    # the block's conditional: 4 views, each worth w of its 50 counts, G_e ~ Dir(γ G_0) integrated out
    omega = w / 50.0
    view = omega * (visual[0] @ theta_v[0].T)  # (L,)
    g = hyper.gamma * np.exp(log_g0)
    log_p = 4 * view + gammaln(g + 4) - gammaln(g)
    p = softmax(log_p)[1]
    assert 0.05 < p < 0.95
    assert softmax(log_p + 4 * (1 / omega - 1) * view)[1] > 0.9999  # every count a draw: a certain move
    z = (hits / reps - p) / np.sqrt(p * (1 - p) / reps)
    assert abs(z) < 4.0, (hits / reps, p)


def test_block_moves_setting_where_it_runs_and_how_it_is_written() -> None:
    """``block_moves``: "off" (default, left out of the written dictionary so files and experiment
    identities from before are unchanged), "adapt" (a new home's sampler), "all" (the joint fit too);
    anything else refused."""
    from spco.errors import ConfigurationError
    from spco.model.transfer import SpCoTransfer

    default = TransferHyperparameters()
    assert default.block_moves == "off" and "block_moves" not in default.to_dict()
    every = default.with_settings(["block_moves=all"])
    assert every.to_dict()["block_moves"] == "all"
    assert TransferHyperparameters.from_dict(every.to_dict()) == every
    assert TransferHyperparameters.from_dict(default.with_settings(["block_moves=adapt"]).to_dict()
                                             ).block_moves == "adapt"
    assert TransferHyperparameters.from_dict(default.to_dict()).block_moves == "off"
    with pytest.raises(ConfigurationError, match="block_moves"):
        default.with_settings(["block_moves=sometimes"])
    assert not SpCoTransfer(hyperparameters=default).sampler_settings().block_moves
    assert SpCoTransfer(hyperparameters=every).sampler_settings().block_moves
    assert not gibbs.SamplerSettings.create("reference", prune=False, block_moves=True).block_moves
