"""The room account's view weight learnt from the experienced homes (``spco.model.view_fit``:
``view_weight_losses(places=…)``) and the typicality ρ learnt from them (``room_typicality``;
docs/model.md, "Opt-in: a room that looks like another concept")."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.special import logsumexp
from test_rooms import _room_views, _world

from spco.errors import ConfigurationError
from spco.model.rooms import HomeRooms, concepts_by_room
from spco.model.state import PreparedData
from spco.model.view_fit import (
    home_concept_totals,
    room_typicality,
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
    given, without = _brute_force_samples(visual, homes, places, concepts, names, L, V, alpha_v, alpha_w, w)
    return float(np.sum(without - given))


def _brute_force_samples(visual: np.ndarray, homes: np.ndarray, places: np.ndarray, concepts: np.ndarray,
                         names: np.ndarray, L: int, V: int, alpha_v: float, alpha_w: float, w: float
                         ) -> tuple[np.ndarray, np.ndarray]:
    """(N,) log p(name | room, view) and (N,) log p(name) of every sample, home left out (by loops)."""
    given_all, without_all = [], []
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
        given_all.append(logsumexp(scores + log_phi_w[:, names[t]]) - logsumexp(scores))
        without_all.append(logsumexp(log_prior + log_phi_w[:, names[t]]))
    return np.array(given_all), np.array(without_all)


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


def test_the_typicality_loss_is_the_brute_force_mixture() -> None:
    """room_typicality: each sample's name predicted by ρ p(name | room, view) + (1 − ρ) p(name), the
    two worked out sample by sample (home left out), at the model's w; ρ the grid's least loss."""
    log_phi_w, log_g0, vocabulary = _names(3)
    visual, places = _homes(np.random.default_rng(5), 60.0, n_homes=3, n_views=4, total=200, D=12)
    grid = (0.3, 0.9, 0.99, 1.0)
    rho, losses, used = room_typicality(visual, places, log_phi_w, log_g0, vocabulary, 3.0, 0.01, 16.0, grid)
    rows = np.vstack(visual).astype(np.float64)
    homes = np.repeat(np.arange(3), [len(p) for p in places])
    names = np.array([vocabulary.index(p) for labels in places for p in labels])
    given, without = _brute_force_samples(rows, homes, names, names, names, 3, len(vocabulary), 3.0, 0.01,
                                          16.0)
    expected = [float(np.sum(without - np.logaddexp(np.log(r) + given, np.log1p(-r) + without)))
                if r < 1 else float(np.sum(without - given)) for r in grid]
    assert used == rows.shape[0]
    np.testing.assert_allclose(losses, expected, rtol=1e-10, atol=1e-10)
    assert rho == grid[int(np.argmin(expected))]
    w_losses, _ = view_weight_losses(*_as_data(rows, homes, names, len(vocabulary)), 3.0, 0.01, (16.0,),
                                     places=names)
    np.testing.assert_allclose(losses[-1], w_losses[0], rtol=1e-12)  # ρ = 1: the room account's loss


def _as_data(rows: np.ndarray, homes: np.ndarray, names: np.ndarray, V: int) -> tuple:
    """(data, concepts, totals, taught, words) of samples whose concept is their name's index."""
    data = _data(rows, homes, names, V)
    return (data, names, *home_concept_totals(data, names, 3))


def test_typicality_follows_how_often_rooms_look_like_another_concept() -> None:
    """Homes whose places all look like their concept learn ρ near 1; when in one home of six two
    places swap names (2 places of 18 look like another concept) ρ falls well below 1 (w = 400: every
    count a draw, so that a swapped place is surely the other concept; 0.82 in seeds 9–11)."""
    log_phi_w, log_g0, vocabulary = _names(3)
    visual, places = _homes(np.random.default_rng(9), 3000.0, n_homes=6)
    tidy, _, _ = room_typicality(visual, places, log_phi_w, log_g0, vocabulary, 3.0, 0.01, 400.0)
    swapped = [list(p) for p in places]
    swapped[0] = ["p1" if p == "p0" else "p0" if p == "p1" else p for p in swapped[0]]
    mixed, _, _ = room_typicality(visual, swapped, log_phi_w, log_g0, vocabulary, 3.0, 0.01, 400.0)
    assert tidy is not None and mixed is not None
    assert tidy > 0.99 and mixed < 0.9


def _by_hand_typical(phi: np.ndarray, g0: np.ndarray, log_k: np.ndarray, rooms_views: list[sp.csr_array],
                     view: sp.csr_array, w: float, rho: float) -> np.ndarray:
    """P(l | x, v) with rooms atypical now and then, by enumeration: room k (prior p(k | x)), its
    concept l ~ G_0, typical (ρ: its views and the view drawn from φ^v_l) or not (1 − ρ: drawn from
    φ^v_l' of a concept l' ~ G_0), the room's own views' likelihood normalising each room's term."""
    L = phi.shape[0]
    v = view.toarray()[0].astype(float)
    joint = np.zeros(L)
    for k, views in enumerate(rooms_views):
        pooled = views.toarray().astype(float).sum(axis=0)
        S = [np.exp(w / pooled.sum() * float(np.log(phi[c]) @ pooled)) for c in range(L)]
        P = [np.exp(w / v.sum() * float(np.log(phi[c]) @ v)) for c in range(L)]
        Z = sum(g0[c] * (rho * S[c] + (1 - rho) * sum(g0[d] * S[d] for d in range(L))) for c in range(L))
        for c in range(L):
            typical = rho * S[c] * P[c]
            atypical = sum((1 - rho) * g0[d] * S[d] * P[d] for d in range(L))
            joint[c] += np.exp(log_k[k]) * g0[c] * (typical + atypical) / Z
    return joint / joint.sum()


@pytest.mark.parametrize("rho", [0.5, 0.9375, 0.999])
def test_typical_rooms_against_enumeration(rho: float) -> None:
    """concepts_by_room(typical=ρ) equals the mixture enumerated over rooms, concepts, typical or not
    and the look-alike concept, at a pose between two rooms (G_0 not uniform)."""
    params, phi = _world()
    params = dataclasses.replace(params, global_concept_weights=np.array([0.5, 0.3, 0.2]))
    kitchen = _room_views(phi, np.array([1.0, 0.0, 0.0]), 6, 3, seed=7)
    washroom = _room_views(phi, np.array([0.6, 0.4, 0.0]), 4, 2, seed=8)
    rooms = HomeRooms.of(np.repeat([0, 1], [6, 4]), sp.csr_array(sp.vstack([kitchen, washroom])),
                         sp.csr_array((10, 3)))
    pose = np.array([[1.15, 0.0, 0.0, 1.0]])
    view = sp.csr_array(_room_views(phi, np.array([0.3, 0.7, 0.0]), 1, 2, seed=9))
    got = concepts_by_room(params, 0, pose, view, rooms, 16.0, typical=rho)
    log_k = -0.5 * np.array([1.15**2, 0.85**2]) / 0.3**2 + np.log([6.0, 4.0])
    log_k -= logsumexp(log_k)
    expected = _by_hand_typical(phi, np.array([0.5, 0.3, 0.2]), log_k, [kitchen, washroom], view, 16.0, rho)
    np.testing.assert_allclose(got[0], expected, rtol=1e-9, atol=1e-12)


def test_typical_one_is_the_room_account_and_caps_a_sure_room() -> None:
    """ρ = 1 is the room account; ρ < 1 keeps a room whose views name another concept from being
    certain (at most about 1 − (1 − G_0) (1 − ρ)/ρ); a bad ρ and a combination are refused, naming it."""
    params, phi = _world()
    washroom = _room_views(phi, np.array([1.0, 0.0, 0.0]), 20, 200, seed=3)  # looks like the kitchen
    rooms = HomeRooms.of(np.ones(20, dtype=int), washroom, sp.csr_array((20, 3)))
    pose = np.array([[2.0, 0.0, 0.0, 1.0]])
    view = sp.csr_array(_room_views(phi, np.array([1.0, 0.0, 0.0]), 1, 200, seed=4))
    default = concepts_by_room(params, 0, pose, view, rooms, 16.0)
    np.testing.assert_allclose(concepts_by_room(params, 0, pose, view, rooms, 16.0, typical=1.0), default,
                               rtol=1e-12, atol=1e-15)
    assert default[0].max() > 0.9999
    capped = concepts_by_room(params, 0, pose, view, rooms, 16.0, typical=0.9)[0]
    assert 0.85 < capped.max() < 0.95
    for bad in (0.0, 1.5, float("nan")):
        with pytest.raises(ConfigurationError, match="typical"):
            concepts_by_room(params, 0, pose, view, rooms, 16.0, typical=bad)
    with pytest.raises(ConfigurationError, match="typical"):
        concepts_by_room(params, 0, pose, view, rooms, 16.0, typical=0.9, view_in_room=True)
