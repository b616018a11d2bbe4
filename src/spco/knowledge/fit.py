"""Fitting knowledge: the shared part of the transfer model learnt from experienced homes and
summarised over several posterior samples (:func:`fit_knowledge`)."""

from __future__ import annotations

import functools
import math
import operator
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.special import logsumexp

from spco.data.environment import Corpus
from spco.errors import ConfigurationError, DataFormatError
from spco.knowledge.diagnostics import _view_fit_record
from spco.knowledge.files import _version
from spco.knowledge.knowledge import (
    DEFAULT_FIT_ITERATIONS,
    DEFAULT_MODEL,
    MODELS,
    Knowledge,
    KnowledgeChannels,
)
from spco.model.answer_settings import LEARN
from spco.model.cut_start import check_cut_start
from spco.model.hyperparameters import PRIORS, TransferHyperparameters, scaled_from, scaled_hyperparameters
from spco.model.name_evidence import channel_evidence, has_english, name_prior
from spco.model.posterior import thinned_sweeps
from spco.model.pruning import words_to_keep
from spco.model.seeds import as_generator, seed_of
from spco.model.sources import PreparedHomes
from spco.model.state import PreparedData
from spco.model.transfer import SpCoTransfer
from spco.model.word_channels import WordChannels, token_weight, uses_word_channels, warm_start_settings
from spco.timestamps import utc_now


def summary_iterations(n_iterations: int, fraction: float = 0.25, every: int = 5) -> list[int]:
    """The sweeps (0-based) whose samples the knowledge averages: every ``every``-th of the last
    ``fraction`` of the chain, ending with the last sweep, with the step shortened so that a short
    chain still gives up to three samples (:func:`spco.model.posterior.thinned_sweeps`)."""
    return thinned_sweeps(n_iterations, fraction, every)


#: Weight, in samples (degrees of freedom), of the default spread Dir(δ φ̄) in :func:`_concentration`.
CONCENTRATION_PRIOR_SAMPLES = 2.0


def _concentration(samples: np.ndarray, default: float) -> np.ndarray:
    """Dirichlet concentration A_l of each row, moment-matched to the samples' spread, shrunk
    towards ``default``: samples (S, L, D) -> (L,).

    With φ̄ the mean and s² = Σ_k Var φ_k (ddof 1) of the S samples, the spread of Dir(A φ̄) is
    Σ_k φ̄_k(1 − φ̄_k) / (A + 1). The variance used pools the samples' S − 1 degrees of freedom
    with :data:`CONCENTRATION_PRIOR_SAMPLES` of the spread at A = ``default``::

        v = ((S − 1) s² + ν Σ_k φ̄_k(1 − φ̄_k) / (default + 1)) / (S − 1 + ν),   A = Σ_k φ̄_k(1 − φ̄_k) / v − 1

    so S = 1 gives ``default``, large S the moment-matched value, and A changes smoothly with S
    and the samples. Rows with no spread at all (φ̄ one-hot) get ``default``.
    """
    n = samples.shape[0]
    mean = samples.mean(axis=0)
    spread = (mean * (1.0 - mean)).sum(axis=-1)
    sample_var = samples.var(axis=0, ddof=1).sum(axis=-1) if n > 1 else np.zeros_like(spread)
    nu = CONCENTRATION_PRIOR_SAMPLES
    var = ((n - 1) * sample_var + nu * spread / (default + 1.0)) / (n - 1 + nu)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = spread / var - 1.0
    return np.where(np.isfinite(a) & (a > 0), a, default)


def _align_to(reference_v: np.ndarray, reference_w: np.ndarray, phi_v: np.ndarray,
              phi_w: np.ndarray) -> np.ndarray:
    """Permutation p of the concepts of one sample matching a reference: slot j takes concept p[j]."""
    cost = np.abs(reference_v[:, None, :] - phi_v[None, :, :]).sum(-1)
    if phi_w.shape[1]:
        cost = cost + np.abs(reference_w[:, None, :] - phi_w[None, :, :]).sum(-1)
    rows, cols = linear_sum_assignment(cost)
    perm = np.empty(cost.shape[0], dtype=np.int64)
    perm[rows] = cols
    return perm


def default_hyperparameters(homes: Any, base: TransferHyperparameters | None = None,
                            psi0: bool = False) -> TransferHyperparameters:
    """The scaled prior of ``homes`` (:func:`~spco.model.hyperparameters.scaled_hyperparameters`): a
    :class:`~spco.data.Corpus` is read here, a :class:`~spco.model.sources.FolderHomes` brings the
    scales it measured while reading its folders, a :class:`~spco.model.sources.SyntheticHomes` fleet
    measures them generating its homes one at a time: the same prior as the corpus of the same homes.
    ``base``: the constants scaled (default the paper's; its ν0 sets Ψ0's weight); ``psi0``: Ψ0 from
    the homes' places too (``prior="places"``)."""
    from spco.model.sources import FolderHomes, SyntheticHomes

    if isinstance(homes, FolderHomes | SyntheticHomes):
        return scaled_from(homes.scales, base, psi0)
    if isinstance(homes, Corpus):
        return scaled_hyperparameters([(t.positions, homes.word_counts(list(t.sentences)))
                                       for t in homes.training_set()], base, psi0)
    return TransferHyperparameters() if base is None else base


def fit_knowledge(
    corpus: Corpus,
    model: str = DEFAULT_MODEL,
    n_iterations: int = DEFAULT_FIT_ITERATIONS,
    random_state: int | np.random.Generator | None = None,
    progress: bool = False,
    hyperparameters: TransferHyperparameters | None = None,
    summary_fraction: float = 0.25,
    summary_every: int = 5,
    provenance: Mapping[str, Any] | None = None,
    extractor: Any = None,
    engine: Any = None,
    prior: str = "places",
) -> Knowledge:
    """Learn the shared part of the transfer model from the experienced homes of ``corpus``.

    Runs the transfer model's Gibbs sampler on every home of ``corpus`` (their training samples)
    and summarises φ^v, φ^w and G_0 over the samples of :func:`summary_iterations` (the last
    quarter of the chain, every 5th sweep): each sample is first aligned to the last one
    (Hungarian matching of its φ rows; late in the chain the labels are stable, and the number of
    samples that needed a relabelling is recorded), then φ and G_0 are averaged, and the spread
    of the samples gives the concentrations used by ``adapt(..., joint=True)``. With word pruning
    the mask is decided again on the averaged φ^w and G_0.

    Parameters
    ----------
    corpus: the experienced homes (a :class:`~spco.data.Corpus`), or a
        :class:`~spco.model.sources.FolderHomes` whose home folders the shards read themselves
        (with Ray or several local shards the driver never holds the homes' samples; the same
        result as the :class:`~spco.data.Corpus` of the same homes), or a
        :class:`~spco.model.sources.SyntheticHomes` fleet that the shards generate.
    model: one of :data:`MODELS` (default ``"spcotransfer+mi"``).
    n_iterations: Gibbs sweeps (200 as in the paper).
    random_state: seed or Generator.
    progress: show a progress bar on standard error.
    hyperparameters: default: the paper's, with the position prior and truncations of ``prior``.
    summary_fraction, summary_every: which sweeps are averaged (see :func:`summary_iterations`).
    provenance: extra entries for the knowledge's provenance (e.g. the data path).
    extractor: the :class:`~spco.features.Extractor` that computed the homes' visual counts from
        images (stored in the knowledge, so that adapt, teach and what use it); ``None`` for
        count vectors given as such.
    engine: where the homes' shards run (:func:`spco.engines.make_engine`): ``None`` in this
        process, ``"ray"`` or an engine object such as ``RayEngine(shards=4, address="auto")``.
    prior: used when ``hyperparameters`` is ``None``: ``"places"`` (default) — κ0, L and K follow
        the homes' spread and place sizes in their map units and Ψ0 the size of their places
        (:func:`default_hyperparameters`); ``"scaled"`` — κ0, L and K so, Ψ0 the paper's;
        ``"paper"`` — the paper's constants (the reproduction).

    Returns
    -------
    The :class:`Knowledge`; its ``provenance`` records the homes, the seed, the iterations, the
    samples averaged, the fit time and the spco version.
    """
    source = _check_fit_arguments(corpus, model, summary_fraction, summary_every, extractor)
    if getattr(hyperparameters, "typical", None) == LEARN and not isinstance(corpus, Corpus):
        raise ConfigurationError("typical='learn' learns ρ from the experienced homes' views and place "
                                 "labels, read here: give the homes as a Corpus (spco fit with one shard and "
                                 "no Ray), or give typical a number within (0, 1]")
    estimator, hyper, settings, evidence = _fit_setup(corpus, model, n_iterations, random_state,
                                                      hyperparameters, prior)
    variant, prune = estimator.variant, estimator.prune_words  # the model's (MODELS), set up once
    rng = as_generator(random_state)
    source, n_samples = _home_source(estimator, corpus, source)
    keep = set(summary_iterations(n_iterations, summary_fraction, summary_every))
    check_cut_start(hyper, keep)
    start = time.perf_counter()
    chain = _sample_chain(engine, source, hyper, settings, rng, evidence, n_iterations, keep,
                          f"fit ({model})" if progress else None, corpus.word_increment, corpus.vocabulary)
    seconds = time.perf_counter() - start
    run = chain.run
    hyper, settings = run.hyper, run.settings  # (with the view weight estimated from the homes)

    stack_v, stack_w, stack_g, relabelled, used, perms = _aligned_samples(chain.samples)
    channels = _averaged_channels(chain.channel_samples, perms, chain.tokens, chain.place_names)
    n = stack_v.shape[0]
    log_phi_v = logsumexp(stack_v, axis=0) - math.log(n)
    has_words = stack_w.shape[2] > 0
    log_phi_w = logsumexp(stack_w, axis=0) - math.log(n) if has_words else np.zeros((hyper.n_concepts, 0))
    log_g0 = logsumexp(stack_g, axis=0) - math.log(n)
    phi_v_samples = np.exp(stack_v)
    spread = np.abs(phi_v_samples - np.exp(log_phi_v)[None]).sum(-1)[:, used]  # total variation × 2
    word_mask = _kept_words(len(corpus.vocabulary), prune, variant, chain.word_mask_last,
                            chain.candidate_words, log_phi_w, log_g0, hyper, settings)
    conc_g = _concentration(np.exp(stack_g)[:, None, :], hyper.gamma)[0]
    record: dict[str, Any] = {
        "homes": list(corpus.names),
        "n_samples": int(n_samples),
        "seed": seed_of(random_state),
        "n_iterations": int(n_iterations),
        "fit_seconds": round(seconds, 3),
        "spco_version": _version(),
        "created": utc_now(),
        "summary": {
            "iterations": sorted(keep),
            "n_samples": int(n),
            "relabelled_samples": int(relabelled),
            "max_visual_distance_from_mean": round(float(0.5 * spread.max()) if spread.size else 0.0, 6),
        },
    }
    # each shard scores its homes (φ^v without their own counts: the pooled totals minus theirs)
    totals = np.sum(run.call("concept_visual_totals"), axis=0)
    fits = [v for part in run.call("held_out_view_fits", log_phi_v, log_g0, totals) for v in part]
    run.close()
    record["view_fit"] = _view_fit_record(dict(zip(corpus.names, fits, strict=True)))
    visual_prior = getattr(run, "visual_prior", None)  # the estimated δ^v, α^v (None: given)
    word_prior = getattr(run, "word_prior", None)  # the estimated δ^w, α^w (None: given)
    if hyper.typical == LEARN:  # ρ from the homes with the knowledge's φ^w, G_0, α's and w
        rho, used = learnt_typicality(list(corpus), log_phi_w, log_g0, list(corpus.vocabulary.words), hyper)
        hyper = replace(hyper, typical=rho)
        record["typical"] = {"learnt": rho, "samples": used}
    record.update({**_view_weight_record(run.view_weight),
                   **({"visual_prior": visual_prior} if visual_prior is not None else {}),
                   **({"word_prior": word_prior} if word_prior is not None else {}),
                   **(provenance or {})})
    return Knowledge(
        log_phi_visual=log_phi_v, log_phi_words=log_phi_w, log_g0=log_g0, word_mask=word_mask,
        concentration_visual=_concentration(phi_v_samples, hyper.delta_visual),
        concentration_words=(_concentration(np.exp(stack_w), hyper.delta_word) if has_words
                             else np.full(hyper.n_concepts, np.nan)),
        name_prior=_fitted_name_prior(corpus, prune and variant == "exact"),
        concentration_g0=float(conc_g), vocabulary=corpus.vocabulary, word_increment=corpus.word_increment,
        hyperparameters=hyper, variant=variant, prune_words=prune, provenance=record,
        extractor=None if extractor is None else extractor.spec().to_dict(),
        extractor_arrays={} if extractor is None else dict(extractor.arrays),
        channels=channels,
    )


def learnt_typicality(homes: Sequence[Any], log_phi_words: np.ndarray, log_g0: np.ndarray,
                      vocabulary: Sequence[str], hyperparameters: TransferHyperparameters
                      ) -> tuple[float, int]:
    """(ρ, samples): ``typical="learn"``'s ρ, how often a room looks like its concept, learnt from the
    experienced ``homes`` (their views, (n_e, D) each, and place labels, their ground truth) with a
    knowledge's φ^w (``log_phi_words`` (L, V) over ``vocabulary``), G_0 (``log_g0`` (L,)), α^v, α^w and
    view weight w (:func:`spco.model.view_fit.room_typicality`); ρ = 1 (the room account) when no
    sample's label is a word of the vocabulary; ``samples``: how many samples were predicted. The one
    way ρ is learnt: :func:`fit_knowledge` with ``typical="learn"`` and the benchmarks that score it.

    Raises :class:`~spco.errors.ConfigurationError` naming the home for a home without place labels."""
    from spco.model.view_fit import room_typicality

    weight = hyperparameters.view_weight()
    if weight is None:
        raise ConfigurationError("typical='learn' weighs a room's views at the view weight w: it needs "
                                 "view_counts a number or 'estimate', got none")
    labels = []
    for home in homes:
        try:
            labels.append(home.labels())
        except DataFormatError:
            raise ConfigurationError(f"typical='learn' learns ρ from the experienced homes' place labels: "
                                     f"home {home.name!r} has none; give typical a number within "
                                     "(0, 1]") from None
    rho, _, used = room_typicality([home.visual for home in homes], labels, log_phi_words, log_g0, vocabulary,
                                   hyperparameters.alpha_visual, hyperparameters.alpha_word, weight)
    return (1.0 if rho is None else rho), int(used)


def _fit_setup(corpus: Any, model: str, n_iterations: int, random_state: Any,
               hyperparameters: TransferHyperparameters | None, prior: str
               ) -> tuple[SpCoTransfer, TransferHyperparameters, Any, tuple[np.ndarray, np.ndarray] | None]:
    """The estimator of ``model``, its checked hyperparameters and sampler settings, and the word
    channels' evidence (``None``: the model learns its words without channels)."""
    variant, prune = MODELS[model]
    if prior not in PRIORS:
        raise ConfigurationError(f"prior must be one of {', '.join(PRIORS)}, got {prior!r}")
    if hyperparameters is None and prior != "paper":
        hyperparameters = default_hyperparameters(corpus, psi0=prior == "places")
    estimator = SpCoTransfer(hyperparameters, variant=variant, prune_words=prune, n_iterations=n_iterations,
                             random_state=random_state)
    hyper = estimator.checked_hyperparameters()
    settings = estimator.sampler_settings()
    if variant == "exact" and prune and hyper.word_model != "channels":
        # one word model on the robot's path: the naming rule is chosen for speech without English
        # function words only, never asked for
        raise ConfigurationError(f"a knowledge of model {model} learns its words with the word channels "
                                 f"(word_model 'channels'), not {hyper.word_model!r}: speech without any "
                                 "English function word (Japanese) is learnt with the naming rule by itself")
    # the word channels (docs/model.md, "Words that are not names") for English speech; speech
    # without any English function word (Japanese) is learnt with the naming rule, as a joint fit
    evidence = _channel_evidence(corpus) if uses_word_channels(hyper, settings) else None
    if uses_word_channels(hyper, settings) and evidence is None:
        hyper = replace(hyper, word_model="naming-rule")
    return estimator, hyper, settings, evidence


@dataclass
class _Chain:
    """What :func:`_sample_chain` keeps of a fit's chain: the run (still open: its shards hold the
    homes), the kept sweeps' (log φ^v, log φ^w, log G_0) and word channels in sweep order, and the
    last sweep's word mask, candidate words and word-channel tokens (the switches' expected counts
    averaged over the kept sweeps; ``None`` without channels), and the kept sweeps' names said at
    each concept's places (empty without channels)."""

    run: Any
    samples: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
    channel_samples: list[WordChannels]
    word_mask_last: np.ndarray
    candidate_words: np.ndarray | None
    tokens: np.ndarray | None
    place_names: list[np.ndarray] = field(default_factory=list)


def _sample_chain(engine: Any, source: Any, hyper: TransferHyperparameters, settings: Any,
                  rng: np.random.Generator, evidence: tuple[np.ndarray, np.ndarray] | None, n_iterations: int,
                  keep: set[int], progress: str | None, word_increment: int,
                  vocabulary: Any = None) -> _Chain:
    """Run the sampler ``n_iterations`` sweeps on the homes of ``source`` (in their shards, on
    ``engine``), keeping the shared parameters of the sweeps in ``keep``; ``progress``: a progress
    bar's label, ``None`` for none; ``word_increment``: S^w of the homes' words (the word channels'
    token weight, :func:`spco.model.word_channels.token_weight`); ``vocabulary``: the homes' (the
    names objects stand in for among the names said at the places,
    :func:`spco.model.unheard.stand_in_columns`; ``None``: none)."""
    by_iteration: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    channel_samples: dict[int, WordChannels] = {}
    expected: dict[int, np.ndarray] = {}  # the kept sweeps' expected switch counts (V, 3)
    at_places: dict[int, np.ndarray] = {}  # the kept sweeps' names said at each concept's places (L, V)
    bar = None
    if progress is not None:
        from spco.progress import progress_bar

        bar = progress_bar(total=n_iterations, desc=progress, unit="sweep", leave=False)
    from spco.engines import start_source_run

    if evidence is not None:  # the warm start with the channels' evidence (warm_start="things" or "words")
        settings = warm_start_settings(settings, hyper, evidence, vocabulary, word_increment)
    run = start_source_run(engine, source, hyper, settings, rng)  # the homes stay in the shards
    stand_ins = None
    if evidence is not None:
        initial = WordChannels.initial(
            evidence[0], run.hyper.n_concepts, run.hyper.evidence_weight, evidence[1],
            token_weight(run.hyper.word_counts, word_increment), power=run.hyper.target == "power")
        run.use_word_channels(initial)
        if vocabulary is not None:  # (the prior's name share is the evidence's: λ does not enter it)
            from spco.model.unheard import stand_in_columns

            stand_ins = stand_in_columns(vocabulary, initial.name_prior())

    def after_sweep(iteration: int, _: float) -> None:  # (a restarted engine repeats sweeps)
        if bar is not None:
            bar.update(1)
        if iteration in keep:
            shared = run.shared
            # the power target: φ^v's conditional mean given the sweep's tables (GlobalStep.visual_mean)
            mean_v = getattr(run.global_step, "visual_mean", None)
            log_phi_v = shared.log_phi_v if mean_v is None else mean_v
            by_iteration[iteration] = (log_phi_v.copy(), shared.log_phi_w.copy(), shared.log_g0.copy())
            if shared.channels is not None:
                # ψ's conditional mean given the sweep's place tokens (GlobalStep.place_mean), not its
                # draw: a concept no home holds has no place token, and a draw of Dir(α^p) is then a
                # spike on one word (an average of a few such draws is still spiky)
                mean_p = getattr(run.global_step, "place_mean", None)
                channels = shared.channels.copy()
                if mean_p is not None:
                    channels = replace(channels, log_place=mean_p.copy())
                channel_samples[iteration] = channels
                expected[iteration] = functools.reduce(operator.add, run.call("expected_channel_tokens"))
                at_places[iteration] = functools.reduce(operator.add,
                                                        run.call("concept_place_names", stand_ins))

    run.fit(n_iterations, after_sweep)
    word_mask_last, candidate_words = run.shared.word_mask, run.call("candidate_words")[0]
    # the tokens per word and channel: the switches' expected counts (Rao-Blackwellised: given each
    # kept sweep's concepts and parameters) averaged over the kept sweeps, not the last sweep's draw
    tokens = None
    if run.shared.channels is not None:
        tokens = (np.mean([expected[i] for i in sorted(expected)], axis=0) if expected else
                  functools.reduce(operator.add, run.call("expected_channel_tokens")))
    if bar is not None:
        bar.close()
    return _Chain(run, [by_iteration[i] for i in sorted(by_iteration)],
                  [channel_samples[i] for i in sorted(channel_samples)], word_mask_last, candidate_words,
                  tokens, [at_places[i] for i in sorted(at_places)])


def _view_weight_record(estimate: dict | None) -> dict[str, Any]:
    """The provenance of an estimated view weight (:attr:`spco.model.driver.ShardedRun.view_weight`):
    ``{"view_weight": {"estimated", "views", "view_counts", "grid", "mean_log_loss"}}`` (the
    leave-one-home-out loss per view at each w of the grid), or nothing when w was given."""
    if estimate is None:
        return {}
    return {"view_weight": {**estimate, "mean_log_loss": [round(x, 6) for x in estimate["mean_log_loss"]]}}


def _channel_evidence(corpus: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """The word channels' linguistic evidence (ν, a) of the experienced homes' words
    (:func:`spco.model.name_evidence.channel_evidence`), or ``None`` when no sentence holds an English
    function word (the evidence is English: such speech is learnt with the naming rule). A
    :class:`~spco.model.sources.FolderHomes` or :class:`~spco.model.sources.SyntheticHomes` brings the
    evidence it computed while reading its sentences."""
    if isinstance(corpus, Corpus):
        sentences = [s for t in corpus.training_set() for s in t.sentences]
        if not has_english(corpus.vocabulary, sentences):
            return None
        return channel_evidence(corpus.vocabulary, sentences)
    return getattr(corpus, "channel_evidence", None)


def _averaged_channels(samples: list[WordChannels], perms: list[np.ndarray],
                       tokens: np.ndarray | None, at_places: list[np.ndarray] | None = None
                       ) -> KnowledgeChannels | None:
    """The word channels of the kept sweeps averaged as φ is: ψ relabelled like φ (``perms``), then
    ψ, β and the shares λ averaged as probabilities; the evidence is fixed. Each sample's ψ is the
    sweep's conditional mean E[ψ | place tokens] (:func:`_sample_chain` keeps it), so the average is a
    Rao-Blackwellised estimate of ψ's posterior mean: the prior's mean for a concept with no token.
    ``tokens``: (V, 3) the expected tokens per word and channel (over all homes), averaged over the
    kept sweeps; ``at_places``: each kept sweep's names said at each concept's places (L, V),
    relabelled like φ and averaged. ``None`` without channels."""
    if not samples or tokens is None:
        return None
    n = len(samples)
    log_place = logsumexp(np.stack([c.log_place[p] for c, p in zip(samples, perms, strict=True)]), axis=0)
    log_background = logsumexp(np.stack([c.log_background for c in samples]), axis=0)
    shares = np.exp(np.stack([c.log_shares[1:] for c in samples])).mean(axis=0)
    averaged = replace(samples[-1], log_place=log_place - math.log(n),
                       log_background=log_background - math.log(n),
                       log_shares=np.concatenate([[0.0], np.log(shares / shares.sum())]), fresh=False)
    place_names = (np.mean([a[p] for a, p in zip(at_places, perms, strict=True)], axis=0)
                   if at_places and len(at_places) == n else None)
    return KnowledgeChannels(averaged, np.asarray(tokens, dtype=np.float64), place_names)


def _home_source(estimator: SpCoTransfer, corpus: Any, source: Any) -> tuple[Any, int]:
    """What the shards start from, in the estimator's position units, and its number of samples:
    a source whose homes the shards read themselves, or the corpus's homes prepared here."""
    scale = estimator.position_scale
    if source is not None:
        source = replace(source, position_scale=scale)
        return source, source.n_samples
    data = PreparedData.from_corpus(corpus, scale)
    return PreparedHomes(data, len(corpus.vocabulary)), data.n_samples


def _check_fit_arguments(corpus: Any, model: str, summary_fraction: float, summary_every: int,
                         extractor: Any) -> Any:
    """Refuse what :func:`fit_knowledge` cannot fit; returns the home source the shards read
    themselves (``None`` for a :class:`~spco.data.Corpus`)."""
    if model not in MODELS:
        raise ConfigurationError(f"unknown model {model!r}; choose one of {', '.join(MODELS)}")
    from spco.model.sources import FolderHomes, SyntheticHomes

    source = corpus if isinstance(corpus, FolderHomes | SyntheticHomes) else None
    if not isinstance(corpus, Corpus) and source is None:
        raise ConfigurationError("fit_knowledge() expects a spco.data.Corpus, or a "
                                 "spco.model.sources.FolderHomes or SyntheticHomes")
    if not (0 < summary_fraction <= 1) or summary_every < 1:
        raise ConfigurationError("summary_fraction must be within (0, 1] and summary_every >= 1")
    n_features = corpus.n_features if source is not None else corpus[0].n_features
    if extractor is not None and extractor.n_features != n_features:
        raise ConfigurationError(f"the extractor gives {extractor.n_features} features, the homes' views "
                                 f"have {n_features}")
    if len(corpus.vocabulary) == 0:
        n_homes = source.n_homes if source is not None else len(corpus)
        raise DataFormatError(None, f"no taught sentence in the {n_homes} experienced home(s) "
                              f"({', '.join(list(corpus.names)[:5])}): there are no place names to learn")
    return source


def _aligned_samples(samples: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, np.ndarray, list[np.ndarray]]:
    """The kept sweeps' (log φ^v, log φ^w, log G_0), each relabelled to match the last sweep's
    concepts (labels are stable late in the chain; this checks it): the three stacks, how many
    sweeps needed a relabelling of a used concept, which concepts the last sweep uses, and each
    sweep's permutation."""
    last_v, last_w = np.exp(samples[-1][0]), np.exp(samples[-1][1])
    used = np.exp(samples[-1][2]) > 0.01
    relabelled = 0
    aligned, perms = [], []
    for log_v, log_w, log_g in samples:
        perm = _align_to(last_v, last_w, np.exp(log_v), np.exp(log_w))
        if (perm[used] != np.flatnonzero(used)).any():
            relabelled += 1
        aligned.append((log_v[perm], log_w[perm], log_g[perm]))
        perms.append(perm)
    stacks = [np.stack([a[i] for a in aligned]) for i in range(3)]
    return stacks[0], stacks[1], stacks[2], relabelled, used, perms


def _kept_words(n_words: int, prune: bool, variant: str, word_mask_last: np.ndarray,
                candidate_words: np.ndarray | None, log_phi_w: np.ndarray, log_g0: np.ndarray,
                hyper: Any, settings: Any) -> np.ndarray:
    """The words the knowledge keeps (every word without pruning)."""
    word_mask = np.ones(n_words, dtype=bool)
    if prune and word_mask.size and variant == "exact":
        # the naming rule on the last sweep's regions (:func:`gibbs.naming_verdicts`), the mask the
        # sampler used: it judges a name said in one home on that home, where it is place-bound
        return word_mask_last.copy()
    if prune and word_mask.size:
        score = settings.pruning_score
        word_mask = words_to_keep(np.exp(log_phi_w), np.exp(log_g0), hyper.pruning_threshold(score), score)
        if candidate_words is not None:  # words the sampler found to depend on the place
            word_mask &= candidate_words
        if not word_mask.any():
            word_mask[np.argmax(np.exp(log_phi_w).max(0))] = True
    return word_mask


def _fitted_name_prior(corpus: Any, naming_rule: bool) -> np.ndarray | None:
    """The name prior of the experienced homes' words (:mod:`spco.model.name_evidence`), for the
    naming rule's models; None otherwise."""
    if not naming_rule:
        return None
    if isinstance(corpus, Corpus):
        return name_prior(corpus.vocabulary, [s for t in corpus.training_set() for s in t.sentences])
    return getattr(corpus, "name_prior", None)  # FolderHomes: computed when its sentences were read
