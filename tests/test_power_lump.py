"""``benchmarks/power_lump.py`` (why the power target lumps a new home) on a tiny power fit: the collapsed
terms against the Dirichlet–multinomial written out, and the one-sample steps' log-odds against the
collapsed joint's difference of the two states (every sample, both view accounts)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from power_lump import home_terms, one_sample_odds, phi_grids, weighted_counts
from split_evidence import dirichlet_multinomial


@pytest.fixture(scope="module")
def power_fit(small_corpus):
    """A short power-target fit of the synthetic corpus."""
    from spco.model import SpCoTransfer, TransferHyperparameters

    hyper = TransferHyperparameters().with_settings(["target=power", "visual_prior=estimate"])
    model = SpCoTransfer(hyper, variant="exact", n_iterations=4, random_state=0, prune_words=True)
    return model.fit(small_corpus)


def _moved(model, e: int) -> np.ndarray:
    """The chain's concepts with home e's samples each moved to another concept."""
    concepts = np.asarray(model.state_.concepts).copy()
    rows = np.flatnonzero(model.data_.homes == e)
    concepts[rows] = (concepts[rows] + 1 + np.arange(rows.size) % 3) % model.state_.log_g.shape[1]
    return concepts


def test_home_terms_are_the_dirichlet_multinomials(power_fit) -> None:
    """G_e, π and θ^v integrated: each term is its Dirichlet–multinomial written out with the chain's G_0,
    β/K and δ^v φ^v."""
    model, e = power_fit, power_fit.data_.n_homes - 1
    state, hyper = model.state_, model.hyperparameters_
    concepts = _moved(model, e)
    got = home_terms(model, concepts, e, None)
    rows = model.data_.homes == e
    L, K = state.log_g.shape[1], state.log_pi.shape[2]
    n = np.bincount(concepts[rows], minlength=L)
    assert got["concept prior"] == pytest.approx(
        dirichlet_multinomial(n.astype(float), hyper.gamma * np.exp(state.log_g0)), rel=1e-10)
    expected_regions = 0.0
    for ell in range(L):
        m = np.bincount(state.regions[rows][concepts[rows] == ell], minlength=K).astype(float)
        expected_regions += dirichlet_multinomial(m, np.full(K, hyper.beta / K))
    assert got["regions"] == pytest.approx(expected_regions, rel=1e-10)
    n_v = weighted_counts(model, concepts)[e]
    used = n_v.sum(axis=1) > 0
    expected_view = dirichlet_multinomial(n_v[used], hyper.delta_visual * np.exp(state.log_phi_v[used]))
    assert got["view | φ chain"] == pytest.approx(expected_view, rel=1e-10)


def test_one_sample_odds_are_the_joint_difference(power_fit) -> None:
    """Every sample's one-sample log-odds (θ integrated; θ and φ integrated) is the collapsed joint of the
    state with that sample moved minus the joint of the start; a sample already in its room concept is
    skipped."""
    model, e = power_fit, power_fit.data_.n_homes - 1
    lump = np.asarray(model.state_.concepts).copy()
    rooms = _moved(model, e)
    rows = np.flatnonzero(model.data_.homes == e)
    labels = np.asarray([f"p{i}" for i in range(rows.size)], dtype=object)  # each sample its own place
    grids = phi_grids(model, e, [lump, rooms], np.random.default_rng(0))
    odds = one_sample_odds(model, lump, rooms, e, grids, 1, labels)
    assert len(odds["θ integrated"]) == rows.size
    before = home_terms(model, lump, e, grids)
    for i, t in enumerate(rows):
        moved = lump.copy()
        moved[t] = rooms[t]
        after = home_terms(model, moved, e, grids)
        for key, view in (("θ integrated", "view | φ chain"), ("θ, φ integrated", "view | φ integrated")):
            want = sum(after[k] - before[k] for k in ("concept prior", "regions", view))
            assert odds[key][i] == pytest.approx(want, abs=1e-6 * max(1.0, abs(want)))
