"""Teaching a home: new sentences and observations, a local update from the home's current state
(:func:`teach`, :mod:`spco.model.local_update`; a home adapted with ``joint=True`` or with the
reference sampler resumes one :class:`~spco.model.home_shard.NewHomeShard` instead), within the
home's limits (:mod:`spco.knowledge.limits`)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.errors import ConfigurationError, ConflictError, NotFoundError
from spco.knowledge.home import HomeModel, Observation, _copy_state
from spco.knowledge.knowledge import DEFAULT_TEACH_SWEEPS
from spco.knowledge.limits import DEFAULT_LIMITS, TeachingLimits, check_sentences
from spco.knowledge.requests import Pose, Teach, View
from spco.knowledge.views import _visual_row, pose_outside_map, view_counts
from spco.model.home_place import grown_home_place
from spco.model.home_shard import NewHomeShard, init_new_words, prepare_home
from spco.model.local_update import teach_locally
from spco.model.seeds import as_generator, seed_of
from spco.timestamps import utc_now

if TYPE_CHECKING:
    from spco.features import Extractor


def carried_switches(old: sp.csr_array, switches: np.ndarray | None, new: sp.csr_array,
                     rows: list[int]) -> np.ndarray:
    """The word channels' switches of the tokens of ``new`` (a home's word counts after a teaching):
    the switch each token of the unchanged sample ``rows`` had in ``old`` (same row, same word), −1
    (to draw) for every other token. ``switches``: (nnz of ``old``,) or ``None`` (all −1)."""
    out = np.full(new.nnz, -1, dtype=np.int8)
    if switches is None or switches.shape != (old.nnz,):
        return out
    for r in rows:  # a loop over the home's samples with a sentence
        a, b = int(old.indptr[r]), int(old.indptr[r + 1])
        c, d = int(new.indptr[r]), int(new.indptr[r + 1])
        if b > a and b - a == d - c and np.array_equal(old.indices[a:b], new.indices[c:d]):
            out[c:d] = switches[a:b]
    return out


def teach(
    home: HomeModel,
    sentences: Mapping[int, str | None] | None = None,
    observations: Sequence[Observation] = (),
    n_sweeps: int = DEFAULT_TEACH_SWEEPS,
    random_state: int | np.random.Generator | None = None,
    limits: TeachingLimits | None = DEFAULT_LIMITS,
) -> HomeModel:
    """Teach the home: new sentences for known samples, new observations; an incremental update.

    Parameters
    ----------
    home: the home model to update (it is not modified: a new one is returned).
    sentences: sample id -> sentence (``None`` or ``""`` forgets the sentence of that sample).
    observations: new samples (:class:`Observation`), appended with new ids.
    n_sweeps: Gibbs sweeps of the part of the home the teaching affects, from the home's current
        state (10 by default, a few tens of milliseconds); prediction then uses the average of the
        last of them (:func:`~spco.model.posterior.thinned_sweeps`) for that part, and the home's
        previous average for the rest.
    random_state: seed or Generator.
    limits: what one teaching may bring (:class:`~spco.knowledge.limits.TeachingLimits`: words per
        sentence, new words, the home's own words); a teaching beyond them is refused whole with a
        :class:`~spco.errors.TeachingLimitError` naming the limit. ``None``: no limits (replaying
        teachings accepted before).

    The library's way in to :func:`teach_requests`: the arguments become checked
    :class:`~spco.knowledge.requests.Teach` requests (an observation's image turned into its counts
    by the knowledge's extractor, :func:`~spco.knowledge.views.view_counts`), taught together.

    The update is local (:mod:`spco.model.local_update`): the taught place changes, and the rest of
    the home only where the new evidence demands it; a concept or region the teaching does not
    touch answers exactly as before. The same home, teaching and seed give the same home.

    New words grow the vocabulary (:meth:`Knowledge.extended`); everything learnt so far is kept:
    the sweeps start from the home's assignments and parameters, with the shared part fixed (or
    learnt with the knowledge as prior if the home was adapted with ``joint=True``).
    """
    if not isinstance(home, HomeModel):
        raise ConfigurationError("teach() expects a HomeModel (from adapt or load_home_model)")
    requests: list[Teach] = []
    for sample_id, sentence in dict(sentences or {}).items():
        if isinstance(sample_id, bool) or not isinstance(sample_id, int | np.integer):
            raise ConfigurationError(f"sample ids are integers, got {sample_id!r}")
        requests.append(Teach(sentence=sentence, id=int(sample_id)))
    for obs in observations:
        if not isinstance(obs, Observation):
            raise ConfigurationError(f"observations must be Observation objects, got {type(obs).__name__}")
        counts = view_counts(home.knowledge, obs.visual, obs.image, obs.encoding)
        requests.append(Teach(sentence=obs.sentence, id=obs.id, pose=Pose(obs.x, obs.y, obs.theta),
                              view=None if counts is None else View(visual=counts)))
    return teach_requests(home, requests, n_sweeps, random_state, limits)[0]


def teach_requests(home: HomeModel, requests: Sequence[Teach], n_sweeps: int = DEFAULT_TEACH_SWEEPS,
                   random_state: int | np.random.Generator | None = None,
                   limits: TeachingLimits | None = DEFAULT_LIMITS, *, on_map: bool = False,
                   extractor: Callable[[], Extractor] | None = None) -> tuple[HomeModel, tuple[Teach, ...]]:
    """The home's one teaching: checked requests (:class:`~spco.knowledge.requests.Teach`), taught together.

    What needs the home is checked here, for the requests together, before anything is learnt: a
    sentence's sample must be known (:class:`~spco.errors.NotFoundError`; a sample added earlier in
    ``requests`` counts), a new observation's ``id`` must be new (:class:`~spco.errors.ConflictError`),
    its view's counts must have the home's visual dimension (an image is turned into counts by the
    knowledge's extractor: ``extractor``, a function giving the one to use, e.g. one the caller
    keeps; :func:`~spco.knowledge.views.view_counts`), its pose must lie on the home's map or at most
    :data:`~spco.knowledge.views.FAR_OUTSIDE_MAP` map sizes off it when ``on_map`` (what a served
    home asks), and the sentences together must keep within ``limits``. Then the home learns
    (see :func:`teach` for ``n_sweeps``, ``random_state`` and the update).

    Returns
    -------
    The taught home, and the requests as applied, in order: a new observation with the ``id`` it got
    and its view as its validated (1, D) count row (``view=None``: no view); what a journal records
    so that the same call on the same home gives the same home again.
    """
    if not isinstance(home, HomeModel):
        raise ConfigurationError("teach() expects a HomeModel (from adapt or load_home_model)")
    if isinstance(n_sweeps, bool) or not isinstance(n_sweeps, int | np.integer) or n_sweeps < 0:
        raise ConfigurationError(f"n_sweeps must be an integer >= 0, got {n_sweeps!r}")
    requests = list(requests)
    if not requests:
        raise ConfigurationError("nothing to teach: give a sentence for a sample or a new observation")
    if any(not isinstance(r, Teach) for r in requests):
        raise ConfigurationError("teach_requests() takes Teach requests (spco.knowledge.requests)")
    check_sentences(home.vocabulary, home.n_knowledge_words, [r.sentence for r in requests if r.sentence],
                    limits)
    start = time.perf_counter()
    new_sentences, applied, poses, rows, no_view = _applied_requests(home, requests, on_map, extractor)
    positions = np.vstack([home.positions, *poses]) if poses else home.positions
    visual = home.visual
    view_missing = np.concatenate([home.view_missing, np.array(no_view, dtype=bool)])
    if rows:
        visual = sp.csr_array(sp.vstack([home.visual, *rows], format="csr"), dtype=np.int64)
    ids = np.concatenate([home.ids, np.array([r.id for r in applied if r.observation], dtype=np.int64)])

    knowledge = home.knowledge.extended(new_sentences)
    local = not home.joint and knowledge.variant == "exact"
    state = _grown_state(home, knowledge, local, len(poses))
    data = prepare_home(positions, visual, new_sentences, knowledge.vocabulary, knowledge.word_increment,
                        home.position_scale, home.map_centre, view_missing)
    if knowledge.channels is not None:  # the untouched sentences keep their tokens' switches
        unchanged = [k for k in range(home.n_samples) if new_sentences[k] == home.sentences[k]]
        state.switches = carried_switches(home.data.words, home.state.switches, data.words, unchanged)
    posterior = _updated_posterior(home, knowledge, data, state, new_sentences, local, int(n_sweeps),
                                   random_state)
    provenance = dict(home.provenance)
    provenance["teach_updates"] = int(provenance.get("teach_updates", 0)) + 1
    provenance["updated"] = utc_now()
    provenance["last_teach"] = {"sentences": sum(not r.observation for r in requests),
                                "observations": len(poses),
                                "new_words": list(knowledge.vocabulary.words[home.knowledge.n_words:]),
                                "n_sweeps": int(n_sweeps), "seed": seed_of(random_state),
                                "seconds": round(time.perf_counter() - start, 4)}
    taught = replace(home, knowledge=knowledge, state=state, ids=ids, positions=positions, visual=visual,
                     sentences=tuple(new_sentences), provenance=provenance, posterior=posterior,
                     view_missing=view_missing)
    return taught, tuple(applied)


def _applied_requests(home: HomeModel, requests: list[Teach], on_map: bool,
                      extractor: Callable[[], Extractor] | None) -> tuple[list[str | None], list[Teach], list,
                                                                          list, list]:
    """The home's sentences with the requests' in place and the new observations' appended, the
    requests as applied (new ids given, views as count rows), and the new samples' poses, count
    rows and whether each had no view."""
    new_sentences: list[str | None] = list(home.sentences)
    index = {int(i): k for k, i in enumerate(home.ids)}
    applied: list[Teach] = []
    poses, rows, no_view = [], [], []
    for request in requests:
        if not request.observation:
            row = index.get(int(request.id))  # type: ignore[arg-type]
            if row is None:
                shown = ", ".join(str(i) for i in home.ids[:5])
                raise NotFoundError(f"home {home.name!r} has no sample with id {request.id} (its "
                                    f"{home.n_samples} samples have ids {shown}"
                                    f"{', …' if home.n_samples > 5 else ''}, up to {int(home.ids.max())}); "
                                    "teach a new place by its pose instead")
            new_sentences[row] = request.sentence
            applied.append(request)
            continue
        new_id = max(index) + 1 if request.id is None else int(request.id)
        if new_id in index:
            raise ConflictError(f"home {home.name!r} already has a sample with id {new_id}")
        pose = request.pose
        assert pose is not None  # an observation has a pose
        if on_map:
            pose_outside_map(home, pose.x, pose.y)  # raises for a pose far off the map
        view = request.view
        counts = None if view is None else view_counts(home.knowledge, view.visual, view.image, view.encoding,
                                                       extractor)
        row = _visual_row(counts, home.knowledge.n_features)
        index[new_id] = len(new_sentences)
        new_sentences.append(request.sentence)
        poses.append(pose.row())
        rows.append(row)
        no_view.append(counts is None)
        applied.append(Teach(sentence=request.sentence, id=new_id, pose=pose,
                             view=None if counts is None else View(visual=row)))
    return new_sentences, applied, poses, rows, no_view


def _grown_state(home: HomeModel, knowledge, local: bool, n_new_samples: int):
    """A copy of the home's state grown to the extended ``knowledge``'s new words (their φ^w and
    θ^w entries at the prior, the knowledge's φ^w for a home that does not learn its own) and to
    ``n_new_samples`` new samples (concept and region 0 until the sweeps draw them)."""
    state = _copy_state(home.state)
    if knowledge.channels is not None:  # the channels of the grown vocabulary (fixed, like φ), with the
        channels = knowledge.channels.channels  # home's own ψ_{e,l} kept (place_channel="home"), grown
        held = None if home.state.channels is None else home.state.channels.log_place_home
        state.channels = replace(channels, log_place_home=grown_home_place(held, channels.log_place))
    added = knowledge.n_words - home.knowledge.n_words
    if added:
        hyper = knowledge.hyperparameters
        log_new = math.log(hyper.alpha_word / hyper.delta_word)
        L = knowledge.n_concepts
        if home.joint or local:  # the home's φ^w (learnt, or a free concept's): grown like the knowledge's
            phi_w = np.concatenate([state.log_phi_w, np.full((L, added), log_new)], axis=1)
            state.log_phi_w = phi_w - logsumexp(phi_w, axis=1, keepdims=True)
        else:
            state.log_phi_w = knowledge.log_phi_words.copy()
        state.log_theta_w = np.concatenate([state.log_theta_w, np.full((1, L, added), log_new)], axis=2)
        said = np.bincount(home.state.concepts, weights=np.asarray(home.data.words.sum(axis=1)).ravel(),
                           minlength=L)
        init_new_words(state, home.knowledge.n_words, said, hyper.delta_word)
        state.word_mask = np.concatenate([state.word_mask, np.ones(added, dtype=bool)])
    if n_new_samples:
        state.concepts = np.concatenate([state.concepts, np.zeros(n_new_samples, dtype=np.int64)])
        state.regions = np.concatenate([state.regions, np.zeros(n_new_samples, dtype=np.int64)])
    return state


def _updated_posterior(home: HomeModel, knowledge, data, state, new_sentences: list, local: bool,
                       n_sweeps: int, random_state):
    """The sweeps of the teaching from ``state`` (updated in place) and the home's new posterior
    average: a local update of the samples taught and added (:func:`teach_locally`), or, for a home
    adapted with ``joint=True`` or the reference sampler, the whole home resumed
    (:class:`NewHomeShard`)."""
    if local:  # a local update: the taught place changes, the rest of the home only where it must
        n_old = home.n_samples
        taught = [k for k in range(n_old) if new_sentences[k] != home.sentences[k]]
        new_rows = np.arange(n_old, len(new_sentences))
        return teach_locally(data, state, knowledge.shared_part(), home.n_knowledge_words,
                             np.concatenate([np.asarray(taught, dtype=np.int64), new_rows]), new_rows,
                             n_sweeps, as_generator(random_state), home.posterior, home.name)
    prior = None
    if home.joint:
        prior = knowledge.shared_prior()
        state.candidate_words = knowledge.word_mask[: home.n_knowledge_words].copy()
        state.candidate_words = np.concatenate([state.candidate_words,
                                                np.ones(knowledge.n_words - home.n_knowledge_words, bool)])
    shard = NewHomeShard(data, state, knowledge.shared_part(), home.n_knowledge_words,
                         as_generator(random_state), prior)
    shard.begin()  # a taught name counts at once
    shard.run(n_sweeps)
    return shard.finish(home.name)
