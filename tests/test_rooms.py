"""A room's evidence (spco.model.rooms): a room's views pooled count as one view, taught names count, a
region taught two names into two concepts is two rooms,
and a room merged into another room's concept is not answered with certainty."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.model.answer_settings import AnswerSettings
from spco.model.confidence import answer_names
from spco.model.parameters import ConceptParameters
from spco.model.rooms import HomeRooms, concepts_by_room, room_concepts

NAMES = ("kitchen", "washroom", "dining")
D = 16


def _world(seed: int = 3) -> tuple[ConceptParameters, np.ndarray]:
    """Three concepts (one per name) with distinct φ^v; a home of two regions 2 m apart whose
    samples the sampler put *both* in concept 0 (π, θ^v_e and G_e say "kitchen" for both)."""
    rng = np.random.default_rng(seed)
    phi = 0.3 * rng.dirichlet(np.full(D, 5.0)) + 0.7 * rng.dirichlet(np.full(D, 0.8), size=3)
    means = np.zeros((1, 2, 4))
    means[0, 1, 0] = 2.0
    means[0, :, 3] = 1.0
    cov = np.tile(np.diag([0.3**2, 0.3**2, 0.1, 0.1]), (1, 2, 1, 1))
    words = np.eye(3)[None]
    home_theta = np.array([0.5 * phi[0] + 0.5 * phi[1], phi[1], phi[2]])  # concept 0 learnt from both rooms
    params = ConceptParameters(
        concept_weights=np.array([[0.98, 0.01, 0.01]]),
        region_weights=np.array([[[0.5, 0.5], [0.5, 0.5], [0.5, 0.5]]]) * np.array([[[1.0], [1e-6], [1e-6]]]),
        region_means=means, region_covariances=cov, word_probabilities=words,
        visual_probabilities=home_theta[None], shared_word_probabilities=words[0],
        shared_visual_probabilities=phi, global_concept_weights=np.full(3, 1.0 / 3),
        word_mask=np.ones(3, dtype=bool), region_counts=np.array([[20, 20]]),
        concept_counts=np.array([[40.0, 0.0, 0.0]]))
    return params, phi


def _room_views(phi: np.ndarray, mix: np.ndarray, n: int, scale: int, seed: int) -> sp.csr_array:
    """``n`` views of one room: each the room's own proportions (a mixture of the concepts' φ^v) drawn
    as 8 draws and copied ``scale`` times (an image's counts are not independent draws)."""
    rng = np.random.default_rng(seed)
    room = mix @ phi
    return sp.csr_array(np.stack([rng.multinomial(8, room) * scale for _ in range(n)]).astype(np.int64))


def _kitchen_and_washroom(phi: np.ndarray, washroom_mix: list[float], n: tuple[int, int] = (20, 20),
                          scale: tuple[int, int] = (200, 200),
                          seeds: tuple[int, int] = (2, 3)) -> tuple[HomeRooms, sp.csr_array, sp.csr_array]:
    """Rooms 0 and 1 of a home without names: the kitchen, ``n[0]`` views of concept 0, and the washroom,
    ``n[1]`` views of the mixture ``washroom_mix`` of the concepts (:func:`_room_views`, ``scale`` and
    ``seeds`` each); the rooms, then the kitchen's and the washroom's views."""
    kitchen = _room_views(phi, np.array([1.0, 0.0, 0.0]), n[0], scale[0], seed=seeds[0])
    washroom = _room_views(phi, np.array(washroom_mix), n[1], scale[1], seed=seeds[1])
    rooms = HomeRooms.of(np.repeat([0, 1], n), sp.csr_array(sp.vstack([kitchen, washroom])),
                         sp.csr_array((sum(n), 3)))
    return rooms, kitchen, washroom


def test_a_rooms_views_pooled_count_as_one_view() -> None:
    """p(l | room) is G_0 · exp(w Σ_d v̂_d log φ^v_l) of the room's pooled proportions: twenty views
    of the room say as much as their sum seen once, not twenty times as much — and a room of one
    view is that view at w."""
    params, phi = _world()
    views = _room_views(phi, np.array([0.45, 0.55, 0.0]), 20, 200, seed=1)
    rooms = HomeRooms.of(np.ones(20, dtype=int), views, sp.csr_array((20, 3)))
    counts, post = room_concepts(params, 0, rooms, view_counts=16.0)
    assert counts.tolist() == [0.0, 20.0]
    pooled = np.asarray(views.sum(axis=0), dtype=float).ravel()
    expected = np.log(1 / 3) + 16.0 / pooled.sum() * (np.log(phi) @ pooled)
    np.testing.assert_allclose(post[1], np.exp(expected - logsumexp(expected)), rtol=1e-10)
    np.testing.assert_allclose(post[0], np.full(3, 1 / 3))  # a region without samples: G_0
    # the same room seen in 20 copies of one view, or the view once: the same posterior
    one = sp.csr_array(views[[0]])
    many = sp.csr_array(sp.vstack([one] * 20))
    once = room_concepts(params, 0, HomeRooms.of([1], one, sp.csr_array((1, 3))), 16.0)[1][1]
    twenty = room_concepts(params, 0, HomeRooms.of(np.ones(20, int), many, sp.csr_array((20, 3))), 16.0)[1][1]
    np.testing.assert_allclose(once, twenty, rtol=1e-10)
    # the sampler's account (each view at w, twenty of them) is far surer than the room's
    per_view = np.log(1 / 3) + sum(16.0 / views[[t]].sum() * (np.log(phi) @ views[[t]].toarray()[0])
                                   for t in range(20))
    assert np.exp(per_view - logsumexp(per_view)).max() > post[1].max()


def test_a_merged_room_is_not_answered_with_certainty() -> None:
    """The washroom (region 1), its views between the kitchen's and the washroom's φ^v, put whole into
    the kitchen's concept: the home's own π and θ^v answer "kitchen" at p ≥ 0.99 there; the room's
    evidence counted once, and the observation's view once, leave the answer between the two below
    0.99, and the real kitchen (region 0) stays "kitchen"."""
    params, phi = _world()
    rooms, kitchen, washroom = _kitchen_and_washroom(phi, [0.5, 0.5, 0.0])
    poses = np.array([[0.0, 0.0, 0.0, 1.0], [2.0, 0.0, 0.0, 1.0]])
    test_views = sp.csr_array(sp.vstack([kitchen[[0]], washroom[[0]]]))
    vocabulary = Vocabulary(list(NAMES))
    before = answer_names(params, 0, vocabulary, poses, test_views, view_counts=16.0, weighting="none",
                          settings=AnswerSettings())
    assert before.best == ["kitchen", "kitchen"] and before.confidence[1] >= 0.99
    after = answer_names(params, 0, vocabulary, poses, test_views, view_counts=16.0, weighting="none",
                         rooms=rooms, settings=AnswerSettings())
    assert after.best[0] == "kitchen" and after.confidence[0] > 0.9
    assert after.confidence[1] < 0.99
    # at a pose well inside the washroom: G_0 · (the room pooled at w) · (the view at w), normalised
    pooled = np.asarray(washroom.sum(axis=0), dtype=float).ravel()
    view = test_views[[1]].toarray()[0].astype(float)
    log_p = (np.log(1 / 3) + 16.0 / pooled.sum() * (np.log(phi) @ pooled)
             + 16.0 / view.sum() * (np.log(phi) @ view))
    np.testing.assert_allclose(after.word_probabilities[1], np.exp(log_p - logsumexp(log_p)), atol=1e-9)
    np.testing.assert_allclose(concepts_by_room(params, 0, poses, test_views, rooms, 16.0).sum(axis=1), 1.0)


def test_names_taught_in_a_room_decide_it() -> None:
    """Three samples of the washroom taught "dining" (a home's own name for it): the room is the
    concept named so, at p ≈ 1, whatever its views look like."""
    params, phi = _world()
    visual = sp.csr_array(sp.vstack([_room_views(phi, np.array([1.0, 0.0, 0.0]), 20, 200, seed=4),
                                     _room_views(phi, np.array([0.5, 0.5, 0.0]), 20, 200, seed=5)]))
    words = sp.lil_array((40, 3))
    for t in (20, 25, 30):
        words[t, 2] = 1
    rooms = HomeRooms.of(np.repeat([0, 1], 20), visual, sp.csr_array(words))
    after = answer_names(params, 0, Vocabulary(list(NAMES)), np.array([[2.0, 0.0, 0.0, 1.0]]), None,
                         view_counts=16.0, weighting="none", rooms=rooms, settings=AnswerSettings())
    assert after.best == ["dining"] and after.confidence[0] > 0.99


def test_without_samples_the_view_answers() -> None:
    """No region with a training sample: the answer is the observation's own (its view and pose
    against the home's parameters), as without rooms."""
    params, phi = _world()
    view = _room_views(phi, np.array([0.0, 1.0, 0.0]), 1, 50, seed=6)
    empty = HomeRooms.of(np.zeros(0, dtype=int), sp.csr_array((0, D)), sp.csr_array((0, 3)))
    pose = np.array([[2.0, 0.0, 0.0, 1.0]])
    vocabulary = Vocabulary(list(NAMES))
    plain = answer_names(params, 0, vocabulary, pose, view, view_counts=16.0, weighting="none",
                         settings=AnswerSettings())
    got = answer_names(params, 0, vocabulary, pose, view, view_counts=16.0, weighting="none", rooms=empty,
                       settings=AnswerSettings())
    np.testing.assert_allclose(got.word_probabilities, plain.word_probabilities)
    assert concepts_by_room(params, 0, pose, view, empty, 16.0) is None


def test_bad_rooms_are_refused() -> None:
    params, _ = _world()
    with pytest.raises(ConfigurationError, match="regions"):
        HomeRooms.of([0, 1], sp.csr_array((3, D)), sp.csr_array((2, 3)))
    with pytest.raises(ConfigurationError, match="negative"):
        HomeRooms.of([-1], sp.csr_array((1, D)), sp.csr_array((1, 3)))
    with pytest.raises(ConfigurationError, match="region 5"):
        room_concepts(params, 0, HomeRooms.of([5], sp.csr_array((1, D)), sp.csr_array((1, 3))), 16.0)
    with pytest.raises(ConfigurationError, match="view_counts"):
        room_concepts(params, 0, HomeRooms.of([0], sp.csr_array(np.ones((1, D))), sp.csr_array((1, 3))), -1.0)
    with pytest.raises(ConfigurationError, match="map"):
        concepts_by_room(params, 0, np.array([[1e300, 1e300, 0.0, 1.0]]), None,
                         HomeRooms.of([0], sp.csr_array(np.ones((1, D))), sp.csr_array((1, 3))), 16.0)


def test_the_view_weighs_in_on_which_room_the_pose_is_in() -> None:
    """P(l | x, v) ∝ Σ_k p(k | x) p(l | room k) p(v | l): at a pose between the kitchen and the
    washroom, nearer the washroom, a view mostly of the kitchen says the robot is in the kitchen (the
    view is likelier under the kitchen room's concept), so the answer is "kitchen". Judging the room
    by the pose alone, p(k | x) · p(l | room k, v) (the account as first built), answers "washroom"
    there at p = 0.91: the washroom's pooled views outvote the view (the synthetic general
    experiment lost A_n that way, benchmarks/rooms_synthetic.py)."""
    params, phi = _world()
    rooms, kitchen, washroom = _kitchen_and_washroom(phi, [0.0, 1.0, 0.0], seeds=(7, 8))
    pose = np.array([[1.15, 0.0, 0.0, 1.0]])
    # a view of the kitchen with the washroom's door in it
    view = sp.csr_array(_room_views(phi, np.array([0.8, 0.2, 0.0]), 1, 200, seed=9))
    got = concepts_by_room(params, 0, pose, view, rooms, 16.0)
    # by hand: p(k | x) ∝ n_k N(x | μ_k, Σ_k) (equal n_k and covariances: the squared distances),
    # p(l | room k) ∝ G_0 Mult(V_k | φ^v)^{w / |V_k|}, p(v | l) = Mult(v | φ^v)^{w / |v|}
    log_k = -0.5 * np.array([1.15**2, 0.85**2]) / 0.3**2
    log_room = np.stack([16.0 / r.sum() * (np.log(phi) @ np.asarray(r.sum(axis=0)).ravel())
                         for r in (kitchen, washroom)])
    log_room -= logsumexp(log_room, axis=1, keepdims=True)
    log_view = 16.0 / view.sum() * (np.log(phi) @ view.toarray()[0])
    joint = logsumexp(log_k[:, None] + log_room + log_view[None, :], axis=0)
    np.testing.assert_allclose(got[0], np.exp(joint - logsumexp(joint)), rtol=1e-9, atol=1e-12)
    assert np.exp(log_k[1] - logsumexp(log_k)) > 0.85 and int(np.argmax(got[0])) == 0 and got[0, 0] > 0.9


def test_a_region_taught_two_names_holds_two_rooms() -> None:
    """A region where two names were taught into two concepts — 15 samples "washroom" and 5 "dining"
    (the sampler gives each name its concept) — is two rooms at the region's Gaussian, each judged by
    its own names: the answer there keeps both names, 3 : 1 by the rooms' taught samples (one room per
    region would have to give both names' tokens to one concept). A region with untaught samples and one
    taught name is one room: the name decides it."""
    params, phi = _world()
    visual = sp.csr_array(sp.vstack([_room_views(phi, np.array([1.0, 0.0, 0.0]), 20, 200, seed=10),
                                     _room_views(phi, np.array([0.0, 1.0, 0.0]), 20, 200, seed=11)]))
    words = sp.lil_array((40, 3))
    concepts = np.repeat([0, 1], 20)
    for t in range(20, 40):
        words[t, 1 if t < 35 else 2] = 5000  # S^w = 5000 counts per token
    concepts[35:] = 2
    rooms = HomeRooms.of(np.repeat([0, 1], 20), visual, sp.csr_array(words), concepts)
    got = answer_names(params, 0, Vocabulary(list(NAMES)), np.array([[2.0, 0.0, 0.0, 1.0]]), None,
                       view_counts=16.0, weighting="none", rooms=rooms, settings=AnswerSettings())
    p = dict(zip(got.words[0], got.probabilities[0], strict=True))
    assert got.best == ["washroom"] and p["dining"] == pytest.approx(0.25, abs=0.02)
    assert p["washroom"] == pytest.approx(0.75, abs=0.02)
    counts, _ = room_concepts(params, 0, rooms, 16.0)
    assert sorted(counts.tolist()) == [5.0, 15.0, 20.0]  # rooms (0), (1, washroom), (1, dining)
    # one name taught once in the kitchen's region, its sample in a concept of its own: one room
    words = sp.lil_array((40, 3))
    words[3, 2] = 5000
    concepts = np.repeat([0, 1], 20)
    concepts[3] = 2
    one = HomeRooms.of(np.repeat([0, 1], 20), visual, sp.csr_array(words), concepts)
    counts, post = room_concepts(params, 0, one, 16.0)
    assert sorted(counts.tolist()) == [20.0, 20.0] and post[0].argmax() == 2


def test_bad_room_concepts_are_refused() -> None:
    params, _ = _world()
    with pytest.raises(ConfigurationError, match="concepts"):
        HomeRooms.of([0, 1], sp.csr_array((2, D)), sp.csr_array((2, 3)), [0])
    with pytest.raises(ConfigurationError, match="negative"):
        HomeRooms.of([0], sp.csr_array((1, D)), sp.csr_array((1, 3)), [-2])
    with pytest.raises(ConfigurationError, match="concept 7"):
        room_concepts(params, 0, HomeRooms.of([0], sp.csr_array((1, D)), sp.csr_array((1, 3)), [7]), 16.0)


def test_the_rooms_evidence_is_kept_per_parameters_object_and_weight() -> None:
    """The rooms' pooled evidence is worked out once per (parameters object, view weight): asked again
    with the same objects it is the same answer; asked with other parameters (a home after a teaching)
    or another weight it is worked out anew, never the kept one."""
    from dataclasses import replace

    params, phi = _world()
    views = _room_views(phi, np.array([0.45, 0.55, 0.0]), 20, 200, seed=1)
    rooms = HomeRooms.of(np.ones(20, dtype=int), views, sp.csr_array((20, 3)))
    first = room_concepts(params, 0, rooms, view_counts=16.0)[1]
    np.testing.assert_array_equal(room_concepts(params, 0, rooms, view_counts=16.0)[1], first)
    other = replace(params, shared_visual_probabilities=phi[[1, 0, 2]])  # the concepts' views swapped
    moved = room_concepts(other, 0, rooms, view_counts=16.0)[1]
    anew = HomeRooms.of(np.ones(20, dtype=int), views, sp.csr_array((20, 3)))
    fresh = room_concepts(other, 0, anew, 16.0)[1]
    np.testing.assert_array_equal(moved, fresh)
    assert np.abs(moved[1] - first[1]).max() > 0.1
    np.testing.assert_array_equal(room_concepts(params, 0, rooms, view_counts=4.0)[1],
                                  room_concepts(params, 0, HomeRooms.of(np.ones(20, dtype=int), views,
                                                                        sp.csr_array((20, 3))), 4.0)[1])


def _by_hand_in_room(phi: np.ndarray, log_k: np.ndarray, rooms_views: list[sp.csr_array], view: sp.csr_array,
                     w: float) -> np.ndarray:
    """P(l | x, v) of ``view_in_room`` by brute force: Σ_k p(k | x) p(l | room k) p(v | room k, l), each
    term written out with loops, η̂_{k,l} = (w φ_l + Σ_{t ∈ k} (w / |v_t|) v_t) / (w + Σ_t w)."""
    L = phi.shape[0]
    joint = np.full(L, -np.inf)
    v = view.toarray()[0].astype(float)
    for k, views in enumerate(rooms_views):
        dense = views.toarray().astype(float)
        pooled = dense.sum(axis=0)
        log_room = np.array([w / pooled.sum() * float(np.log(phi[c]) @ pooled) for c in range(L)])
        log_room -= logsumexp(log_room)
        own = sum(w / row.sum() * row for row in dense)
        for c in range(L):
            eta = (w * phi[c] + own) / (w + w * dense.shape[0])
            joint[c] = np.logaddexp(joint[c], log_k[k] + log_room[c] + w / v.sum() * float(np.log(eta) @ v))
    return np.exp(joint - logsumexp(joint))


def test_view_in_room_against_brute_force() -> None:
    """``view_in_room``: the view a draw of its room's own distribution around the room's concept —
    equal to the sum over rooms and concepts written out by hand, at a pose between two rooms."""
    params, phi = _world()
    rooms, kitchen, washroom = _kitchen_and_washroom(phi, [0.0, 1.0, 0.0], (6, 4), (200, 150), (7, 8))
    pose = np.array([[1.15, 0.0, 0.0, 1.0]])
    view = sp.csr_array(_room_views(phi, np.array([0.8, 0.2, 0.0]), 1, 200, seed=9))
    got = concepts_by_room(params, 0, pose, view, rooms, 16.0, view_in_room=True)
    log_k = -0.5 * np.array([1.15**2, 0.85**2]) / 0.3**2 + np.log([6.0, 4.0])
    log_k -= logsumexp(log_k)
    np.testing.assert_allclose(got[0], _by_hand_in_room(phi, log_k, [kitchen, washroom], view, 16.0),
                               rtol=1e-9, atol=1e-12)
    assert int(np.argmax(got[0])) == 0  # the kitchen's view still says the robot is in the kitchen


def test_view_in_room_does_not_lift_a_rooms_answer() -> None:
    """A merged washroom (its views between the kitchen's and the washroom's φ^v): by default the
    observation's view, counted against φ^v beside its room, lifts the room's answer; drawn from the
    room's own distribution it hardly moves it (the room's 20 views, each worth w, against the prior's
    w), so the answer is the room's p(l | room k). A room with no views: the view against φ^v."""
    params, phi = _world()
    rooms = _kitchen_and_washroom(phi, [0.5, 0.5, 0.0])[0]
    pose = np.array([[2.0, 0.0, 0.0, 1.0]])
    view = sp.csr_array(_room_views(phi, np.array([0.3, 0.7, 0.0]), 1, 200, seed=10))
    room_alone = room_concepts(params, 0, rooms, 16.0)[1][1]
    lifted = concepts_by_room(params, 0, pose, view, rooms, 16.0)[0]
    in_room = concepts_by_room(params, 0, pose, view, rooms, 16.0, view_in_room=True)[0]
    assert np.abs(in_room - room_alone).max() < 0.5 * np.abs(lifted - room_alone).max()
    np.testing.assert_allclose(in_room.sum(), 1.0)
    # no views in the rooms: η̂ = φ^v, the default account
    blind = HomeRooms.of(np.repeat([0, 1], 20), sp.csr_array((40, D)), sp.csr_array((40, 3)))
    np.testing.assert_allclose(concepts_by_room(params, 0, pose, view, blind, 16.0, view_in_room=True),
                               concepts_by_room(params, 0, pose, view, blind, 16.0), rtol=1e-12)
    with pytest.raises(ConfigurationError, match="view_in_room"):
        concepts_by_room(params, 0, pose, view, rooms, None, view_in_room=True)
