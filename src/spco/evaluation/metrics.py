"""The paper's accuracies: A_n (name prediction) and A_p (position prediction), and their chance levels.

- **A_n** of place ``l``: the fraction of the test samples labelled ``l`` whose predicted name is
  ``l`` — or one of ``l``'s accepted names when the ground truth lists synonyms
  (:attr:`~spco.data.environment.GroundTruth.accepted_names`: "bathroom" is right at the bath). The
  mean over places is the score of a home.
- **A_p** of name ``l``: the fraction of the positions drawn for ``l`` that fall inside the
  ground-truth area of ``l`` (a union of rectangles, bounds inclusive), measured two ways:

  * ``position_accuracy`` — *most probable region*: every position is drawn from the Gaussian of
    m̂ = argmax_m p(m | l), as the authors' published code does (``position_mode="argmax"``);
  * ``position_accuracy_mixture`` — *sampled from p(x | l)*: each position is drawn from a region
    drawn from p(m | l), i.e. from the whole mixture Σ_m p(m | l) N(x | μ_m, Σ_m), as the paper's
    text describes it. A name whose probability is spread over several regions scores lower here.

  With accepted names, ``where`` is asked for each of them that the vocabulary holds and A_p of
  ``l`` is the mean over those names (a name the model pruned scores 0; a name never said in any
  home is not asked).
- Chance: ``1/|V|`` for names (a uniformly random word) and ``1/|places|`` for positions.

A place with no test sample (or no ground-truth area) has accuracy NaN, which
:func:`mean_over_places` leaves out of the mean.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from spco.data.environment import Environment
from spco.data.language import Vocabulary, normalize_name
from spco.data.regions import PlaceRegions
from spco.errors import ConfigurationError, DataFormatError
from spco.model.answer_settings import AnswerSettings
from spco.model.confidence import answer_names
from spco.model.hyperparameters import NamePrior
from spco.model.parameters import ConceptParameters
from spco.model.position_prediction import PositionMode, PositionPrediction, predict_positions
from spco.model.prediction import NamePrediction, UnknownNameError, Weighting
from spco.model.rooms import HomeRooms

__all__ = [
    "HomeScores",
    "evaluate_answers",
    "evaluate_home",
    "json_score",
    "mean_over_places",
    "name_accuracy",
    "name_chance",
    "position_accuracy",
    "position_chance",
]


def _norm(label: str | None) -> str | None:
    if label is None:
        return None
    return normalize_name(str(label)) or None


def name_accuracy(
    predicted: Sequence[str | None],
    labels: Sequence[str | None],
    places: Sequence[str] | None = None,
    accepted: Mapping[str, Sequence[str]] | None = None,
) -> dict[str, float]:
    """A_n per place: the fraction of the samples labelled ``l`` whose predicted name is ``l`` (or
    one of ``accepted[l]``).

    Parameters
    ----------
    predicted: (n,) predicted name of each test sample (``None`` = no prediction, counts as wrong).
    labels: (n,) true place of each sample; samples labelled ``None`` are ignored.
    places: the places to score (default: the labels, in order of first appearance).
    accepted: place -> names also counted right for it (default: none).

    Names and labels are compared after :func:`~spco.data.language.normalize_name`. A place with
    no sample gets NaN (excluded by :func:`mean_over_places`).
    """
    if len(predicted) != len(labels):
        raise ConfigurationError(f"{len(predicted)} predictions for {len(labels)} labels")
    pred = np.array([_norm(p) or "" for p in predicted], dtype=object)
    lab = np.array([_norm(lab) for lab in labels], dtype=object)
    if places is None:
        order = list(dict.fromkeys(lab_ for lab_ in lab if lab_ is not None))
    else:
        order = list(dict.fromkeys(_norm(p) for p in places if _norm(p) is not None))
    synonyms = {_norm(k): {_norm(n) for n in v} for k, v in (accepted or {}).items()}
    out: dict[str, float] = {}
    for place in order:  # loop over places (a handful), vectorised over samples
        rows = lab == place
        count = int(rows.sum())
        right = np.isin(pred[rows], sorted({place, *synonyms.get(place, set())} - {None}))
        out[place] = float(right.sum() / count) if count else math.nan
    return out


def mean_over_places(scores: Mapping[str, float]) -> float:
    """Mean of the per-place accuracies, NaN entries left out; NaN if every entry is NaN (or none)."""
    values = np.asarray(list(scores.values()), dtype=np.float64)
    if values.size == 0 or np.isnan(values).all():
        return math.nan
    return float(np.nanmean(values))


def position_accuracy(
    samples_by_name: Mapping[str, np.ndarray], regions: PlaceRegions
) -> dict[str, float]:
    """A_p per name: the fraction of its sampled positions inside its ground-truth area.

    Parameters
    ----------
    samples_by_name: name -> (P, 2) or (P, 3) positions in metres (only x, y are used).
    regions: the ground-truth areas; a point on a rectangle's edge is inside.

    A name with no sample (P = 0) gets NaN. A name without a ground-truth area raises
    :class:`~spco.errors.ConfigurationError`. NaN coordinates are outside.
    """
    out: dict[str, float] = {}
    for name, samples in samples_by_name.items():
        key = normalize_name(name)
        if key not in regions.places:
            raise ConfigurationError(f"no ground-truth area for place {name!r}; places with one: "
                                     f"{', '.join(regions.places)}")
        xy = np.asarray(samples, dtype=np.float64)
        if xy.size == 0:
            out[key] = math.nan
            continue
        xy = np.atleast_2d(xy)
        if xy.shape[1] < 2:
            raise ConfigurationError(f"positions for {name!r} must have shape (P, 2) or (P, 3)")
        out[key] = float(regions.contains(key, xy[:, :2]).mean())
    return out


def name_chance(vocabulary_size: int) -> float:
    """Chance level of A_n: 1/|V| (a word drawn uniformly from the vocabulary)."""
    if vocabulary_size < 1:
        raise ConfigurationError(f"the vocabulary size must be >= 1, got {vocabulary_size}")
    return 1.0 / vocabulary_size


def position_chance(n_places: int) -> float:
    """Chance level of A_p: 1/|places| (a position drawn uniformly among the places)."""
    if n_places < 1:
        raise ConfigurationError(f"the number of places must be >= 1, got {n_places}")
    return 1.0 / n_places


def json_score(value: float | None) -> float | None:
    """A score as JSON writes it: ``None`` for a missing (``None``) or undefined (NaN) one, else the
    float as measured, unrounded (the one rule of :meth:`HomeScores.summary` and the experiments'
    records; a table rounds when it prints)."""
    return None if value is None or math.isnan(value) else float(value)


@dataclass(frozen=True, eq=False)
class HomeScores:
    """Name and position accuracy of one home.

    Attributes
    ----------
    home: the home's name.
    places: the places scored (normalised names).
    name_accuracy: place -> A_n (NaN: no test sample of that place).
    position_accuracy: place -> A_p, positions from the most probable region (``position_mode``,
        default ``"argmax"``, the authors' code) (NaN: no ground-truth area; 0: the name cannot be
        predicted).
    position_accuracy_mixture: place -> A_p, positions sampled from the whole mixture p(x | name)
        (the paper's text).
    mean_name_accuracy, mean_position_accuracy, mean_position_accuracy_mixture: NaN-excluding
        means over places.
    name_chance: 1/|V| (NaN for an empty vocabulary); position_chance: 1/|places|.
    labels: (n,) true place of each scored sample.
    predicted_names: (n,) predicted name of each scored sample (``None``: no word survived).
    name_predictions: the full :class:`~spco.model.prediction.NamePrediction` of the scored samples.
    test_positions: (n, 4) poses of the scored samples.
    position_predictions: place -> :class:`~spco.model.position_prediction.PositionPrediction`
        (names that could be predicted only).
    """

    home: str
    places: tuple[str, ...]
    name_accuracy: dict[str, float]
    position_accuracy: dict[str, float]
    mean_name_accuracy: float
    mean_position_accuracy: float
    name_chance: float
    position_chance: float
    labels: tuple[str | None, ...]
    predicted_names: tuple[str | None, ...]
    name_predictions: NamePrediction
    test_positions: np.ndarray
    position_predictions: dict[str, PositionPrediction] = field(default_factory=dict)
    position_accuracy_mixture: dict[str, float] = field(default_factory=dict)

    @property
    def mean_position_accuracy_mixture(self) -> float:
        """NaN-excluding mean over places of :attr:`position_accuracy_mixture`."""
        return mean_over_places(self.position_accuracy_mixture)

    @property
    def predicted_positions(self) -> dict[str, np.ndarray]:
        """place -> (P, 3) sampled poses ``(x, y, θ)``, for :func:`spco.plots.plot_home_map`."""
        return {name: pred.samples for name, pred in self.position_predictions.items()}

    def summary(self) -> dict[str, object]:
        """A JSON-ready summary: the scores as measured, NaN written as ``None`` (:func:`json_score`);
        the experiments' records hold the same fields (:mod:`spco.evaluation.runs`)."""
        clean = json_score
        return {
            "home": self.home,
            "name_accuracy": {k: clean(v) for k, v in self.name_accuracy.items()},
            "position_accuracy": {k: clean(v) for k, v in self.position_accuracy.items()},
            "mean_name_accuracy": clean(self.mean_name_accuracy),
            "mean_position_accuracy": clean(self.mean_position_accuracy),
            "position_accuracy_mixture": {k: clean(v) for k, v in self.position_accuracy_mixture.items()},
            "mean_position_accuracy_mixture": clean(self.mean_position_accuracy_mixture),
            "name_chance": clean(self.name_chance),
            "position_chance": clean(self.position_chance),
        }


def evaluate_home(
    params: ConceptParameters,
    e: int,
    environment: Environment,
    vocabulary: Vocabulary,
    places: Sequence[str] | None = None,
    specific: bool = False,
    n_positions: int = 10,
    rng: np.random.Generator | int | None = None,
    weighting: Weighting = "mi",
    position_mode: PositionMode = "argmax",
    xy_only: bool = False,
    name_prior: NamePrior = "off",
    view_counts: float | None = None,
    answer_params: ConceptParameters | None = None,
    answer_rooms: HomeRooms | None = None,
    settings: AnswerSettings | None = None,
) -> HomeScores:
    """Score name and position prediction in home ``e`` (the paper's A_n and A_p).

    Parameters
    ----------
    params, e: the model and the index of ``environment`` among its homes.
    environment: the home, with ground truth (labels, and regions for A_p).
    vocabulary: the corpus vocabulary the model was learnt with.
    places: the places to score. Default: general — every labelled place of the home;
        specific — the places of the home-specific test samples.
    specific: the home-specific experiment: score the samples of ``ground_truth.specific_test``
        against ``ground_truth.specific_labels`` instead of the test samples against the labels.
    n_positions: positions drawn per name for A_p (each way).
    rng: Generator or seed for the position draws (the mixture draws use a child stream of it, so
        the most-probable-region draws do not depend on them).
    weighting: name weighting (see :func:`spco.model.prediction.predict_names`).
    view_counts: the model's view weight w (see :func:`spco.model.prediction.predict_names`;
        ``None``: every count a draw).
    answer_params: the parameters the robot answers names with
        (:func:`spco.model.confidence.model_answer_parameters`); names are then predicted by the
        robot's own function, :func:`spco.model.confidence.answer_names`, and positions by its
        ``where``'s, :func:`spco.model.position_prediction.predict_positions` with these parameters,
        ``answer_rooms`` and ``params.word_mask`` as the words looked up (``None``: ``params``).
    answer_rooms: the home's rooms as the robot's answer reads them
        (:func:`spco.model.rooms.model_rooms`; ``None``: names from each sample's own view and pose,
        regions from the home's π and G).
    settings: the answer's settings, the model's
        (:meth:`~spco.model.hyperparameters.TransferHyperparameters.answer_settings`; ``None``: the
        defaults, no opt-in): read by :func:`spco.model.confidence.answer_names` with ``answer_rooms``
        (``view_in_room`` needs them). Positions are unchanged (``where`` reads no view).
    name_prior: ``"wordnet"`` orders each concept's words by the name prior when names are
        predicted (opt-in; see :func:`spco.model.prediction.predict_names`).
    position_mode, xy_only: see :func:`spco.model.position_prediction.predict_positions`;
        ``position_mode`` is the mode of ``position_accuracy``; ``position_accuracy_mixture`` is
        always ``"mixture"``.

    Conventions: a place with no scored sample has A_n = NaN, left out of the mean. A place whose
    name the model cannot predict (never taught, or pruned) gets A_n = 0 (it is never predicted)
    and A_p = 0 (no position can be proposed). A place without a ground-truth area has A_p = NaN,
    and if the home has no regions at all every A_p is NaN.
    """
    settings = AnswerSettings() if settings is None else settings
    if settings.view_in_room and answer_rooms is None:
        raise ConfigurationError("view_in_room needs the home's rooms (answer_rooms), got None")
    gt = environment.ground_truth
    if gt is None:
        raise DataFormatError(environment.source or environment.name, "this home has no ground truth "
                              "to evaluate against")
    all_labels = environment.labels(specific)
    if specific:
        if gt.specific_test is None:
            raise DataFormatError(environment.source or environment.name,
                                  "this home has no home-specific test samples")
        rows = np.flatnonzero(np.asarray(gt.specific_test, dtype=bool))
    else:
        rows = np.flatnonzero(environment.is_test)
    labels = tuple(all_labels[i] for i in rows)
    if places is None:
        source = labels if specific else all_labels
        place_list = list(dict.fromkeys(p for p in source if p is not None))
    else:
        place_list = list(dict.fromkeys(n for n in (_norm(p) for p in places) if n is not None))

    positions = environment.positions[rows]
    visual = environment.visual[rows]
    prediction = answer_names(params if answer_params is None else answer_params, e, vocabulary, positions,
                              visual, top_k=3, weighting=weighting, name_prior=name_prior,
                              view_counts=view_counts, rooms=answer_rooms, settings=settings)
    predicted = tuple(prediction.best)
    accepted = {place: gt.accepted(place) for place in place_list}
    name_scores = name_accuracy(predicted, labels, place_list, accepted)

    # the robot's where (spco.knowledge.where): its answer's parameters and rooms, the fit's word mask
    where_params = params if answer_params is None else answer_params
    gen = np.random.default_rng(rng)
    gen_mixture = gen.spawn(1)[0]  # a child stream: the argmax draws stay as they were
    pos_scores: dict[str, float] = {}
    mix_scores: dict[str, float] = {}
    pos_predictions: dict[str, PositionPrediction] = {}
    regions = gt.regions
    for place in place_list:  # a handful of names
        if regions is None or place not in regions.places:
            pos_scores[place] = mix_scores[place] = math.nan
            continue
        # the place's own name, and every accepted synonym the vocabulary holds as one token
        names = [n for i, n in enumerate(accepted[place]) if i == 0 or vocabulary.index(n) is not None]
        for mode, stream, out in ((position_mode, gen, pos_scores), ("mixture", gen_mixture, mix_scores)):
            scores: list[float] = []
            for name in names:
                try:
                    # A_p scores the names the model learnt: no lexicon look-up of a name never said
                    pred = predict_positions(where_params, e, vocabulary, name, n=n_positions, rng=stream,
                                             mode=mode, xy_only=xy_only, unheard=False, rooms=answer_rooms,
                                             view_counts=view_counts, lookup=params.word_mask)
                except UnknownNameError:
                    scores.append(0.0)
                    continue
                if stream is gen:
                    pos_predictions.setdefault(place, pred)
                scores.append(position_accuracy({place: pred.samples}, regions)[place])
            if len(names) > 1 and vocabulary.index(place) is None:
                scores.pop(0)  # the label itself was never said (people use its synonyms)
            out[place] = float(np.mean(scores))

    return HomeScores(
        home=environment.name,
        places=tuple(place_list),
        name_accuracy=name_scores,
        position_accuracy=pos_scores,
        mean_name_accuracy=mean_over_places(name_scores),
        mean_position_accuracy=mean_over_places(pos_scores),
        name_chance=name_chance(len(vocabulary)) if len(vocabulary) else math.nan,
        position_chance=position_chance(len(place_list)) if place_list else math.nan,
        labels=labels,
        predicted_names=predicted,
        name_predictions=prediction,
        test_positions=positions,
        position_predictions=pos_predictions,
        position_accuracy_mixture=mix_scores,
    )


def evaluate_answers(
    model: object,
    e: int,
    environment: Environment,
    places: Sequence[str] | None = None,
    specific: bool = False,
    n_positions: int = 10,
    rng: np.random.Generator | int | None = None,
    name_prior: NamePrior | None = None,
    settings: AnswerSettings | None = None,
) -> HomeScores:
    """Score home ``e`` of a fitted model as the robot answers it: :func:`evaluate_home` with the
    model's own answer inputs (``model.answer_inputs(e)``: the answer's parameters, the home's rooms
    and the name weighting), its view weight, its name prior and its answer settings
    (``hyperparameters_.answer_settings()``: ``view_in_room``, ``typical``). The one way the experiments
    and the benchmarks score a model's answers, so that no caller scores another weighting than the
    robot's.

    ``model``: a fitted :class:`~spco.model.transfer.SpCoTransfer` (or SpCoA); ``name_prior``
    overrides the model's ``hyperparameters_.name_prior`` (``None``: the model's); ``settings``: the
    one override of the answer settings, for an experiment that scores one fit two ways (``None``:
    the model's)."""
    answer_params, answer_rooms, weighting = model.answer_inputs(e)  # type: ignore[attr-defined]
    sampler = getattr(model, "settings_", None)
    hyper = getattr(model, "hyperparameters_", None)
    prior = name_prior if name_prior is not None else getattr(hyper, "name_prior", "off")
    if settings is None:
        settings = hyper.answer_settings() if hyper is not None else AnswerSettings()
    return evaluate_home(model.parameters_, e, environment, model.vocabulary_,  # type: ignore[attr-defined]
                         places=places, specific=specific, n_positions=n_positions, rng=rng,
                         weighting=weighting, name_prior=prior,
                         view_counts=getattr(sampler, "view_counts", None),
                         answer_params=answer_params, answer_rooms=answer_rooms, settings=settings)
