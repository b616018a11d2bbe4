"""Where to ask "what is this place?": the expected information of an answer about the names of a
home's places, in closed form from the home's current posterior.

A robot in a new home can ask a person to name the place it stands in. An answer teaches the
most where the robot cannot predict it: where two concepts compete, where a room looks like
nothing the experienced homes had (its samples sit in a concept the knowledge does not use and
that nobody named here), and where a room may carry a name of its own. This module scores every
recorded sample of a home by the expected information of the answer there (SpCoAE's criterion,
Taniguchi et al., arXiv 2211.10934: the expected information gain of an imagined answer drawn from
the current posterior), computed without re-running the sampler.

The names of the home's samples
-------------------------------
Each sample ``i`` has a name ``Y_i``: one of the home's usable names ``w`` (the words the naming
rule kept) or ``⋆``, a name the robot has never learnt. Its distribution combines the model with the
chance ``ρ_i`` that the room has a name of its own::

    p_i(w) = (1 − ρ_i) Σ_{l named} P(l | x_i, v_i) θ̃_l(w)
    p_i(⋆) = ρ_i + (1 − ρ_i) Σ_{l unnamed} P(l | x_i, v_i)

``P(l | x, v)`` is the concept posterior (as ``what`` computes it), ``θ̃_l`` concept l's word
distribution restricted to the usable names and renormalised; *unnamed* concepts are those the
knowledge does not use and that hold no taught sample of this home (their names are unknown, whatever
word the sampler's draw of φ^w happens to favour), and those that give no usable name any mass. The
answer's information about ``Y_i`` is its entropy ``H_i = H(p_i) + p_i(⋆) · H_⋆``: a name never
learnt is worth at least the choice among all the names the robot knows and one more,
``H_⋆ = log(|names| + 1)``.

A name of its own (ρ)
---------------------
The transfer model expects the home to name its places as the experienced homes did (θ^w of the
home is held at φ^w by δ^w = 10^4 pseudo-counts), so by itself it never expects "Emma's room". The
criterion adds what it cannot know: the chance that a *room* (:func:`group_rooms`: the sampler's
regions, joined when they look like the same kind of place and touch) carries a name of its own,
learnt from this home's answers per *kind* of room — the concept the knowledge uses that the room
looks like — as a Beta–Bernoulli mean::

    ρ(kind) = (c · ρ_0 + own(kind)) / (c + own(kind) + transferred(kind))

where ``own`` / ``transferred`` count the taught rooms of that kind whose answer held a name the
knowledge does not give / one it does, ``c`` = :data:`OWN_NAME_PRIOR_WEIGHT` and the prior mean
``ρ_0`` is :data:`OWN_NAME_PRIOR_SHARED` when the home has several rooms of the kind (a name that
several rooms share cannot send the robot to one of them: people tell such rooms apart by name —
"Emma's room", "the guest bathroom"), else :data:`OWN_NAME_PRIOR_ALONE`. A taught room's own name
is known: ``ρ = 0`` there.

The gain of a question
----------------------
An answer names the room it is given in: ``teach`` spreads a name first heard in the home over the
sampler's region where it is said (``own_names_to_free_concepts``) and a transferred name over the
concept's samples. The gain of asking at an untaught sample ``i`` of room ``R`` is the information
about the names of the room's untaught samples::

    gain(i) = Σ_{j ∈ R, j untaught} H_j        (nats)

so every untaught sample of a room has its room's gain; :func:`rank_questions` asks at the most
uncertain, then most central sample of each room, best room first, and ranks a further sample of a
room already asked by its own ``H_j`` (what is left to learn there once the room is named).
Everything is a few matrix products over the home's samples: ranking a SIGVerse home's 260 samples
takes milliseconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import entr

from spco.errors import ConfigurationError

__all__ = [
    "CRITERIA",
    "MIN_ROOM_SAMPLES",
    "OWN_NAME_PRIOR_ALONE",
    "OWN_NAME_PRIOR_SHARED",
    "OWN_NAME_PRIOR_WEIGHT",
    "ROOM_LINK_METRES",
    "ROOM_NAME_WEIGHT",
    "QuestionScores",
    "entropy_rows",
    "group_rooms",
    "name_entropy",
    "question_scores",
    "rank_questions",
    "room_novelty",
]

#: Two regions of the same kind whose samples come this close (metres) are one room. The robot's
#: samples are ~0.1–0.25 m apart along its path (SIGVerse: median 0.09 m, 99th percentile 0.24 m);
#: rooms of one kind are separated by walls and other rooms.
ROOM_LINK_METRES = 0.5
#: A region with fewer samples does not count as a room of its kind (a stray sample).
MIN_ROOM_SAMPLES = 3
#: Prior mean of ρ for a room that is the only one of its kind in the home.
OWN_NAME_PRIOR_ALONE = 0.1
#: Prior mean of ρ for one of several rooms of a kind.
OWN_NAME_PRIOR_SHARED = 0.5
#: Weight of the prior mean, in rooms: the first answer about a kind moves ρ by up to 1/3.
OWN_NAME_PRIOR_WEIGHT = 2.0
#: In a taught room, the weight of the room's taught names against the model's names as a witness
#: of an untaught sample's name: two equal witnesses.
ROOM_NAME_WEIGHT = 0.5


def entropy_rows(p: np.ndarray) -> np.ndarray:
    """Entropy (nats) of each row (last axis) of non-negative weights ``p``, not renormalised:
    ``-Σ p log p`` with 0 log 0 = 0 (:func:`scipy.special.entr`)."""
    return entr(p).sum(axis=-1)


def name_entropy(probabilities: np.ndarray, unknown: np.ndarray, n_names: int) -> np.ndarray:
    """``H_i = H(p_i) + p_i(⋆) log(n_names + 1)``: the information of learning each sample's name.

    Parameters
    ----------
    probabilities: (n, V') p_i(w) over the usable names (rows sum to ``1 − unknown``).
    unknown: (n,) p_i(⋆), the probability of a name the robot has not learnt.
    n_names: V', the number of usable names.

    Returns
    -------
    (n,) float64 nats, ≥ 0.
    """
    p = np.asarray(probabilities, dtype=np.float64)
    u = np.asarray(unknown, dtype=np.float64)
    return entropy_rows(p) + entropy_rows(u[:, None]) + u * math.log(n_names + 1)


def group_rooms(regions: np.ndarray, kinds: np.ndarray, xy: np.ndarray,
                link: float = ROOM_LINK_METRES) -> np.ndarray:
    """The room of each sample: the sampler's regions, joined when they hold the same kind of place
    (the majority kind of their samples) and two of their samples are closer than ``link`` metres.

    Parameters
    ----------
    regions: (n,) int, each sample's region; kinds: (n,) int, the kind each sample looks like;
    xy: (n, 2) positions, metres; link: the joining distance.

    Returns
    -------
    (n,) int, rooms numbered 0, 1, … in order of their first sample.
    """
    regions = np.asarray(regions, dtype=np.int64)
    kinds = np.asarray(kinds, dtype=np.int64)
    xy = np.asarray(xy, dtype=np.float64)
    if not regions.shape == kinds.shape == xy.shape[:1] or xy.ndim != 2 or xy.shape[1] != 2:
        raise ConfigurationError(f"regions {regions.shape}, kinds {kinds.shape} and xy {xy.shape} must "
                                 "describe the same samples ((n,), (n,), (n, 2))")
    used, local = np.unique(regions, return_inverse=True)
    if used.size == 0:
        return np.zeros(0, dtype=np.int64)
    majority = np.array([np.bincount(kinds[local == r]).argmax()
                         for r in range(used.size)])  # a loop over the home's regions (≤ K)
    parent = np.arange(used.size)

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = int(parent[a])
        return a

    tree = cKDTree(xy)
    for i, j in tree.query_pairs(float(link), output_type="ndarray"):
        a, b = int(local[i]), int(local[j])
        if a != b and majority[a] == majority[b]:
            parent[find(a)] = find(b)
    roots = np.array([find(r) for r in range(used.size)])
    _, first = np.unique(roots[local], return_index=True)
    order = np.argsort(first, kind="stable")
    renumber = np.empty(order.size, dtype=np.int64)
    renumber[order] = np.arange(order.size)
    return renumber[np.unique(roots[local], return_inverse=True)[1]]


@dataclass(frozen=True, eq=False)
class QuestionScores:
    """What an answer at each of a home's ``n`` samples would teach (:func:`question_scores`).

    Attributes
    ----------
    criterion: ``"information"`` or ``"errors"``: what :attr:`gain` measures.
    gain: (n,) the value of asking at each sample (0 at taught samples): its room's ``information``
        or ``errors``.
    entropy: (n,) H_i, the information (nats) of learning sample i's own name.
    errors: (n,) the probability that the robot's answer at sample i (``what``'s best name) is wrong.
    probabilities: (n, V') p_i(w) over the usable names (ρ and the room's taught names mixed in).
    model_probabilities: (n, V') the model's p(w | x_i, v_i) from the named concepts, renormalised
        over the usable names (0 for a sample whose concepts are all unnamed): what ``what`` answers.
    unknown: (n,) p_i(⋆); unnamed: (n,) the concept posterior's mass on unnamed concepts.
    own_name: (n,) ρ_i; rooms: (n,) room of each sample; kinds: (n,) the kind each sample looks
        like; room_kinds: (R,) each room's kind; rooms_of_kind: (L,) rooms of each kind in the home
        (rooms of at least :data:`MIN_ROOM_SAMPLES` samples); own_answers, transferred_answers: (L,)
        taught rooms of each kind answered with a name of their own / a transferred name.
    room_gain: (R,) each room's gain; room_names: (R, V') the names taught in each room (rows sum to
        1 for taught rooms, 0 otherwise); taught: (n,) bool, samples with a name taught;
    centrality: (n,) distance of each sample to its room's mean position, metres.
    novelty: (n,) how far the views of each sample's room are from anything the experienced homes
        showed, 0 … 1 (:func:`room_novelty`); room_fit: (R,) the rooms' view fits (NaN: unknown).
    """

    criterion: str
    gain: np.ndarray
    entropy: np.ndarray
    errors: np.ndarray
    probabilities: np.ndarray
    model_probabilities: np.ndarray
    unknown: np.ndarray
    unnamed: np.ndarray
    own_name: np.ndarray
    rooms: np.ndarray
    kinds: np.ndarray
    room_kinds: np.ndarray
    rooms_of_kind: np.ndarray
    own_answers: np.ndarray
    transferred_answers: np.ndarray
    room_gain: np.ndarray
    room_names: np.ndarray
    taught: np.ndarray
    centrality: np.ndarray
    novelty: np.ndarray
    room_fit: np.ndarray

    @property
    def n_samples(self) -> int:
        """n."""
        return int(self.gain.size)

    @property
    def residual(self) -> np.ndarray:
        """(n,) the value of a further question at a sample whose room was just asked: its own
        ``entropy`` (information) or ``errors``."""
        return self.entropy if self.criterion == "information" else self.errors


def room_novelty(room_fit: np.ndarray, fit_range: tuple[float, float] | None) -> np.ndarray:
    """How far each room's views are from anything the experienced homes showed, 0 … 1.

    ``room_fit``: (R,) the median view fit of each room's samples (nats per count by which the
    knowledge's visual mixture explains a view better than a uniform guess,
    :func:`spco.model.view_fit.view_fit`); ``fit_range = (normal, foreign)``: ``normal`` the lowest
    fit of the experienced homes (every experienced home's views are explained at least this well),
    ``foreign`` the level below which the knowledge is taken not to fit a home at all (half of it,
    :data:`spco.knowledge.VIEW_FIT_WARN_FRACTION`). Novelty is 0 at or above ``normal``, 1 at or
    below ``foreign``, linear between; 0 where the fit is unknown (NaN) or ``fit_range`` is ``None``.
    A room this novel may have a name no experienced home used: it is the room's own-name
    probability ρ at least (:func:`question_scores`).
    """
    fit = np.asarray(room_fit, dtype=np.float64)
    if fit_range is None or not fit.size:
        return np.zeros(fit.shape)
    normal, foreign = (float(v) for v in fit_range)
    if not (np.isfinite(normal) and np.isfinite(foreign)) or normal <= foreign:
        raise ConfigurationError(f"fit_range must be (normal, foreign) with normal > foreign, "
                                 f"got {fit_range!r}")
    with np.errstate(invalid="ignore"):
        novelty = np.clip((normal - fit) / (normal - foreign), 0.0, 1.0)
    return np.where(np.isfinite(fit), novelty, 0.0)


#: The criteria :func:`question_scores` computes.
CRITERIA = ("information", "errors")


def _checked_score_inputs(criterion: str, concepts: Any, name_matrix: Any, unnamed: Any, kinds: Any,
                          regions: Any, xy: Any, taught_names: Any, taught_own: Any,
                          weights: tuple[float, float, float, float]) -> tuple[np.ndarray, ...]:
    """:func:`question_scores`'s arrays as NumPy arrays, checked (shapes, ranges, the criterion and
    ``weights`` = prior_alone, prior_shared, prior_weight, room_weight): (concepts, name matrix,
    unnamed, kinds, taught names, taught own)."""
    if criterion not in CRITERIA:
        raise ConfigurationError(f"criterion must be one of {', '.join(CRITERIA)}, got {criterion!r}")
    q = np.asarray(concepts, dtype=np.float64)
    names = np.asarray(name_matrix, dtype=np.float64)
    if q.ndim != 2 or names.ndim != 2 or names.shape[0] != q.shape[1]:
        raise ConfigurationError(f"concepts (n, L) and name_matrix (L, V') do not fit: {q.shape}, "
                                 f"{names.shape}")
    n, n_concepts = q.shape
    n_names = names.shape[1]
    unnamed = np.asarray(unnamed, dtype=bool)
    kinds = np.asarray(kinds, dtype=np.int64)
    said = np.asarray(taught_names, dtype=np.float64)
    taught_own = np.asarray(taught_own, dtype=bool)
    for label, array, shape in (("unnamed", unnamed, (n_concepts,)), ("kinds", kinds, (n,)),
                                ("taught_names", said, (n, n_names)), ("taught_own", taught_own, (n,)),
                                ("regions", np.asarray(regions), (n,)), ("xy", np.asarray(xy), (n, 2))):
        if array.shape != shape:
            raise ConfigurationError(f"{label} has shape {array.shape}, expected {shape}")
    if n and (kinds.min() < 0 or kinds.max() >= n_concepts):
        raise ConfigurationError(f"kinds must be concepts 0..{n_concepts - 1}")
    if not all(np.isfinite(a).all() and (a >= 0).all() for a in (q, names, said)):
        raise ConfigurationError("concept, name and taught-name weights must be finite and >= 0")
    prior_alone, prior_shared, prior_weight, room_weight = weights
    for label, value in (("prior_alone", prior_alone), ("prior_shared", prior_shared),
                         ("room_weight", room_weight)):
        if not 0.0 <= value <= 1.0:
            raise ConfigurationError(f"{label} must be within 0..1, got {value!r}")
    if not prior_weight > 0:
        raise ConfigurationError(f"prior_weight must be > 0, got {prior_weight!r}")
    return q, names, unnamed, kinds, said, taught_own


def _room_view_fits(view_fits: Any, rooms: np.ndarray, n_rooms: int) -> np.ndarray:
    """(R,) the median view fit of each room's samples with a view (NaN: none, or no fits given)."""
    room_fit = np.full(n_rooms, np.nan)
    if view_fits is None:
        return room_fit
    fits = np.asarray(view_fits, dtype=np.float64)
    if fits.shape != rooms.shape:
        raise ConfigurationError(f"view_fits has shape {fits.shape}, expected {rooms.shape}")
    for r in range(n_rooms):  # a loop over rooms
        seen = fits[rooms == r]
        seen = seen[np.isfinite(seen)]
        if seen.size:
            room_fit[r] = float(np.median(seen))
    return room_fit


def question_scores(
    concepts: np.ndarray,
    name_matrix: np.ndarray,
    unnamed: np.ndarray,
    kinds: np.ndarray,
    regions: np.ndarray,
    xy: np.ndarray,
    taught_names: np.ndarray,
    taught_own: np.ndarray,
    criterion: str = "information",
    link: float = ROOM_LINK_METRES,
    prior_alone: float = OWN_NAME_PRIOR_ALONE,
    prior_shared: float = OWN_NAME_PRIOR_SHARED,
    prior_weight: float = OWN_NAME_PRIOR_WEIGHT,
    room_weight: float = ROOM_NAME_WEIGHT,
    view_fits: np.ndarray | None = None,
    fit_range: tuple[float, float] | None = None,
) -> QuestionScores:
    """The value of an answer at each of a home's samples (module docstring).

    Parameters
    ----------
    concepts: (n, L) P(l | x_i, v_i), rows summing to 1.
    name_matrix: (L, V') p(name | concept) over the usable names (rows summing to 1, or to 0 for a
        concept that gives no usable name any mass).
    unnamed: (L,) bool, concepts whose names are unknown (the knowledge does not use them and no
        taught sample of the home sits in them).
    kinds: (n,) int in 0..L-1, the kind of place (a concept the knowledge uses) each sample looks like.
    regions: (n,) int, each sample's region in the sampler's state; xy: (n, 2) positions, metres.
    taught_names: (n, V') the usable names each sample was taught (a row of a taught sample sums to
        1 over its names; 0 for untaught samples and for sentences that hold no usable name).
    taught_own: (n,) bool, taught samples whose sentence holds no name the knowledge gives (a name of
        the home's own).
    criterion: ``"information"`` (expected information, nats) or ``"errors"`` (expected wrong
        answers corrected), see :data:`CRITERIA`.
    link, prior_alone, prior_shared, prior_weight, room_weight: :data:`ROOM_LINK_METRES`,
        :data:`OWN_NAME_PRIOR_ALONE`, :data:`OWN_NAME_PRIOR_SHARED`, :data:`OWN_NAME_PRIOR_WEIGHT`,
        :data:`ROOM_NAME_WEIGHT`.
    view_fits: (n,) each sample's view fit (nats per count by which the knowledge's views explain
        it better than a uniform guess; NaN: no view), or ``None``; fit_range: ``(normal, foreign)``
        for :func:`room_novelty` (``None``: no novelty).

    Returns
    -------
    :class:`QuestionScores`. Raises :class:`~spco.errors.ConfigurationError` on inconsistent shapes
    or values.
    """
    q, names, unnamed, kinds, said, taught_own = _checked_score_inputs(
        criterion, concepts, name_matrix, unnamed, kinds, regions, xy, taught_names, taught_own,
        (prior_alone, prior_shared, prior_weight, room_weight))
    n, n_concepts = q.shape
    n_names = names.shape[1]
    taught = said.sum(axis=1) > 0
    taught_own = taught_own & taught
    named = ~unnamed & (names.sum(axis=1) > 0)
    model = q[:, named] @ names[named]  # (n, V'): the named share of p(w | x, v)
    nameless = q[:, ~named].sum(axis=1)

    xy = np.asarray(xy, dtype=np.float64)
    rooms = group_rooms(regions, kinds, xy, link)
    n_rooms = int(rooms.max()) + 1 if n else 0
    size = np.bincount(rooms, minlength=n_rooms)
    room_kinds = np.array([np.bincount(kinds[rooms == r], minlength=n_concepts).argmax()
                           for r in range(n_rooms)], dtype=np.int64)  # a loop over rooms
    indicator = np.zeros((n_rooms, n))
    indicator[rooms, np.arange(n)] = 1.0
    room_said = indicator @ said  # (R, V')
    room_taught = room_said.sum(axis=1) > 0
    room_names = np.divide(room_said, room_said.sum(axis=1, keepdims=True), out=np.zeros_like(room_said),
                           where=room_taught[:, None])
    room_own = np.bincount(rooms, weights=taught_own, minlength=n_rooms) > 0
    rooms_of_kind = np.bincount(room_kinds[size >= MIN_ROOM_SAMPLES], minlength=n_concepts)
    own_answers = np.bincount(room_kinds[room_own], minlength=n_concepts).astype(np.float64)
    transferred_answers = np.bincount(room_kinds[room_taught & ~room_own],
                                      minlength=n_concepts).astype(np.float64)
    prior = np.where(rooms_of_kind >= 2, prior_shared, prior_alone)
    rho_kind = (prior_weight * prior + own_answers) / (prior_weight + own_answers + transferred_answers)
    room_fit = _room_view_fits(view_fits, rooms, n_rooms)
    novelty_room = room_novelty(room_fit, fit_range)
    rho_room = np.where(room_taught, 0.0, np.maximum(rho_kind[room_kinds], novelty_room))
    rho = rho_room[rooms] if n else np.zeros(0)

    probabilities = (1.0 - rho)[:, None] * model
    unknown = rho + (1.0 - rho) * nameless
    # in a taught room, the room's taught names are a second witness of each sample's name
    witness = (room_taught[rooms] & ~taught) if n else np.zeros(0, dtype=bool)
    weight = np.where(witness, room_weight, 0.0)
    probabilities = (1.0 - weight)[:, None] * probabilities + weight[:, None] * room_names[rooms]
    unknown = (1.0 - weight) * unknown
    entropy = name_entropy(probabilities, unknown, n_names)
    answered = np.argmax(model, axis=1) if n_names else np.zeros(n, dtype=np.int64)
    right = (np.take_along_axis(probabilities, answered[:, None], axis=1)[:, 0] if n_names
             else np.zeros(n))
    right = np.where(model.sum(axis=1) > 0, right, 0.0)  # no name answered: wrong whatever it is
    errors = np.clip(1.0 - right, 0.0, 1.0)
    value = entropy if criterion == "information" else errors
    room_gain = np.bincount(rooms, weights=np.where(taught, 0.0, value), minlength=n_rooms)
    gain = np.where(taught, 0.0, room_gain[rooms] if n else np.zeros(0))
    centre = np.stack([np.bincount(rooms, weights=xy[:, d], minlength=n_rooms) / np.maximum(size, 1)
                       for d in range(2)], axis=1) if n else np.zeros((0, 2))
    centrality = np.linalg.norm(xy - centre[rooms], axis=1) if n else np.zeros(0)
    total = model.sum(axis=1, keepdims=True)
    model_probabilities = np.divide(model, total, out=np.zeros_like(model), where=total > 0)
    return QuestionScores(criterion=criterion, gain=gain, entropy=entropy, errors=errors,
                          probabilities=probabilities, model_probabilities=model_probabilities,
                          unknown=unknown, unnamed=nameless, own_name=rho, rooms=rooms, kinds=kinds,
                          room_kinds=room_kinds, rooms_of_kind=rooms_of_kind, own_answers=own_answers,
                          transferred_answers=transferred_answers, room_gain=room_gain,
                          room_names=room_names, taught=taught, centrality=centrality,
                          novelty=novelty_room[rooms] if n else np.zeros(0), room_fit=room_fit)


def rank_questions(scores: QuestionScores, candidates: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The candidates in the order to ask them, with the gain of each at its place in that order.

    Each room is asked first at its most uncertain untaught candidate (ties: the one nearest the
    room's mean position), best room first, with the room's gain; a further candidate of a room
    already in the list is worth its own entropy ``H_j`` (what is left to learn there once the room
    is named). The list is sorted by that gain (a stable sort: rooms before their further samples
    at equal gain).

    Parameters
    ----------
    scores: from :func:`question_scores`.
    candidates: (c,) sample rows that may be asked (default: every untaught sample).

    Returns
    -------
    ``(rows, gains)``: (c,) int sample rows, best first, and (c,) their gains (nats).
    """
    if candidates is None:
        rows = np.flatnonzero(~scores.taught)
    else:
        rows = np.unique(np.asarray(candidates, dtype=np.int64))
        if rows.size and (rows.min() < 0 or rows.max() >= scores.n_samples):
            raise ConfigurationError(f"candidates must be sample rows 0..{scores.n_samples - 1}")
    if rows.size == 0:
        return rows, np.zeros(0)
    # within a room: most uncertain first (to 0.01), then of the room's kind, then nearest its middle
    typical = scores.kinds[rows] != scores.room_kinds[scores.rooms[rows]]
    within = np.lexsort((rows, scores.centrality[rows], typical, -np.round(scores.residual[rows], 2),
                         scores.rooms[rows]))
    ordered = rows[within]
    first = np.ones(ordered.size, dtype=bool)
    first[1:] = scores.rooms[ordered[1:]] != scores.rooms[ordered[:-1]]
    gains = np.where(first, scores.room_gain[scores.rooms[ordered]], scores.residual[ordered])
    order = np.lexsort((~first, -gains), axis=-1)
    return ordered[order], gains[order]
