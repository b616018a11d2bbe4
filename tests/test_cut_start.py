"""The power target's chain started from the cut's state (``TransferHyperparameters.cut_start``,
:mod:`spco.model.cut_start`; issue 29).

- the default (the cut sampler) and ``cut_start=0`` (today's power target) are the chains of main
  0174bb6, to the bit (a short synthetic fit with the word channels, hashed; the hashes were made by
  main's code);
- with ``cut_start=k`` the first k sweeps are the cut's sweeps for the same seed (every home's
  assignments, regions, switches and parameters, one worker and two), and the sweeps from k on are the
  power target's (settings, hyperparameters, word channels, the estimated δ^v);
- started from the cut's state, the kept sweeps target the power model docs/model.md states: the
  enumerated posterior of ``tests/test_power_target.py`` on two homes of two samples each;
- a setting the fit cannot honour raises a ConfigurationError naming ``cut_start``; files carry it;
  the same seed gives the same fit with any number of workers.
"""

from __future__ import annotations

import hashlib
import warnings
from dataclasses import replace

import numpy as np
import pytest
from conftest import chisquare_p

from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.errors import ConfigurationError
from spco.model import driver
from spco.model.cut_start import check_cut_start, cut_phase, cut_sweeps
from spco.model.driver import LocalEngine
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.state import PreparedData
from spco.model.transfer import SpCoTransfer

POWER = TransferHyperparameters(target="power", visual_prior="estimate")
#: sha256 of :func:`_fit`'s assignments, regions, log joints and shared parameters, made with main
#: 0174bb6's code (before cut_start existed)
MAIN_HASHES = {
    "cut": "1091b7b419340b38e831f038a1277e65c5c94d18777008ba5f5eec5b43493305",
    "power": "5bbd7619c3c7ad7b71b0bbfce18357533696d30fee110b2a40e7983405ddbf0d",
}


def _corpus():
    return generate_homes(3, seed=4, new_homes=1, config=SyntheticConfig(n_features=64, n_train=8),
                          specific_rooms=False)


def _fit(hyper: TransferHyperparameters, shards: int = 1, n_iterations: int = 12) -> SpCoTransfer:
    """A short fit of three synthetic English homes (one new), word channels on, seed 5."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return SpCoTransfer(hyper, n_iterations=n_iterations, random_state=5, prune_words=True).fit(
            _corpus(), engine=LocalEngine(shards))


def _hash(model: SpCoTransfer) -> str:
    p = model.parameters_
    h = hashlib.sha256()
    for a in (np.concatenate(model.concepts_), np.concatenate(model.regions_), model.log_joint_,
              p.shared_visual_probabilities, p.shared_word_probabilities):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def test_the_default_and_cut_start_0_are_main_s_chains() -> None:
    cut = _fit(TransferHyperparameters())
    assert cut.word_channels_ is not None  # (the word channels' path is what the fit ran)
    assert _hash(cut) == MAIN_HASHES["cut"]
    assert _hash(_fit(replace(POWER, cut_start=0))) == MAIN_HASHES["power"]


def _recorded_sweeps(monkeypatch, hyper: TransferHyperparameters,
                     shards: int) -> tuple[list[dict], SpCoTransfer]:
    """:func:`_fit` with every sweep's joined state and the run's sampler recorded after the sweep."""
    seen: list[dict] = []
    sweep = driver.ShardedRun.sweep

    def recording(run, iteration: int) -> float:
        value = sweep(run, iteration)
        state = run.state()
        seen.append({"iteration": iteration, "concepts": state.concepts.copy(),
                     "regions": state.regions.copy(),
                     "switches": None if state.switches is None else state.switches.copy(),
                     "log_theta_v": state.log_theta_v.copy(), "log_theta_w": state.log_theta_w.copy(),
                     "log_phi_v": run.shared.log_phi_v.copy(), "log_g0": run.shared.log_g0.copy(),
                     "means": state.means.copy(), "power": run.settings.power, "target": run.hyper.target,
                     "delta_visual": run.hyper.delta_visual,
                     "channels_power": None if run.shared.channels is None else run.shared.channels.power,
                     "workers_power": [h.settings.power for s in run.shards for h in s.homes]})
        return value

    monkeypatch.setattr(driver.ShardedRun, "sweep", recording)
    model = _fit(hyper, shards)
    monkeypatch.setattr(driver.ShardedRun, "sweep", sweep)
    return seen, model


ARRAYS = ("concepts", "regions", "switches", "log_theta_v", "log_theta_w", "log_phi_v", "log_g0", "means")


@pytest.mark.parametrize("shards", [1, 2])
def test_the_first_k_sweeps_are_the_cut_s_and_the_rest_the_power_target_s(monkeypatch, shards: int) -> None:
    k = 4
    cut, _ = _recorded_sweeps(monkeypatch, TransferHyperparameters(), shards)
    started, model = _recorded_sweeps(monkeypatch, replace(POWER, cut_start=k), shards)
    power, _ = _recorded_sweeps(monkeypatch, POWER, shards)
    assert len(started) == len(cut) == 12
    for a, b in zip(cut[:k], started[:k], strict=True):
        for name in ARRAYS:
            np.testing.assert_array_equal(a[name], b[name], err_msg=f"sweep {a['iteration']}: {name}")
        assert b["target"] == "cut" and not b["power"] and b["channels_power"] is False
        assert not any(b["workers_power"]) and b["delta_visual"] == TransferHyperparameters().delta_visual
    # from sweep k on: the power target's sweeps, with the δ^v its estimate gives (on the start's
    # concepts: the cut's start, so not the number of the power target's own start)
    estimated = model.hyperparameters_.delta_visual
    assert estimated == model.hyperparameters_.delta_visual != TransferHyperparameters().delta_visual
    assert power[0]["delta_visual"] != TransferHyperparameters().delta_visual
    for b in started[k:]:
        assert b["target"] == "power" and b["power"] and b["channels_power"] is True
        assert all(b["workers_power"]) and b["delta_visual"] == estimated
    assert not np.array_equal(cut[k]["log_theta_v"], started[k]["log_theta_v"])
    assert not np.array_equal(cut[k]["log_phi_v"], started[k]["log_phi_v"])
    # the fitted model is the power target's, and says it was started from the cut's state
    assert model.hyperparameters_.target == "power" and model.hyperparameters_.cut_start == k
    assert model.settings_.power and model.word_channels_.power


def test_same_seed_same_fit_with_any_number_of_workers() -> None:
    hyper = replace(POWER, cut_start=3)
    one = _hash(_fit(hyper, 1))
    assert _hash(_fit(hyper, 1)) == one
    assert _hash(_fit(hyper, 2)) == one
    assert one not in MAIN_HASHES.values()


def test_the_word_prior_estimate_is_the_power_target_s() -> None:
    """``word_prior="estimate"`` with a cut start: the estimate is made as the power target makes it,
    in its units (these homes name alike, so δ^w is the given one times W^w / S^w, as in
    ``tests/test_word_prior.py``; α^w estimated), and the fit's hyperparameters hold it."""
    hyper = replace(POWER, word_prior="estimate")
    started = _fit(replace(hyper, cut_start=3))
    scale = hyper.word_counts / _corpus().word_increment
    assert started.hyperparameters_.delta_word == pytest.approx(hyper.delta_word * scale)
    assert started.hyperparameters_.alpha_word != hyper.alpha_word


@pytest.mark.parametrize(("field", "value", "bad", "message"), [
    ("cut_start", 10, (-1, 2.5, True, "10"), "cut_start must be a whole number"),
    ("phi_passes", 2, (0, -1, 2.5, True, "2", None), "phi_passes must be an integer >= 1"),
])
def test_a_power_sweep_count_the_fit_cannot_honour_names_itself(field: str, value: int, bad: tuple,
                                                                 message: str) -> None:
    """``cut_start`` and ``phi_passes``: a value that is not a count, or one other than the default
    without the power target (made or set with ``--set``), or a ``--set`` value that is not a
    number, is refused naming the field."""
    for v in bad:
        with pytest.raises(ConfigurationError, match=message):
            replace(POWER, **{field: v})
    with pytest.raises(ConfigurationError, match=f"{field}={value} needs target='power'"):
        TransferHyperparameters(**{field: value})
    with pytest.raises(ConfigurationError, match=f"{field}={value} needs target='power'"):
        TransferHyperparameters().with_settings([f"{field}={value}"])
    with pytest.raises(ConfigurationError, match=f"{field} needs integer"):
        POWER.with_settings([f"{field}=ten"])


def test_cut_start_must_leave_every_kept_sweep_a_power_sweep() -> None:
    # every kept sweep must be a power sweep: 12 sweeps average 9, 10, 11 (0-based)
    check_cut_start(replace(POWER, cut_start=9), [9, 10, 11])
    first_kept = r"cut_start=10 must be at most the first averaged sweep \(9"
    with pytest.raises(ConfigurationError, match=first_kept):
        check_cut_start(replace(POWER, cut_start=10), [11, 9, 10])
    with pytest.raises(ConfigurationError, match="cut_start=10 must be at most"):
        _fit(replace(POWER, cut_start=10))


def test_files_carry_the_setting_and_older_ones_read_as_0() -> None:
    hyper = POWER.with_settings(["cut_start=20"])
    assert hyper.cut_start == 20 and hyper.to_dict()["cut_start"] == 20
    assert TransferHyperparameters.from_dict(hyper.to_dict()) == hyper
    assert "cut_start" not in POWER.to_dict() and "cut_start" not in TransferHyperparameters().to_dict()
    assert TransferHyperparameters.from_dict(POWER.to_dict()).cut_start == 0
    assert cut_sweeps(hyper) == 20 and cut_sweeps(POWER) == 0
    cut, settings = cut_phase(replace(hyper, block_moves="phi", phi_every=3),
                              SpCoTransfer(hyper).sampler_settings())
    assert (cut.target, cut.visual_prior, cut.word_prior, cut.cut_start) == ("cut", "given", "given", 0)
    assert cut.block_moves == "off" and cut.phi_every == 1
    assert not settings.power and not settings.phi_moves


def test_the_knowledge_file_carries_it(tmp_path) -> None:
    import spco.knowledge as kn
    from spco.data.environment import Corpus

    experienced = Corpus(list(_corpus())[:-1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        knowledge = kn.fit_knowledge(experienced, n_iterations=8, random_state=0,
                                     hyperparameters=replace(POWER, cut_start=2))
    assert knowledge.hyperparameters.cut_start == 2 and knowledge.hyperparameters.target == "power"
    assert knowledge.hyperparameters.delta_visual != TransferHyperparameters().delta_visual
    knowledge.save(tmp_path / "k.spco")
    assert kn.load_knowledge(tmp_path / "k.spco").hyperparameters == knowledge.hyperparameters
    with pytest.raises(ConfigurationError, match="cut_start=7 must be at most"):
        kn.fit_knowledge(experienced, n_iterations=8, random_state=0,
                         hyperparameters=replace(POWER, cut_start=7))


def _sharded_run_from_cut(seed: int, k: int):
    """The two homes of ``tests/test_power_target.py`` as a :class:`~spco.model.driver.LocalRun` (one
    worker per home) whose first ``k`` sweeps are the cut sampler's and the rest the power target's:
    the driver's own sweep and switch (:meth:`~spco.model.driver.ShardedRun._start_power`)."""
    from test_power_target import _chain_start

    from spco.model import shard as shards_api
    from spco.model.shard_group import ShardGroup
    from spco.model.state import SharedParameters

    data, state, hyper, settings, rng = _chain_start(True, seed)
    hyper = replace(hyper, cut_start=k)
    cut_hyper, cut_settings = cut_phase(hyper, settings)
    state.channels = replace(state.channels, power=False)
    homes = [shards_api.HomeShard(d, s, cut_hyper, cut_settings, np.random.default_rng([seed, e]),
                                  n_fit_homes=2) for e, (d, s) in enumerate(shards_api.split(data, state, 2))]
    run = object.__new__(driver.LocalRun)
    run.shards = [ShardGroup([h], first=e) for e, h in enumerate(homes)]
    run.target_hyper, run.target_settings = hyper, settings
    run.hyper, run.settings, run.rng = cut_hyper, cut_settings, rng
    run.cut_start, run.cutting = k, True
    run.global_step = shards_api.GlobalStep(cut_hyper, cut_settings, rng)
    run.shared = SharedParameters.of(state)
    return run, homes


def test_started_from_the_cut_the_kept_sweeps_target_the_stated_power_model() -> None:
    from test_power_target import _label_class, exact_class_probabilities

    exact = exact_class_probabilities()
    run, homes = _sharded_run_from_cut(seed=7, k=100)
    seen = np.zeros(8)
    for i in range(8_000 + 200):
        run.sweep(i)
        if i < 100:
            assert not homes[0].settings.power and not run.global_step.settings.power
        if i >= 200 and i % 2 == 0:
            seen[_label_class(np.concatenate([h.state.concepts for h in homes]))] += 1
    assert run.settings.power and homes[1].state.channels.power and run.shared.channels.power
    assert chisquare_p(seen, exact) > 1e-3, (seen / seen.sum(), exact)


def _engine_chain(engine, after_sweep=None, n_sweeps: int = 12):
    """(log-joint trace, concepts, log φ^v, run) of 12 sweeps with ``cut_start=6`` started on ``engine``."""
    from spco.model import gibbs
    from spco.model.driver import start_run

    corpus = generate_homes(5, seed=2, new_homes=1, config=SyntheticConfig(n_features=64, n_train=12))
    model = SpCoTransfer(replace(POWER, cut_start=6), random_state=5, prune_words=True)
    data = PreparedData.from_corpus(corpus, 1.0)
    run = start_run(engine, data, len(corpus.vocabulary), model.checked_hyperparameters(),
                    model.sampler_settings(), np.random.default_rng(5))
    trace = run.fit(n_sweeps, None if after_sweep is None else lambda i, v: after_sweep(run, i))
    state = run.state()
    run.close()
    assert isinstance(state, gibbs.GibbsState)
    return trace, state.concepts, run.shared.log_phi_v, run


def test_ray_restarts_before_the_switch_rewind_to_the_cut(ray_session) -> None:
    """Ray, checkpoints every 5 sweeps, an actor killed after sweep 7 (the power target's from sweep 6
    on): the fit restarts at sweep 5, runs sweep 5 as the cut again, switches again before sweep 6 and
    ends where the fault-free local fit ends."""
    from spco.engines.ray import RayEngine

    local = _engine_chain(LocalEngine(2))
    killed: list[bool] = []

    def kill_once(run, iteration: int) -> None:
        if iteration == 7 and not killed:
            killed.append(True)
            ray_session.kill(run.actors[1])

    remote = _engine_chain(RayEngine(2, checkpoint_every=5), kill_once)
    assert remote[3].restarts == 1 and not remote[3].cutting and remote[3].settings.power
    for a, b in zip(local[:3], remote[:3], strict=True):
        np.testing.assert_array_equal(a, b)
