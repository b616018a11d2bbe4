"""Teaching a home: new sentences and observations, a local update from the home's current state
(:func:`teach`, :mod:`spco.model.local_update`; a home adapted with ``joint=True`` or with the
reference sampler resumes one :class:`~spco.model.home_shard.NewHomeShard` instead), within the
home's limits (:mod:`spco.knowledge.limits`)."""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from scipy.special import logsumexp

from spco.errors import ConfigurationError
from spco.knowledge.home import HomeModel, Observation, _copy_state
from spco.knowledge.knowledge import DEFAULT_TEACH_SWEEPS
from spco.knowledge.limits import DEFAULT_LIMITS, TeachingLimits, check_sentences
from spco.knowledge.requests import clean_sentence
from spco.knowledge.views import _pose, _visual_row, view_counts
from spco.model.home_shard import NewHomeShard, init_new_words, prepare_home
from spco.model.local_update import teach_locally
from spco.model.seeds import as_generator, seed_of
from spco.timestamps import utc_now


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

    The update is local (:mod:`spco.model.local_update`): the taught place changes, and the rest of
    the home only where the new evidence demands it; a concept or region the teaching does not
    touch answers exactly as before. The same home, teaching and seed give the same home.

    New words grow the vocabulary (:meth:`Knowledge.extended`); everything learnt so far is kept:
    the sweeps start from the home's assignments and parameters, with the shared part fixed (or
    learnt with the knowledge as prior if the home was adapted with ``joint=True``).
    """
    sentences, observations = _checked_teaching(home, sentences, observations, n_sweeps, limits)
    start = time.perf_counter()
    new_sentences = _taught_sentences(home, sentences)
    ids, poses, rows, no_view = _new_samples(home, observations, new_sentences)
    positions = np.vstack([home.positions, *poses]) if poses else home.positions
    visual = home.visual
    view_missing = np.concatenate([home.view_missing, np.array(no_view, dtype=bool)])
    if rows:
        visual = sp.csr_array(sp.vstack([home.visual, *rows], format="csr"), dtype=np.int64)

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
    provenance["last_teach"] = {"sentences": len(sentences), "observations": len(observations),
                                "new_words": list(knowledge.vocabulary.words[home.knowledge.n_words:]),
                                "n_sweeps": int(n_sweeps), "seed": seed_of(random_state),
                                "seconds": round(time.perf_counter() - start, 4)}
    return replace(home, knowledge=knowledge, state=state, ids=np.asarray(ids, dtype=np.int64),
                   positions=positions, visual=visual, sentences=tuple(new_sentences), provenance=provenance,
                   posterior=posterior, view_missing=view_missing)


def _checked_teaching(home: HomeModel, sentences: Mapping[int, str | None] | None,
                      observations: Sequence[Observation], n_sweeps: int,
                      limits: TeachingLimits | None) -> tuple[dict, list]:
    """The teaching's sentences (a dict) and observations (a list), checked: a home, a number of
    sweeps, something to teach, and words within ``limits``."""
    if not isinstance(home, HomeModel):
        raise ConfigurationError("teach() expects a HomeModel (from adapt or load_home_model)")
    if not isinstance(n_sweeps, int | np.integer) or n_sweeps < 0:
        raise ConfigurationError(f"n_sweeps must be an integer >= 0, got {n_sweeps!r}")
    sentences = dict(sentences or {})
    observations = list(observations)
    if not sentences and not observations:
        raise ConfigurationError("nothing to teach: give a sentence for a sample or a new observation")
    said = [s for s in sentences.values() if isinstance(s, str)]
    said += [o.sentence for o in observations if isinstance(o, Observation) and isinstance(o.sentence, str)]
    check_sentences(home.vocabulary, home.n_knowledge_words, said, limits)
    return sentences, observations


def _taught_sentences(home: HomeModel, sentences: Mapping[int, str | None]) -> list[str | None]:
    """The home's sentences with those of ``sentences`` (sample id -> sentence, cleaned; ``None``
    or "" forgets it) in place; an unknown or non-integer id is a clear error."""
    new_sentences = list(home.sentences)
    index = {int(i): k for k, i in enumerate(home.ids)}
    for sample_id, sentence in sentences.items():
        if isinstance(sample_id, bool) or not isinstance(sample_id, int | np.integer):
            raise ConfigurationError(f"sample ids are integers, got {sample_id!r}")
        if int(sample_id) not in index:
            shown = ", ".join(str(i) for i in home.ids[:5])
            raise ConfigurationError(f"home {home.name!r} has no sample with id {sample_id} (its "
                                     f"{home.n_samples} training samples have ids {shown}"
                                     f"{', …' if home.n_samples > 5 else ''}, up to {int(home.ids.max())})")
        new_sentences[index[int(sample_id)]] = clean_sentence(sentence, None)
    return new_sentences


def _new_samples(home: HomeModel, observations: list, new_sentences: list) -> tuple[list, list, list, list]:
    """The observations as new samples: every id (the home's, then the new ones: given, or the
    next free), their poses, visual count rows and whether each had no view; their sentences are
    appended to ``new_sentences``."""
    ids = list(home.ids.tolist())
    taken = set(ids)
    poses, rows, no_view = [], [], []
    for obs in observations:
        if not isinstance(obs, Observation):
            raise ConfigurationError(f"observations must be Observation objects, got {type(obs).__name__}")
        new_id = max(taken) + 1 if obs.id is None else int(obs.id)
        if new_id in taken:
            raise ConfigurationError(f"home {home.name!r} already has a sample with id {new_id}")
        taken.add(new_id)
        ids.append(new_id)
        poses.append(_pose(obs.x, obs.y, obs.theta))
        counts = view_counts(home.knowledge, obs.visual, obs.image, obs.encoding)
        no_view.append(counts is None)
        rows.append(_visual_row(counts, home.knowledge.n_features))
        new_sentences.append(clean_sentence(obs.sentence, None))
    return ids, poses, rows, no_view


def _grown_state(home: HomeModel, knowledge, local: bool, n_new_samples: int):
    """A copy of the home's state grown to the extended ``knowledge``'s new words (their φ^w and
    θ^w entries at the prior, the knowledge's φ^w for a home that does not learn its own) and to
    ``n_new_samples`` new samples (concept and region 0 until the sweeps draw them)."""
    state = _copy_state(home.state)
    if knowledge.channels is not None:  # the channels of the grown vocabulary (fixed, like φ)
        state.channels = knowledge.channels.channels
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
