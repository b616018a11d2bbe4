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

Semantics
---------
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
:data:`CONCENTRATION_PRIOR_SAMPLES` samples (:func:`_concentration`): one sample gives exactly
δ, many give the moment-matched value, and every number of samples in between lies between them
(no cliff).

*New words* (a word no experienced home used, such as ``emma's-room``) are appended to the
vocabulary; their φ^w_{l,k} is α^w/δ^w in every concept (rows renormalised), so a home's
θ^w_{e,l} ~ Dir(δ^w φ^w_l + n) gives them the prior mass α^w of a word never seen, and they are
learnt from the home's counts. Their θ^w starts at its posterior mean given the current
assignments (:func:`_init_new_words`), so the first samples that say a new word are placed by what
they see and where they are, preferring concepts that hold few words yet. With word pruning
("+MI" models) the words of the knowledge keep its decision and new words are judged in the home
(mutual information of the word and the concept under θ^w_e and G_e, threshold ε) after every
adaptation or teaching: a home-specific name that no other home uses would score low against G_0.

*Teaching* appends or replaces sentences and observations and runs a few sweeps (10 by default)
of the same sampler, starting from the home's current state: everything learnt so far is kept
(about 0.1 s for a SIGVerse home of 260–370 samples).

*Answers* (:func:`where`, :func:`what`) come from the home's parameters averaged over thinned
sweeps of the last adaptation or teaching (``HomeModel.posterior``, :mod:`spco.model.posterior`),
not from the last draw; ``where`` reports ``learnt`` False and a low ``support`` when the name's
probability in the home comes from concepts that hold none of its samples (no such place learnt
in this home).

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
    load_knowledge,
)
from spco.knowledge.queries import (
    WHERE_ANYWHERE_WEIGHT,
    WHERE_MODEL_WEIGHT,
    answer_parameters,
    describe_model_file,
    name_prediction,
    unused_word_hint,
    what,
    where,
)
from spco.knowledge.updating import teach
from spco.knowledge.views import FAR_OUTSIDE_MAP, map_bounds, pose_outside_map, read_visual_vector
from spco.model.home_shard import FREE_CONCEPT_WEIGHT, OWN_NAMES_SPREAD_WARNING, OwnNamesSpreadWarning
from spco.model.view_fit import concept_visual_totals, held_out_view_fits, view_fit

__all__ = [
    "CONCENTRATION_PRIOR_SAMPLES",
    "DEFAULT_ADAPT_ITERATIONS",
    "DEFAULT_FIT_ITERATIONS",
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
    "WHERE_ANYWHERE_WEIGHT",
    "WHERE_MODEL_WEIGHT",
    "ExperiencedHomeWarning",
    "HomeModel",
    "Knowledge",
    "KnowledgeMismatchWarning",
    "Observation",
    "OwnNamesSpreadWarning",
    "Question",
    "adapt",
    "answer_parameters",
    "ask",
    "check_view_fit",
    "concept_visual_totals",
    "describe_model_file",
    "fit_knowledge",
    "held_out_view_fits",
    "load_home_model",
    "load_knowledge",
    "map_bounds",
    "model_file_format",
    "name_prediction",
    "pose_outside_map",
    "read_visual_vector",
    "summary_iterations",
    "teach",
    "unused_word_hint",
    "view_fit",
    "view_fit_warning",
    "what",
    "where",
]
