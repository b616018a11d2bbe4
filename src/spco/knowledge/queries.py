"""Questions to a home: where a place is (:func:`where`), what a place is called (:func:`what`),
why a word is not used (:func:`unused_word_hint`), and what a knowledge or home file holds
(:func:`describe_model_file`).

*Answers* (:func:`where`, :func:`what`) come from the home's parameters averaged over thinned
sweeps of the last adaptation or teaching (``HomeModel.posterior``, :mod:`spco.model.posterior`),
not from the last draw; ``where`` reports ``learnt`` False and a low ``support`` when the name's
probability in the home comes from concepts that hold none of its samples (no such place learnt
in this home).
"""

from __future__ import annotations

import warnings
import weakref
from collections.abc import Callable
from dataclasses import replace
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from spco.errors import ConfigurationError
from spco.knowledge.files import HOME_FORMAT, model_file_format
from spco.knowledge.home import HomeModel, load_home_model
from spco.knowledge.knowledge import load_knowledge
from spco.knowledge.requests import Pose, What
from spco.knowledge.views import _visual_row, pose_outside_map, view_counts
from spco.model import confidence
from spco.model.confidence import UNSURE_BELOW
from spco.model.parameters import ConceptParameters
from spco.model.position_prediction import PositionPrediction
from spco.model.prediction import NamePrediction, UnknownNameError
from spco.model.rooms import HomeRooms, sample_rooms
from spco.model.seeds import as_generator
from spco.model.word_channels import concept_name_tokens, name_token_counts, name_tokens, rooms_concentration


def where(home: HomeModel, name: str, n: int = 10,
          random_state: int | np.random.Generator | None = None) -> PositionPrediction:
    """Poses ``(x, y, θ)`` to go to for the place ``name`` in ``home``.

    The one p(pose | name) (:func:`spco.model.position_prediction.predict_positions`, which the
    experiments' A_p calls too): p(m | name) ∝ Σ_{rooms k of m} n_k Σ_l p(l | room k) p(name | room k, l),
    the rooms those of the room account of the home's training samples (:func:`home_rooms`: each room's
    pooled views, its taught names and G_0 decide its concept) and each room's names drawn around its
    concept's — the names ``what`` answers (:func:`answer_parameters`, and with the word channels the
    words of the place ψ: "where is the fridge") — updated by the words said in the room
    (docs/model.md, "Where a place is"): a name said in one room is found there, and in a home taught
    nothing ``where`` is the Bayes inverse of ``what`` at the pose alone.
    The poses are drawn from the answer regions — those at least half as probable as the best
    (a name taught at two places of the home finds both) — in proportion to their probability, at
    least one per region (:func:`~spco.model.position_prediction.answer_regions`); each pose's
    ``weights`` entry is its share of the density p(x | name) among the ``n`` poses. Raises
    :class:`~spco.model.prediction.UnknownNameError` (with suggestions) for a name the home cannot
    use: never heard, or pruned as no name.
    ``name`` is read like a sentence (``"Living Room"``, ``"living-room"`` → ``living room``); a name
    never learnt as one term is its known words said together (``study + room``). ``learnt`` is
    False (and ``support`` low) when no such place was learnt in this home: the name is carried
    mostly by concepts holding none of its samples, and :func:`what` at the centre
    of the answer region does not answer it either (``called``: the name it answers there, the
    home's own name for the place; a name ``what`` answers there counts as learnt, whatever the
    support: ``where`` and ``what`` agree). A name nobody said
    ("restroom") is first looked up in the lexicon as the experiments' predictor looks it up
    (:func:`spco.model.position_prediction.resolve_unheard`, with the home's parameters' words): the
    answer is then for the known name it found (``name``: "toilet"; ``asked``: "restroom"; ``via``:
    how).
    """
    try:
        return _where(home, name, n, random_state)
    except UnknownNameError:
        hint = unused_word_hint(home, name)
        if hint is None:
            raise
        raise UnknownNameError(name, home.known_names, reason=hint) from None


def _where(home: HomeModel, name: str, n: int, random_state: int | np.random.Generator | None
           ) -> PositionPrediction:
    """:func:`where` without the hint for unusable names: the scored predictor itself
    (:func:`~spco.model.position_prediction.predict_positions` with its own look-up of a name nobody
    said, :func:`~spco.model.position_prediction.resolve_unheard`) on the answer's parameters and rooms,
    the words a place is looked up by those of the home's parameters (:attr:`HomeModel.said_words`)."""
    from spco.model.position_prediction import predict_positions

    params, rooms = answer_inputs(home)
    pred = predict_positions(params, 0, home.vocabulary, name, n, as_generator(random_state), mode="answer",
                             unheard=True, rooms=rooms, view_counts=home.hyperparameters.view_weight(),
                             lookup=home.parameters.word_mask)
    if pred.learnt:
        return pred
    # what `what` answers where the poses are: the name itself (learnt after all) or another
    called = answered_at_region(home, pred.region)
    learnt = called == pred.name
    return replace(pred, learnt=learnt, called=None if learnt else called)


def answered_at_region(home: HomeModel, region: int) -> str | None:
    """The name :func:`what` answers (the position alone) at the centre of the home's region
    ``region``: the name the home gives the place there; ``None`` if it knows none."""
    words = names_at_regions(home, [region], top_k=1).words[0]
    return str(words[0]) if len(words) else None


def names_at_regions(home: HomeModel, regions: Any, top_k: int = 3) -> NamePrediction:
    """What :func:`what` answers (the position alone) at the centre of each of the home's regions
    ``regions`` (indices; its mean pose, the heading from the mean's sin θ and cos θ): one row per
    region, as :func:`name_prediction` answers them (a centre off the map is still answered)."""
    rows = np.asarray(regions, dtype=np.int64).reshape(-1)
    means = np.asarray(home.parameters.region_means[0], dtype=np.float64)[rows]  # (n, 4): x, y, sin θ, cos θ
    theta = np.arctan2(means[:, 2], means[:, 3])
    poses = np.column_stack([means[:, 0], means[:, 1], np.sin(theta), np.cos(theta)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a region's centre off the map: still the region's answer
        return name_prediction(home, poses, None, top_k=top_k)


def places(home: HomeModel) -> dict[str, PositionPrediction]:
    """:func:`where` of every name the home answers (:attr:`~spco.knowledge.home.HomeModel.known_names`),
    without poses: where each place is, as ``where`` answers it (``region``, its probability
    ``region_probabilities[region]``, ``learnt``). What labels the places of a map (the page of
    ``spco serve``, the ROS markers, Foxglove): a name is labelled at the region ``where`` goes to for
    it. A name ``where`` cannot use (:class:`~spco.model.prediction.UnknownNameError`) is left out."""
    found: dict[str, PositionPrediction] = {}
    for name in home.known_names:
        try:
            found[name] = where(home, name, n=0, random_state=0)
        except UnknownNameError:
            continue
    return found


def unused_word_hint(home: HomeModel, word: str) -> str | None:
    """Why a word of the home's vocabulary is not used (pruned as uninformative) and what to do about
    it, or ``None`` if the word is unknown or used.

    A word taught at a few samples of this home is pruned when the naming rule finds its uses no
    more often in one region than chance, and a word the knowledge pruned stays pruned until the
    home's teachings show it marks a place (:func:`_home_word_mask`): in both cases teaching it at a
    few more samples of the same place (the nearest untaught samples are suggested) can make it a
    place name.
    """
    index = home.vocabulary.index(word)
    channels = home.knowledge.channels is not None
    if index is None or bool((home.name_mask if channels else home.said_words)[index]):
        return None
    w = home.vocabulary.words[index]
    taught = [k for k, sentence in enumerate(home.sentences) if w in home.vocabulary.tokenize(sentence)]
    if channels:  # the word channels: the word's uses are words of a place or background, not names
        tokens = home.channel_tokens[index]
        if not taught or tokens[2] >= tokens[:2].sum():
            return (f"the word {w!r} names no place: {tokens[2]:.0f} of its {tokens.sum():.0f} uses (the "
                    f"experienced homes' and this home's) are background words, said alike everywhere "
                    f"(function words, fillers, greetings); teach the place by its name (\"this is the …\")")
    if not taught:
        return (f"the word {w!r} was pruned as uninformative in the experienced homes: it is said at "
                f"every kind of place (or too rarely) to tell places apart, so it names no place")
    xy = home.positions[:, :2]
    distance = np.linalg.norm(xy - xy[taught].mean(0), axis=1)
    untaught = [k for k in np.argsort(distance, kind="stable") if home.sentences[k] is None][:3]
    ids = [int(home.ids[k]) for k in untaught]
    more = ("teach it at a few more samples of that place"
            + (", e.g. the nearest untaught ones: spco teach HOME "
               + " ".join(f'--id {i} --sentence "this is {w}"' for i in ids) if ids else ""))
    if index < home.n_knowledge_words and not bool(home.knowledge.word_mask[index]):
        # the home takes such a word back once its own samples show it marks a place (_home_word_mask)
        return (f"the word {w!r} was pruned as uninformative by the knowledge: in its experienced "
                f"homes it did not tell places apart (a word said everywhere, or a name said in one "
                f"home only), and this home's {len(taught)} teaching(s) do not yet show that it marks "
                f"one place here; {more} (or fit the knowledge with --model spcotransfer: no pruning)")
    shown = ", ".join(str(int(home.ids[k])) for k in taught[:5]) + (", …" if len(taught) > 5 else "")
    if channels:
        return (f"the word {w!r} is not used as a place name yet: it is taught at {len(taught)} sample(s) of "
                f"this home (id {shown}), and how it is said makes it a word of its place (an object, an "
                f"activity: `where` finds the place by it) more likely than the place's name; to name the "
                f"place, say its name as one (\"this is the …\"), or {more}")
    return (f"the word {w!r} is not used as a place name yet: it is taught at {len(taught)} sample(s) of "
            f"this home (id {shown}), too few to tell its place from the others (pruned as "
            f"uninformative); {more}")



def what(home: HomeModel, x: float, y: float, theta: float, visual: Any = None,
         top_k: int = 3, image: Any = None, encoding: str | None = None,
         unsure_below: float = UNSURE_BELOW) -> NamePrediction:
    """The ``top_k`` place names at pose ``(x, y, θ)``, with the view's visual counts if given.

    The probabilities are honest (:mod:`spco.model.confidence`): a view counts as the model's view
    weight w draws (the one the home was learnt with), a room's training views together as one view
    (the room account, :func:`name_prediction`), a concept nobody named has no name;
    an answer whose probability is below ``unsure_below`` (default
    :data:`~spco.model.confidence.UNSURE_BELOW`) is flagged ``unsure``.

    A pose off the home's map is answered with a :class:`UserWarning`, one more than
    :data:`FAR_OUTSIDE_MAP` map sizes off it is refused (:func:`pose_outside_map`); ``θ`` must be in
    radians (``|θ| ≤ 2π``).

    ``image`` (a path, a JPEG/PNG file's bytes or an array of pixels) gives the view as an image
    instead, for a home whose knowledge was fitted on images: its extractor computes the counts.
    ``encoding`` is an array's colour order — ``rgb8`` (PIL, matplotlib, ``cv_bridge``'s rgb8),
    ``bgr8`` (OpenCV, the default), ``mono8``, ``rgba8``, ``bgra8`` (:mod:`spco.features.pixels`).
    Without a view the names come from the position alone (``use_vision=False``). The returned
    :class:`~spco.model.prediction.NamePrediction` holds one row: ``words[0]``, ``probabilities[0]``
    (p(w | x, v)), ``scores[0]`` (the ranking score), ``confidence[0]`` (the answer's probability)
    and ``unsure[0]``.
    """
    pose = Pose(x, y, theta)
    outside = pose_outside_map(home, pose.x, pose.y)
    if outside is not None:
        warnings.warn(f"{outside}; the names are extrapolated from the nearest regions", stacklevel=2)
    counts = view_counts(home.knowledge, visual, image, encoding)
    return _names_at(home, pose, counts, top_k, unsure_below)


def what_request(home: HomeModel, request: What, *, extractor: Callable[[], Any] | None = None,
                 unsure_below: float = UNSURE_BELOW) -> tuple[NamePrediction, str | None]:
    """The home's one answer to a checked :class:`~spco.knowledge.requests.What` (HTTP, ROS, the
    command line): every name ranked as :func:`what` ranks them (``request.top`` is the caller's to
    show), and ``None`` for a pose on the map or the sentence saying how far off it is (instead of
    :func:`what`'s warning: a server answers many such poses). Checks what needs the home: the pose
    (:func:`pose_outside_map` raises for one far off), then the view (its counts of the home's
    dimension; an image turned into counts by the knowledge's extractor: ``extractor``, a function
    giving the one to use, :func:`~spco.knowledge.views.view_counts`)."""
    if not isinstance(request, What):
        raise ConfigurationError(f"what_request() takes a What request, got {type(request).__name__}")
    pose, view = request.pose, request.view
    outside = pose_outside_map(home, pose.x, pose.y)  # before an image is turned into counts
    counts = None if view is None else view_counts(home.knowledge, view.visual, view.image, view.encoding,
                                                   extractor)
    return _names_at(home, pose, counts, max(len(home.vocabulary), 1), unsure_below), outside


def _names_at(home: HomeModel, pose: Pose, counts: Any, top_k: int, unsure_below: float) -> NamePrediction:
    """:func:`name_prediction` at one checked pose, with one view's counts (``None``: no view)."""
    row = None if counts is None else _visual_row(counts, home.knowledge.n_features)
    return name_prediction(home, pose.row()[None, :], row, top_k=top_k, unsure_below=unsure_below)


def answer_parameters(home: HomeModel) -> ConceptParameters:
    """The home's parameters as every answer about names uses them (``what``, ``ask``, the service
    and the ROS node through them): the one place where a home's p(name | concept) is decided.

    The posterior average θ^w of the home (with the word channels: the names channel), with the
    concepts the knowledge does not use at their posterior mean given the home's own taught names
    (:func:`spco.model.confidence.named_parameters`: uniform over the names when nothing was taught
    there; with the channels the name tokens of the home's switches); with the channels, each concept
    the knowledge uses at its posterior mean around the names said by its experienced samples and at
    their places (:func:`spco.model.confidence.place_named_parameters`: a concept of people who named
    only the furniture answers the room's name said where they stood), and ``word_mask`` the home's
    names (:attr:`~spco.knowledge.home.HomeModel.name_mask`): with the channels, the words most of
    whose tokens are names — never a word said as an object or a background word — and each
    concept's names-channel mass on other words spread evenly over the home's names
    (:func:`spco.model.confidence.answerable_names`: a concept named with a masked word answers
    unsure, not a neighbour's name at p ≈ 1).
    """
    words = home.data.words
    if home.knowledge.channels is not None and home.state.switches is not None and words.nnz:
        words = name_tokens(words, home.state.switches)  # a free concept's names: its name tokens
    params = confidence.answer_parameters(home.parameters, 0, words, home.state.concepts,
                                          home.knowledge.log_g0, home.hyperparameters.alpha_word)
    # the names only (the word channels: a word said as an object or a function word is never a name)
    if home.knowledge.channels is None:
        return replace(params, word_mask=home.name_mask)
    at_places = home.knowledge.channels.place_names
    state = home.state
    if at_places is not None and state.channels is not None:
        # each concept's names around those said where its experienced samples stand, updated by the
        # home's own name tokens (spco.model.confidence.place_named_parameters)
        own = concept_name_tokens(home.data.words, home.data.homes, state.concepts, state.log_theta_w,
                                  state.channels, params.n_concepts)
        params = confidence.place_named_parameters(
            params, 0, at_places, own, home.hyperparameters.delta_word,
            name_token_counts(home.hyperparameters, float(home.knowledge.word_increment)))
    # with the channels θ^w is the names channel: its mass on a word the home does not answer says
    # the place's name is none of the home's names (spco.model.confidence.answerable_names)
    return confidence.answerable_names(params, 0, home.name_mask)


def name_prediction(home: HomeModel, poses: np.ndarray, visual: Any = None, top_k: int = 3,
                    unsure_below: float = UNSURE_BELOW, by_room: bool = True) -> NamePrediction:
    """The names :func:`what` answers, for ``n`` poses at once and without its checks of the pose:
    p(name | pose, view) = Σ_l p(name | l) P(l | pose, view), with p(name | l) from
    :func:`answer_parameters` and P(l | pose, view) the room account
    (:func:`spco.model.confidence.answer_concepts`, :mod:`spco.model.rooms`: P(l | pose, view) ∝
    Σ_k p(k | pose) p(l | room k) p(view | l), room k's training views pooled and the view each worth
    the model's view weight w draws against φ^v, the weight the home was learnt with,
    :meth:`~spco.model.hyperparameters.TransferHyperparameters.view_weight`; docs/model.md, "A room's
    evidence"), with the model's answer settings
    (:meth:`~spco.model.hyperparameters.TransferHyperparameters.answer_settings`: ``view_in_room``,
    ``typical``). ``what``, ``ask``, the service and the ROS node answer through it.

    Parameters
    ----------
    home: the home.
    poses: (n, 4) ``(x, y, sin θ, cos θ)`` in metres.
    visual: (n, D) the views' counts (sparse or dense), or ``None`` for the positions alone.
    top_k, unsure_below: as :func:`what`.
    by_room: ``False`` only to compare: the view and the pose against the home's π and θ^v, each of
        a room's views counted as independent evidence (what ``what`` answered before the room
        account; benchmarks/README.md, "Issue 29: the room account the default").

    Returns
    -------
    The :class:`~spco.model.prediction.NamePrediction` with ``confidence`` and ``unsure``.
    """
    params, rooms = answer_inputs(home)
    return confidence.answer_names(params, 0, home.vocabulary, poses, visual, top_k=top_k,
                                   weighting=home.weighting,  # type: ignore[arg-type]
                                   view_counts=home.hyperparameters.view_weight(), unsure_below=unsure_below,
                                   rooms=rooms if by_room else None,
                                   settings=home.hyperparameters.answer_settings())


#: each home's answer parameters and rooms, worked out once per home object: a home is not changed in
#: place (a teaching or an undo makes a new :class:`HomeModel`, as its cached ``parameters`` assume)
_ANSWER_INPUTS: weakref.WeakKeyDictionary[HomeModel, tuple[ConceptParameters, HomeRooms]] = (
    weakref.WeakKeyDictionary())


def answer_inputs(home: HomeModel) -> tuple[ConceptParameters, HomeRooms]:
    """(:func:`answer_parameters`, :func:`home_rooms`) of ``home``, kept while the home lives: what
    every answer about names (``what``, ``ask``) reads, worked out once per home."""
    known = _ANSWER_INPUTS.get(home)
    if known is None:
        known = _ANSWER_INPUTS[home] = (answer_parameters(home), home_rooms(home))
    return known


def home_rooms(home: HomeModel) -> HomeRooms:
    """The home's training samples as the room-level answer reads them (:mod:`spco.model.rooms`):
    their regions and concepts (a region split by the names taught in it,
    :meth:`~spco.model.rooms.HomeRooms.membership`), their views and the name tokens taught at them
    (with the word channels the tokens drawn as names, as :func:`answer_parameters` counts them, and
    those drawn as words of the place) with δ^w, for a room's own names in ``where``
    (:func:`spco.model.position_prediction.region_posterior_for_name`): the rooms' one builder,
    :func:`spco.model.rooms.sample_rooms`, as the experiments build a joint fit's."""
    return sample_rooms(home.data, home.state, rooms_concentration(home.hyperparameters,
                                                                   float(home.knowledge.word_increment)))


def describe_model_file(path: str | PathLike[str]) -> dict[str, Any]:
    """What a knowledge or home file holds, for people and scripts (``spco inspect FILE``).

    Keys: ``file``, ``kind`` (``"knowledge"`` or ``"home"``), ``model``, ``visual_dimension``,
    ``extractor`` (the feature extractor recorded with the views, or ``None``), ``vocabulary``,
    ``kept_names`` (the words usable as place names), ``text`` (how text written without spaces is
    cut: :meth:`~spco.data.segmentation.Segmentation.describe`, or ``None``), ``homes`` (the
    experienced homes), the view fit (:func:`view_fit`) and the ``provenance``; a home file adds
    ``home``, ``samples``, ``taught`` and ``extent``. Raises :class:`~spco.errors.ModelFileError`
    for a file that is neither (or broken).
    """
    kind = model_file_format(path)
    if kind == HOME_FORMAT:
        home = load_home_model(path)
        knowledge, names = home.knowledge, home.known_names
        provenance = dict(home.provenance)
        homes = list(provenance.get("knowledge_homes") or [])
    else:
        knowledge = load_knowledge(path)  # also the error for a file that is neither
        names, provenance = knowledge.known_names, dict(knowledge.provenance)
        homes = list(provenance.get("homes") or [])
    view = provenance.pop("view_fit", None)
    info: dict[str, Any] = {
        "file": str(Path(path)), "kind": "home" if kind == HOME_FORMAT else "knowledge",
        "model": knowledge.model, "visual_dimension": knowledge.n_features,
        "extractor": knowledge.extractor,
        "vocabulary": list(knowledge.vocabulary.words), "kept_names": list(names), "homes": homes,
        "text": None if knowledge.vocabulary.segmentation is None
        else knowledge.vocabulary.segmentation.describe(),
        "view_fit": view, "provenance": provenance,
    }
    if kind == HOME_FORMAT:
        info.update({"home": home.name, "samples": home.n_samples, "taught": home.n_taught,
                     "extent": None if home.extent is None else list(home.extent)})
    return info
