"""A home's layout as evidence for its rooms: which concepts a home holds at all (opt-in).

The room account (:mod:`spco.model.rooms`) judges each room's concept p(l | room k) independently. A
home is not a bag of independent rooms: the experienced homes each hold a washroom, a kitchen, a
bedroom. The layout prior replaces the independent rooms by one joint distribution over the concepts
l_1 … l_R of a home's R rooms (the rooms of :meth:`~spco.model.rooms.HomeRooms.membership` with
training samples),

    p(l_1 … l_R | evidence) ∝ Π_k p(l_k | room k) · Π_l g_l(1[some room is of concept l]),

with p(l_k | room k) the room account's unnormalised room posterior (G_0, the room's pooled views, its
taught names) and g_l the **presence prior** of concept l: whether a home holds concept l at all,
g_l(1) = P_l(present), g_l(0) = 1 − P_l(present), learnt from the experienced homes
(:func:`layout_prior`). Each room's marginal p(l_k | all rooms' evidence) is computed exactly
(:func:`room_marginals`) and used where p(l | room k) is used.

Why presence and not a count of rooms: the new home's rooms are the sampler's regions (split by the
names taught in them), and one place of a home — a kitchen — is several regions (2LDK_6's kitchen is
4 regions of 3–6 views each with colour-hog and 4 experienced homes), while the experienced homes'
places are known by their names (their rooms as the sampler saw them are not kept in the knowledge).
A count of rooms learnt from places would not match what the new home's rooms are; whether a concept
holds *any* room is the same whether the units are places or regions, so that is what is learnt.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from spco.errors import ConfigurationError

__all__ = ["MAX_LAYOUT_STATES", "NEGLIGIBLE", "LayoutPrior", "layout_prior", "room_marginals"]

#: the largest R · 2^L (rooms × sets of concepts present) :func:`room_marginals` works through
#: (2^22 ≈ 4·10^6 log values per table, ~34 MB); above it the layout is refused with the reason
MAX_LAYOUT_STATES = 2**22
#: the largest bound ε on the neglected share of the joint with which :func:`room_marginals` leaves
#: concepts out of its dynamic programme (they enter to first order)
NEGLIGIBLE = 1e-12


@dataclass(frozen=True)
class LayoutPrior:
    """The presence prior of each concept (:func:`layout_prior`).

    Attributes
    ----------
    log_present: (L,) log P_l(a home holds concept l in some room).
    log_absent: (L,) log (1 − P_l).
    """

    log_present: np.ndarray
    log_absent: np.ndarray

    @classmethod
    def of(cls, present: object) -> LayoutPrior:
        """The prior of presence probabilities ``present`` (L,), each within (0, 1)."""
        p = np.asarray(present, dtype=np.float64).ravel()
        if p.size == 0 or not (np.isfinite(p).all() and (p > 0).all() and (p < 1).all()):
            raise ConfigurationError("layout: each concept's presence probability must be within (0, 1) "
                                     "(open), got " + np.array2string(p, precision=3))
        return cls(np.log(p), np.log1p(-p))

    @property
    def n_concepts(self) -> int:
        """L, the concepts the prior covers."""
        return int(self.log_present.size)


def layout_prior(log_phi_words: np.ndarray, log_g0: np.ndarray, vocabulary: Sequence[str],
                 homes_places: Sequence[Sequence[str]], smoothing: float = 0.5) -> LayoutPrior:
    """The presence prior learnt from the experienced homes.

    Each experienced home's places are its distinct place names (the names taught there: a SIGVerse
    home's labels). A place named ``n`` is of concept l with p(l | n) ∝ G_0,l φ^w_{l,n} (the knowledge's
    G_0 and φ^w); home e holds concept l with probability 1 − Π_{places n of e} (1 − p(l | n)), and
    P_l(present) = (Σ_e P(home e holds l) + s) / (E + 2 s) — the posterior mean under a Beta(s, s)
    prior (s = ``smoothing``, Jeffreys' 0.5 by default), never 0 or 1.

    Parameters
    ----------
    log_phi_words: (L, V) log φ^w; log_g0: (L,) log G_0; vocabulary: the V words of φ^w's columns.
    homes_places: per experienced home, its place names (a name not in the vocabulary is skipped).
    smoothing: s > 0.
    """
    phi = np.asarray(log_phi_words, dtype=np.float64)
    g0 = np.asarray(log_g0, dtype=np.float64).ravel()
    if phi.ndim != 2 or phi.shape[0] != g0.size or phi.shape[1] != len(vocabulary):
        raise ConfigurationError(f"layout: log_phi_words {phi.shape} does not match log_g0 ({g0.size},) "
                                 f"and a vocabulary of {len(vocabulary)} words")
    if not (np.isfinite(smoothing) and smoothing > 0):
        raise ConfigurationError(f"layout: smoothing must be a finite number > 0, got {smoothing!r}")
    if not homes_places:
        raise ConfigurationError("layout: homes_places is empty (no experienced home to learn from)")
    index = {w: i for i, w in enumerate(vocabulary)}
    held = np.zeros(g0.size)
    for places in homes_places:
        log_absent = np.zeros(g0.size)
        for name in sorted(set(places)):
            if name not in index:
                continue
            post = g0 + phi[:, index[name]]
            post = np.exp(post - logsumexp(post))
            log_absent += np.log1p(-np.minimum(post, 1.0 - 1e-15))
        held += -np.expm1(log_absent)
    return LayoutPrior.of((held + smoothing) / (len(homes_places) + 2.0 * smoothing))


def room_marginals(room_log: np.ndarray, prior: LayoutPrior) -> np.ndarray:
    """(R, L) log p(l_k = l | all rooms' evidence) under the layout prior.

    ``room_log`` (R, L): each room's unnormalised log p(l | room k) (−inf allowed; each row needs a
    finite entry). The joint ∝ Π_k exp(room_log[k, l_k]) Π_l g_l(1[l ∈ {l_1 … l_R}]) is summed by
    dynamic programming over the rooms with the set S of concepts used so far (forward α_k(S),
    backward β_k(S): R · L' · 2^L' steps), in log space, over the L' concepts some room gives a weight
    within :data:`NEGLIGIBLE` nats of its best. A concept c no room comes that near (a weight below
    e^−60 of every room's best) enters to first order: p(l_k = c | …) = e^{room_log[k, c]} ·
    g_c(1)/g_c(0) · Z_{−k} / Z (Z_{−k}: the other rooms' sum), which neglects only terms smaller by
    another such factor (relative error below R · e^−60 · max_c g_c(1)/g_c(0), ~10^−24 for 16 rooms and
    16 homes) — its marginal stays, tiny, so that an observation's own view can still outweigh it.
    Refuses (ConfigurationError) when R · 2^L' exceeds :data:`MAX_LAYOUT_STATES`."""
    E = np.asarray(room_log, dtype=np.float64)
    if E.ndim != 2 or E.shape[1] != prior.n_concepts:
        raise ConfigurationError(f"layout: room_log {E.shape} but the prior covers {prior.n_concepts} "
                                 "concepts")
    R = E.shape[0]
    if R == 0:
        return E.copy()
    if np.isnan(E).any() or not np.isfinite(E.max(axis=1)).all():
        raise ConfigurationError("layout: room_log holds NaN or a room without a finite concept weight")
    E = E - E.max(axis=1, keepdims=True)  # each room's scale (cancels in its marginal)
    near = _concepts_in_play(E, prior)  # the concepts the DP works through
    L = near.size
    if R * 2**L > MAX_LAYOUT_STATES:
        raise ConfigurationError(f"layout: {R} rooms and {L} concepts in play need R·2^L = {R * 2**L:,} "
                                 f"states, above the bound {MAX_LAYOUT_STATES:,} (MAX_LAYOUT_STATES)")
    far = np.setdiff1d(np.arange(E.shape[1]), near)
    En = E[:, near]
    present, absent = prior.log_present[near], prior.log_absent[near]
    sets = np.arange(2**L, dtype=np.int64)
    bits = [(sets >> c) & 1 == 1 for c in range(L)]  # (2^L,) does S hold concept c
    final = np.zeros(2**L)  # log Π_l g_l(S) over the concepts in play (the others: absent, a constant)
    for c in range(L):
        final += np.where(bits[c], present[c], absent[c])
    alpha = np.full((R + 1, 2**L), -np.inf)
    alpha[0, 0] = 0.0
    for k in range(R):
        step = np.full(2**L, -np.inf)
        for c in range(L):  # S' = S ∪ {c}: S' holds c, S = S' or S' without c
            if not np.isfinite(En[k, c]):
                continue
            into = np.logaddexp(alpha[k], alpha[k, sets ^ (1 << c)]) + En[k, c]
            step = np.logaddexp(step, np.where(bits[c], into, -np.inf))
        alpha[k + 1] = step
    log_z = logsumexp(alpha[R] + final)
    beta = final.copy()
    out = np.full(E.shape, -np.inf)
    odds = prior.log_present[far] - prior.log_absent[far]
    for k in range(R - 1, -1, -1):  # beta = β_{k+1}(S): the rooms after k given S used so far
        out[k, far] = E[k, far] + odds + logsumexp(alpha[k] + beta) - log_z  # first order (docstring)
        new_beta = np.full(2**L, -np.inf)
        for c in range(L):
            if not np.isfinite(En[k, c]):
                continue
            ahead = beta[sets | (1 << c)] + En[k, c]
            out[k, near[c]] = logsumexp(alpha[k] + ahead) - log_z
            new_beta = np.logaddexp(new_beta, ahead)
        beta = new_beta
    return out - logsumexp(out, axis=1, keepdims=True)


def _concepts_in_play(E: np.ndarray, prior: LayoutPrior) -> np.ndarray:
    """The concepts :func:`room_marginals` works through exactly: all but the least weighty, left out
    while ε = M Σ_{k, c left out} e^{E[k, c]} g_c(1)/g_c(0) stays ≤ :data:`NEGLIGIBLE` (``E``: each row's
    best 0)."""
    odds = prior.log_present - prior.log_absent
    log_m = max(0.0, float(np.max(-odds)))
    with np.errstate(divide="ignore"):
        weight = logsumexp(E, axis=0) + odds + log_m  # (L,) log of each concept's share of ε
    order = np.argsort(weight)  # least weighty first
    spent = np.logaddexp.accumulate(weight[order])
    dropped = order[spent <= np.log(NEGLIGIBLE)]
    return np.setdiff1d(np.arange(E.shape[1]), dropped)
