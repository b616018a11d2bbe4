"""A home's layout as evidence for its rooms (spco.model.layout): the rooms' marginals under the presence
prior against brute-force enumeration, the prior learnt from the experienced homes' places, the room
account with it against a sum written out, a flat prior equal to none, and errors naming the field."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.special import logsumexp
from test_rooms import NAMES, _room_views, _world

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.model.confidence import answer_names
from spco.model.layout import MAX_LAYOUT_STATES, LayoutPrior, layout_prior, room_marginals
from spco.model.rooms import HomeRooms, concepts_by_room, room_concepts


def _brute_marginals(E: np.ndarray, prior: LayoutPrior) -> np.ndarray:
    """(R, L) p(l_k = l | all) by enumerating every assignment of the R rooms to the L concepts."""
    R, L = E.shape
    marg = np.zeros((R, L))
    total = 0.0
    for labels in itertools.product(range(L), repeat=R):
        log_w = sum(E[k, labels[k]] for k in range(R))
        log_w += sum(prior.log_present[c] if c in labels else prior.log_absent[c] for c in range(L))
        w = float(np.exp(log_w))
        total += w
        for k in range(R):
            marg[k, labels[k]] += w
    return marg / total


@pytest.mark.parametrize("rooms", [2, 3, 4])
def test_room_marginals_against_brute_force(rooms: int) -> None:
    """The dynamic programme over sets of concepts present equals enumeration (2–4 rooms, 3 concepts),
    with a forbidden assignment (−inf) in one room and, separately, a concept far below every room's
    best (entering to first order: its log marginal still equals enumeration's)."""
    rng = np.random.default_rng(rooms)
    prior = LayoutPrior.of(rng.uniform(0.05, 0.95, 3))
    E = 3.0 * rng.normal(size=(rooms, 3)) + 40.0  # an unnormalised scale (cancels)
    E[0, 1] = -np.inf
    got = room_marginals(E, prior)
    np.testing.assert_allclose(np.exp(got), _brute_marginals(E, prior), rtol=1e-10, atol=1e-14)
    E[0, 1] = 0.0
    E[:, 2] -= 70.0  # concept 2 negligible in every room: it enters to first order
    got = room_marginals(E, prior)
    want = _brute_marginals(E, prior)
    np.testing.assert_allclose(np.exp(got), want, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(got[:, 2], np.log(want[:, 2]), rtol=1e-10)
    E[:, 2] += 40.0  # near the edge of negligible (ε ~ 1e-12): left out or not, the same marginals
    got = room_marginals(E, prior)
    want = _brute_marginals(E, prior)
    np.testing.assert_allclose(np.exp(got), want, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(got[:, 2], np.log(want[:, 2]), rtol=1e-9)


def test_presence_moves_the_cheapest_room() -> None:
    """Two rooms both favouring concept 0 and a concept 1 every home holds: the room whose evidence
    for 0 is weaker is the one moved to 1; a flat prior (presence 0.5) leaves the rooms independent."""
    E = np.log(np.array([[0.9, 0.1], [0.6, 0.4]]))
    got = np.exp(room_marginals(E, LayoutPrior.of([0.5, 0.999])))
    assert got[1, 1] > 0.8 and got[0, 1] < 0.25  # (both in 1 holds it too)
    flat = np.exp(room_marginals(E, LayoutPrior.of([0.5, 0.5])))
    np.testing.assert_allclose(flat, np.exp(E), rtol=1e-12)


def test_layout_prior_learnt_from_the_places() -> None:
    """P_l(present) = (Σ_e (1 − Π_{places n of e} (1 − p(l | n))) + s) / (E + 2 s),
    p(l | n) ∝ G_0,l φ^w_{l,n}; a name outside the vocabulary skipped, a place said twice once."""
    phi = np.log(np.array([[0.8, 0.1, 0.1], [0.1, 0.8, 0.1], [0.2, 0.2, 0.6]]))
    g0 = np.log(np.array([0.5, 0.3, 0.2]))
    homes = [["kitchen", "washroom"], ["kitchen", "unknown name"], ["dining", "kitchen", "kitchen"]]
    got = layout_prior(phi, g0, list(NAMES), homes)
    post = np.exp(g0[:, None] + phi)
    post /= post.sum(axis=0, keepdims=True)  # (L, V) p(l | name)
    held = np.zeros(3)
    for places in ([0, 1], [0], [2, 0]):
        held += 1.0 - np.prod([1.0 - post[:, n] for n in places], axis=0)
    np.testing.assert_allclose(np.exp(got.log_present), (held + 0.5) / 4.0, rtol=1e-12)
    np.testing.assert_allclose(np.exp(got.log_absent), 1.0 - (held + 0.5) / 4.0, rtol=1e-12)


def test_concepts_by_room_with_layout_against_brute_force() -> None:
    """P(l | x, v) ∝ Σ_k p(k | x) p(l_k = l | both rooms) p(v | l), the joint over the two rooms' concepts
    enumerated by hand — a washroom merged into the kitchen's concept, the layout saying a home holds
    a washroom — at a pose between the rooms; the washroom room's answer moves towards "washroom"."""
    params, phi = _world()
    kitchen = _room_views(phi, np.array([1.0, 0.0, 0.0]), 6, 200, seed=7)
    washroom = _room_views(phi, np.array([0.55, 0.45, 0.0]), 4, 150, seed=8)
    rooms = HomeRooms.of(np.repeat([0, 1], [6, 4]), sp.csr_array(sp.vstack([kitchen, washroom])),
                         sp.csr_array((10, 3)))
    prior = LayoutPrior.of([0.9, 0.99, 0.3])
    pose = np.array([[1.15, 0.0, 0.0, 1.0]])
    view = sp.csr_array(_room_views(phi, np.array([0.6, 0.4, 0.0]), 1, 200, seed=9))
    got = concepts_by_room(params, 0, pose, view, rooms, 16.0, layout=prior)
    _, indep = room_concepts(params, 0, rooms, 16.0)
    joint = np.zeros((3, 3))
    for a, b in itertools.product(range(3), repeat=2):
        joint[a, b] = indep[0, a] * indep[1, b] * np.prod(
            [np.exp(prior.log_present[c]) if c in (a, b) else np.exp(prior.log_absent[c]) for c in range(3)])
    joint /= joint.sum()
    marg = np.stack([joint.sum(axis=1), joint.sum(axis=0)])
    log_k = -0.5 * np.array([1.15**2, 0.85**2]) / 0.3**2 + np.log([6.0, 4.0])
    log_k -= logsumexp(log_k)
    v = view.toarray()[0].astype(float)
    log_v = np.array([16.0 / v.sum() * float(np.log(phi[c]) @ v) for c in range(3)])
    want = sum(np.exp(log_k[k] + np.log(marg[k]) + log_v) for k in range(2))
    np.testing.assert_allclose(got[0], want / want.sum(), rtol=1e-9, atol=1e-12)
    assert marg[1, 1] > indep[1, 1]


def test_off_and_flat_layout_are_the_room_account() -> None:
    """``layout=None`` is the room account as it was (the same bytes as not passing it), and a flat
    prior (every presence 0.5) the same answers to rounding."""
    params, phi = _world()
    kitchen = _room_views(phi, np.array([1.0, 0.0, 0.0]), 20, 200, seed=2)
    washroom = _room_views(phi, np.array([0.5, 0.5, 0.0]), 20, 200, seed=3)
    rooms = HomeRooms.of(np.repeat([0, 1], 20), sp.csr_array(sp.vstack([kitchen, washroom])),
                         sp.csr_array((40, 3)))
    poses = np.array([[0.0, 0.0, 0.0, 1.0], [1.2, 0.0, 0.0, 1.0], [2.0, 0.0, 0.0, 1.0]])
    views = sp.csr_array(_room_views(phi, np.array([0.3, 0.7, 0.0]), 3, 200, seed=10))
    vocabulary = Vocabulary(NAMES)
    base = answer_names(params, 0, vocabulary, poses, views, view_counts=16.0, weighting="none", rooms=rooms)
    off = answer_names(params, 0, vocabulary, poses, views, view_counts=16.0, weighting="none", rooms=rooms,
                       layout=None)
    assert base.word_probabilities.tobytes() == off.word_probabilities.tobytes()
    assert list(base.best) == list(off.best)
    flat = answer_names(params, 0, vocabulary, poses, views, view_counts=16.0, weighting="none", rooms=rooms,
                        layout=LayoutPrior.of([0.5, 0.5, 0.5]))
    np.testing.assert_allclose(flat.word_probabilities, base.word_probabilities, rtol=1e-10, atol=1e-14)
    sure = answer_names(params, 0, vocabulary, poses, views, view_counts=16.0, weighting="none", rooms=rooms,
                        layout=LayoutPrior.of([0.5, 0.999, 0.5]))
    assert np.abs(sure.word_probabilities - base.word_probabilities).max() > 1e-3


def test_errors_name_the_field() -> None:
    """A presence of 0 or 1, a room_log of the wrong width, too many rooms and concepts for the
    bound, no experienced home, a bad smoothing: each a ConfigurationError naming what is wrong."""
    with pytest.raises(ConfigurationError, match="presence probability"):
        LayoutPrior.of([0.0, 0.5])
    with pytest.raises(ConfigurationError, match="presence probability"):
        LayoutPrior.of([1.0])
    prior = LayoutPrior.of([0.5, 0.5, 0.5])
    with pytest.raises(ConfigurationError, match="room_log"):
        room_marginals(np.zeros((2, 4)), prior)
    with pytest.raises(ConfigurationError, match="room_log"):
        room_marginals(np.array([[0.0, np.nan, 0.0]]), prior)
    L = 20
    rooms = MAX_LAYOUT_STATES // 2**L + 1
    with pytest.raises(ConfigurationError, match="MAX_LAYOUT_STATES"):
        room_marginals(np.zeros((rooms, L)), LayoutPrior.of(np.full(L, 0.5)))
    phi, g0 = np.log(np.full((3, 3), 1 / 3)), np.log(np.full(3, 1 / 3))
    with pytest.raises(ConfigurationError, match="homes_places"):
        layout_prior(phi, g0, list(NAMES), [])
    with pytest.raises(ConfigurationError, match="smoothing"):
        layout_prior(phi, g0, list(NAMES), [["kitchen"]], smoothing=0.0)
    with pytest.raises(ConfigurationError, match="log_phi_words"):
        layout_prior(phi[:2], g0, list(NAMES), [["kitchen"]])
