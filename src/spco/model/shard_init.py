"""The start of every fit, inside the shards: every shard starts its own homes, the driver only
reduces.

Each worker prepares its homes (:mod:`spco.model.sources`) and runs their per-home start (k-means
regions, Gaussians, π: :func:`spco.model.gibbs.initialize`, each home with its own generator); the
exact sampler's warm start then runs as map → reduce steps — homes learnt on their own for a few
sweeps, their labels aligned across homes, the shared part set from the aligned counts, each home's
weighted by how much it was taught:

1. with the naming rule, the places the names mark: the naming statistics of all homes
   (:class:`~spco.model.pruning.Colocation`, (V,) × 3) are summed by the driver and sent back;
   each shard starts its homes' concepts from them;
2. ``n_sweeps`` independent (SpCoA) sweeps of every home, the sweep-0 word mask judged by the
   driver on the summed naming statistics; a word token weighs
   :attr:`~spco.model.state.SamplerSettings.word_weight` of its S^w counts in them (W^w / S^w with
   the word channels), and when that is below 1 the samples of a home taught less than the most
   taught that stand for a name of its own are held in their concepts (:func:`_hold_own_names`);
3. the cross-home label alignment: the driver receives per home only its word total, the names it
   says and its taught fraction, and then aligns the homes one by one in the order of
   :func:`~spco.model.gibbs.align_homes` (most words first) against a running pooled reference
   ((L, D) + (L, V), kept in the driver), fetching each home's concept × word and concept × view
   counts ((L, V) and sparse (L, D)) from its shard in batches (:func:`align_in_order`, the same
   permutations as ``align_homes`` given the same counts); the shards apply the permutations;
4. the new homes' own names to free concepts (the driver hands the free labels out in home
   order), the taught-fraction weights (:func:`~spco.model.gibbs.initial_home_weights`, from the
   gathered (E,) fractions), and the weighted counts summed over shards: φ^v, φ^w, G_0 drawn by
   the driver, then every shard's home step.

The driver holds (E,) and (E, V) vectors, the pooled reference and one batch of homes' counts:
megabytes at D = 4,096, whatever the number of homes. Every home draws from its own generator and
the driver from its own, and what the driver sums adds up exactly, so the start depends on the
seed only: the same for any number of shards and on either engine (``tests/test_shard_init.py``).

Why this start: with ~7,000 visual and S^w = 5000 word counts per sample the chain keeps whatever
partition its first sweeps make, and label switching between homes is the sampler's hardest move
(:mod:`spco.model.moves`). With the naming rule ("+MI") each home starts from the places its names
mark (:func:`~spco.model.gibbs.concepts_by_name`, synonyms as one), so that two rooms of one home
that the transferred knowledge sees alike (Emma's and mother's bedrooms) start as two concepts.
Homes taught little (a new home) count little in the initial shared part
(:func:`~spco.model.gibbs.initial_home_weights`), so their samples are first assigned by the
knowledge of the taught homes; their own names start in free concepts of their own.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from spco.model import allocation, assignments, gibbs, parameter_steps, sweep_statistics
from spco.model.additive import PooledCounts, on_sum_grid
from spco.model.alignment import ALIGNMENT_BATCH, HomeCounts, align_in_order
from spco.model.gibbs import GibbsState, PreparedData, SamplerSettings
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.kernels.dirichlet import log_dirichlet
from spco.model.observations import GaussianRegions
from spco.model.pruning import NAME, NOT_A_NAME, Colocation, judge_names
from spco.model.state import SharedParameters
from spco.model.synonyms import NameOverlaps, name_overlaps, name_region_overlaps, same_place_names

#: The per-home sampler of the warm start (θ_{e,l} ~ Dir(α + n), the SpCoA conditionals).
INDEPENDENT = SamplerSettings(variant="spcoa", prune=False, hierarchical=False, joint_assignment=True,
                              pruning_score="mi")



@dataclass
class HomeSummary:
    """What a shard tells the driver about its homes before the alignment: word totals (E_s,),
    the names each home says (E_s, V) bool (``None`` without the naming start), taught
    fractions (E_s,)."""

    word_totals: np.ndarray
    names_said: np.ndarray | None
    taught_fraction: np.ndarray

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays."""
        said = 0 if self.names_said is None else self.names_said.nbytes
        return self.word_totals.nbytes + said + self.taught_fraction.nbytes


class ShardInitialisation:
    """The shard's side of the initialisation (mixed into :class:`~spco.model.shard.HomeShard`,
    whose ``data``, ``state``, ``hyper``, ``settings`` and ``rng`` it uses). Called in the order
    of :func:`initialise`."""

    data: PreparedData
    state: GibbsState
    hyper: TransferHyperparameters
    settings: SamplerSettings
    rng: np.random.Generator

    def init_has_words(self) -> bool:
        """Whether any of the shard's samples has a sentence."""
        return bool(self.data.words.nnz)

    def init_names(self, naming: Colocation) -> NameOverlaps:
        """The name each sample stands for, judged on ``naming`` (all homes' statistics); returns
        the shard's sums of the names' region overlaps (:class:`~spco.model.synonyms.NameOverlaps`),
        to be pooled over all homes."""
        data, state, hyper = self.data, self.state, self.hyper
        named = judge_names(naming) == NAME
        named[list(self.settings.start_not_names)] = False  # (warm_start_settings)
        self._names = gibbs.sample_names(data, state.regions, hyper, named=named, stats=naming)
        overlaps = name_overlaps(name_region_overlaps(self._names, state.regions, data.offsets,
                                                      hyper.n_regions), data.words.shape[1])
        return NameOverlaps(on_sum_grid(overlaps.weighted), overlaps.weights)

    def init_places(self, overlaps: NameOverlaps) -> None:
        """Start each home's concepts from the places its names mark, synonyms (``overlaps``
        pooled over all homes: :func:`~spco.model.synonyms.same_place_names`) as one, then draw
        its parameters as on its own."""
        data, state, hyper = self.data, self.state, self.hyper
        places = same_place_names(self._names, state.regions, data.offsets, hyper.n_regions,
                                  data.words.shape[1], overlaps=overlaps)
        state.concepts = gibbs.concepts_by_name(data, state.regions, hyper, places)
        stats = sweep_statistics.sufficient_statistics(data, state, hyper,
                                                       self.settings.learning_view_counts())
        independent_home_step(data, state, stats, hyper, self.rng)

    def init_taught(self) -> np.ndarray:
        """The share of each of the shard's homes' samples with a sentence, (E_s,)."""
        data = self.data
        taught = np.bincount(data.homes, weights=np.diff(data.words.indptr) > 0, minlength=data.n_homes)
        return taught / np.maximum(np.diff(data.offsets), 1)

    def init_said_in_kept(self, weights: np.ndarray) -> np.ndarray:
        """The words said in the shard's homes of weight 1 (``weights`` (E_s,)): (V,) bool."""
        said = np.zeros(self.data.words.shape[1], dtype=bool)
        said[np.unique(self.data.words[np.flatnonzero(weights[self.data.homes] >= 1.0)].indices)] = True
        return said

    def init_hold(self, weights: np.ndarray, said_elsewhere: np.ndarray) -> None:
        """Hold the samples of a reduced home (``weights`` < 1) that stand for a name of its own
        (said in no home of weight 1, ``said_elsewhere``) in their starting concepts through the
        independent sweeps."""
        names, data = self._names, self.data
        reduced = (weights < 1.0)[data.homes]
        own = (names >= 0) & reduced
        own[own] = ~said_elsewhere[names[own]]
        self._held = np.flatnonzero(own)
        self._held_concepts = self.state.concepts[self._held].copy()
        if reduced.any():  # a partly taught home's words weigh S^w in the start, as without channels
            self._word_weight = np.where(reduced, 1.0, self.settings.word_weight)

    def init_local_step(self) -> None:
        """One local step of the independent warm-start sampler (statistics kept)."""
        # the same view evidence, and a word token's as the chain weighs it (SamplerSettings.word_weight)
        independent = replace(INDEPENDENT, view_counts=self.settings.view_counts,
                              word_weight=getattr(self, "_word_weight", self.settings.word_weight))
        assignments.local_step(self.data, self.state, independent, self.rng)
        held = getattr(self, "_held", None)
        if held is not None and held.size:
            self.state.concepts[held] = self._held_concepts
        self._init_stats = sweep_statistics.sufficient_statistics(self.data, self.state, self.hyper,
                                                          self.settings.learning_view_counts())

    def init_home_step(self, word_mask: np.ndarray | None = None,
                       name_words: np.ndarray | None = None) -> None:
        """Take ``word_mask`` and ``name_words`` (if given), then the independent home step."""
        if word_mask is not None:
            self.state.word_mask = word_mask
        if name_words is not None:
            self.state.name_words = name_words
        independent_home_step(self.data, self.state, self._init_stats, self.hyper, self.rng)

    def init_summary(self) -> HomeSummary:
        """Per-home word totals, names said and taught fractions (see :class:`HomeSummary`)."""
        data, state, hyper = self.data, self.state, self.hyper
        stats = self._init_stats = sweep_statistics.sufficient_statistics(data, state, hyper,
                                                               self.settings.learning_view_counts())
        self._name_counts = None
        names_said = None
        names = getattr(self, "_names", None)
        if names is not None:
            named = names >= 0
            counts = np.zeros((data.n_homes, hyper.n_concepts, data.words.shape[1]))
            np.add.at(counts, (data.homes[named], state.concepts[named], names[named]), 1.0)
            self._name_counts = counts
            names_said = counts.sum(axis=1) > 0
        taught = np.bincount(data.homes, weights=np.diff(data.words.indptr) > 0, minlength=data.n_homes)
        return HomeSummary(stats.words.sum(axis=(1, 2)), names_said,
                           taught / np.maximum(np.diff(data.offsets), 1))

    def init_home_counts(self, homes: list[int]) -> list[HomeCounts]:
        """The counts by concept of the shard's homes ``homes`` (local indices)."""
        stats, names = self._init_stats, self._name_counts
        return [HomeCounts(sp.csr_array(stats.visual[e]), stats.words[e].copy(),
                           None if names is None else names[e].copy()) for e in homes]

    def init_align(self, perms: np.ndarray) -> None:
        """Relabel the homes' concepts by ``perms`` (E_s, L) (slot j takes old concept perms[e, j])."""
        parameter_steps.apply_permutations(self.data, self.state, perms)
        self._name_counts = None
        self._init_stats = sweep_statistics.sufficient_statistics(self.data, self.state, self.hyper,
                                                          self.settings.learning_view_counts())

    def init_kept(self, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Take the homes' weights (E_s,); return the words said in the kept homes (weight 1), (V,)
        bool, and their concept counts summed, (L,)."""
        data = self.data
        self._weights = weights
        reduced = weights < 1.0
        said = np.zeros(data.words.shape[1], dtype=bool)
        said[np.unique(data.words[np.flatnonzero(~reduced[data.homes])].indices)] = True
        return said, self._init_stats.concepts[~reduced].sum(axis=0)

    def init_own_names(self, said_elsewhere: np.ndarray) -> dict[int, np.ndarray]:
        """Names said in a reduced home (weight < 1) and in no kept home: local home -> names."""
        names, data = self._names, self.data
        own: dict[int, np.ndarray] = {}
        for e in np.flatnonzero(self._weights < 1.0):  # a loop over the few new homes
            rows = slice(data.offsets[e], data.offsets[e + 1])
            words = np.unique(names[rows][names[rows] >= 0])
            words = words[~said_elsewhere[words]]
            if words.size:
                own[int(e)] = words
        return own

    def init_give_labels(self, given: dict[int, list[tuple[int, int]]]) -> None:
        """Move each reduced home's samples standing for an own name to the label the driver gave
        it: home -> [(name, label), ...]; those labels keep their counts in full."""
        self._own = {}
        for e, pairs in given.items():
            rows = np.arange(self.data.offsets[e], self.data.offsets[e + 1])
            for word, label in pairs:
                self.state.concepts[rows[self._names[rows] == word]] = label
            self._own[e] = np.array([label for _, label in pairs], dtype=np.int64)
        if given:
            self._init_stats = sweep_statistics.sufficient_statistics(self.data, self.state, self.hyper,
                                                          self.settings.learning_view_counts())

    def init_weighted_counts(self, scale: bool):
        """The statistics weighted by the homes' weights (with ``scale``; the kept labels of own
        names in full), summed over the shard's homes (a :class:`~spco.model.additive.PooledCounts`)."""
        stats, own = self._init_stats, getattr(self, "_own", {})
        if scale:
            # rint(n · w), computed for the homes with w < 1 only: a
            # home of weight 1 keeps its counts exactly (rint(n · 1.0) = n), and no (E, L, D)
            # float temporary is made (the shard's peak memory at D = 4,096)
            reduced = np.flatnonzero(self._weights < 1.0)
            for name in ("visual", "words", "concepts", "regions_by_concept"):
                counts = getattr(stats, name)
                if reduced.size == 0 and counts.dtype == np.int64:
                    continue  # every home of weight 1: the counts as they are, no copy
                scaled = np.array(counts, dtype=np.int64)
                weights = self._weights[reduced].reshape((-1,) + (1,) * (counts.ndim - 1))
                scaled[reduced] = np.rint(counts[reduced] * weights).astype(np.int64)
                for e, labels in own.items():
                    scaled[e, labels] = counts[e, labels]
                setattr(stats, name, scaled)
        return PooledCounts(stats.visual.sum(0), stats.words.sum(0), stats.concepts.sum(0))

    def init_reference_weights(self, log_g0: np.ndarray) -> None:
        """Reference variant: take the driver's G_0 and draw the homes' G_e ~ Dir(G_0 + γ)."""
        state, hyper = self.state, self.hyper
        state.log_g0 = log_g0
        state.log_g = log_dirichlet(np.exp(log_g0)[None, :] + hyper.gamma + np.zeros((self.data.n_homes,
                                                                                     hyper.n_concepts)),
                                    self.rng)

    def init_finish(self, shared) -> None:
        """Take the initial shared parameters and draw θ, G_e, π, μ, Σ given them (exact variant)."""
        state = self.state
        state.log_phi_v, state.log_phi_w = shared.log_phi_v, shared.log_phi_w
        state.log_g0, state.word_mask = shared.log_g0, shared.word_mask
        state.name_words = shared.name_words
        parameter_steps.home_step(self.data, state, self._init_stats, self.hyper, self.settings, self.rng)
        for name in ("_init_stats", "_names", "_name_counts", "_weights", "_own", "_held", "_held_concepts",
                     "_word_weight"):
            self.__dict__.pop(name, None)


#: Homes whose θ^v the warm start's home step draws at a time (bounds its temporaries).
THETA_CHUNK = 64


def independent_home_step(data: PreparedData, state: GibbsState, stats: sweep_statistics.Statistics,
                          hyper: TransferHyperparameters, rng: np.random.Generator) -> None:
    """The warm start's per-home step (the SpCoA conditionals of ``parameter_steps.home_step``): θ^v_{e,l} ~
    Dir(α^v + n^v_{e,l}), θ^w likewise, G_e ~ Dir(γ/L + n_e), π, μ, Σ. θ^v is drawn
    :data:`THETA_CHUNK` homes at a time into one (E, L, D) array, the old θ^v freed first (the
    step does not read it), and the SpCoA export of the homes' mean as φ, G_0 is left out (the
    warm start sets those from the aligned counts): two (E, L, D) arrays fewer at a shard's peak
    memory than ``parameter_steps.home_step`` with the SpCoA settings."""
    E, L, K = data.n_homes, hyper.n_concepts, hyper.n_regions
    state.log_theta_v = None
    theta_v = np.empty(stats.visual.shape)
    for first in range(0, E, THETA_CHUNK):
        last = min(first + THETA_CHUNK, E)
        theta_v[first:last] = log_dirichlet(hyper.alpha_visual + stats.visual[first:last], rng)
    state.log_theta_v = theta_v
    state.log_theta_w = log_dirichlet(hyper.alpha_word + stats.words, rng)
    state.log_g = log_dirichlet(hyper.gamma / L + stats.concepts, rng)
    state.log_pi = allocation.sample_region_weights(stats.regions_by_concept, hyper.beta / K, rng)
    state.means, state.covariances = GaussianRegions.sample_posterior(
        stats.region_count, stats.region_total, stats.region_scatter,
        parameter_steps.niw_prior(data, hyper, INDEPENDENT), rng)
    state.region_counts = stats.region_count.astype(np.int64)


# ----------------------------------------------------------------------------- the driver's side


@dataclass
class InitialisationReport:
    """What the initialisation moved (bytes the driver received from the shards and sent to them)
    and its wall time: the whole warm start, and the driver's streamed alignment within it."""

    bytes_received: int = 0
    bytes_sent: int = 0
    seconds: float = 0.0
    alignment_seconds: float = 0.0


def _nbytes(value) -> int:
    if value is None or isinstance(value, bool | int | float):
        return 8
    if hasattr(value, "nbytes"):
        return int(value.nbytes)
    if dataclasses.is_dataclass(value):
        return sum(_nbytes(getattr(value, f.name)) for f in dataclasses.fields(value))
    if isinstance(value, tuple | list):
        return sum(_nbytes(v) for v in value)
    if isinstance(value, dict):
        return sum(_nbytes(k) + _nbytes(v) for k, v in value.items())
    raise TypeError(f"cannot size {type(value).__name__}")


def _uniform_start(call, gather, settings: SamplerSettings, hyper: TransferHyperparameters,
                   rng: np.random.Generator, report: InitialisationReport, n_shards: int):
    """The shared parameters of a start without warm start (the reference and SpCoA samplers): φ and
    G_0 uniform, the reference sampler's G_0 drawn from its prior and sent to the shards."""
    shared = gather(call("shared_parameters"))[0]  # (the same in every shard but G_0)
    if settings.variant == "reference":
        shared.log_g0 = log_dirichlet(np.full(hyper.n_concepts, hyper.gamma0), rng)
        call("init_reference_weights", shared.log_g0)
        report.bytes_sent += shared.log_g0.nbytes * n_shards
    return shared


def _home_counts_fetcher(call_each, gather, bounds: list[tuple[int, int]], report: InitialisationReport):
    """``fetch(homes)``: the :class:`HomeCounts` of the given homes, asked of the shards holding them,
    in the order asked."""
    starts = np.array([a for a, _ in bounds])
    n_shards = len(bounds)

    def fetch(homes: np.ndarray) -> list[HomeCounts]:
        owner = np.searchsorted(starts, homes, side="right") - 1
        asked = [[int(h - starts[s]) for h, o in zip(homes, owner, strict=True) if o == s]
                 for s in range(n_shards)]
        answers = gather(call_each("init_home_counts", [(a,) for a in asked]))
        report.bytes_sent += 8 * len(homes)
        position = [0] * n_shards
        out = []
        for o in owner:
            out.append(answers[o][position[o]])
            position[o] += 1
        return out

    return fetch


def _first_sweeps(call, total, settings: SamplerSettings, n_words: int, n_sweeps: int,
                  report: InitialisationReport, n_shards: int) -> tuple[np.ndarray, np.ndarray | None]:
    """The start's ``n_sweeps`` local and home steps; with word pruning the naming rule judges the
    words after the first local step. Returns the words kept (all without pruning) and the words
    judged names (``None`` without pruning)."""
    word_mask = np.ones(n_words, dtype=bool)
    name_words = None
    for sweep_index in range(n_sweeps):
        call("init_local_step")
        mask = names = None
        if sweep_index == 0 and settings.prune and n_words:
            verdicts = judge_names(total(call("colocation")))
            mask = word_mask = verdicts != NOT_A_NAME
            names = name_words = verdicts == NAME
            report.bytes_sent += (mask.nbytes + names.nbytes) * n_shards
        call("init_home_step", mask, names)
    return word_mask, name_words


def _hold_own_names(call, call_each, gather, bounds: list[tuple[int, int]],
                    report: InitialisationReport) -> None:
    """Have the shards hold, through the independent sweeps, the samples of every reduced home (taught
    less than the most taught: :func:`~spco.model.gibbs.initial_home_weights` < 1) that stand for a
    name of the home's own (said in no home of weight 1) in the concepts its names start in: what
    :func:`initialise` later gives free labels. A start that weighs a word token below S^w
    (:attr:`~spco.model.state.SamplerSettings.word_weight`) would otherwise let a taught room's few
    samples be drawn by view and position into the home's other concepts before their names get a
    concept of their own."""
    weights = gibbs.initial_home_weights(np.concatenate(gather(call("init_taught"))))
    said = np.logical_or.reduce(gather(call_each("init_said_in_kept", [(weights[a:b],) for a, b in bounds])))
    call_each("init_hold", [(weights[a:b], said) for a, b in bounds])
    report.bytes_sent += weights.nbytes + said.nbytes * len(bounds)


def _hand_out_labels(owns: list[dict[int, Any]], free: list[int]) -> list[dict[int, list[tuple[int, int]]]]:
    """The free concept labels handed out in home order: per shard, home -> (own word, label) pairs,
    one label per word of the home's own while labels are left (``free`` is used up in place)."""
    given: list[dict[int, list[tuple[int, int]]]] = []
    for own in owns:
        pairs_of: dict[int, list[tuple[int, int]]] = {}
        for e in sorted(own):
            pairs = []
            for word in own[e]:
                if not free:
                    break
                pairs.append((int(word), int(free.pop(0))))
            if pairs:
                pairs_of[e] = pairs
        given.append(pairs_of)
    return given


def initialise(call, call_each, bounds: list[tuple[int, int]], n_words: int, hyper: TransferHyperparameters,
               settings: SamplerSettings, rng: np.random.Generator, n_sweeps: int = 3,
               batch: int = ALIGNMENT_BATCH):
    """Finish the shards' initialisation (their homes already started with
    :func:`spco.model.gibbs.initialize`) and return the initial
    :class:`~spco.model.state.SharedParameters` and an :class:`InitialisationReport`.

    ``call(method, *args)`` runs a shard method on every shard (results in shard order);
    ``call_each(method, args)`` runs it on shard i with ``args[i]``; ``bounds`` are the shards'
    home ranges [first, last). ``rng`` is the driver's generator (the shared draws)."""
    report = InitialisationReport()
    started = time.perf_counter()

    def gather(results: list) -> list:
        report.bytes_received += _nbytes(results)
        return results

    def total(parts: list):
        gather(parts)
        out = parts[0]
        for part in parts[1:]:
            out = out + part
        return out

    n_shards = len(bounds)
    L = hyper.n_concepts
    if settings.variant != "exact":  # no warm start: φ and G_0 start uniform (reference: G_0 drawn)
        return _uniform_start(call, gather, settings, hyper, rng, report, n_shards), report

    naming_start = settings.prune and any(gather(call("init_has_words")))
    if naming_start:
        naming = total(call("colocation"))
        overlaps = total(call("init_names", naming))
        call("init_places", overlaps)
        if settings.word_weight < 1.0:  # a start that weighs words below S^w (warm_start_settings)
            _hold_own_names(call, call_each, gather, bounds, report)
        report.bytes_sent += overlaps.nbytes * n_shards
        report.bytes_sent += naming.nbytes * n_shards
    word_mask, name_words = _first_sweeps(call, total, settings, n_words, n_sweeps, report, n_shards)

    summaries = gather(call("init_summary"))
    word_totals = np.concatenate([s.word_totals for s in summaries])
    names_said = np.concatenate([s.names_said for s in summaries]) if naming_start else None
    taught = np.concatenate([s.taught_fraction for s in summaries])
    fetch = _home_counts_fetcher(call_each, gather, bounds, report)
    aligning = time.perf_counter()
    perms = align_in_order(fetch, word_totals, names_said, hyper.alpha_visual, hyper.alpha_word, L, batch)
    report.alignment_seconds = time.perf_counter() - aligning
    call_each("init_align", [(perms[a:b],) for a, b in bounds])
    report.bytes_sent += perms.nbytes

    weights = gibbs.initial_home_weights(taught)
    reduced = weights < 1.0
    kept = gather(call_each("init_kept", [(weights[a:b],) for a, b in bounds]))
    report.bytes_sent += weights.nbytes
    if naming_start and reduced.any():
        said_elsewhere = np.logical_or.reduce([k[0] for k in kept])
        free = list(np.flatnonzero(sum(k[1] for k in kept) == 0))
        owns = gather(call_each("init_own_names", [(said_elsewhere,)] * n_shards))
        given = _hand_out_labels(owns, free)
        call_each("init_give_labels", [(g,) for g in given])
        report.bytes_sent += _nbytes(given) + said_elsewhere.nbytes * n_shards
    counts = total(call("init_weighted_counts", bool(reduced.any())))
    shared = SharedParameters(log_dirichlet(hyper.alpha_visual + counts.visual, rng),
                              log_dirichlet(hyper.alpha_word + counts.words, rng),
                              log_dirichlet(hyper.gamma0 / hyper.n_concepts + counts.concepts, rng),
                              word_mask, name_words)
    call("init_finish", shared)
    report.bytes_sent += shared.nbytes * n_shards
    report.seconds = time.perf_counter() - started
    return shared, report
