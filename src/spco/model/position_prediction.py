"""Prediction in a learnt home: positions from place names (p(pose | name)): the one predictor of
``where`` (:func:`spco.knowledge.where`, the service, the ROS node) and of the
experiments' A_p (:func:`spco.evaluation.metrics.evaluate_home`, the home-specific rooms).

Pure functions of a :class:`~spco.model.parameters.ConceptParameters` sample, a home index ``e``
and the corpus :class:`~spco.data.language.Vocabulary`, as :mod:`spco.model.prediction` (names
from observations), whose validation and helpers they share.

Regions, the posterior predictive of the region of a sample whose sentence says ``w``. With the
home's rooms (:class:`~spco.model.rooms.HomeRooms`, the robot always has them: the room account of
``what``, :mod:`spco.model.rooms`), each room k (n_k samples, region r(k)) has names of its own, drawn
around its concept's (docs/model.md, "Where a place is")::

    p(m | w) ∝ Σ_{k: r(k) = m} n_k Σ_l p(l | room k) p(w | room k, l),
    p(w | room k, l) = Σ_c a_{c,w} (δ p_{c,l,w} + X_{c,k,w}) / (δ + T_{c,k})

(:func:`room_name_log_likelihood`)
over the channels c a word is said through — its names, θ^w of the answer's parameters, and with the
word channels its words of the place, ψ — with a_{c,w} = p(c | w) (1 without the channels: so
Σ_c a_{c,w} p_{c,l,w} is :func:`said_word_matrix`, the names the robot answers), p(l | room k) room
k's pooled views, its taught names and G_0 deciding its concept, X_{c,k,w} the tokens of w the sampler
drew through channel c at the room's samples and T_{c,k} those of every word a place is looked up by
(S^w counts each: :func:`room_said_counts`), δ = δ^w (``HomeRooms.concentration``). A room where
nothing was said says its concept's names, so for a home taught nothing ``where`` is the Bayes inverse
of ``what`` at the pose alone; a name said in one room is found there. Without rooms
(a bare parameter set) p(m | w) ∝ Σ_l p(w | l) G_{e,l} π_{e,l,m} over the concepts holding the home's samples
(:func:`concept_stand_ins` for the others). Poses are drawn from the answer regions
(:func:`answer_regions`: those at least half as probable as the best, the robot's ``where``), or
from m̂ = argmax_m p(m | w) (the paper's A_p), or from p(m | w) (``"mixture"``)::

    x ~ N(μ_{e,m}, Σ_{e,m}).

The share of Σ_l G_{e,l} p(w | l) that the concepts holding samples of home e (``concept_counts``
≥ 1) hold is the name's ``support`` in the home; below :data:`LEARNT_SUPPORT` the place is reported
as not learnt in this home (``PositionPrediction.learnt`` False): its name is explained mostly by
concepts of other homes, e.g. ``dining`` in a home without a dining room.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import pairwise
from typing import Literal

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.model.parameters import ConceptParameters
from spco.model.prediction import (
    _LOG_FLOOR,
    UnknownNameError,
    _check_home,
    _check_vocabulary,
    _cholesky,
    _safe_log,
    _word_matrix,
    concept_information,
    gaussian_log_density,
    mutual_information_weights,
)
from spco.model.rooms import HomeRooms
from spco.model.unheard import SAID_WORDS, ResolvedName, resolve_name, said_as_one

__all__ = [
    "LEARNT_SUPPORT",
    "PositionPrediction",
    "answer_regions",
    "concept_stand_ins",
    "draw_poses",
    "name_support",
    "place_word_information",
    "predict_positions",
    "query_forms",
    "query_indices",
    "query_name",
    "region_posterior_for_name",
    "resolve_unheard",
    "room_name_log_likelihood",
    "room_said_counts",
    "said_word_matrix",
]

PositionMode = Literal["argmax", "mixture", "answer"]

#: A place name is *learnt* in a home when at least this share of its probability there comes
#: from concepts that hold samples of the home (see :func:`name_support`).
LEARNT_SUPPORT = 0.5


@dataclass(frozen=True, eq=False)
class PositionPrediction:
    """Positions predicted for one place name.

    Attributes
    ----------
    name: how the name asked for is understood (:func:`query_name`): its usable tokens joined by
        ``" + "`` (``"living room"``; ``"study + room"`` for a name never learnt as one term).
    region: m̂ = argmax_m p(m | w).
    region_probabilities: (K,) p(m | w).
    samples: (n, 3) sampled poses ``(x, y, θ)``, metres and radians; ``θ = atan2(sin, cos)`` of
        the sampled 4-D vector, NaN when ``xy_only``. The same draws in the input convention
        ``(x, y, sin θ, cos θ)`` are :attr:`poses`.
    regions: (n,) int, the region each sample was drawn from.
    log_density: (n,) log-density of each raw draw (4-D, or x–y when ``xy_only``) under the
        whole mixture Σ_m p(m | w) N(· | μ_m, Σ_m).
    weights: (n,) that density normalised over the ``n`` samples (sums to 1).
    mode: ``"argmax"`` or ``"mixture"``.
    xy_only: whether only the x–y marginal was sampled.
    support: the share of the name's probability in the home that comes from concepts holding
        samples of the home (:func:`name_support`); 1.0 when the parameters carry no concept
        counts.
    learnt: ``support >= LEARNT_SUPPORT`` (for a home file, :func:`spco.knowledge.where`: or ``what``
        answers the name at the centre of ``region``); False means "no such place learnt in this home": the
        region and samples are then the best the model can say, but not knowledge of this home.
    called: when ``learnt`` is False, the name ``what`` answers at the centre of ``region`` (the
        home's own name for the place the poses were drawn from; ``where`` of a home file sets it),
        else None.
    asked: the name asked for when nobody said it and the lexicon found the known name ``name``
        for it (:func:`spco.model.unheard.resolve_name`: "restroom" asked, "toilet" used); else None.
    via: how the lexicon related them (``"synonym"``, ``"gloss"``, …), or None.
    """

    name: str
    region: int
    region_probabilities: np.ndarray
    samples: np.ndarray
    regions: np.ndarray
    log_density: np.ndarray
    weights: np.ndarray
    mode: str
    xy_only: bool
    support: float = 1.0
    learnt: bool = True
    called: str | None = None
    asked: str | None = None
    via: str | None = None

    @property
    def xy(self) -> np.ndarray:
        """(n, 2) sampled x, y in metres."""
        return self.samples[:, :2]

    @property
    def poses(self) -> np.ndarray:
        """(n, 4) the samples as ``(x, y, sin θ, cos θ)``, the convention of the inputs (NaN
        columns 3–4 when ``xy_only``)."""
        theta = self.samples[:, 2]
        return np.column_stack([self.samples[:, :2], np.sin(theta), np.cos(theta)])


# ---------------------------------------------------------------------------------- positions
def query_indices(params: ConceptParameters, vocabulary: Vocabulary, name: str,
                  lookup: np.ndarray | None = None) -> list[int]:
    """Columns of the usable tokens of a name asked for (see :func:`region_posterior_for_name`):
    those of ``lookup`` ((V,) bool, the words a place is looked up by; default ``params.word_mask``)."""
    return _query(params, vocabulary, name, lookup)[1]


def _query(params: ConceptParameters, vocabulary: Vocabulary, name: str, lookup: np.ndarray | None
           ) -> tuple[list[str], list[int], np.ndarray]:
    """The name's tokens (:meth:`Vocabulary.query`), the columns of its usable ones
    (:func:`query_indices`) and the lookup mask (V,) bool; raises :class:`UnknownNameError` if none."""
    _check_vocabulary(params, vocabulary)
    mask = np.asarray(params.word_mask if lookup is None else lookup, dtype=bool)
    if mask.shape != (len(vocabulary),):
        raise ConfigurationError(f"lookup must be a ({len(vocabulary)},) bool array, got {mask.shape}")
    tokens, indices = vocabulary.query(name)
    usable = list(dict.fromkeys(k for k in indices if mask[k]))
    if usable:
        return tokens, usable, mask
    known = [w for w, keep in zip(vocabulary.words, mask, strict=True) if keep]
    if not indices:
        raise UnknownNameError(name, known)
    pruned = ", ".join(repr(vocabulary.words[k]) for k in dict.fromkeys(indices))
    raise UnknownNameError(name, known, reason=f"the word {pruned} was pruned as uninformative (it names "
                           "no place)" if len(set(indices)) == 1 else
                           f"the words {pruned} were pruned as uninformative (they name no place)")


def query_forms(params: ConceptParameters, vocabulary: Vocabulary, name: str,
                lookup: np.ndarray | None = None, alone: bool = True) -> list[list[int]]:
    """The words that say each token of a name asked for (:func:`query_indices`): the token itself,
    and — for a name of one token — every usable learnt term that holds its words side by side
    ("dining" → "dining", "dining room", "dining space"; "living" → "living", "living room").

    The bag of words keeps one token per term: a sentence that says "dining room" holds the token
    "dining room", not "dining". A person asking for "dining" means a place said with that word, so
    p(dining | l) is the probability that a token of concept l holds it, Σ over its forms (disjoint
    events). A name of several tokens keeps its own tokens (each token one form), known or not: "study
    room", never learnt, is "study" and "room" said together, and "bunk room" ("bunk" unknown) is its
    word "room", not every term that holds "room".

    ``alone``: ``name`` is the name as the person asked it. False: it is the known words of a longer
    name nobody said ("spare room", answered by its word "room": :data:`spco.model.unheard.SAID_WORDS`),
    which the lexicon found to be none of the home's names, so its word is only itself."""
    tokens, columns, mask = _query(params, vocabulary, name, lookup)
    if len(columns) != 1 or not alone or len(tokens) != 1:  # "bunk room": "room" known
        return [[k] for k in columns]
    k = columns[0]  # the terms holding it: Vocabulary.terms_holding, kept with the vocabulary
    return [[k, *(j for j in vocabulary.terms_holding(vocabulary.words[k]) if j != k and mask[j])]]


def query_name(vocabulary: Vocabulary, params: ConceptParameters, name: str,
               lookup: np.ndarray | None = None) -> str:
    """How a name asked for is understood: its usable tokens joined by ``" + "`` (``"living room"``,
    or ``"study + room"`` for a name never learnt as one term); :attr:`PositionPrediction.name`."""
    return _understood_as(vocabulary, query_indices(params, vocabulary, name, lookup))


def _understood_as(vocabulary: Vocabulary, columns: list[int]) -> str:
    """The words of the usable tokens' ``columns`` joined by ``" + "`` (:func:`query_name`)."""
    return " + ".join(vocabulary.words[k] for k in columns)


def _occupied_concepts(params: ConceptParameters, e: int) -> np.ndarray:
    """(L,) bool: concepts holding training samples of home ``e`` (mean count ≥ 1); all True when
    the parameters carry no concept counts."""
    if params.concept_counts is None:
        return np.ones(params.n_concepts, dtype=bool)
    return np.asarray(params.concept_counts[e], dtype=np.float64) >= 1.0


def said_word_matrix(params: ConceptParameters, e: int) -> np.ndarray:
    """(L, V) how much each concept of home ``e`` explains a word said there, for ``where``.

    Without word channels: θ^w_{e,l}. With them (:mod:`spco.model.word_channels`): the word as a
    name or as a word of the place, p(name | w) θ^w_{e,l,w} + p(place | w) ψ_{l,w} — "where is the
    fridge" finds the kitchen, "where is the bath" the bath even when people say "bath" mostly as a
    thing ("take a bath"). The background part, the same in every concept, is left out: it cannot
    tell places apart. ``what`` names with θ^w alone
    (:func:`spco.model.word_channels.name_log_probabilities`)."""
    theta = _word_matrix(params, e)
    psi, prior = params.place_word_probabilities, params.word_channel_prior
    if psi is None or prior is None:
        return theta
    prior = np.asarray(prior, dtype=np.float64)
    psi = np.clip(np.asarray(psi, dtype=np.float64), 0.0, 1.0)
    return prior[None, :, 0] * theta + prior[None, :, 1] * psi


def place_word_information(params: ConceptParameters, e: int) -> np.ndarray:
    """(V,) I(w): mutual information (nats) between the indicator "word = w" and the concept, as
    :func:`spco.model.prediction.mutual_information_weights` but with the words as ``where`` reads
    them (:func:`said_word_matrix`: as a name or as a word of the place, ψ): how much a word said
    tells which place it is said at, objects and acts included ("tub", "mirror", "bed"). 0 for a
    pruned word."""
    e = _check_home(params, e)
    said = np.clip(said_word_matrix(params, e), 0.0, 1.0)
    return concept_information(params, e, said * np.asarray(params.word_mask, dtype=bool)[None, :])


def _name_likelihood(params: ConceptParameters, e: int, forms: list[list[int]]) -> np.ndarray:
    """(L,) Π_i Σ_{j ∈ F_i} p(w_j | l): how much each concept of home e explains the tokens said
    together, each token by the words that say it (its forms F_i, :func:`query_forms`;
    :func:`said_word_matrix`), scaled by the largest concept's product (several small p multiply);
    a concept in which a token has probability 0 keeps weight 0."""
    said = said_word_matrix(params, e)
    log_theta = np.zeros(said.shape[0])
    for form in forms:
        log_theta += _safe_log(said[:, form].sum(axis=1))  # (L,)
    top = float(log_theta.max())
    return np.exp(log_theta - top) if top > _LOG_FLOOR else np.zeros_like(log_theta)


def _name_concept_weights(params: ConceptParameters, e: int, forms: list[list[int]]) -> np.ndarray:
    """(L,) G_{e,l} Π_i Σ_{j ∈ F_i} p(w_j | l) (:func:`_name_likelihood`)."""
    g = np.clip(np.asarray(params.concept_weights[e], dtype=np.float64), 0.0, None)
    return g * _name_likelihood(params, e, forms)


def concept_stand_ins(params: ConceptParameters, e: int) -> np.ndarray:
    """(L,) int: the concept of home ``e`` that stands in for each concept when a name is looked for.

    A concept holding samples of the home (``concept_counts`` ≥ 1) stands for itself. A concept with
    none has no place in this home (its π there is its prior), yet it may carry a name the other
    homes say at a place this home has under another concept: people call the bath "bath",
    "bathroom" or "shower", each household its own way, and the sampler learns one concept per name
    (a synonym's samples keep to the concept whose θ^w gives it the most). Such a concept is looked
    for where the home keeps the concept its views would be assigned to: the occupied concept l
    maximising Σ_d φ^v_{l',d} log θ^v_{e,l,d}, the log-likelihood per count of the concept's shared
    view profile φ^v_{l'} (a typical view of it). Views carry thousands of counts per sample, so that
    assignment is a hard choice and this one is too. Identity when no concept is occupied or the
    parameters carry no concept counts.
    """
    e = _check_home(params, e)
    n_concepts = params.n_concepts
    occupied = _occupied_concepts(params, e)
    stand_in = np.arange(n_concepts)
    if occupied.all() or not occupied.any():
        return stand_in
    phi_v = np.clip(np.asarray(params.shared_visual_probabilities, dtype=np.float64), 0.0, None)  # (L, D)
    log_theta_v = _safe_log(np.asarray(params.visual_probabilities[e], dtype=np.float64))  # (L, D)
    fit = phi_v[~occupied] @ log_theta_v[occupied].T  # (unoccupied, occupied)
    stand_in[~occupied] = np.flatnonzero(occupied)[np.argmax(fit, axis=1)]
    return stand_in


def name_support(params: ConceptParameters, e: int, vocabulary: Vocabulary, name: str,
                 lookup: np.ndarray | None = None, alone: bool = True) -> float:
    """Share of p(name | home e) = Σ_l G_{e,l} θ^w_{e,l,w} held by concepts with samples of home e.

    Near 1: the name belongs to places the home's samples were assigned to. Near 0: the name is
    explained by concepts that hold no sample of this home (their θ^w and π come from the prior,
    i.e. from the other homes): no such place was learnt in this home. Returns a float in [0, 1]
    (0 if the name has probability 0 in every concept).
    """
    e = _check_home(params, e)
    return _name_support(params, e, query_forms(params, vocabulary, name, lookup, alone))


def _name_support(params: ConceptParameters, e: int, forms: list[list[int]]) -> float:
    """:func:`name_support` of the name said by ``forms`` (:func:`query_forms`) in home ``e``."""
    weights = _name_concept_weights(params, e, forms)
    total = weights.sum()
    return float(weights[_occupied_concepts(params, e)].sum() / total) if total > 0 else 0.0


def room_said_counts(rooms: HomeRooms, n_regions: int
                     ) -> tuple[np.ndarray, sp.csr_array, sp.csr_array | None]:
    """(R,) the region of each room, (R, V) the name tokens said in it and (R, V) the place-word tokens
    (``None`` without the word channels): each sample's tokens (``rooms.names``, or without the word
    channels ``rooms.words``; ``rooms.places``) in
    proportion to its share in the room (:meth:`HomeRooms.membership`: a taught sample wholly in its
    room, an untaught one shared by the rooms of its region). Kept with ``rooms``."""
    known = rooms._known.get(("said", n_regions))
    if known is not None:
        return known
    share, region_of = rooms.membership(n_regions)
    names = rooms.words if rooms.names is None else rooms.names
    places = None if rooms.places is None else sp.csr_array(share @ rooms.places)
    result = region_of, sp.csr_array(share @ names), places
    rooms._known[("said", n_regions)] = result
    return result


def _dense_said_counts(rooms: HomeRooms, n_regions: int) -> tuple[np.ndarray, np.ndarray | None]:
    """:func:`room_said_counts`' (R, V) name and place-word tokens as dense arrays (tens of rooms by
    hundreds of words), kept with ``rooms``: ``where`` reads a few columns of them per name."""
    known = rooms._known.get(("said-dense", n_regions))
    if known is None:
        _, named, placed = room_said_counts(rooms, n_regions)
        known = named.toarray(), None if placed is None else placed.toarray()
        rooms._known[("said-dense", n_regions)] = known
    return known


def _log_sum_exp(a: np.ndarray, axis: int) -> np.ndarray:
    """log Σ exp(a) along ``axis`` (-inf where every term is -inf): scipy's logsumexp without its
    per-call overhead, for ``where``'s few small arrays per name."""
    top = np.max(a, axis=axis, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        return np.log(np.sum(np.exp(a - top), axis=axis)) + np.squeeze(top, axis=axis)


#: One channel of a room's names for :func:`room_name_log_likelihood`: (a (n,) the share of each token's
#: probability the channel holds, p (L, n) the concepts' probabilities of the tokens, X (R, n) the
#: rooms' counts of the tokens, T (R,) the rooms' counts of every word of the channel).
RoomChannel = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def room_name_log_likelihood(channels: list[RoomChannel], concentration: float | None,
                             forms: list[list[int]] | None = None) -> np.ndarray:
    """(R, L) log p(w_1 … w_n | room k, concept l): each token w_i of a name said in room k through a
    channel c (the names, the words of the place) with probability a_{c,i}, and then drawn from the
    room's own probability of it in that channel, φ_{c,k,w} ~ Beta(δ p_{c,l,w}, δ (1 − p_{c,l,w}))
    around its concept's p_{c,l,w}, given the room's X_{c,k,w} tokens of w among its T_{c,k} tokens
    of the channel (the Dirichlet of the room's words around its concept's, aggregated to w / not w)::

        p(w | room k, l) = Σ_c a_{c,w} (δ p_{c,l,w} + X_{c,k,w}) / (δ + T_{c,k}).

    ``concentration``: δ > 0, or ``None`` (δ → ∞: every room says its concept's Σ_c a_{c,w} p_{c,l,w}).
    ``forms``: the tokens asked for as groups of the n columns (:func:`query_forms`: the words that say
    each token), a token's probability the sum of its forms'; ``None``: each column one token.
    Log space; a probability 0 is the finite floor. Raises :class:`ConfigurationError` for δ ≤ 0 or a
    count outside [0, the room's total]."""
    if not channels:
        raise ConfigurationError("a room's names need at least one channel")
    if concentration is not None and not (np.isfinite(concentration) and concentration > 0):
        raise ConfigurationError(f"the concentration must be a finite number > 0, got {concentration!r}")
    total = None
    for share, probs, counts, totals in channels:
        a = np.clip(np.asarray(share, dtype=np.float64), 0.0, 1.0)  # (n,)
        p = np.clip(np.asarray(probs, dtype=np.float64), 0.0, 1.0)  # (L, n)
        x = np.asarray(counts, dtype=np.float64)  # (R, n)
        tot = np.asarray(totals, dtype=np.float64)  # (R,)
        if concentration is None:
            part = np.broadcast_to((a[None, :] * p)[None, :, :], (x.shape[0], *p.shape))
        else:
            if x.size and (x.min() < 0 or (x > tot[:, None] * (1 + 1e-9) + 1e-9).any()):
                raise ConfigurationError("a room's count of a word must be in [0, the room's total]")
            delta = float(concentration)
            part = a[None, None, :] * (delta * p[None, :, :] + x[:, None, :]) / (delta + tot)[:, None, None]
        total = part if total is None else total + part  # (R, L, n)
    if forms is not None:
        total = np.stack([total[:, :, form].sum(axis=2) for form in forms], axis=2)
    return _safe_log(total).sum(axis=2)


def _room_concepts(params: ConceptParameters, rooms: HomeRooms, view_counts: float | None, e: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R, L) log p(l | room k), (R,) the rooms' samples n_k and (R,) their regions
    (:func:`spco.model.rooms._room_log_posterior` normalised per room), worked out once per ``rooms``
    and ``params`` object as that is: the part of ``where`` that does not depend on the name."""
    from spco.model.rooms import _room_log_posterior

    known = rooms._known.get(("concepts", view_counts, e))
    if known is not None and known[0] is params:
        return known[1]
    log_post, counts, region_of = _room_log_posterior(params, rooms, view_counts, e)
    result = log_post - logsumexp(log_post, axis=1, keepdims=True), counts, region_of
    rooms._known[("concepts", view_counts, e)] = (params, result)
    return result


def _room_weights(params: ConceptParameters, e: int, rooms: HomeRooms, view_counts: float | None,
                  forms: list[list[int]], lookup: np.ndarray) -> np.ndarray | None:
    """(K,) Σ_{k: r(k) = m} n_k Σ_l p(l | room k) p(w | room k, l) (up to a constant), the room
    account's regions for the name's tokens, each said by its ``forms`` (:func:`query_forms`); ``None``
    if no room holds a training sample."""
    log_concept, counts, region_of = _room_concepts(params, rooms, view_counts, e)  # (R, L), (R,), (R,)
    if not counts.sum() > 0:
        return None
    K = int(np.shape(params.region_means)[1])
    R = region_of.size
    words = [j for form in forms for j in form]
    starts = np.cumsum([0, *(len(form) for form in forms)]).tolist()
    groups = [list(range(a, b)) for a, b in pairwise(starts)]
    concentration = rooms.concentration
    theta = _word_matrix(params, e)[:, words]  # (L, n)
    psi, prior = params.place_word_probabilities, params.word_channel_prior
    channel_share = (np.ones(len(words)), None) if psi is None or prior is None else \
        tuple(np.asarray(prior, dtype=np.float64)[words, c] for c in (0, 1))
    mask = np.asarray(lookup, dtype=np.float64)
    read = concentration is not None and rooms.words.shape[1] == mask.size
    named, placed = _dense_said_counts(rooms, K) if read else (None, None)
    channels: list[RoomChannel] = []
    for c, (said, probs) in enumerate(((named, theta), (placed, None if psi is None else
                                                         np.asarray(psi, dtype=np.float64)[:, words]))):
        if probs is None or channel_share[c] is None:
            continue
        if said is None:
            channels.append((channel_share[c], probs, np.zeros((R, len(words))), np.zeros(R)))
        else:
            channels.append((channel_share[c], probs, said[:, words] * mask[None, words], said @ mask))
    log_word = room_name_log_likelihood(channels, concentration if read else None, groups)  # (R, L)
    if not log_word.max() > _LOG_FLOOR:  # the name has probability 0 in every room
        return np.zeros(K)
    log_room = _safe_log(counts) + _log_sum_exp(log_concept + log_word, axis=1)  # (R,)
    log_room = np.where(counts > 0, log_room, -np.inf)
    weights = np.exp(log_room - log_room.max())
    return np.bincount(region_of, weights=weights, minlength=K)


def region_posterior_for_name(
    params: ConceptParameters, e: int, vocabulary: Vocabulary, name: str, *,
    rooms: HomeRooms | None = None, view_counts: float | None = None, lookup: np.ndarray | None = None,
    alone: bool = True,
) -> np.ndarray:
    """p(m | w) ∝ Σ_l p(w | l) p(l, m | home) for the place name ``name``: the one p(region | name)
    (module docstring; ``where``, the service, the ROS node and the experiments' A_p call it).

    ``params`` are the answer's parameters (:func:`spco.model.confidence.answer_parameters`, the
    names ``what`` answers: one account of which concept a name means): p(w | l) is
    :func:`said_word_matrix` of them. ``lookup``: (V,) bool, the words a place is looked up by
    (default ``params.word_mask``; the robot's: the fit's word mask, with the word channels the names
    and the words said mostly as words of a place, "where is the fridge", found through ψ).

    With ``rooms`` (the home's training samples' regions, concepts, views and taught names:
    :func:`spco.knowledge.queries.home_rooms`, :func:`spco.model.rooms.model_rooms`),
    p(l, m | home) is the room account, each room's pooled views worth ``view_counts`` = w draws
    against φ^v (:func:`spco.model.rooms.room_concepts`). Without them (or no room holding a sample)
    p(l, m | home) ∝ G_{e,l} π_{e,l,m} over the concepts holding samples of home ``e``
    (``concept_counts`` ≥ 1), a concept without samples looked for where its stand-in is
    (:func:`concept_stand_ins`), or over all concepts if the name has no probability in those.

    ``name`` is tokenised like a sentence (:meth:`~spco.data.language.Vocabulary.tokenize`:
    ``"Living Room"``, ``"living-room"`` → the token ``"living room"``). A name of several tokens
    (``"study room"`` never learnt as one term) is understood as all its known, unpruned tokens said
    together: p(w_1 … w_n | l) = Π_i p(w_i | l); its unknown or pruned tokens are left out. A name of
    one word is said by every usable learnt term that holds it (:func:`query_forms`; ``alone``).
    Returns (K,) float64 summing to 1. Raises :class:`UnknownNameError` if no token of the name is
    known and unpruned, or the name has probability 0 in every concept of home ``e``.
    """
    e = _check_home(params, e)
    forms = query_forms(params, vocabulary, name, lookup, alone)
    mask = np.asarray(params.word_mask if lookup is None else lookup, dtype=bool)
    return _region_posterior(params, e, vocabulary, name, forms, mask, rooms, view_counts)


def _region_posterior(params: ConceptParameters, e: int, vocabulary: Vocabulary, name: str,
                      forms: list[list[int]], mask: np.ndarray, rooms: HomeRooms | None,
                      view_counts: float | None) -> np.ndarray:
    """:func:`region_posterior_for_name` of the name ``name`` said by ``forms`` (:func:`query_forms`)
    in home ``e``, ``mask`` the words a place is looked up by."""
    weights = None if rooms is None else _room_weights(params, e, rooms, view_counts, forms, mask)
    if weights is None:
        concept_weights = _name_concept_weights(params, e, forms)  # (L,)
        # a concept without samples of this home is looked for where its stand-in is (synonyms)
        concept_weights = np.bincount(concept_stand_ins(params, e), weights=concept_weights,
                                      minlength=concept_weights.size)
        occupied = _occupied_concepts(params, e)
        if (concept_weights[occupied] > 0).any():
            concept_weights = np.where(occupied, concept_weights, 0.0)
        pi = np.clip(np.asarray(params.region_weights[e], dtype=np.float64), 0.0, None)  # (L, K)
        weights = concept_weights @ pi  # (K,)
    total = weights.sum()
    if not total > 0:
        known = [v for v, keep in zip(vocabulary.words, mask, strict=True) if keep]
        shown = " + ".join(vocabulary.words[form[0]] for form in forms)
        raise UnknownNameError(name, known, reason=f"the name {shown!r} has "
                               f"probability 0 in every concept of home {e}")
    return weights / total


def answer_regions(region_probabilities: np.ndarray, n: int) -> np.ndarray:
    """(n,) the regions of ``n`` poses the robot's ``where`` draws: the answer regions — those at least
    half as probable as the best (a name taught at two places of a home finds both) — in proportion
    to their probability, at least one pose per region when ``n`` allows, most probable first."""
    probs = np.asarray(region_probabilities, dtype=np.float64)
    answer = np.flatnonzero(probs >= 0.5 * probs.max())
    answer = answer[np.argsort(-probs[answer], kind="stable")]
    share = probs[answer] / probs[answer].sum()
    per_region = np.floor(share * n).astype(np.int64)
    if n >= answer.size:
        per_region = np.maximum(per_region, 1)
    while per_region.sum() > n:
        per_region[np.argmax(per_region)] -= 1
    while per_region.sum() < n:
        per_region[np.argmax(share * n - per_region)] += 1
    return np.repeat(answer, per_region).astype(np.int64)


def draw_poses(params: ConceptParameters, e: int, region_probabilities: np.ndarray, regions: np.ndarray,
               rng: np.random.Generator, xy_only: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses drawn from the Gaussians of ``regions`` (n,) of home ``e``, one per entry.

    Returns ``samples`` (n, 3) = (x, y, θ) (θ NaN when ``xy_only``: the x–y marginal is drawn),
    ``log_density`` (n,) of each raw draw under the mixture Σ_m p(m) N(· | μ_m, Σ_m) with
    p(m) = ``region_probabilities``, and ``weights`` (n,), that density normalised over the draws.
    """
    n = regions.size
    d = 2 if xy_only else 4
    means = np.asarray(params.region_means[e], dtype=np.float64)[:, :d]
    covs = np.asarray(params.region_covariances[e], dtype=np.float64)[:, :d, :d]
    z = rng.standard_normal((n, d))
    draws = means[regions] + np.einsum("nij,nj->ni", _cholesky(covs)[regions], z)
    if not n:
        return np.empty((0, 3)), np.empty(0), np.empty(0)
    theta = np.full(n, np.nan) if xy_only else np.arctan2(draws[:, 2], draws[:, 3])
    samples = np.column_stack([draws[:, 0], draws[:, 1], theta])
    log_mixture = _safe_log(region_probabilities)[None, :] + gaussian_log_density(draws, means, covs)
    log_density = _log_sum_exp(log_mixture, axis=1)
    return samples, log_density, np.exp(log_density - _log_sum_exp(log_density, axis=0))


def resolve_unheard(params: ConceptParameters, e: int, vocabulary: Vocabulary, name: str,
                    lookup: np.ndarray | None = None) -> ResolvedName | None:
    """The known name the lexicon finds for ``name`` when it is not one usable token
    (:func:`spco.model.unheard.resolve_name`), else ``None``: the one look-up of a name nobody said,
    :func:`predict_positions`' (the robot's ``where`` and the experiments' A_p alike). The candidates
    are the words of ``lookup`` (default ``params.word_mask``), ranked by their mutual information with
    home ``e``'s concepts in ``params`` as names (θ^w) and as ``where`` reads them (names or words of a
    place, ψ), over those same words (worked out only when the name needs the look-up)."""
    mask = np.asarray(params.word_mask if lookup is None else lookup, dtype=bool)
    if said_as_one(vocabulary, mask, name):
        return None
    looked = params if np.array_equal(mask, np.asarray(params.word_mask, dtype=bool)) else \
        replace(params, word_mask=mask)
    return resolve_name(vocabulary, mask, name, params.name_prior,
                        information=mutual_information_weights(looked, e),
                        place_information=place_word_information(looked, e))


def predict_positions(
    params: ConceptParameters,
    e: int,
    vocabulary: Vocabulary,
    name: str,
    n: int = 10,
    rng: np.random.Generator | int | None = None,
    mode: PositionMode = "argmax",
    xy_only: bool = False,
    unheard: bool = True,
    *,
    rooms: HomeRooms | None = None,
    view_counts: float | None = None,
    lookup: np.ndarray | None = None,
    alone: bool = True,
) -> PositionPrediction:
    """Sample ``n`` poses where the place ``name`` is, in home ``e``: the one p(pose | name) of the
    robot's ``where`` and the experiments' A_p (module docstring).

    Parameters
    ----------
    params, rooms, view_counts, lookup: as :func:`region_posterior_for_name` (the robot's: the
        answer's parameters, the home's rooms, the model's view weight w, the fit's word mask).
    mode: ``"answer"`` — the robot's ``where``: the regions of :func:`answer_regions` (those at
        least half as probable as the best, in proportion); ``"argmax"`` — draw from N(μ_m̂, Σ_m̂)
        with m̂ = argmax p(m | w) (the paper's A_p); ``"mixture"`` — draw each sample's region from
        p(m | w) first.
    xy_only: draw from the x–y marginal only (the authors' code); θ is then NaN.
    rng: a Generator (advanced by the draws) or a seed.
    unheard: a name that is not a usable token is first looked up in the lexicon
        (:func:`resolve_unheard`; ``asked`` and ``via`` of the result say so); False: only the name's
        own known tokens are used.
    alone: ``name`` is the name as asked: a name of one word is read by every learnt term that holds
        it (:func:`query_forms`); False for the words of a longer name nobody said (set on the
        lexicon's answer by its own words, :data:`spco.model.unheard.SAID_WORDS`).

    Returns a :class:`PositionPrediction` with samples (n, 3) = (x, y, θ) (``poses``: the same
    as (x, y, sin θ, cos θ)), ``region`` the most probable region, the name's ``support`` in the home
    and ``learnt`` (see the module docstring: False means no such place was learnt in this home).
    """
    if n < 0:
        raise ConfigurationError(f"the number of positions must be >= 0, got {n}")
    if mode not in ("argmax", "mixture", "answer"):
        raise ConfigurationError(f"mode must be 'argmax', 'mixture' or 'answer', got {mode!r}")
    e = _check_home(params, e)
    resolved = resolve_unheard(params, e, vocabulary, name, lookup) if unheard else None
    if resolved is not None:  # a name nobody said: the known name the lexicon finds for it
        pred = predict_positions(params, e, vocabulary, resolved.name, n, rng, mode, xy_only, unheard=False,
                                 rooms=rooms, view_counts=view_counts, lookup=lookup,
                                 alone=resolved.how != SAID_WORDS)
        return replace(pred, asked=resolved.asked, via=resolved.how)
    forms = query_forms(params, vocabulary, name, lookup, alone)  # once, for the regions and the support
    probs = _region_posterior(params, e, vocabulary, name, forms,
                              np.asarray(params.word_mask if lookup is None else lookup, dtype=bool),
                              rooms, view_counts)
    support = _name_support(params, e, forms)
    best = int(np.argmax(probs))
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    if mode == "argmax":
        regions = np.full(n, best, dtype=np.int64)
    elif mode == "answer":
        regions = answer_regions(probs, n)
    else:
        regions = gen.choice(probs.size, size=n, p=probs).astype(np.int64)
    samples, log_density, weights = draw_poses(params, e, probs, regions, gen, xy_only)
    return PositionPrediction(
        name=_understood_as(vocabulary, [form[0] for form in forms]),  # a form's first word is its token
        region=best,
        region_probabilities=probs,
        samples=samples,
        regions=regions,
        log_density=log_density,
        weights=weights,
        mode=mode,
        xy_only=bool(xy_only),
        support=support,
        learnt=support >= LEARNT_SUPPORT,
    )
