"""The power target's CPU (issue 29, branch fastpower20): speedups that leave every draw the same.

- φ^v's fractional weight computed for a worker's homes in one call
  (:func:`spco.model.kernels.fractional.fractional_log_weights_grouped`: exp and ln Γ of what depends on
  φ alone once per concept and dimension) is, bit for bit, the sum over the homes in order of the
  one-group kernel it replaces (kept here as the reference), on counts with whole parts, fractions,
  zeros and a dimension whose a underflows to 0;
- a worker's answer (:meth:`ShardGroup.visual_log_weight`) is its homes' own answers summed, to the bit,
  at every call of a short power fit;
- the power likelihood's tokens' log-sum-exp (:func:`spco.model.word_channels._logsumexp_last`) is
  SciPy's, to the bit, on random logits and on ties, infinities and NaN;
- short synthetic fits (the cut, the power target, the power target from the cut's state, one worker
  and two) are the chains of branch cutstart20 011610d, to the bit (hashes made with that code).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from numba import njit
from scipy.special import logsumexp
from test_cut_start import _fit, _hash

from spco.model.hyperparameters import TransferHyperparameters
from spco.model.kernels.fractional import fractional_log_weights_by_dimension, fractional_log_weights_grouped
from spco.model.shard_group import ShardGroup, _sum
from spco.model.word_channels import _logsumexp_last

POWER = TransferHyperparameters(target="power", visual_prior="estimate")

#: sha256 of :func:`_hash` of :func:`_fit`, made with branch cutstart20 011610d's code (before this
#: branch), for (setting, workers)
BEFORE = {
    ("cut", 1): "1091b7b419340b38e831f038a1277e65c5c94d18777008ba5f5eec5b43493305",
    ("cut", 2): "1091b7b419340b38e831f038a1277e65c5c94d18777008ba5f5eec5b43493305",
    ("power", 1): "5bbd7619c3c7ad7b71b0bbfce18357533696d30fee110b2a40e7983405ddbf0d",
    ("power", 2): "5bbd7619c3c7ad7b71b0bbfce18357533696d30fee110b2a40e7983405ddbf0d",
    ("cut_start4", 1): "99aacefa922a3531cc7fdb541c8a84d3c29d5f8e121ef3af89dc9dccd2c62b77",
    ("cut_start4", 2): "99aacefa922a3531cc7fdb541c8a84d3c29d5f8e121ef3af89dc9dccd2c62b77",
}
SETTINGS = {"cut": TransferHyperparameters(), "power": POWER, "cut_start4": replace(POWER, cut_start=4)}


@njit(cache=False, error_model="numpy")
def _before(n, log_phi, log_delta, out):  # pragma: no cover - compiled
    """011610d's kernel (one group of homes), the reference."""
    n_homes, n_concepts, n_dims = n.shape
    for c in range(n_concepts):
        for k in range(n_dims):
            out[c, k] = 0.0
        for e in range(n_homes):
            for k in range(n_dims):
                x = n[e, c, k]
                whole = math.floor(x)
                if x == whole:
                    continue
                tilt = x if whole == 0.0 else 0.0
                log_a = log_delta + log_phi[c, k]
                a = math.exp(log_a)
                if a > 0.0:
                    out[c, k] += math.lgamma(a + x) - math.lgamma(a + whole) - tilt * log_a
                else:
                    out[c, k] = -math.inf


def _before_summed(groups: list[np.ndarray], log_phi: np.ndarray, delta: float) -> np.ndarray:
    parts = []
    for n in groups:
        out = np.empty(log_phi.shape)
        _before(np.ascontiguousarray(n, dtype=np.float64), log_phi, math.log(delta), out)
        parts.append(out)
    return _sum(parts)


def _counts(rng: np.random.Generator, homes: int, concepts: int, dims: int) -> np.ndarray:
    n = rng.gamma(0.2, 1.5, size=(homes, concepts, dims)) * (rng.random((homes, concepts, dims)) < 0.6)
    n[:, 0, :3] = np.floor(n[:, 0, :3]) + 1.0  # whole counts
    n[0, 1, 1] = 2.75  # a whole part and a fraction
    n[:, 2] = 0.0  # a concept without counts
    return n


@pytest.mark.parametrize("delta", [0.05, 3.0, 5e4])
@pytest.mark.parametrize("sizes", [[1], [3], [1, 1, 1, 1], [2, 1, 3]])
def test_the_grouped_weight_is_the_groups_sum_bit_for_bit(delta: float, sizes: list[int]) -> None:
    rng = np.random.default_rng(11)
    groups = [_counts(rng, s, 5, 37) for s in sizes]
    log_phi = np.log(rng.dirichlet(np.full(37, 0.3), size=5))
    log_phi[3, 4] = -np.inf  # a underflows where a home's count may be fractional
    groups[0][0, 3, 4] = 0.5
    got = fractional_log_weights_grouped(groups, log_phi, delta)
    expected = _before_summed(groups, log_phi, delta)
    assert got.tobytes() == expected.tobytes()
    assert got[3, 4] == -math.inf and np.all(got[2] == 0.0)
    one = np.concatenate(groups)
    assert fractional_log_weights_by_dimension(one, log_phi, delta).tobytes() == \
        _before_summed([one], log_phi, delta).tobytes()


def test_whole_counts_of_a_group_weigh_nothing() -> None:
    rng = np.random.default_rng(2)
    log_phi = np.log(rng.dirichlet(np.ones(6), size=3))
    whole = rng.integers(0, 5, size=(2, 3, 6))
    real = _counts(rng, 2, 3, 6)
    got = fractional_log_weights_grouped([real, whole], log_phi, 2.0)
    assert got.tobytes() == (fractional_log_weights_grouped([real], log_phi, 2.0) + 0.0).tobytes()
    assert not fractional_log_weights_grouped([whole], log_phi, 2.0).any()


def test_counts_of_the_wrong_shape_are_refused() -> None:
    with pytest.raises(ValueError, match="shape"):
        fractional_log_weights_grouped([np.zeros((1, 2, 3))], np.zeros((2, 4)), 1.0)
    with pytest.raises(ValueError, match="no group"):
        fractional_log_weights_grouped([], np.zeros((2, 4)), 1.0)


@pytest.mark.parametrize("key", sorted(BEFORE))
def test_the_chains_are_the_chains_before_to_the_bit(key: tuple[str, int]) -> None:
    setting, shards = key
    assert _hash(_fit(SETTINGS[setting], shards)) == BEFORE[key]


def test_a_worker_s_weight_is_its_homes_summed_bit_for_bit(monkeypatch) -> None:
    grouped = ShardGroup.visual_log_weight
    calls = []

    def checked(self: ShardGroup, log_phi: np.ndarray) -> np.ndarray:
        got = grouped(self, log_phi)
        expected = _sum(h.visual_log_weight(log_phi) for h in self.homes)
        calls.append((len(self.homes), got.tobytes() == expected.tobytes(),
                      bool(np.any(got != 0.0))))
        return got

    monkeypatch.setattr(ShardGroup, "visual_log_weight", checked)
    _fit(replace(POWER, cut_start=2), 1, n_iterations=4)
    assert calls and all(same for _, same, _ in calls)
    assert any(homes > 1 and weighed for homes, _, weighed in calls)  # the grouped path ran on real weights


@pytest.mark.parametrize("scale", [0.1, 5.0, 400.0])
def test_the_tokens_log_sum_exp_is_scipy_s_bit_for_bit(scale: float) -> None:
    rng = np.random.default_rng(8)
    a = rng.normal(size=(300, 7, 3)) * scale
    a[0, 0] = -np.inf  # every channel impossible
    a[1, 0, :2] = 3.0  # a tie at the top
    a[2, 0, 1] = -np.inf
    a[3, 0] = [np.inf, 1.0, 2.0]
    a[4, 0] = [np.nan, 1.0, 2.0]
    a[5, 0] = 2.0  # three ties
    a[6, 0] = [800.0, 800.0, -1.0]  # e^a overflows
    a[7, 0] = [-800.0, -745.0, -1e308]  # e^a underflows
    a[8, :, 2] = np.round(a[8, :, 0], 1)
    expected = logsumexp(a, axis=-1)
    got = _logsumexp_last(a)
    assert got.shape == expected.shape and got.tobytes() == expected.tobytes()
