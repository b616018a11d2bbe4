"""A shard of one home with the shared part fixed: how a new home is learnt from knowledge.

The knowledge learnt from experienced homes (:class:`spco.knowledge.Knowledge`) is, for the new
home, the shared part of the transfer model — φ^v, φ^w, G_0, the word mask — given as a
:class:`SharedPart` of plain arrays. :class:`NewHomeShard` holds one home's prepared data and
sampler state and runs the exact conditionals of the model for that home alone with the shared
part fixed (``SamplerSettings.create(variant, prune, learn_shared=False)``), or learnt too with the
knowledge as its Dirichlet prior (:class:`SharedPrior`, ``joint``). ``spco adapt`` starts one
(:meth:`NewHomeShard.start`), ``spco teach`` resumes one from a home's state; both then run
:meth:`~NewHomeShard.begin`, :meth:`~NewHomeShard.run` and :meth:`~NewHomeShard.finish`.

Words first heard in the home (after the knowledge's ``n_known`` words) are judged in the home
(:func:`judge_new_words`); names first heard here get concepts of their own, ones the knowledge does
not use (:func:`own_names_to_free_concepts`, :func:`learn_free_concepts`). See
:mod:`spco.knowledge` for the semantics.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.cluster.vq import kmeans2

from spco.data.language import Vocabulary
from spco.model import assignments, gibbs, parameter_steps, sweep_statistics
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.kernels.counts import stack_counts
from spco.model.kernels.crt import sample_crt
from spco.model.kernels.dirichlet import log_dirichlet
from spco.model.observations import HierarchicalMultinomial
from spco.model.parameters import ConceptParameters
from spco.model.posterior import ParameterAverage, thinned_sweeps
from spco.model.pruning import NOT_A_NAME, words_to_keep
from spco.model.state import GibbsState, PreparedData, SamplerSettings
from spco.model.word_channels import NAME, WordChannels, expected_tokens, switch_probabilities, token_rows

__all__ = [
    "FREE_CONCEPT_WEIGHT",
    "NAME_SHARE",
    "NAME_TOKENS",
    "OWN_NAMES_SPREAD_WARNING",
    "NewHomeShard",
    "OwnNamesSpreadWarning",
    "SharedPart",
    "SharedPrior",
    "new_home_block_moves",
    "prepare_home",
]


@dataclass(frozen=True, eq=False)
class SharedPart:
    """The shared part of the transfer model as a new home sees it (built by the knowledge layer,
    :meth:`spco.knowledge.Knowledge.shared_part`).

    Attributes
    ----------
    log_phi_visual: (L, D) log φ^v; log_phi_words: (L, V) log φ^w; log_g0: (L,) log G_0.
    word_mask: (V,) bool, the words the knowledge kept.
    hyperparameters: the model's hyperparameters.
    variant: the sampler (``"exact"`` or ``"reference"``); prune_words: "+MI".
    words: the V words of φ^w's columns (for messages).
    channels: the word channels (:class:`~spco.model.word_channels.WordChannels`: ψ, β, the shares
        and the evidence, fixed like φ), or ``None`` (the naming rule's word model).
    """

    log_phi_visual: np.ndarray
    log_phi_words: np.ndarray
    log_g0: np.ndarray
    word_mask: np.ndarray
    hyperparameters: TransferHyperparameters
    variant: str
    prune_words: bool
    words: tuple[str, ...]
    channels: WordChannels | None = None

    @property
    def n_features(self) -> int:
        """Visual dimension D."""
        return int(self.log_phi_visual.shape[1])

    @property
    def n_words(self) -> int:
        """Vocabulary size V."""
        return int(self.log_phi_words.shape[1])

    def sampler_settings(self) -> SamplerSettings:
        """The sampler of a home with this shared part fixed: its variant and "+MI", the view weight
        and the block moves of its hyperparameters (:func:`new_home_block_moves`)."""
        return SamplerSettings.create(self.variant, self.prune_words, learn_shared=False,
                                      view_counts=self.hyperparameters.view_counts,
                                      block_moves=new_home_block_moves(self.hyperparameters.block_moves),
                                      power=self.hyperparameters.target == "power")


def new_home_block_moves(block_moves: str) -> bool:
    """Whether a new home's sampler (``adapt``, ``adapt --joint``, a teaching's local update) runs the
    region block moves of :mod:`spco.model.blocks`, given the knowledge's ``block_moves``: ``"adapt"``
    and ``"all"`` run them; ``"off"`` and ``"phi"`` do not. ``"phi"`` names the φ^v-marginal block
    moves of the joint fit (:mod:`spco.model.phi_moves`: a home's blocks move with θ^v and φ^v
    integrated out given the other homes' tables), a setting of the fit: a new home's sampler holds
    φ^v at the knowledge (or, with ``joint``, draws it under the knowledge as its prior, with no other
    homes' tables), so that move has nothing to integrate and is not one of its steps. Knowledge
    fitted with ``"phi"`` therefore adapts and teaches as knowledge fitted with ``"off"`` would
    (the same draws); ``spco fit --set block_moves=adapt`` is the setting for block moves in new homes."""
    return block_moves in ("adapt", "all")


@dataclass(frozen=True)
class SharedPrior:
    """The knowledge as the prior of the shared part (``joint``): Dir(A φ̄), Dir(A_g Ḡ_0).

    visual (L, D) A^v_l φ̄^v_l; words (L, V) A^w_l φ̄^w_l; g0 (L,) A_g Ḡ_0."""

    visual: np.ndarray  # (L, D)
    words: np.ndarray  # (L, V)
    g0: np.ndarray  # (L,)

    @classmethod
    def of(cls, shared: SharedPart, concentration_visual: np.ndarray, concentration_words: np.ndarray,
           concentration_g0: float) -> SharedPrior:
        """The prior from the shared part's means and their concentrations ((L,), (L,), scalar;
        NaN or non-positive: unknown, replaced by δ^v, δ^w, γ)."""
        hyper = shared.hyperparameters

        def filled(a: np.ndarray, default: float) -> np.ndarray:
            a = np.asarray(a, dtype=np.float64)
            return np.where(np.isfinite(a) & (a > 0), a, default)

        a_v = filled(concentration_visual, hyper.delta_visual)
        a_w = filled(concentration_words, hyper.delta_word)
        a_g = float(filled(np.array([concentration_g0]), hyper.gamma)[0])
        return cls(visual=a_v[:, None] * np.exp(shared.log_phi_visual),
                   words=a_w[:, None] * np.exp(shared.log_phi_words),
                   g0=a_g * np.exp(shared.log_g0))


def prepare_home(positions: np.ndarray, visual: sp.csr_array, sentences: Sequence[str | None],
                 vocabulary: Vocabulary, word_increment: int, scale: float,
                 centre: np.ndarray, view_missing: np.ndarray | None = None) -> PreparedData:
    """PreparedData of one home (positions in metres are scaled to the sampler's units).

    Parameters
    ----------
    positions: (n, 4) metres ``(x, y, sin θ, cos θ)``; visual: (n, D) counts; sentences: n
    sentences (``None``: untaught); vocabulary, word_increment: how sentences become counts;
    scale: sampler units per metre; centre: (4,) the regions' prior mean, metres;
    view_missing: (n,) bool, the samples without a view (their rows of ``visual`` are ignored).
    """
    n = positions.shape[0]
    factor = np.array([scale, scale, 1.0, 1.0])
    missing = np.zeros(n, dtype=bool) if view_missing is None else np.asarray(view_missing, dtype=bool)
    if missing.any():  # a sample without a view has no counts, whatever its row held
        keep = sp.diags_array((~missing).astype(np.int64), dtype=np.int64)
        visual = sp.csr_array(keep @ sp.csr_array(visual), dtype=np.int64)
    return PreparedData(
        positions=np.asarray(positions, dtype=np.float64) * factor,
        homes=np.zeros(n, dtype=np.int64),
        visual=stack_counts(visual),
        words=stack_counts(vocabulary.encode(list(sentences), word_increment)),
        n_homes=1, offsets=np.array([0, n], dtype=np.int64), position_scale=scale,
        map_centres=(np.asarray(centre, dtype=np.float64) * factor)[None, :],
        view_missing=missing,
    )


def switch_tokens(data: PreparedData, state: GibbsState) -> np.ndarray:
    """(V, 3) the home's expected tokens of each word per channel (name, place, background): every
    token's switch probabilities given its sample's concept (each token counted once,
    :func:`spco.model.word_channels.switch_probabilities`); zeros without channels or words."""
    if state.channels is None or not data.words.nnz:
        return np.zeros((data.words.shape[1], 3))
    return expected_tokens(data.words, data.homes, state.concepts, state.log_theta_w, state.channels)


def draw_switches(data: PreparedData, state: GibbsState, rng: np.random.Generator,
                  rows: np.ndarray | None = None) -> None:
    """Draw the word channels' switch of the tokens of the samples ``rows`` (default: every token
    whose switch is unknown, −1, or all of them if the state has none for ``data``) given their
    sample's concept, each token once (:func:`spco.model.word_channels.switch_probabilities`), in
    place. Nothing without channels."""
    words = data.words
    if state.channels is None or not words.nnz:
        if state.channels is not None:
            state.switches = np.zeros(0, dtype=np.int8)
        return
    token_row = token_rows(words)
    if state.switches is None or state.switches.shape != (words.nnz,):
        state.switches = np.full(words.nnz, -1, dtype=np.int8)
    if rows is None:
        todo = np.flatnonzero(state.switches < 0)
    else:
        todo = np.flatnonzero(np.isin(token_row, np.asarray(rows, dtype=np.int64)))
    if todo.size == 0:
        return
    sub_rows = np.unique(token_row[todo])
    sub = sp.csr_array(words[sub_rows])
    p = switch_probabilities(sub, data.homes[sub_rows], state.concepts[sub_rows], state.log_theta_w,
                             state.channels)
    # the tokens of ``sub`` in the order of ``words``' tokens of those rows
    position = np.concatenate([np.arange(words.indptr[r], words.indptr[r + 1]) for r in sub_rows])
    wanted = np.isin(position, todo)
    u = rng.random(int(wanted.sum()))
    drawn = (u[:, None] > np.cumsum(p[wanted], axis=1)[:, :2]).sum(axis=1).astype(np.int8)
    switches = state.switches.copy()
    switches[position[wanted]] = drawn
    state.switches = switches


#: A word is one of a home's names once the posterior expects at least this many of its uses to be
#: names: the switches' expected counts (each token's switch probability given its concept), averaged
#: over the fit's kept sweeps (`KnowledgeChannels.tokens`; a joint fit's `SpCoTransfer.channel_tokens_`)
#: plus the home's. A word said once is a name when its switch says name more likely than not ("this
#: is the study room"), not when it says place ("the fridge is over here": the evidence gives P(name)
#: 0.22); a function word, with no name use at all, never.
NAME_TOKENS = 0.5
#: ... and at least this share of its uses: a word of the experienced homes whose uses are names often
#: enough ("dining", names in 9–18 % of its SIGVerse template uses and an activity in the rest, names
#: the dining area); "location", "place", "space" (no name use, at most 2 of 39 in a synthetic seed,
#: 0.051) are none. Chosen on development data inside the range where no verdict changes: on the six
#: fits of benchmarks/README.md, "Which words are names", and the four synthetic template fits of
#: tests/test_name_decision.py every verdict is the same for any share from 0.052 to 0.091; at 0.1 (the
#: value chosen on the templates before) "dining" was a name in 5 of the 6 fits.
NAME_SHARE = 0.07


def name_words(tokens: np.ndarray) -> np.ndarray:
    """(V,) bool: the words that are names given their uses per channel ``tokens`` (V, 3) (name,
    place, background; the switches' expected counts): at least :data:`NAME_TOKENS` name uses and at
    least :data:`NAME_SHARE` of all its uses."""
    tokens = np.asarray(tokens, dtype=np.float64)
    return (tokens[:, NAME] >= NAME_TOKENS) & (tokens[:, NAME] >= NAME_SHARE * tokens.sum(axis=1))


#: A concept whose knowledge weight G_0 is below this is one the experienced homes did not use:
#: the knowledge holds no information about it (its φ is a prior draw), see :func:`learn_free_concepts`.
FREE_CONCEPT_WEIGHT = 1e-3


def own_names_to_free_concepts(data: PreparedData, state: GibbsState, shared: SharedPart,
                                n_known: int, words: np.ndarray | None = None,
                                movable: np.ndarray | None = None) -> bool:
    """Give each name first heard in this home a concept of its own, one the knowledge does not use.

    The samples standing for such a name (:func:`gibbs.sample_names`: those that say it, and the
    untaught samples of the regions where it is said most) move together to a free concept, unless
    they already hold one alone. Left to the sampler, a new name lands in the concept of another
    place (every concept gives an unheard word the same tiny mass), whose visual distribution —
    δ^v = 3·10^5 pseudo-counts of that place's views — then sends the rest of the room's views to the
    transferred concept of its kind ("bedroom"). ``words``: only these names (word ids; a teaching's
    own words, :func:`spco.model.local_update.teach_locally`), default every new name of the home;
    ``movable``: (N,) bool, the only samples that may stand for them (default every sample).
    Returns whether any sample moved."""
    if shared.variant != "exact" or data.words.shape[1] <= n_known:
        return False
    hyper = shared.hyperparameters
    candidate = np.zeros(data.words.shape[1], dtype=bool)
    if shared.channels is not None:  # with the word channels: a new word whose tokens here are names
        candidate[n_known:] = name_words(switch_tokens(data, state))[n_known:]
    else:
        verdict = gibbs.naming_verdicts(data, state, hyper)
        candidate[n_known:] = verdict[n_known:] != NOT_A_NAME
    names = gibbs.sample_names(data, state.regions, hyper, named=candidate)
    if words is not None:  # the names of every sample judged as before, only these names moved
        names = np.where(np.isin(names, np.asarray(words, dtype=np.int64)), names, -1)
    if movable is not None:
        names = np.where(movable, names, -1)
    free = np.exp(shared.log_g0) < FREE_CONCEPT_WEIGHT
    moved = False
    for word in np.unique(names[names >= 0]):  # a loop over the home's few new names
        rows = names == word
        held = np.unique(state.concepts[rows])
        if held.size == 1 and free[held[0]] and not (state.concepts[~rows] == held[0]).any():
            continue
        open_slots = np.flatnonzero(free & (np.bincount(state.concepts[~rows], minlength=free.size) == 0))
        if open_slots.size == 0:
            break
        state.concepts[rows] = open_slots[0]
        moved = True
    return moved


def learn_free_concepts(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters,
                         settings: SamplerSettings, rng: np.random.Generator) -> None:
    """Learn φ of the concepts the knowledge does not use from this home, then redraw the home's θ,
    G_e, π and regions given them (exact sampler, shared part otherwise fixed).

    The posterior of such a concept's φ given the experienced homes is its prior, so given this home
    too it is the prior updated by this home: φ_l ~ Dir(α + table counts of this home), tables ~
    CRT(n, δ φ_l) — the global step of the exact sampler restricted to these concepts. Then θ | φ,
    as the partially collapsed order requires. G_0 (``state.log_g0``) is the knowledge's.
    """
    if settings.variant != "exact":
        return
    unused = np.exp(state.log_g0) < FREE_CONCEPT_WEIGHT  # G_0 is the knowledge's: fixed while adapting
    if not unused[state.concepts].any():
        return
    stats = sweep_statistics.sufficient_statistics(data, state, hyper, settings.learning_view_counts())
    free = np.flatnonzero(unused & (stats.concepts[0] > 0))
    state.log_phi_v[free] = HierarchicalMultinomial.sample_shared_given_counts(
        stats.visual[:, free], state.log_phi_v[free], hyper.delta_visual, hyper.alpha_visual, rng,
        passes=hyper.phi_passes)
    tables_w = HierarchicalMultinomial.sample_tables(stats.words[:, free], state.log_phi_w[free],
                                                     hyper.delta_word, rng)
    state.log_phi_w[free] = HierarchicalMultinomial.sample_shared(tables_w, hyper.alpha_word, rng)
    parameter_steps.home_step(data, state, stats, hyper, settings, rng)


def sweep_home(data: PreparedData, state: GibbsState, hyper: TransferHyperparameters,
           settings: SamplerSettings, rng: np.random.Generator, prior: SharedPrior | None,
           n_known: int) -> None:
    """One sweep for one home: shared part fixed (``prior`` None) or learnt with ``prior``.

    Learning the shared part with pruning re-decides about the knowledge's words (only those the
    knowledge kept can stay: ``state.candidate_words``); the words first heard in this home are
    kept during the sweeps and judged in the home afterwards (:func:`judge_new_words`)."""
    if prior is None:
        gibbs.sweep(data, state, hyper, settings, rng, swaps=False)
        learn_free_concepts(data, state, hyper, settings, rng)
        return
    assignments.local_step(data, state, settings, rng, hyper)
    stats = sweep_statistics.sufficient_statistics(data, state, hyper, settings.learning_view_counts())
    if settings.variant == "reference":  # the authors' order: home, then shared from pooled counts
        parameter_steps.home_step_reference(data, state, stats, hyper, settings, rng)
        state.log_phi_v = log_dirichlet(prior.visual + stats.visual.sum(0), rng)
        state.log_phi_w = log_dirichlet(prior.words + stats.words.sum(0), rng)
        state.log_g0 = log_dirichlet(prior.g0 + stats.concepts.sum(0), rng)
    else:  # exact: shared given table counts (θ, G_e integrated out), then the home
        state.log_phi_v = HierarchicalMultinomial.sample_shared_given_counts(
            stats.visual, state.log_phi_v, hyper.delta_visual, prior.visual, rng, passes=hyper.phi_passes)
        tables_w = HierarchicalMultinomial.sample_tables(stats.words, state.log_phi_w, hyper.delta_word, rng)
        state.log_phi_w = log_dirichlet(prior.words + tables_w, rng)
        tables_g = sample_crt(stats.concepts, hyper.gamma * np.exp(state.log_g0)[None, :], rng).sum(axis=0)
        state.log_g0 = log_dirichlet(prior.g0 + tables_g, rng)
        parameter_steps.home_step(data, state, stats, hyper, settings, rng)
    if state.channels is not None:  # the word channels: no word is pruned
        return
    if settings.prune and settings.variant == "exact":
        known = state.candidate_words if state.candidate_words is not None else state.word_mask
        state.word_mask = home_word_mask(gibbs.naming_verdicts(data, state, hyper), known, n_known)
    elif settings.prune:
        gibbs.prune(state, hyper, settings)
        state.word_mask[n_known:] = True


def initial_state(data: PreparedData, shared: SharedPart, settings: SamplerSettings,
                   n_known: int, rng: np.random.Generator) -> GibbsState:
    """The state a new home starts from: the knowledge's shared part; regions by k-means; θ, G_e
    drawn from their priors given the shared part; π uniform (so that the first assignments follow
    the regions and the knowledge's visual distributions); new words' θ^w equal in every concept
    (they carry no information until samples are assigned)."""
    hyper = shared.hyperparameters
    L, K = hyper.n_concepts, hyper.n_regions
    n = data.n_samples
    x = data.positions
    k = min(K, n)
    best = np.inf
    for _ in range(10 if settings.variant == "reference" else 1):
        centres, labels = kmeans2(x, k, minit="++", seed=int(rng.integers(0, 2**31 - 1)))
        cost = ((x - centres[labels]) ** 2).sum()
        if cost < best:
            best, best_centres, best_labels = cost, centres, labels
    means = np.empty((1, K, 4))
    means[0, :k] = best_centres
    means[0, k:] = best_centres[rng.integers(0, k, size=K - k)]
    state = GibbsState(
        concepts=np.zeros(n, dtype=np.int64), regions=best_labels.astype(np.int64),
        log_g=np.full((1, L), -math.log(L)), log_g0=shared.log_g0.copy(),
        log_pi=np.full((1, L, K), -math.log(K)), means=means,
        covariances=np.tile(100.0 * np.eye(4), (1, K, 1, 1)),
        log_theta_v=np.broadcast_to(shared.log_phi_visual, (1, L, shared.n_features)).copy(),
        log_theta_w=np.broadcast_to(shared.log_phi_words, (1, L, shared.n_words)).copy(),
        log_phi_v=shared.log_phi_visual.copy(), log_phi_w=shared.log_phi_words.copy(),
        word_mask=shared.word_mask.copy(), channels=shared.channels,
    )
    stats = sweep_statistics.sufficient_statistics(data, state, hyper, settings.learning_view_counts())
    for name in ("visual", "words", "concepts", "regions_by_concept"):
        setattr(stats, name, np.zeros_like(getattr(stats, name)))  # new arrays: the sampler caches n^v
    if settings.variant == "reference":
        parameter_steps.home_step_reference(data, state, stats, hyper, settings, rng)
    else:
        parameter_steps.home_step(data, state, stats, hyper, settings, rng)
    state.log_pi = np.full((1, L, K), -math.log(K))
    init_new_words(state, n_known, np.zeros(L), hyper.delta_word)
    return state


def init_new_words(state: GibbsState, n_known: int, word_counts: np.ndarray,
                    delta_word: float) -> None:
    """Start the θ^w of the words first heard in this home at their posterior mean.

    Given the current assignments, E[θ^w_{l,k}] = δ^w φ^w_{l,k} / (δ^w + N_l) for a word k that no
    sample of concept l has said yet (N_l: the words said in concept l; ``word_counts``, (L,)):
    a concept that already holds many words leaves less room for a new one — the Dirichlet's own
    crowding. (A draw from that Dirichlet would hide it under the spread of a Gamma(α^w) variate,
    hundreds of nats for S^w = 5000 counts, and send the first sample that says the word to a
    random concept.) Before any assignment (``adapt``) this is the same in every concept, so the
    first samples that say a new word are placed by what they see and where they are.
    """
    if state.log_theta_w.shape[2] <= n_known:
        return
    log_a = math.log(delta_word) + state.log_phi_w[:, n_known:]  # (L, new)
    state.log_theta_w[0, :, n_known:] = log_a - np.log(delta_word + np.asarray(word_counts, float))[:, None]


def home_word_mask(verdict: np.ndarray, known_mask: np.ndarray, n_known: int) -> np.ndarray:
    """The words a home may use, (V,) bool: the first ``n_known`` (the knowledge's words) if the
    knowledge kept them (``known_mask``) or the home names a place with them (``verdict`` NAME);
    the words first heard in the home unless the home shows they are no name (NOT_A_NAME)."""
    from spco.model.pruning import NAME, NOT_A_NAME

    mask = verdict != NOT_A_NAME
    mask[:n_known] = np.asarray(known_mask[:n_known], dtype=bool) | (verdict[:n_known] == NAME)
    return mask


def judge_new_words(state: GibbsState, shared: SharedPart, n_known: int,
                     data: PreparedData | None = None) -> None:
    """With pruning, decide about the home's words.

    Exact variant (given the home's ``data``): the naming rule judged in this home
    (:func:`gibbs.naming_verdicts` on its samples' regions). A word the knowledge kept stays kept;
    a word it pruned is kept again if the home says it mostly at one place (a home-specific name
    such as ``study`` that the experienced homes used differently); a word first heard here is
    kept unless the home shows that it is said alike everywhere — a name taught once is usable at
    once. Reference variant: the words first heard here are judged by the authors' score on the
    home's θ^w and G_e."""
    if not shared.prune_words:
        return
    if shared.channels is not None:  # the word channels: no word is pruned, the switches say names
        state.word_mask = np.ones(state.log_theta_w.shape[2], dtype=bool)
        return
    state.word_mask = state.word_mask.copy()
    if shared.variant == "exact" and data is not None:
        verdict = gibbs.naming_verdicts(data, state, shared.hyperparameters)
        state.word_mask = home_word_mask(verdict, shared.word_mask, n_known)
        return
    if state.log_theta_w.shape[2] <= n_known:
        return
    score = "kl" if shared.variant == "reference" else "mi"
    theta = np.exp(state.log_theta_w[0])
    weights = np.exp(state.log_g[0])
    threshold = shared.hyperparameters.pruning_threshold(score)
    keep = words_to_keep(theta, weights / weights.sum(), threshold, score)
    state.word_mask[n_known:] = keep[n_known:]


#: Share of a home's samples that the home's own names (concepts the knowledge does not use) may
#: take in regions where none of them was said before :func:`warn_if_own_names_spread` warns.
OWN_NAMES_SPREAD_WARNING = 0.25


class OwnNamesSpreadWarning(UserWarning):
    """The home's own names took over much of the home, far from where they were said."""


def warn_if_own_names_spread(data: PreparedData, state: GibbsState, shared: SharedPart, home_name: str,
                             n_known: int, stacklevel: int = 3) -> float:
    """Warn when the concepts of the home's own names hold more than :data:`OWN_NAMES_SPREAD_WARNING`
    of the home's samples in regions where none of those names was said; returns that share.

    The home's own names are the names it uses that the knowledge does not give (words first heard
    in the home, after the knowledge's ``n_known``, and words the knowledge pruned); their concepts
    are the concepts the knowledge does not use (G_0 below :data:`FREE_CONCEPT_WEIGHT`) that hold a
    sample saying one. A home without own names is never warned about (its samples may still sit in
    such concepts: views the knowledge explains poorly, which :func:`spco.knowledge.check_view_fit`
    measures).

    A concept the knowledge does not use learns its views from this home alone; when the
    knowledge's concepts explain the home's views poorly (a knowledge from few homes or few sweeps),
    such a concept explains the other rooms' views better than they do and gathers them sweep after
    sweep: one `teach` of "study room" at the entrance then names the kitchen and the bedroom "study
    room" too. (Measured: a knowledge of 3 synthetic homes and 12 sweeps, one teaching: 92 of the
    home's 120 samples, 72 outside the taught room; of 16 homes and 100 sweeps: the taught room's 20
    samples and none outside.)

    Diagnosis (``benchmarks/own_name_spread.py``): the rooms leaving the knowledge's concepts is the
    model's posterior given a fixed knowledge (θ^v is held at φ^v by δ^v, so those concepts cannot
    adapt to the home's views), but their gathering in the *named* concept is the sampler's: the
    assignment with the other rooms in other, unnamed free concepts scores 4·10^3 nats higher (3
    homes) and the sampler keeps it once there, yet no single-sample move opens an empty free concept
    (its φ^v is a prior draw). With 16 homes that assignment scores 1.6·10^4 nats higher than the
    sampler's, and in it `what` answers no transferred name at any room: a sampler that found it would
    trade this warning for homes that lose their names, so the sampler is left as it is."""
    free = np.exp(shared.log_g0) < FREE_CONCEPT_WEIGHT
    own = np.ones(data.words.shape[1], dtype=bool)
    own[:n_known] = ~np.asarray(shared.word_mask[:n_known], dtype=bool)
    own &= np.asarray(state.word_mask, dtype=bool)
    says_own = np.diff(data.words[:, np.flatnonzero(own)].indptr) > 0 if own.any() else np.zeros(
        data.n_samples, dtype=bool)
    named = np.zeros(free.size, dtype=bool)
    named[state.concepts[says_own & free[state.concepts]]] = True
    in_named = named[state.concepts]
    if not in_named.any():
        return 0.0
    said_regions = np.zeros(int(state.regions.max()) + 1, dtype=bool)
    said_regions[state.regions[says_own & in_named]] = True
    spread = float(np.mean(in_named & ~said_regions[state.regions]))
    if spread > OWN_NAMES_SPREAD_WARNING:
        said = np.asarray(data.words[says_own & in_named].sum(axis=0)).ravel() > 0
        names = [shared.words[w] for w in np.flatnonzero(said & own)]
        shown = ", ".join(repr(n) for n in names[:4])
        verb = "stands" if len(names) == 1 else "stand"
        warnings.warn(f"{home_name}: {shown} now {verb} for {spread:.0%} of the home's samples in regions "
                      "where they were never said: the knowledge explains this home's views poorly, so a "
                      "place learnt from this home alone takes in other rooms. Check `spco what` at other "
                      "places; teach the places of the home by their names, or fit the knowledge on more "
                      "homes or sweeps", OwnNamesSpreadWarning, stacklevel=stacklevel)
    return spread


class NewHomeShard:
    """One home's data and sampler state, learnt with the shared part fixed (or, with ``prior``,
    learnt too with the knowledge as its prior).

    Parameters
    ----------
    data: the home's samples (:func:`prepare_home`); state: its sampler state (one home);
    shared: the shared part; n_known: how many of the vocabulary's words come from the knowledge
    (the rest were first heard in this home); rng: the home's random generator;
    prior: ``None`` (shared part fixed) or the shared part's prior (``joint``).
    """

    def __init__(self, data: PreparedData, state: GibbsState, shared: SharedPart, n_known: int,
                 rng: np.random.Generator, prior: SharedPrior | None = None) -> None:
        self.data, self.state, self.shared = data, state, shared
        self.n_known, self.rng, self.prior = n_known, rng, prior
        self.settings = shared.sampler_settings()
        self.average = ParameterAverage(data.homes, data.position_scale)

    @classmethod
    def start(cls, data: PreparedData, shared: SharedPart, n_known: int, rng: np.random.Generator,
              prior: SharedPrior | None = None) -> NewHomeShard:
        """A new home's shard from its first state (:func:`initial_state`); with ``prior`` the
        words the knowledge kept are the only candidates among its words."""
        settings = shared.sampler_settings()
        state = initial_state(data, shared, settings, n_known, rng)
        if prior is not None:
            state.candidate_words = shared.word_mask.copy()
        return cls(data, state, shared, n_known, rng, prior)

    def begin(self) -> None:
        """Before the sweeps: judge the home's words (a taught name counts at once) and, with the
        shared part fixed, give the home's own names concepts of their own."""
        judge_new_words(self.state, self.shared, self.n_known, self.data)
        draw_switches(self.data, self.state, self.rng)  # (channels: the tokens not drawn yet)
        if self.prior is None and own_names_to_free_concepts(self.data, self.state, self.shared,
                                                             self.n_known):
            learn_free_concepts(self.data, self.state, self.shared.hyperparameters, self.settings, self.rng)

    def sweep(self) -> None:
        """One sweep (:func:`sweep_home`)."""
        sweep_home(self.data, self.state, self.shared.hyperparameters, self.settings, self.rng, self.prior,
                   self.n_known)

    def run(self, n_sweeps: int, iterations: Iterable[int] | None = None) -> None:
        """``n_sweeps`` sweeps, the states of the thinned ones
        (:func:`~spco.model.posterior.thinned_sweeps`) averaged for :meth:`finish`. ``iterations``:
        the sweep numbers to loop over (default ``range(n_sweeps)``; e.g. wrapped in a progress bar)."""
        averaged = set(thinned_sweeps(int(n_sweeps))) if n_sweeps else set()
        for iteration in range(int(n_sweeps)) if iterations is None else iterations:
            self.sweep()
            if iteration in averaged:
                self.average.add(self.state)

    def finish(self, home_name: str) -> ConceptParameters | None:
        """After the sweeps: judge the home's words again and, with the shared part fixed, warn if
        the home's own names spread (:func:`warn_if_own_names_spread`). Returns the home's
        parameters averaged over the thinned sweeps of :meth:`run` (with the final word mask),
        ``None`` if no sweep was run."""
        judge_new_words(self.state, self.shared, self.n_known, self.data)
        if self.prior is None:
            warn_if_own_names_spread(self.data, self.state, self.shared, home_name, self.n_known,
                                     stacklevel=4)
        return self.average.result(self.state) if self.average.n_samples else None
