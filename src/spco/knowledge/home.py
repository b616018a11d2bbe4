"""A home learnt with transferred knowledge (:class:`HomeModel`), its file
(:func:`load_home_model`) and the new observations :func:`spco.knowledge.teach` takes
(:class:`Observation`)."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from spco.data.environment import Environment, Extent
from spco.data.language import Vocabulary
from spco.errors import ModelFileError
from spco.knowledge.files import (
    HOME_FORMAT,
    HOME_PLACE_FORMAT_VERSION,
    _read_archive,
    _require,
    _version,
    _write_archive,
    format_version,
)
from spco.knowledge.knowledge import Knowledge
from spco.model import gibbs
from spco.model.home_place import home_place_mean, home_place_statistics, uses_home_place
from spco.model.home_shard import name_words, prepare_home, switch_tokens
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.name_evidence import extend_prior
from spco.model.parameters import ConceptParameters
from spco.model.transfer import export_parameters
from spco.model.word_channels import channel_parameters


@dataclass(frozen=True)
class Observation:
    """A new observation for :func:`teach`: a pose, the view's visual counts and what was said.

    x, y in metres on the home's map, theta (heading) in radians; visual: (D,) counts (dense array
    or a 1-row sparse matrix); sentence: the user's words, or ``None``; id: the sample id (default:
    one more than the largest id of the home); image: the view as an image (path, file bytes or array
    of pixels) in place of ``visual``, for a home whose knowledge was fitted on images (its extractor
    computes the counts); encoding: an array's colour order (``rgb8``, ``bgr8`` — the default —,
    ``mono8``, ``rgba8``, ``bgra8``; :mod:`spco.features.pixels`).
    With neither ``visual`` nor ``image`` the observation has no view (a camera that dropped the
    frame): it is learnt from its pose and words.
    """

    x: float
    y: float
    theta: float
    visual: Any = None
    sentence: str | None = None
    id: int | None = None
    image: Any = None
    encoding: str | None = None


@dataclass(frozen=True, eq=False)
class HomeModel:
    """One home learnt with transferred knowledge: its parameters, samples and sampler state.

    Attributes
    ----------
    name: the home's name.
    knowledge: the shared part this home was adapted from (with the home's new words appended to
        its vocabulary): the prior of the shared part, and the vocabulary of the home.
    state: the Gibbs sampler's state (one home; sampler units: centimetres for the reference
        sampler), including the current shared part (refined if ``joint``).
    ids: (n,) sample ids of the home's training samples; positions: (n, 4) metres
        ``(x, y, sin θ, cos θ)``; visual: (n, D) sparse counts; sentences: what was taught at each.
    view_missing: (n,) bool, the samples without a view (their rows of ``visual`` are empty);
        ``None``: every sample has one.
    extent: the map extent ``(x_min, x_max, y_min, y_max)`` or ``None``.
    map_centre: (4,) prior mean of the regions, metres.
    n_knowledge_words: how many of the vocabulary's words come from the knowledge (the rest were
        first heard in this home).
    joint: whether the shared part is learnt with the home (``adapt(..., joint=True)``).
    provenance: the knowledge's checksum and provenance, the adaptation and teaching history.
    posterior: the home's parameters averaged over thinned sweeps of the last adaptation or
        teaching (:mod:`spco.model.posterior`), which prediction uses; ``None``: the state's
        own draw is used (no sweep was run).
    """

    name: str
    knowledge: Knowledge
    state: gibbs.GibbsState
    ids: np.ndarray
    positions: np.ndarray
    visual: sp.csr_array
    sentences: tuple[str | None, ...]
    extent: Extent | None
    map_centre: np.ndarray
    n_knowledge_words: int
    joint: bool = False
    provenance: dict[str, Any] = field(default_factory=dict)
    posterior: ConceptParameters | None = None
    view_missing: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = int(np.asarray(self.ids).size)
        missing = np.zeros(n, dtype=bool) if self.view_missing is None \
            else np.asarray(self.view_missing, dtype=bool)
        object.__setattr__(self, "view_missing", missing)

    @property
    def n_views(self) -> int:
        """Number of the home's samples with a view."""
        return int((~self.view_missing).sum())

    # ------------------------------------------------------------------ views
    @property
    def vocabulary(self) -> Vocabulary:
        """The home's vocabulary (the knowledge's words, then the home's new words)."""
        return self.knowledge.vocabulary

    @property
    def hyperparameters(self) -> TransferHyperparameters:
        """The model's hyperparameters."""
        return self.knowledge.hyperparameters

    @property
    def n_samples(self) -> int:
        """Number of the home's samples."""
        return int(self.ids.size)

    @property
    def n_taught(self) -> int:
        """Number of samples with a sentence."""
        return sum(s is not None for s in self.sentences)

    @property
    def weighting(self) -> str:
        """Name weighting for prediction: the authors' KL score for the reference sampler; none with
        the naming rule (exact sampler with pruning: only names are kept, and the name people say
        most at a place comes first — the MI weight would put a name taught once behind names of
        the places around); MI without pruning (it keeps "this" and "is" from being answered)."""
        from spco.model.confidence import answer_weighting

        return answer_weighting(self.knowledge.variant, self.knowledge.prune_words,
                                self.knowledge.hyperparameters.name_answer)

    @property
    def position_scale(self) -> float:
        """Sampler units per metre."""
        return gibbs.CM_PER_M if self.knowledge.variant == "reference" else 1.0

    @functools.cached_property
    def data(self) -> gibbs.PreparedData:
        """The home's samples in the sampler's form."""
        return prepare_home(self.positions, self.visual, self.sentences, self.vocabulary,
                            self.knowledge.word_increment, self.position_scale, self.map_centre,
                            self.view_missing)

    @functools.cached_property
    def parameters(self) -> ConceptParameters:
        """The home's parameters (one home, metres), as prediction uses them: the posterior
        average of the last sweeps (``posterior``), or the state's draw if there is none. With the
        word channels they carry ψ and the switch's prior (``where`` finds a place by its names and
        its place words), and ``word_mask`` holds the words that are names or place words
        (:attr:`said_words`)."""
        params = self.posterior if self.posterior is not None else export_parameters(self.state, self.data)
        prior = extend_prior(self.knowledge.name_prior, self.vocabulary, self.sentences)
        if prior is not None:
            params = replace(params, name_prior=prior)
        if self.knowledge.channels is not None:
            params = replace(params, word_mask=self.said_words,
                             **channel_parameters(self.knowledge.channels.channels, self._place_mean()))
        return params

    def _place_mean(self) -> np.ndarray | None:
        """(L, V) log E[ψ_{e,l} | ψ_l, the home's place tokens] with the place channel's home level
        (:func:`spco.model.home_place.home_place_mean`: the home's own place words, their conditional
        mean given the state's switches, as a fit exports ψ_l's mean given its last sweep); ``None``
        without it (ψ_l, the knowledge's)."""
        hyper, state = self.hyperparameters, self.state
        if not uses_home_place(hyper) or state.channels is None or state.switches is None:
            return None
        counts = home_place_statistics(self.data, state, hyper, 1, self.knowledge.n_concepts)
        return home_place_mean(counts, state.channels.log_place, hyper.delta_place)[0]

    @functools.cached_property
    def channel_tokens(self) -> np.ndarray | None:
        """(V, 3) each word's tokens as name, place word and background word: the knowledge's fit
        plus this home's expected switches (:func:`spco.model.home_shard.switch_tokens`); ``None``
        without the word channels."""
        if self.knowledge.channels is None:
            return None
        return self.knowledge.channels.tokens + switch_tokens(self.data, self.state)

    @functools.cached_property
    def name_mask(self) -> np.ndarray:
        """(V,) bool: the words the home answers as place names. With the word channels: the words
        enough of whose uses (the experienced homes' and this home's, :attr:`channel_tokens`) are
        expected to be names (:func:`spco.model.home_shard.name_words`) — a function word, or an
        object said once ("the fridge is over here"), is never answered; otherwise the words the
        naming rule keeps (``state.word_mask``)."""
        channels = self.knowledge.channels
        if channels is None:
            return np.asarray(self.state.word_mask, dtype=bool)
        return name_words(self.channel_tokens) & np.asarray(self.state.word_mask, bool)

    @functools.cached_property
    def said_words(self) -> np.ndarray:
        """(V,) bool: the words ``where`` looks a place up by — with the word channels, the names and
        the words said mostly as words of a place (objects, activities: "where is the fridge"),
        not the background; otherwise :attr:`name_mask`."""
        if self.knowledge.channels is None:
            return self.name_mask
        tokens = self.channel_tokens
        total = tokens.sum(axis=1)
        said = (total > 0) & (tokens[:, 0] + tokens[:, 1] >= 0.5 * total)
        return (said | self.name_mask) & np.asarray(self.state.word_mask, bool)

    @property
    def known_names(self) -> list[str]:
        """The words the home can answer for (:attr:`name_mask`)."""
        return [w for w, keep in zip(self.vocabulary.words, self.name_mask, strict=True) if keep]

    def environment(self) -> Environment:
        """The home's samples as an :class:`~spco.data.Environment` (all training, no ground truth)."""
        return Environment(name=self.name, ids=self.ids, positions=self.positions, visual=self.visual,
                           sentences=self.sentences, is_test=np.zeros(self.n_samples, dtype=bool),
                           extent=self.extent)

    # ------------------------------------------------------------------ files
    def save(self, path: str | PathLike[str], overwrite: bool = False) -> Path:
        """Write the home file to ``path`` (atomically; an existing file only with ``overwrite``)."""
        s = self.state
        visual = sp.csr_array(self.visual)
        k_arrays, k_header = self.knowledge._arrays_and_header()
        arrays: dict[str, np.ndarray] = {"knowledge." + k: v for k, v in k_arrays.items()}
        arrays.update({
            "ids": np.asarray(self.ids, dtype=np.int64),
            "positions": np.asarray(self.positions, dtype=np.float64),
            "visual_data": visual.data.astype(np.int64),
            "visual_indices": visual.indices.astype(np.int32),
            "visual_indptr": visual.indptr.astype(np.int64),
            "map_centre": np.asarray(self.map_centre, dtype=np.float64),
        })
        if self.view_missing.any():  # (absent: every sample has a view)
            arrays["view_missing"] = np.asarray(self.view_missing, dtype=bool)
        for name in _STATE_ARRAYS:
            arrays["state." + name] = np.asarray(getattr(s, name))
        if s.switches is not None:  # the word channels' switch of every token
            arrays["state.switches"] = np.asarray(s.switches, dtype=np.int8)
        place_home = None if s.channels is None else s.channels.log_place_home
        if place_home is not None:  # the place channel's home level: the home's own ψ_{e,l}
            arrays["state.log_place_home"] = np.asarray(place_home, dtype=np.float64)
        if self.posterior is not None:
            arrays.update({"posterior." + k: np.asarray(v) for k, v in self.posterior.arrays().items()})
        header = {
            "format": HOME_FORMAT,
            "format_version": HOME_PLACE_FORMAT_VERSION if place_home is not None else format_version(
                self.vocabulary, self.knowledge.variant == "exact" and self.knowledge.prune_words),
            "spco_version": _version(),
            "name": self.name,
            "sentences": list(self.sentences),
            "extent": None if self.extent is None else list(self.extent),
            "n_features": int(visual.shape[1]),
            "n_knowledge_words": int(self.n_knowledge_words),
            "joint": bool(self.joint),
            "model": k_header["model"],
            "variant": k_header["variant"],
            "prune_words": k_header["prune_words"],
            "hyperparameters": k_header["hyperparameters"],
            "vocabulary": k_header["vocabulary"],
            "segmentation": k_header["segmentation"],
            "word_increment": k_header["word_increment"],
            "knowledge_provenance": k_header["provenance"],
            "provenance": self.provenance,
            "extractor": k_header["extractor"],
        }
        return _write_archive(path, arrays, header, overwrite, "home file")

    @classmethod
    def load(cls, path: str | PathLike[str]) -> HomeModel:
        """Read a home file written by :meth:`save`; see :func:`load_home_model`."""
        file, header, arrays = _read_archive(path, HOME_FORMAT)
        _require(file, header, arrays, ("name", "sentences", "extent", "n_features", "n_knowledge_words"),
                 ["ids", "positions", "visual_data", "visual_indices", "visual_indptr", "map_centre",
                  *("state." + n for n in _STATE_ARRAYS)])
        k_header = dict(header)
        k_header["provenance"] = header.get("knowledge_provenance") or {}
        knowledge = Knowledge._from_parts(file, k_header, arrays, "knowledge.")
        try:
            n = arrays["ids"].size
            visual = sp.csr_array((arrays["visual_data"], arrays["visual_indices"], arrays["visual_indptr"]),
                                  shape=(n, int(header["n_features"])))
            state = gibbs.GibbsState(**{name: arrays["state." + name] for name in _STATE_ARRAYS})
            if knowledge.channels is not None:
                state.channels = replace(knowledge.channels.channels,  # (absent: none held, ψ_l read)
                                         log_place_home=arrays.get("state.log_place_home"))
                state.switches = arrays.get("state.switches")
            sentences = tuple(None if s is None else str(s) for s in header["sentences"])
            extent = None if header["extent"] is None else tuple(float(v) for v in header["extent"])
            posterior_arrays = {k.removeprefix("posterior."): v for k, v in arrays.items()
                                if k.startswith("posterior.")}
            posterior = ConceptParameters(**posterior_arrays) if posterior_arrays else None
            home = cls(name=str(header["name"]), knowledge=knowledge, state=state, ids=arrays["ids"],
                       positions=arrays["positions"], visual=visual, sentences=sentences,
                       extent=extent, map_centre=arrays["map_centre"],
                       n_knowledge_words=int(header["n_knowledge_words"]), joint=bool(header.get("joint")),
                       provenance=dict(header.get("provenance") or {}), posterior=posterior,
                       view_missing=arrays.get("view_missing"))
        except (TypeError, ValueError, IndexError, KeyError) as exc:
            raise ModelFileError(file, f"inconsistent home file: {exc}") from exc
        problems = _check_home(home)
        if problems:
            raise ModelFileError(file, "inconsistent home file: " + "; ".join(problems))
        return home

    def describe(self) -> str:
        """A few lines for people: samples, taught, concepts and regions used, words."""
        s = self.state
        concepts = np.unique(s.concepts).size
        regions = int((s.region_counts > 0).sum())
        views = f", {self.n_views} with a view" if self.view_missing.any() else ""
        return (f"home {self.name}: {self.n_samples} samples ({self.n_taught} taught{views}), "
                f"{concepts} concepts and {regions} regions in use, {len(self.vocabulary)} words "
                f"({len(self.known_names)} usable), model {self.knowledge.model}"
                f"{' (shared part refined)' if self.joint else ''}")


_STATE_ARRAYS = ("concepts", "regions", "log_g", "log_g0", "log_pi", "means", "covariances", "log_theta_v",
                 "log_theta_w", "log_phi_v", "log_phi_w", "word_mask", "region_counts")


def _check_home(home: HomeModel) -> list[str]:
    """Shape problems of a home model read from a file (empty if consistent)."""
    s, k = home.state, home.knowledge
    n, L, V, D = home.n_samples, k.n_concepts, k.n_words, k.n_features
    K = k.hyperparameters.n_regions
    expected = {
        "concepts": (n,), "regions": (n,), "log_g": (1, L), "log_g0": (L,), "log_pi": (1, L, K),
        "means": (1, K, 4), "covariances": (1, K, 4, 4), "log_theta_v": (1, L, D), "log_theta_w": (1, L, V),
        "log_phi_v": (L, D), "log_phi_w": (L, V), "word_mask": (V,), "region_counts": (1, K),
    }
    problems = [f"state.{name} has shape {np.shape(getattr(s, name))}, expected {shape}"
                for name, shape in expected.items() if np.shape(getattr(s, name)) != shape]
    if np.shape(home.positions) != (n, 4):
        problems.append(f"positions have shape {np.shape(home.positions)}")
    if len(home.sentences) != n:
        problems.append(f"{len(home.sentences)} sentences for {n} samples")
    if home.visual.shape[1] != D:
        problems.append(f"visual counts have {home.visual.shape[1]} features, the knowledge {D}")
    if home.view_missing.shape != (n,):
        problems.append(f"view_missing has shape {home.view_missing.shape}, expected ({n},)")
    elif home.view_missing.any() and home.visual[np.flatnonzero(home.view_missing)].nnz:
        problems.append("a sample without a view has visual counts")
    if not 0 <= home.n_knowledge_words <= V:
        problems.append(f"n_knowledge_words {home.n_knowledge_words} out of range")
    if home.posterior is not None:
        p = home.posterior
        for name, shape in (("word_probabilities", (1, L, V)), ("visual_probabilities", (1, L, D)),
                            ("region_weights", (1, L, K)), ("region_means", (1, K, 4))):
            if np.shape(getattr(p, name)) != shape:
                problems.append(f"posterior.{name} has shape {np.shape(getattr(p, name))}, expected {shape}")
    if k.channels is not None and not problems:
        nnz = home.data.words.nnz
        if s.switches is None:
            problems.append("the home holds no state.switches (the word channels' switch of each token)")
        elif np.shape(s.switches) != (nnz,) or (nnz and (s.switches.min() < 0 or s.switches.max() > 2)):
            problems.append(f"state.switches has shape {np.shape(s.switches)} (expected ({nnz},), one switch "
                            "0, 1 or 2 per word token of the sentences)")
    place_home = None if s.channels is None else s.channels.log_place_home
    if place_home is not None:
        if not uses_home_place(k.hyperparameters):
            problems.append("state.log_place_home (a home's own place words) in a home whose hyperparameters "
                            "have place_channel 'shared'")
        elif np.shape(place_home) != (1, L, V):
            problems.append(f"state.log_place_home has shape {np.shape(place_home)}, expected {(1, L, V)}")
        elif np.isnan(place_home).any() or (place_home == np.inf).any():
            problems.append("state.log_place_home holds a NaN or +inf log-probability")
    if n and ((s.concepts < 0).any() or (s.concepts >= L).any()
              or (s.regions < 0).any() or (s.regions >= K).any()):
        problems.append("assignments out of range")
    return problems


def load_home_model(path: str | PathLike[str]) -> HomeModel:
    """Read a home file (``spco adapt``, ``spco teach``).

    Raises :class:`~spco.errors.ModelFileError` if the file is missing, truncated, not a home
    file, edited after it was written (checksum mismatch) or written by a newer spco.
    """
    return HomeModel.load(path)



def _copy_state(state: gibbs.GibbsState) -> gibbs.GibbsState:
    copy = gibbs.GibbsState(**{name: np.array(getattr(state, name), copy=True) for name in _STATE_ARRAYS})
    copy.channels = state.channels  # (never changed in place: replaced)
    copy.switches = None if state.switches is None else state.switches.copy()
    return copy
