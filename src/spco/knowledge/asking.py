"""A robot that asks: where in a home an answer to "what is this place?" teaches the most
(:func:`ask`), with a reason a person can read (:class:`Question`).

The criterion is :mod:`spco.model.question_scores` (by default the expected number of wrong answers an
answer corrects; or the expected information of the answer about the names of the home's places;
both in closed form from the home's posterior); this module reads the home's state
for it: the concept posterior and the names at every recorded sample (as ``what`` computes them),
which concepts nobody named, what kind of place each sample looks like, and which samples were
taught with a name of the home's own.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from spco.errors import ConfigurationError
from spco.knowledge.home import HomeModel
from spco.knowledge.queries import answer_inputs, name_prediction
from spco.model.confidence import UNSURE_BELOW, answer_concepts
from spco.model.home_shard import FREE_CONCEPT_WEIGHT
from spco.model.question_scores import QuestionScores, question_scores, rank_questions

__all__ = ["DEFAULT_CRITERION", "NAMELESS_MASS", "Question", "ask",
           "home_question_scores", "name_columns"]

#: What :func:`ask` ranks by (:data:`spco.model.question_scores.CRITERIA`).
DEFAULT_CRITERION = "errors"
#: A concept whose usable names hold less than this share of its word distribution names nothing
#: (its words are all pruned: it is treated as unnamed).
NAMELESS_MASS = 0.01
#: A reason says two concepts compete when the second name has at least this share of the first's
#: probability.
_COMPETING = 0.5
#: ... and that rooms of a kind may have names of their own when ρ is at least this.
_OWN_NAME_REASON = 0.25


@dataclass(frozen=True)
class Question:
    """A place to ask "what is this place?" (:func:`ask`).

    Attributes
    ----------
    id: the sample's id (``spco teach HOME --id ID --sentence …`` records the answer).
    x, y: its position, metres; theta: its heading, radians.
    gain: the expected information of the answer about the names of the home's places, nats.
    reason: why, in words.
    names: the model's best names there with their probability over the usable names (what
        ``what`` would answer), best first (at most three).
    unknown: the probability that the answer is a name the robot has not learnt.
    room: the room (joined regions) the sample belongs to.
    confidence: the probability of the answer the robot expects there (its most probable name,
        a name of the room's own and the room's taught names counted): ``names``' first p × (1 −
        ``own_name``) when the room has no taught name.
    own_name: the probability that the room has a name of its own (one no experienced home gave).
    worth_asking: ``confidence`` is below :data:`UNSURE_BELOW`: the robot is unsure of the answer
        (a robot that asks only when unsure stops at the first question that is not worth asking).
    """

    id: int
    x: float
    y: float
    theta: float
    gain: float
    reason: str
    names: tuple[tuple[str, float], ...] = ()
    unknown: float = 0.0
    room: int = 0
    confidence: float = 0.0
    worth_asking: bool = True
    own_name: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """The question as JSON: ``{"id", "x", "y", "theta", "gain", "reason", "names": [{"name",
        "p"}], "unknown", "confidence", "worth_asking", "own_name"}``."""
        return {"id": self.id, "x": self.x, "y": self.y, "theta": self.theta, "gain": self.gain,
                "reason": self.reason, "names": [{"name": n, "p": p} for n, p in self.names],
                "unknown": self.unknown, "confidence": self.confidence, "worth_asking": self.worth_asking,
                "own_name": self.own_name}


def name_columns(home: HomeModel) -> np.ndarray:
    """(V',) vocabulary columns of the home's usable names (:attr:`HomeModel.name_mask`: the word
    channels' names, or the words the naming rule keeps)."""
    return np.flatnonzero(np.asarray(home.name_mask, dtype=bool))


def home_question_scores(home: HomeModel, criterion: str = DEFAULT_CRITERION) -> QuestionScores:
    """What an answer at each of the home's samples would teach
    (:func:`spco.model.question_scores.question_scores` on the home's state).

    The inputs: the concept posterior P(l | x_i, v_i) of every sample as ``what`` answers it (the room
    account, :func:`spco.model.confidence.answer_concepts`); each concept's distribution over the
    usable names (θ^w of the home);
    the *unnamed* concepts — those the knowledge does not use (G_0 below
    :data:`~spco.model.home_shard.FREE_CONCEPT_WEIGHT`) holding no sample taught in this home, and
    those whose usable names hold less than :data:`NAMELESS_MASS` of their words; the *kind* of each
    sample — its concept if the knowledge uses it, else the used concept whose view distribution in
    this home explains its view best; its region; and whether it was taught a name (a usable word),
    of the home's own (no word the knowledge keeps) or transferred.

    ``criterion``: ``"information"`` or ``"errors"`` (:data:`spco.model.question_scores.CRITERIA`).

    Returns
    -------
    :class:`~spco.model.question_scores.QuestionScores` over the home's ``n`` samples, in the order of
    ``home.ids``.
    """
    if not isinstance(home, HomeModel):
        raise ConfigurationError("ask() expects a HomeModel (from adapt or load_home_model)")
    params, rooms = answer_inputs(home)  # p(name | concept) and the rooms as what answers
    columns = name_columns(home)
    # P(l | x_i, v_i) as `what` answers it (the room account, spco.model.confidence.answer_concepts)
    # (the reference sampler's KL-weighted answer is view by view, as in answer_names)
    concepts = answer_concepts(params, 0, home.positions, home.visual,
                               view_counts=home.hyperparameters.view_weight(),
                               rooms=None if home.weighting == "reference" else rooms,
                               settings=home.hyperparameters.answer_settings())
    theta = np.clip(np.asarray(params.word_probabilities[0], dtype=np.float64), 0.0, None)  # (L, V)
    mass = theta[:, columns].sum(axis=1)
    names = np.divide(theta[:, columns], mass[:, None], out=np.zeros((theta.shape[0], columns.size)),
                      where=mass[:, None] > 0)
    nameless = mass < NAMELESS_MASS * np.maximum(theta.sum(axis=1), np.finfo(float).tiny)
    names[nameless] = 0.0

    state = home.state
    words = sp.csr_array(home.data.words, dtype=np.float64)
    sentence = np.array([s is not None for s in home.sentences], dtype=bool)
    said = np.asarray((words[:, columns] > 0).astype(np.float64).todense()) if columns.size else \
        np.zeros((home.n_samples, 0))
    said[~sentence] = 0.0
    totals = said.sum(axis=1, keepdims=True)
    taught_names = np.divide(said, totals, out=np.zeros_like(said), where=totals > 0)
    taught = totals[:, 0] > 0
    n_concepts = home.knowledge.n_concepts
    used = np.exp(np.asarray(home.knowledge.log_g0, dtype=np.float64)) >= FREE_CONCEPT_WEIGHT
    held_taught = np.bincount(state.concepts[taught], minlength=n_concepts) > 0
    unnamed = (~used & ~held_taught) | nameless

    known = np.zeros(len(home.vocabulary), dtype=bool)
    k = home.n_knowledge_words
    channels = home.knowledge.channels  # the knowledge's names: the channels' or the words it kept
    known[:k] = np.asarray((home.knowledge.word_mask if channels is None else channels.name_mask())[:k], bool)
    taught_own = taught & ~(said[:, known[columns]] > 0).any(axis=1)

    kinds = np.asarray(state.concepts, dtype=np.int64).copy()
    if used.any():
        away = ~used[kinds]
        if away.any():
            log_theta_v = np.log(np.maximum(np.asarray(params.visual_probabilities[0], dtype=np.float64),
                                            np.finfo(float).tiny))[used]
            views = sp.csr_array(home.visual, dtype=np.float64)[np.flatnonzero(away)]
            fit = np.asarray(views @ log_theta_v.T)
            kinds[away] = np.flatnonzero(used)[np.argmax(fit, axis=1)]
    fits, fit_range = _view_fits(home)
    return question_scores(concepts, names, unnamed, kinds, state.regions, home.positions[:, :2],
                           taught_names, taught_own, criterion=criterion, view_fits=fits, fit_range=fit_range)


def _view_fits(home: HomeModel) -> tuple[np.ndarray, tuple[float, float] | None]:
    """Each sample's view fit under the knowledge's visual mixture (nats per count better than a
    uniform guess, :func:`spco.model.view_fit.view_fit` for one view; NaN for a sample without a
    view), and ``(normal, foreign)`` from the knowledge's record of its experienced homes: the lowest
    of their fits, and the level below which it is taken not to fit a home (``warn_below``); ``None``
    for a knowledge without that record."""
    from scipy.special import logsumexp

    knowledge = home.knowledge
    counts = sp.csr_array(home.visual, dtype=np.float64)
    totals = np.asarray(counts.sum(axis=1)).ravel()
    log_phi = np.maximum(np.asarray(knowledge.log_phi_visual, dtype=np.float64), np.log(np.finfo(float).tiny))
    mixture = logsumexp(np.asarray(counts @ log_phi.T) + np.asarray(knowledge.log_g0)[None, :], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        fits = np.where(totals > 0, mixture / totals + np.log(log_phi.shape[1]), np.nan)
    record = knowledge.provenance.get("view_fit")
    homes = [float(v) for v in ((record or {}).get("homes") or {}).values() if v is not None] \
        if isinstance(record, dict) else []
    warn = record.get("warn_below") if isinstance(record, dict) else None
    if not homes or warn is None or not min(homes) > float(warn):
        return fits, None
    return fits, (min(homes), float(warn))


def _kind_name(home: HomeModel, columns: np.ndarray, kind: int) -> str:
    """The name the knowledge gives a kind of place: its concept's most probable usable name."""
    log_phi = np.asarray(home.knowledge.log_phi_words, dtype=np.float64)[kind, columns]
    return str(home.vocabulary.words[int(columns[np.argmax(log_phi)])]) if columns.size else f"concept {kind}"


def _reason(home: HomeModel, scores: QuestionScores, columns: np.ndarray, row: int,
            answered: list[tuple[str, float]] | None = None) -> str:
    """Why asking at sample ``row`` teaches what it does, in words; ``answered``: the names ``what``
    answers there with their probabilities, best first (default: the scores' own)."""
    words = home.vocabulary.words

    def top(p: np.ndarray) -> list[tuple[str, float]]:
        order = np.argsort(-p, kind="stable")[:2]
        return [(str(words[int(columns[j])]), float(p[j])) for j in order if p[j] > 0.005]

    def said(pairs: list[tuple[str, float]]) -> str:
        return ", ".join(f"{w} {q:.2f}" for w, q in pairs)

    if scores.taught[row]:
        return "already taught here"
    room = scores.rooms[row]
    in_room = (scores.rooms == room) & ~scores.taught
    kind = int(scores.room_kinds[room])
    kind_name = _kind_name(home, columns, kind)
    rho = float(scores.own_name[row])
    here = top(scores.model_probabilities[row]) if answered is None else \
        [(w, q) for w, q in answered[:2] if q > 0.005]
    if float(scores.novelty[row]) >= 0.5:
        return (f"no experienced home has a place that looks like this: the knowledge explains this room's "
                f"views by {float(scores.room_fit[room]):.2f} nats per count better than a uniform guess, "
                f"less than in any experienced home (a name of its own: p {rho:.2f})")
    if float(scores.unnamed[row]) >= 0.5:
        room_taught = (scores.taught & (scores.rooms == room)).any()
        if float(scores.unnamed[in_room].mean()) >= 0.5 and not room_taught:
            return (f"no experienced home has a place that looks like this: its {int(in_room.sum())} samples "
                    f"are learnt as a place of this home alone, and nobody has named it yet (it looks most "
                    f"like a {kind_name})")
        return (f"nobody has named this part of the room yet: its views are learnt as a place of this home "
                f"alone (the room looks most like a {kind_name})")
    taught_here = top(scores.room_names[room])
    if taught_here and here and here[0][0] not in {w for w, _ in taught_here}:
        return (f"this room was taught {taught_here[0][0]!r}, but the robot would answer {here[0][0]!r} here "
                f"({said(here[:1])})")
    if len(here) == 2 and here[1][1] >= _COMPETING * here[0][1]:
        return f"two concepts compete here: {said(here)}"
    room_names = here  # the numbers of `what` at this sample, as the answer line prints them
    if rho >= _OWN_NAME_REASON and float(scores.own_answers[kind]) > 0:
        own_rows = np.flatnonzero(scores.taught & (scores.kinds == kind))
        examples = sorted({w for i in own_rows for w in home.vocabulary.tokenize(home.sentences[i])
                           if (k := home.vocabulary.index(w)) is not None and k >= home.n_knowledge_words})
        named = ", ".join(examples[:3]) or "names of their own"
        return (f"rooms like this {kind_name} had names of their own here ({named}): this one's name may be "
                f"its own too (p {rho:.2f})")
    n_rooms = int(scores.rooms_of_kind[kind])
    if rho >= _OWN_NAME_REASON and n_rooms >= 2:
        return (f"the home has {n_rooms} rooms that look like a {kind_name}: people often tell such rooms "
                f"apart by name (a name of its own: p {rho:.2f})")
    if room_names and room_names[0][1] >= 0.9:
        return f"already known: {said(room_names[:1])} (an answer would confirm it)"
    return f"the model is unsure of this room's name: {said(room_names or here)}"


def ask(home: HomeModel, n: int = 5, criterion: str = DEFAULT_CRITERION, unsure_only: bool = False,
        unsure_below: float = UNSURE_BELOW) -> list[Question]:
    """The ``n`` places of ``home`` where an answer to "what is this place?" teaches the most.

    Candidates are the home's recorded samples without a name taught (a sample taught a sentence
    naming no place stays a candidate). Each is scored by the expected information of the answer
    about the names of the home's places (:mod:`spco.model.question_scores`): the answer's entropy under the
    current posterior — concepts that compete there, a place nobody named that no experienced home
    had, the chance that the room has a name of its own — summed over the samples of its room,
    which the answer names. One question per room comes first, best room first, each at the room's
    most uncertain and most central sample.

    Parameters
    ----------
    home: the home (from :func:`~spco.knowledge.adapt`, :func:`~spco.knowledge.teach` or a home file).
    n: how many questions (≥ 1); fewer if fewer samples are untaught.
    criterion: ``"information"`` (expected information, nats) or ``"errors"`` (expected wrong
        answers corrected); default :data:`DEFAULT_CRITERION`.
    unsure_only: list only the questions worth asking (``worth_asking``: the robot's confidence in
        the answer it expects is below ``unsure_below``); an empty list says "nothing worth asking".
    unsure_below: the threshold of ``worth_asking`` (default :data:`UNSURE_BELOW`).

    Returns
    -------
    list of :class:`Question`, best first. Raises :class:`~spco.errors.ConfigurationError` for a bad
    ``n`` or something that is not a home.
    """
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ConfigurationError(f"the number of questions must be an integer >= 1, got {n!r}")
    if isinstance(unsure_below, bool) or not isinstance(unsure_below, int | float | np.floating) \
            or not 0.0 <= float(unsure_below) <= 1.0:
        raise ConfigurationError(f"unsure_below must be a probability within 0..1, got {unsure_below!r}")
    scores = home_question_scores(home, criterion)
    rows, gains = rank_questions(scores)
    confidence = scores.probabilities.max(axis=1, initial=0.0)
    if unsure_only:
        keep = confidence[rows] < float(unsure_below)
        rows, gains = rows[keep], gains[keep]
    columns = name_columns(home)
    rows, gains = rows[: int(n)], gains[: int(n)]
    # the names and numbers `what` answers at each asked sample, with its view: the one predictor
    # (the scores' p(w | x, v) leaves out the concepts they count unnamed, a share of ~1e-7 at times)
    said = name_prediction(home, home.positions[rows], home.visual[rows], top_k=3) if rows.size else None
    questions = []
    for i, (row, gain) in enumerate(zip(rows, gains, strict=True)):
        answered = [(str(w), float(q)) for w, q in zip(said.words[i], said.probabilities[i], strict=True)
                    if q > 0]
        x, y, s, c = (float(v) for v in home.positions[row])
        questions.append(Question(
            id=int(home.ids[row]), x=x, y=y, theta=float(np.arctan2(s, c)), gain=float(gain),
            reason=_reason(home, scores, columns, int(row), answered),
            names=tuple(answered),
            unknown=float(scores.unknown[row]), room=int(scores.rooms[row]),
            confidence=float(confidence[row]), worth_asking=bool(confidence[row] < float(unsure_below)),
            own_name=float(scores.own_name[row])))
    return questions
