"""Estimators: the transfer model (SpCoTransfer) and the single-home baselines (SpCoA, SpCoA+MI).

In the style of scikit-learn's ``sklearn.mixture``: hyperparameters in the constructor,
``fit(corpus)`` returns the model, learnt state in trailing-underscore attributes, validation at
the boundary, ``random_state`` for reproducibility, and scikit-learn's parameter protocol
(``get_params``, ``set_params``; ``sklearn.base.clone`` and :func:`clone` work without
scikit-learn being a dependency). Positions in and out are in metres.

``random_state``: an int seeds a new Generator; a :class:`numpy.random.Generator` is *copied*
before use, never advanced, so the same Generator gives the same fit every time, as an int does
(draw a seed from it to get a different fit: ``random_state=int(gen.integers(2**63))``).

Poses: observations are given as ``(x, y, sin θ, cos θ)`` rows (the model's 4-D region space);
:meth:`~SpatialConceptModel.predict_positions` returns a
:class:`~spco.model.position_prediction.PositionPrediction` whose ``samples`` are ``(x, y, θ)`` (θ in
radians, for a robot's goal) and whose ``poses`` are the same draws as ``(x, y, sin θ, cos θ)``, the input
convention, ready for :meth:`~SpatialConceptModel.predict_names`.

The parameters used for prediction (``parameters_``) are a posterior summary, the average over
thinned sweeps of the last quarter of the chain (:mod:`spco.model.posterior`), not the last draw.

Example
-------
>>> from spco.data.synthetic import generate_homes            # doctest: +SKIP
>>> corpus = generate_homes(5, seed=0, new_homes=1)           # doctest: +SKIP
>>> model = SpCoTransfer(n_iterations=50, random_state=0).fit(corpus)   # doctest: +SKIP
>>> model.predict_names(corpus[-1].name, *corpus[-1].test_observations())  # doctest: +SKIP
"""

from __future__ import annotations

import copy
import functools
import inspect
import operator
import time
from dataclasses import replace
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.environment import Corpus
from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.model import gibbs
from spco.model.answer_settings import LEARN
from spco.model.archive import write_npz_atomic
from spco.model.cut_start import check_cut_start
from spco.model.hyperparameters import SpCoAHyperparameters, TransferHyperparameters
from spco.model.name_evidence import channel_evidence, has_english, name_prior
from spco.model.parameters import ConceptParameters
from spco.model.posterior import (
    ParameterAverage,
    masked_rows,
    thinned_sweeps,
    untaught_concepts_name_nothing,
)
from spco.model.seeds import as_generator
from spco.model.word_channels import (
    WordChannels,
    channel_parameters,
    token_weight,
    uses_word_channels,
    warm_start_settings,
)
from spco.timestamps import utc_now


def clone(estimator: SpatialConceptModel) -> SpatialConceptModel:
    """A new unfitted estimator with the same parameters (``sklearn.base.clone`` without
    scikit-learn): ``type(estimator)(**estimator.get_params())``; hyperparameters are immutable
    and shared, a Generator ``random_state`` is copied."""
    params = estimator.get_params()
    if isinstance(params.get("random_state"), np.random.Generator):
        params["random_state"] = copy.deepcopy(params["random_state"])
    return type(estimator)(**params)


class SpatialConceptModel:
    """Common machinery of the spatial-concept models; use :class:`SpCoTransfer` or :class:`SpCoA`.

    Parameters
    ----------
    hyperparameters:
        A :class:`TransferHyperparameters` (defaults: the paper's values).
    variant:
        ``"exact"`` (the model's conditionals) or ``"reference"`` (the authors' code); see
        :mod:`spco.model.gibbs`.
    prune_words:
        Mutual-information word pruning after every sweep (the "+MI" models). A heuristic outside
        the model: with it the chain has no stated stationary distribution and ``log_joint_``
        jumps when the mask changes (see :func:`spco.model.gibbs.prune`); without it the exact
        sampler is an MCMC for the model's posterior.
    n_iterations:
        Gibbs sweeps (200 in the paper).
    random_state:
        Seed or Generator; the same seed gives the same result. A Generator is copied, not
        advanced (the same Generator gives the same result too).
    progress:
        Show a progress bar (stderr).
    record_log_joint:
        Record log p(data, C, R | parameters) after every sweep in ``log_joint_`` (see
        :func:`spco.model.gibbs.log_joint`).
    """

    _sampler = "exact"

    def __init__(self, hyperparameters: TransferHyperparameters | None = None, *, variant: str = "exact",
                 prune_words: bool = False, n_iterations: int = 200,
                 random_state: int | np.random.Generator | None = None, progress: bool = False,
                 record_log_joint: bool = True) -> None:
        self.hyperparameters = hyperparameters
        self.variant = variant
        self.prune_words = prune_words
        self.n_iterations = n_iterations
        self.random_state = random_state
        self.progress = progress
        self.record_log_joint = record_log_joint

    # ------------------------------------------------------------------ scikit-learn protocol
    @classmethod
    def _get_param_names(cls) -> list[str]:
        """The constructor's parameter names (scikit-learn's convention)."""
        signature = inspect.signature(cls.__init__)
        return sorted(p.name for p in signature.parameters.values()
                      if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD))

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """The constructor parameters as a dict (``deep`` is accepted for scikit-learn; the
        hyperparameters are one immutable value, not a nested estimator)."""
        return {name: getattr(self, name) for name in self._get_param_names()}

    def set_params(self, **params: Any) -> SpatialConceptModel:
        """Set constructor parameters (scikit-learn's convention); returns ``self``. An unknown
        name raises :class:`~spco.errors.ConfigurationError`. Values are checked at ``fit``."""
        valid = self._get_param_names()
        for name, value in params.items():
            if name not in valid:
                raise ConfigurationError(f"invalid parameter {name!r} for {type(self).__name__}; "
                                         f"valid: {', '.join(valid)}")
            setattr(self, name, value)
        return self

    def __repr__(self) -> str:
        changed = []
        defaults = inspect.signature(type(self).__init__).parameters
        for name, value in self.get_params().items():
            default = defaults[name].default
            if default is inspect.Parameter.empty or (value is not default and value != default):
                changed.append(f"{name}={value!r}")
        return f"{type(self).__name__}({', '.join(changed)})"

    # ------------------------------------------------------------------ configuration
    def _default_hyperparameters(self) -> TransferHyperparameters:
        return TransferHyperparameters()

    def sampler_settings(self) -> gibbs.SamplerSettings:
        """The sampler's settings for this estimator's ``variant`` and ``prune_words`` (raises
        :class:`~spco.errors.ConfigurationError` for an unknown variant)."""
        if self.variant not in ("exact", "reference"):
            raise ConfigurationError(f"variant must be 'exact' or 'reference', got {self.variant!r}")
        hyper = self.hyperparameters if self.hyperparameters is not None else self._default_hyperparameters()
        return gibbs.SamplerSettings.create(self.variant, bool(self.prune_words),
                                            view_counts=getattr(hyper, "view_counts", None),
                                            block_moves=getattr(hyper, "block_moves", "off") == "all",
                                            power=getattr(hyper, "target", "cut") == "power",
                                            phi_moves=getattr(hyper, "block_moves", "off") == "phi")

    def checked_hyperparameters(self) -> TransferHyperparameters:
        """The hyperparameters this estimator fits with (the paper's when none were given), checked
        with ``n_iterations``; raises :class:`~spco.errors.ConfigurationError` if they are not valid."""
        hyper = self.hyperparameters if self.hyperparameters is not None else self._default_hyperparameters()
        if not isinstance(hyper, TransferHyperparameters):
            raise ConfigurationError("hyperparameters must be a TransferHyperparameters instance")
        if not isinstance(self.n_iterations, int | np.integer) or self.n_iterations < 1:
            raise ConfigurationError(f"n_iterations must be an integer >= 1, got {self.n_iterations!r}")
        check_cut_start(hyper, thinned_sweeps(int(self.n_iterations)))  # (every kept sweep a power sweep)
        return hyper

    # ------------------------------------------------------------------ data
    @property
    def position_scale(self) -> float:
        """Metres to the sampler's position units: centimetres (:data:`~spco.model.gibbs.CM_PER_M`)
        for the ``reference`` variant, as the authors' code has them; metres otherwise."""
        return gibbs.CM_PER_M if self.variant == "reference" else 1.0

    # ------------------------------------------------------------------ fitting
    def fit(self, corpus: Corpus, engine=None) -> SpatialConceptModel:
        """Learn from every home of ``corpus`` (their training samples) and return ``self``.

        ``engine`` runs the homes' shards: ``None`` or ``"local"`` in this process, one shard
        (:class:`~spco.model.driver.LocalEngine`); or an engine object such as
        ``spco.engines.make_engine("ray")`` or ``RayEngine(shards=4, address="auto")``.

        Sets ``parameters_`` (:class:`ConceptParameters`, metres: the average over the thinned
        sweeps of :func:`~spco.model.posterior.thinned_sweeps`, see :mod:`spco.model.posterior`),
        ``vocabulary_``,
        ``home_names_``, ``concepts_`` and ``regions_`` (per home, for its training samples),
        ``log_joint_`` (per sweep), ``n_iter_`` and ``fit_seconds_``.
        """
        hyper = self.checked_hyperparameters()
        if getattr(hyper, "typical", None) == LEARN:
            raise ConfigurationError("typical='learn': ρ is learnt from the experienced homes when a "
                                     "knowledge is fitted (spco fit, fit_knowledge); a joint fit takes a "
                                     "number within (0, 1] (spco.knowledge.fit.learnt_typicality of a "
                                     "knowledge)")
        settings = self.sampler_settings()
        rng = as_generator(self.random_state)
        data = gibbs.PreparedData.from_corpus(corpus, self.position_scale)
        start = time.perf_counter()
        average = _SweepAverage(int(self.n_iterations), data)
        bar = self._progress_bar(settings)
        from spco.model.driver import start_run

        evidence, settings = self._channel_evidence(corpus, data, hyper, settings)
        run = start_run(engine, data, len(corpus.vocabulary), hyper, settings, rng)
        hyper, settings = run.hyper, run.settings  # with the view weight estimated from the homes
        hyper = self._start_word_channels(run, corpus, data, hyper, settings, evidence)

        def after_sweep(iteration: int, previous: float) -> None:
            average.after_sweep(run, iteration)
            if bar is not None:
                bar.update(1)
                bar.set_postfix(log_joint=f"{previous:.4g}", refresh=False)

        # each sweep reports the log joint of the state it started from: the previous sweep's
        log_joints = run.fit(int(self.n_iterations), after_sweep)
        # (a cut start: the power target's, from its first sweep on; the word model as chosen above)
        hyper, settings = replace(run.hyper, word_model=hyper.word_model), run.settings
        trace = list(log_joints[1:]) if self.record_log_joint else []
        # the final state joined, then the workers (their states, data views and caches) dropped
        # before the state's log joint and its place in the average allocate: a lower peak
        state = run.state()
        run.close()
        if bar is not None:
            bar.close()
        if self.record_log_joint:
            trace.append(gibbs.log_joint(data, state, hyper, settings))
            data.__dict__.pop("visual_by_dimension", None)  # (a cache the last log joint built: not kept)
        average.add_final(state)
        self.fit_seconds_ = time.perf_counter() - start
        self.hyperparameters_, self.settings_, self.view_weight_ = hyper, settings, run.view_weight
        self.vocabulary_: Vocabulary = corpus.vocabulary
        self.word_increment_ = corpus.word_increment
        self.home_names_ = corpus.names
        self.state_ = state
        self.data_ = data
        self.log_joint_ = np.asarray(trace, dtype=float)
        self.n_iter_ = int(self.n_iterations)
        averaged_parameters = average.result(state)
        self.parameters_ = self._fitted_parameters(averaged_parameters, corpus, data, state, hyper, settings,
                                                   None if evidence is None else evidence[0])
        self.word_channels_ = state.channels
        #: (V, 3) each word's expected tokens as name, place and background word over the fit's homes,
        #: averaged over the averaged sweeps (``None`` without the word channels): which words are names
        self.channel_tokens_ = average.expected_tokens()
        if state.channels is not None:
            self.parameters_ = replace(self.parameters_,  # ψ: its mean, not the draw
                                       **channel_parameters(state.channels, average.place_mean))
        splits = np.split(np.arange(data.n_samples), data.offsets[1:-1])
        self.concepts_ = [state.concepts[s].copy() for s in splits]
        self.regions_ = [state.regions[s].copy() for s in splits]
        self.training_ids_ = [t.ids for t in corpus.training_set()]
        return self

    def _progress_bar(self, settings: gibbs.SamplerSettings):
        """The fit's progress bar (``None`` without ``progress``)."""
        if not self.progress:
            return None
        from spco.progress import progress_bar

        return progress_bar(total=int(self.n_iterations), desc=f"{type(self).__name__} ({settings.variant})",
                            unit="sweep", leave=False)

    @staticmethod
    def _channel_evidence(corpus: Corpus, data: gibbs.PreparedData, hyper: TransferHyperparameters,
                          settings: gibbs.SamplerSettings
                          ) -> tuple[tuple[np.ndarray, np.ndarray] | None, gibbs.SamplerSettings]:
        """The channels' name evidence (ν, a) of the corpus's words (:func:`channel_evidence`) when the
        fit learns its words with the word channels (``None`` when it does not — no channels or no words
        — or its speech has no English function word: learnt with the naming rule), and ``settings``
        for its warm start (:func:`~spco.model.word_channels.warm_start_settings`: as they are with
        ``warm_start="names"``)."""
        if not (uses_word_channels(hyper, settings) and bool(data.words.nnz)):
            return None, settings
        sentences = [s for t in corpus.training_set() for s in t.sentences]
        if not has_english(corpus.vocabulary, sentences):
            return None, settings
        evidence = channel_evidence(corpus.vocabulary, sentences)
        start = warm_start_settings(settings, hyper, evidence, corpus.vocabulary, corpus.word_increment)
        return evidence, start

    @staticmethod
    def _start_word_channels(run, corpus: Corpus, data: gibbs.PreparedData, hyper: TransferHyperparameters,
                             settings: gibbs.SamplerSettings,
                             evidence: tuple[np.ndarray, np.ndarray] | None) -> TransferHyperparameters:
        """Give ``run`` the word channels (:mod:`spco.model.word_channels`) when the model uses them,
        from the channels' ``evidence`` (:meth:`_channel_evidence`); returns the hyperparameters the
        fit used (``word_model`` "naming-rule" for speech without any English function word)."""
        if not (uses_word_channels(hyper, settings) and bool(data.words.nnz)):
            return hyper
        if evidence is None:
            # the channels' prior is English evidence; speech with no English function word at all
            # (Japanese) is learnt with the naming rule, which measures where words are said
            return replace(hyper, word_model="naming-rule")
        nu, content = evidence
        run.use_word_channels(WordChannels.initial(nu, hyper.n_concepts, hyper.evidence_weight,
                                                   content, token_weight(hyper.word_counts,
                                                                         corpus.word_increment),
                                                   power=hyper.target == "power"))
        return run.hyper  # (δ^w and α^w estimated as the channels start: word_prior)

    @staticmethod
    def _fitted_parameters(params: ConceptParameters, corpus: Corpus, data: gibbs.PreparedData,
                           state: gibbs.GibbsState, hyper: TransferHyperparameters,
                           settings: gibbs.SamplerSettings,
                           evidence: np.ndarray | None = None) -> ConceptParameters:
        """The averaged parameters as the exact model exports them: concepts no taught sample was
        ever assigned to name nothing, and (with the naming rule or the word channels) each word's
        name prior (``evidence``: the channels' evidence, computed before the chain)."""
        if settings.variant == "exact":  # (the authors' sampler and SpCoA export as published)
            taught = np.zeros(hyper.n_concepts, dtype=bool)  # concepts holding a taught sample somewhere
            taught[np.unique(state.concepts[np.diff(data.words.indptr) > 0])] = True
            params = untaught_concepts_name_nothing(params, taught)
        if settings.prune and settings.variant == "exact":
            # the naming rule's linguistic evidence, how name-like each word is: candidates for names
            # never heard (spco.model.unheard), and the order of each concept's words with the
            # opt-in hyperparameters.name_prior = "wordnet"
            if evidence is None:
                sentences = [s for t in corpus.training_set() for s in t.sentences]
                evidence = name_prior(corpus.vocabulary, sentences)
            params = replace(params, name_prior=evidence)
        return params

    # ------------------------------------------------------------------ use
    def _check_fitted(self) -> None:
        if not hasattr(self, "parameters_"):
            raise ConfigurationError(f"this {type(self).__name__} is not fitted yet: call fit(corpus) first")

    def home_index(self, home: str | int) -> int:
        """Index of a home by name (or pass an index through)."""
        self._check_fitted()
        if isinstance(home, int | np.integer):
            if not 0 <= home < len(self.home_names_):
                raise ConfigurationError(f"home index {home} out of range (0..{len(self.home_names_) - 1})")
            return int(home)
        if home not in self.home_names_:
            raise ConfigurationError(
                f"the model knows no home {home!r}; it learnt {', '.join(self.home_names_)}")
        return self.home_names_.index(home)

    def answer_inputs(self, home: str | int) -> tuple[ConceptParameters, Any, str]:
        """What the robot answers ``home``'s questions with: ``(params, rooms, weighting)``, the answer's
        parameters (:func:`spco.model.confidence.model_answer_parameters`), the home's rooms
        (:func:`spco.model.rooms.model_rooms`, the room account) and the name weighting
        (:func:`spco.model.confidence.answer_weighting`), as a home adapted from a knowledge answers.
        :meth:`predict_names`, :meth:`predict_positions` and the experiments
        (:func:`spco.evaluation.runs.execute_run`) read them. Worked out once per fit.

        Raises :class:`~spco.errors.ConfigurationError` for a model loaded from a file: it keeps no
        training samples, and the rooms are the home's samples' regions, views and names."""
        from spco.model.confidence import model_answer_parameters
        from spco.model.rooms import model_rooms

        e = self.home_index(home)
        if not (hasattr(self, "state_") and hasattr(self, "data_")):
            raise ConfigurationError(
                "this model was loaded from a file, which keeps no training samples: the robot's answers "
                "read the home's rooms (its samples' regions, views and names); predict with the fitted "
                "model, or adapt a knowledge to the home (spco.knowledge.adapt) and ask the home")
        known = self.__dict__.setdefault("_answers", {})
        if known.get("parameters") is not self.parameters_:  # a new fit: forget the old answers
            known.clear()
            known["parameters"] = self.parameters_
        if e not in known:
            known[e] = (model_answer_parameters(self, e), model_rooms(self, e), self.name_weighting())
        return known[e]

    def name_weighting(self) -> str:
        """The name weighting of this model's answers (:func:`spco.model.confidence.answer_weighting`
        of its ``variant`` and ``prune_words``: as a home adapted from such a knowledge answers)."""
        from spco.model.confidence import answer_weighting

        hyper = getattr(self, "hyperparameters_", None) or self.hyperparameters
        return answer_weighting(self.variant, bool(self.prune_words), getattr(hyper, "name_answer", "said"))

    def predict_names(self, home: str | int, positions: np.ndarray, visual: Any, top_k: int = 3):
        """Top-``top_k`` place names for observations of ``home``: the names the robot answers there
        (:func:`spco.model.confidence.answer_names` with :meth:`answer_inputs`, a view worth the
        model's view weight w, answers below :data:`~spco.model.confidence.UNSURE_BELOW` flagged
        ``unsure``), what the experiments score (the hyperparameters' ``name_prior`` setting applies)."""
        from spco.model.confidence import answer_names

        e = self.home_index(home)
        params, rooms, weighting = self.answer_inputs(e)
        return answer_names(params, e, self.vocabulary_, np.asarray(positions), visual, top_k=top_k,
                            weighting=weighting, view_counts=self.settings_.view_counts,  # type: ignore[arg-type]
                            name_prior=self.hyperparameters_.name_prior, rooms=rooms,
                            settings=self.hyperparameters_.answer_settings())

    def predict_positions(self, home: str | int, name: str, n: int = 10,
                          random_state: int | np.random.Generator | None = None, mode: str = "answer"):
        """Positions to go to for place ``name`` in ``home``: the robot's ``where``
        (:func:`spco.model.position_prediction.predict_positions` with :meth:`answer_inputs`, the
        model's view weight and its word mask as the words looked up), what the experiments' A_p
        scores. ``mode``: ``"answer"`` (the robot's: the regions at least half as probable as the
        best), ``"argmax"`` (the paper's A_p) or ``"mixture"``. The result's ``samples`` are (x, y, θ),
        its ``poses`` (x, y, sin θ, cos θ); ``learnt`` is False when the name's probability in this
        home comes from concepts that hold none of its samples."""
        from spco.model import position_prediction

        e = self.home_index(home)
        params, rooms, _ = self.answer_inputs(e)
        return position_prediction.predict_positions(params, e, self.vocabulary_, name, n=n,
                                                     rng=as_generator(random_state), mode=mode,  # type: ignore[arg-type]
                                                     rooms=rooms, view_counts=self.settings_.view_counts,
                                                     lookup=self.parameters_.word_mask)

    def save(self, path, overwrite: bool = False) -> None:
        """Write the fitted model to ``path`` atomically (:func:`save_model`); an existing
        file is replaced only with ``overwrite=True``."""
        self._check_fitted()
        save_model(self, path, overwrite=overwrite)


def export_parameters(state: gibbs.GibbsState, data: gibbs.PreparedData) -> ConceptParameters:
    """One state's parameters (a single draw) as probabilities, positions converted back to metres."""
    s = data.position_scale
    scale = np.array([s, s, 1.0, 1.0])
    means = state.means / scale
    covariances = state.covariances / np.outer(scale, scale)
    mask = state.word_mask
    return ConceptParameters(
        concept_weights=np.exp(state.log_g), region_weights=np.exp(state.log_pi),
        region_means=means, region_covariances=covariances,
        word_probabilities=masked_rows(state.log_theta_w, mask),
        visual_probabilities=np.exp(state.log_theta_v),
        shared_word_probabilities=masked_rows(state.log_phi_w, mask),
        shared_visual_probabilities=np.exp(state.log_phi_v),
        global_concept_weights=np.exp(state.log_g0), word_mask=state.word_mask.copy(),
        region_counts=state.region_counts.copy(),
        concept_counts=np.stack([np.bincount(state.concepts[data.homes == e], minlength=state.log_g.shape[1])
                                 for e in range(data.n_homes)]).astype(np.float64),
    )


class SpCoTransfer(SpatialConceptModel):
    """The hierarchical transfer model of Hagiwara et al. (2021), learnt from several homes at once.

    Homes that were fully taught, partly taught and not taught at all (the new home) are learnt
    jointly; the shared φ^v, φ^w and G_0 carry knowledge from experienced homes to the new one.
    ``prune_words=True`` gives the "+MI" model. See :class:`SpatialConceptModel` for parameters.
    """


class SpCoA(SpatialConceptModel):
    """The SpCoA baseline: one home, no environment plate, no transfer.

    Fits only the home given to :meth:`fit` (a corpus of exactly one home, or ``home=`` to pick one).
    ``prune_words=True`` gives SpCoA+MI. Default hyperparameters: :class:`SpCoAHyperparameters`.
    """

    def __init__(self, hyperparameters: TransferHyperparameters | None = None, *, prune_words: bool = False,
                 n_iterations: int = 200, random_state: int | np.random.Generator | None = None,
                 progress: bool = False, record_log_joint: bool = True) -> None:
        super().__init__(hyperparameters, variant="exact", prune_words=prune_words,
                         n_iterations=n_iterations, random_state=random_state, progress=progress,
                         record_log_joint=record_log_joint)

    def _default_hyperparameters(self) -> TransferHyperparameters:
        return SpCoAHyperparameters()

    def answer_inputs(self, home: str | int) -> tuple[ConceptParameters, Any, str]:
        """SpCoA's answers (one home, no knowledge, no room account): its parameters, no rooms, the
        MI weighting — what the experiments score for SpCoA (a model loaded from a file answers too)."""
        self.home_index(home)
        return self.parameters_, None, self.name_weighting()

    def name_weighting(self) -> str:
        """SpCoA's name weighting: the mutual information, with or without pruning (the baseline as
        the experiments have always scored it)."""
        return "mi"

    def sampler_settings(self) -> gibbs.SamplerSettings:
        """The SpCoA sampler's settings (``prune_words`` as set)."""
        return gibbs.SamplerSettings.create("spcoa", bool(self.prune_words))

    def fit(self, corpus: Corpus, home: str | None = None) -> SpCoA:  # type: ignore[override]
        """Learn the single home ``home`` of ``corpus`` (or its only home) and return ``self``."""
        if not isinstance(corpus, Corpus):
            raise ConfigurationError("fit() expects a spco.data.Corpus")
        if home is None:
            if len(corpus) != 1:
                raise ConfigurationError(
                    f"SpCoA learns one home; the corpus holds {len(corpus)} — pass home=NAME")
            home = corpus.names[0]
        if home not in corpus.names:
            raise ConfigurationError(f"no home named {home!r} in the corpus")
        single = Corpus([corpus[home]], vocabulary=corpus.vocabulary, word_increment=corpus.word_increment)
        super().fit(single)
        return self


def with_hyperparameters(model: SpatialConceptModel, **changes: Any) -> SpatialConceptModel:
    """A copy of an unfitted model with some hyperparameters changed."""
    hyper = model.hyperparameters or model._default_hyperparameters()
    clone = type(model).__new__(type(model))
    clone.__dict__.update({k: v for k, v in model.__dict__.items() if not k.endswith("_")})
    clone.hyperparameters = replace(hyper, **changes)
    return clone


class _SweepAverage:
    """The thinned sweeps of a fit averaged (:class:`~spco.model.posterior.ParameterAverage`,
    :func:`~spco.model.posterior.thinned_sweeps`) as the sweeps run, without a joined copy of
    every home's θ^v; the last sweep's state, which the fit joins and keeps, is added after the
    sweeps (:meth:`add_final`), once the workers are dropped."""

    def __init__(self, n_iterations: int, data: gibbs.PreparedData) -> None:
        self.n_iterations = n_iterations
        self.averaged = set(thinned_sweeps(n_iterations))
        self.average = ParameterAverage(data.homes, data.position_scale)
        self.added: set[int] = set()
        #: the averaged sweeps' expected switch counts per word and channel (V, 3), with the word channels
        self.channel_tokens: list[np.ndarray] = []
        #: log E[φ^v | the last sweep's tables] under the power target (``GlobalStep.visual_mean``),
        #: exported instead of the last sweep's draw of φ^v (a Dirichlet with parameters far below one
        #: draws most coordinates near e^(−1/a): no estimate of its mean); ``None`` otherwise
        self.visual_mean: np.ndarray | None = None
        #: each home's log θ^v conditional mean at the last sweep under the power target (else ``None``)
        self.final_visual: list[np.ndarray] | None = None
        #: log E[ψ | the last sweep's place tokens] with the word channels (``GlobalStep.place_mean``),
        #: exported instead of the last sweep's draw of ψ; ``None`` otherwise
        self.place_mean: np.ndarray | None = None

    def after_sweep(self, run, iteration: int) -> None:
        """Add sweep ``iteration``'s state if it is averaged (not the last sweep's: see
        :meth:`add_final`). A restarted engine repeats the sweeps since its checkpoint (the same
        chain): each averaged sweep is added once."""
        power = run.hyper.target == "power"  # θ^v's and φ^v's conditional means, not their draws
        if iteration == self.n_iterations - 1:  # the power target: φ^v's mean given the last tables
            self.visual_mean = getattr(run.global_step, "visual_mean", None)
            self.place_mean = getattr(run.global_step, "place_mean", None)
            self.final_visual = [m for part in run.call("visual_means") for m in part] if power else None
        if iteration not in self.averaged or iteration in self.added:
            return
        if iteration != self.n_iterations - 1:  # (the last sweep's state: add_final, without the workers)
            visual = (m for part in run.call("visual_means") for m in part) if power else run.home_visual()
            self.average.add(run.state(visual=False), visual=visual)
        if run.shared.channels is not None:
            self.channel_tokens.append(functools.reduce(operator.add, run.call("expected_channel_tokens")))
        self.added.add(iteration)

    def add_final(self, state: gibbs.GibbsState) -> None:
        """Add the last sweep's state (joined: ``run.state()`` after the sweeps, the workers dropped);
        it is always averaged (its switch counts were taken by :meth:`after_sweep`)."""
        self.average.add(state, visual=self.final_visual)

    def result(self, state: gibbs.GibbsState):
        """The averaged parameters (:meth:`ParameterAverage.result`, releasing the sums), with φ^v
        the last sweep's conditional mean under the power target (:attr:`visual_mean`)."""
        params = self.average.result(state, release=True)
        if self.visual_mean is None:
            return params
        return replace(params, shared_visual_probabilities=np.exp(self.visual_mean))

    def expected_tokens(self) -> np.ndarray | None:
        """(V, 3) the switches' expected counts per word and channel averaged over the averaged
        sweeps (Rao-Blackwellised), ``None`` without the word channels."""
        return np.mean(self.channel_tokens, axis=0) if self.channel_tokens else None


# ----------------------------------------------------------------------------- the model file
# (its format: :mod:`spco.model.io`, which reads it)

#: Value of the model file header's ``"format"`` field.
FORMAT_NAME = "spco-model"
#: The model file's arrays of the :class:`ConceptParameters` are named ``param.<name>``.
PARAM_PREFIX = "param."


def _model_class_name(model: SpatialConceptModel) -> str:
    if isinstance(model, SpCoA):
        return "SpCoA"
    if isinstance(model, SpatialConceptModel):
        return "SpCoTransfer"
    raise ConfigurationError(f"save_model() expects a fitted SpCoTransfer or SpCoA, "
                             f"got {type(model).__name__}")


def _concatenate(per_home: list[np.ndarray], dtype: type) -> np.ndarray:
    if not per_home:
        return np.zeros(0, dtype=dtype)
    return np.concatenate([np.asarray(a, dtype=dtype).ravel() for a in per_home])


def _arrays_and_header(model: SpatialConceptModel) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays to store and the header (without its checksums)."""
    if not hasattr(model, "parameters_"):
        raise ConfigurationError(f"this {type(model).__name__} is not fitted yet: "
                                 "call fit(corpus) before saving")
    arrays: dict[str, np.ndarray] = {}
    for name, value in model.parameters_.arrays().items():
        arrays[PARAM_PREFIX + name] = np.asarray(value)
    arrays["log_joint"] = np.asarray(model.log_joint_, dtype=np.float64)
    concepts = list(model.concepts_)
    sizes = [np.asarray(c).size for c in concepts]
    for name, values in (("regions", model.regions_), ("training_ids", model.training_ids_)):
        if [np.asarray(v).size for v in values] != sizes:
            raise ConfigurationError(f"the model's {name}_ do not match its concepts_ (one entry per "
                                     "training sample of each home)")
    arrays["home_offsets"] = np.concatenate([[0], np.cumsum(sizes, dtype=np.int64)]).astype(np.int64)
    arrays["concepts"] = _concatenate(concepts, np.int64)
    arrays["regions"] = _concatenate(list(model.regions_), np.int64)
    arrays["training_ids"] = _concatenate(list(model.training_ids_), np.int64)

    from spco import __version__

    random_state = model.random_state
    if isinstance(random_state, bool) or not isinstance(random_state, int | np.integer):
        random_state = None  # a Generator (or None) cannot be written down
    hyper: TransferHyperparameters = model.hyperparameters_
    segmentation = model.vocabulary_.segmentation
    header: dict[str, Any] = {
        "format": FORMAT_NAME,
        # version 2 only for a vocabulary that segments text written without spaces (``segmentation``)
        "format_version": 2 if segmentation is not None and segmentation.segments else 1,
        "spco_version": __version__,
        "model_class": _model_class_name(model),
        "hyperparameters_class": type(hyper).__name__,
        "variant": model.variant,
        "prune_words": bool(model.prune_words),
        "n_iterations": int(model.n_iterations),
        "n_iter": int(getattr(model, "n_iter_", model.n_iterations)),
        "random_state": None if random_state is None else int(random_state),
        "hyperparameters": hyper.to_dict(),
        "vocabulary": list(model.vocabulary_.words),
        "segmentation": None if segmentation is None else segmentation.to_dict(),
        "word_increment": int(model.word_increment_),
        "home_names": list(model.home_names_),
        "fit_seconds": float(getattr(model, "fit_seconds_", float("nan"))),
        "created": utc_now(),
    }
    return arrays, header


def save_model(model: SpatialConceptModel, path: str | PathLike[str], overwrite: bool = False) -> Path:
    """Write a fitted model to ``path`` (a ``.npz`` file), atomically.

    Parameters
    ----------
    model: a fitted :class:`~spco.model.transfer.SpCoTransfer` or :class:`~spco.model.transfer.SpCoA`.
    path: the file to write (used as given: no suffix is added).
    overwrite: replace an existing file; without it an existing ``path`` raises
        :class:`~spco.errors.ModelFileError`.

    Returns
    -------
    The path written.

    The file is first written to a temporary file in the same folder, flushed to disk, then renamed
    over ``path``; on any error the temporary file is removed and ``path`` is left as it was.
    """
    arrays, header = _arrays_and_header(model)
    return write_npz_atomic(path, header, arrays, overwrite, "model file")
