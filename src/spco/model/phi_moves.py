"""The power target's φ^v-marginal block move (issue 29): a home's blocks of samples change concept
with θ^v and φ^v integrated out given the other homes, so a new home's places can leave a concept
the chain's φ^v draw holds them in (``block_moves="phi"``, with ``target="power"``).

Why. Under the power target a new home's places lump into one concept: each single-sample step and
the region block moves (:mod:`spco.model.blocks`) condition on a φ^v draw that is near zero wherever
a concept's tables are thin, so moving a place there costs hundreds of nats, while the model with θ^v
and φ^v integrated out prefers the true rooms by +1,073 to +1,415 nats on development data
(benchmarks/README.md, "Issue 29: the power target's lump with θ^v and φ^v integrated out").

The move, for one home e on each sweep its schedule names (:func:`phi_moves_due`; e drawn uniformly
from the homes taught nothing, or from every home if each is taught: :func:`moved_homes`), after the
sweep's statistics:

1. the other homes' tables M_{−e} (CRT of ⌊n_{−e}⌋ given the current φ^v) and fractions F_{−e}
   are drawn as the φ^v step draws them (:meth:`HierarchicalMultinomial.table_parts`);
2. the blocks of home e — each (region, concept) pair's samples, as in :mod:`spco.model.blocks` —
   are visited in the order of their lowest samples; a block B of concept l in region k proposes a
   concept l' among the free ones — those no sample of home e holds in region k, so a block never
   joins another — with probability ∝ exp(τ s_{l'}) (:data:`PROPOSAL_TEMPERATURE`; s its counts'
   log-likelihood under the mean of Dir(α + M + F) plus its words'), and is accepted with
   probability min(1, e^{Δ + ln q(l | B at l') − ln q(l' | B at l)}) (the free set seen from l'
   holds l instead of l'), where

       Δ = P_{l'}(n_{e,l'} + b) − P_{l'}(n_{e,l'}) + P_l(n_{e,l} − b) − P_l(n_{e,l})
           + ln Γ(g_{l'} + N_{l'} + |B|) − ln Γ(g_{l'} + N_{l'}) − ln Γ(β + N_{l'} + |B|) + ln Γ(β + N_{l'})
           − [the same for l, with N_l counted without B]
           + Σ_{t ∈ B} [ℓ^w_t(l') − ℓ^w_t(l)],

   b the block's weighted counts Σ_{t∈B} ω_t v_t, P_c(n) = ln p(n | M_{−e}, n_{−e}) the concept's
   view evidence with θ^v_{e,c} and φ^v_c integrated out (:class:`spco.model.phi_evidence.ConceptGrid`,
   exact for real counts: the fractional weight w of the other homes' real counts included), N the
   home's samples per concept outside B, g = γ G_0, β the regions' concentration (G_e ~ Dir(γ G_0) and
   π_{e,l} ~ Dir(β/K) integrated out, as in :mod:`spco.model.blocks`), ℓ^w_t the sample's word
   log-likelihood given θ^w (and the channels, switches summed out; 0 for an untaught sample);
3. the word switches are redrawn given the new concepts, and the statistics recounted;
4. φ^v is drawn by the φ^v step with the tables M_{−e} + M_e (M_e the CRT tables of home e's new
   counts) and its Metropolis–Hastings test over every home's real counts
   (:func:`phi_after_move`); then the home step draws θ^v, G_e and π as always.

This is the partially collapsed Gibbs order (van Dyk & Park 2008) of the sketch. One caveat, which
the enumerated-posterior test (tests/test_power_target.py) checks empirically rather than proves:
with real counts the φ^v draw of step 4 is itself a Metropolis–Hastings step started at the
previous φ^v, not an independent draw from its conditional, so the composition is exact only in so
far as that step forgets its start (van Dyk & Jiao 2015). The regions, θ^w and the word channels
are conditioned on; G_e, π, θ^v and φ^v are redrawn after the move, before anything conditions on
them.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.special import gammaln, logsumexp

from spco.model.assignments import concept_loglik, home_concept_concentration, view_weights
from spco.model.blocks import region_blocks
from spco.model.observations import HierarchicalMultinomial
from spco.model.phi_evidence import ConceptGrid
from spco.model.sweep_statistics import sufficient_statistics
from spco.model.word_channels import sample_switches

__all__ = ["HomeMove", "move_home", "phi_after_move", "phi_block_step", "phi_moves_due", "sharded_phi_move"]


#: τ of the proposal: a block proposes a free concept c with probability ∝ exp(τ s_c), s_c its
#: counts' log-likelihood under the mean of φ_c's proposal Dir(α + M + F) plus its words'; the
#: Hastings ratio corrects for it (the free set seen from the target holds the source instead).
#: τ < 1 keeps proposals going to the concepts that score well without letting a summary that is
#: off by tens of nats decide alone.
PROPOSAL_TEMPERATURE = 0.5


class HomeMove:
    """The state of one home's φ^v-marginal block moves: its counts per concept, the concepts'
    evidence grids (built when a block first touches the concept) and the assignment prior's counts.

    ``n_e`` (L, D) the home's weighted view counts; ``others`` (E', L, D) the other homes' real counts;
    ``pseudo`` (L, D) α + M_{−e} + F_{−e}; ``counts`` (L,) the home's samples per concept; ``g`` (L,)
    γ G_0; ``beta`` β."""

    def __init__(self, n_e: np.ndarray, others: np.ndarray, pseudo: np.ndarray, delta: float,
                 counts: np.ndarray, g: np.ndarray, beta: float) -> None:
        self.n_e = np.array(n_e, dtype=np.float64)
        self.others, self.pseudo, self.delta = others, pseudo, float(delta)
        self.counts = np.array(counts, dtype=np.int64)
        self.g, self.beta = np.asarray(g, dtype=np.float64), float(beta)
        self.bound = self.n_e.sum(axis=0)  # no concept can hold more than the whole home
        self.grids: dict[int, ConceptGrid] = {}
        self.current: dict[int, float] = {}

    def grid(self, c: int) -> ConceptGrid:
        """Concept c's evidence grid given the other homes (built once per move pass)."""
        if c not in self.grids:
            self.grids[c] = ConceptGrid(self.pseudo[c], self.others[:, c], self.delta, self.bound)
        return self.grids[c]

    def evidence(self, c: int, n: np.ndarray | None = None) -> float:
        """P_c(n): the view evidence of counts n (default: the home's counts of c) in concept c."""
        if n is None:
            if c not in self.current:
                self.current[c] = self.grid(c).log_predictive(self.n_e[c])
            return self.current[c]
        return self.grid(c).log_predictive(n)

    def _prior(self, c: int, outside: int, size: int) -> float:
        g = self.g[c]
        if not g + outside > 0.0:  # G_{e,c} ~ Dir(γ G_0) puts no mass on an empty concept with G_0,c = 0
            return -math.inf
        return (math.lgamma(g + outside + size) - math.lgamma(g + outside)
                - math.lgamma(self.beta + outside + size) + math.lgamma(self.beta + outside))

    def log_ratio(self, block: np.ndarray, size: int, source: int, target: int,
                  word_delta: float = 0.0) -> tuple[float, np.ndarray, np.ndarray]:
        """Δ of moving a block (weighted counts ``block`` (D,), ``size`` samples) from concept
        ``source`` to ``target`` (module docstring), and the two concepts' counts after the move."""
        moved_to = self.n_e[target] + block
        if self.counts[source] == size:
            left = np.zeros_like(block)
        else:
            left = np.maximum(self.n_e[source] - block, 0.0)
        delta = (self.evidence(target, moved_to) - self.evidence(target)
                 + self.evidence(source, left) - self.evidence(source)
                 + self._prior(target, int(self.counts[target]), size)
                 - self._prior(source, int(self.counts[source]) - size, size) + word_delta)
        return delta, moved_to, left

    def apply(self, source: int, target: int, size: int, moved_to: np.ndarray, left: np.ndarray) -> None:
        """Carry out a move :meth:`log_ratio` priced."""
        self.n_e[target], self.n_e[source] = moved_to, left
        self.counts[target] += size
        self.counts[source] -= size
        self.current.pop(target, None)
        self.current.pop(source, None)


def home_pass(move: HomeMove, visual: sp.csr_array, weights: np.ndarray, concepts: np.ndarray,
              regions: np.ndarray, word_ll: np.ndarray, n_regions: int,
              rng: np.random.Generator) -> tuple[np.ndarray, int]:
    """One pass of the move over a home's blocks (module docstring, step 2): ``visual`` (n, D) its
    samples' views, ``weights`` (n,) their powers ω, ``concepts``, ``regions`` (n,), ``word_ll``
    (n, L) their word log-likelihoods. Returns the new concepts and the number of accepted moves."""
    n_samples, n_concepts = word_ll.shape
    concepts = concepts.copy()
    if n_samples == 0:
        return concepts, 0
    block, first = region_blocks(np.zeros(n_samples, dtype=np.int64), concepts, regions, n_concepts,
                                 n_regions)
    members = sp.csr_array((np.ones(n_samples), (block, np.arange(n_samples))), shape=(first.size, n_samples))
    block_counts = np.asarray((members @ sp.csr_array(visual.multiply(weights[:, None]))).todense())
    block_words = members @ word_ll
    log_mean = np.log(move.pseudo) - np.log(move.pseudo.sum(axis=1, keepdims=True))
    score = PROPOSAL_TEMPERATURE * (block_counts @ log_mean.T + block_words)  # (blocks, L)
    size = np.bincount(block, minlength=first.size)
    occupied = np.zeros((n_regions, n_concepts), dtype=bool)
    occupied[regions, concepts] = True
    block_concept = concepts[first].copy()
    accepted = 0
    for b in range(first.size):
        k, source = regions[first[b]], block_concept[b]
        free = np.flatnonzero(~occupied[k] & (move.g > 0))
        if free.size == 0:
            continue
        weights_b = score[b, free] - score[b, free].max()
        p = np.exp(weights_b)
        target = int(free[min(int(np.searchsorted(np.cumsum(p), rng.random() * p.sum(), side="right")),
                              free.size - 1)])
        back = np.append(free[free != target], source)  # the free concepts seen from the target
        log_q = ((score[b, source] - logsumexp(score[b, back]))
                 - (score[b, target] - logsumexp(score[b, free])))
        log_u = math.log(rng.random())
        delta, moved_to, left = move.log_ratio(block_counts[b], int(size[b]), int(source), target,
                                               float(block_words[b, target] - block_words[b, source]))
        delta += log_q
        if log_u < delta:
            move.apply(int(source), target, int(size[b]), moved_to, left)
            occupied[k, source], occupied[k, target] = False, True
            block_concept[b] = target
            accepted += 1
    return block_concept[block], accepted


def moved_homes(data) -> np.ndarray:
    """The homes the move draws from: those taught nothing (no sample with a word: a new home, whose
    places only its views tell apart, where the lump forms), or every home if each is taught."""
    return move_candidates(taught_homes(data))


def taught_homes(data) -> np.ndarray:
    """(E,) whether each home of ``data`` has a sample with a word."""
    has_words = np.diff(data.words.indptr) > 0
    return np.array([has_words[data.offsets[e]:data.offsets[e + 1]].any() for e in range(data.n_homes)],
                    dtype=bool)


def move_candidates(taught: np.ndarray) -> np.ndarray:
    """The homes the move draws from, given which homes are taught (E,): the untaught, or every home
    if each is taught."""
    untaught = np.flatnonzero(~np.asarray(taught, dtype=bool))
    return untaught if untaught.size else np.arange(len(taught))


def phi_moves_due(iteration: int, hyper) -> bool:
    """Whether sweep number ``iteration`` (0-based) runs the φ^v-marginal block moves: a multiple of
    ``hyper.phi_every``, and below ``hyper.phi_until`` when it is set. The schedule is fixed in
    advance (it depends on the sweep's number only, never on the state), so each sweep is a
    composition of steps that each keep the target, and the chain keeps it."""
    every = int(getattr(hyper, "phi_every", 1))
    until = getattr(hyper, "phi_until", None)
    return iteration % every == 0 and (until is None or iteration < int(until))


def phi_block_step(data, state, stats, hyper, settings, rng: np.random.Generator):
    """Steps 1–3 of the module docstring on one home drawn uniformly from :func:`moved_homes`: returns
    the statistics (recounted if a block moved) and the other homes' tables (M_{−e}, F_{−e}, H_{−e}, e)
    for :func:`phi_after_move`."""
    e = int(rng.choice(moved_homes(data)))
    others = np.ascontiguousarray(np.delete(np.asarray(stats.visual), e, axis=0))
    tables = HierarchicalMultinomial.table_parts(others, state.log_phi_v, hyper.delta_visual, rng)
    stats, _ = move_home(data, state, stats, hyper, settings, e, others, tables, rng)
    return stats, (*tables, e)


def move_home(data, state, stats, hyper, settings, e: int, others: np.ndarray, tables,
              rng: np.random.Generator):
    """Steps 2–3 of the module docstring for home ``e`` of ``data``, given the other homes' real
    counts ``others`` (E', L, D) and their tables ``tables`` (M_{−e}, F_{−e}, H_{−e}) drawn given
    the state's φ^v: one pass over the home's blocks, then (if a block moved) its word switches
    redrawn and the statistics recounted. Returns the statistics and the number of accepted moves.
    The single-process sweep (:func:`phi_block_step`) and a home's shard in the sharded fit
    (:meth:`spco.model.shard.HomeShard.phi_move`) both run it."""
    rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
    pseudo = hyper.alpha_visual + tables[0] + tables[1]
    prior = home_concept_concentration(state, hyper, settings)
    move = HomeMove(stats.visual[e], others, pseudo, hyper.delta_visual, stats.concepts[e], prior, hyper.beta)
    weights = view_weights(data, settings.learning_view_counts())
    weights = np.ones(data.n_samples) if weights is None else weights
    word_ll = _word_log_likelihood(data, state, settings, rows)
    concepts, accepted = home_pass(move, sp.csr_array(data.visual[rows]), weights[rows], state.concepts[rows],
                                   state.regions[rows], word_ll, state.log_pi.shape[2], rng)
    if accepted:
        state.concepts = state.concepts.copy()
        state.concepts[rows] = concepts
        if state.channels is not None:  # each token's switch given its sample's new concept
            state.switches = sample_switches(data.words, data.homes, state.concepts, state.log_theta_w,
                                             state.channels, rng)
        stats = sufficient_statistics(data, state, hyper, settings.learning_view_counts())
    return stats, accepted


def sharded_phi_move(call, log_phi_v: np.ndarray, hyper, rng: np.random.Generator):
    """The driver's side of the move in the sharded fit (:func:`spco.model.shard.sweep`), after the
    local steps: every home's real counts (E, L, D) and whether it is taught from the workers
    (``call``: :class:`~spco.model.shard_group.ShardGroup` methods), home e drawn uniformly from
    :func:`move_candidates` and the other homes' tables given φ^v (``rng``: the driver's), the pass
    run by home e's shard with its own generator (:meth:`spco.model.shard.HomeShard.phi_move`), then
    home e's tables given its new counts. Returns (M, F, H) of every home — what the φ^v step
    proposes from, as :func:`phi_after_move` has them — or ``None`` for a fit of one home."""
    taught = np.concatenate([np.asarray(t, dtype=bool) for t in call("taught_homes")])
    if taught.size < 2:
        return None
    counts = np.concatenate(call("visual_counts"), axis=0)
    e = int(rng.choice(move_candidates(taught)))
    others = np.ascontiguousarray(np.delete(counts, e, axis=0))
    tables = HierarchicalMultinomial.table_parts(others, log_phi_v, hyper.delta_visual, rng)
    new = [c for c in call("phi_move", e, others, tables) if c is not None]
    if len(new) != 1:
        raise RuntimeError(f"the φ^v-marginal move: {len(new)} workers hold home {e}, not one")
    own = HierarchicalMultinomial.table_parts(np.asarray(new[0])[None], log_phi_v, hyper.delta_visual, rng)
    return tables[0] + own[0], tables[1] + own[1], (tables[2] + own[2]) > 0


def _word_log_likelihood(data, state, settings, rows: slice) -> np.ndarray:
    """(n, L) the words' part of the home's samples' concept log-likelihoods (the sampler's own,
    without the views): 0 for untaught samples."""
    n_concepts = state.log_g.shape[1]
    if not data.words.nnz:
        return np.zeros((rows.stop - rows.start, n_concepts))
    full = concept_loglik(data, state, None, settings.word_weight)[rows]
    visual = HierarchicalMultinomial.log_likelihood(data.visual, data.homes, state.log_theta_v,
                                                    by_dimension=data.visual_by_dimension)[rows]
    return full - visual


def phi_after_move(n: np.ndarray, log_phi: np.ndarray, delta: float, alpha, tables,
                   rng: np.random.Generator, passes: int | None = None) -> np.ndarray:
    """Step 4: φ^v given the other homes' tables of :func:`phi_block_step` (M_{−e}, F_{−e}, H_{−e}, e)
    and the moved home's tables M_e (drawn here given φ^v), then the blocked step of
    :meth:`HierarchicalMultinomial.accept_shared` with the fractional weight of every home's real
    counts ``n`` (E, L, D); ``passes``: its passes (``TransferHyperparameters.phi_passes``)."""
    tables_o, frac_o, fractional_o, e = tables
    own = HierarchicalMultinomial.table_parts(np.asarray(n)[e:e + 1], log_phi, delta, rng)
    return HierarchicalMultinomial.accept_shared(
        HierarchicalMultinomial.fractional_log_weight_evaluator(np.asarray(n), delta), log_phi, alpha,
        tables_o + own[0], frac_o + own[1], rng, (fractional_o + own[2]) > 0, passes=passes)


def log_assignment_prior(counts: np.ndarray, region_counts: np.ndarray, g: np.ndarray, beta: float) -> float:
    """ln p(C_e | R_e) of a home with G_e ~ Dir(g) and π_{e,l} ~ Dir(β/K) integrated out, from its
    samples per concept (L,) and per concept and region (L, K) (the brute-force side of the tests)."""
    n_regions = region_counts.shape[1]
    value = gammaln(g.sum()) - gammaln(g.sum() + counts.sum()) + (gammaln(g + counts) - gammaln(g)).sum()
    used = counts > 0
    value += (gammaln(beta) - gammaln(beta + counts[used])).sum()
    value += (gammaln(beta / n_regions + region_counts[used]) - gammaln(beta / n_regions)).sum()
    return float(value)
