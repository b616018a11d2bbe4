"""The power target's CPU (issue 29, branch powercost21): speedups that leave every draw the same.

- the blocked φ^v step (:meth:`HierarchicalMultinomial.accept_shared`, its columns gathered by
  ``np.take`` when every concept moves) draws what it drew before, and leaves the generator where it
  left it, with every concept moving and with some, at 1, 2 and 4 passes;
- φ^v's fractional weight from the counts' fractional entries gathered once
  (:class:`spco.model.kernels.fractional.FractionalCounts`) is, bit for bit at every φ, the one-group
  kernel of branch cutstart20 011610d (``tests/test_fast_power.py``'s reference) summed over the groups;
- a worker gathers its homes' fractional counts once a sweep (once per statistics) and every
  evaluation of the φ^v step reads them; a new sweep's statistics are gathered again;
- short fits — the sharded fit (one worker and two: the grouped and the one-home path), the
  single-process sweep with and without the φ^v-marginal block move, the joint adapt — are the
  chains of this branch before the speedups (1c555fa), to the bit (hashes made with that code).
"""

from __future__ import annotations

import hashlib
import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
from test_cut_start import _corpus, _fit, _hash
from test_fast_power import _before_summed, _counts

from spco.model import gibbs
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.kernels import fractional
from spco.model.kernels.fractional import FractionalCounts
from spco.model.observations import HierarchicalMultinomial

POWER = TransferHyperparameters(target="power", visual_prior="estimate")

#: sha256 of the chains below, made with this branch's code before the speedups (1c555fa)
BEFORE = {
    "fit 1": "99aacefa922a3531cc7fdb541c8a84d3c29d5f8e121ef3af89dc9dccd2c62b77",
    "fit 2": "99aacefa922a3531cc7fdb541c8a84d3c29d5f8e121ef3af89dc9dccd2c62b77",
    "fit 2 passes 2": "2f6b83abcbd15ffed9d3a737953b5fa87d3db01ec2b2d0bd877b6225508df1a3",
    "sweep": "9e0b32ee356aedb6eae55462c0e11121f7749547e63387249db4eb9c711d0199",
    "sweep phi": "dc14ad3bff1e59308ae80006c5573a0575e60ae011185f3ede8a134e082ffe57",
    "adapt": "60ef771c77c219d1a477abef0610294b758e96ddd1af30fc91adf45496363a3d",
    "steps": "e7b4cd9965b4ea550a17bb84ce9e2eb74d211d28a5d49950292d4a12d167805f",
}


def test_gathered_counts_weigh_as_before_at_every_phi() -> None:
    rng = np.random.default_rng(5)
    groups = [_counts(rng, s, 6, 41) for s in (2, 1, 3)]
    groups[1][0, 4, 7] = 3.5  # a whole part and a fraction
    gathered = FractionalCounts(groups)
    assert gathered.n_fractional == sum(int((n != np.floor(n)).sum()) for n in groups)
    for delta in (0.05, 3.0, 5e4):
        for _ in range(3):
            log_phi = np.log(rng.dirichlet(np.full(41, 0.3), size=6))
            log_phi[3, 4] = -np.inf  # a underflows where a home's count may be fractional
            groups_with = [n.copy() for n in groups]
            groups_with[0][0, 3, 4] = 0.5
            expected = _before_summed(groups_with, log_phi, delta)
            got = FractionalCounts(groups_with).log_weights(log_phi, delta)
            assert got.tobytes() == expected.tobytes()
            assert got[3, 4] == -math.inf
            again = _before_summed(groups, log_phi, delta)
            assert gathered.log_weights(log_phi, delta).tobytes() == again.tobytes()
    with pytest.raises(ValueError, match="shape"):
        FractionalCounts([np.zeros((1, 2, 3)), np.zeros((1, 2, 4))])
    with pytest.raises(ValueError, match="shape"):
        gathered.log_weights(np.zeros((6, 40)), 1.0)


def test_a_worker_gathers_once_a_sweep(monkeypatch) -> None:
    made = []
    gather = fractional._gather_fractional

    def counting(n, home_group):
        made.append(len(np.unique(home_group)))
        return gather(n, home_group)

    monkeypatch.setattr(fractional, "_gather_fractional", counting)
    evaluations = []
    weights = FractionalCounts.log_weights

    def evaluated(self, log_phi, delta):
        evaluations.append(1)
        return weights(self, log_phi, delta)

    monkeypatch.setattr(FractionalCounts, "log_weights", evaluated)
    _fit(replace(POWER, cut_start=2), 1, n_iterations=6)
    # one worker of 3 homes: the switch's φ^v step and 4 power sweeps', each gathering once and
    # evaluating 5 times (its start and 4 passes)
    assert made == [3] * 5 and len(evaluations) == 25
    made.clear()
    evaluations.clear()
    _fit(replace(POWER, cut_start=2), 2, n_iterations=6)
    assert sorted(made) == [1] * 5 + [2] * 5 and len(evaluations) == 50  # workers of 2 homes and of 1


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


@pytest.mark.parametrize("key", ["fit 1", "fit 2", "fit 2 passes 2"])
def test_the_fits_are_the_chains_before_to_the_bit(key: str) -> None:
    hyper = replace(POWER, cut_start=4, phi_passes=2 if "passes" in key else 4)
    assert _hash(_fit(hyper, int(key.split()[1]))) == BEFORE[key]


@pytest.mark.parametrize("phi_moves", [False, True])
def test_the_single_process_sweeps_are_the_chains_before_to_the_bit(phi_moves: bool) -> None:
    from test_power_target import _chain_start

    data, state, hyper, settings, rng = _chain_start(True, 4, phi_moves)
    for _ in range(30):
        gibbs.sweep(data, state, hyper, settings, rng)
    got = _digest(state.concepts, state.log_phi_v, state.log_theta_v, state.log_phi_w, state.log_g0)
    assert got == BEFORE["sweep phi" if phi_moves else "sweep"]


def test_a_joint_adapt_is_the_chain_before_to_the_bit() -> None:
    import spco.knowledge as kn
    from spco.data.environment import Corpus

    corpus = list(_corpus())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        knowledge = kn.fit_knowledge(Corpus(corpus[:-1]), n_iterations=6, random_state=0,
                                     hyperparameters=replace(POWER, cut_start=2))
        home = kn.adapt(knowledge, corpus[-1], n_iterations=4, random_state=1, joint=True)
    assert _digest(knowledge.log_phi_visual, home.state.concepts, home.state.log_phi_v,
                   home.state.log_theta_v) == BEFORE["adapt"]


def test_the_evaluator_is_the_terms_and_gathers_lazily(monkeypatch) -> None:
    rng = np.random.default_rng(1)
    n = _counts(rng, 3, 4, 19)
    made = []
    from spco.model import observations

    monkeypatch.setattr(observations, "FractionalCounts",
                        lambda groups: made.append(1) or FractionalCounts(groups))
    evaluate = HierarchicalMultinomial.fractional_log_weight_evaluator(n, 2.5)
    assert not made  # nothing gathered before the first evaluation
    for _ in range(3):
        log_phi = np.log(rng.dirichlet(np.ones(19), size=4))
        assert evaluate(log_phi).tobytes() == \
            HierarchicalMultinomial.fractional_log_weight_terms(n, log_phi, 2.5).tobytes()
    assert len(made) == 1
    whole = HierarchicalMultinomial.fractional_log_weight_evaluator(n.astype(np.int64), 2.5)
    assert not whole(log_phi).any() and len(made) == 1


def test_the_phi_step_draws_as_before_to_the_bit() -> None:
    rng = np.random.default_rng(12)
    h = hashlib.sha256()
    for rows in ("all", "some"):
        for passes in (1, 2, 4):
            n = rng.gamma(0.3, 2.0, size=(3, 5, 67)) * (rng.random((3, 5, 67)) < 0.5)
            if rows == "some":  # concepts 1 and 3 whole: the CRT draw, the others by blocks
                n[:, 1] = np.floor(n[:, 1])
                n[:, 3] = np.floor(n[:, 3])
            log_phi = np.log(rng.dirichlet(np.full(67, 0.4), size=5))
            step_rng = np.random.default_rng([passes, len(rows)])
            out = HierarchicalMultinomial.sample_shared_given_counts(n, log_phi, 7.0, 0.9, step_rng,
                                                                     passes=passes)
            h.update(out.tobytes())
            h.update(step_rng.bytes(16))  # the generator where the step left it
    assert h.hexdigest() == BEFORE["steps"]
