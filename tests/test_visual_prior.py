"""The visual prior estimated from the homes (``visual_prior="estimate"``): δ^v and α^v by the method
of moments of the views' proportions (``spco.model.visual_prior``), used from the first sweep of the
chain on and carried by the knowledge."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import fit_twice_and_adapt

from spco.errors import ConfigurationError
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.state import PreparedData
from spco.model.visual_prior import estimate_visual_prior, home_view_moments


def _homes(rng: np.random.Generator, delta: float, alpha: float, n_homes: int = 30, L: int = 40,
           D: int = 50, n_views: int = 6, total: int = 400) -> tuple[PreparedData, np.ndarray]:
    """Homes drawn from the model: φ_l ~ Dir(α 1), θ_{e,l} ~ Dir(δ φ_l), each view ``total`` counts
    from its home's θ (``n_views`` per home and concept)."""
    phi = rng.dirichlet(np.full(D, alpha), size=L)
    rows, homes, concepts = [], [], []
    for e in range(n_homes):
        for c in range(L):
            theta = rng.dirichlet(delta * phi[c] + 1e-12)
            for _ in range(n_views):
                rows.append(rng.multinomial(total, theta))
                homes.append(e)
                concepts.append(c)
    n = len(rows)
    visual = sp.csr_array(np.array(rows, dtype=np.int64))
    words = sp.csr_array(np.ones((n, 1), dtype=np.int64))  # every view taught
    offsets = np.arange(0, n + 1, L * n_views)
    data = PreparedData(positions=np.zeros((n, 4)), homes=np.array(homes), visual=visual, words=words,
                        n_homes=n_homes, offsets=offsets, position_scale=1.0,
                        map_centres=np.zeros((n_homes, 4)))
    return data, np.array(concepts)


@pytest.mark.parametrize(("delta", "alpha"), [(30.0, 0.05), (300.0, 0.5), (3000.0, 2.0)])
def test_the_estimate_recovers_the_model_s_concentrations(delta: float, alpha: float) -> None:
    """Homes drawn at a known δ^v and α^v: the estimates land within a factor 1.5 of them (the views'
    own multinomial noise, 400 counts each, taken out of the homes' spread), and move with them."""
    data, concepts = _homes(np.random.default_rng(1), delta, alpha)
    m, s, q = home_view_moments(data, concepts, 40)
    assert m.sum() == data.n_samples and np.allclose(s.sum(axis=-1), m)
    d_hat, a_hat = estimate_visual_prior(m, s, q)
    assert d_hat is not None and a_hat is not None
    assert delta / 1.5 < d_hat < delta * 1.5, d_hat
    assert alpha / 1.5 < a_hat < alpha * 1.5, a_hat


def test_the_moments_brute_force() -> None:
    """:func:`home_view_moments` against a loop over the taught views of two small homes."""
    rng = np.random.default_rng(0)
    counts = rng.integers(0, 4, size=(7, 5))
    counts[2] = 0  # a sample without a view is left out
    said = np.array([1, 1, 1, 1, 0, 1, 1])  # and one without a word (untaught)
    homes = np.array([0, 0, 0, 1, 1, 1, 1])
    concepts = np.array([1, 0, 1, 2, 2, 0, 2])
    data = PreparedData(positions=np.zeros((7, 4)), homes=homes, visual=sp.csr_array(counts),
                        words=sp.csr_array(said[:, None]), n_homes=2, offsets=np.array([0, 3, 7]),
                        position_scale=1.0, map_centres=np.zeros((2, 4)))
    m, s, q = home_view_moments(data, concepts, 3)
    m2, s2, q2 = np.zeros((2, 3)), np.zeros((2, 3, 5)), np.zeros((2, 3))
    for t in range(7):
        if counts[t].sum() == 0 or not said[t]:
            continue
        p = counts[t] / counts[t].sum()
        m2[homes[t], concepts[t]] += 1
        s2[homes[t], concepts[t]] += p
        q2[homes[t], concepts[t]] += (p * p).sum()
    np.testing.assert_allclose(m, m2)
    np.testing.assert_allclose(s, s2)
    np.testing.assert_allclose(q, q2)


def test_nothing_to_estimate_from() -> None:
    """One home (no spread between homes): no δ^v; no view at all: neither."""
    data, concepts = _homes(np.random.default_rng(2), 100.0, 0.5, n_homes=1, L=3)
    m, s, q = home_view_moments(data, concepts, 3)
    delta, alpha = estimate_visual_prior(m, s, q)
    assert delta is None and alpha is not None and alpha > 0
    assert estimate_visual_prior(np.zeros((2, 3)), np.zeros((2, 3, 4)), np.zeros((2, 3))) == (None, None)


def test_the_setting_reads_and_is_written_only_when_estimated() -> None:
    hyper = TransferHyperparameters()
    assert hyper.visual_prior == "given" and "visual_prior" not in hyper.to_dict()
    estimate = hyper.with_settings(["visual_prior=estimate"])
    assert TransferHyperparameters.from_dict(estimate.to_dict()).visual_prior == "estimate"
    with pytest.raises(ConfigurationError, match="visual_prior"):
        TransferHyperparameters(visual_prior="sometimes")  # type: ignore[arg-type]


def test_the_knowledge_carries_the_estimate() -> None:
    """A fit of synthetic homes with ``visual_prior="estimate"``: the knowledge's δ^v and α^v are the
    estimate the provenance records (not the given ones); the same seed gives the same numbers; a
    home adapted from it keeps them."""
    hyper = TransferHyperparameters(visual_prior="estimate", target="power")
    _, fits, home = fit_twice_and_adapt(hyper)
    knowledge = fits[0]
    record = knowledge.provenance["visual_prior"]
    assert record["delta_visual_estimated"] and record["alpha_visual_estimated"]
    got = knowledge.hyperparameters
    assert (got.delta_visual, got.alpha_visual) == (record["delta_visual"], record["alpha_visual"])
    assert got.delta_visual != hyper.delta_visual and got.alpha_visual != hyper.alpha_visual
    assert fits[1].provenance["visual_prior"] == record
    assert (home.hyperparameters.delta_visual, home.hyperparameters.alpha_visual) == (got.delta_visual,
                                                                                        got.alpha_visual)
