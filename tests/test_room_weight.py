"""The room account's view weight learnt from the experienced homes (``spco.model.view_fit``:
``view_weight_losses(places=…)`` and ``room_view_weight``; docs/model.md, "A room's evidence learnt
from the experienced homes")."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.errors import ConfigurationError
from spco.model.state import PreparedData
from spco.model.view_fit import (
    VIEW_WEIGHT_GRID,
    estimate_view_weight,
    home_concept_totals,
    room_view_weight,
    view_weight_losses,
)


def _data(visual: np.ndarray, homes: np.ndarray, names: np.ndarray, n_words: int) -> PreparedData:
    """PreparedData of views ``visual`` (N, D), home indices (sorted) and one name token per sample."""
    n = homes.size
    E = int(homes.max()) + 1
    return PreparedData(positions=np.zeros((n, 4)), homes=homes, visual=sp.csr_array(visual),
                        words=sp.csr_array((np.ones(n), (np.arange(n), names)), shape=(n, n_words)),
                        n_homes=E, offsets=np.searchsorted(homes, np.arange(E + 1)), position_scale=1.0,
                        map_centres=np.zeros((E, 4)))


def _brute_force(visual: np.ndarray, homes: np.ndarray, places: np.ndarray, concepts: np.ndarray,
                 names: np.ndarray, L: int, V: int, alpha_v: float, alpha_w: float, w: float) -> float:
    """The leave-one-home-out loss written out sample by sample: φ^v, p(l) and φ^w from the other
    homes' samples, the sample's place's other views summed by a loop, p(l | room, v) by enumerating
    the concepts."""
    total = 0.0
    for t in range(homes.size):
        others = homes != homes[t]
        counts = np.full((L, visual.shape[1]), alpha_v)
        said = np.full((L, V), alpha_w)
        seen = np.full(L, 1.0 / L)
        for s in np.flatnonzero(others):
            counts[concepts[s]] += visual[s]
            said[concepts[s], names[s]] += 1.0
            seen[concepts[s]] += 1.0
        log_phi = np.log(counts / counts.sum(1, keepdims=True))
        log_phi_w = np.log(said / said.sum(1, keepdims=True))
        log_prior = np.log(seen / seen.sum())
        room = np.zeros(visual.shape[1])
        for s in range(homes.size):
            if s != t and homes[s] == homes[t] and places[s] == places[t] and places[t] >= 0:
                room += visual[s]
        omega_v = min(1.0, w / max(visual[t].sum(), 1.0))
        omega_r = min(1.0, w / max(room.sum(), 1.0))
        scores = np.array([log_prior[c] + omega_r * room @ log_phi[c] + omega_v * visual[t] @ log_phi[c]
                           for c in range(L)])
        given = logsumexp(scores + log_phi_w[:, names[t]]) - logsumexp(scores)
        without = logsumexp(log_prior + log_phi_w[:, names[t]])
        total += without - given
    return total


def _tiny(rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """Three homes of two or three places, 2–4 samples each, D = 5, L = 2 concepts, V = 3 names."""
    rows, homes, places, concepts, names = [], [], [], [], []
    for e, layout in enumerate([(0, 1), (1, 0, 1), (0, 1)]):
        for p, c in enumerate(layout):
            for _ in range(int(rng.integers(2, 5))):
                rows.append(rng.integers(0, 40, size=5))
                homes.append(e)
                places.append(p)
                concepts.append(c)
                names.append(c if p < 2 else 2)  # the third place's name is its own word
    return (np.array(rows, dtype=np.float64), np.array(homes), np.array(places), np.array(concepts),
            np.array(names))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_room_loss_is_the_brute_force_sum(seed: int) -> None:
    """view_weight_losses with places: each taught view predicted from its place's other views pooled
    and itself, each worth w draws, against the other homes — equal to the sum written out sample by
    sample, at weights from 1/16 (every view and room below one draw) to 2^14 (every count a draw)."""
    visual, homes, places, concepts, names = _tiny(np.random.default_rng(seed))
    data = _data(visual, homes, names, 3)
    totals, taught, words = home_concept_totals(data, concepts, 2)
    grid = (0.0625, 1.0, 7.0, 16.0, 90.5, 16384.0)
    losses, used = view_weight_losses(data, concepts, totals, taught, words, 3.0, 0.5, grid, places=places)
    assert used == homes.size
    expected = [_brute_force(visual, homes, places, concepts, names, 2, 3, 3.0, 0.5, w) for w in grid]
    np.testing.assert_allclose(losses, expected, rtol=1e-10, atol=1e-10)


def test_no_place_is_the_view_alone() -> None:
    """A sample without a place (-1 everywhere) is predicted from its view alone: the loss without
    places (the view-weight estimate's, unchanged)."""
    visual, homes, _, concepts, names = _tiny(np.random.default_rng(3))
    data = _data(visual, homes, names, 3)
    totals, taught, words = home_concept_totals(data, concepts, 2)
    alone, _ = view_weight_losses(data, concepts, totals, taught, words, 3.0, 0.5)
    nowhere, _ = view_weight_losses(data, concepts, totals, taught, words, 3.0, 0.5,
                                    places=np.full(homes.size, -1))
    np.testing.assert_allclose(nowhere, alone, rtol=1e-12, atol=1e-12)


def _homes(rng: np.random.Generator, spread: float, n_homes: int = 5, L: int = 3, n_views: int = 10,
           total: int = 400, D: int = 40) -> tuple[list[np.ndarray], list[list[str]]]:
    """Homes of L places each, named "p0".."p{L-1}"; a place's views are draws from its own η ~
    Dir(spread · θ_l) around its concept's θ_l: the smaller ``spread``, the further a home's room
    departs from its concept."""
    base = rng.dirichlet(np.full(D, 2.0))
    theta = 0.8 * base + 0.2 * rng.dirichlet(np.full(D, 2.0), size=L)
    visual, places = [], []
    for _ in range(n_homes):
        rows, labels = [], []
        for c in range(L):
            eta = rng.dirichlet(spread * theta[c] + 1e-3)
            rows += [rng.multinomial(total, eta) for _ in range(n_views)]
            labels += [f"p{c}"] * n_views
        visual.append(np.array(rows))
        places.append(labels)
    return visual, places


def _names(L: int) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """φ^w and G_0 in which name "p{l}" is concept l's (an unused word "x" last)."""
    phi = np.full((L, L + 1), 1e-6)
    phi[np.arange(L), np.arange(L)] = 1.0
    phi /= phi.sum(1, keepdims=True)
    return np.log(phi), np.full(L, -np.log(L)), [f"p{c}" for c in range(L)] + ["x"]


def test_the_weight_follows_how_far_rooms_depart_from_their_concept() -> None:
    """Rooms that look their own way (η far from θ) get a small weight, rooms close to their
    concept a large one: the weight is learnt from the homes, not a constant (and a grid value)."""
    log_phi_w, log_g0, vocabulary = _names(3)
    chosen = {}
    for spread in (30.0, 3000.0):
        visual, places = _homes(np.random.default_rng(7), spread)
        w, losses, used = room_view_weight(visual, places, log_phi_w, log_g0, vocabulary, 3.0, 0.01)
        assert used == 5 * 3 * 10 and np.isfinite(losses).all()
        chosen[spread] = w
    assert set(chosen.values()) <= set(VIEW_WEIGHT_GRID)
    assert chosen[30.0] < chosen[3000.0]


def test_room_view_weight_is_the_loss_of_its_places() -> None:
    """room_view_weight: the place names decide the concepts (argmax G_0 φ^w), a name not in the
    vocabulary leaves its samples out, and the loss is view_weight_losses' with the places."""
    log_phi_w, log_g0, vocabulary = _names(3)
    visual, places = _homes(np.random.default_rng(11), 100.0, n_homes=3)
    places[1] = ["?" if p == "p2" else p for p in places[1]]  # home 1's third place has no known name
    w, losses, used = room_view_weight(visual, places, log_phi_w, log_g0, vocabulary, 3.0, 0.01)
    keep = [np.array([p in vocabulary for p in labels]) for labels in places]
    rows = np.vstack([v[k] for v, k in zip(visual, keep, strict=True)]).astype(np.float64)
    homes = np.concatenate([np.full(int(k.sum()), e) for e, k in enumerate(keep)])
    labels = [p for labels, k in zip(places, keep, strict=True)
              for p, kk in zip(labels, k, strict=True) if kk]
    names = np.array([vocabulary.index(p) for p in labels])
    place_ids = np.array([int(p[1]) for p in labels])
    data = _data(rows, homes, names, len(vocabulary))
    concepts = names.copy()
    totals, taught, words = home_concept_totals(data, concepts, 3)
    expected, n = view_weight_losses(data, concepts, totals, taught, words, 3.0, 0.01, places=place_ids)
    assert used == n == 3 * 3 * 10 - 10
    np.testing.assert_allclose(losses, expected, rtol=1e-12)
    assert w == estimate_view_weight(expected, n)


def test_room_view_weight_errors_name_the_field() -> None:
    log_phi_w, log_g0, vocabulary = _names(3)
    visual, places = _homes(np.random.default_rng(1), 100.0, n_homes=2)
    with pytest.raises(ConfigurationError, match="places"):
        room_view_weight(visual, places[:1], log_phi_w, log_g0, vocabulary, 3.0, 0.01)
    with pytest.raises(ConfigurationError, match="place names"):
        room_view_weight(visual, [places[0], places[1][:-1]], log_phi_w, log_g0, vocabulary, 3.0, 0.01)
    with pytest.raises(ConfigurationError, match="log_phi_words"):
        room_view_weight(visual, places, log_phi_w, log_g0, vocabulary[:-1], 3.0, 0.01)
    w, _, used = room_view_weight(visual, [["?"] * len(p) for p in places], log_phi_w, log_g0, vocabulary,
                                  3.0, 0.01)
    assert w is None and used == 0
