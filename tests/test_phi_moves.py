"""The power target's φ^v-marginal block move (:mod:`spco.model.phi_moves`, ``block_moves="phi"``):
its acceptance ratio against brute force on a tiny problem (D = 2: φ^v of each concept integrated by
quadrature over the segment, θ^v exactly, G_e and π by their Dirichlet–multinomials written out), and
the setting's checks. That the chain with the move keeps the stated power model's posterior is
tests/test_power_target.py's enumerated-posterior test."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.special import gammaln
from scipy.stats import chi2
from test_tempered import log_integral

from spco.errors import ConfigurationError
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.phi_moves import HomeMove, home_pass, log_assignment_prior

pytestmark = pytest.mark.usefixtures("single_numba_thread")

DELTA, ALPHA, BETA = 6.0, 0.7, 1.5


def _log_w(p: np.ndarray, others: np.ndarray) -> np.ndarray:
    """ln w(φ) of the other homes' real counts (E', 2) at φ = (p, 1 − p), written out per entry."""
    out = np.zeros_like(p)
    for row in others:
        for d, n in enumerate(row):
            x = DELTA * (p if d == 0 else 1.0 - p)
            whole = np.floor(n)
            if n != whole:
                out += gammaln(x + n) - gammaln(x + whole) - (n * np.log(x) if whole == 0 else 0.0)
    return out


def _brute_evidence(pseudo: np.ndarray, others: np.ndarray, n: np.ndarray) -> float:
    """ln ∫ Beta(p; pseudo) w(p) B(δφ + n)/B(δφ) dp / ∫ Beta(p; pseudo) w(p) dp, φ = (p, 1 − p)."""
    def base(p):
        return (pseudo[0] - 1) * np.log(p) + (pseudo[1] - 1) * np.log1p(-p) + _log_w(p, others)

    def with_home(p):
        x = DELTA * np.stack([p, 1.0 - p], -1)
        h = (gammaln(x + n) - gammaln(x)).sum(-1) + gammaln(DELTA) - gammaln(DELTA + n.sum())
        return base(p) + h
    if not n.sum() > 0:
        return 0.0
    return log_integral(with_home) - log_integral(base)


def _problem(seed: int):
    rng = np.random.default_rng(seed)
    n_samples, n_concepts, n_regions = 5, 3, 2
    views = rng.integers(5, 40, size=(n_samples, 2)).astype(float)
    weights = np.minimum(1.0, 6.0 / views.sum(1))  # ω: real counts
    others = rng.integers(0, 4, size=(2, n_concepts, 2)) + np.round(rng.random((2, n_concepts, 2)), 2)
    pseudo = ALPHA + rng.integers(0, 6, size=(n_concepts, 2)) + np.round(rng.random((n_concepts, 2)), 2)
    g = rng.uniform(0.3, 3.0, n_concepts)
    regions = np.array([0, 0, 1, 1, 1])
    concepts = np.array([0, 0, 1, 1, 2])  # blocks: (0, 0) {0, 1}, (1, 1) {2, 3}, (1, 2) {4}
    word_ll = rng.normal(0.0, 2.0, size=(n_samples, n_concepts))
    return views, weights, others, pseudo, g, regions, concepts, word_ll, n_regions


def _brute_log_target(concepts, views, weights, others, pseudo, g, regions, word_ll, n_regions) -> float:
    """ln p(C_e | M_{−e}, rest) up to a constant, from the whole home's assignment."""
    n_concepts = pseudo.shape[0]
    total = 0.0
    for c in range(n_concepts):
        n = (weights[concepts == c, None] * views[concepts == c]).sum(0)
        total += _brute_evidence(pseudo[c], others[:, c], n)
    counts = np.bincount(concepts, minlength=n_concepts)
    by_region = np.zeros((n_concepts, n_regions))
    np.add.at(by_region, (concepts, regions), 1)
    total += log_assignment_prior(counts, by_region, g, BETA)
    return total + float(word_ll[np.arange(concepts.size), concepts].sum())


@pytest.mark.parametrize("seed", range(3))
def test_the_move_s_ratio_is_the_brute_force_posterior_ratio(seed: int) -> None:
    """Δ of every block to every free concept = ln p(C') − ln p(C) of the home's assignment with θ^v and
    φ^v integrated out given the other homes' real counts (and G_e, π integrated out, words given)."""
    views, weights, others, pseudo, g, regions, concepts, word_ll, n_regions = _problem(seed)
    n_e = np.zeros((3, 2))
    np.add.at(n_e, concepts, weights[:, None] * views)
    before = _brute_log_target(concepts, views, weights, others, pseudo, g, regions, word_ll, n_regions)
    checked = 0
    for members in ([0, 1], [2, 3], [4]):
        source, k = concepts[members[0]], regions[members[0]]
        for target in range(3):
            if target == source or ((regions == k) & (concepts == target)).any():
                continue
            move = HomeMove(n_e, others, pseudo, DELTA, np.bincount(concepts, minlength=3), g, BETA)
            block = (weights[members, None] * views[members]).sum(0)
            words = float(word_ll[members, target].sum() - word_ll[members, source].sum())
            got, _, _ = move.log_ratio(block, len(members), int(source), target, words)
            after = concepts.copy()
            after[members] = target
            want = _brute_log_target(after, views, weights, others, pseudo, g, regions, word_ll,
                                     n_regions) - before
            assert abs(got - want) < 2e-3, (members, target, got, want)
            checked += 1
    assert checked == 4  # {0, 1} → 1 or 2 (region 0 holds only 0); {2, 3} and {4} → 0 (region 1 holds 1, 2)


def test_a_pass_visits_the_blocks_and_keeps_them_whole() -> None:
    """A pass moves whole blocks only, to concepts free in their region, and its counts stay the home's."""
    views, weights, others, pseudo, g, regions, concepts, word_ll, n_regions = _problem(0)
    n_e = np.zeros((3, 2))
    np.add.at(n_e, concepts, weights[:, None] * views)
    seen = set()
    for seed in range(40):
        move = HomeMove(n_e, others, pseudo, DELTA, np.bincount(concepts, minlength=3), g, BETA)
        new, accepted = home_pass(move, sp.csr_array(views), weights, concepts, regions, word_ll * 0.0,
                                  n_regions, np.random.default_rng(seed))
        assert new[0] == new[1] and new[2] == new[3]
        assert len({(r, c) for r, c in zip(regions, new, strict=True)}) == 3  # no block joined another
        expect = np.zeros((3, 2))
        np.add.at(expect, new, weights[:, None] * views)
        np.testing.assert_allclose(move.n_e, expect, atol=1e-12)
        assert (move.counts == np.bincount(new, minlength=3)).all()
        assert accepted == int((new[[0, 2, 4]] != concepts[[0, 2, 4]]).sum())  # each block visited once
        seen.add(tuple(new))
    assert len(seen) > 1  # the move does move


def test_the_setting_needs_the_power_target_and_runs_in_the_joint_fit() -> None:
    """(A new home's sampler runs no block moves with it: tests/test_fit_only_settings.py.)"""
    from spco.model import gibbs
    from spco.model.transfer import SpCoTransfer

    hyper = TransferHyperparameters().with_settings(["target=power", "block_moves=phi"])
    assert hyper.block_moves == "phi"
    assert TransferHyperparameters.from_dict(hyper.to_dict()) == hyper
    with pytest.raises(ConfigurationError, match="block_moves='phi' needs target='power'"):
        TransferHyperparameters(block_moves="phi")
    assert SpCoTransfer(hyperparameters=hyper).sampler_settings().phi_moves  # the joint fit runs them
    plain = TransferHyperparameters(target="power")
    assert not SpCoTransfer(hyperparameters=plain).sampler_settings().phi_moves
    assert gibbs.SamplerSettings.create("exact", prune=True, power=True, phi_moves=True).phi_moves
    assert not gibbs.SamplerSettings.create("exact", prune=True, phi_moves=True).phi_moves  # cut target
    assert not gibbs.SamplerSettings.create("reference", prune=True, power=True, phi_moves=True).phi_moves


def test_the_schedule_runs_the_moves_on_the_sweeps_it_names_and_is_checked() -> None:
    from spco.model.phi_moves import phi_moves_due

    base = TransferHyperparameters(target="power", block_moves="phi")
    assert base.phi_every == 1 and base.phi_until is None
    assert all(phi_moves_due(i, base) for i in range(50))
    every = base.with_settings(["phi_every=5"])
    assert [i for i in range(23) if phi_moves_due(i, every)] == [0, 5, 10, 15, 20]
    first = base.with_settings(["phi_until=20"])
    assert [i for i in range(30) if phi_moves_due(i, first)] == list(range(20))
    both = base.with_settings(["phi_every=3", "phi_until=7"])
    assert [i for i in range(30) if phi_moves_due(i, both)] == [0, 3, 6]
    assert not any(phi_moves_due(i, base.with_settings(["phi_until=0"])) for i in range(10))
    assert base.with_settings(["phi_until=20", "phi_until=none"]).phi_until is None
    # written only when set: files and experiment identities from before the schedule are unchanged
    assert "phi_every" not in base.to_dict() and "phi_until" not in base.to_dict()
    assert TransferHyperparameters.from_dict(both.to_dict()) == both
    with pytest.raises(ConfigurationError, match="phi_every must be an integer >= 1"):
        base.with_settings(["phi_every=0"])
    with pytest.raises(ConfigurationError, match="phi_until must be none or an integer >= 0"):
        TransferHyperparameters(target="power", block_moves="phi", phi_until=-1)
    with pytest.raises(ConfigurationError, match="phi_every needs integer"):
        base.with_settings(["phi_every=2.5"])
    with pytest.raises(ConfigurationError, match="they need block_moves='phi'"):
        TransferHyperparameters(target="power", phi_every=5)


def _fit_digest(settings: list[str], shards: int = 1, sweeps: int = 7) -> str:
    """SHA-256 of a short synthetic fit's state, averaged parameters and log-joint trace."""
    import hashlib
    import warnings

    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.engines import LocalEngine
    from spco.model.transfer import SpCoTransfer

    corpus = generate_homes(4, seed=3, config=SyntheticConfig(n_features=32, n_train=12, language="free"),
                            new_homes=1)
    hyper = TransferHyperparameters().with_settings(settings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = SpCoTransfer(hyperparameters=hyper, n_iterations=sweeps, random_state=7,
                             record_log_joint=True).fit(corpus, engine=LocalEngine(shards))
    digest = hashlib.sha256()
    for part in (model.state_, model.parameters_):
        for name, value in sorted(vars(part).items()):
            if isinstance(value, np.ndarray):
                digest.update(name.encode() + np.ascontiguousarray(value).tobytes())
    digest.update(np.ascontiguousarray(model.log_joint_).tobytes())
    return digest.hexdigest()


def test_the_sharded_fit_runs_the_moves_on_its_schedule_the_same_for_any_workers(phi_passes) -> None:
    """``SpCoTransfer.fit`` (the experiments' fit) runs the move on the sweeps the schedule names, one
    pass each; the chain is the same for one worker and three; a schedule that never runs it
    (``phi_until=0``) leaves the power target's fit byte for byte as without the setting (the move
    draws nothing when it does not run)."""
    power = ["target=power", "visual_prior=estimate"]
    scheduled = [*power, "block_moves=phi", "phi_every=3", "phi_until=7"]
    one = _fit_digest(scheduled)
    assert len(phi_passes) == 3  # sweeps 0, 3, 6 of 7
    assert _fit_digest(scheduled, shards=3) == one
    phi_passes.clear()
    assert _fit_digest([*power, "block_moves=phi", "phi_until=0"]) == _fit_digest(power)
    assert phi_passes == []
    assert _fit_digest([*power, "block_moves=phi"]) != _fit_digest(power)
    assert len(phi_passes) == 7


# ----------------------------------------------------------------------------- the move alone

MOVE_VIEWS = np.array([[28.0, 12.0], [9.0, 31.0], [30.0, 10.0], [14.0, 26.0]])
MOVE_HOMES = np.array([0, 0, 1, 1])
MOVE_REGIONS = np.array([0, 1, 0, 1])  # each sample its own region: every block is one sample
MOVE_HYPER = TransferHyperparameters(n_concepts=2, n_regions=2, alpha_visual=1.0, delta_visual=3.0, gamma=1.5,
                                     beta=1.0, view_counts=4.0, target="power", block_moves="phi")


def _move_posterior() -> np.ndarray:
    """p(C | data) (16 assignments, index Σ_t C_t 2^(3−t)) of the power model with θ^v, φ^v, G_e (G_0
    fixed uniform) and π integrated out, every regions given: φ^v of each concept by quadrature."""
    from test_power_target import _shared_integral

    h = MOVE_HYPER
    powers = np.minimum(1.0, 4.0 / MOVE_VIEWS.sum(1))
    cache: dict = {}
    log_p = np.empty(16)
    for i, c in enumerate(itertools.product(range(2), repeat=4)):
        c = np.array(c)
        total = 0.0
        for concept in range(2):
            key = tuple(tuple((powers[(c == concept) & (MOVE_HOMES == e), None]
                               * MOVE_VIEWS[(c == concept) & (MOVE_HOMES == e)]).sum(0)) for e in range(2))
            total += _shared_integral(cache, key, h.alpha_visual, h.delta_visual)
        for e in range(2):
            mine = MOVE_HOMES == e
            by_region = np.zeros((2, 2))
            np.add.at(by_region, (c[mine], MOVE_REGIONS[mine]), 1)
            total += log_assignment_prior(by_region.sum(1), by_region, np.full(2, h.gamma / 2), h.beta)
        log_p[i] = total
    return np.exp(log_p - np.logaddexp.reduce(log_p))


def test_the_move_and_phi_s_step_alone_keep_the_posterior() -> None:
    """A chain whose assignments change only by the φ^v-marginal move (one home at random per step, the
    other homes' tables drawn given φ^v) and whose φ^v changes only by the step after it (the tables of
    the moved home added, the Metropolis–Hastings test of the real counts) — the partially collapsed
    order of :mod:`spco.model.phi_moves` with nothing else mixing — against the enumerated posterior.
    Its φ^v step starts from the previous φ^v (not an independent draw): this checks that the order
    keeps the target here."""
    from conftest import csr

    from spco.model import gibbs, sweep_statistics
    from spco.model.phi_moves import phi_after_move, phi_block_step

    h, n = MOVE_HYPER, 4
    rng = np.random.default_rng(7)
    data = gibbs.PreparedData(positions=np.zeros((n, 4)), homes=MOVE_HOMES, visual=csr(MOVE_VIEWS),
                              words=csr(np.zeros((n, 1))), n_homes=2, offsets=np.array([0, 2, 4]),
                              position_scale=1.0, map_centres=np.zeros((2, 4)))
    settings = gibbs.SamplerSettings.create("exact", prune=False, view_counts=4.0, power=True, phi_moves=True)
    state = gibbs.GibbsState(
        concepts=np.array([0, 0, 0, 0]), regions=MOVE_REGIONS.copy(), log_g=np.log(np.full((2, 2), 0.5)),
        log_g0=np.log([0.5, 0.5]), log_pi=np.log(np.full((2, 2, 2), 0.5)), means=np.zeros((2, 2, 4)),
        covariances=np.tile(np.eye(4), (2, 2, 1, 1)), log_theta_v=np.log(np.full((2, 2, 2), 0.5)),
        log_theta_w=np.zeros((2, 2, 1)), log_phi_v=np.log(np.full((2, 2), 0.5)), log_phi_w=np.zeros((2, 1)),
        word_mask=np.ones(1, dtype=bool))
    classes = []
    for i in range(15_200):
        stats = sweep_statistics.sufficient_statistics(data, state, h, settings.learning_view_counts())
        stats, moved = phi_block_step(data, state, stats, h, settings, rng)
        state.log_phi_v = phi_after_move(stats.visual, state.log_phi_v, h.delta_visual, h.alpha_visual, moved,
                                         rng)
        if i >= 200:
            classes.append(int((state.concepts * [8, 4, 2, 1]).sum()))
    exact = _move_posterior()
    # successive states are correlated (a block moves or stays): standard errors by batch means
    visits = np.eye(16)[classes].reshape(50, -1, 16).mean(axis=1)
    z = (visits.mean(axis=0) - exact) / (visits.std(axis=0, ddof=1) / np.sqrt(50))
    assert (z**2).sum() < chi2.ppf(1 - 1e-3, 15), (np.round(visits.mean(axis=0), 4), np.round(exact, 4))
