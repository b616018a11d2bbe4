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
assumed-density filtering: exact if that posterior were Dirichlet. A knowledge summarising fewer
than three samples has no spread; its concentration then defaults to δ^v, δ^w and γ (the knowledge
weighs as much as one home).

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

Files
-----
Knowledge (``.spco``, format ``spco-knowledge``) and home (``.spco``, format ``spco-home``) files
are NumPy ``.npz`` archives read with ``allow_pickle=False``: arrays plus a ``header`` array holding
a UTF-8 JSON document with the format name, ``format_version`` (1), the spco version, the
hyperparameters, the vocabulary, provenance, a sha256 checksum of every array and a ``checksum`` of
the whole content (header and arrays). They are written to a temporary file in the target's folder,
flushed and renamed into place (atomic), and never replace an existing file unless asked
(``overwrite=True``, ``--force``). A missing, truncated, edited or foreign file, or one written by
a newer spco, raises :class:`~spco.errors.ModelFileError` naming the file and the problem.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import time
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

from spco.data.environment import Corpus, Environment, Extent
from spco.data.language import Vocabulary
from spco.errors import ConfigurationError, DataFormatError, ModelFileError
from spco.model import gibbs
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.io import _checksum, write_npz_atomic
from spco.model.observations import HierarchicalMultinomial
from spco.model.parameters import ConceptParameters
from spco.model.pruning import words_to_keep
from spco.model.random import log_dirichlet, sample_crt, stack_counts
from spco.model.transfer import SpatialConceptModel, SpCoTransfer, export_parameters
from spco.prediction import NamePrediction, PositionPrediction, predict_names, predict_positions

__all__ = [
    "DEFAULT_ADAPT_ITERATIONS",
    "DEFAULT_TEACH_SWEEPS",
    "FORMAT_VERSION",
    "HOME_FORMAT",
    "KNOWLEDGE_FORMAT",
    "MODELS",
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
#: Version of both file layouts written by this module; newer files are refused.
FORMAT_VERSION = 1

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
    if isinstance(random_state, np.random.Generator):
        return random_state
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
    """Write ``arrays`` and ``header`` (+ array and content checksums) to ``path`` atomically."""
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
        of φ^v_l, φ^w_l (moment-matched over the averaged samples; NaN: unknown).
    concentration_g0: the same for G_0 (NaN: unknown).
    vocabulary: the words of φ^w's columns.
    word_increment: S^w, the count of each word occurrence.
    hyperparameters: the model's hyperparameters.
    variant: the sampler (``"exact"`` or ``"reference"``); prune_words: "+MI".
    provenance: homes, seed, iterations, samples averaged, spco version, time of the fit, ...
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
        return "\n".join(lines)


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
    chain still gives up to three samples."""
    window = max(1, int(n_iterations * fraction))
    step = max(1, min(every, window // 3))
    return sorted(range(n_iterations - 1, n_iterations - 1 - window, -step))


def _concentration(samples: np.ndarray) -> np.ndarray:
    """Moment-matched Dirichlet concentration of each row: samples (S, L, D) -> (L,) (NaN if S < 3)."""
    if samples.shape[0] < 3:
        return np.full(samples.shape[1], np.nan)
    mean = samples.mean(axis=0)
    var = samples.var(axis=0, ddof=1).sum(axis=-1)
    spread = (mean * (1.0 - mean)).sum(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = spread / var - 1.0
    return np.where(np.isfinite(a) & (a > 0), a, np.nan)


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
    corpus: the experienced homes (a :class:`~spco.data.Corpus`).
    model: one of :data:`MODELS` (default ``"spcotransfer+mi"``).
    n_iterations: Gibbs sweeps (200 as in the paper).
    random_state: seed or Generator.
    progress: show a progress bar on standard error.
    hyperparameters: default: the paper's.
    summary_fraction, summary_every: which sweeps are averaged (see :func:`summary_iterations`).
    provenance: extra entries for the knowledge's provenance (e.g. the data path).
    engine: where the homes' shards run (:func:`spco.engines.make_engine`): ``None`` in this
        process, ``"ray"`` or an engine object such as ``RayEngine(shards=4, address="auto")``.

    Returns
    -------
    The :class:`Knowledge`; its ``provenance`` records the homes, the seed, the iterations, the
    samples averaged, the fit time and the spco version.
    """
    if model not in MODELS:
        raise ConfigurationError(f"unknown model {model!r}; choose one of {', '.join(MODELS)}")
    if not isinstance(corpus, Corpus):
        raise ConfigurationError("fit_knowledge() expects a spco.data.Corpus")
    variant, prune = MODELS[model]
    estimator = SpCoTransfer(hyperparameters, variant=variant, prune_words=prune, n_iterations=n_iterations,
                             random_state=random_state)
    hyper = estimator._validate()
    if not (0 < summary_fraction <= 1) or summary_every < 1:
        raise ConfigurationError("summary_fraction must be within (0, 1] and summary_every >= 1")
    if len(corpus.vocabulary) == 0:
        raise DataFormatError(None, f"no taught sentence in the {len(corpus)} experienced home(s) "
                              f"({', '.join(corpus.names[:5])}): there are no place names to learn")
    settings = estimator._settings()
    rng = _as_generator(random_state)
    scale = gibbs.CM_PER_M if variant == "reference" else 1.0
    data = SpatialConceptModel._prepare(corpus, scale)
    keep = set(summary_iterations(n_iterations, summary_fraction, summary_every))
    start = time.perf_counter()
    state = gibbs.initialize(data, len(corpus.vocabulary), hyper, settings, rng)
    by_iteration: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n_iterations, desc=f"fit ({model})", unit="sweep", leave=False)
    from spco.engines import LocalEngine, make_engine

    run = (make_engine(engine) if isinstance(engine, str) else (engine or LocalEngine())).start(
        data, state, hyper, settings, rng)

    def after_sweep(iteration: int, _: float) -> None:  # (a restarted engine repeats sweeps)
        if bar is not None:
            bar.update(1)
        if iteration in keep:
            shared = run.shared
            by_iteration[iteration] = (shared.log_phi_v.copy(), shared.log_phi_w.copy(), shared.log_g0.copy())

    run.fit(n_iterations, after_sweep)
    state = run.state()
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
    if prune and word_mask.size:
        score = settings.pruning_score
        word_mask = words_to_keep(np.exp(log_phi_w), np.exp(log_g0), hyper.pruning_threshold(score), score)
        if state.candidate_words is not None:  # words the sampler found to depend on the place
            word_mask &= state.candidate_words
        if not word_mask.any():
            word_mask[np.argmax(np.exp(log_phi_w).max(0))] = True
    conc_g = _concentration(np.exp(stack_g)[:, None, :])[0]
    record: dict[str, Any] = {
        "homes": list(corpus.names),
        "n_samples": int(data.n_samples),
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
    record.update(provenance or {})
    return Knowledge(
        log_phi_visual=log_phi_v, log_phi_words=log_phi_w, log_g0=log_g0, word_mask=word_mask,
        concentration_visual=_concentration(phi_v_samples),
        concentration_words=(_concentration(np.exp(stack_w)) if has_words
                             else np.full(hyper.n_concepts, np.nan)),
        concentration_g0=float(conc_g), vocabulary=corpus.vocabulary, word_increment=corpus.word_increment,
        hyperparameters=hyper, variant=variant, prune_words=prune, provenance=record,
    )


# ============================================================================ home models


@dataclass(frozen=True)
class Observation:
    """A new observation for :func:`teach`: a pose, the view's visual counts and what was said.

    x, y in metres on the home's map, theta (heading) in radians; visual: (D,) counts (dense array
    or a 1-row sparse matrix); sentence: the user's words, or ``None``; id: the sample id (default:
    one more than the largest id of the home).
    """

    x: float
    y: float
    theta: float
    visual: Any
    sentence: str | None = None
    id: int | None = None


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
        """Name weighting for prediction: the authors' KL score for the reference sampler, else MI."""
        return "reference" if self.knowledge.variant == "reference" else "mi"

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
        """The home's parameters (one home, metres), as prediction uses them."""
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

    def what(self, x: float, y: float, theta: float, visual: Any = None, top_k: int = 3) -> NamePrediction:
        """Place names at a pose; see :func:`what`."""
        return what(self, x, y, theta, visual=visual, top_k=top_k)

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
            home = cls(name=str(header["name"]), knowledge=knowledge, state=state, ids=arrays["ids"],
                       positions=arrays["positions"], visual=visual, sentences=sentences,
                       extent=extent, map_centre=arrays["map_centre"],
                       n_knowledge_words=int(header["n_knowledge_words"]), joint=bool(header.get("joint")),
                       provenance=dict(header.get("provenance") or {}))
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


def _sweep(data: gibbs.PreparedData, state: gibbs.GibbsState, hyper: TransferHyperparameters,
           settings: gibbs.SamplerSettings, rng: np.random.Generator, prior: _SharedPrior | None,
           n_known: int) -> None:
    """One sweep for one home: shared part fixed (``prior`` None) or learnt with ``prior``.

    Learning the shared part with pruning re-decides about the knowledge's words (only those the
    knowledge kept can stay: ``state.candidate_words``); the words first heard in this home are
    kept during the sweeps and judged in the home afterwards (:func:`_judge_new_words`)."""
    if prior is None:
        gibbs.sweep(data, state, hyper, settings, rng, swaps=False)
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
    if settings.prune:
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


def _judge_new_words(state: gibbs.GibbsState, knowledge: Knowledge, n_known: int) -> None:
    """With pruning, decide about the words first heard in this home on the home's θ^w and G_e
    (a home-specific name would score low against the global weights G_0: it is said in one home)."""
    if not knowledge.prune_words or state.log_theta_w.shape[2] <= n_known:
        return
    score = "kl" if knowledge.variant == "reference" else "mi"
    theta = np.exp(state.log_theta_w[0])
    weights = np.exp(state.log_g[0])
    threshold = knowledge.hyperparameters.pruning_threshold(score)
    keep = words_to_keep(theta, weights / weights.sum(), threshold, score)
    state.word_mask = state.word_mask.copy()
    state.word_mask[n_known:] = keep[n_known:]


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
                              f"was learnt with {knowledge.n_features}: it comes from other data")


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
    for _ in iterator:
        _sweep(data, state, hyper, settings, rng, prior, n_known)
    _judge_new_words(state, extended, n_known)
    seconds = time.perf_counter() - start
    record: dict[str, Any] = {
        "knowledge_checksum": knowledge.checksum,
        "knowledge_homes": list(knowledge.provenance.get("homes") or []),
        "adapt": {"seed": _seed_of(random_state), "n_iterations": int(n_iterations), "joint": bool(joint),
                  "seconds": round(seconds, 3), "new_words": list(extended.vocabulary.words[n_known:])},
        "teach_updates": 0,
        "spco_version": _version(),
        "created": _now(),
    }
    record.update(provenance or {})
    return HomeModel(name=home.name, knowledge=extended, state=state, ids=train.ids,
                     positions=train.positions, visual=sp.csr_array(train.visual, dtype=np.int64),
                     sentences=tuple(train.sentences), extent=home.extent, map_centre=centre,
                     n_knowledge_words=n_known, joint=bool(joint), provenance=record)


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
        raise ConfigurationError("a new observation needs its visual counts (the view's features)")
    if sp.issparse(visual):
        row = sp.csr_array(visual)
        values = row.data
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
        values = dense
    if row.shape != (1, n_features):
        raise ConfigurationError(f"visual counts have {row.shape[1]} values, the home's views {n_features}")
    values = np.asarray(values, dtype=np.float64)
    bad = not np.isfinite(values).all() or (values < 0).any() or (values != np.floor(values)).any()
    if values.size and bad:
        raise ConfigurationError("visual counts must be non-negative whole numbers (for real-valued CNN "
                                 "features give a visual scale: counts = floor(max(f, 0) × scale))")
    out = sp.csr_array(row, dtype=np.int64)
    out.eliminate_zeros()
    return out


def _pose(x: float, y: float, theta: float) -> np.ndarray:
    pose = np.array([x, y, math.sin(theta), math.cos(theta)], dtype=np.float64)
    if not np.isfinite(pose).all():
        raise ConfigurationError(f"the pose must be finite numbers, got x={x!r}, y={y!r}, theta={theta!r}")
    return pose


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
        milliseconds for a home of 300 samples).
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
        rows.append(_visual_row(obs.visual, home.knowledge.n_features))
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
    for _ in range(int(n_sweeps)):
        _sweep(data, state, knowledge.hyperparameters, settings, rng, prior, home.n_knowledge_words)
    _judge_new_words(state, knowledge, home.n_knowledge_words)
    provenance = dict(home.provenance)
    provenance["teach_updates"] = int(provenance.get("teach_updates", 0)) + 1
    provenance["updated"] = _now()
    provenance["last_teach"] = {"sentences": len(sentences), "observations": len(observations),
                                "new_words": list(knowledge.vocabulary.words[home.knowledge.n_words:]),
                                "n_sweeps": int(n_sweeps), "seed": _seed_of(random_state),
                                "seconds": round(time.perf_counter() - start, 4)}
    return replace(home, knowledge=knowledge, state=state, ids=np.asarray(ids, dtype=np.int64),
                   positions=positions, visual=visual, sentences=tuple(new_sentences), provenance=provenance)


def _copy_state(state: gibbs.GibbsState) -> gibbs.GibbsState:
    return gibbs.GibbsState(**{name: np.array(getattr(state, name), copy=True) for name in _STATE_ARRAYS})


# ---------------------------------------------------------------------------- questions


def where(home: HomeModel, name: str, n: int = 10,
          random_state: int | np.random.Generator | None = None) -> PositionPrediction:
    """Poses ``(x, y, θ)`` to go to for the place ``name`` in ``home``.

    The region m̂ = argmax_m p(m | name) and ``n`` poses drawn from its Gaussian
    (:func:`spco.prediction.predict_positions`); each pose's ``weights`` entry is its share of the
    density p(x | name) among the ``n`` poses. Raises :class:`~spco.prediction.UnknownNameError`
    (with suggestions) for a name the home cannot use: never heard, or pruned as uninformative.
    """
    return predict_positions(home.parameters, 0, home.vocabulary, name, n=n, rng=_as_generator(random_state))


def what(home: HomeModel, x: float, y: float, theta: float, visual: Any = None,
         top_k: int = 3) -> NamePrediction:
    """The ``top_k`` place names at pose ``(x, y, θ)``, with the view's visual counts if given.

    Without ``visual`` the names come from the position alone (``use_vision=False``). The returned
    :class:`~spco.prediction.NamePrediction` holds one row: ``words[0]``, ``probabilities[0]``
    (p(w | x, v)) and ``scores[0]`` (the ranking score).
    """
    pose = _pose(x, y, theta)[None, :]
    row = None if visual is None else _visual_row(visual, home.knowledge.n_features)
    return predict_names(home.parameters, 0, home.vocabulary, pose, row, top_k=top_k,
                         weighting=home.weighting, use_vision=row is not None)  # type: ignore[arg-type]


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

