"""Hyperparameters of the spatial-concept models, with the paper's values as defaults.

Units: positions are in metres everywhere in spco's API. The paper states Ψ0 in cm² for x and y
(``diag(10, 10, 0.5, 0.5)``); :class:`TransferHyperparameters` takes it that way (``psi0`` in the
paper's units, ``position_unit_cm=True``) and the sampler converts it to metres, which leaves the
model unchanged (``../docs`` of the project: a change of units with μ0 and Ψ0 changed with it is
the same model).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any, Literal

import numpy as np

from spco.errors import ConfigurationError
from spco.model.answer_settings import LEARN, AnswerSettings, check_answer_settings

#: Default ε per pruning score (see ``TransferHyperparameters.mi_threshold``).
DEFAULT_PRUNING_THRESHOLDS = {"kl": 0.1, "mi": 0.01}

#: The settings of ``TransferHyperparameters.name_prior``: off, or the words of each concept ordered
#: by the name prior of sentence positions and WordNet (:mod:`spco.model.name_evidence`).
NAME_PRIORS = ("off", "wordnet")
NamePrior = Literal["off", "wordnet"]
#: Where the region block moves run (:mod:`spco.model.blocks`): not at all, in a new home's sampler
#: (``adapt``; a teaching's local update does not run them), or there and in the joint fit too;
#: ``phi``: the power target's φ^v-marginal block moves instead (:mod:`spco.model.phi_moves`), in the
#: joint fit (single-process and sharded), not in a new home's sampler.
BLOCK_MOVES = ("off", "adapt", "all", "phi")
BlockMoves = Literal["off", "adapt", "all", "phi"]
#: The exact sampler's warm start with the word channels (``TransferHyperparameters.warm_start``):
#: ``"things"`` (the default) — the words the evidence calls objects and WordNet calls things
#: (``Lexicon.is_thing``) mark no place, the start's sweeps weigh a token S^w;
#: ``"names"`` — the naming rule's names mark the places, a token weighs S^w (the start before things16);
#: ``"words"`` — the sweeps weigh a token W^w, the objects WordNet knows no room sense of mark no place,
#: a partly taught home's own names are held (:func:`spco.model.word_channels.warm_start_settings`;
#: opt-in, issue 28 class c). start14's ``"objects"`` is gone: a file that says it is read as
#: ``"things"`` (:data:`OLD_WARM_STARTS`).
WARM_STARTS = ("names", "words", "things")
WarmStart = Literal["names", "words", "things"]
#: Warm starts that are no longer options, and the start a file that says one is read as.
OLD_WARM_STARTS = {"objects": "things"}

#: What the exact sampler targets (``TransferHyperparameters.target``; docs/model.md, "The model the
#: sampler targets"): ``"power"`` — the power likelihood, every step (assignments, θ, φ, switches, label
#: swaps) weighing a view by its weight w and a word token by W^w, one joint distribution; ``"cut"`` —
#: the assignments weigh them so, θ^v and φ^v learn from every visual count and θ^w from S^w counts per
#: name token (a modular, "cut" sampler, no single stationary distribution).
TARGETS = ("cut", "power")
Target = Literal["cut", "power"]

#: The place channel of the word channels (``TransferHyperparameters.place_channel``): ``"shared"`` —
#: one ψ_l ~ Dir(α^p) per concept for every home; ``"home"`` — a home level, ψ_{e,l} ~ Dir(δ^p ψ_l)
#: around it, as θ^w around φ^w (:mod:`spco.model.home_place`; opt-in, issue 28 class a).
PLACE_CHANNELS = ("shared", "home")
PlaceChannel = Literal["shared", "home"]
#: δ^p, the concentration of a home's place words ψ_{e,l} around ψ_l (in place tokens, each once).
DELTA_PLACE = 10.0

#: Which name the robot answers at an observation (``TransferHyperparameters.name_answer``): ``"said"`` —
#: the name people say most there, p(w | x, v); ``"listener"`` — the name a listener would take to mean
#: the concept it is in (:func:`spco.model.prediction.listener_weights`; opt-in, issue 28 class b);
#: ``"looks"`` — the same, with a listener that takes concepts that look alike as one referent
#: (:func:`spco.model.prediction.looks_kernel`; opt-in, branch natural22).
NAME_ANSWERS = ("said", "listener", "looks")
NameAnswer = Literal["said", "listener", "looks"]

#: Where the exact sampler's δ^v and α^v come from (``TransferHyperparameters.visual_prior``): as given,
#: or estimated from the homes' views after the start (:mod:`spco.model.visual_prior`).
VISUAL_PRIORS = ("given", "estimate")
VisualPrior = Literal["given", "estimate"]

#: Where the exact sampler's δ^w and α^w come from (``TransferHyperparameters.word_prior``): as given,
#: or estimated from the homes' name tokens when the word channels start (:mod:`spco.model.word_prior`).
WORD_PRIORS = ("given", "estimate")
WordPrior = Literal["given", "estimate"]

#: The word models of the exact sampler with "+MI": word channels (name / place / background switch per
#: token, :mod:`spco.model.word_channels`) or the naming rule (words pruned by where they are said,
#: :mod:`spco.model.pruning`).
WORD_MODELS = ("channels", "naming-rule")
WordModel = Literal["channels", "naming-rule"]

#: η of ``TransferHyperparameters.evidence_weight``.
EVIDENCE_WEIGHT = 1.0

#: The paper's Ψ0 for (x, y, sin θ, cos θ), x and y in cm².
PAPER_PSI0_CM = (10.0, 10.0, 0.5, 0.5)

#: The view weight w, in counts: the default of ``TransferHyperparameters.view_counts``, the one
#: weight of a view in the sampler and in every answer (docs/model.md, "A view's evidence"); chosen
#: on development configurations. With ``view_counts="estimate"`` also the weight of the start's
#: sweeps before w is estimated, and of a fit that cannot estimate it.
VIEW_COUNTS = 16.0


def view_powers(totals, view_counts):
    """ω = min(1, w / Σ_d v_d), the power of each view's multinomial likelihood for the view weight
    w = ``view_counts`` and the views' total counts ``totals`` (broadcast: a grid of weights against
    the views gives the grid of powers): the one definition of a view's weight, used by the sampler
    (:func:`spco.model.assignments.view_weights`), every answer (:mod:`spco.model.prediction`) and the
    view-weight estimate (:mod:`spco.model.view_fit`). Views with fewer than one count count whole."""
    return np.minimum(1.0, np.asarray(view_counts, dtype=np.float64)
                      / np.maximum(np.asarray(totals, dtype=np.float64), 1.0))


#: ``TransferHyperparameters.view_counts`` of a model whose view weight is learnt from its homes.
ESTIMATE = "estimate"

#: The word weight W^w, in counts: the default of ``TransferHyperparameters.word_counts``, the
#: evidence of one word token in its concept's assignment (word channels; docs/model.md, "A word
#: token's evidence"): a token weighs as one view (:data:`VIEW_COUNTS`), not as the S^w = 5,000
#: counts that θ^w counts it with.
WORD_COUNTS = VIEW_COUNTS


#: The passes of the power target's blocked φ^v step (``TransferHyperparameters.phi_passes``,
#: :meth:`spco.model.observations.HierarchicalMultinomial.accept_shared`), each over a fresh random
#: partition of the dimensions; benchmarks/README.md, "Issue 29: an exact φ^v step at fc7's size".
PHI_PASSES = 4


#: Largest Dirichlet concentration or NIW κ0 accepted (sums over thousands of dimensions stay finite).
MAX_CONCENTRATION = 1e100
#: Largest condition number of Ψ0 (its smallest eigenvalue must be representable beside its largest
#: in a Cholesky factor: float64 holds 16 digits).
MAX_CONDITION = 1e12


def _check_power_count(name: str, value: Any, minimum: int, default: int, kind: str, why: str,
                       target: str) -> None:
    """Raise :class:`~spco.errors.ConfigurationError` naming ``name`` unless ``value`` is an integer
    >= ``minimum`` (said as ``kind``), and other than ``default`` only with ``target="power"``
    (``why``: what the setting is to the power target)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ConfigurationError(f"{name} must be {kind} >= {minimum}, got {value!r}")
    if value != default and target != "power":
        raise ConfigurationError(f"{name}={value} needs target='power' ({why}), got target={target!r}")


def _check_cut_start(cut_start: Any, target: str) -> None:
    """``cut_start``: a whole number of sweeps >= 0, positive only with ``target="power"``."""
    _check_power_count("cut_start", cut_start, 0, 0, "a whole number of sweeps",
                       "the cut's sweeps start the power target's chain", target)


def _check_phi_passes(passes: Any, target: str) -> None:
    """``phi_passes``: an integer >= 1, other than :data:`PHI_PASSES` only with ``target="power"``
    (the cut's φ^v counts are whole: its φ^v step is the CRT step's draw, which has no passes, and a
    fit must not ignore it)."""
    _check_power_count("phi_passes", passes, 1, PHI_PASSES, "an integer",
                       "the passes of the power target's blocked φ^v step", target)


def _check_phi_schedule(every: int, until: int | None, block_moves: str) -> None:
    """Raise :class:`ConfigurationError` naming the field for a schedule of the φ^v-marginal block
    moves that is not an integer ≥ 1 (``phi_every``) or ≥ 0 (``phi_until``), or that is set without
    ``block_moves="phi"`` (a fit must not ignore it)."""
    if isinstance(every, bool) or not isinstance(every, int | np.integer) or every < 1:
        raise ConfigurationError(f"phi_every must be an integer >= 1, got {every!r}")
    if until is not None and (isinstance(until, bool) or not isinstance(until, int | np.integer)
                              or until < 0):
        raise ConfigurationError(f"phi_until must be none or an integer >= 0, got {until!r}")
    if (every != 1 or until is not None) and block_moves != "phi":
        raise ConfigurationError(f"phi_every and phi_until schedule the φ^v-marginal block moves: they need "
                                 f"block_moves='phi', got block_moves={block_moves!r}")


def _positive(name: str, value: float) -> None:
    if not (np.isfinite(value) and value > 0):
        raise ConfigurationError(f"{name} must be a positive number, got {value!r}")


@dataclass(frozen=True)
class TransferHyperparameters:
    """Hyperparameters of the transfer model (Hagiwara et al., 2021); defaults are the paper's.

    Attributes
    ----------
    n_concepts: L, weak-limit truncation of the concept HDP (15).
    n_regions: K, regions per home (20).
    alpha_visual, alpha_word: α^v = 3, α^w = 0.01, Dirichlet priors of the shared φ^v, φ^w.
    delta_visual, delta_word: δ^v = 3e5, δ^w = 1e4, concentrations of the home-specific θ around φ.
    gamma: γ = 10, concentration of G_e ~ DP(γ, G_0).
    gamma0: γ0 = 0.2, concentration of G_0 ~ GEM(γ0) (weak limit Dir(γ0/L)).
    beta: β = 3, concentration of the region weights π_{e,l} (weak limit Dir(β/K)).
    kappa0, nu0: κ0 = 0.05, ν0 = 10 of the Normal–inverse-Wishart prior.
    psi0: diagonal of Ψ0 (4 values) or a full 4×4 matrix, x and y in cm² when
        ``psi0_in_cm2`` (the paper's convention, default ``diag(10, 10, 0.5, 0.5)``), else metres²
        (the map's units²: the scaled prior of :func:`scaled_hyperparameters` sets it from the homes'
        places, ``(ν0 − 5)·diag(s²/5, s²/5, 0.1, 0.1)`` at ν0 = :data:`PLACES_NU0`).
    mu0: prior mean of the region means in metres (4 values), or ``None`` for the map centre
        with heading (0, 0).
    mi_threshold: ε, words whose score with every concept is below ε are pruned (models "+MI"
        only). ``None`` (default) picks the threshold for the sampler's score: 0.1 for the
        authors' Bernoulli-KL score (reference variant, the paper's ε), 0.01 nats for the true
        mutual information of the exact variant. The two scores live on different scales: a place
        name said in one of L ≈ 10 equally likely concepts with P(name | concept) ≈ 0.2 has a
        2×2 mutual information of about 0.02–0.06 nats (a KL score of 0.2–0.4), the template
        words "this", "is", "the" about 0.001–0.005; with ε = 0.1 the true MI would prune every
        word.
    view_counts: the view weight w, the evidence of one view in counts — the one definition of
        a view's weight, used by the sampler's assignments, ``adapt``, ``teach``, ``what``, ``ask``
        and the experiments (:meth:`view_weight`). A view carries thousands of counts (SIGVerse
        fc7: ~7,000) and the multinomial scores each as an independent draw, so that two concepts'
        views differ by thousands of nats; but the counts of one image are not independent. With
        w a view's log-likelihood under every concept is weighted by ``min(1, w / Σ_d v_d)``: its
        proportions are scored as w draws (a power likelihood). Default :data:`VIEW_COUNTS`.
        ``"estimate"`` (opt-in): w is learnt from the experienced homes when the exact sampler fits
        several homes — the least leave-one-home-out log loss of the words taught at each view given
        the view (:func:`spco.model.view_fit.estimate_view_weight`), after the start and before the
        chain —
        and the fitted model's hyperparameters hold the number (so a knowledge file, and every home
        adapted from it, carries it); a fit that cannot estimate it uses :data:`VIEW_COUNTS`.
        ``None``: every count a draw (the paper's multinomial). Exact variant only.
    name_prior: ``"off"`` (default) or ``"wordnet"``: with ``"wordnet"``, the MI-weighted name
        prediction reorders the words of each concept by how name-like they are (the sentence
        positions and WordNet, :mod:`spco.model.name_evidence`; models with the naming rule only).
        Off by default: on the held-out speech set it lowered A_n (docs/model.md, "Which of the
        words said at a place is its name"). It changes prediction only, never the fit, and is
        written by :meth:`to_dict` only when not ``"off"`` (files and experiment identities from
        before it are unchanged).
    word_model: the exact sampler's account of the words that are not names ("+MI" models):
        ``"channels"`` (default) — every word token comes from the concept's names, the place's
        associated words or a background, a latent switch with a learnt prior and the linguistic
        evidence (:mod:`spco.model.word_channels`, docs/model.md "Words that are not names");
        ``"naming-rule"`` — the earlier rule that prunes words by where they are said
        (:mod:`spco.model.pruning`). A dictionary without it (a file from before it) reads as
        ``"naming-rule"``, the model it was learnt with.
    word_counts: the word weight W^w, the evidence of one word token in its sample's concept
        assignment, in counts (word channels only): each token's log-likelihood under every concept,
        log Σ_c p(z = c | k) p(k | c, l), is weighed by ``word_counts`` instead of the token's S^w
        counts (``Corpus.word_increment``), in the sampler, ``adapt`` and ``teach`` alike — a power
        likelihood as a view's w. θ^w still counts a name token S^w times (the names' concentration
        against δ^w φ^w). Default :data:`WORD_COUNTS` (a token weighs as a view), chosen on development
        data (docs/model.md, "A word token's evidence"); ``None``: S^w, every word's counts (as
        before it; a dictionary without it, a file from before it, reads as ``None``).
    block_moves: where the exact sampler moves a region's samples of one concept to another concept
        together after each sweep's one-sample draws (:mod:`spco.model.blocks`, G_e and π integrated
        out; an exact Gibbs step): ``"off"`` (default) nowhere, ``"adapt"`` in a new home's sampler
        (``adapt``; not in a teaching's local update), ``"all"`` in the joint fit too. Opt-in: on
        development it helps little and, with the places prior, changes which synonym ``what``
        answers first in ``tests/test_knowledge.py`` (benchmarks/README.md, "Issue 29: block moves
        in adapt"). ``"phi"`` (``target="power"`` only): the φ^v-marginal block moves instead — a
        home's (region, concept) blocks move with θ^v and φ^v integrated out given the other homes
        (:mod:`spco.model.phi_moves`, issue 29), run by the joint fit (:func:`spco.model.gibbs.sweep`
        and the sharded fit of ``SpCoTransfer.fit``, ``spco fit``; scheduled by ``phi_every`` and
        ``phi_until``) — a setting of the fit: a new home's sampler (``adapt``, a teaching), which
        holds φ^v at the knowledge, runs no block moves with it, as with ``"off"``
        (:func:`spco.model.home_shard.new_home_block_moves`).
        Written by :meth:`to_dict` only when not ``"off"`` (files and experiment identities from
        before it are unchanged).
    target: what the exact sampler's chain targets (:data:`TARGETS`): ``"power"`` — the power
        likelihood of docs/model.md ("The model the sampler targets"): a view's multinomial raised to
        ω_t = min(1, w / Σ_d v_d), a word token's channel likelihood to W^w times its occurrences, in
        every conditional (θ^v, φ^v, θ^w, ψ, β, the switches, the assignments, the label swaps and
        block moves), so that the chain has one stationary distribution; it needs a whole
        ``word_counts`` (a word token's counts stay whole: φ^w's CRT tables). ``"cut"`` (default) —
        the assignments weigh views and tokens so, θ^v and φ^v count every visual count, θ^w a name
        token's S^w counts and the switch a token once (a modular sampler). Written by :meth:`to_dict`
        only when not ``"cut"`` (files and experiment identities from before it are unchanged). The
        paper's δ^v and α^v are set for raw counts: with ``"power"`` use ``visual_prior="estimate"``
        (docs/model.md, "The visual prior in the power target's units").
    visual_prior: ``"given"`` (default): δ^v and α^v as set; ``"estimate"``: both estimated from the
        experienced homes' views by the method of moments, on the concepts of the start, before the
        chain (:func:`spco.model.visual_prior.estimate_visual_prior`; exact variant, two homes or
        more): δ^v from the spread of the homes' view proportions around their concept's mean, α^v
        from the concepts' spread around the uniform — the priors in the units of proportions,
        which the power target's w draws per view do not swamp (``target="power"``). The fitted
        model's hyperparameters hold the numbers (a knowledge file, and every home adapted from it,
        carries them); a quantity that cannot be estimated keeps its given value. Written by
        :meth:`to_dict` only when not ``"given"``.
    word_prior: ``"given"`` (default): δ^w and α^w as set; ``"estimate"``: both estimated from the
        experienced homes' name tokens by the same method of moments, on the concepts of the start,
        each token weighed by the switch's prior p(z = name | word), when the word channels start
        (:func:`spco.model.word_prior.estimate_word_prior`; exact variant, word channels, two homes or
        more): δ^w from the spread of the homes' name proportions around their concept's mean, α^w
        from the concepts' spread around the uniform — the priors in the units of proportions, which
        the power target's W^w counts per token do not swamp (the given δ^w = 10^4 was set against
        S^w = 5,000 counts per token). Kept in the fitted hyperparameters (the knowledge file, and
        every home adapted or taught from it, uses the numbers); a quantity that cannot be estimated
        keeps its given value. Written by :meth:`to_dict` only when not ``"given"``.
    warm_start: the exact sampler's start with the word channels (:data:`WARM_STARTS`; docs/model.md,
        "With the word channels the start can weigh words as the chain does"). ``"things"`` (default):
        a word the evidence calls an object (name prior below
        :data:`spco.model.unheard.OBJECT_BELOW`) marks no place when WordNet gives positive evidence
        that its head word is a thing (:meth:`spco.data.lexicon.Lexicon.is_thing`: "fridge", "bed",
        "towel"; not a word WordNet does not know, "dormitorio", nor one it knows mostly as an act,
        "dining", nor a thing it also calls by a room's word, "tub": also "bath"), so such a word said
        in two rooms does not join their places at the chain's start; the start's sweeps weigh a token
        S^w. It is the default because on development data every guard of its rule, committed before
        its runs, held (natural speech +0.0015 ± 0.013 on fresh seeds 70–89, within noise; the written
        set's A_p +0.028 ± 0.027; benchmarks/README.md, branches objfilter15 and things16).
        ``"names"`` — the naming rule's names mark the places, objects too (the start before).
        ``"words"`` — the start's sweeps weigh a word token W^w (``word_counts``) as the chain does,
        the words the evidence calls objects that WordNet knows no room sense of mark no place, and a
        partly taught home keeps its own names; opt-in (benchmarks/README.md, branches start10 and
        start12). A file that says start14's ``"objects"`` (no longer an option) is read as
        ``"things"`` with a :class:`FutureWarning`. Written by :meth:`to_dict` always (a file without
        it, written before things16, means ``"names"``).
    place_channel: the place channel ψ of the word channels (:data:`PLACE_CHANNELS`): ``"shared"``
        (default) — one ψ_l ~ Dir(α^p) per concept, the same in every home; ``"home"`` — a home level,
        ψ_{e,l} ~ Dir(δ^p ψ_l), so that one home's objects and its people's object words do not make
        a concept of their own (:mod:`spco.model.home_place`; opt-in, benchmarks/README.md, branch
        psi16: it halves the views answered with an object word, but as the default it did not raise
        development natural speech's mean A_n beyond noise, +0.006 ± 0.010 over 20 fresh seeds,
        branch psidef18). Written by :meth:`to_dict` only when not ``"shared"``.
    delta_place: δ^p, the concentration of ψ_{e,l} around ψ_l, in place tokens (each token once, as
        ψ learns; default :data:`DELTA_PLACE`). Used with ``place_channel="home"``; written by
        :meth:`to_dict` only when not the default or with ``place_channel="home"``.
    name_answer: which name the robot answers with the naming rule's pruning or the word channels
        (:data:`NAME_ANSWERS`): ``"said"`` (default) — the name people say most at the observation,
        p(w | x, v); ``"listener"`` — a pragmatic speaker's, Σ_l P(l | x, v) θ^w_{e,l,w} L(l | w) with the
        listener L(l | w) ∝ G_0,l θ^w_{e,l,w}, so a name said here that is mostly another concept's
        ("kitchen" said at the washroom) comes behind a name of this concept's own (opt-in,
        benchmarks/README.md, branch classc18); ``"looks"`` — the same speaker with a listener that takes
        concepts that look alike as one referent, Σ_l' s(l, l') L(l' | w) with s(l, l') the
        Bhattacharyya coefficient of φ^v_l and φ^v_l' to the power of the view weight
        (:func:`spco.model.prediction.looks_kernel`: a name shared by concepts of one kind of place,
        "bedroom", is not taken as another concept's; opt-in, branch natural22). Read by the answers
        only, not by the fit. Written by
        :meth:`to_dict` only when not ``"said"``.
    view_in_room, typical: the answer's opt-ins (:mod:`spco.model.answer_settings`, read by the answers
        only, :meth:`answer_settings`; docs/model.md, "The answer's settings are the model's"):
        ``view_in_room`` (default ``False``) the observation's view as a draw of its room; ``typical``
        ρ, how often a room looks like its concept: ``None`` (default, off), a number within (0, 1] or
        ``"learn"``, learnt from the experienced homes' views and place labels when a knowledge is
        fitted and held as the number (:func:`spco.knowledge.fit.learnt_typicality`). Written by
        :meth:`to_dict` only when not default (an older spco refuses such a file).
    evidence_weight: η, the weight of the linguistic evidence in the switch's prior (word channels):
        p(z = name | word) ∝ λ_name ν^η, p(z = place or background) ∝ λ_c (1 − ν)^η, ν the name
        evidence of :mod:`spco.model.name_evidence`. Default :data:`EVIDENCE_WEIGHT`, chosen on
        development data (docs/model.md, "Words that are not names").
    phi_every, phi_until: the schedule of the φ^v-marginal block moves (``block_moves="phi"``): they
        run on sweep i (0-based) when i is a multiple of ``phi_every`` (default 1: every sweep) and, if
        ``phi_until`` is set, i < ``phi_until`` (the first sweeps, where a new home's places gather).
        A move on a fixed schedule keeps the chain's target (:func:`spco.model.phi_moves.phi_moves_due`).
        Only with ``block_moves="phi"``; written by :meth:`to_dict` only when not the default.
    cut_start: sweeps of the cut sampler before the power target's chain (``target="power"`` only;
        default 0: the power target from the start). The joint fit starts and runs its first
        ``cut_start`` sweeps as ``target="cut"`` with the given δ^v, α^v would (the same chain for the
        same seed), then keeps the assignments, regions and switches, redraws every parameter from
        the power target's conditionals and continues with the power target's sweeps
        (:mod:`spco.model.cut_start`; the estimates of ``visual_prior``/``word_prior="estimate"``
        made as the power target makes them). It must end before the first averaged sweep, so every
        kept draw is a power sweep: exact MCMC with a cut start. A new home's sampler (``adapt``,
        a teaching) runs the power target from its start. Written by :meth:`to_dict` only when not 0
        (a file without it reads as 0).
    phi_passes: the passes of the power target's blocked Metropolis–Hastings step for φ^v
        (:meth:`spco.model.observations.HierarchicalMultinomial.accept_shared`; default
        :data:`PHI_PASSES` = 4), each over a fresh random partition of the dimensions into blocks; in
        the joint fit, ``adapt`` and a teaching alike. Every pass leaves the power target's φ^v
        conditional invariant, so any number ≥ 1 targets the same model and only changes how far φ^v
        moves in a sweep (and its CPU: one evaluation of the fractional weight a pass). Other than 4
        only with ``target="power"``; written by :meth:`to_dict` only when not 4 (a file without it
        reads as 4).
    """

    n_concepts: int = 15
    n_regions: int = 20
    alpha_visual: float = 3.0
    alpha_word: float = 0.01
    delta_visual: float = 3e5
    delta_word: float = 1e4
    gamma: float = 10.0
    gamma0: float = 0.2
    beta: float = 3.0
    kappa0: float = 0.05
    nu0: float = 10.0
    psi0: tuple[float, ...] | tuple[tuple[float, ...], ...] = PAPER_PSI0_CM
    psi0_in_cm2: bool = True
    mu0: tuple[float, float, float, float] | None = None
    mi_threshold: float | None = None
    view_counts: float | str | None = VIEW_COUNTS
    name_prior: NamePrior = "off"
    word_model: WordModel = "channels"
    evidence_weight: float = EVIDENCE_WEIGHT
    word_counts: float | None = WORD_COUNTS
    block_moves: BlockMoves = "off"
    target: Target = "cut"
    visual_prior: VisualPrior = "given"
    word_prior: WordPrior = "given"
    warm_start: WarmStart = "things"
    place_channel: PlaceChannel = "shared"
    delta_place: float = DELTA_PLACE
    name_answer: NameAnswer = "said"
    view_in_room: bool = False
    typical: float | str | None = None
    phi_every: int = 1
    phi_until: int | None = None
    cut_start: int = 0
    phi_passes: int = PHI_PASSES

    def __post_init__(self) -> None:
        for name in ("n_concepts", "n_regions"):
            value = getattr(self, name)
            if not isinstance(value, int | np.integer) or value < 1:
                raise ConfigurationError(f"{name} must be an integer >= 1, got {value!r}")
        for name in ("alpha_visual", "alpha_word", "delta_visual", "delta_word", "gamma", "gamma0",
                     "beta", "kappa0", "evidence_weight"):
            _positive(name, float(getattr(self, name)))
            if not float(getattr(self, name)) <= MAX_CONCENTRATION:
                raise ConfigurationError(f"{name} must be at most {MAX_CONCENTRATION:g} (a Dirichlet's "
                                         f"concentrations are summed over its dimensions), got "
                                         f"{getattr(self, name)!r}")
        if not (np.isfinite(self.nu0) and 3 < self.nu0 <= MAX_CONCENTRATION):
            raise ConfigurationError(f"nu0 must exceed the dimension minus one (3) and be at most "
                                     f"{MAX_CONCENTRATION:g}, got {self.nu0!r}")
        if isinstance(self.view_counts, str):
            if self.view_counts != ESTIMATE:
                raise ConfigurationError(f"view_counts must be a number, none or {ESTIMATE!r}, "
                                         f"got {self.view_counts!r}")
        elif self.view_counts is not None:
            _positive("view_counts", float(self.view_counts))
            if not float(self.view_counts) <= MAX_CONCENTRATION:
                raise ConfigurationError(f"view_counts must be at most {MAX_CONCENTRATION:g}, "
                                         f"got {self.view_counts!r}")
        if self.word_counts is not None:
            _positive("word_counts", float(self.word_counts))
            if not float(self.word_counts) <= MAX_CONCENTRATION:
                raise ConfigurationError(f"word_counts must be at most {MAX_CONCENTRATION:g}, "
                                         f"got {self.word_counts!r}")
        if self.mi_threshold is not None and not (np.isfinite(self.mi_threshold) and self.mi_threshold >= 0):
            raise ConfigurationError(f"mi_threshold must be >= 0, got {self.mi_threshold!r}")
        if self.word_model not in WORD_MODELS:
            raise ConfigurationError(f"word_model must be one of {', '.join(map(repr, WORD_MODELS))}, "
                                     f"got {self.word_model!r}")
        if self.block_moves not in BLOCK_MOVES:
            raise ConfigurationError(f"block_moves must be one of {', '.join(map(repr, BLOCK_MOVES))}, "
                                     f"got {self.block_moves!r}")
        if self.block_moves == "phi" and self.target != "power":
            raise ConfigurationError(f"block_moves='phi' needs target='power' (the moves integrate the "
                                     f"power target's φ^v out), got target={self.target!r}")
        _check_phi_schedule(self.phi_every, self.phi_until, self.block_moves)
        for name, choices in (("target", TARGETS), ("visual_prior", VISUAL_PRIORS),
                              ("word_prior", WORD_PRIORS), ("name_answer", NAME_ANSWERS)):
            if getattr(self, name) not in choices:
                raise ConfigurationError(f"{name} must be one of {', '.join(map(repr, choices))}, "
                                         f"got {getattr(self, name)!r}")
        if (self.target == "power" and self.word_counts is not None
                and float(self.word_counts) != round(float(self.word_counts))):
            raise ConfigurationError(f"word_counts must be a whole number with target='power' (a word "
                                     f"token's counts stay whole), got {self.word_counts!r}")
        _check_cut_start(self.cut_start, self.target)
        _check_phi_passes(self.phi_passes, self.target)
        if self.warm_start not in WARM_STARTS:
            raise ConfigurationError(f"warm_start must be one of {', '.join(map(repr, WARM_STARTS))}, "
                                     f"got {self.warm_start!r}")
        self._check_place_channel()
        self._check_answer_settings()
        if self.name_prior not in NAME_PRIORS:
            raise ConfigurationError(f"name_prior must be one of {', '.join(map(repr, NAME_PRIORS))}, "
                                     f"got {self.name_prior!r}")
        psi = self.psi0_matrix_m2()
        try:
            np.linalg.cholesky(psi)
        except np.linalg.LinAlgError:
            raise ConfigurationError(f"psi0 must be symmetric positive definite, got {self.psi0!r}") from None
        eig = np.linalg.eigvalsh(psi)
        if not (eig.min() >= 1e-100 and eig.max() <= 1e100 and eig.max() <= MAX_CONDITION * eig.min()):
            raise ConfigurationError(f"psi0 must have eigenvalues within 1e-100..1e100 m² and a condition "
                                     f"number at most {MAX_CONDITION:g} (x, y beside sin θ, cos θ: a region "
                                     f"with no sample has covariance ~Ψ0 and must factorise), got "
                                     f"{self.psi0!r}")
        if self.mu0 is not None and (len(self.mu0) != 4 or not np.isfinite(self.mu0).all()):
            raise ConfigurationError(f"mu0 must be 4 finite numbers (x, y, sin θ, cos θ), got {self.mu0!r}")

    def _check_answer_settings(self) -> None:
        """:func:`~spco.model.answer_settings.check_answer_settings`; a bool and a float (JSON-ready)."""
        check_answer_settings(self.view_in_room, self.typical, learn=True)
        object.__setattr__(self, "view_in_room", bool(self.view_in_room))
        if self.typical not in (None, LEARN):
            object.__setattr__(self, "typical", float(self.typical))  # type: ignore[arg-type]

    def _check_place_channel(self) -> None:
        """Raise :class:`~spco.errors.ConfigurationError` naming ``place_channel`` or ``delta_place``."""
        if self.place_channel not in PLACE_CHANNELS:
            raise ConfigurationError(f"place_channel must be one of {', '.join(map(repr, PLACE_CHANNELS))}, "
                                     f"got {self.place_channel!r}")
        if not (isinstance(self.delta_place, int | float | np.number) and np.isfinite(self.delta_place)
                and 0 < self.delta_place <= MAX_CONCENTRATION):
            raise ConfigurationError(f"delta_place must be a positive number at most {MAX_CONCENTRATION:g}, "
                                     f"got {self.delta_place!r}")

    def answer_settings(self) -> AnswerSettings:
        """The answer's opt-in settings (``view_in_room``, ``typical``) as every answer reads them.
        Raises :class:`~spco.errors.ConfigurationError` for ``typical="learn"`` not yet learnt (a
        knowledge's fit learns it: :func:`spco.knowledge.fit.fit_knowledge`)."""
        if self.typical == LEARN:
            raise ConfigurationError("typical='learn' is learnt when a knowledge is fitted (spco fit); "
                                     "this model holds no ρ: give typical a number within (0, 1]")
        return AnswerSettings(view_in_room=bool(self.view_in_room),
                              typical=None if self.typical is None else float(self.typical))

    def pruning_threshold(self, score: str) -> float:
        """ε for the pruning score ``"mi"`` (exact variant) or ``"kl"`` (reference variant)."""
        if self.mi_threshold is not None:
            return float(self.mi_threshold)
        return DEFAULT_PRUNING_THRESHOLDS[score]

    def view_weight(self) -> float | None:
        """The view weight w as a number (``None``: every count a draw): ``view_counts``, or
        :data:`VIEW_COUNTS` while it is still to be estimated (``"estimate"``)."""
        if self.view_counts == ESTIMATE:
            return VIEW_COUNTS
        return None if self.view_counts is None else float(self.view_counts)

    def psi0_matrix_m2(self) -> np.ndarray:
        """Ψ0 as a 4×4 matrix with x and y in metres²."""
        psi = np.asarray(self.psi0, dtype=float)
        if psi.shape == (4,):
            psi = np.diag(psi)
        if psi.shape != (4, 4) or not np.isfinite(psi).all() or not np.allclose(psi, psi.T):
            raise ConfigurationError(
                f"psi0 must be 4 positive values or a symmetric 4×4 matrix, got {self.psi0!r}")
        if self.psi0_in_cm2:
            scale = np.array([0.01, 0.01, 1.0, 1.0])
            psi = psi * np.outer(scale, scale)
        return psi

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (``name_prior`` and ``block_moves`` only when not ``"off"``, ``target``
        only when not ``"cut"``, ``visual_prior`` and ``word_prior`` only when not ``"given"``,
        ``warm_start`` always: a file without it means ``"names"``, the default before things16;
        ``place_channel`` only when not ``"shared"`` and ``delta_place`` only with it or when not the
        default, ``name_answer`` only when not ``"said"``, ``view_in_room`` only when ``True``,
        ``typical`` only when not ``None``, ``phi_every`` only when not 1 and
        ``phi_until`` only when not ``None``, ``cut_start`` only when not 0, ``phi_passes`` only when not
        :data:`PHI_PASSES`)."""
        data = asdict(self)
        if data["place_channel"] == "shared":
            del data["place_channel"]
            if data["delta_place"] == DELTA_PLACE:
                del data["delta_place"]
        if data["name_answer"] == "said":
            del data["name_answer"]
        for name, default in (("view_in_room", False), ("typical", None)):
            if data[name] == default:
                del data[name]
        if data["target"] == "cut":
            del data["target"]
        if data["visual_prior"] == "given":
            del data["visual_prior"]
        if data["word_prior"] == "given":
            del data["word_prior"]
        if data["name_prior"] == "off":
            del data["name_prior"]
        if data["block_moves"] == "off":
            del data["block_moves"]
        if data["phi_every"] == 1:
            del data["phi_every"]
        if data["phi_until"] is None:
            del data["phi_until"]
        for name, default in (("cut_start", 0), ("phi_passes", PHI_PASSES)):
            if data[name] == default:
                del data[name]
            else:
                data[name] = int(data[name])
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TransferHyperparameters:
        """Inverse of :meth:`to_dict`."""
        data = dict(data)
        data.setdefault("word_model", "naming-rule")  # written before the word channels
        data.setdefault("word_counts", None)  # written before the word weight: S^w counts per token
        data.setdefault("warm_start", "names")  # written before things16, whose default is "things"
        if data["warm_start"] in OLD_WARM_STARTS:
            new = OLD_WARM_STARTS[data["warm_start"]]
            warnings.warn(f"hyperparameter warm_start={data['warm_start']!r} is no longer an option: read as "
                          f"{new!r} (the start whose objects are what WordNet calls things; "
                          "benchmarks/README.md, branch things16)", FutureWarning, stacklevel=2)
            data["warm_start"] = new
        for key in ("psi0", "mu0"):
            if data.get(key) is not None:
                data[key] = _to_tuple(data[key])
        return cls(**data)

    def with_settings(self, settings: Sequence[str]) -> TransferHyperparameters:
        """A copy with ``NAME=VALUE`` settings applied (``spco fit --set``), e.g.
        ``["n_concepts=30", "kappa0=0.001"]``.

        Scalars only (:data:`SETTABLE`): integers for ``n_concepts`` / ``n_regions``, numbers
        otherwise, ``none`` for ``view_counts`` (every count a draw), ``word_counts`` (S^w per token)
        or ``mi_threshold`` (the score's default), ``estimate`` for ``view_counts`` (learnt from the
        homes), ``true``/``false`` for ``view_in_room``, ``off``, a number or ``learn`` for ``typical``.
        Raises :class:`~spco.errors.ConfigurationError` naming the setting for an unknown name, a value
        of the wrong kind, or one the model refuses (e.g. ``kappa0=-1``).
        """
        changes: dict[str, Any] = {}
        for setting in settings:
            name, sep, text = (part.strip() for part in setting.partition("="))
            if not sep or not name or not text:
                raise ConfigurationError(f"hyperparameter setting {setting!r}: write NAME=VALUE, "
                                         "e.g. n_concepts=30")
            kind = SETTABLE.get(name)
            if kind is None:
                raise ConfigurationError(f"hyperparameter setting {setting!r}: no hyperparameter {name!r}; "
                                         f"settable: {', '.join(SETTABLE)}")
            if kind.startswith("one of "):  # a choice: checked by the constructor, which names them
                changes[name] = text
                continue
            if kind == "true or false" and text.lower() in ("true", "false"):  # else refused below
                changes[name] = text.lower() == "true"
                continue
            if name == "typical" and text.lower() in ("off", LEARN):
                changes[name] = None if text.lower() == "off" else LEARN
                continue
            if name == "view_counts" and text.lower() == ESTIMATE:
                changes[name] = ESTIMATE
                continue
            if text.lower() == "none":
                if kind not in ("number or none", "number, none or estimate", "integer or none"):
                    raise ConfigurationError(f"hyperparameter setting {setting!r}: {name} needs {kind}")
                changes[name] = None
                continue
            try:
                value: float | int = int(text) if kind.startswith("integer") else float(text)
            except ValueError:
                raise ConfigurationError(f"hyperparameter setting {setting!r}: {name} needs {kind}, "
                                         f"got {text!r}") from None
            changes[name] = value
        try:
            return replace(self, **changes)
        except ConfigurationError as exc:
            raise ConfigurationError(f"hyperparameter settings {list(settings)!r}: {exc}") from None


#: Hyperparameters :meth:`TransferHyperparameters.with_settings` sets, with the kind of value each takes.
SETTABLE: dict[str, str] = {
    "n_concepts": "integer", "n_regions": "integer", "alpha_visual": "a number", "alpha_word": "a number",
    "delta_visual": "a number", "delta_word": "a number", "gamma0": "a number", "gamma": "a number",
    "beta": "a number", "kappa0": "a number", "nu0": "a number", "mi_threshold": "number or none",
    "view_counts": "number, none or estimate", "evidence_weight": "a number", "word_counts": "number or none",
    "word_model": "one of channels, naming-rule", "block_moves": "one of off, adapt, all, phi",
    "target": "one of cut, power", "visual_prior": "one of given, estimate",
    "word_prior": "one of given, estimate", "warm_start": "one of names, words, things",
    "place_channel": "one of shared, home", "delta_place": "a number",
    "name_answer": "one of said, listener, looks", "view_in_room": "true or false",
    "typical": "off, a number within (0, 1] or learn", "phi_every": "integer", "phi_until": "integer or none",
    "cut_start": "integer", "phi_passes": "integer",
}


def _to_tuple(value: Any) -> Any:
    if isinstance(value, list | tuple):
        return tuple(_to_tuple(v) for v in value)
    return value


@dataclass(frozen=True)
class SpCoAHyperparameters(TransferHyperparameters):
    """Hyperparameters of the SpCoA baseline (one home, no environment plate).

    SpCoA draws θ^v_l ~ Dir(α), θ^w_l ~ Dir(α) directly (``alpha_visual = alpha_word = 0.1``),
    G ~ Dir(γ/L) with γ = 10, π_l ~ Dir(β/K) with β = 1 (the authors' code used 0.4), and the same
    Normal–inverse-Wishart prior. The δ's and γ0 are unused.
    """

    alpha_visual: float = 0.1
    alpha_word: float = 0.1
    beta: float = 1.0
    view_counts: float | None = None  # the baseline as published: every count a draw


#: Where the default position prior and truncations come from (``fit_knowledge(prior=…)``,
#: ``spco fit --prior``): ``"scaled"`` follows the experienced homes' scale (κ0, L, K:
#: :func:`scaled_hyperparameters`), ``"places"`` (the default) also sets Ψ0 from the homes' places,
#: ``"paper"`` is the paper's constants (the reproduction).
PRIORS = ("scaled", "places", "paper")
#: Words said at least this many times in a home measure its place sizes (:func:`scaled_hyperparameters`).
_MIN_USES = 3


def home_scales(positions: np.ndarray, said: Any) -> tuple[float, float, int]:
    """(R, s, n) of one home's training samples, in map units.

    R: the spread of its positions, sqrt of the mean variance of x and y. s: the size of its places,
    the 25th percentile over its words said at ≥ 3 samples of the spread of those samples (a place
    name is said at one place, a frame word such as "this" all over the home: the lower quartile
    is the names'), NaN with fewer than two such words. n: how many of those words are said within
    half the home's spread (words that mark one place: a count of the home's named places).

    ``said``: (n_samples, V) sparse or dense, non-zero where a sample's sentence holds the word.
    """
    xy = np.asarray(positions, dtype=np.float64)[:, :2]
    spread = float(np.sqrt(xy.var(axis=0).mean())) if xy.shape[0] else 0.0
    dense = said.todense() if hasattr(said, "todense") else said
    mask = np.asarray(dense) != 0
    uses = mask.sum(axis=0)
    sizes = np.array([np.sqrt(xy[mask[:, w]].var(axis=0).mean()) for w in np.flatnonzero(uses >= _MIN_USES)])
    size = float(np.percentile(sizes, 25)) if sizes.size >= 2 else float("nan")
    return spread, size, int((sizes < spread / 2).sum())


#: E[Σ] of the heading (sin θ, cos θ) under the paper's prior: Ψ0's 0.5 over ν0 − d − 1 = 5. The scaled
#: prior keeps it (the heading has no map units) and sets x, y from the homes' place size.
HEADING_VARIANCE = PAPER_PSI0_CM[2] / (10.0 - 4 - 1)
#: E[Σ] of a region's x and y under the scaled prior, as a share of the places' variance s²: at the
#: paper's ν0 = 10, Ψ0 = diag(s², s², 0.5, 0.5) — the paper's Ψ0 with s² for its 10 cm². Chosen on
#: development (``benchmarks/teaching.py``, synthetic homes; docs/samplers.md): with E[Σ] = s² a region
#: of a small room is as wide as a typical place and `where` draws leave the room.
REGION_SHARE = 0.2
#: ν0 of the places prior (``prior="places"``) when none is given: the prior's weight in samples,
#: ν0 − d − 1 = 15, about a place's samples in the homes it was chosen on (20 per place), so that a
#: region's covariance is the places' part unless a region's own samples outweigh it: two rooms of
#: one concept no longer score higher as one region (chosen on development, ``teaching.py``'s
#: synthetic homes; docs/samplers.md, "Priors that fit the map").
PLACES_NU0 = 20.0
#: The scaled prior's x, y variance is kept within this factor of :data:`HEADING_VARIANCE` either way:
#: Ψ0 must factorise with x, y beside the heading (its condition number at most :data:`MAX_CONDITION`).
MAX_SCALE_RATIO = 1e10


def scaled_psi0(size: float, nu0: float) -> tuple[tuple[float, float, float, float], bool]:
    """Ψ0's diagonal (map units², for ``psi0_in_cm2=False``) whose prior mean of a region's covariance
    is diag(r s², r s², h, h): E[Σ] = Ψ0 / (ν0 − d − 1), d = 4, s = ``size`` the places' size in map
    units, r = :data:`REGION_SHARE`, h = :data:`HEADING_VARIANCE` (the paper's); at ν0 = 10,
    diag(s², s², 0.5, 0.5). r s² is kept within :data:`MAX_SCALE_RATIO` of h (a map whose places
    measure less than ~7·10⁻⁶ or more than ~7·10⁴ map units); the flag says it was.

    Raises :class:`~spco.errors.ConfigurationError` for a size that is not a finite number ≥ 0 or a
    ν0 ≤ d + 1 (no prior mean of Σ)."""
    if not (np.isfinite(size) and size >= 0):
        raise ConfigurationError(f"the homes' place size must be a finite number >= 0 (map units), "
                                 f"got {size!r}")
    if not (np.isfinite(nu0) and nu0 > 5):
        raise ConfigurationError(f"nu0 must exceed d + 1 = 5 for the scaled prior (Ψ0 = (ν0 − 5)·E[Σ]: the "
                                 f"prior mean of a region's covariance must exist), got {nu0!r}; "
                                 "use --prior paper for a smaller nu0")
    variance = REGION_SHARE * size * size
    low, high = HEADING_VARIANCE / MAX_SCALE_RATIO, HEADING_VARIANCE * MAX_SCALE_RATIO
    kept = float(min(max(variance, low), high))
    strength = nu0 - 4 - 1
    xy, heading = strength * kept, strength * HEADING_VARIANCE
    return (xy, xy, heading, heading), kept != variance


def scaled_hyperparameters(homes: Sequence[tuple[np.ndarray, Any]],
                           base: TransferHyperparameters | None = None,
                           psi0: bool = False) -> TransferHyperparameters:
    """The paper's hyperparameters with the position prior and truncations following the homes' scale.

    ``homes``: (positions (n, ≥2) in map units, said (n, V)) of each experienced home's training
    samples (:func:`home_scales`). With R the median spread of the homes and s the median size of
    their places (both in map units):

    - with ``psi0`` (``prior="places"``, the default of ``fit_knowledge``): ν0 = :data:`PLACES_NU0`
      (20; ``base.nu0`` when a ``base`` is given) and Ψ0 = (ν0 − 5)·diag(s²/5, s²/5, 0.1, 0.1)
      (:func:`scaled_psi0`; at the paper's ν0 = 10 the paper's Ψ0 with the places' size s² for its
      10 cm²): the prior mean of a region's covariance is E[Σ] = Ψ0 / (ν0 − d − 1) = diag(s²/5,
      s²/5, h, h), d = 4, h the paper's heading variance (0.1): a region a part of a place, never
      wider than one (a region of n samples has E[Σ | data] = (Ψ0 + scatter)/(ν0 + n − 5): the
      places' part until its own samples outnumber ν0 − 5 = 15, so that two rooms of one concept
      score higher as two regions than as one).
      The paper's Ψ0 = diag(10 cm², 10 cm², 0.5, 0.5) expects regions of (1.4 cm)², whatever the
      map: every region must win ν0/2·log|Ψ0| back from its data, and two neighbouring rooms in one
      region are preferred to a split (benchmarks/README.md, "Teaching a live home").
    - κ0 = min(κ0_paper, (s / 2R)²). A region's mean is a priori N(μ0, Σ/κ0) around the map centre,
      and its covariance's posterior gains κ0·n/(κ0 + n)·(x̄ − μ0)(x̄ − μ0)ᵀ: with the paper's 0.05 a
      place 25 m from the centre of a university floor gets ≈ 31 m² added (its `where` draws land at
      the next room). With (s/2R)² the mean's prior spreads over twice the home's spread and the
      added term stays within a place's size wherever the place is (SIGVerse flats: s ≈ 0.3 m,
      R ≈ 2.7 m, κ0 ≈ 0.003; the CC4F floor: s ≈ 0.7 m, R ≈ 15 m, κ0 ≈ 0.0006).
    - L and K at least twice the most places any home names (words said within half its spread),
      the paper's 15 and 20 otherwise: a weak-limit truncation below the places merges them.

    Every term is in the map's units, so the same homes in metres or centimetres get the same model
    (the answers are the same). Without two words said ≥ 3 times in any home, κ0 and Ψ0 stay the
    base's (the paper's).
    """
    return scaled_from([home_scales(positions, said) for positions, said in homes], base, psi0)


def scaled_from(scales: Sequence[tuple[float, float, int]],
                base: TransferHyperparameters | None = None, psi0: bool = False) -> TransferHyperparameters:
    """:func:`scaled_hyperparameters` from the homes' :func:`home_scales` (R, s, n), computed where
    the homes are read (a :class:`~spco.model.sources.FolderHomes` keeps them). With ``psi0``, ν0 is
    ``base.nu0`` when a ``base`` is given, :data:`PLACES_NU0` otherwise, and Ψ0 follows it (E[Σ] stays
    the same whatever ν0); warns when the places' size is beyond
    what Ψ0 can hold beside the heading (:func:`scaled_psi0`)."""
    given, base = base, TransferHyperparameters() if base is None else base
    if not scales:
        return base
    nu0 = PLACES_NU0 if given is None else base.nu0
    spread = float(np.median([r for r, _, _ in scales]))
    sizes = [s for _, s, _ in scales if np.isfinite(s)]
    places = max(n for _, _, n in scales)
    changes: dict[str, Any] = {}
    if sizes and spread > 0:
        size = float(np.median(sizes))
        changes["kappa0"] = float(min(base.kappa0, max((size / (2.0 * spread)) ** 2, 1e-12)))
    if sizes and spread > 0 and psi0:
        size = float(np.median(sizes))
        psi, clamped = scaled_psi0(size, nu0)
        if clamped:
            taken = psi[0] / (nu0 - 5)
            warnings.warn(f"the homes' places measure {size:.3g} map units, beyond what the position prior "
                          f"holds beside the heading: its x, y variance is taken as {taken:.3g} map units² "
                          "(a map in metres, centimetres or millimetres is within)", stacklevel=2)
        changes.update(psi0=psi, psi0_in_cm2=False, nu0=nu0)
    return replace(base, n_concepts=max(base.n_concepts, 2 * places),
                   n_regions=max(base.n_regions, 2 * places), **changes)
