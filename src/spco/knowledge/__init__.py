"""Knowledge that travels: learn once from experienced homes, adapt to a new home, answer at once.

The paper re-learns every experienced home together with each new one. A robot that arrives in a
new home cannot: it carries what it learnt, adapts on site and answers questions at once. This
package splits the transfer model (Hagiwara et al. 2021, ``docs/model.md``) along its plates:

- :class:`Knowledge` — the shared, home-independent part learnt from experienced homes
  (:func:`fit_knowledge`): the concepts' visual and word distributions φ^v (L, D), φ^w (L, V), the
  global concept weights G_0 (L,), the words kept by pruning, the vocabulary, the hyperparameters
  and the sampler, *summarised over several posterior samples* (the mean of the samples of the last
  quarter of the chain), with a Dirichlet approximation of their posterior spread and provenance.
- :class:`HomeModel` — one home learnt with the knowledge as its prior (:func:`adapt`): its own
  regions (μ, Σ), region weights π, concept weights G_e, θ^v, θ^w, the assignments of its samples,
  and what :func:`teach` needs to update it incrementally (its samples' positions, visual counts and
  sentences).
- :func:`where` (positions for a place name), :func:`what` (place names at a pose) and
  :func:`teach` (new sentences, new observations, new words; a few sweeps from the current state).

What adapting, teaching and answering compute is in the modules that do it:
:mod:`~spco.knowledge.adapting`, :mod:`~spco.knowledge.updating`, :mod:`~spco.knowledge.queries`.

Files
-----
Knowledge and home files are ``.npz`` archives with a JSON header and checksums, written
atomically under a write lock: :mod:`spco.knowledge.files`, :mod:`spco.knowledge.locking`.

Layout
------
:mod:`~spco.knowledge.knowledge` (:class:`Knowledge`), :mod:`~spco.knowledge.home`
(:class:`HomeModel`, :class:`Observation`), :mod:`~spco.knowledge.fit` (:func:`fit_knowledge`),
:mod:`~spco.knowledge.diagnostics` (view fit), :mod:`~spco.knowledge.adapting` (:func:`adapt`),
:mod:`~spco.knowledge.updating` (:func:`teach`), :mod:`~spco.knowledge.queries` (:func:`where`,
:func:`what`), :mod:`~spco.knowledge.asking` (:func:`ask`: where an answer teaches the most),
:mod:`~spco.knowledge.views` (one observation's pose and view, feature files),
:mod:`~spco.knowledge.files` and :mod:`~spco.knowledge.locking`. The sampler of a new home is
:class:`spco.model.home_shard.NewHomeShard`: a shard of one home with the shared part fixed.
"""

from __future__ import annotations

from spco.knowledge.adapting import adapt
from spco.knowledge.asking import Question, ask
from spco.knowledge.diagnostics import (
    VIEW_FIT_MEASURE,
    VIEW_FIT_WARN_FRACTION,
    ExperiencedHomeWarning,
    KnowledgeMismatchWarning,
    check_view_fit,
    fit_range_text,
    view_fit_warning,
)
from spco.knowledge.files import FORMAT_VERSION, HOME_FORMAT, KNOWLEDGE_FORMAT, model_file_format
from spco.knowledge.fit import CONCENTRATION_PRIOR_SAMPLES, fit_knowledge, summary_iterations
from spco.knowledge.home import HomeModel, Observation, load_home_model
from spco.knowledge.knowledge import (
    DEFAULT_ADAPT_ITERATIONS,
    DEFAULT_FIT_ITERATIONS,
    DEFAULT_MODEL,
    DEFAULT_TEACH_SWEEPS,
    MODELS,
    Knowledge,
    KnowledgeChannels,
    load_knowledge,
)
from spco.knowledge.limits import DEFAULT_LIMITS, TeachingLimits
from spco.knowledge.queries import (
    answer_parameters,
    describe_model_file,
    name_prediction,
    names_at_regions,
    places,
    unused_word_hint,
    what,
    what_request,
    where,
)
from spco.knowledge.updating import teach, teach_requests
from spco.knowledge.views import (
    FAR_OUTSIDE_MAP,
    map_bounds,
    pose_outside_map,
    read_visual_vector,
    view_counts,
)
from spco.model.home_shard import FREE_CONCEPT_WEIGHT, OWN_NAMES_SPREAD_WARNING, OwnNamesSpreadWarning
from spco.model.view_fit import concept_visual_totals, held_out_view_fits, view_fit

__all__ = [
    "CONCENTRATION_PRIOR_SAMPLES",
    "DEFAULT_ADAPT_ITERATIONS",
    "DEFAULT_FIT_ITERATIONS",
    "DEFAULT_LIMITS",
    "DEFAULT_MODEL",
    "DEFAULT_TEACH_SWEEPS",
    "FAR_OUTSIDE_MAP",
    "FORMAT_VERSION",
    "FREE_CONCEPT_WEIGHT",
    "HOME_FORMAT",
    "KNOWLEDGE_FORMAT",
    "MODELS",
    "OWN_NAMES_SPREAD_WARNING",
    "VIEW_FIT_MEASURE",
    "VIEW_FIT_WARN_FRACTION",
    "ExperiencedHomeWarning",
    "HomeModel",
    "Knowledge",
    "KnowledgeChannels",
    "KnowledgeMismatchWarning",
    "Observation",
    "OwnNamesSpreadWarning",
    "Question",
    "TeachingLimits",
    "adapt",
    "answer_parameters",
    "ask",
    "check_view_fit",
    "concept_visual_totals",
    "describe_model_file",
    "fit_knowledge",
    "fit_range_text",
    "held_out_view_fits",
    "load_home_model",
    "load_knowledge",
    "map_bounds",
    "model_file_format",
    "name_prediction",
    "names_at_regions",
    "places",
    "pose_outside_map",
    "read_visual_vector",
    "summary_iterations",
    "teach",
    "teach_requests",
    "unused_word_hint",
    "view_counts",
    "view_fit",
    "view_fit_warning",
    "what",
    "what_request",
    "where",
]
