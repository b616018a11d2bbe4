"""Honest confidence for place names: what ``what`` answers, and how sure it may be.

The model's name posterior ``p(w | x, v) = Σ_l θ^w_{e,l,w} P(l | x, v)`` (:mod:`spco.model.prediction`)
counts two kinds of evidence that are not independent as if they were; this module corrects both
(``docs/model.md``, "Confidence"):

1. **A view is not thousands of independent draws.** The visual likelihood is a multinomial over
   the view's counts (~1,950 per colour-hog image, ~7,300 per fc7 vector), and counts of one image
   are not independent draws from the concept's θ^v. A view is scored as the model's view weight
   w draws of its proportions (``min(1, w / Σ_d v_d)`` times its log-likelihood): the same w the
   sampler learnt with (16 by default, or estimated from the experienced homes;
   :attr:`spco.model.hyperparameters.TransferHyperparameters.view_counts`,
   :meth:`~spco.model.hyperparameters.TransferHyperparameters.view_weight`; docs/model.md, "A view's
   evidence"). There is no separate constant for prediction.
2. **A concept nobody named has no name.** A concept the knowledge does not use (G_0 below
   ``free_weight``, e.g. a third bedroom unlike the experienced ones) gets its φ^w redrawn from the
   sparse prior Dir(α^w) at each sweep of ``adapt`` — nearly one-hot on a random word — and the few
   averaged draws would give it a name at p ≈ 1. Its word distribution is
   replaced by its posterior mean given the home's own taught words (Rao-Blackwellised:
   ``(α^w + N_{l,w}) / (V α^w + N_l)``, N the home's word counts in the concept), which is the
   prior mean — uniform over the names — when nothing was taught there.
3. **A concept named with a word the home does not answer has no answerable name.** With the word
   channels a home answers only the words enough of whose uses are names
   (:attr:`spco.knowledge.home.HomeModel.name_mask`); a concept whose names channel holds another
   word ("dining", its uses nearly all drawn as a place word) would, once that word is masked, answer
   whatever name its θ^w holds at 10^-6 with p ≈ 1 after the answer's normalisation. The mass θ^w
   puts on words the home does not answer is spread evenly over the names it does
   (:func:`answerable_names`): such a concept answers at p ≈ 1 / (number of names), i.e. unsure.
4. **A room's views are one piece of evidence.** Given the home's rooms (:func:`answer_names`'s
   ``rooms``: the robot's answers, ``what``, ``ask`` and the experiments, always pass them), the
   concept at a pose is judged from the rooms the pose may be in — each room's training views pooled,
   worth w draws — and the observation's view, worth w, against φ^v (the view weighs in on which room
   as well as on its concept), not from the home's π and θ^v, which hold each of the room's views as
   independent evidence (:func:`answer_concepts`, :mod:`spco.model.rooms`; docs/model.md, "A room's
   evidence"). Without rooms (a bare :class:`ConceptParameters`, SpCoA's single-home fit, the
   authors' reference weighting) the view-by-view posterior of :mod:`spco.model.prediction` answers.

An answer whose probability is below :data:`UNSURE_BELOW` is flagged *unsure*
(:attr:`spco.model.prediction.NamePrediction.unsure`; ``spco what`` says so, ``--json`` has
``"unsure": true``); ``ask`` uses the same threshold for a question worth asking, and scores views
with the same view weight.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.model.answer_settings import AnswerSettings
from spco.model.parameters import ConceptParameters
from spco.model.prediction import NamePrediction, Weighting, concept_posterior, predict_names
from spco.model.rooms import HomeRooms, concepts_by_room

__all__ = [
    "UNSURE_BELOW",
    "answer_concepts",
    "answer_names",
    "answer_parameters",
    "answer_weighting",
    "answerable_names",
    "concept_word_counts",
    "model_answer_parameters",
    "named_parameters",
    "place_named_parameters",
]

#: The one "unsure" threshold: an answer whose probability p(name | pose, view) is below this is
#: *unsure* (``what``, the service, the ROS node), and a place where the answer the robot expects is
#: below it is worth asking about (``ask``, ``Question.worth_asking``). Set on the development home
#: 3LDK_9 (``spco experiment active``: 0.6–0.8 ask the same 3.1 questions on average and reach the
#: accuracy of 15; 0.5 stops before the bedrooms, whose own-name probability is 0.5).
UNSURE_BELOW = 0.7


def concept_word_counts(words: sp.csr_array | np.ndarray, concepts: np.ndarray, n_concepts: int
                        ) -> np.ndarray:
    """N (L, V): a home's word counts summed by concept.

    Parameters
    ----------
    words: (n, V) word counts of the home's samples (rows of untaught samples empty).
    concepts: (n,) the concept of each sample.
    n_concepts: L.

    Returns
    -------
    (L, V) float64.
    """
    concepts = np.asarray(concepts, dtype=np.int64)
    indicator = sp.csr_array((np.ones(concepts.size), (concepts, np.arange(concepts.size))),
                             shape=(n_concepts, concepts.size))
    return np.asarray((indicator @ sp.csr_array(words, dtype=np.float64)).toarray(), dtype=np.float64)


def named_parameters(params: ConceptParameters, e: int, free: np.ndarray, word_counts: np.ndarray,
                     alpha_word: float) -> ConceptParameters:
    """``params`` with the word distributions of home ``e``'s free concepts at their posterior mean.

    A free concept (one the knowledge does not use) has θ^w_{e,l} ≈ φ^w_l with φ^w_l ~ Dir(α^w) a
    priori, updated by this home's words only; its posterior mean is
    ``(α^w + N_{l,w}) / (V α^w + N_l)`` (exact when nothing was taught there: the prior mean,
    uniform), instead of the average of a few sparse draws.

    Parameters
    ----------
    params: the model; e: the home.
    free: (L,) bool, the concepts the knowledge does not use.
    word_counts: (L, V) the home's word counts by concept (:func:`concept_word_counts`).
    alpha_word: α^w, the Dirichlet parameter of each word in φ^w's prior.

    Returns
    -------
    A :class:`ConceptParameters` sharing every other array with ``params``.
    """
    free = np.asarray(free, dtype=bool)
    theta = np.asarray(params.word_probabilities, dtype=np.float64)
    if free.shape != (params.n_concepts,):
        raise ConfigurationError(f"free must be a ({params.n_concepts},) bool array, got {free.shape}")
    counts = np.asarray(word_counts, dtype=np.float64)
    if counts.shape != theta.shape[1:]:
        raise ConfigurationError(f"word_counts must have shape {theta.shape[1:]}, got {counts.shape}")
    if not free.any() or theta.shape[-1] == 0:
        return params
    if not alpha_word > 0:
        raise ConfigurationError(f"alpha_word must be > 0, got {alpha_word!r}")
    rows = counts[free] + alpha_word
    theta = theta.copy()
    theta[e, free] = rows / rows.sum(axis=1, keepdims=True)
    return replace(params, word_probabilities=theta)


def answerable_names(params: ConceptParameters, e: int, names: np.ndarray) -> ConceptParameters:
    """``params`` with home ``e``'s p(name | concept) over the names the home answers: θ^w on
    ``names``, plus the mass θ^w puts on every other word spread evenly over ``names`` (rows still sum
    to 1; other words get 0; ``word_mask`` becomes ``names``).

    A concept whose names channel says a word the home does not answer (masked) then says nothing
    about which of the home's names applies — uniform over them — instead of the largest of its
    near-zero masses renormalised to p ≈ 1 (:func:`spco.model.prediction.predict_names` normalises
    over the unmasked words). A concept whose θ^w is on the names is unchanged.

    Parameters
    ----------
    params: the model; e: the home.
    names: (V,) bool, the words the home answers.
    """
    names = np.asarray(names, dtype=bool)
    theta = np.asarray(params.word_probabilities, dtype=np.float64)
    if names.shape != theta.shape[-1:]:
        raise ConfigurationError(f"names must be a ({theta.shape[-1]},) bool array, got {names.shape}")
    if not names.any():
        return replace(params, word_mask=names)
    rows = np.clip(theta[e], 0.0, None)
    total = rows.sum(axis=1, keepdims=True)
    rows = np.divide(rows, total, out=np.zeros_like(rows), where=total > 0)
    on_names = rows * names[None, :]
    elsewhere = 1.0 - on_names.sum(axis=1, keepdims=True)
    theta = theta.copy()
    theta[e] = on_names + np.clip(elsewhere, 0.0, 1.0) * names[None, :] / names.sum()
    return replace(params, word_probabilities=theta, word_mask=names)


def place_named_parameters(params: ConceptParameters, e: int, place_names: np.ndarray,
                           home_names: np.ndarray, delta_word: float, word_increment: float
                           ) -> ConceptParameters:
    """``params`` with home ``e``'s names of each concept at their posterior mean around the names
    said at the concept's places, instead of around its own names channel φ^w.

    For a concept l with names said at its places (``place_names`` row l, from the experienced
    homes: :func:`spco.model.word_channels.place_names`), normalised to P̂_l::

        θ^w_{e,l} = (δ^w P̂_l + S^w N_{e,l}) / (δ^w + S^w n_{e,l})

    with N_{e,l} the home's own expected name tokens in l (``home_names``, each S^w counts as θ^w
    counts them) and n_{e,l} their total: the posterior mean of θ^w_{e,l} ~ Dir(δ^w P̂_l) given the
    home's names. A home that taught nothing in l answers the names people say where l's samples
    stand; a home that named it answers its own names as before. Concepts with no such names (free
    concepts, no experienced sample) keep their row. docs/model.md, "Names said at a concept's
    places".

    Parameters
    ----------
    params: the model; e: the home.
    place_names: (L, V) names said at each concept's places (expected tokens).
    home_names: (L, V) the home's expected name tokens by concept.
    delta_word: δ^w; word_increment: S^w, the counts of one name token in θ^w.
    """
    theta = np.asarray(params.word_probabilities, dtype=np.float64)
    place_names = np.asarray(place_names, dtype=np.float64)
    home_names = np.asarray(home_names, dtype=np.float64)
    if place_names.shape != theta.shape[1:] or home_names.shape != theta.shape[1:]:
        raise ConfigurationError(f"place_names and home_names must have shape {theta.shape[1:]}, got "
                                 f"{place_names.shape} and {home_names.shape}")
    if not (delta_word > 0 and word_increment > 0):
        raise ConfigurationError(f"delta_word and word_increment must be > 0, got {delta_word!r}, "
                                 f"{word_increment!r}")
    mass = place_names.sum(axis=1)
    rows = mass > 0
    if not rows.any():
        return params
    prior = place_names[rows] / mass[rows, None]
    counts = word_increment * np.clip(home_names[rows], 0.0, None)
    theta = theta.copy()
    theta[e, rows] = (delta_word * prior + counts) / (delta_word + counts.sum(axis=1, keepdims=True))
    return replace(params, word_probabilities=theta)


def answer_parameters(params: ConceptParameters, e: int, words: sp.csr_array | np.ndarray,
                      concepts: np.ndarray, log_g0: np.ndarray, alpha_word: float) -> ConceptParameters:
    """``params`` as every answer about home ``e``'s names uses them: its concepts that the shared
    knowledge does not use (G_0 below :data:`~spco.model.home_shard.FREE_CONCEPT_WEIGHT`) with
    their word distributions at the posterior mean given the home's own words
    (:func:`named_parameters`).

    Parameters
    ----------
    params: the model; e: the home.
    words: (n, V) the home's training word counts; concepts: (n,) their concepts.
    log_g0: (L,) log G_0 of the knowledge; alpha_word: α^w.
    """
    from spco.model.home_shard import FREE_CONCEPT_WEIGHT

    counts = concept_word_counts(words, concepts, params.n_concepts)
    return named_parameters(params, e, np.exp(np.asarray(log_g0, dtype=np.float64)) < FREE_CONCEPT_WEIGHT,
                            counts, alpha_word)


def answer_concepts(params: ConceptParameters, e: int, positions: np.ndarray, visual: object, *,
                    view_counts: float | None, rooms: HomeRooms | None, settings: AnswerSettings
                    ) -> np.ndarray:
    """(n, L) P(l | pose, view) as the robot answers it: the one concept posterior behind every answer
    about names (:func:`answer_names`; ``ask``'s question scores).

    With ``rooms`` (the home's training samples' regions, views and taught names) the room account,
    P(l | x, v) ∝ Σ_k p(k | x) p(l | room k) p(v | l) (:func:`spco.model.rooms.concepts_by_room`;
    docs/model.md, "A room's evidence"); without them, or if no region holds a training sample, the
    view-by-view posterior of the home's parameters (:func:`spco.model.prediction.concept_posterior`).
    A view counts as ``view_counts`` = w draws either way (``visual`` ``None``: the pose alone).
    ``settings``: the model's answer settings
    (:meth:`~spco.model.hyperparameters.TransferHyperparameters.answer_settings`): ``view_in_room``, the
    view as a draw of its room's own distribution, and ``typical``, how often a room looks like its
    concept (:func:`spco.model.rooms.concepts_by_room`; both opt-in, read with the room account only).
    """
    concepts = None
    if rooms is not None:
        concepts = concepts_by_room(params, e, positions, visual, rooms, view_counts,
                                    view_in_room=settings.view_in_room, typical=settings.typical)
    if concepts is None:
        concepts = concept_posterior(params, e, positions, visual, use_vision=visual is not None,
                                     view_counts=view_counts)
    return concepts


def answer_names(
    params: ConceptParameters,
    e: int,
    vocabulary: Vocabulary,
    positions: np.ndarray | None,
    visual: object,
    *,
    view_counts: float | None,
    weighting: Weighting,
    top_k: int = 3,
    unsure_below: float = UNSURE_BELOW,
    name_prior: str = "off",
    rooms: HomeRooms | None = None,
    settings: AnswerSettings,
) -> NamePrediction:
    """The names the robot answers at ``n`` observations of home ``e`` — the one predictor of
    p(name | pose, view): ``what`` (:func:`spco.knowledge.name_prediction`, the service, the ROS
    node), ``ask`` and the experiments (:func:`spco.evaluation.metrics.evaluate_home`) call it.

    ``params`` are the answer's parameters (:func:`answer_parameters`); ``view_counts`` the model's
    view weight w (:meth:`~spco.model.hyperparameters.TransferHyperparameters.view_weight`);
    ``weighting`` the model's name weighting (:func:`answer_weighting`); answers below
    ``unsure_below`` (default :data:`UNSURE_BELOW`) are flagged unsure; ``name_prior``: the opt-in
    ordering of :func:`~spco.model.prediction.predict_names` (off for the robot's answers).
    ``rooms``: the home's training samples' regions, views and taught names (the robot always has
    them: :func:`spco.knowledge.queries.home_rooms`, :func:`spco.model.rooms.model_rooms`); with them
    and a pose, the concept is judged by :func:`answer_concepts` — the rooms the pose may be in, each
    room's training views pooled as one piece of evidence, and the observation's view, each worth w
    draws against φ^v (docs/model.md, "A room's evidence"). ``None``: view by view against the home's
    π and θ^v (a bare parameter set, SpCoA's single-home fit). ``settings``: the model's answer
    settings, :meth:`~spco.model.hyperparameters.TransferHyperparameters.answer_settings` (the home's,
    the fit's; opt-in ``view_in_room`` and ``typical``, read by :func:`answer_concepts`).
    """
    if not 0.0 <= unsure_below <= 1.0:
        raise ConfigurationError(f"unsure_below must be within 0..1, got {unsure_below!r}")
    concepts = None
    if rooms is not None and positions is not None and weighting != "reference":
        concepts = answer_concepts(params, e, positions, visual, view_counts=view_counts, rooms=rooms,
                                   settings=settings)
    return predict_names(params, e, vocabulary, positions, visual, top_k=top_k, weighting=weighting,
                         use_vision=visual is not None, view_counts=view_counts, unsure_below=unsure_below,
                         name_prior=name_prior, concepts=concepts)  # type: ignore[arg-type]


def answer_weighting(variant: str, prune_words: bool, name_answer: str = "said") -> Weighting:
    """The name weighting of a model's answers: the authors' KL score for the reference sampler;
    none with the naming rule (exact sampler with pruning: only names are kept, and the name people
    say most at a place comes first — the MI weight would put a name taught once behind names of
    the places around), or the pragmatic speaker's ``"listener"`` with ``name_answer="listener"`` (and
    ``"looks"``, its listener taking concepts that look alike as one referent, with ``name_answer="looks"``)
    (:attr:`~spco.model.hyperparameters.TransferHyperparameters.name_answer`); MI without pruning (it
    keeps "this" and "is" from being answered)."""
    if variant == "reference":
        return "reference"
    if not prune_words:
        return "mi"
    return name_answer if name_answer in ("listener", "looks") else "none"


def model_answer_parameters(model: object, e: int, place_names: bool = True) -> ConceptParameters:
    """:func:`answer_parameters` of home ``e`` of a fitted joint model
    (:class:`~spco.model.transfer.SpatialConceptModel`: the experiments' fit of the experienced
    and new homes together): its averaged parameters, its concepts of the home's training samples,
    its G_0.

    With the word channels, the names the home answers are chosen as the robot's home chooses
    them (:attr:`spco.knowledge.home.HomeModel.name_mask`): the words enough of whose uses over the
    fit's homes are expected to be names (:func:`~spco.model.home_shard.name_words` of
    ``channel_tokens_``, the switches' expected counts averaged over the averaged sweeps), and each
    concept's names-channel mass on other words spread over them (:func:`answerable_names`), so an
    experiment scores what the robot would answer (never "the" or "this", which the channels draw as
    background), and each concept's names at their posterior mean around the names said by its
    samples in the other homes and at their places (:func:`place_named_parameters`, as a home adapted
    from a knowledge answers; ``place_names=False``: around the concept's own names channel, the
    answer before it, for comparison).
    """
    from spco.model.home_shard import name_words, switch_tokens

    params = model.parameters_  # type: ignore[attr-defined]
    data = model.data_  # type: ignore[attr-defined]
    rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
    log_g0 = np.log(np.maximum(np.asarray(params.global_concept_weights, dtype=np.float64), 1e-300))
    answer = answer_parameters(params, e, data.words[rows], model.concepts_[e], log_g0,  # type: ignore[attr-defined]
                               model.hyperparameters_.alpha_word)  # type: ignore[attr-defined]
    state = model.state_  # type: ignore[attr-defined]
    if state.channels is None:  # (the model's word_channels_ are these)
        return answer
    tokens = getattr(model, "channel_tokens_", None)  # averaged over the fit's averaged sweeps
    if tokens is None:
        tokens = switch_tokens(data, state)
    names = name_words(tokens) & np.asarray(answer.word_mask, dtype=bool)
    if place_names:
        answer = _model_place_names(model, e, answer)
    return answerable_names(answer, e, names)


def _model_place_names(model: object, e: int, answer: ConceptParameters) -> ConceptParameters:
    """:func:`place_named_parameters` of home ``e`` of a joint fit with the word channels: the names
    said by each concept's samples and at their places over the other homes, objects counted for the
    names they stand in for (:func:`spco.model.unheard.stand_in_columns`), at the fit's final state
    (a knowledge averages them over its kept sweeps)."""
    from spco.model.unheard import stand_in_columns
    from spco.model.word_channels import concept_name_tokens, name_token_counts, place_names

    data, state = model.data_, model.state_  # type: ignore[attr-defined]
    L = state.log_theta_w.shape[1]
    others = np.flatnonzero(np.asarray(data.homes) != e)
    stand_ins = stand_in_columns(model.vocabulary_, state.channels.name_prior())  # type: ignore[attr-defined]
    at_places = place_names(data.words, data.homes, state.concepts, state.regions, state.log_theta_w,
                            state.channels, L, rows=others, stand_ins=stand_ins)
    rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
    own = concept_name_tokens(sp.csr_array(data.words[rows]), data.homes[rows], state.concepts[rows],
                              state.log_theta_w, state.channels, L)
    hyper = model.hyperparameters_  # type: ignore[attr-defined]
    return place_named_parameters(answer, e, at_places, own, hyper.delta_word,
                                  name_token_counts(hyper, float(model.word_increment_)))  # type: ignore[attr-defined]
