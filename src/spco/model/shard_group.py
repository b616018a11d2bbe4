"""The homes one worker runs: a group of one-home shards, each drawing from its own home's stream.

A fit's home e draws every random number from its own generator (:func:`~spco.model.shard.home_generator`,
seeded from the fit's seed and e), in a :class:`~spco.model.shard.HomeShard` of that home alone. A
worker — the one in-process run, or a Ray actor — holds consecutive homes as a :class:`ShardGroup`,
which answers the driver's calls (:mod:`spco.model.driver`, :mod:`spco.model.shard_init`) with the
same methods as a shard and combines its homes' answers in home order: statistics that add up are
summed (exact: integer counts, floats on :data:`~spco.model.additive.SUM_GRID`), per-home answers are
concatenated, and what every home answers alike (the shared parameters, the pruning mask of a
shared score) is taken from the first. So the chain depends on the seed only, not on how many
workers the homes are split into nor where they run.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from spco.model import shard as shards_api
from spco.model.additive import SUM_GRID, PooledCounts
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.kernels.crt import sample_crt_totals_each
from spco.model.kernels.fractional import FractionalCounts
from spco.model.kernels.special import scaled_exp
from spco.model.observations import HierarchicalMultinomial
from spco.model.pruning import Colocation, colocation
from spco.model.shard import HomeShard, HomeStepResult
from spco.model.shard_init import HomeSummary
from spco.model.state import GibbsState, PreparedData, SamplerSettings, SharedParameters
from spco.model.synonyms import NameOverlaps

__all__ = ["ShardGroup"]


def _sum(parts: Iterable):
    """Parts added up in order (exact for the statistics shards send); from an iterator, each part
    is added as it comes and then dropped (no list of every home's part at once)."""
    parts = iter(parts)
    total = next(parts)
    for part in parts:
        total = total + part
    return total


@dataclass
class ShardGroup:
    """Consecutive homes ``first``..``first + len(homes) − 1`` of a fit, one
    :class:`~spco.model.shard.HomeShard` each; ``words`` (N, V) and ``home_of_sample`` (N,) are their
    samples' words and homes stacked (the naming rule's statistics are counted for all at once)."""

    homes: list[HomeShard]
    first: int = 0
    words: sp.csr_array | None = None
    home_of_sample: np.ndarray | None = None

    @classmethod
    def start(cls, data: PreparedData, first: int, entropy: list[int], n_words: int, n_fit_homes: int,
              hyper: TransferHyperparameters, settings: SamplerSettings) -> ShardGroup:
        """Start the homes of ``data`` (homes ``first``.. of the fit), each on its own with its own
        generator (:meth:`HomeShard.start`)."""
        homes = []
        for e in range(data.n_homes):  # a loop over the worker's homes, each started alone
            one = shards_api.data_of_homes(data, e, e + 1) if data.n_homes > 1 else data
            homes.append(HomeShard.start(one, n_words, hyper, settings,
                                         shards_api.home_generator(entropy, first + e), n_fit_homes))
        return cls(homes, first, data.words, data.homes)

    @classmethod
    def from_part(cls, part, first: int, entropy: list[int], n_words: int, n_fit_homes: int,
                  hyper: TransferHyperparameters, settings: SamplerSettings) -> ShardGroup:
        """Prepare the homes of ``part`` (a :class:`~spco.model.sources.HomesPart`) and start them;
        ``setup_seconds`` records the time to prepare and to start."""
        t0 = time.perf_counter()
        data = part.prepare()
        t1 = time.perf_counter()
        group = cls.start(data, first, entropy, n_words, n_fit_homes, hyper, settings)
        group.setup_seconds = {"prepare": t1 - t0, "initialise": time.perf_counter() - t1}
        return group

    @classmethod
    def restore(cls, data: PreparedData, state: GibbsState, rng_states: list[dict], first: int,
                n_fit_homes: int, hyper: TransferHyperparameters, settings: SamplerSettings) -> ShardGroup:
        """The group of ``data`` and its joined ``state`` (:attr:`state`) with its homes' generator
        states (:meth:`rng_states`): a checkpoint taken up again."""
        homes = []
        for e, rng_state in enumerate(rng_states):
            rng = np.random.default_rng()
            rng.bit_generator.state = rng_state
            homes.append(HomeShard(shards_api.data_of_homes(data, e, e + 1) if data.n_homes > 1 else data,
                                   shards_api.state_of_homes(data, state, e, e + 1), hyper, settings, rng,
                                   n_fit_homes))
        return cls(homes, first, data.words, data.homes)

    def __post_init__(self) -> None:
        self.setup_seconds: dict[str, float] = {}
        #: (the homes' statistics, their visual counts' fractional entries: :meth:`visual_log_weight`)
        self._fractional: tuple[tuple, FractionalCounts] | None = None

    # ------------------------------------------------------------------ the group as a whole
    @property
    def n_homes(self) -> int:
        """Homes in this group."""
        return len(self.homes)

    @property
    def state(self) -> GibbsState:
        """The homes' states joined (:func:`~spco.model.shard.join_states`; copies)."""
        if len(self.homes) == 1:
            return self.homes[0].state
        return shards_api.join_states([h.state for h in self.homes])

    def rng_states(self) -> list[dict]:
        """Every home's generator state, in home order."""
        return [h.rng.bit_generator.state for h in self.homes]

    def _each(self, method: str, *args) -> list:
        return [getattr(h, method)(*args) for h in self.homes]

    def _each_lazily(self, method: str, *args) -> Iterator:
        """:meth:`_each` one home at a time (for :func:`_sum`)."""
        return (getattr(h, method)(*args) for h in self.homes)

    # ------------------------------------------------------------------ a sweep
    def local_step(self, word_mask: np.ndarray | None = None,
                   name_words: np.ndarray | None = None, channels=None) -> list[float]:
        """Every home's local step; their log joints, in home order (summed by the driver)."""
        return self._each("local_step", word_mask, name_words, channels)

    def channel_counts(self):
        """The switches' counts of the homes, summed (integers)."""
        return _sum(self._each_lazily("channel_counts"))

    def expected_channel_tokens(self) -> np.ndarray:
        """The homes' expected tokens per word and channel, summed (V, 3)."""
        return _sum(self._each_lazily("expected_channel_tokens"))

    def concept_place_names(self, stand_ins: np.ndarray | None = None) -> np.ndarray:
        """The names said at each concept's places over the homes, summed (L, V)."""
        return _sum(self._each_lazily("concept_place_names", stand_ins))

    def tables(self, kind: str) -> np.ndarray:
        """CRT table counts of the homes, summed (integers): the sum of the homes' own
        (:meth:`HomeShard.tables`), the visual and word tables drawn in one call, each home from a
        seed of its own stream (:func:`~spco.model.kernels.crt.sample_crt_totals_each`)."""
        if kind not in ("visual", "words") or len(self.homes) == 1:
            return _sum(self._each_lazily("tables", kind))
        first = self.homes[0]
        counts = np.concatenate([getattr(h._stats(), kind) for h in self.homes])
        log_phi, delta = ((first.state.log_phi_v, first.hyper.delta_visual) if kind == "visual"
                          else (first.state.log_phi_w, first.hyper.delta_word))
        seeds = np.array([h.rng.integers(0, 2**63 - 1, dtype=np.int64) for h in self.homes], dtype=np.uint64)
        if kind == "words":
            return sample_crt_totals_each(counts, scaled_exp(log_phi, delta), seeds)
        # visual: (3, L, D) as HierarchicalMultinomial.table_parts
        whole, frac, fractional = HierarchicalMultinomial.whole_parts(counts)
        tables = sample_crt_totals_each(whole, scaled_exp(log_phi, delta), seeds)
        return np.stack([tables.astype(np.float64), frac, fractional])

    def visual_counts(self) -> np.ndarray:
        """(E_g, L, D) the homes' real view counts per concept, in home order."""
        return np.concatenate(self._each("visual_counts"), axis=0)

    def taught_homes(self) -> np.ndarray:
        """(E_g,) whether each home has a sample with a word, in home order."""
        return np.concatenate(self._each("taught_homes"))

    def phi_move(self, home: int, others: np.ndarray, tables) -> np.ndarray | None:
        """The φ^v-marginal move's pass over fit home ``home`` if this group holds it
        (:meth:`HomeShard.phi_move`: its counts per concept after the pass), else ``None``."""
        if not self.first <= home < self.first + len(self.homes):
            return None
        return self.homes[home - self.first].phi_move(others, tables)

    def visual_log_weight(self, log_phi: np.ndarray) -> np.ndarray:
        """(L, D) the homes' parts of φ^v's fractional weight per dimension, summed: bit for bit the
        sum of the homes' own (:meth:`HomeShard.visual_log_weight`) in home order, computed in one
        call (:class:`~spco.model.kernels.fractional.FractionalCounts`: what depends on φ^v alone
        computed once for every home; the homes' fractional counts gathered once for the statistics
        of a sweep, which every evaluation of its φ^v step reads)."""
        deltas = {h.hyper.delta_visual for h in self.homes}
        if len(self.homes) == 1 or len(deltas) != 1:
            return _sum(self._each_lazily("visual_log_weight", log_phi))
        stats = tuple(h._stats() for h in self.homes)
        held = self._fractional
        if held is None or any(a is not b for a, b in zip(held[0], stats, strict=True)):
            self._fractional = (stats, FractionalCounts([s.visual for s in stats]))
        return self._fractional[1].log_weights(log_phi, deltas.pop())

    def pooled_counts(self) -> PooledCounts:
        """The homes' pooled counts, summed (integers)."""
        return _sum(self._each_lazily("pooled_counts"))

    def home_step(self, shared: SharedParameters | None, swaps: bool = False,
                  prune: bool = False) -> HomeStepResult:
        """Every home's home step; the result of the first (the mask of a shared score, the same in
        every home)."""
        return self._each("home_step", shared, swaps, prune)[0]

    def receive(self, shared: SharedParameters, prune: bool = False) -> HomeStepResult:
        """Every home takes the shared parameters; the result of the first."""
        return self._each("receive", shared, prune)[0]

    def colocation(self) -> Colocation:
        """The naming rule's statistics of the homes, counted at once: the sum of the homes' own
        (:meth:`HomeShard.colocation`), bit for bit (every home's part on the grid)."""
        if self.words is None:
            return _sum(self._each_lazily("colocation"))
        regions = np.concatenate([h.state.regions for h in self.homes])
        return colocation(self.words, self.home_of_sample, regions, len(self.homes),
                          self.homes[0].hyper.n_regions, grid=SUM_GRID)

    def candidate_words(self) -> np.ndarray | None:
        """The candidate words (a shared part of the state)."""
        return self.homes[0].candidate_words()

    def shared_parameters(self) -> SharedParameters:
        """The shared parameters the homes hold."""
        return self.homes[0].shared_parameters()

    def concept_visual_totals(self) -> np.ndarray:
        """Visual counts by concept of the homes, summed, (L,)."""
        return _sum(self._each_lazily("concept_visual_totals"))

    def held_out_view_fits(self, log_phi_v: np.ndarray, log_g0: np.ndarray,
                           totals: np.ndarray) -> list[float | None]:
        """The held-out view fit of every home, in home order."""
        return [v for fits in self._each("held_out_view_fits", log_phi_v, log_g0, totals) for v in fits]

    def view_weight_totals(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The homes' visual counts (L, D), taught views (L,) and taught words (L, V) by concept,
        summed."""
        parts = self._each("view_weight_totals")
        return _sum([p[0] for p in parts]), _sum([p[1] for p in parts]), _sum([p[2] for p in parts])

    def view_weight_losses(self, totals: np.ndarray, taught: np.ndarray, words: np.ndarray
                           ) -> list[tuple[np.ndarray, int]]:
        """Every home's leave-one-home-out losses on the view-weight grid and its views, in home
        order (summed by the driver in home order: the same sum for any number of workers)."""
        return self._each("view_weight_losses", totals, taught, words)

    def set_view_weight(self, view_counts: float | None) -> None:
        """Every home weighs a view ``view_counts`` from the next sweep on."""
        self._each("set_view_weight", view_counts)

    def visual_prior_moments(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Every home's view moments by concept (:func:`spco.model.visual_prior.home_view_moments`),
        in home order."""
        return self._each("visual_prior_moments")

    def word_prior_moments(self, name_prior: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Every home's name tokens by concept (:func:`spco.model.word_prior.home_name_moments`), in
        home order."""
        return self._each("word_prior_moments", name_prior)

    def set_word_prior(self, delta_word: float, alpha_word: float) -> None:
        """Every home draws θ^w at these δ^w and α^w from the next sweep on."""
        self._each("set_word_prior", delta_word, alpha_word)

    def visual_means(self) -> list[np.ndarray]:
        """Every home's log θ^v summary (:meth:`HomeShard.visual_means`), in home order."""
        return [m for h in self.homes for m in h.visual_means()]

    def start_power(self, hyper: TransferHyperparameters, settings: SamplerSettings, channels) -> None:
        """Every home ends its cut start (:meth:`spco.model.shard.HomeShard.start_power`)."""
        self._each("start_power", hyper, settings, channels)

    def set_visual_prior(self, delta_visual: float, alpha_visual: float) -> None:
        """Every home draws θ^v at these δ^v and α^v from the next sweep on."""
        self._each("set_visual_prior", delta_visual, alpha_visual)

    # ------------------------------------------------------------------ the start (shard_init)
    def init_has_words(self) -> bool:
        """Whether any home has a sentence."""
        return any(self._each("init_has_words"))

    def init_names(self, naming: Colocation) -> NameOverlaps:
        """The homes' names; their region overlaps summed (exact on the grid)."""
        return _sum(self._each_lazily("init_names", naming))

    def init_places(self, overlaps: NameOverlaps) -> None:
        """Every home starts from the places its names mark."""
        self._each("init_places", overlaps)

    def init_taught(self) -> np.ndarray:
        """The homes' taught fractions, concatenated in home order."""
        return np.concatenate(self._each("init_taught"))

    def init_said_in_kept(self, weights: np.ndarray) -> np.ndarray:
        """Words said in the homes of weight 1 (or)."""
        return np.logical_or.reduce([h.init_said_in_kept(weights[e:e + 1]) for e, h in enumerate(self.homes)])

    def init_hold(self, weights: np.ndarray, said_elsewhere: np.ndarray) -> None:
        """Every reduced home holds its own names' samples through the independent sweeps."""
        for e, h in enumerate(self.homes):
            h.init_hold(weights[e:e + 1], said_elsewhere)

    def init_local_step(self) -> None:
        """Every home's independent local step."""
        self._each("init_local_step")

    def init_home_step(self, word_mask: np.ndarray | None = None,
                       name_words: np.ndarray | None = None) -> None:
        """Every home's independent home step."""
        self._each("init_home_step", word_mask, name_words)

    def init_summary(self) -> HomeSummary:
        """The homes' summaries, concatenated in home order."""
        parts = self._each("init_summary")
        said = None if parts[0].names_said is None else np.concatenate([p.names_said for p in parts])
        return HomeSummary(np.concatenate([p.word_totals for p in parts]), said,
                           np.concatenate([p.taught_fraction for p in parts]))

    def init_home_counts(self, homes: list[int]) -> list:
        """The counts by concept of the group's homes ``homes`` (indices in the group)."""
        return [self.homes[e].init_home_counts([0])[0] for e in homes]

    def init_align(self, perms: np.ndarray) -> None:
        """Relabel every home by its row of ``perms`` (E_g, L)."""
        for e, h in enumerate(self.homes):
            h.init_align(perms[e:e + 1])

    def init_kept(self, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Words said in the kept homes (or) and their concept counts (summed)."""
        parts = [h.init_kept(weights[e:e + 1]) for e, h in enumerate(self.homes)]
        return np.logical_or.reduce([p[0] for p in parts]), _sum([p[1] for p in parts])

    def init_own_names(self, said_elsewhere: np.ndarray) -> dict[int, np.ndarray]:
        """Names said in a reduced home only: group home index -> names."""
        own = {}
        for e, names in enumerate(self._each("init_own_names", said_elsewhere)):
            if names:
                own[e] = names[0]
        return own

    def init_give_labels(self, given: dict[int, list[tuple[int, int]]]) -> None:
        """Every home takes the labels given to its own names."""
        for e, h in enumerate(self.homes):
            h.init_give_labels({0: given[e]} if e in given else {})

    def init_weighted_counts(self, scale: bool) -> PooledCounts:
        """The homes' weighted counts, summed (integers)."""
        return _sum(self._each_lazily("init_weighted_counts", scale))

    def init_reference_weights(self, log_g0: np.ndarray) -> None:
        """Every home draws its G_e given the driver's G_0 (reference variant)."""
        self._each("init_reference_weights", log_g0)

    def init_finish(self, shared: SharedParameters) -> None:
        """Every home takes the initial shared parameters and draws its own given them."""
        self._each("init_finish", shared)
