"""How well a set of visual distributions explains a home's views: the numbers behind the
knowledge's view-fit diagnostics (:mod:`spco.knowledge.diagnostics`), computed where the homes are
(a shard scores its own homes, :meth:`spco.model.shard.HomeShard.held_out_view_fits`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.model.hyperparameters import view_powers
from spco.model.state import PreparedData

__all__ = [
    "TYPICALITY_GRID",
    "VIEW_WEIGHT_GRID",
    "concept_visual_totals",
    "estimate_view_weight",
    "held_out_view_fits",
    "home_concept_totals",
    "room_typicality",
    "view_fit",
    "view_weight_losses",
]


def view_fit(log_phi_visual: np.ndarray, log_g0: np.ndarray, visual: Any) -> float | None:
    """How well a knowledge's visual distributions explain a home's views:
    :data:`spco.knowledge.diagnostics.VIEW_FIT_MEASURE`.

    Parameters
    ----------
    log_phi_visual: (L, D) log φ^v; log_g0: (L,) log G_0; visual: (n, D) counts (sparse or dense).

    Returns the median over the views with at least one count of their per-count log-likelihood under
    the mixture Σ_l G_0,l Mult(v | φ^v_l) (without the multinomial coefficient), plus log D; ``None``
    if no view has a count. About 0.6–0.8 (synthetic homes) and 0.9–1.4 (SIGVerse fc7) for homes
    like the experienced ones; negative for views from another feature extractor or distribution.
    """
    counts = sp.csr_array(visual, dtype=np.float64)
    totals = np.asarray(counts.sum(axis=1)).ravel()
    seen = totals > 0
    if not seen.any():
        return None
    log_phi = np.maximum(np.asarray(log_phi_visual, dtype=np.float64), np.log(np.finfo(float).tiny))
    per_concept = np.asarray(counts[seen] @ log_phi.T)  # (n, L): Σ_d v_d log φ_l,d
    mixture = logsumexp(per_concept + np.asarray(log_g0, dtype=np.float64)[None, :], axis=1)
    return float(np.median(mixture / totals[seen]) + math.log(log_phi.shape[1]))


def _home_concept_counts(data: PreparedData, concepts: np.ndarray, e: int,
                         n_concepts: int) -> np.ndarray:
    """Home ``e``'s visual counts by concept, (L, D) n_{e,l,d}."""
    rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
    n = rows.stop - rows.start
    onehot = sp.csr_array((np.ones(n), (concepts[rows], np.arange(n))), shape=(n_concepts, n))
    return np.asarray((onehot @ sp.csr_array(data.visual[rows], dtype=np.float64)).todense())


def concept_visual_totals(data: PreparedData, concepts: np.ndarray, n_concepts: int) -> np.ndarray:
    """The visual counts of each concept summed over the homes of ``data``, (L,) N_l (summed over
    shards, the totals of all homes: integers, so the sum is exact in any order)."""
    return sum((_home_concept_counts(data, concepts, e, n_concepts).sum(1) for e in range(data.n_homes)),
               np.zeros(n_concepts))


def held_out_view_fits(log_phi_v: np.ndarray, log_g0: np.ndarray, totals: np.ndarray,
                       data: PreparedData, concepts: np.ndarray) -> list[float | None]:
    """The held-out :func:`view_fit` of every home of ``data``, ``totals`` the (L,) visual counts by
    concept of all homes of the fit.

    A home's views helped to learn φ^v, so their fit under φ^v itself flatters them. Each home is
    scored instead under φ^v without its own counts: φ^v_l × (N_l + D) − n_{e,l} (N_l the counts
    of concept l over all homes, n_{e,l} home e's, with the concepts of the chain's last sweep, to
    which φ^v is aligned), floored at 1 % of φ^v_l × (N_l + D) and renormalised.
    """
    L, D = log_phi_v.shape
    mass = np.exp(log_phi_v) * (totals + D)[:, None]
    fits = []
    for e in range(data.n_homes):  # a loop over homes, each scored as a whole
        held_out = np.maximum(mass - _home_concept_counts(data, concepts, e, L), 0.01 * mass)
        log_held_out = np.log(held_out / held_out.sum(1, keepdims=True))
        rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
        fits.append(view_fit(log_held_out, log_g0, data.visual[rows]))
    return fits


#: The view weights w the estimate chooses from: √2 steps from 1/16 to 2^14 counts (a grid, not a
#: search: the leave-one-home-out loss is flat within a step).
VIEW_WEIGHT_GRID = tuple(float(2.0 ** (k / 2)) for k in range(-8, 29))


def home_concept_totals(data: PreparedData, concepts: np.ndarray, n_concepts: int
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the view-weight estimate needs of the homes of ``data``, summed over them: (L, D) their
    visual counts by concept (every sample), (L,) their *taught* samples with a view by concept, and
    (L, V) the word counts of those taught samples by concept (what the estimate predicts)."""
    counts = sum((_home_concept_counts(data, concepts, e, n_concepts) for e in range(data.n_homes)),
                 np.zeros((n_concepts, data.visual.shape[1])))
    labelled = _labelled(data)
    taught = np.bincount(concepts[labelled], minlength=n_concepts).astype(np.float64)
    return counts, taught, _concept_words(data, concepts, labelled, n_concepts)


def _concept_words(data: PreparedData, concepts: np.ndarray, rows: np.ndarray, n_concepts: int) -> np.ndarray:
    """(L, V) the word counts of the samples ``rows`` (bool or indices) by concept."""
    rows = np.flatnonzero(rows) if rows.dtype == bool else rows
    onehot = sp.csr_array((np.ones(rows.size), (concepts[rows], np.arange(rows.size))),
                          shape=(n_concepts, rows.size))
    return np.asarray((onehot @ sp.csr_array(data.words[rows], dtype=np.float64)).todense(), dtype=np.float64)


def _labelled(data: PreparedData) -> np.ndarray:
    """(N,) bool: the samples the estimate predicts — taught (a sentence) and seen."""
    has_words = np.diff(data.words.indptr) > 0 if data.words.shape[1] else np.zeros(data.n_samples, bool)
    return has_words & (data.view_totals > 0)


def view_weight_losses(data: PreparedData, concepts: np.ndarray, totals: np.ndarray, taught: np.ndarray,
                       words: np.ndarray, alpha_visual: float, alpha_word: float,
                       grid: tuple[float, ...] = VIEW_WEIGHT_GRID, places: np.ndarray | None = None
                       ) -> tuple[np.ndarray, int]:
    """The leave-one-home-out log loss of what was taught at each of ``data``'s taught views given
    the view, for every view weight w of ``grid``: summed over the views, and how many views.

    ``places`` (N,) int, optional: each sample's place within its home (a room; ``-1``: none). With
    them a view is predicted as the room account answers it (:mod:`spco.model.rooms`): from its
    place's *other* views pooled into one count vector, worth w draws, and the view itself, worth w
    draws, p(l | room, v) ∝ p(l) exp(ω_R Σ_d R_d log φ^v_{l,d} + ω Σ_d v_d log φ^v_{l,d}) with R the
    place's views without v and ω_R = min(1, w / Σ_d R_d) — the weight at which a room's evidence
    predicts a home the weight's choice did not see.

    Each home e is predicted from the other homes only: φ^v_l ∝ α^v + N_l − n_{e,l} (the visual
    counts of concept l in all homes, ``totals`` (L, D), without e's own), φ^w_l ∝ α^w + W_l − w_{e,l}
    (the taught word counts of concept l, ``words`` (L, V), without e's own) and p(l) ∝
    T_l − t_{e,l} + 1/L (``taught`` (L,): the taught views by concept in all homes). A taught view
    v with the words u scores −log p(u | v) + log p(u) with

        p(u | v) = Σ_l p(l | v) Π_w φ^w_{l,w}^{u_w},
        p(l | v) ∝ p(l) exp(min(1, w / Σ_d v_d) Σ_d v_d log φ^v_{l,d}),

    the view counting as w draws (log p(u), the words without the view, does not depend on w: it
    makes the loss the information the view gives about the words, 0 for a view that says nothing).
    What is predicted is what was observed — the words — not the concept the sampler's start put
    the sample in: a start that splits one place over two concepts (or holds two places in one)
    leaves the words' predictive, and so the estimate, as it is. Homes of another shard contribute
    through ``totals``, ``taught`` and ``words`` only.
    """
    losses = np.zeros(len(grid))
    used = 0
    for given_view, without in _held_out_answers(data, concepts, totals, taught, words, alpha_visual,
                                                 alpha_word, grid, places):
        losses += (without[None, :] - given_view).sum(axis=1)
        used += without.size
    return losses, used


def _held_out_answers(data: PreparedData, concepts: np.ndarray, totals: np.ndarray, taught: np.ndarray,
                      words: np.ndarray, alpha_visual: float, alpha_word: float, grid: tuple[float, ...],
                      places: np.ndarray | None) -> Any:
    """Per home with taught views, (G, n) log p(u | v) at each weight of ``grid`` and (n,) log p(u)
    of its taught views, the home left out (:func:`view_weight_losses`, which sums them)."""
    L = totals.shape[0]
    labelled = _labelled(data)
    weights = np.asarray(grid, dtype=np.float64)
    for e in range(data.n_homes):  # a loop over homes, each left out in turn
        rows = np.flatnonzero(labelled & (data.homes == e))
        if rows.size == 0:
            continue
        own = _home_concept_counts(data, concepts, e, L)
        others = np.maximum(totals - own, 0.0) + alpha_visual
        log_phi = np.log(others) - np.log(others.sum(1, keepdims=True))
        own_taught = np.bincount(concepts[rows], minlength=L)
        log_prior = np.log(np.maximum(taught - own_taught, 0.0) + 1.0 / L)
        log_prior -= logsumexp(log_prior)
        other_words = np.maximum(words - _concept_words(data, concepts, rows, L), 0.0) + alpha_word
        log_phi_w = np.log(other_words) - np.log(other_words.sum(1, keepdims=True))
        said = np.asarray(sp.csr_array(data.words[rows], dtype=np.float64) @ log_phi_w.T)  # (n, L)
        visual = sp.csr_array(data.visual[rows], dtype=np.float64)
        loglik = np.asarray(visual @ log_phi.T)  # (n, L)
        scale = view_powers(data.view_totals[rows][None, :], weights[:, None])  # (G, n)
        scores = scale[:, :, None] * loglik[None] + log_prior[None, None, :]  # (G, n, L)
        if places is not None:  # the view's place's other views pooled, one piece of evidence at w
            rest, rest_totals = _place_rest(data, places, e, rows, log_phi, loglik)
            scores += view_powers(rest_totals[None, :], weights[:, None])[:, :, None] * rest[None]
        given_view = logsumexp(scores + said[None], axis=2) - logsumexp(scores, axis=2)  # log p(u | v)
        without = logsumexp(log_prior[None, :] + said, axis=1)  # log p(u)
        yield given_view, without


def _place_rest(data: PreparedData, places: np.ndarray, e: int, rows: np.ndarray, log_phi: np.ndarray,
                loglik: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n, L) Σ_d R_d log φ^v_{l,d} and (n,) Σ_d R_d for the samples ``rows`` of home ``e``, R the
    pooled views of the sample's place without its own view (:func:`view_weight_losses`' ``places``;
    ``loglik`` (n, L): the rows' own Σ_d v_d log φ^v_{l,d}). A sample without a place: R = 0."""
    home = np.arange(int(data.offsets[e]), int(data.offsets[e + 1]))
    own = np.asarray(places, dtype=np.int64)[home]
    if own.size == 0 or own.max() < 0:
        return np.zeros_like(loglik), np.zeros(rows.size)
    kept = own >= 0
    n_places = int(own.max()) + 1
    onehot = sp.csr_array((np.ones(int(kept.sum())), (own[kept], home[kept] - home[0])),
                          shape=(n_places, home.size))
    visual = sp.csr_array(data.visual[home], dtype=np.float64)
    pooled = np.asarray(onehot @ visual @ log_phi.T)  # (P, L)
    pooled_totals = np.asarray(onehot @ data.view_totals[home], dtype=np.float64).ravel()  # (P,)
    place = np.asarray(places, dtype=np.int64)[rows]
    has = place >= 0
    rest = np.zeros_like(loglik)
    rest[has] = pooled[place[has]] - loglik[has]
    rest_totals = np.zeros(rows.size)
    rest_totals[has] = pooled_totals[place[has]] - data.view_totals[rows][has]
    return rest, np.maximum(rest_totals, 0.0)


def estimate_view_weight(losses: np.ndarray, used: int, grid: tuple[float, ...] = VIEW_WEIGHT_GRID
                         ) -> float | None:
    """The view weight of least leave-one-home-out log loss (:func:`view_weight_losses`, summed over
    every shard's homes); ``None`` when no home had a taught view (nothing to estimate from). Of the
    weights within 0.001 nats per view of the least loss, the smallest: where the loss is flat
    (views that every weight above some w places right) the homes give no reason
    for more evidence than that w, and a new home unlike them would pay for it."""
    if used == 0 or not np.isfinite(losses).all():
        return None
    least = np.flatnonzero(losses <= losses.min() + 1e-3 * used)
    return float(grid[int(least[0])])


#: The typicalities ρ :func:`room_typicality` chooses from: 1 − ρ in √2 steps from 2^−½ to 2^−20, and 1.
TYPICALITY_GRID = tuple([1.0 - 2.0 ** (-k / 2) for k in range(1, 41)] + [1.0])


def room_typicality(visual: Sequence[Any], places: Sequence[Sequence[str]], log_phi_words: np.ndarray,
                    log_g0: np.ndarray, vocabulary: Sequence[str], alpha_visual: float, alpha_word: float,
                    view_weight: float, grid: tuple[float, ...] = TYPICALITY_GRID
                    ) -> tuple[float | None, np.ndarray, int]:
    """ρ, how often a room looks like its concept, learnt from the experienced homes (opt-in;
    docs/model.md, "Opt-in: a room that looks like another concept"): a room is *typical* with
    probability ρ — its pooled views and a view in it are evidence at ``view_weight`` w against its
    concept's φ^v — and otherwise looks like a concept drawn from the prior, unrelated to what it is.

    Each experienced home is left out in turn, as the room account's answers are (the same φ^v_{−e},
    p_{−e}(l), p_{−e}(name | l), a place's concept its name's), and its samples' names are predicted
    from their place's other views pooled and their own view, each at w: under the mixture

        p(name | R, v) = ρ Σ_l p_{−e}(l | R, v) p_{−e}(name | l) + (1 − ρ) Σ_l p_{−e}(l) p_{−e}(name | l)

    (the atypical room's views are a draw of a concept l' ~ p(l'), whatever its own concept: they say
    nothing of it). ρ is the value of ``grid`` of least summed log loss.

    Returns (ρ, losses, used): ρ (``None``: no sample to learn from), (G,) the summed loss
    −log p(name | R, v) + log p(name) at each ρ, and how many samples were predicted.
    """
    data, concepts, place_ids = _experienced_rooms(visual, places, log_phi_words, log_g0, vocabulary)
    rho = np.asarray(grid, dtype=np.float64)
    if data is None:
        return None, np.full(rho.size, np.nan), 0
    if not (np.isfinite(rho).all() and (rho > 0).all() and (rho <= 1).all()):
        from spco.errors import ConfigurationError

        raise ConfigurationError("room typicality: every ρ of the grid must be within (0, 1]")
    totals, taught, words = home_concept_totals(data, concepts, np.asarray(log_g0).size)
    losses = np.zeros(rho.size)
    used = 0
    with np.errstate(divide="ignore"):
        log_rho, log_rest = np.log(rho), np.log1p(-rho)
    for given_view, without in _held_out_answers(data, concepts, totals, taught, words, alpha_visual,
                                                 alpha_word, (float(view_weight),), place_ids):
        mixed = np.logaddexp(log_rho[:, None] + given_view, log_rest[:, None] + without[None, :])
        losses += (without[None, :] - mixed).sum(axis=1)
        used += without.size
    if used == 0:
        return None, losses, 0
    return float(rho[int(np.argmin(losses))]), losses, used


def _experienced_rooms(visual: Sequence[Any], places: Sequence[Sequence[str]], log_phi_words: np.ndarray,
                       log_g0: np.ndarray, vocabulary: Sequence[str]
                       ) -> tuple[PreparedData | None, np.ndarray, np.ndarray]:
    """The experienced homes' samples with a known place name as (data, concepts, places): one name
    token each, its concept argmax_l G_0,l φ^w_{l,name}, its place's index within its home
    (:func:`room_typicality`); data ``None`` when no name is known."""
    from spco.errors import ConfigurationError

    phi = np.asarray(log_phi_words, dtype=np.float64)
    g0 = np.asarray(log_g0, dtype=np.float64).ravel()
    if phi.ndim != 2 or phi.shape[0] != g0.size or phi.shape[1] != len(vocabulary):
        raise ConfigurationError(f"the experienced rooms: log_phi_words {phi.shape} does not match log_g0 "
                                 f"({g0.size},) and a vocabulary of {len(vocabulary)} words")
    if len(visual) != len(places) or not visual:
        raise ConfigurationError(f"the experienced rooms: {len(visual)} homes' views but {len(places)} "
                                 "homes' "
                                 "places (one entry per experienced home, at least one)")
    index = {w: i for i, w in enumerate(vocabulary)}
    rows_v, names, place_ids, homes = [], [], [], []
    for e, (views, labels) in enumerate(zip(visual, places, strict=True)):
        views = sp.csr_array(views, dtype=np.float64)
        if views.shape[0] != len(labels):
            raise ConfigurationError(f"the experienced rooms: home {e} has {views.shape[0]} views but "
                                     f"{len(labels)} place names")
        known = np.array([label in index for label in labels], dtype=bool)
        own = sorted({label for label in labels if label in index})
        rows_v.append(views[np.flatnonzero(known)])
        names += [index[label] for label in labels if label in index]
        place_ids += [own.index(label) for label in labels if label in index]
        homes += [e] * int(known.sum())
    name = np.asarray(names, dtype=np.int64)
    if name.size == 0:
        return None, name, name
    E, N = len(visual), name.size
    homes_a = np.asarray(homes, dtype=np.int64)
    concepts = np.argmax(g0[:, None] + phi[:, name], axis=0)  # (N,) each place name's concept
    data = PreparedData(positions=np.zeros((N, 4)), homes=homes_a, visual=sp.csr_array(sp.vstack(rows_v)),
                        words=sp.csr_array((np.ones(N), (np.arange(N), name)), shape=(N, len(vocabulary))),
                        n_homes=E, offsets=np.searchsorted(homes_a, np.arange(E + 1)), position_scale=1.0,
                        map_centres=np.zeros((E, 4)))
    return data, concepts, np.asarray(place_ids, dtype=np.int64)
