"""The passes of the power target's blocked φ^v step as a hyperparameter
(``TransferHyperparameters.phi_passes``, issue 29, branch powercost21).

- the default (4, :data:`~spco.model.hyperparameters.PHI_PASSES`) and ``phi_passes=4`` given are the
  chains of main before the setting, to the bit (the pinned hashes of ``tests/test_fast_power.py``:
  the cut, the power target, the power target from the cut's state, one worker and two);
- ``phi_passes=p`` reaches the φ^v step wherever it runs (the joint fit's driver, one worker and two,
  the single-process sweep, ``adapt``'s and a teaching's concepts the knowledge does not use): p passes,
  p + 1 evaluations of the fractional weight a step, and a different chain for p ≠ 4;
- the blocked step at 1 and 2 passes keeps the exact posterior (``tests/test_phi_block_step.py``);
- a bad value raises a ConfigurationError naming ``phi_passes``; files carry it (a file without it
  reads as 4); the cut's sweeps of a cut start run the cut's step.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
from test_cut_start import _corpus, _fit, _hash
from test_fast_power import BEFORE, SETTINGS

from spco.errors import ConfigurationError
from spco.model import gibbs, observations
from spco.model.cut_start import cut_phase
from spco.model.hyperparameters import PHI_PASSES, TransferHyperparameters
from spco.model.observations import HierarchicalMultinomial
from spco.model.transfer import SpCoTransfer

POWER = TransferHyperparameters(target="power", visual_prior="estimate")


def test_the_default_is_four_passes() -> None:
    assert PHI_PASSES == 4 and TransferHyperparameters().phi_passes == 4 and POWER.phi_passes == 4


@pytest.mark.parametrize("key", [("cut", 1), ("power", 2), ("cut_start4", 1)])
def test_four_passes_given_are_the_chains_before_to_the_bit(key: tuple[str, int]) -> None:
    setting, shards = key
    hyper = replace(SETTINGS[setting], phi_passes=4)
    assert hyper == SETTINGS[setting]
    assert _hash(_fit(hyper, shards)) == BEFORE[key]


def _recorded(monkeypatch, run) -> list[tuple[int | None, int, bool]]:
    """(passes, evaluations of the weight, any fractional concept) of every φ^v step ``run()`` makes."""
    step = HierarchicalMultinomial.accept_shared
    calls: list[tuple[int | None, int, bool]] = []

    def recording(log_weights, log_phi, prior, tables, frac, rng, fractional=True, block_size=None,
                  passes=None):
        evaluations = [0]

        def counted(phi):
            evaluations[0] += 1
            return log_weights(phi)
        result = step(counted, log_phi, prior, tables, frac, rng, fractional, block_size, passes)
        calls.append((passes, evaluations[0], bool(np.any(fractional))))
        return result

    monkeypatch.setattr(HierarchicalMultinomial, "accept_shared", staticmethod(recording))
    run()
    monkeypatch.setattr(HierarchicalMultinomial, "accept_shared", staticmethod(step))
    return calls


@pytest.mark.parametrize("shards", [1, 2])
def test_the_passes_reach_the_joint_fit_s_step(monkeypatch, shards: int) -> None:
    hyper = replace(POWER, cut_start=2, phi_passes=2)
    models = []
    calls = _recorded(monkeypatch, lambda: models.append(_fit(hyper, shards, n_iterations=6)))
    # the cut's two sweeps: the default passes and whole counts (the CRT draw, no weight evaluated);
    # then the switch's draw of the power target's parameters and its four sweeps: 2 passes, 3
    # evaluations of the weight each
    assert calls == [(4, 0, False)] * 2 + [(2, 3, True)] * 5
    assert models[0].hyperparameters_.phi_passes == 2
    four = _recorded(monkeypatch, lambda: _fit(replace(hyper, phi_passes=4), shards, n_iterations=6))
    assert four == [(4, 0, False)] * 2 + [(4, 5, True)] * 5


def test_two_passes_make_another_chain_and_the_same_for_any_number_of_workers() -> None:
    hyper = replace(POWER, cut_start=4, phi_passes=2)
    two = _hash(_fit(hyper, 1))
    assert two == _hash(_fit(hyper, 2))
    assert two not in BEFORE.values()


@pytest.mark.parametrize("phi_moves", [False, True])
def test_the_passes_reach_the_single_process_sweep(monkeypatch, phi_moves: bool) -> None:
    """:func:`spco.model.gibbs.sweep` on the two homes of ``tests/test_power_target.py``, with the φ^v
    step after a φ^v-marginal block move too (``block_moves="phi"``)."""
    from test_power_target import _chain_start

    def run(passes: int) -> None:
        data, state, hyper, settings, rng = _chain_start(True, 3, phi_moves, {"phi_passes": passes})
        hyper = replace(hyper, phi_passes=passes)
        for _ in range(3):
            gibbs.sweep(data, state, hyper, settings, rng)

    for passes in (1, 3):
        calls = _recorded(monkeypatch, lambda p=passes: run(p))
        assert len(calls) == 3 and all(c[0] == passes for c in calls)
        assert all(c[1] == passes + 1 for c in calls if c[2])  # with fractional counts: its passes
        assert any(c[2] for c in calls)


def test_the_passes_reach_adapt_and_a_teaching(monkeypatch) -> None:
    """A knowledge fitted with ``phi_passes=2`` adapts a new home with 2 passes: jointly (the home's
    sweep with the shared part learnt, every sweep) and with the shared part fixed, then teaches it
    (the φ^v of a concept the knowledge does not use: every concept made one here, by a threshold
    of G_0 above 1, so that the step runs)."""
    import spco.knowledge as kn
    from spco.data.environment import Corpus
    from spco.model import home_shard, local_update

    corpus = list(_corpus())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        knowledge = kn.fit_knowledge(Corpus(corpus[:-1]), n_iterations=6, random_state=0,
                                     hyperparameters=replace(POWER, cut_start=2, phi_passes=2))
        assert knowledge.hyperparameters.phi_passes == 2
        joint = _recorded(monkeypatch, lambda: kn.adapt(knowledge, corpus[-1], n_iterations=4,
                                                        random_state=1, joint=True))
        monkeypatch.setattr(home_shard, "FREE_CONCEPT_WEIGHT", 2.0)
        monkeypatch.setattr(local_update, "FREE_CONCEPT_WEIGHT", 2.0)
        homes = []
        fixed = _recorded(monkeypatch, lambda: homes.append(kn.adapt(knowledge, corpus[-1], n_iterations=4,
                                                                     random_state=1)))
        home = homes[0]
        taught = _recorded(monkeypatch, lambda: kn.teach(home, {int(home.ids[0]): "this is the kitchen"},
                                                         random_state=0))
    assert len(joint) == 4 and all(c[0] == 2 for c in joint) and any(c[1] == 3 for c in joint)
    assert fixed and taught and all(c[0] == 2 for c in fixed + taught)
    assert any(c[1] == 3 for c in fixed) and any(c[1] == 3 for c in taught)
    assert home.knowledge.hyperparameters.phi_passes == 2


def test_a_bad_value_names_phi_passes() -> None:
    # the checks it shares with cut_start: test_cut_start.py, test_a_power_sweep_count_…_names_itself
    with pytest.raises(ConfigurationError, match="phi_passes must be an integer >= 1"):
        POWER.with_settings(["phi_passes=0"])
    assert TransferHyperparameters(phi_passes=4) == TransferHyperparameters()  # the default: any target
    assert POWER.with_settings(["phi_passes=2"]).phi_passes == 2
    assert SpCoTransfer(replace(POWER, phi_passes=1)).checked_hyperparameters().phi_passes == 1


def test_files_carry_it_and_older_ones_read_as_four(tmp_path) -> None:
    hyper = POWER.with_settings(["phi_passes=2", "cut_start=3"])
    assert hyper.to_dict()["phi_passes"] == 2 and type(hyper.to_dict()["phi_passes"]) is int
    assert TransferHyperparameters.from_dict(hyper.to_dict()) == hyper
    assert "phi_passes" not in POWER.to_dict() and "phi_passes" not in TransferHyperparameters().to_dict()
    assert TransferHyperparameters.from_dict(POWER.to_dict()).phi_passes == 4
    assert replace(POWER, phi_passes=np.int64(3)).to_dict()["phi_passes"] == 3
    cut, _ = cut_phase(hyper, SpCoTransfer(hyper).sampler_settings())
    assert (cut.target, cut.phi_passes, cut.cut_start) == ("cut", 4, 0)


def test_the_step_runs_its_passes_and_one_weight_a_pass() -> None:
    """``accept_shared(passes=p)``: p + 1 evaluations of the weight (the start and one a pass) and p
    Dirichlet draws; the same generator gives the first pass's state whatever passes follow it."""
    rng = np.random.default_rng(3)
    n = rng.gamma(0.5, 2.0, size=(2, 3, 20))
    log_phi = np.log(rng.dirichlet(np.ones(20), size=3))
    seen = []
    for passes in (1, 2, 4):
        evaluations = []

        def weights(phi, evaluations=evaluations):
            evaluations.append(1)
            return HierarchicalMultinomial.fractional_log_weight_terms(n, phi, 2.0)
        tables, frac, fractional = HierarchicalMultinomial.table_parts(n, log_phi, 2.0,
                                                                        np.random.default_rng(9))
        out = HierarchicalMultinomial.accept_shared(weights, log_phi, 0.7, tables, frac,
                                                    np.random.default_rng(9), fractional > 0, passes=passes)
        assert len(evaluations) == passes + 1 and np.all(np.isfinite(out))
        np.testing.assert_allclose(np.exp(out).sum(-1), 1.0)
        seen.append(out)
    assert not np.array_equal(seen[0], seen[1]) and not np.array_equal(seen[1], seen[2])
    assert observations.PHI_PASSES == PHI_PASSES  # the one default, read by the step
