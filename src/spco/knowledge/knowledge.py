"""The knowledge: the shared, home-independent part of the transfer model learnt from experienced
homes (:class:`Knowledge`), and its file (:func:`load_knowledge`)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
from scipy.special import logsumexp

from spco.data.language import Vocabulary
from spco.errors import ConfigurationError, ModelFileError
from spco.knowledge.files import (
    KNOWLEDGE_FORMAT,
    _content_checksum,
    _read_archive,
    _require,
    _version,
    _write_archive,
    check_word_model,
    format_version,
    segmentation_of,
)
from spco.model.archive import checksum
from spco.model.home_shard import FREE_CONCEPT_WEIGHT, SharedPart, SharedPrior, name_words
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.word_channels import WordChannels

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
#: Concepts no experienced home uses that a new home is adapted with at least
#: (:meth:`Knowledge.with_free_concepts`): one per name of the home's own (the knowledge of the
#: paper's 16 SIGVerse homes learnt with the word channels uses 15 of its 16 concepts — places split
#: by the frames said around their names — which left 3LDK_9's three own names one concept).
MIN_FREE_CONCEPTS = 8




@dataclass(frozen=True, eq=False)
class KnowledgeChannels:
    """The word channels a knowledge carries (:mod:`spco.model.word_channels`): the learnt
    distributions and the switches' statistics of the fit.

    Attributes
    ----------
    channels: the :class:`~spco.model.word_channels.WordChannels` averaged over the kept sweeps: log ψ
        (L, V) each concept's place words, log β (V,) the background, log λ (3,) the learnt shares and
        the linguistic evidence log e (V, 3) of every word (the switch's prior).
    tokens: (V, 3) the experienced homes' expected tokens of each word as name, place word and
        background word: the switch probabilities of its tokens summed, averaged over the fit's kept
        sweeps (0 for words first heard in a home): which words are names (:meth:`name_mask`).
    place_names: (L, V) the names said at each concept's places in the experienced homes
        (:func:`spco.model.word_channels.place_names`), relabelled like φ and averaged over the kept
        sweeps: the names a home's concept answers around
        (:func:`spco.model.confidence.place_named_parameters`);
        ``None`` in a file written before it (the concept's φ^w then).
    """

    channels: WordChannels
    tokens: np.ndarray
    place_names: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "tokens", np.asarray(self.tokens, dtype=np.float64))
        if self.place_names is not None:
            object.__setattr__(self, "place_names", np.asarray(self.place_names, dtype=np.float64))

    def check(self, n_concepts: int, n_words: int) -> list[str]:
        """Shape problems for ``n_concepts`` concepts and ``n_words`` words (empty if none)."""
        c = self.channels
        expected = {"log_place": (n_concepts, n_words), "log_background": (n_words,), "log_shares": (3,),
                    "log_evidence": (n_words, 3), "tokens": (n_words, 3)}
        found = {"log_place": c.log_place, "log_background": c.log_background, "log_shares": c.log_shares,
                 "log_evidence": c.log_evidence, "tokens": self.tokens}
        problems = [f"channels.{k} has shape {np.shape(found[k])}, expected {v}"
                    for k, v in expected.items() if np.shape(found[k]) != v]
        if not problems and not all(np.isfinite(a).all() for a in found.values() if a is not self.tokens):
            problems.append("the channels hold a NaN or an infinite log-probability")
        if self.place_names is not None:
            if self.place_names.shape != (n_concepts, n_words):
                problems.append(f"channels.place_names has shape {self.place_names.shape}, expected "
                                f"{(n_concepts, n_words)}")
            elif not (np.isfinite(self.place_names).all() and (self.place_names >= 0).all()):
                problems.append("channels.place_names holds a negative, NaN or infinite count")
        return problems

    def extended(self, n_words: int, evidence: np.ndarray, content: np.ndarray,
                 weight: float) -> KnowledgeChannels:
        """The channels of a vocabulary grown to ``n_words``: the new words with their evidence (ν,
        a: ``evidence``, ``content``, (n_words,) of which the new entries are used) and no token."""
        added = n_words - self.tokens.shape[0]
        if added <= 0:
            return self
        V = self.tokens.shape[0]
        channels = self.channels.extended(n_words, evidence, content, weight)
        # a word never said is as unlikely a place word of one concept as of another: the same ψ in
        # every concept (the smallest of the knowledge's), so that with its weight in the concept's
        # likelihood (W^w counts, or S^w for a knowledge without the word weight) it draws no sample
        # to the concept whose ψ happens to be least sparse
        place = channels.log_place.copy()
        place[:, V:] = float(self.channels.log_place.min()) if self.channels.log_place.size else 0.0
        channels = replace(channels, log_place=place - logsumexp(place, axis=1, keepdims=True))
        first = V if self.channels.prior_only_from is None else self.channels.prior_only_from
        at_places = (None if self.place_names is None else
                     np.concatenate([self.place_names, np.zeros((self.place_names.shape[0], added))], axis=1))
        return KnowledgeChannels(replace(channels, prior_only_from=first),
                                 np.concatenate([self.tokens, np.zeros((added, 3))]), at_places)

    def name_mask(self, home_tokens: np.ndarray | None = None) -> np.ndarray:
        """(V,) bool: the words that are names (:func:`spco.model.home_shard.name_words`) by the fit's
        tokens (:attr:`tokens`) plus a home's own (``home_tokens``, (V, 3), e.g. its switches'
        expected counts)."""
        tokens = self.tokens if home_tokens is None else self.tokens + np.asarray(home_tokens, float)
        return name_words(tokens)

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays a file holds (``channels.<name>``)."""
        c = self.channels
        arrays = {"channels.log_place": np.asarray(c.log_place, dtype=np.float64),
                  "channels.log_background": np.asarray(c.log_background, dtype=np.float64),
                  "channels.log_shares": np.asarray(c.log_shares, dtype=np.float64),
                  "channels.log_evidence": np.asarray(c.log_evidence, dtype=np.float64),
                  "channels.tokens": self.tokens}
        if c.prior_only_from is not None:
            arrays["channels.prior_only_from"] = np.array([c.prior_only_from], dtype=np.int64)
        if c.token_weight != 1.0:  # (a file without it: S^w counts per token, as before the word weight)
            arrays["channels.token_weight"] = np.array([c.token_weight], dtype=np.float64)
        if c.power:  # (a file without it: the cut sampler, as before the power target)
            arrays["channels.power"] = np.array([True])
        if self.place_names is not None:  # (a file without it: the concepts' φ^w answer)
            arrays["channels.place_names"] = self.place_names
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str = "") -> KnowledgeChannels | None:
        """The channels of a file's arrays (``None`` if it holds none)."""
        if prefix + "channels.log_place" not in arrays:
            return None
        a = {name: arrays[prefix + "channels." + name] for name in
             ("log_place", "log_background", "log_shares", "log_evidence", "tokens")}
        channels = WordChannels(np.asarray(a["log_place"], dtype=np.float64),
                                np.asarray(a["log_background"], dtype=np.float64),
                                np.asarray(a["log_shares"], dtype=np.float64),
                                np.asarray(a["log_evidence"], dtype=np.float64), False)
        first = arrays.get(prefix + "channels.prior_only_from")
        if first is not None:
            channels = replace(channels, prior_only_from=int(np.asarray(first).reshape(-1)[0]))
        weight = arrays.get(prefix + "channels.token_weight")
        if weight is not None:
            value = float(np.asarray(weight, dtype=np.float64).reshape(-1)[0])
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"channels.token_weight must be a positive number, got {value!r}")
            channels = replace(channels, token_weight=value)
        power = arrays.get(prefix + "channels.power")
        if power is not None:
            channels = replace(channels, power=bool(np.asarray(power).reshape(-1)[0]))
        at_places = arrays.get(prefix + "channels.place_names")
        return cls(channels, a["tokens"],
                   None if at_places is None else np.asarray(at_places, dtype=np.float64))


def _model_name(variant: str, prune: bool) -> str:
    for name, spec in MODELS.items():
        if spec == (variant, prune):
            return name
    raise ConfigurationError(f"no transfer model with sampler {variant!r} and pruning {prune}")


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
    name_prior: (V,) P(name | how each word was said and what it is)
        (:func:`spco.model.name_evidence.name_prior`, from the experienced homes' sentences; used
        for names nobody said, :mod:`spco.model.unheard`), or ``None`` (models without the naming
        rule, files written before it existed).
    channels: the word channels (:class:`KnowledgeChannels`: names, place words ψ, background β, the
        switch's learnt shares and evidence) of a knowledge learnt with them
        (``hyperparameters.word_model == "channels"``), or ``None`` (the naming rule: speech without
        English function words, and the models without pruning or with the authors' sampler).
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
    name_prior: np.ndarray | None = None
    channels: KnowledgeChannels | None = None

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
        if self.channels is not None:
            problems += self.channels.check(L, V)
        learnt_with_channels = (self.variant == "exact" and self.prune_words
                                and self.hyperparameters.word_model == "channels")
        if learnt_with_channels and self.channels is None:
            problems.append("the hyperparameters say word_model 'channels' but the knowledge holds none")
        if self.channels is not None and not learnt_with_channels:
            problems.append("word channels in a knowledge whose model does not learn them")
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
    def name_mask(self) -> np.ndarray:
        """(V,) bool: the knowledge's place names — with the word channels the words enough of whose
        uses the fit expects to be names (:meth:`KnowledgeChannels.name_mask`), otherwise the words kept
        by pruning (``word_mask``)."""
        return self.word_mask if self.channels is None else self.channels.name_mask() & self.word_mask

    @property
    def known_names(self) -> list[str]:
        """The knowledge's place names (:attr:`name_mask`)."""
        return [w for w, keep in zip(self.vocabulary.words, self.name_mask, strict=True) if keep]

    @property
    def checksum(self) -> str:
        """sha256 identifying this knowledge's content (the ``checksum`` of its file)."""
        arrays, header = self._arrays_and_header()
        header = dict(header)
        header["array_checksums"] = {n: checksum(np.asarray(a)) for n, a in arrays.items()}
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
        channels = self.channels
        if channels is not None:  # the new words' evidence, from how the home says them
            from spco.model.name_evidence import channel_evidence

            nu, content = channel_evidence(vocabulary, [s for s in sentences if s])
            channels = channels.extended(len(vocabulary), nu, content, hyper.evidence_weight)
        return replace(self, log_phi_words=log_phi, word_mask=mask, vocabulary=vocabulary, channels=channels)

    # ------------------------------------------------------------------ for a new home
    def with_free_concepts(self, n_free: int = MIN_FREE_CONCEPTS) -> Knowledge:
        """This knowledge with at least ``n_free`` concepts the experienced homes do not use (G_0
        below :data:`~spco.model.home_shard.FREE_CONCEPT_WEIGHT`), appended when it has fewer: the
        concepts a new home's own names take (names nobody in the experienced homes said: "emma's
        room", a room taught once). A concept no experienced home used has its prior as posterior,
        and a knowledge holds the posterior *mean* of each concept's φ and ψ (averaged over the fit's
        kept sweeps), so an appended one holds what a fit with a larger truncation L would report
        for it: the prior's mean — φ^v, φ^w and ψ uniform — not one prior draw. (One draw of
        Dir(α^w) with a small α^w puts nearly all its mass on one word of the vocabulary at random;
        a concept holding it explains every sentence with that word, and on the synthetic home of
        ``benchmarks/teaching.py`` it drew taught samples and views away from their place: a single
        teaching was effective in 60 % of teachings instead of 95 %.) G_0 the weight of the
        knowledge's own unused concepts (or 1e-12), concentrations unknown (δ, γ). Deterministic (the
        prior's mean needs no draw). Returns ``self`` when it has enough."""
        g0 = np.exp(self.log_g0)
        free = g0 < FREE_CONCEPT_WEIGHT
        added = int(n_free) - int(free.sum())
        if added <= 0:
            return self
        L, D, V = self.n_concepts, self.n_features, self.n_words
        hyper = self.hyperparameters

        def prior_mean(rows: int, size: int) -> np.ndarray:
            return np.full((rows, size), -math.log(size) if size else 0.0)

        weight = float(g0[free].min()) if free.any() and g0[free].min() > 0 else 1e-12
        log_g0 = np.concatenate([self.log_g0, np.full(added, math.log(weight))])
        log_g0 -= logsumexp(log_g0)
        channels = self.channels
        if channels is not None:
            c = channels.channels
            place = np.concatenate([c.log_place, prior_mean(added, V)])
            at_places = (None if channels.place_names is None else
                         np.concatenate([channels.place_names, np.zeros((added, V))]))  # nothing said there
            channels = KnowledgeChannels(replace(c, log_place=place), channels.tokens, at_places)
        return replace(
            self, log_g0=log_g0,
            log_phi_visual=np.concatenate([self.log_phi_visual, prior_mean(added, D)]),
            log_phi_words=np.concatenate([self.log_phi_words, prior_mean(added, V)]),
            concentration_visual=np.concatenate([self.concentration_visual, np.full(added, np.nan)]),
            concentration_words=np.concatenate([self.concentration_words, np.full(added, np.nan)]),
            hyperparameters=replace(hyper, n_concepts=L + added), channels=channels)

    def shared_part(self) -> SharedPart:
        """The shared part as a new home is learnt with it (:class:`spco.model.home_shard.SharedPart`)."""
        return SharedPart(log_phi_visual=self.log_phi_visual, log_phi_words=self.log_phi_words,
                          log_g0=self.log_g0, word_mask=self.word_mask,
                          hyperparameters=self.hyperparameters, variant=self.variant,
                          prune_words=self.prune_words, words=tuple(self.vocabulary.words),
                          channels=None if self.channels is None else self.channels.channels)

    def shared_prior(self) -> SharedPrior:
        """The knowledge as the prior of the shared part (``adapt(..., joint=True)``): Dir(A φ̄),
        Dir(A_g Ḡ_0) with the concentrations of :attr:`concentration_visual`, ... (δ, γ where unknown)."""
        return SharedPrior.of(self.shared_part(), self.concentration_visual, self.concentration_words,
                              self.concentration_g0)

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
        if self.name_prior is not None:
            arrays["name_prior"] = np.asarray(self.name_prior, dtype=np.float64)
        if self.channels is not None:
            arrays.update(self.channels.arrays())
        header = {
            "format": KNOWLEDGE_FORMAT,
            "format_version": format_version(self.vocabulary, self.variant == "exact" and self.prune_words),
            "spco_version": _version(),
            "model": self.model,
            "variant": self.variant,
            "prune_words": bool(self.prune_words),
            "hyperparameters": self.hyperparameters.to_dict(),
            "vocabulary": list(self.vocabulary.words),
            "segmentation": None if self.vocabulary.segmentation is None
            else self.vocabulary.segmentation.to_dict(),
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
        check_word_model(file, header)
        try:
            return cls(
                log_phi_visual=arrays[prefix + "log_phi_visual"],
                log_phi_words=arrays[prefix + "log_phi_words"],
                log_g0=arrays[prefix + "log_g0"],
                word_mask=arrays[prefix + "word_mask"],
                concentration_visual=arrays[prefix + "concentration_visual"],
                concentration_words=arrays[prefix + "concentration_words"],
                concentration_g0=float(arrays[prefix + "concentration_g0"].reshape(-1)[0]),
                vocabulary=Vocabulary(tuple(str(w) for w in header["vocabulary"]), segmentation_of(header)),
                word_increment=int(header["word_increment"]),
                hyperparameters=TransferHyperparameters.from_dict(header["hyperparameters"]),
                variant=str(header["variant"]),
                prune_words=bool(header["prune_words"]),
                provenance=dict(header.get("provenance") or {}),
                extractor=_extractor_of(header),
                extractor_arrays={name[len(prefix) + len("extractor."):]: a for name, a in arrays.items()
                                  if name.startswith(prefix + "extractor.")},
                name_prior=arrays.get(prefix + "name_prior"),
                channels=KnowledgeChannels.from_arrays(arrays, prefix),
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
        if self.vocabulary.segmentation is not None:
            lines.append(f"text written without spaces: {self.vocabulary.segmentation.describe()}")
        hyper = self.hyperparameters  # the answer's opt-ins (spco.model.answer_settings)
        if hyper.view_in_room:
            lines.append("answers: the view as a draw of its room (view_in_room)")
        if hyper.typical is not None:
            learnt = p.get("typical")
            lines.append(f"answers: rooms typical with ρ = {hyper.typical:g}"
                         + (f" (learnt from {learnt['samples']} samples)" if learnt else ""))
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
