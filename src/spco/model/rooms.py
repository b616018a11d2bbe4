"""A room's evidence: which concept a home's room is, with the room's views as one piece of evidence.

The sampler decides each sample's concept from its own view (weighted as the model's view weight w,
:meth:`~spco.model.hyperparameters.TransferHyperparameters.view_weight`) and its region, so a room's
~20 views count as 20 independent pieces of evidence about which concept the room is. They are not:
a room's views pooled are worth about as many draws as one view (leave-one-home-out on the
experienced homes; docs/model.md, "A room's evidence"), and a room that looks like another room's
concept is put there, and answered, with certainty.

The room account (how the robot answers: :func:`spco.model.confidence.answer_concepts`, through
:func:`spco.model.confidence.answer_names`'s ``rooms`` for ``what``, ``ask``, the service, the ROS node
and the experiments) judges an observation's concept from two pieces of evidence, each worth the
model's w draws: the room it is in — the room's training views pooled into one count vector
(:func:`room_concepts`) — and its own view, both against the shared visual distributions φ^v (the
concepts as the experienced homes taught them, not the home's own θ^v, which already holds the room's
views), with the prior G_0 and the names taught in the room (each taught name token counted as θ^w
counts it, S^w draws from θ^w of the concept: a name taught in a room decides the room's concept). A
*room* is a region of the sampler's state, split by the names taught in it, or where nothing was
taught by the sampler's concepts (:meth:`HomeRooms.membership`): a region where two names were taught
into two concepts (a room taught "tub room" and "shower room") holds two rooms, each at the region's
Gaussian; a region where one name was taught is one room. The observation is in room k with prior
p(k | x) ∝ n_k N(x | μ_r(k), Σ_r(k)) (n_k the room's training samples, r(k) its region); room k is of
concept l with p(l | room k) ∝ G_0,l · exp(ω_k Σ_d V_{k,d} log φ^v_{l,d}) · Π_{t ∈ k} Π_w
θ^w_{e,l,w}^{u_{t,w}}; and the view is drawn from the room's concept,
p(v | l) = exp(ω_v Σ_d v_d log φ^v_{l,d}). So

    P(l | x, v) ∝ Σ_k p(k | x) p(l | room k) p(v | l),

ω_k = min(1, w / Σ_d V_{k,d}) with V_k the room's pooled counts, ω_v = min(1, w / Σ_d v_d): two
pieces of evidence where the home's π and θ^v hold twenty-one. The view weighs in on which room the
pose is in as well as on the room's concept (the sum over k is normalised jointly): a view unlike
everything the room at the pose looks like says the robot is in the room next door.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.errors import ConfigurationError
from spco.model.hyperparameters import view_powers
from spco.model.parameters import ConceptParameters
from spco.model.prediction import _safe_log, _visual_log_likelihood

__all__ = ["HomeRooms", "concepts_by_room", "model_rooms", "room_concepts", "sample_rooms"]


@dataclass(frozen=True)
class HomeRooms:
    """What the room-level answer needs of a home's training samples.

    Attributes
    ----------
    regions: (n,) int, the region of each training sample (the sampler's state).
    visual: (n, D) the samples' view counts (a missing view: an empty row).
    words: (n, V) the name tokens taught at each sample (untaught: an empty row).
    concepts: (n,) int, the concept of each sample (the sampler's state), or ``None``. With them a
        region is split by the names taught in it (:meth:`membership`); without them a room is a
        region.
    names, places: (n, V) the tokens said at each sample as names and as words of the place (the word
        channels' expected tokens, :func:`spco.model.word_channels.channel_token_counts`), in the
        counts θ^w and ψ count a token with, or ``None`` (no word channels: ``words`` are the names).
    concentration: δ, how many counts a concept's names (θ^w) and place words (ψ) weigh as against
        a room's own ``names`` and ``places`` in the room's names (δ^w: a room's names are drawn around
        its concept's as a home's around the experienced homes';
        :func:`spco.model.position_prediction.region_posterior_for_name`); ``None``: a room's own
        words are not read by ``where``.
    """

    regions: np.ndarray
    visual: sp.csr_array
    words: sp.csr_array
    concepts: np.ndarray | None = None
    names: sp.csr_array | None = None
    places: sp.csr_array | None = None
    concentration: float | None = None
    #: the rooms' evidence already worked out, per answer's parameters (:func:`_room_log_posterior`):
    #: ``(view_counts, e) -> (params, result)``, kept only while the same ``params`` object is asked
    _known: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def of(cls, regions: object, visual: object, words: object, concepts: object = None, *,
           names: object = None, places: object = None, concentration: float | None = None) -> HomeRooms:
        """Validated :class:`HomeRooms` (sparse copies of ``visual``, ``words``, ``names`` and ``places``)."""
        regions = np.asarray(regions, dtype=np.int64).ravel()
        visual = sp.csr_array(visual, dtype=np.float64)
        words = sp.csr_array(words, dtype=np.float64)
        if visual.shape[0] != regions.size or words.shape[0] != regions.size:
            raise ConfigurationError(f"rooms: {regions.size} regions but {visual.shape[0]} views and "
                                     f"{words.shape[0]} word rows")
        said = []
        for label, counts in (("name", names), ("place word", places)):
            rows = None if counts is None else sp.csr_array(counts, dtype=np.float64)
            if rows is not None and rows.shape != words.shape:
                raise ConfigurationError(f"rooms: {words.shape} word counts but {rows.shape} {label} counts")
            if rows is not None and rows.nnz and not (np.isfinite(rows.data).all() and rows.data.min() >= 0):
                raise ConfigurationError(f"rooms: the {label} counts must be finite counts >= 0")
            said.append(rows)
        if concentration is not None and not (np.isfinite(concentration) and concentration > 0):
            raise ConfigurationError(f"rooms: the concentration must be a finite number > 0, got "
                                     f"{concentration!r}")
        if regions.size and regions.min() < 0:
            raise ConfigurationError("rooms: a region index is negative")
        labels = None
        if concepts is not None:
            labels = np.asarray(concepts, dtype=np.int64).ravel()
            if labels.size != regions.size:
                raise ConfigurationError(f"rooms: {regions.size} regions but {labels.size} concepts")
            if labels.size and labels.min() < 0:
                raise ConfigurationError("rooms: a concept index is negative")
        return cls(regions, visual, words, labels, said[0], said[1],
                   None if concentration is None else float(concentration))

    def subset(self, keep: np.ndarray) -> HomeRooms:
        """The rooms of the samples ``keep`` (a bool mask or indices), e.g. one sample left out."""
        return HomeRooms.of(self.regions[keep], self.visual[keep], self.words[keep],
                            None if self.concepts is None else self.concepts[keep],
                            names=None if self.names is None else self.names[keep],
                            places=None if self.places is None else self.places[keep],
                            concentration=self.concentration)

    def membership(self, n_regions: int) -> tuple[sp.csr_array, np.ndarray]:
        """(R, n) each sample's share in each room and (R,) the region of each room.

        Without ``concepts`` the rooms are the regions 0..``n_regions``-1. With them a region is split
        by the names taught in it: each concept holding taught samples (a name token) of the region is
        a room, holding those samples and the region's untaught samples (whole in its pooled views, in
        proportion to its taught samples in its size n_k): a region where "tub room" was said three
        times and "shower room" once, the sampler giving each name its concept, is two rooms, 3 : 1.
        A region where names of one concept were taught is one room (the name decides it); a region
        where nothing was taught is a room per concept of its samples (a region reaching over a wall
        into another place holds two rooms). Worked out once per ``n_regions`` (kept with the rooms)."""
        known = self._known.get(("membership", n_regions))
        if known is None:
            known = self._known[("membership", n_regions)] = self._membership(n_regions)
        return known

    def members(self, n_regions: int) -> sp.csr_array:
        """(R, n) 1 where a sample is in a room (:meth:`membership`'s shares made whole: a room's views
        and names are each member's whole counts). Worked out once per ``n_regions``."""
        known = self._known.get(("members", n_regions))
        if known is None:
            known = self.membership(n_regions)[0].copy()
            known.data[:] = 1.0
            self._known[("members", n_regions)] = known
        return known

    def _membership(self, n_regions: int) -> tuple[sp.csr_array, np.ndarray]:
        """:meth:`membership` worked out."""
        n = self.regions.size
        if self.concepts is None:
            return sp.csr_array((np.ones(n), (self.regions, np.arange(n))), shape=(n_regions, n)), \
                np.arange(n_regions)
        taught = np.diff(self.words.indptr) > 0
        rows: list[int] = []
        cols: list[int] = []
        vals: list[float] = []
        region_of: list[int] = []
        for r in np.unique(self.regions):
            members = np.flatnonzero(self.regions == r)
            said = members[taught[members]]
            groups = np.unique(self.concepts[said])
            if groups.size <= 1:  # nothing taught: a room per concept; one name's concept: the region
                parts = np.unique(self.concepts[members]) if groups.size == 0 else np.array([-1])
                for c in parts:
                    own = members if c < 0 else members[self.concepts[members] == c]
                    rows += [len(region_of)] * own.size
                    cols += own.tolist()
                    vals += [1.0] * own.size
                    region_of.append(int(r))
                continue
            untaught = members[~taught[members]]
            for c in groups:
                own = said[self.concepts[said] == c]
                share = own.size / said.size
                rows += [len(region_of)] * (own.size + untaught.size)
                cols += own.tolist() + untaught.tolist()
                vals += [1.0] * own.size + [share] * untaught.size
                region_of.append(int(r))
        R = len(region_of)
        index = (np.asarray(rows, dtype=np.int64), np.asarray(cols, dtype=np.int64))
        return sp.csr_array((np.asarray(vals), index), shape=(R, n)), np.asarray(region_of, dtype=np.int64)


def _room_log_posterior(params: ConceptParameters, rooms: HomeRooms, view_counts: float | None,
                        e: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R, L) log G_0 + each room's pooled views at w against φ^v + its taught name tokens under θ^w
    (unnormalised); (R,) training samples per room; (R,) each room's region. Worked out once per
    ``rooms`` and ``params`` object (both are read, never written, so a live home that answers from the
    same two objects — :func:`spco.knowledge.queries.name_prediction` — pays for it once per state)."""
    known = rooms._known.get((view_counts, e))
    if known is not None and known[0] is params:
        return known[1]
    result = _room_evidence(params, rooms, view_counts, e)
    rooms._known[(view_counts, e)] = (params, result)
    return result


def _room_evidence(params: ConceptParameters, rooms: HomeRooms, view_counts: float | None,
                   e: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_room_log_posterior` worked out."""
    K = int(np.shape(params.region_means)[1])
    if rooms.regions.size and rooms.regions.max() >= K:
        raise ConfigurationError(f"rooms: region {int(rooms.regions.max())} but the model has {K}")
    if rooms.concepts is not None and rooms.concepts.size and rooms.concepts.max() >= params.n_concepts:
        raise ConfigurationError(f"rooms: concept {int(rooms.concepts.max())} but the model has "
                                 f"{params.n_concepts}")
    share, region_of = rooms.membership(K)  # (R, n) each sample's share in each room
    R = region_of.size
    onehot = rooms.members(K)  # the room's views and names: each member's whole (counts stay counts)
    log_post = np.broadcast_to(_safe_log(params.global_concept_weights)[None, :],
                               (R, params.n_concepts)).copy()
    phi_v = np.asarray(params.shared_visual_probabilities, dtype=np.float64)
    if phi_v.size and rooms.visual.shape[1] == phi_v.shape[1]:  # the room's views pooled: one view at w
        log_post += _pooled_views_log(phi_v, onehot, rooms, view_counts)
    names = np.asarray(params.word_mask, dtype=bool)
    if rooms.words.nnz and names.any() and rooms.words.shape[1] == names.size:
        theta = np.clip(np.asarray(params.word_probabilities[e], dtype=np.float64), 0.0, None)
        theta = theta * names[None, :]
        theta /= np.maximum(theta.sum(axis=1, keepdims=True), np.finfo(np.float64).tiny)
        said = sp.csr_array(onehot @ (rooms.words @ sp.diags_array(names.astype(np.float64))))
        log_post += np.asarray(said @ _safe_log(theta).T)
    counts = np.asarray(share.sum(axis=1), dtype=np.float64).ravel()  # n_k: the shares
    return log_post, counts, region_of


def _pooled_views_log(phi_v: np.ndarray, onehot: sp.csr_array, rooms: HomeRooms, view_counts: float | None
                      ) -> np.ndarray:
    """(R, L) each room's training views pooled into one count vector (``onehot`` (R, n): the rooms'
    members) against φ^v, worth w = ``view_counts`` draws."""
    return _visual_log_likelihood(phi_v, sp.csr_array(onehot @ rooms.visual), view_counts)


def room_concepts(params: ConceptParameters, e: int, rooms: HomeRooms, view_counts: float | None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Each room's concept, its views pooled as one piece of evidence (module docstring).

    Parameters
    ----------
    params: the answer's parameters (their θ^w and ``word_mask``: the names the home answers).
    e: the home; rooms: its training samples' regions (and concepts), views and taught name tokens.
    view_counts: the model's view weight w (``None``: every count a draw).

    Returns
    -------
    counts: (R,) training samples per room; posterior: (R, L) p(l | room k), rows sum to 1 (a room
    without samples: G_0). Without ``rooms.concepts`` the rooms are the model's K regions.
    """
    log_post, counts, _ = _room_log_posterior(params, rooms, view_counts, e)
    return counts, np.exp(log_post - logsumexp(log_post, axis=1, keepdims=True))


def concepts_by_room(params: ConceptParameters, e: int, positions: np.ndarray, visual: object,
                     rooms: HomeRooms, view_counts: float | None, view_in_room: bool = False,
                     typical: float | None = None) -> np.ndarray | None:
    """(n, L) P(l | x, v) ∝ Σ_k p(k | x) p(l | room k) p(v | l) at poses ``positions`` (n, 4) of home
    ``e`` with views ``visual`` (n, D; ``None`` or an empty row: no view), p(k | x) ∝ n_k N(x | μ_r(k),
    Σ_r(k)) over the rooms with training samples (r(k) the room's region), p(l | room k) ∝ G_0,l ·
    (room k's pooled views at w) · (its taught names) and p(v | l) the view at w, both against φ^v
    (module docstring); ``None`` if no room has a training sample (the caller answers from the view
    and the pose against the home's parameters instead).

    ``view_in_room`` (opt-in, measured on development views: docs/model.md, "A room's evidence"): the
    view is drawn from its room's own visual distribution η_k rather than from the concept's φ^v,
    η_k ~ Dir(w φ^v_l) — the room about as informative of its concept as the w draws its pooled views
    count as — so p(v | k, l) = Mult(v | η̂_{k,l})^{ω_v} with η̂_{k,l} = (w φ^v_l + Ñ_k) / (w + |Ñ_k|)
    its posterior mean given the room's training views Ñ_k, each worth w (:func:`_room_view_log`):
    the view says which room the pose is in, and little more about the room's concept than its
    room's views already said. Needs a view weight w.

    ``typical`` (opt-in, ρ within (0, 1]; docs/model.md, "Opt-in: a room that looks like another
    concept"): a room looks like its concept with probability ρ; otherwise its views — its pooled
    views and the observation's view — are those of a concept l' ~ G_0 drawn whatever its own concept
    is, and say nothing of it. Room k's term p(l | room k) p(v | l) becomes

        π_k(l) [ρ S_k(l) p(v | l) + (1 − ρ) Σ_l' G_0,l' S_k(l') p(v | l')] / Z_k,

    π_k(l) ∝ G_0,l (its taught names) the room's evidence but its views, S_k(l) its pooled views at w
    against φ^v_l, Z_k = Σ_l π_k(l) [ρ S_k(l) + (1 − ρ) Σ_l' G_0,l' S_k(l')] (the room's own views'
    likelihood, as the room account normalises p(l | room k)); ρ = 1 is the room account. Learnt
    from the experienced homes by :func:`spco.model.view_fit.room_typicality`."""
    from spco.model.prediction import gaussian_log_density, validate_poses

    if typical is not None:
        if not (isinstance(typical, float | int) and 0.0 < float(typical) <= 1.0):
            raise ConfigurationError(f"typical must be a number within (0, 1], got {typical!r}")
        if view_in_room:
            raise ConfigurationError("typical: not with view_in_room (one opt-in at a time)")

    room_log, counts, region_of = _room_log_posterior(params, rooms, view_counts, e)  # (R, L) unnormalised
    if not (counts > 0).any():
        return None
    x = validate_poses(positions)
    with np.errstate(over="ignore", invalid="ignore"):
        log_n = gaussian_log_density(x, params.region_means[e], params.region_covariances[e])  # (n, K)
    log_k = np.where(counts[None, :] > 0, log_n[:, region_of] + _safe_log(counts)[None, :], -np.inf)
    total = logsumexp(log_k, axis=1, keepdims=True)
    if not np.isfinite(total).all():
        i = int(np.flatnonzero(~np.isfinite(total).ravel())[0])
        raise ConfigurationError(f"observation {i} at {tuple(float(v) for v in x[i, :2])}: every region's "
                                 f"density is 0 in floating point; is the position on the home's map, in "
                                 f"metres?")
    view_log = np.zeros((x.shape[0], params.n_concepts))
    phi_v = np.asarray(params.shared_visual_probabilities, dtype=np.float64)
    has_view = visual is not None and phi_v.size > 0
    if has_view:
        view_log = _visual_log_likelihood(phi_v, visual, view_counts)
        if view_log.shape[0] != x.shape[0]:
            raise ConfigurationError(f"{x.shape[0]} positions but {view_log.shape[0]} visual feature rows")
    if view_in_room and view_counts is None:
        raise ConfigurationError("view_in_room needs the model's view weight w (view_counts), got None")
    # log p(k | x) + log p(l | room k) + log p(v | l): the view weighs in on the room as on its concept
    # (a view unlike everything room k looks like says the pose is not in room k)
    room_norm = room_log - logsumexp(room_log, axis=1, keepdims=True)  # (R, L) log p(l | room k)
    joint = np.full((x.shape[0], params.n_concepts), -np.inf)
    if typical is not None:
        room_terms = _atypical_rooms(params, rooms, room_log, view_log, view_counts, float(typical))
    for k in np.flatnonzero(counts > 0):  # a loop over the home's rooms (tens)
        if has_view and view_in_room:
            view_log = _room_view_log(phi_v, rooms, k, visual, float(view_counts),  # type: ignore[arg-type]
                                      int(np.shape(params.region_means)[1]))
        if typical is None:
            joint = np.logaddexp(joint, (log_k[:, [k]] - total) + room_norm[k][None, :] + view_log)
        else:
            joint = np.logaddexp(joint, (log_k[:, [k]] - total) + room_terms(k))
    return np.exp(joint - logsumexp(joint, axis=1, keepdims=True))


def _atypical_rooms(params: ConceptParameters, rooms: HomeRooms, room_log: np.ndarray, view_log: np.ndarray,
                    view_counts: float | None, typical: float) -> Any:
    """k -> (n, L) log of room k's term under :func:`concepts_by_room`'s ``typical`` = ρ, given
    ``room_log`` (R, L) the rooms' unnormalised log p(l | room k) and ``view_log`` (n, L) log p(v | l)."""
    phi_v = np.asarray(params.shared_visual_probabilities, dtype=np.float64)
    views = np.zeros_like(room_log)
    if phi_v.size and rooms.visual.shape[1] == phi_v.shape[1]:
        onehot = rooms.members(int(np.shape(params.region_means)[1]))
        views = _pooled_views_log(phi_v, onehot, rooms, view_counts)  # (R, L) log S_k(l)
    rest = room_log - views  # log π_k(l), unnormalised
    log_g0 = _safe_log(params.global_concept_weights)
    with np.errstate(divide="ignore"):
        log_rho, log_other = np.log(typical), np.log1p(-typical)

    def term(k: int) -> np.ndarray:
        seen = views[k][None, :] + view_log  # (n, L) log S_k(l) p(v | l)
        other = logsumexp(log_g0[None, :] + seen, axis=1, keepdims=True)  # a concept l' ~ G_0's
        alone = np.logaddexp(log_rho + views[k], log_other + logsumexp(log_g0 + views[k]))
        return rest[k][None, :] + np.logaddexp(log_rho + seen, log_other + other) \
            - logsumexp(rest[k] + alone)
    return term


def _room_view_log(phi_v: np.ndarray, rooms: HomeRooms, k: int, visual: object, view_counts: float,
                   n_regions: int) -> np.ndarray:
    """(n, L) log p(v | room k, l) = ω_v Σ_d v_d log η̂_{k,l,d}: each view of ``visual`` (n, D) as a draw
    of room k's own distribution, η̂_{k,l} = (w φ^v_l + Ñ_k) / (w + |Ñ_k|), the posterior mean of
    η_k ~ Dir(w φ^v_l) given the room's training views Ñ_k = Σ_{t ∈ k} ω_t v_t (each worth w; a room
    without views: φ^v_l), with w = ``view_counts``; k a room of :meth:`HomeRooms.membership` of
    ``n_regions`` (:func:`concepts_by_room`, ``view_in_room``)."""
    weighted = rooms._known.get(("view_in_room", view_counts, n_regions))
    if weighted is None:  # (R, D) each room's training views, each worth w draws
        onehot = rooms.members(n_regions)
        totals = np.asarray(rooms.visual.sum(axis=1), dtype=np.float64).ravel()
        powers = np.zeros_like(totals)
        seen = totals > 0
        powers[seen] = view_powers(totals[seen], view_counts)
        weighted = np.asarray((onehot @ (sp.diags_array(powers) @ rooms.visual)).toarray(), dtype=np.float64)
        rooms._known[("view_in_room", view_counts, n_regions)] = weighted
    own = weighted[k] if k < weighted.shape[0] else np.zeros(phi_v.shape[1])
    eta = (view_counts * phi_v + own[None, :]) / (view_counts + own.sum())
    return _visual_log_likelihood(eta, visual, view_counts)


def sample_rooms(data: object, state: object, concentration: float | None, rows: slice | None = None
                 ) -> HomeRooms:
    """:class:`HomeRooms` of the training samples ``rows`` (default: all) of a sampler's data
    (:class:`~spco.model.gibbs.PreparedData`: ``words``, ``homes``, ``visual``) and state
    (:class:`~spco.model.gibbs.GibbsState`: ``regions``, ``concepts``, and with the word channels
    ``channels``, ``switches`` and ``log_theta_w``): the one builder of the rooms every answer reads,
    a robot's home's (:func:`spco.knowledge.queries.home_rooms`) and a joint fit's home's
    (:func:`model_rooms`, the experiments').

    The rooms' name tokens are the tokens the sampler drew as names (with the word channels;
    :func:`~spco.model.word_channels.name_tokens`), and ``names`` and ``places`` each sample's
    expected tokens per channel (:func:`~spco.model.word_channels.channel_token_counts`), as θ^w and
    ψ count them; ``concentration``: δ^w (``None``: a room's own words are not read by ``where``)."""
    from spco.model.word_channels import channel_token_counts, name_tokens

    rows = slice(None) if rows is None else rows
    words = data.words  # type: ignore[attr-defined]
    channels = getattr(state, "channels", None)
    switches = getattr(state, "switches", None)
    if channels is not None and switches is not None and words.nnz:
        words = name_tokens(words, switches)  # (the switches run over every token: slice after)
    names = places = None
    concepts = np.asarray(state.concepts)[rows]  # type: ignore[attr-defined]
    if channels is not None:
        names, places = channel_token_counts(sp.csr_array(data.words[rows]),  # type: ignore[attr-defined]
                                             np.asarray(data.homes)[rows], concepts,  # type: ignore[attr-defined]
                                             state.log_theta_w, channels)  # type: ignore[attr-defined]
    return HomeRooms.of(np.asarray(state.regions)[rows], data.visual[rows], words[rows],  # type: ignore[attr-defined]
                        concepts, names=names, places=places, concentration=concentration)


def model_rooms(model: object, e: int) -> HomeRooms:
    """:class:`HomeRooms` of home ``e`` of a fitted joint model
    (:class:`~spco.model.transfer.SpatialConceptModel`, the experiments' fit): :func:`sample_rooms` of
    its training samples of the home, with its δ^w, so that an experiment scores the names the robot
    answers (:func:`spco.model.confidence.answer_names`). Needs the sampler's state (``state_``,
    ``data_``: a fitted model, not one loaded from a file)."""
    from spco.model.word_channels import rooms_concentration

    data = model.data_  # type: ignore[attr-defined]
    rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
    concentration = rooms_concentration(model.hyperparameters_, float(model.word_increment_))  # type: ignore[attr-defined]
    return sample_rooms(data, model.state_, concentration, rows)  # type: ignore[attr-defined]
