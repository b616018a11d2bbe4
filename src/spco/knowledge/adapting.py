"""Adapting knowledge to a new home: the home learnt with the knowledge as its prior
(:func:`adapt`), one :class:`~spco.model.home_shard.NewHomeShard` run from its first state.

*Adapting* runs the exact conditionals of the model for the new home alone with φ^v, φ^w and G_0
fixed at the knowledge (``SamplerSettings.create(variant, prune, learn_shared=False)``): this is the
model's posterior of the home given the shared part, which is what joint learning computes for the
new home when the experienced homes pin the shared part down. With ``joint=True`` the shared part
is learnt too, with the knowledge as its prior: the posterior of φ_l given the experienced homes is
approximated by a Dirichlet with the knowledge's mean and a concentration A_l moment-matched to the
spread of the averaged posterior samples (``A_l + 1 = Σ_k φ̄_k(1 − φ̄_k) / Σ_k Var φ_k``), so
``φ_l | new home ~ Dir(A_l φ̄_l + table counts of the new home)`` (the same for G_0). This is
assumed-density filtering: exact if that posterior were Dirichlet. With few samples the spread is
poorly known, so it is shrunk towards the spread of Dir(δ φ̄_l) — the spread of one home's θ_{e,l}
around φ_l, concentration δ^v, δ^w (γ for G_0) — with the weight of
:data:`~spco.knowledge.fit.CONCENTRATION_PRIOR_SAMPLES` samples
(:func:`spco.knowledge.fit._concentration`): one sample gives exactly δ, many give the
moment-matched value, and every number of samples in between lies between them (no cliff).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from spco.data.environment import Environment, TrainingData
from spco.errors import ConfigurationError, DataFormatError
from spco.knowledge.diagnostics import ExperiencedHomeWarning, check_view_fit
from spco.knowledge.files import _version
from spco.knowledge.home import HomeModel
from spco.knowledge.knowledge import DEFAULT_ADAPT_ITERATIONS, Knowledge
from spco.model import gibbs
from spco.model.home_shard import NewHomeShard, prepare_home
from spco.model.seeds import as_generator, seed_of
from spco.timestamps import utc_now


def _map_centre(home: Environment) -> np.ndarray:
    centre = np.zeros(4)
    if home.extent is not None:
        x0, x1, y0, y1 = home.extent
        centre[:2] = ((x0 + x1) / 2, (y0 + y1) / 2)
    else:
        centre[:2] = home.training_data().positions[:, :2].mean(0)
    return centre


def _check_visual_dimension(knowledge: Knowledge, n_features: int, where: str) -> None:
    if n_features != knowledge.n_features:
        raise DataFormatError(where, f"visual features have {n_features} dimensions but the knowledge "
                              f"needs {knowledge.n_features}: knowledge transfers only between homes whose "
                              f"views come from the same feature extractor; compute this home's views with "
                              f"the extractor of the experienced homes (e.g. CaffeNet fc7, 4096 values per "
                              f"view, for the SIGVerse knowledge), or fit knowledge on homes recorded like "
                              f"this one (spco fit)")


def _views_for(knowledge: Knowledge, train: TrainingData, where: str) -> TrainingData:
    """The training samples with views of the knowledge's dimension: a home without any view is
    widened to it (every view missing); for knowledge learnt without views (``D = 0``) the home's
    views are left out, with a warning."""
    if train.visual.shape[1] == knowledge.n_features:
        return train
    if train.view_missing.all() and train.visual.nnz == 0:
        return replace(train, visual=sp.csr_array((train.n_samples, knowledge.n_features), dtype=np.int64))
    if knowledge.n_features == 0:
        warnings.warn(f"{where}: the knowledge was learnt from homes without views, so this home's views "
                      "are left out (it is learnt from its poses and words)", NoViewsWarning, stacklevel=3)
        return replace(train, visual=sp.csr_array((train.n_samples, 0), dtype=np.int64),
                       view_missing=np.ones(train.n_samples, dtype=bool))
    return train  # a mismatch: refused by _check_visual_dimension


class NoViewsWarning(UserWarning):
    """Views given to knowledge learnt without views: they are left out."""


def adapt(
    knowledge: Knowledge,
    home: Environment,
    n_iterations: int = DEFAULT_ADAPT_ITERATIONS,
    random_state: int | np.random.Generator | None = None,
    joint: bool = False,
    progress: bool = False,
    provenance: Mapping[str, Any] | None = None,
) -> HomeModel:
    """Learn the new home ``home`` (its training samples) with ``knowledge`` as its prior.

    The home's regions, π, G_e, θ and the concept and region assignments of its samples are learnt
    by ``n_iterations`` Gibbs sweeps of the knowledge's sampler with the shared part fixed, or with
    ``joint=True`` learnt too, the knowledge as its prior (module docstring). Words of the home's
    sentences that the knowledge does not know are added to the vocabulary.

    Returns a :class:`HomeModel`; ``provenance`` records the knowledge's checksum and homes, the
    seed, the iterations and the time taken (``adapt_seconds``).
    """
    if not isinstance(knowledge, Knowledge):
        raise ConfigurationError("adapt() expects a Knowledge (from fit_knowledge or load_knowledge)")
    if not isinstance(home, Environment):
        raise ConfigurationError("adapt() expects a spco.data.Environment (one home)")
    if not isinstance(n_iterations, int | np.integer) or n_iterations < 1:
        raise ConfigurationError(f"n_iterations must be an integer >= 1, got {n_iterations!r}")
    start = time.perf_counter()
    train = home.training_data()
    if train.n_samples == 0:
        raise ConfigurationError(f"home {home.name!r} has no training samples to adapt to")
    train = _views_for(knowledge, train, home.source or home.name)
    _check_visual_dimension(knowledge, train.visual.shape[1], home.source or home.name)
    fit_of_views = check_view_fit(knowledge, train.visual, home.name)
    if home.name in (knowledge.provenance.get("homes") or []):
        warnings.warn(f"home {home.name!r} has the name of a home this knowledge was learnt from: if it is "
                      "that home, it is not new to the knowledge and its answers say little about a new "
                      "home (spco synth: write new homes with another --seed than the experienced ones)",
                      ExperiencedHomeWarning, stacklevel=2)
    # concepts for the home's own names (names the experienced homes never said), then its new words
    rng = as_generator(random_state)
    extended = knowledge.with_free_concepts().extended(train.sentences)
    n_known = knowledge.n_words
    scale = gibbs.CM_PER_M if extended.variant == "reference" else 1.0
    centre = _map_centre(home)
    data = prepare_home(train.positions, train.visual, train.sentences, extended.vocabulary,
                        extended.word_increment, scale, centre, train.view_missing)
    shard = NewHomeShard.start(data, extended.shared_part(), n_known, rng,
                               prior=extended.shared_prior() if joint else None)
    iterator: Iterable[int] = range(int(n_iterations))
    if progress:
        from spco.progress import progress_bar

        iterator = progress_bar(iterator, desc=f"adapt {home.name}", unit="sweep", leave=False)
    shard.begin()
    shard.run(int(n_iterations), iterator)
    posterior = shard.finish(home.name)
    seconds = time.perf_counter() - start
    record: dict[str, Any] = {
        "knowledge_checksum": knowledge.checksum,
        "knowledge_homes": list(knowledge.provenance.get("homes") or []),
        "adapt": {"seed": seed_of(random_state), "n_iterations": int(n_iterations), "joint": bool(joint),
                  "seconds": round(seconds, 3), "new_words": list(extended.vocabulary.words[n_known:])},
        "teach_updates": 0,
        "view_fit": fit_of_views,
        "spco_version": _version(),
        "created": utc_now(),
    }
    record.update(provenance or {})
    return HomeModel(name=home.name, knowledge=extended, state=shard.state, ids=train.ids,
                     positions=train.positions, visual=sp.csr_array(train.visual, dtype=np.int64),
                     sentences=tuple(train.sentences), extent=home.extent, map_centre=centre,
                     n_knowledge_words=n_known, joint=bool(joint), provenance=record,
                     posterior=posterior, view_missing=train.view_missing.copy())


