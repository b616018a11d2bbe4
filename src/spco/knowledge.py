"""Knowledge that travels: learn once from experienced homes, adapt to a new home, answer at once.

The paper re-learns every experienced home together with each new one. A robot that arrives in a
new home cannot: it carries what it learnt, adapts on site and answers questions at once. This
module splits the transfer model (Hagiwara et al. 2021, ``docs/model.md``) along its plates:

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
Knowledge (``.spco``, format ``spco-knowledge``) and home (``.spco``, format ``spco-home``) files
are NumPy ``.npz`` archives read with ``allow_pickle=False``: arrays plus a ``header`` array holding
a UTF-8 JSON document with the format name, ``format_version`` (2), the spco version, the
hyperparameters, the vocabulary, provenance, the image extractor (``extractor``: name, version,
settings and checksum of its weights, ``null`` for knowledge fitted on count vectors; its weights,
such as a codebook, as arrays ``extractor.<name>``; version 1 files, which predate it, are read
as fitted on count vectors), a sha256 checksum of every array and a ``checksum`` of
the whole content (header and arrays). They are written to a temporary file in the target's folder,
flushed and renamed into place (atomic), and never replace an existing file unless asked
(``overwrite=True``, ``--force``). A missing, truncated, edited or foreign file, or one written by
a newer spco, raises :class:`~spco.errors.ModelFileError` naming the file and the problem.
Every save holds the file's write lock (:func:`spco.locking.locked`, a ``flock`` on ``<file>.lock``);
to read, update and replace a file without losing another process's update, hold it around all
three (``with locked(path): home = load_home_model(path); …; home.save(path, overwrite=True)``).
"""

from __future__ import annotations

import copy
import functools
import hashlib
import json
import math
import time
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.cluster.vq import kmeans2
from scipy.optimize import linear_sum_assignment
from scipy.special import logsumexp

from spco.confidence import UNSURE_BELOW, concept_word_counts, predict_names_honestly
from spco.data.environment import Corpus, Environment, Extent
from spco.data.language import Vocabulary
from spco.errors import ConfigurationError, DataFormatError, ModelFileError
from spco.locking import locked
from spco.model import gibbs
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.io import _checksum, write_npz_atomic
from spco.model.observations import HierarchicalMultinomial
from spco.model.parameters import ConceptParameters
from spco.model.posterior import ParameterAverage, thinned_sweeps
from spco.model.pruning import NOT_A_NAME, words_to_keep
from spco.model.random import log_dirichlet, sample_crt, stack_counts
from spco.model.transfer import SpatialConceptModel, SpCoTransfer, export_parameters
from spco.prediction import (
    NamePrediction,
    PositionPrediction,
    UnknownNameError,
    validate_visual_counts,
)

__all__ = [
    "DEFAULT_ADAPT_ITERATIONS",
    "DEFAULT_TEACH_SWEEPS",
    "FORMAT_VERSION",
    "HOME_FORMAT",
    "KNOWLEDGE_FORMAT",
    "MODELS",
    "WHERE_MODEL_WEIGHT",
    "HomeModel",
    "Knowledge",
    "Observation",
    "adapt",
    "fit_knowledge",
    "load_home_model",
    "load_knowledge",
    "read_visual_vector",
    "summary_iterations",
    "teach",
    "what",
    "where",
]

#: Header ``format`` of knowledge files and home files.
KNOWLEDGE_FORMAT = "spco-knowledge"
HOME_FORMAT = "spco-home"
#: Version of both file layouts written by this module; newer files are refused. Version 2 added
#: the image extractor (``extractor`` in the header); version 1 files are read as count-vector ones.
FORMAT_VERSION = 2

#: The transfer models whose shared part can be learnt: name -> (sampler variant, word pruning).
MODELS: dict[str, tuple[str, bool]] = {
    "spcotransfer+mi": ("exact", True),
    "spcotransfer": ("exact", False),
    "spcotransfer-ref+mi": ("reference", True),
    "spcotransfer-ref": ("reference", False),
}

DEFAULT_MODEL = "spcotransfer+mi"
DEFAULT_FIT_ITERATIONS = 200
DEFAULT_ADAPT_ITERATIONS = 100
DEFAULT_TEACH_SWEEPS = 10

_FORMAT_NAMES = {KNOWLEDGE_FORMAT: "knowledge file", HOME_FORMAT: "home file",
                 "spco-model": "spco model file (spco fit --save / model.save)"}
_UNREADABLE = "not a readable spco file (truncated or corrupted?)"


def _model_name(variant: str, prune: bool) -> str:
    for name, spec in MODELS.items():
        if spec == (variant, prune):
            return name
    raise ConfigurationError(f"no transfer model with sampler {variant!r} and pruning {prune}")


def _as_generator(random_state: int | np.random.Generator | None) -> np.random.Generator:
    """A new Generator from a seed, or a copy of a Generator: the caller's is never advanced."""
    if isinstance(random_state, np.random.Generator):
        return copy.deepcopy(random_state)
    return np.random.default_rng(random_state)


def _seed_of(random_state: object) -> int | None:
    if isinstance(random_state, bool) or not isinstance(random_state, int | np.integer):
        return None
    return int(random_state)


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _version() -> str:
    from spco import __version__

    return __version__


# ============================================================================ file helpers


def _canonical(obj: Any) -> bytes:
    return json.dumps(obj, sort_keys=True, ensure_ascii=False, allow_nan=True,
                      separators=(",", ":")).encode("utf-8")


def _content_checksum(header: Mapping[str, Any]) -> str:
    """sha256 of the header, which holds every array's checksum; its own ``checksum`` and the
    version of the spco that wrote it are left out (the same content has the same checksum)."""
    content = {k: v for k, v in header.items() if k not in ("checksum", "spco_version")}
    return hashlib.sha256(_canonical(content)).hexdigest()


def _write_archive(path: str | PathLike[str], arrays: Mapping[str, np.ndarray], header: dict[str, Any],
                   overwrite: bool, what: str) -> Path:
    """Write ``arrays`` and ``header`` (+ array and content checksums) to ``path`` atomically,
    holding the file's write lock (:func:`spco.locking.locked`; re-entrant, so a caller may hold it
    already while it reads and updates the file)."""
    target = Path(path).expanduser()
    if target.is_dir() or not target.parent.is_dir():  # no lock to take: the writer says what is wrong
        return write_npz_atomic(path, header, arrays, overwrite, what, seal=_content_checksum)
    with locked(target):
        return write_npz_atomic(path, header, arrays, overwrite, what, seal=_content_checksum)


def _read_archive(path: str | PathLike[str],
                  expected: str) -> tuple[Path, dict[str, Any], dict[str, np.ndarray]]:
    """Header and arrays of a file of format ``expected``, verified; any problem -> ModelFileError."""
    file = Path(path).expanduser()
    what = _FORMAT_NAMES[expected]
    if not file.exists():
        raise ModelFileError(file, f"no such {what}")
    if file.is_dir():
        raise ModelFileError(file, f"is a folder, not a {what}")
    try:
        archive = np.load(file, allow_pickle=False)
    except Exception as exc:  # any failure to parse means it is not a readable file
        raise ModelFileError(file, f"{_UNREADABLE}: {exc}") from exc
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise ModelFileError(file, f"not a {what} (a single NumPy array, not an .npz archive)")
    try:
        with archive:
            if "header" not in archive.files:
                raise ModelFileError(file, f"not a {what} (no header; is it another program's .npz?)")
            header = _decode_header(file, archive["header"], expected)
            arrays = {name: archive[name] for name in archive.files if name != "header"}
    except ModelFileError:
        raise
    except Exception as exc:  # zipfile.BadZipFile (bad CRC), EOFError, ValueError, OSError, ...
        raise ModelFileError(file, f"{_UNREADABLE}: {exc}") from exc
    checksums = header.get("array_checksums")
    if not isinstance(checksums, dict):
        raise ModelFileError(file, "the header has no array checksums")
    missing = sorted(set(checksums) - set(arrays))
    extra = sorted(set(arrays) - set(checksums))
    if missing or extra:
        raise ModelFileError(file, "the arrays do not match the header (missing: "
                             f"{', '.join(missing) or '-'}; unexpected: {', '.join(extra) or '-'})")
    for name, expected_sum in checksums.items():
        if _checksum(arrays[name]) != expected_sum:
            raise ModelFileError(file, f"checksum mismatch for array {name!r}: the file was modified or "
                                 "corrupted after it was written")
    if header.get("checksum") != _content_checksum(header):
        raise ModelFileError(file, "checksum mismatch of the header: the file was modified after it "
                             "was written")
    return file, header, arrays


def _decode_header(path: Path, raw: np.ndarray, expected: str) -> dict[str, Any]:
    what = _FORMAT_NAMES[expected]
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise ModelFileError(path, f"not a {what} (its header is not a JSON byte string)")
    try:
        header = json.loads(raw.tobytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(path, f"the header is not valid JSON: {exc}") from exc
    found = header.get("format") if isinstance(header, dict) else None
    if found != expected:
        hint = ""
        if found in _FORMAT_NAMES:
            hint = f": it is a {_FORMAT_NAMES[found]}"
            if expected == HOME_FORMAT and found == KNOWLEDGE_FORMAT:
                hint += " — make a home file from it with `spco adapt`"
            if expected == KNOWLEDGE_FORMAT and found == HOME_FORMAT:
                hint += " — `spco adapt` needs the knowledge file written by `spco fit`"
        raise ModelFileError(path, f"not a {what} (format {found!r}, expected {expected!r}){hint}")
    version = header.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise ModelFileError(path, f"invalid format_version {version!r}")
    if version > FORMAT_VERSION:
        raise ModelFileError(path, f"written by a newer spco ({what} format version {version}, spco "
                             f"{header.get('spco_version', '?')}); this spco reads up to version "
                             f"{FORMAT_VERSION} — upgrade spco to read it")
    return header


def _require(path: Path, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray],
             keys: Iterable[str], names: Iterable[str]) -> None:
    missing = [k for k in keys if k not in header]
    missing += [n for n in names if n not in arrays]
    if missing:
        raise ModelFileError(path, f"incomplete file: it lacks {', '.join(missing)}")


# ============================================================================ knowledge


@dataclass(frozen=True, eq=False)
class Knowledge:
    """The shared, home-independent part of the transfer model, learnt from experienced homes.

    Attributes
    ----------
    log_phi_visual: (L, D) log φ^v, the concepts' visual distributions.
    log_phi_words: (L, V) log φ^w, the concepts' word distributions (pruned words included).
    log_g0: (L,) log G_0, the global concept weights.
    word_mask: (V,) bool, False for words removed by pruning.
    concentration_visual, concentration_words: (L,) Dirichlet concentration A_l of the posterior
        of φ^v_l, φ^w_l (moment-matched over the averaged samples, shrunk towards δ: see
        :func:`_concentration`; NaN: unknown, in files written before, read as δ).
    concentration_g0: the same for G_0 (shrunk towards γ; NaN: unknown).
    vocabulary: the words of φ^w's columns.
    word_increment: S^w, the count of each word occurrence.
    hyperparameters: the model's hyperparameters.
    variant: the sampler (``"exact"`` or ``"reference"``); prune_words: "+MI".
    provenance: homes, seed, iterations, samples averaged, spco version, time of the fit, ...
    extractor: the image extractor the visual counts come from
        (:meth:`spco.features.ExtractorSpec.to_dict`), or ``None`` if fitted on count vectors.
    extractor_arrays: its weights (e.g. ``{"codebook": (W, d)}``), stored in the file.
    """

    log_phi_visual: np.ndarray
    log_phi_words: np.ndarray
    log_g0: np.ndarray
    word_mask: np.ndarray
    concentration_visual: np.ndarray
    concentration_words: np.ndarray
    concentration_g0: float
    vocabulary: Vocabulary
    word_increment: int
    hyperparameters: TransferHyperparameters
    variant: str
    prune_words: bool
    provenance: dict[str, Any] = field(default_factory=dict)
    extractor: dict[str, Any] | None = None
    extractor_arrays: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        L = self.log_g0.shape[0] if np.ndim(self.log_g0) == 1 else -1
        V = len(self.vocabulary)
        problems = []
        if L != self.hyperparameters.n_concepts:
            problems.append(f"G_0 has {L} concepts, the hyperparameters {self.hyperparameters.n_concepts}")
        if np.ndim(self.log_phi_visual) != 2 or self.log_phi_visual.shape[0] != L:
            problems.append(f"φ^v has shape {np.shape(self.log_phi_visual)}")
        if np.shape(self.log_phi_words) != (L, V):
            problems.append(f"φ^w has shape {np.shape(self.log_phi_words)} for {L} concepts and {V} words")
        if np.shape(self.word_mask) != (V,):
            problems.append(f"the word mask has shape {np.shape(self.word_mask)} for {V} words")
        for name in ("concentration_visual", "concentration_words"):
            if np.shape(getattr(self, name)) != (L,):
                problems.append(f"{name} has shape {np.shape(getattr(self, name))}")
        if self.variant not in ("exact", "reference"):
            problems.append(f"unknown sampler {self.variant!r}")
        if problems:
            raise ConfigurationError("inconsistent knowledge: " + "; ".join(problems))
        object.__setattr__(self, "word_mask", np.asarray(self.word_mask, dtype=bool))

    # ------------------------------------------------------------------ sizes and names
    @property
    def n_concepts(self) -> int:
        """L."""
        return int(self.log_g0.shape[0])

    @property
    def n_features(self) -> int:
        """Visual dimension D."""
        return int(self.log_phi_visual.shape[1])

    @property
    def n_words(self) -> int:
        """Vocabulary size V."""
        return len(self.vocabulary)

    @property
    def model(self) -> str:
        """The model's name (``"spcotransfer+mi"``, ...)."""
        return _model_name(self.variant, self.prune_words)

    @property
    def known_names(self) -> list[str]:
        """The words kept by pruning."""
        return [w for w, keep in zip(self.vocabulary.words, self.word_mask, strict=True) if keep]

    @property
    def checksum(self) -> str:
        """sha256 identifying this knowledge's content (the ``checksum`` of its file)."""
        arrays, header = self._arrays_and_header()
        header = dict(header)
        header["array_checksums"] = {n: _checksum(np.asarray(a)) for n, a in arrays.items()}
        return _content_checksum(header)

    @property
    def fitted_on_images(self) -> bool:
        """Whether the visual counts come from images through an extractor (:attr:`extractor`)."""
        return self.extractor is not None

    def image_extractor(self, model_path: str | PathLike[str] | None = None) -> Any:
        """The :class:`~spco.features.Extractor` this knowledge was fitted with, rebuilt and checked.

        ``model_path``: where the ONNX model file is now, if it moved (its checksum must match).
        Raises ConfigurationError for knowledge fitted on count vectors, or weights that differ.
        """
        from spco.features import build_extractor

        if self.extractor is None:
            raise ConfigurationError("this knowledge was fitted on visual count vectors, not on images: "
                                     "give views as features (--visual), or fit a knowledge on homes "
                                     "with images")
        extractor = build_extractor(self.extractor, self.extractor_arrays, model_path=model_path)
        if extractor.n_features != self.n_features:
            raise ConfigurationError(f"the extractor gives {extractor.n_features} features, the knowledge "
                                     f"has {self.n_features}")
        return extractor

    def used_concepts(self, threshold: float = 0.01) -> int:
        """Number of concepts with G_0 above ``threshold``."""
        return int((np.exp(self.log_g0) > threshold).sum())

    # ------------------------------------------------------------------ growing the vocabulary
    def extended(self, sentences: Iterable[str | None]) -> Knowledge:
        """This knowledge with the new words of ``sentences`` appended to the vocabulary.

        A new word's φ^w_{l,k} is α^w/δ^w in every concept (rows renormalised): the home's
        θ^w_{e,l} ~ Dir(δ^w φ^w_l + n) then gives it the prior mass α^w of a word never seen.
        New words are kept by the mask (a home decides about them). Returns ``self`` if no word
        is new.
        """
        vocabulary = self.vocabulary.extended(sentences)
        added = len(vocabulary) - self.n_words
        if added == 0:
            return self
        hyper = self.hyperparameters
        log_new = math.log(hyper.alpha_word / hyper.delta_word)
        log_phi = np.concatenate([self.log_phi_words, np.full((self.n_concepts, added), log_new)], axis=1)
        log_phi -= logsumexp(log_phi, axis=1, keepdims=True)
        mask = np.concatenate([self.word_mask, np.ones(added, dtype=bool)])
        return replace(self, log_phi_words=log_phi, word_mask=mask, vocabulary=vocabulary)

    # ------------------------------------------------------------------ files
    def _arrays_and_header(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        arrays = {
            "log_phi_visual": np.asarray(self.log_phi_visual, dtype=np.float64),
            "log_phi_words": np.asarray(self.log_phi_words, dtype=np.float64),
            "log_g0": np.asarray(self.log_g0, dtype=np.float64),
            "word_mask": np.asarray(self.word_mask, dtype=bool),
            "concentration_visual": np.asarray(self.concentration_visual, dtype=np.float64),
            "concentration_words": np.asarray(self.concentration_words, dtype=np.float64),
            "concentration_g0": np.asarray([self.concentration_g0], dtype=np.float64),
        }
        for name, value in self.extractor_arrays.items():
            arrays["extractor." + name] = np.asarray(value)
        header = {
            "format": KNOWLEDGE_FORMAT,
            "format_version": FORMAT_VERSION,
            "spco_version": _version(),
            "model": self.model,
            "variant": self.variant,
            "prune_words": bool(self.prune_words),
            "hyperparameters": self.hyperparameters.to_dict(),
            "vocabulary": list(self.vocabulary.words),
            "word_increment": int(self.word_increment),
            "provenance": self.provenance,
            "extractor": self.extractor,
        }
        return arrays, header

    def save(self, path: str | PathLike[str], overwrite: bool = False) -> Path:
        """Write this knowledge to ``path`` (atomically; an existing file only with ``overwrite``)."""
        arrays, header = self._arrays_and_header()
        return _write_archive(path, arrays, header, overwrite, "knowledge file")

    @classmethod
    def load(cls, path: str | PathLike[str]) -> Knowledge:
        """Read a knowledge file written by :meth:`save`; see :func:`load_knowledge`."""
        file, header, arrays = _read_archive(path, KNOWLEDGE_FORMAT)
        return cls._from_parts(file, header, arrays, "")

    @classmethod
    def _from_parts(cls, file: Path, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray],
                    prefix: str) -> Knowledge:
        names = ("log_phi_visual", "log_phi_words", "log_g0", "word_mask", "concentration_visual",
                 "concentration_words", "concentration_g0")
        _require(file, header, arrays, ("variant", "prune_words", "hyperparameters", "vocabulary",
                                        "word_increment"), [prefix + n for n in names])
        try:
            return cls(
                log_phi_visual=arrays[prefix + "log_phi_visual"],
                log_phi_words=arrays[prefix + "log_phi_words"],
                log_g0=arrays[prefix + "log_g0"],
                word_mask=arrays[prefix + "word_mask"],
                concentration_visual=arrays[prefix + "concentration_visual"],
                concentration_words=arrays[prefix + "concentration_words"],
                concentration_g0=float(arrays[prefix + "concentration_g0"].reshape(-1)[0]),
                vocabulary=Vocabulary(tuple(str(w) for w in header["vocabulary"])),
                word_increment=int(header["word_increment"]),
                hyperparameters=TransferHyperparameters.from_dict(header["hyperparameters"]),
                variant=str(header["variant"]),
                prune_words=bool(header["prune_words"]),
                provenance=dict(header.get("provenance") or {}),
                extractor=_extractor_of(header),
                extractor_arrays={name[len(prefix) + len("extractor."):]: a for name, a in arrays.items()
                                  if name.startswith(prefix + "extractor.")},
            )
        except (ConfigurationError, TypeError, ValueError, IndexError) as exc:
            raise ModelFileError(file, f"inconsistent file: {exc}") from exc

    def describe(self) -> str:
        """A few lines for people: model, homes, concepts, words, samples averaged."""
        p = self.provenance
        homes = p.get("homes") or []
        summary = p.get("summary") or {}
        lines = [
            f"model {self.model}: {self.used_concepts()} of {self.n_concepts} concepts used, "
            f"{self.n_words} words ({len(self.known_names)} kept), {self.n_features} visual features",
            f"learnt from {len(homes)} homes ({', '.join(homes[:6])}{', …' if len(homes) > 6 else ''}) "
            f"in {p.get('n_iterations', '?')} sweeps, seed {p.get('seed')}; averaged over "
            f"{summary.get('n_samples', '?')} posterior samples",
        ]
        if self.extractor is not None:
            from spco.features import ExtractorSpec

            lines.append(f"views: images, extractor {ExtractorSpec.from_dict(self.extractor).describe()}")
        return "\n".join(lines)


def _extractor_of(header: Mapping[str, Any]) -> dict[str, Any] | None:
    """The extractor description of a header (``None``: count vectors; absent in version 1)."""
    from spco.features import ExtractorSpec

    value = header.get("extractor")
    return None if value is None else ExtractorSpec.from_dict(value).to_dict()


def load_knowledge(path: str | PathLike[str]) -> Knowledge:
    """Read a knowledge file (``spco fit``).

    Raises :class:`~spco.errors.ModelFileError` if the file is missing, truncated, not a knowledge
    file, edited after it was written (checksum mismatch) or written by a newer spco.
    """
    return Knowledge.load(path)


# ---------------------------------------------------------------------------- fitting


def summary_iterations(n_iterations: int, fraction: float = 0.25, every: int = 5) -> list[int]:
    """The sweeps (0-based) whose samples the knowledge averages: every ``every``-th of the last
    ``fraction`` of the chain, ending with the last sweep, with the step shortened so that a short
    chain still gives up to three samples (:func:`spco.model.posterior.thinned_sweeps`)."""
    return thinned_sweeps(n_iterations, fraction, every)


#: Weight, in samples (degrees of freedom), of the default spread Dir(δ φ̄) in :func:`_concentration`.
CONCENTRATION_PRIOR_SAMPLES = 2.0


def _concentration(samples: np.ndarray, default: float) -> np.ndarray:
    """Dirichlet concentration A_l of each row, moment-matched to the samples' spread, shrunk
    towards ``default``: samples (S, L, D) -> (L,).

    With φ̄ the mean and s² = Σ_k Var φ_k (ddof 1) of the S samples, the spread of Dir(A φ̄) is
    Σ_k φ̄_k(1 − φ̄_k) / (A + 1). The variance used pools the samples' S − 1 degrees of freedom
    with :data:`CONCENTRATION_PRIOR_SAMPLES` of the spread at A = ``default``::

        v = ((S − 1) s² + ν Σ_k φ̄_k(1 − φ̄_k) / (default + 1)) / (S − 1 + ν),   A = Σ_k φ̄_k(1 − φ̄_k) / v − 1

    so S = 1 gives ``default``, large S the moment-matched value, and A changes smoothly with S
    and the samples. Rows with no spread at all (φ̄ one-hot) get ``default``.
    """
    n = samples.shape[0]
    mean = samples.mean(axis=0)
    spread = (mean * (1.0 - mean)).sum(axis=-1)
    sample_var = samples.var(axis=0, ddof=1).sum(axis=-1) if n > 1 else np.zeros_like(spread)
    nu = CONCENTRATION_PRIOR_SAMPLES
    var = ((n - 1) * sample_var + nu * spread / (default + 1.0)) / (n - 1 + nu)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = spread / var - 1.0
    return np.where(np.isfinite(a) & (a > 0), a, default)


def _align_to(reference_v: np.ndarray, reference_w: np.ndarray, phi_v: np.ndarray,
              phi_w: np.ndarray) -> np.ndarray:
    """Permutation p of the concepts of one sample matching a reference: slot j takes concept p[j]."""
    cost = np.abs(reference_v[:, None, :] - phi_v[None, :, :]).sum(-1)
    if phi_w.shape[1]:
        cost = cost + np.abs(reference_w[:, None, :] - phi_w[None, :, :]).sum(-1)
    rows, cols = linear_sum_assignment(cost)
    perm = np.empty(cost.shape[0], dtype=np.int64)
    perm[rows] = cols
    return perm


def fit_knowledge(
    corpus: Corpus,
    model: str = DEFAULT_MODEL,
    n_iterations: int = DEFAULT_FIT_ITERATIONS,
    random_state: int | np.random.Generator | None = None,
    progress: bool = False,
    hyperparameters: TransferHyperparameters | None = None,
    summary_fraction: float = 0.25,
    summary_every: int = 5,
    provenance: Mapping[str, Any] | None = None,
    extractor: Any = None,
    engine: Any = None,
) -> Knowledge:
    """Learn the shared part of the transfer model from the experienced homes of ``corpus``.

    Runs the transfer model's Gibbs sampler on every home of ``corpus`` (their training samples)
    and summarises φ^v, φ^w and G_0 over the samples of :func:`summary_iterations` (the last
    quarter of the chain, every 5th sweep): each sample is first aligned to the last one
    (Hungarian matching of its φ rows; late in the chain the labels are stable, and the number of
    samples that needed a relabelling is recorded), then φ and G_0 are averaged, and the spread
    of the samples gives the concentrations used by ``adapt(..., joint=True)``. With word pruning
    the mask is decided again on the averaged φ^w and G_0.

    Parameters
    ----------
    corpus: the experienced homes (a :class:`~spco.data.Corpus`), or a
        :class:`~spco.model.sources.FolderHomes` whose home folders the shards read themselves
        (with Ray or several local shards the driver never holds the homes' samples; the same
        result as the :class:`~spco.data.Corpus` of the same homes).
    model: one of :data:`MODELS` (default ``"spcotransfer+mi"``).
    n_iterations: Gibbs sweeps (200 as in the paper).
    random_state: seed or Generator.
    progress: show a progress bar on standard error.
    hyperparameters: default: the paper's.
    summary_fraction, summary_every: which sweeps are averaged (see :func:`summary_iterations`).
    provenance: extra entries for the knowledge's provenance (e.g. the data path).
    extractor: the :class:`~spco.features.Extractor` that computed the homes' visual counts from
        images (stored in the knowledge, so that adapt, teach and what use it); ``None`` for
        count vectors given as such.
    engine: where the homes' shards run (:func:`spco.engines.make_engine`): ``None`` in this
        process, ``"ray"`` or an engine object such as ``RayEngine(shards=4, address="auto")``.

    Returns
    -------
    The :class:`Knowledge`; its ``provenance`` records the homes, the seed, the iterations, the
    samples averaged, the fit time and the spco version.
    """
    if model not in MODELS:
        raise ConfigurationError(f"unknown model {model!r}; choose one of {', '.join(MODELS)}")
    from spco.model.sources import FolderHomes

    source = corpus if isinstance(corpus, FolderHomes) else None
    if not isinstance(corpus, Corpus) and source is None:
        raise ConfigurationError("fit_knowledge() expects a spco.data.Corpus or a "
                                 "spco.model.sources.FolderHomes")
    variant, prune = MODELS[model]
    estimator = SpCoTransfer(hyperparameters, variant=variant, prune_words=prune, n_iterations=n_iterations,
                             random_state=random_state)
    hyper = estimator._validate()
    if not (0 < summary_fraction <= 1) or summary_every < 1:
        raise ConfigurationError("summary_fraction must be within (0, 1] and summary_every >= 1")
    n_features = corpus.n_features if source is not None else corpus[0].n_features
    if extractor is not None and extractor.n_features != n_features:
        raise ConfigurationError(f"the extractor gives {extractor.n_features} features, the homes' views "
                                 f"have {n_features}")
    if len(corpus.vocabulary) == 0:
        n_homes = source.n_homes if source is not None else len(corpus)
        raise DataFormatError(None, f"no taught sentence in the {n_homes} experienced home(s) "
                              f"({', '.join(list(corpus.names)[:5])}): there are no place names to learn")
    settings = estimator._settings()
    rng = _as_generator(random_state)
    scale = gibbs.CM_PER_M if variant == "reference" else 1.0
    if source is not None:
        source = replace(source, position_scale=scale)
    data = SpatialConceptModel._prepare(corpus, scale) if source is None else None
    keep = set(summary_iterations(n_iterations, summary_fraction, summary_every))
    start = time.perf_counter()
    by_iteration: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n_iterations, desc=f"fit ({model})", unit="sweep", leave=False)
    from spco.engines import start_run, start_source_run

    if source is not None:  # the shards read their homes (or, one process, the driver reads them)
        run, data = start_source_run(engine, source, hyper, settings, rng)
    else:
        run = start_run(engine, data, len(corpus.vocabulary), hyper, settings, rng)

    def after_sweep(iteration: int, _: float) -> None:  # (a restarted engine repeats sweeps)
        if bar is not None:
            bar.update(1)
        if iteration in keep:
            shared = run.shared
            by_iteration[iteration] = (shared.log_phi_v.copy(), shared.log_phi_w.copy(), shared.log_g0.copy())

    run.fit(n_iterations, after_sweep)
    if data is None:  # the homes stay in the shards: no joined state
        word_mask_last, candidate_words = run.shared.word_mask, run.call("candidate_words")[0]
    else:
        state = run.state()
        word_mask_last, candidate_words = state.word_mask, state.candidate_words
        run.close()
    if bar is not None:
        bar.close()
    samples = [by_iteration[i] for i in sorted(by_iteration)]
    seconds = time.perf_counter() - start

    # align every sample to the last (labels are stable late in the chain; check and record it)
    last_v, last_w = np.exp(samples[-1][0]), np.exp(samples[-1][1])
    used = np.exp(samples[-1][2]) > 0.01
    relabelled = 0
    aligned = []
    for log_v, log_w, log_g in samples:
        perm = _align_to(last_v, last_w, np.exp(log_v), np.exp(log_w))
        if (perm[used] != np.flatnonzero(used)).any():
            relabelled += 1
        aligned.append((log_v[perm], log_w[perm], log_g[perm]))
    stack_v = np.stack([a[0] for a in aligned])
    stack_w = np.stack([a[1] for a in aligned])
    stack_g = np.stack([a[2] for a in aligned])
    n = stack_v.shape[0]
    log_phi_v = logsumexp(stack_v, axis=0) - math.log(n)
    has_words = stack_w.shape[2] > 0
    log_phi_w = logsumexp(stack_w, axis=0) - math.log(n) if has_words else np.zeros((hyper.n_concepts, 0))
    log_g0 = logsumexp(stack_g, axis=0) - math.log(n)
    phi_v_samples = np.exp(stack_v)
    spread = np.abs(phi_v_samples - np.exp(log_phi_v)[None]).sum(-1)[:, used]  # total variation × 2
    word_mask = np.ones(len(corpus.vocabulary), dtype=bool)
    if prune and word_mask.size and variant == "exact":
        # the naming rule on the last sweep's regions (:func:`gibbs.naming_verdicts`), the mask the
        # sampler used: it judges a name said in one home on that home, where it is place-bound
        word_mask = word_mask_last.copy()
    elif prune and word_mask.size:
        score = settings.pruning_score
        word_mask = words_to_keep(np.exp(log_phi_w), np.exp(log_g0), hyper.pruning_threshold(score), score)
        if candidate_words is not None:  # words the sampler found to depend on the place
            word_mask &= candidate_words
        if not word_mask.any():
            word_mask[np.argmax(np.exp(log_phi_w).max(0))] = True
    conc_g = _concentration(np.exp(stack_g)[:, None, :], hyper.gamma)[0]
    record: dict[str, Any] = {
        "homes": list(corpus.names),
        "n_samples": int(source.n_samples if data is None else data.n_samples),
        "seed": _seed_of(random_state),
        "n_iterations": int(n_iterations),
        "fit_seconds": round(seconds, 3),
        "spco_version": _version(),
        "created": _now(),
        "summary": {
            "iterations": sorted(keep),
            "n_samples": int(n),
            "relabelled_samples": int(relabelled),
            "max_visual_distance_from_mean": round(float(0.5 * spread.max()) if spread.size else 0.0, 6),
        },
    }
    if data is None:  # each shard scores its homes (φ^v without their counts: the pooled totals)
        totals = np.sum(run.call("concept_visual_totals"), axis=0)
        fits = [v for part in run.call("held_out_view_fits", log_phi_v, log_g0, totals) for v in part]
        run.close()
        record["view_fit"] = _view_fit_record(dict(zip(corpus.names, fits, strict=True)))
    else:
        record["view_fit"] = _experienced_view_fit(log_phi_v, log_g0, data, state.concepts, corpus.names)
    record.update(provenance or {})
    return Knowledge(
        log_phi_visual=log_phi_v, log_phi_words=log_phi_w, log_g0=log_g0, word_mask=word_mask,
        concentration_visual=_concentration(phi_v_samples, hyper.delta_visual),
        concentration_words=(_concentration(np.exp(stack_w), hyper.delta_word) if has_words
                             else np.full(hyper.n_concepts, np.nan)),
        concentration_g0=float(conc_g), vocabulary=corpus.vocabulary, word_increment=corpus.word_increment,
        hyperparameters=hyper, variant=variant, prune_words=prune, provenance=record,
        extractor=None if extractor is None else extractor.spec().to_dict(),
        extractor_arrays={} if extractor is None else dict(extractor.arrays),
    )


# ============================================================================ fit of the views

#: What :func:`view_fit` measures (stored with the figures in knowledge and home files).
VIEW_FIT_MEASURE = ("median over a home's views v of log(Σ_l G_0,l Π_d φ^v_l,d ^ v_d) / Σ_d v_d + log D: "
                    "nats per count by which the knowledge's visual mixture explains the views better "
                    "than a uniform guess")

#: A home whose :func:`view_fit` is below this fraction of the lowest of the experienced homes' is
#: warned about: the knowledge has lost more than half its advantage over a uniform guess there.
VIEW_FIT_WARN_FRACTION = 0.5


class ExperiencedHomeWarning(UserWarning):
    """A home given to :func:`adapt` has the name of one of the knowledge's experienced homes."""


class KnowledgeMismatchWarning(UserWarning):
    """The knowledge explains a home's views much worse than its experienced homes' (:func:`view_fit`)."""


def view_fit(log_phi_visual: np.ndarray, log_g0: np.ndarray, visual: Any) -> float | None:
    """How well a knowledge's visual distributions explain a home's views: :data:`VIEW_FIT_MEASURE`.

    Parameters
    ----------
    log_phi_visual: (L, D) log φ^v; log_g0: (L,) log G_0; visual: (n, D) counts (sparse or dense).

    Returns the median over the views with at least one count of their per-count log-likelihood under
    the mixture Σ_l G_0,l Mult(v | φ^v_l) (without the multinomial coefficient), plus log D; ``None``
    if no view has a count. About 0.6–0.8 (synthetic homes) and 0.9–1.4 (SIGVerse fc7) for homes
    like the experienced ones; negative for views from another feature extractor or distribution.
    """
    counts = sp.csr_array(visual, dtype=np.float64)
    totals = np.asarray(counts.sum(axis=1)).ravel()
    seen = totals > 0
    if not seen.any():
        return None
    log_phi = np.maximum(np.asarray(log_phi_visual, dtype=np.float64), np.log(np.finfo(float).tiny))
    per_concept = np.asarray(counts[seen] @ log_phi.T)  # (n, L): Σ_d v_d log φ_l,d
    mixture = logsumexp(per_concept + np.asarray(log_g0, dtype=np.float64)[None, :], axis=1)
    return float(np.median(mixture / totals[seen]) + math.log(log_phi.shape[1]))


def _experienced_view_fit(log_phi_v: np.ndarray, log_g0: np.ndarray, data: gibbs.PreparedData,
                          concepts: np.ndarray, names: Sequence[str]) -> dict[str, Any]:
    """The :func:`view_fit` of every experienced home, each held out, and the level below which a new
    home is warned about.

    A home's views helped to learn φ^v, so their fit under φ^v itself flatters them. Each home is
    scored instead under φ^v without its own counts: φ^v_l × (N_l + D) − n_{e,l} (N_l the counts
    of concept l over all homes, n_{e,l} home e's, with the concepts of the chain's last sweep, to
    which φ^v is aligned), floored at 1 % of φ^v_l × (N_l + D) and renormalised.
    """
    totals = concept_visual_totals(data, concepts, log_phi_v.shape[0])
    fits = held_out_view_fits(log_phi_v, log_g0, totals, data, concepts)
    return _view_fit_record(dict(zip(names, fits, strict=True)))


def _home_concept_counts(data: gibbs.PreparedData, concepts: np.ndarray, e: int,
                         n_concepts: int) -> np.ndarray:
    """Home ``e``'s visual counts by concept, (L, D) n_{e,l,d}."""
    rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
    n = rows.stop - rows.start
    onehot = sp.csr_array((np.ones(n), (concepts[rows], np.arange(n))), shape=(n_concepts, n))
    return np.asarray((onehot @ sp.csr_array(data.visual[rows], dtype=np.float64)).todense())


def concept_visual_totals(data: gibbs.PreparedData, concepts: np.ndarray, n_concepts: int) -> np.ndarray:
    """The visual counts of each concept summed over the homes of ``data``, (L,) N_l (summed over
    shards, the totals of all homes: integers, so the sum is exact in any order)."""
    return sum((_home_concept_counts(data, concepts, e, n_concepts).sum(1) for e in range(data.n_homes)),
               np.zeros(n_concepts))


def held_out_view_fits(log_phi_v: np.ndarray, log_g0: np.ndarray, totals: np.ndarray,
                       data: gibbs.PreparedData, concepts: np.ndarray) -> list[float | None]:
    """The held-out :func:`view_fit` of every home of ``data`` (see :func:`_experienced_view_fit`),
    ``totals`` the (L,) visual counts by concept of all homes of the fit."""
    L, D = log_phi_v.shape
    mass = np.exp(log_phi_v) * (totals + D)[:, None]
    fits = []
    for e in range(data.n_homes):  # a loop over homes, each scored as a whole
        held_out = np.maximum(mass - _home_concept_counts(data, concepts, e, L), 0.01 * mass)
        log_held_out = np.log(held_out / held_out.sum(1, keepdims=True))
        rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
        fits.append(view_fit(log_held_out, log_g0, data.visual[rows]))
    return fits


def _view_fit_record(homes: dict[str, float | None]) -> dict[str, Any]:
    """The provenance record of the experienced homes' view fits (home name -> fit)."""
    values = [v for v in homes.values() if v is not None]
    return {"measure": VIEW_FIT_MEASURE,
            "homes": {name: None if v is None else round(v, 4) for name, v in homes.items()},
            "warn_below": round(VIEW_FIT_WARN_FRACTION * min(values), 4) if values else None}


def check_view_fit(knowledge: Knowledge, visual: Any, home_name: str) -> dict[str, Any] | None:
    """The home's :func:`view_fit` against the experienced homes' (``None`` if the knowledge file
    predates the measure); warns with :class:`KnowledgeMismatchWarning` when it is below the level
    recorded at fit time."""
    recorded = knowledge.provenance.get("view_fit")
    if not isinstance(recorded, Mapping) or recorded.get("warn_below") is None:
        return None
    value = view_fit(knowledge.log_phi_visual, knowledge.log_g0, visual)
    experienced = [float(v) for v in (recorded.get("homes") or {}).values() if v is not None]
    warn_below = float(recorded["warn_below"])
    fits = value is not None and value >= warn_below
    result = {"value": None if value is None else round(value, 4), "warn_below": warn_below,
              "experienced_range": [min(experienced), max(experienced)] if experienced else None,
              "fits": bool(fits)}
    if not fits:
        warnings.warn(view_fit_warning(home_name, result), KnowledgeMismatchWarning, stacklevel=3)
    return result


def view_fit_warning(home_name: str, result: Mapping[str, Any]) -> str:
    """The sentence that says a knowledge does not fit a home (``result``: :func:`check_view_fit`)."""
    span = result.get("experienced_range") or [float("nan")] * 2
    value = "no view has a count" if result.get("value") is None else f"{result['value']:.2f}"
    return (f"the knowledge does not fit home {home_name!r}: it explains its views by {value} nats per "
            f"count better than a uniform guess, against {span[0]:.2f}…{span[1]:.2f} in its experienced "
            f"homes (warned below {result['warn_below']:.2f}); the views probably come from another "
            f"feature extractor or another kind of place, and answers here may be confidently wrong")


# ============================================================================ home models


@dataclass(frozen=True)
class Observation:
    """A new observation for :func:`teach`: a pose, the view's visual counts and what was said.

    x, y in metres on the home's map, theta (heading) in radians; visual: (D,) counts (dense array
    or a 1-row sparse matrix); sentence: the user's words, or ``None``; id: the sample id (default:
    one more than the largest id of the home); image: the view as an image (path or array) in place
    of ``visual``, for a home whose knowledge was fitted on images (its extractor computes the counts).
    """

    x: float
    y: float
    theta: float
    visual: Any = None
    sentence: str | None = None
    id: int | None = None
    image: Any = None


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
        if self.knowledge.variant == "reference":
            return "reference"
        return "none" if self.knowledge.prune_words else "mi"

    @property
    def position_scale(self) -> float:
        """Sampler units per metre."""
        return gibbs.CM_PER_M if self.knowledge.variant == "reference" else 1.0

    @functools.cached_property
    def data(self) -> gibbs.PreparedData:
        """The home's samples in the sampler's form."""
        return _prepare(self.positions, self.visual, self.sentences, self.vocabulary,
                        self.knowledge.word_increment, self.position_scale, self.map_centre)

    @functools.cached_property
    def parameters(self) -> ConceptParameters:
        """The home's parameters (one home, metres), as prediction uses them: the posterior
        average of the last sweeps (``posterior``), or the state's draw if there is none."""
        if self.posterior is not None:
            return self.posterior
        return export_parameters(self.state, self.data)

    @property
    def known_names(self) -> list[str]:
        """The words the home can answer for (kept by pruning)."""
        return [w for w, keep in zip(self.vocabulary.words, self.state.word_mask, strict=True) if keep]

    def environment(self) -> Environment:
        """The home's samples as an :class:`~spco.data.Environment` (all training, no ground truth)."""
        return Environment(name=self.name, ids=self.ids, positions=self.positions, visual=self.visual,
                           sentences=self.sentences, is_test=np.zeros(self.n_samples, dtype=bool),
                           extent=self.extent)

    # ------------------------------------------------------------------ questions
    def where(self, name: str, n: int = 10, random_state: int | np.random.Generator | None = None
              ) -> PositionPrediction:
        """Positions for the place ``name``; see :func:`where`."""
        return where(self, name, n=n, random_state=random_state)

    def what(self, x: float, y: float, theta: float, visual: Any = None, top_k: int = 3,
             image: Any = None, unsure_below: float = UNSURE_BELOW) -> NamePrediction:
        """Place names at a pose; see :func:`what`."""
        return what(self, x, y, theta, visual=visual, top_k=top_k, image=image, unsure_below=unsure_below)

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
        for name in _STATE_ARRAYS:
            arrays["state." + name] = np.asarray(getattr(s, name))
        if self.posterior is not None:
            arrays.update({"posterior." + k: np.asarray(v) for k, v in self.posterior.arrays().items()})
        header = {
            "format": HOME_FORMAT,
            "format_version": FORMAT_VERSION,
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
            sentences = tuple(None if s is None else str(s) for s in header["sentences"])
            extent = None if header["extent"] is None else tuple(float(v) for v in header["extent"])
            posterior_arrays = {k.removeprefix("posterior."): v for k, v in arrays.items()
                                if k.startswith("posterior.")}
            posterior = ConceptParameters(**posterior_arrays) if posterior_arrays else None
            home = cls(name=str(header["name"]), knowledge=knowledge, state=state, ids=arrays["ids"],
                       positions=arrays["positions"], visual=visual, sentences=sentences,
                       extent=extent, map_centre=arrays["map_centre"],
                       n_knowledge_words=int(header["n_knowledge_words"]), joint=bool(header.get("joint")),
                       provenance=dict(header.get("provenance") or {}), posterior=posterior)
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
        return (f"home {self.name}: {self.n_samples} samples ({self.n_taught} taught), {concepts} concepts "
                f"and {regions} regions in use, {len(self.vocabulary)} words "
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
    if not 0 <= home.n_knowledge_words <= V:
        problems.append(f"n_knowledge_words {home.n_knowledge_words} out of range")
    if home.posterior is not None:
        p = home.posterior
        for name, shape in (("word_probabilities", (1, L, V)), ("visual_probabilities", (1, L, D)),
                            ("region_weights", (1, L, K)), ("region_means", (1, K, 4))):
            if np.shape(getattr(p, name)) != shape:
                problems.append(f"posterior.{name} has shape {np.shape(getattr(p, name))}, expected {shape}")
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


# ---------------------------------------------------------------------------- adapting


def _prepare(positions: np.ndarray, visual: sp.csr_array, sentences: Sequence[str | None],
             vocabulary: Vocabulary, word_increment: int, scale: float,
             centre: np.ndarray) -> gibbs.PreparedData:
    """PreparedData of one home (positions in metres are scaled to the sampler's units)."""
    n = positions.shape[0]
    factor = np.array([scale, scale, 1.0, 1.0])
    return gibbs.PreparedData(
        positions=np.asarray(positions, dtype=np.float64) * factor,
        homes=np.zeros(n, dtype=np.int64),
        visual=stack_counts(visual),
        words=stack_counts(vocabulary.encode(list(sentences), word_increment)),
        n_homes=1, offsets=np.array([0, n], dtype=np.int64), position_scale=scale,
        map_centres=(np.asarray(centre, dtype=np.float64) * factor)[None, :],
    )


@dataclass(frozen=True)
class _SharedPrior:
    """The knowledge as the prior of the shared part (``joint``): Dir(A φ̄), Dir(A_g Ḡ_0)."""

    visual: np.ndarray  # (L, D)
    words: np.ndarray  # (L, V)
    g0: np.ndarray  # (L,)

    @classmethod
    def of(cls, knowledge: Knowledge) -> _SharedPrior:
        hyper = knowledge.hyperparameters

        def filled(a: np.ndarray, default: float) -> np.ndarray:
            a = np.asarray(a, dtype=np.float64)
            return np.where(np.isfinite(a) & (a > 0), a, default)

        a_v = filled(knowledge.concentration_visual, hyper.delta_visual)
        a_w = filled(knowledge.concentration_words, hyper.delta_word)
        a_g = float(filled(np.array([knowledge.concentration_g0]), hyper.gamma)[0])
        return cls(visual=a_v[:, None] * np.exp(knowledge.log_phi_visual),
                   words=a_w[:, None] * np.exp(knowledge.log_phi_words),
                   g0=a_g * np.exp(knowledge.log_g0))


#: A concept whose knowledge weight G_0 is below this is one the experienced homes did not use:
#: the knowledge holds no information about it (its φ is a prior draw), see :func:`_learn_free_concepts`.
FREE_CONCEPT_WEIGHT = 1e-3


def _own_names_to_free_concepts(data: gibbs.PreparedData, state: gibbs.GibbsState, knowledge: Knowledge,
                                n_known: int) -> bool:
    """Give each name first heard in this home a concept of its own, one the knowledge does not use.

    The samples standing for such a name (:func:`gibbs.sample_names`: those that say it, and the
    untaught samples of the regions where it is said most) move together to a free concept, unless
    they already hold one alone. Left to the sampler, a new name lands in the concept of another
    place (every concept gives an unheard word the same tiny mass), whose visual distribution —
    δ^v = 3·10^5 pseudo-counts of that place's views — then sends the rest of the room's views to the
    transferred concept of its kind ("bedroom"). Returns whether any sample moved."""
    if knowledge.variant != "exact" or data.words.shape[1] <= n_known:
        return False
    hyper = knowledge.hyperparameters
    verdict = gibbs.naming_verdicts(data, state, hyper)
    candidate = np.zeros(data.words.shape[1], dtype=bool)
    candidate[n_known:] = verdict[n_known:] != NOT_A_NAME
    names = gibbs.sample_names(data, state.regions, hyper, named=candidate)
    free = np.exp(knowledge.log_g0) < FREE_CONCEPT_WEIGHT
    moved = False
    for word in np.unique(names[names >= 0]):  # a loop over the home's few new names
        rows = names == word
        held = np.unique(state.concepts[rows])
        if held.size == 1 and free[held[0]] and not (state.concepts[~rows] == held[0]).any():
            continue
        open_slots = np.flatnonzero(free & (np.bincount(state.concepts[~rows], minlength=free.size) == 0))
        if open_slots.size == 0:
            break
        state.concepts[rows] = open_slots[0]
        moved = True
    return moved


def _learn_free_concepts(data: gibbs.PreparedData, state: gibbs.GibbsState, hyper: TransferHyperparameters,
                         settings: gibbs.SamplerSettings, rng: np.random.Generator) -> None:
    """Learn φ of the concepts the knowledge does not use from this home, then redraw the home's θ,
    G_e, π and regions given them (exact sampler, shared part otherwise fixed).

    The posterior of such a concept's φ given the experienced homes is its prior, so given this home
    too it is the prior updated by this home: φ_l ~ Dir(α + table counts of this home), tables ~
    CRT(n, δ φ_l) — the global step of the exact sampler restricted to these concepts. Then θ | φ,
    as the partially collapsed order requires. G_0 (``state.log_g0``) is the knowledge's.
    """
    if settings.variant != "exact":
        return
    unused = np.exp(state.log_g0) < FREE_CONCEPT_WEIGHT  # G_0 is the knowledge's: fixed while adapting
    if not unused[state.concepts].any():
        return
    stats = gibbs.sufficient_statistics(data, state, hyper)
    free = np.flatnonzero(unused & (stats.concepts[0] > 0))
    tables_v = HierarchicalMultinomial.sample_tables(stats.visual[:, free], state.log_phi_v[free],
                                                     hyper.delta_visual, rng)
    state.log_phi_v[free] = HierarchicalMultinomial.sample_shared(tables_v, hyper.alpha_visual, rng)
    tables_w = HierarchicalMultinomial.sample_tables(stats.words[:, free], state.log_phi_w[free],
                                                     hyper.delta_word, rng)
    state.log_phi_w[free] = HierarchicalMultinomial.sample_shared(tables_w, hyper.alpha_word, rng)
    gibbs.home_step(data, state, stats, hyper, settings, rng)


def _sweep(data: gibbs.PreparedData, state: gibbs.GibbsState, hyper: TransferHyperparameters,
           settings: gibbs.SamplerSettings, rng: np.random.Generator, prior: _SharedPrior | None,
           n_known: int) -> None:
    """One sweep for one home: shared part fixed (``prior`` None) or learnt with ``prior``.

    Learning the shared part with pruning re-decides about the knowledge's words (only those the
    knowledge kept can stay: ``state.candidate_words``); the words first heard in this home are
    kept during the sweeps and judged in the home afterwards (:func:`_judge_new_words`)."""
    if prior is None:
        gibbs.sweep(data, state, hyper, settings, rng, swaps=False)
        _learn_free_concepts(data, state, hyper, settings, rng)
        return
    gibbs.local_step(data, state, settings, rng)
    stats = gibbs.sufficient_statistics(data, state, hyper)
    if settings.variant == "reference":  # the authors' order: home, then shared from pooled counts
        gibbs.home_step_reference(data, state, stats, hyper, settings, rng)
        state.log_phi_v = log_dirichlet(prior.visual + stats.visual.sum(0), rng)
        state.log_phi_w = log_dirichlet(prior.words + stats.words.sum(0), rng)
        state.log_g0 = log_dirichlet(prior.g0 + stats.concepts.sum(0), rng)
    else:  # exact: shared given table counts (θ, G_e integrated out), then the home
        tables_v = HierarchicalMultinomial.sample_tables(stats.visual, state.log_phi_v, hyper.delta_visual,
                                                         rng)
        state.log_phi_v = log_dirichlet(prior.visual + tables_v, rng)
        tables_w = HierarchicalMultinomial.sample_tables(stats.words, state.log_phi_w, hyper.delta_word, rng)
        state.log_phi_w = log_dirichlet(prior.words + tables_w, rng)
        tables_g = sample_crt(stats.concepts, hyper.gamma * np.exp(state.log_g0)[None, :], rng).sum(axis=0)
        state.log_g0 = log_dirichlet(prior.g0 + tables_g, rng)
        gibbs.home_step(data, state, stats, hyper, settings, rng)
    if settings.prune and settings.variant == "exact":
        known = state.candidate_words if state.candidate_words is not None else state.word_mask
        state.word_mask = _home_word_mask(gibbs.naming_verdicts(data, state, hyper), known, n_known)
    elif settings.prune:
        gibbs.prune(state, hyper, settings)
        state.word_mask[n_known:] = True


def _initial_state(data: gibbs.PreparedData, knowledge: Knowledge, settings: gibbs.SamplerSettings,
                   n_known: int, rng: np.random.Generator) -> gibbs.GibbsState:
    """The state a new home starts from: the knowledge's shared part; regions by k-means; θ, G_e
    drawn from their priors given the shared part; π uniform (so that the first assignments follow
    the regions and the knowledge's visual distributions); new words' θ^w equal in every concept
    (they carry no information until samples are assigned)."""
    hyper = knowledge.hyperparameters
    L, K = hyper.n_concepts, hyper.n_regions
    n = data.n_samples
    x = data.positions
    k = min(K, n)
    best = np.inf
    for _ in range(10 if settings.variant == "reference" else 1):
        centres, labels = kmeans2(x, k, minit="++", seed=int(rng.integers(0, 2**31 - 1)))
        cost = ((x - centres[labels]) ** 2).sum()
        if cost < best:
            best, best_centres, best_labels = cost, centres, labels
    means = np.empty((1, K, 4))
    means[0, :k] = best_centres
    means[0, k:] = best_centres[rng.integers(0, k, size=K - k)]
    state = gibbs.GibbsState(
        concepts=np.zeros(n, dtype=np.int64), regions=best_labels.astype(np.int64),
        log_g=np.full((1, L), -math.log(L)), log_g0=knowledge.log_g0.copy(),
        log_pi=np.full((1, L, K), -math.log(K)), means=means,
        covariances=np.tile(100.0 * np.eye(4), (1, K, 1, 1)),
        log_theta_v=np.broadcast_to(knowledge.log_phi_visual, (1, L, knowledge.n_features)).copy(),
        log_theta_w=np.broadcast_to(knowledge.log_phi_words, (1, L, knowledge.n_words)).copy(),
        log_phi_v=knowledge.log_phi_visual.copy(), log_phi_w=knowledge.log_phi_words.copy(),
        word_mask=knowledge.word_mask.copy(),
    )
    stats = gibbs.sufficient_statistics(data, state, hyper)
    for name in ("visual", "words", "concepts", "regions_by_concept"):
        setattr(stats, name, np.zeros_like(getattr(stats, name)))  # new arrays: the sampler caches n^v
    if settings.variant == "reference":
        gibbs.home_step_reference(data, state, stats, hyper, settings, rng)
    else:
        gibbs.home_step(data, state, stats, hyper, settings, rng)
    state.log_pi = np.full((1, L, K), -math.log(K))
    _init_new_words(state, n_known, np.zeros(L), hyper.delta_word)
    return state


def _init_new_words(state: gibbs.GibbsState, n_known: int, word_counts: np.ndarray,
                    delta_word: float) -> None:
    """Start the θ^w of the words first heard in this home at their posterior mean.

    Given the current assignments, E[θ^w_{l,k}] = δ^w φ^w_{l,k} / (δ^w + N_l) for a word k that no
    sample of concept l has said yet (N_l: the words said in concept l; ``word_counts``, (L,)):
    a concept that already holds many words leaves less room for a new one — the Dirichlet's own
    crowding. (A draw from that Dirichlet would hide it under the spread of a Gamma(α^w) variate,
    hundreds of nats for S^w = 5000 counts, and send the first sample that says the word to a
    random concept.) Before any assignment (``adapt``) this is the same in every concept, so the
    first samples that say a new word are placed by what they see and where they are.
    """
    if state.log_theta_w.shape[2] <= n_known:
        return
    log_a = math.log(delta_word) + state.log_phi_w[:, n_known:]  # (L, new)
    state.log_theta_w[0, :, n_known:] = log_a - np.log(delta_word + np.asarray(word_counts, float))[:, None]


def _home_word_mask(verdict: np.ndarray, known_mask: np.ndarray, n_known: int) -> np.ndarray:
    """The words a home may use, (V,) bool: the first ``n_known`` (the knowledge's words) if the
    knowledge kept them (``known_mask``) or the home names a place with them (``verdict`` NAME);
    the words first heard in the home unless the home shows they are no name (NOT_A_NAME)."""
    from spco.model.pruning import NAME, NOT_A_NAME

    mask = verdict != NOT_A_NAME
    mask[:n_known] = np.asarray(known_mask[:n_known], dtype=bool) | (verdict[:n_known] == NAME)
    return mask


def _judge_new_words(state: gibbs.GibbsState, knowledge: Knowledge, n_known: int,
                     data: gibbs.PreparedData | None = None) -> None:
    """With pruning, decide about the home's words.

    Exact variant (given the home's ``data``): the naming rule judged in this home
    (:func:`gibbs.naming_verdicts` on its samples' regions). A word the knowledge kept stays kept;
    a word it pruned is kept again if the home says it mostly at one place (a home-specific name
    such as ``study`` that the experienced homes used differently); a word first heard here is
    kept unless the home shows that it is said alike everywhere — a name taught once is usable at
    once. Reference variant: the words first heard here are judged by the authors' score on the
    home's θ^w and G_e."""
    if not knowledge.prune_words:
        return
    state.word_mask = state.word_mask.copy()
    if knowledge.variant == "exact" and data is not None:
        verdict = gibbs.naming_verdicts(data, state, knowledge.hyperparameters)
        state.word_mask = _home_word_mask(verdict, knowledge.word_mask, n_known)
        return
    if state.log_theta_w.shape[2] <= n_known:
        return
    score = "kl" if knowledge.variant == "reference" else "mi"
    theta = np.exp(state.log_theta_w[0])
    weights = np.exp(state.log_g[0])
    threshold = knowledge.hyperparameters.pruning_threshold(score)
    keep = words_to_keep(theta, weights / weights.sum(), threshold, score)
    state.word_mask[n_known:] = keep[n_known:]


#: Share of a home's samples that the home's own names (concepts the knowledge does not use) may
#: take in regions where none of them was said before :func:`_warn_if_own_names_spread` warns.
OWN_NAMES_SPREAD_WARNING = 0.25


class OwnNamesSpreadWarning(UserWarning):
    """The home's own names took over much of the home, far from where they were said."""


def _warn_if_own_names_spread(data: gibbs.PreparedData, state: gibbs.GibbsState, knowledge: Knowledge,
                              home_name: str) -> float:
    """Warn when the concepts of the home's own names (those the knowledge does not use) hold more
    than :data:`OWN_NAMES_SPREAD_WARNING` of the home's samples in regions where no sentence of
    theirs was said; returns that share.

    A concept the knowledge does not use learns its views from this home alone; when the
    knowledge's concepts explain the home's views poorly (a knowledge from few homes or few sweeps),
    such a concept explains the other rooms' views better than they do and gathers them sweep after
    sweep: one `teach` of "study room" at the entrance then names the kitchen and the bedroom "study
    room" too. (Measured: a knowledge of 3 synthetic homes and 12 sweeps, one teaching: 92 of the
    home's 120 samples, 72 outside the taught room; of 16 homes and 100 sweeps: the taught room's 20
    samples and none outside.)

    Diagnosis (``benchmarks/own_name_spread.py``): the rooms leaving the knowledge's concepts is the
    model's posterior given a fixed knowledge (θ^v is held at φ^v by δ^v, so those concepts cannot
    adapt to the home's views), but their gathering in the *named* concept is the sampler's: the
    assignment with the other rooms in other, unnamed free concepts scores 4·10^3 nats higher (3
    homes) and the sampler keeps it once there, yet no single-sample move opens an empty free concept
    (its φ^v is a prior draw). With 16 homes that assignment scores 1.6·10^4 nats higher than the
    sampler's, and in it `what` answers no transferred name at any room: a sampler that found it would
    trade this warning for homes that lose their names, so the sampler is left as it is."""
    free = np.exp(knowledge.log_g0) < FREE_CONCEPT_WEIGHT
    in_free = free[state.concepts]
    if not in_free.any():
        return 0.0
    taught = np.diff(data.words.indptr) > 0
    said_regions = np.zeros(int(state.regions.max()) + 1, dtype=bool)
    said_regions[state.regions[taught & in_free]] = True
    spread = float(np.mean(in_free & ~said_regions[state.regions]))
    if spread > OWN_NAMES_SPREAD_WARNING:
        said = np.asarray(data.words[taught & in_free].sum(axis=0)).ravel() > 0
        names = [knowledge.vocabulary.words[w] for w in np.flatnonzero(said & state.word_mask)]
        shown = ", ".join(repr(n) for n in names[:4]) or "the home's own names"
        verb = "stands" if len(names) == 1 else "stand"
        warnings.warn(f"{home_name}: {shown} now {verb} for {spread:.0%} of the home's samples in regions "
                      "where they were never said: the knowledge explains this home's views poorly, so a "
                      "place learnt from this home alone takes in other rooms. Check `spco what` at other "
                      "places; teach the places of the home by their names, or fit the knowledge on more "
                      "homes or sweeps", OwnNamesSpreadWarning, stacklevel=3)
    return spread


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
    _check_visual_dimension(knowledge, train.visual.shape[1], home.source or home.name)
    fit_of_views = check_view_fit(knowledge, train.visual, home.name)
    if home.name in (knowledge.provenance.get("homes") or []):
        warnings.warn(f"home {home.name!r} has the name of a home this knowledge was learnt from: if it is "
                      "that home, it is not new to the knowledge and its answers say little about a new "
                      "home (spco synth: write new homes with another --seed than the experienced ones)",
                      ExperiencedHomeWarning, stacklevel=2)
    extended = knowledge.extended(train.sentences)
    n_known = knowledge.n_words
    hyper = extended.hyperparameters
    settings = gibbs.SamplerSettings.create(extended.variant, extended.prune_words, learn_shared=False)
    rng = _as_generator(random_state)
    scale = gibbs.CM_PER_M if extended.variant == "reference" else 1.0
    centre = _map_centre(home)
    data = _prepare(train.positions, train.visual, train.sentences, extended.vocabulary,
                    extended.word_increment, scale, centre)
    state = _initial_state(data, extended, settings, n_known, rng)
    prior = None
    if joint:
        prior = _SharedPrior.of(extended)
        state.candidate_words = extended.word_mask.copy()
    iterator: Iterable[int] = range(int(n_iterations))
    if progress:
        from tqdm.auto import tqdm

        iterator = tqdm(iterator, desc=f"adapt {home.name}", unit="sweep", leave=False)
    _judge_new_words(state, extended, n_known, data)
    if prior is None and _own_names_to_free_concepts(data, state, extended, n_known):
        _learn_free_concepts(data, state, hyper, settings, rng)
    averaged = set(thinned_sweeps(int(n_iterations)))
    average = ParameterAverage(data.homes, data.position_scale)
    for iteration in iterator:
        _sweep(data, state, hyper, settings, rng, prior, n_known)
        if iteration in averaged:
            average.add(state)
    _judge_new_words(state, extended, n_known, data)
    if prior is None:
        _warn_if_own_names_spread(data, state, extended, home.name)
    seconds = time.perf_counter() - start
    record: dict[str, Any] = {
        "knowledge_checksum": knowledge.checksum,
        "knowledge_homes": list(knowledge.provenance.get("homes") or []),
        "adapt": {"seed": _seed_of(random_state), "n_iterations": int(n_iterations), "joint": bool(joint),
                  "seconds": round(seconds, 3), "new_words": list(extended.vocabulary.words[n_known:])},
        "teach_updates": 0,
        "view_fit": fit_of_views,
        "spco_version": _version(),
        "created": _now(),
    }
    record.update(provenance or {})
    return HomeModel(name=home.name, knowledge=extended, state=state, ids=train.ids,
                     positions=train.positions, visual=sp.csr_array(train.visual, dtype=np.int64),
                     sentences=tuple(train.sentences), extent=home.extent, map_centre=centre,
                     n_knowledge_words=n_known, joint=bool(joint), provenance=record,
                     posterior=average.result(state))


# ---------------------------------------------------------------------------- teaching


def _clean_sentence(sentence: str | None) -> str | None:
    if sentence is None:
        return None
    if not isinstance(sentence, str):
        raise ConfigurationError(f"a sentence must be a string or None, got {sentence!r}")
    return sentence.strip() or None


def _visual_row(visual: Any, n_features: int) -> sp.csr_array:
    """One observation's visual counts as a (1, D) int64 CSR row, validated."""
    if visual is None:
        raise ConfigurationError("a new observation needs its view: visual counts (the view's features) or "
                                 "an image")
    if sp.issparse(visual):
        row = sp.csr_array(visual)
    else:
        dense = np.asarray(visual)
        if dense.ndim == 2 and dense.shape[0] == 1:
            dense = dense[0]
        if dense.ndim != 1:
            raise ConfigurationError(f"visual counts of one observation must be a vector, got shape "
                                     f"{dense.shape}")
        if not np.issubdtype(dense.dtype, np.number):
            raise ConfigurationError("visual counts must be numbers")
        row = sp.csr_array(dense[None, :])
    if row.shape != (1, n_features):
        raise ConfigurationError(f"visual counts have {row.shape[1]} values, the home's views {n_features}")
    out = sp.csr_array(validate_visual_counts(row, n_features), dtype=np.int64)  # the library's checks
    out.eliminate_zeros()
    return out


def _pose(x: float, y: float, theta: float) -> np.ndarray:
    pose = np.array([x, y, math.sin(theta), math.cos(theta)], dtype=np.float64)
    if not (np.isfinite(pose).all() and math.isfinite(theta)):
        raise ConfigurationError(f"the pose must be finite numbers, got x={x!r}, y={y!r}, theta={theta!r}")
    if abs(theta) > 2 * math.pi + 1e-9:
        raise ConfigurationError(f"theta = {theta:g} is more than a full turn: the heading is in radians "
                                 f"(degrees? {theta:g}° = {math.radians(theta):.4f} rad)")
    return pose


#: How far beyond its map (in map sizes) a pose is still answered (with a warning) by :func:`what`.
FAR_OUTSIDE_MAP = 1.0


def map_bounds(home: HomeModel) -> tuple[float, float, float, float]:
    """``(x_min, x_max, y_min, y_max)`` of the home's map: its extent, or the box around its samples."""
    if home.extent is not None:
        return tuple(float(v) for v in home.extent)  # type: ignore[return-value]
    xy = home.positions[:, :2]
    return float(xy[:, 0].min()), float(xy[:, 0].max()), float(xy[:, 1].min()), float(xy[:, 1].max())


def pose_outside_map(home: HomeModel, x: float, y: float) -> str | None:
    """``None`` if ``(x, y)`` lies on the home's map (:func:`map_bounds`), else a sentence saying how far
    outside it is. Raises :class:`ConfigurationError` when the pose is more than
    :data:`FAR_OUTSIDE_MAP` map sizes beyond the map: the robot has learnt nothing about such a place,
    and the region Gaussians' densities there are all zero in floating point."""
    x0, x1, y0, y1 = map_bounds(home)
    size = max(x1 - x0, y1 - y0, 1.0)
    beyond = max(x0 - x, x - x1, y0 - y, y - y1, 0.0)
    if beyond == 0.0:
        return None
    where = (f"the pose ({x:g}, {y:g}) is {beyond:.3g} m outside the map of home {home.name!r} "
             f"(x {x0:g}…{x1:g}, y {y0:g}…{y1:g} m)")
    if beyond > FAR_OUTSIDE_MAP * size:
        raise ConfigurationError(f"{where}: the robot has learnt nothing there; give a pose on the map, "
                                 f"in metres, in the map frame the home was recorded in")
    return where


def teach(
    home: HomeModel,
    sentences: Mapping[int, str | None] | None = None,
    observations: Sequence[Observation] = (),
    n_sweeps: int = DEFAULT_TEACH_SWEEPS,
    random_state: int | np.random.Generator | None = None,
) -> HomeModel:
    """Teach the home: new sentences for known samples, new observations; an incremental update.

    Parameters
    ----------
    home: the home model to update (it is not modified: a new one is returned).
    sentences: sample id -> sentence (``None`` or ``""`` forgets the sentence of that sample).
    observations: new samples (:class:`Observation`), appended with new ids.
    n_sweeps: Gibbs sweeps run from the home's current state (10 by default, a few tens of
        milliseconds for a home of 300 samples); prediction then uses the average of the last
        of them (:func:`~spco.model.posterior.thinned_sweeps`), with 0 the state's own draw.
    random_state: seed or Generator.

    New words grow the vocabulary (:meth:`Knowledge.extended`); everything learnt so far is kept:
    the sweeps start from the home's assignments and parameters, with the shared part fixed (or
    learnt with the knowledge as prior if the home was adapted with ``joint=True``).
    """
    if not isinstance(home, HomeModel):
        raise ConfigurationError("teach() expects a HomeModel (from adapt or load_home_model)")
    if not isinstance(n_sweeps, int | np.integer) or n_sweeps < 0:
        raise ConfigurationError(f"n_sweeps must be an integer >= 0, got {n_sweeps!r}")
    sentences = dict(sentences or {})
    observations = list(observations)
    if not sentences and not observations:
        raise ConfigurationError("nothing to teach: give a sentence for a sample or a new observation")
    start = time.perf_counter()
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
        new_sentences[index[int(sample_id)]] = _clean_sentence(sentence)
    ids = list(home.ids.tolist())
    taken = set(ids)
    poses, rows = [], []
    for obs in observations:
        if not isinstance(obs, Observation):
            raise ConfigurationError(f"observations must be Observation objects, got {type(obs).__name__}")
        new_id = max(taken) + 1 if obs.id is None else int(obs.id)
        if new_id in taken:
            raise ConfigurationError(f"home {home.name!r} already has a sample with id {new_id}")
        taken.add(new_id)
        ids.append(new_id)
        poses.append(_pose(obs.x, obs.y, obs.theta))
        rows.append(_visual_row(_view_counts(home.knowledge, obs.visual, obs.image),
                                home.knowledge.n_features))
        new_sentences.append(_clean_sentence(obs.sentence))
    positions = np.vstack([home.positions, *poses]) if poses else home.positions
    visual = home.visual
    if rows:
        visual = sp.csr_array(sp.vstack([home.visual, *rows], format="csr"), dtype=np.int64)

    knowledge = home.knowledge.extended(new_sentences)
    added = knowledge.n_words - home.knowledge.n_words
    state = _copy_state(home.state)
    if added:
        hyper = knowledge.hyperparameters
        log_new = math.log(hyper.alpha_word / hyper.delta_word)
        L = knowledge.n_concepts
        if home.joint:  # the shared part is the home's: grow it like the knowledge
            phi_w = np.concatenate([state.log_phi_w, np.full((L, added), log_new)], axis=1)
            state.log_phi_w = phi_w - logsumexp(phi_w, axis=1, keepdims=True)
        else:
            state.log_phi_w = knowledge.log_phi_words.copy()
        state.log_theta_w = np.concatenate([state.log_theta_w, np.full((1, L, added), log_new)], axis=2)
        said = np.bincount(home.state.concepts, weights=np.asarray(home.data.words.sum(axis=1)).ravel(),
                           minlength=L)
        _init_new_words(state, home.knowledge.n_words, said, hyper.delta_word)
        state.word_mask = np.concatenate([state.word_mask, np.ones(added, dtype=bool)])
    if poses:
        extra = len(poses)
        state.concepts = np.concatenate([state.concepts, np.zeros(extra, dtype=np.int64)])
        state.regions = np.concatenate([state.regions, np.zeros(extra, dtype=np.int64)])
    data = _prepare(positions, visual, new_sentences, knowledge.vocabulary, knowledge.word_increment,
                    home.position_scale, home.map_centre)
    settings = gibbs.SamplerSettings.create(knowledge.variant, knowledge.prune_words, learn_shared=False)
    prior = None
    if home.joint:
        prior = _SharedPrior.of(knowledge)
        state.candidate_words = knowledge.word_mask[: home.n_knowledge_words].copy()
        state.candidate_words = np.concatenate([state.candidate_words,
                                                np.ones(knowledge.n_words - home.n_knowledge_words, bool)])
    rng = _as_generator(random_state)
    _judge_new_words(state, knowledge, home.n_knowledge_words, data)  # a taught name counts at once
    if prior is None and _own_names_to_free_concepts(data, state, knowledge, home.n_knowledge_words):
        _learn_free_concepts(data, state, knowledge.hyperparameters, settings, rng)
    averaged = set(thinned_sweeps(int(n_sweeps))) if n_sweeps else set()
    average = ParameterAverage(data.homes, data.position_scale)
    for iteration in range(int(n_sweeps)):
        _sweep(data, state, knowledge.hyperparameters, settings, rng, prior, home.n_knowledge_words)
        if iteration in averaged:
            average.add(state)
    _judge_new_words(state, knowledge, home.n_knowledge_words, data)
    if prior is None:
        _warn_if_own_names_spread(data, state, knowledge, home.name)
    provenance = dict(home.provenance)
    provenance["teach_updates"] = int(provenance.get("teach_updates", 0)) + 1
    provenance["updated"] = _now()
    provenance["last_teach"] = {"sentences": len(sentences), "observations": len(observations),
                                "new_words": list(knowledge.vocabulary.words[home.knowledge.n_words:]),
                                "n_sweeps": int(n_sweeps), "seed": _seed_of(random_state),
                                "seconds": round(time.perf_counter() - start, 4)}
    posterior = average.result(state) if average.n_samples else None
    return replace(home, knowledge=knowledge, state=state, ids=np.asarray(ids, dtype=np.int64),
                   positions=positions, visual=visual, sentences=tuple(new_sentences), provenance=provenance,
                   posterior=posterior)


def _copy_state(state: gibbs.GibbsState) -> gibbs.GibbsState:
    return gibbs.GibbsState(**{name: np.array(getattr(state, name), copy=True) for name in _STATE_ARRAYS})


# ---------------------------------------------------------------------------- questions


#: How many of the home's own teachings the model's p(m | name) weighs as, in :func:`where`.
WHERE_MODEL_WEIGHT = 1.0
#: ... and the home's regions in proportion to their samples (where a place taught a few times
#: could still be), once the name was taught in the home.
WHERE_ANYWHERE_WEIGHT = 1.0


def where(home: HomeModel, name: str, n: int = 10,
          random_state: int | np.random.Generator | None = None) -> PositionPrediction:
    """Poses ``(x, y, θ)`` to go to for the place ``name`` in ``home``.

    The region probabilities combine the model with the home's own teachings of the name:
    ``p(m | name) = (c_m + κ · p_model(m | name) + λ · u_m) / (c + κ + λ)``, where ``c_m`` counts the
    home's samples whose sentence holds the name and that sit in region m, ``c`` all of them, κ =
    :data:`WHERE_MODEL_WEIGHT`, ``p_model(m | name) ∝ Σ_l π_{l,m} θ^w_{l,name} G_l``
    (:func:`spco.prediction.region_posterior_for_name`), u_m the share of the home's samples in
    region m and λ = :data:`WHERE_ANYWHERE_WEIGHT` (0 for a name never taught in this home, which is
    answered by the model alone). A name taught once is answered with the region of that sample at
    about 0.6–0.65 (little evidence); each further teaching there makes it firmer.
    The poses are drawn from the answer regions — those at least half as probable as the best
    (a name taught at two places of the home finds both) — in proportion to their probability, at
    least one per region; each pose's ``weights`` entry is its share of the density p(x | name)
    among the ``n`` poses. Raises :class:`~spco.prediction.UnknownNameError` (with suggestions)
    for a name the home cannot use: never heard, or pruned as no name.
    ``name`` is read like a sentence (``"Living Room"``, ``"living-room"`` → ``living room``); a name
    never learnt as one term is its known words said together (``study + room``). ``learnt`` is
    False (and ``support`` low) when no such place was learnt in this home: the name is neither
    taught in the home nor carried by concepts holding its samples.
    """
    try:
        return _where(home, name, n, random_state)
    except UnknownNameError:
        hint = unused_word_hint(home, name)
        if hint is None:
            raise
        raise UnknownNameError(name, home.known_names, reason=hint) from None


def _where(home: HomeModel, name: str, n: int,
           random_state: int | np.random.Generator | None) -> PositionPrediction:
    """:func:`where` without the hint for unusable names."""
    from spco.prediction import (
        LEARNT_SUPPORT,
        draw_poses,
        name_support,
        query_indices,
        query_name,
        region_posterior_for_name,
    )

    if n < 0:
        raise ConfigurationError(f"the number of positions must be >= 0, got {n}")
    params, vocabulary = home.parameters, home.vocabulary
    model = region_posterior_for_name(params, 0, vocabulary, name)
    columns = query_indices(params, vocabulary, name)
    words = home.data.words[:, columns]  # type: ignore[index]
    said = np.asarray((words > 0).sum(axis=1)).ravel() == len(columns)  # every token of the name said
    counts = np.bincount(home.state.regions[said], minlength=model.size).astype(np.float64)
    probs = counts + WHERE_MODEL_WEIGHT * model
    if counts.sum() > 0:  # a place taught a few times could still be anywhere in the home
        anywhere = np.bincount(home.state.regions, minlength=model.size) / home.state.regions.size
        probs = probs + WHERE_ANYWHERE_WEIGHT * anywhere
    probs = probs / probs.sum()
    support = 1.0 if counts.sum() > 0 else name_support(params, 0, vocabulary, name)
    answer = np.flatnonzero(probs >= 0.5 * probs.max())
    answer = answer[np.argsort(-probs[answer], kind="stable")]
    share = probs[answer] / probs[answer].sum()
    per_region = np.floor(share * n).astype(np.int64)
    if n >= answer.size:
        per_region = np.maximum(per_region, 1)
    while per_region.sum() > n:
        per_region[np.argmax(per_region)] -= 1
    while per_region.sum() < n:
        per_region[np.argmax(share * n - per_region)] += 1
    regions = np.repeat(answer, per_region)
    samples, log_density, weights = draw_poses(params, 0, probs, regions, _as_generator(random_state))
    return PositionPrediction(name=query_name(vocabulary, params, name), region=int(answer[0]),
                              region_probabilities=probs, samples=samples, regions=regions,
                              log_density=log_density, weights=weights, mode="mixture", xy_only=False,
                              support=support, learnt=support >= LEARNT_SUPPORT)


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
    if index is None or bool(home.state.word_mask[index]):
        return None
    w = home.vocabulary.words[index]
    taught = [k for k, sentence in enumerate(home.sentences) if w in home.vocabulary.tokenize(sentence)]
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
    return (f"the word {w!r} is not used as a place name yet: it is taught at {len(taught)} sample(s) of "
            f"this home (id {shown}), too few to tell its place from the others (pruned as "
            f"uninformative); {more}")


def _view_counts(knowledge: Knowledge, visual: Any, image: Any) -> Any:
    """A view's counts: ``visual`` as given, or ``image`` through the knowledge's extractor."""
    if image is None:
        return visual
    if visual is not None:
        raise ConfigurationError("give a view either as visual counts or as an image, not both")
    if not knowledge.fitted_on_images:
        raise ConfigurationError("the knowledge of this home was fitted on visual count vectors, not on "
                                 "images: give the view's features (--visual), not an image")
    return knowledge.image_extractor().extract(image)


def what(home: HomeModel, x: float, y: float, theta: float, visual: Any = None,
         top_k: int = 3, image: Any = None, unsure_below: float = UNSURE_BELOW) -> NamePrediction:
    """The ``top_k`` place names at pose ``(x, y, θ)``, with the view's visual counts if given.

    The probabilities are honest (:mod:`spco.confidence`): a view counts as
    :data:`~spco.confidence.VIEW_EFFECTIVE_COUNTS` draws, a concept nobody named has no name; an
    answer below ``unsure_below`` (default 0.5) is flagged ``unsure``.

    A pose off the home's map is answered with a :class:`UserWarning`, one more than
    :data:`FAR_OUTSIDE_MAP` map sizes off it is refused (:func:`pose_outside_map`); ``θ`` must be in
    radians (``|θ| ≤ 2π``).

    ``image`` (a path or an array) gives the view as an image instead, for a home whose knowledge
    was fitted on images: its extractor computes the counts.
    Without a view the names come from the position alone (``use_vision=False``). The returned
    :class:`~spco.prediction.NamePrediction` holds one row: ``words[0]``, ``probabilities[0]``
    (p(w | x, v)), ``scores[0]`` (the ranking score), ``confidence[0]`` and ``unsure[0]``.
    """
    pose = _pose(x, y, theta)[None, :]
    outside = pose_outside_map(home, x, y)
    if outside is not None:
        warnings.warn(f"{outside}; the names are extrapolated from the nearest regions", stacklevel=2)
    visual = _view_counts(home.knowledge, visual, image)
    row = None if visual is None else _visual_row(visual, home.knowledge.n_features)
    return predict_names_honestly(
        home.parameters, 0, home.vocabulary, pose, row, top_k=top_k, use_vision=row is not None,
        weighting=home.weighting,  # type: ignore[arg-type]
        free=np.exp(home.knowledge.log_g0) < FREE_CONCEPT_WEIGHT,
        word_counts=concept_word_counts(home.data.words, home.state.concepts, home.knowledge.n_concepts),
        alpha_word=home.hyperparameters.alpha_word, unsure_below=unsure_below)


# ---------------------------------------------------------------------------- files of features


def read_visual_vector(path: str | PathLike[str], n_features: int | None = None,
                       scale: float | None = None) -> np.ndarray:
    """One view's visual features from a file, as a (D,) int64 count vector.

    Accepted: ``.npy`` (a vector or a 1-row matrix), ``.npz`` (one array, or a sparse 1-row matrix
    saved with ``scipy.sparse.save_npz``), or text (``.csv``, ``.txt``: numbers separated by
    newlines, commas or spaces — the SIGVerse ``vision_fc7_normalized/<i>.csv`` files). With
    ``scale``, real-valued features become counts ``floor(max(f, 0) × scale)``; without, the
    values must be non-negative whole numbers. Raises :class:`~spco.errors.DataFormatError`.
    """
    from spco.data.plain import features_to_counts

    file = Path(path).expanduser()
    if not file.is_file():
        raise DataFormatError(file, "no such visual feature file")
    try:
        if file.suffix in (".npy", ".npz"):
            from spco.data.plain import _load_visual_file

            raw = _load_visual_file(file)
            values = np.asarray(raw.toarray() if sp.issparse(raw) else raw, dtype=np.float64)
        else:
            text = file.read_text(encoding="utf-8-sig")
            tokens = text.replace(",", " ").split()
            values = np.array([float(t) for t in tokens], dtype=np.float64)
    except DataFormatError:
        raise
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise DataFormatError(file, f"not a readable feature vector ({exc})") from None
    if values.ndim == 2 and values.shape[0] == 1:
        values = values[0]
    if values.ndim != 1 or values.size == 0:
        raise DataFormatError(file, f"expected one feature vector, got shape {values.shape}")
    if n_features is not None and values.size != n_features:
        raise DataFormatError(file, f"has {values.size} values; the model's views have {n_features}")
    if not np.isfinite(values).all():
        raise DataFormatError(file, "holds NaN or infinite values")
    if scale is not None:
        return np.asarray(features_to_counts(values, scale), dtype=np.int64)
    if (values < 0).any() or (values != np.floor(values)).any():
        raise DataFormatError(file, "holds negative or non-integer values; visual counts must be whole "
                              "numbers >= 0 (for real-valued CNN features pass a visual scale, e.g. 5)")
    return values.astype(np.int64)


# ---------------------------------------------------------------------------- inspecting files


def model_file_format(path: str | PathLike[str]) -> str | None:
    """:data:`KNOWLEDGE_FORMAT` or :data:`HOME_FORMAT` if ``path`` is such a file (by its header), else
    ``None`` (a folder, a cache file, another program's file: not verified here)."""
    file = Path(path).expanduser()
    if not file.is_file():
        return None
    try:
        with np.load(file, allow_pickle=False) as archive:
            if "header" not in archive.files:
                return None
            header = json.loads(archive["header"].tobytes().decode("utf-8"))
    except Exception:  # not an .npz archive with a JSON header: not a model file
        return None
    found = header.get("format") if isinstance(header, dict) else None
    return found if found in (KNOWLEDGE_FORMAT, HOME_FORMAT) else None


def describe_model_file(path: str | PathLike[str]) -> dict[str, Any]:
    """What a knowledge or home file holds, for people and scripts (``spco inspect FILE``).

    Keys: ``file``, ``kind`` (``"knowledge"`` or ``"home"``), ``model``, ``visual_dimension``,
    ``extractor`` (the feature extractor recorded with the views, or ``None``), ``vocabulary``,
    ``kept_names`` (the words usable as place names), ``homes`` (the experienced homes), the view fit
    (:func:`view_fit`) and the ``provenance``; a home file adds ``home``, ``samples``, ``taught`` and
    ``extent``. Raises :class:`~spco.errors.ModelFileError` for a file that is neither (or broken).
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
        "view_fit": view, "provenance": provenance,
    }
    if kind == HOME_FORMAT:
        info.update({"home": home.name, "samples": home.n_samples, "taught": home.n_taught,
                     "extent": None if home.extent is None else list(home.extent)})
    return info

