"""The in-memory representation of a home (an *environment*) and of a *corpus* of homes.

Every part of spco works on these two types:

- :class:`Environment` — one home: sample ids, poses ``(x, y, sin θ, cos θ)`` in metres, visual
  bag-of-features counts (sparse, integer), the taught sentence of each sample (or ``None``), a
  train/test split, the map extent and the home's name. Evaluation-only ground truth lives in a
  separate :class:`GroundTruth` attached as ``environment.ground_truth``.
- :class:`Corpus` — environments that share one :class:`~spco.data.language.Vocabulary`.

Evaluation labels cannot leak into training by accident: learning code only ever sees
:class:`TrainingData` (built by :meth:`Environment.training_data`), which holds the training
samples' observations and sentences and nothing else — no labels, no test samples.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from spco.data.language import DEFAULT_WORD_INCREMENT, Vocabulary, normalize_name
from spco.data.regions import PlaceRegions
from spco.errors import ConfigurationError, DataFormatError

#: Largest tolerated deviation of sin²θ + cos²θ from 1 before a pose is refused.
HEADING_TOLERANCE = 0.05
#: Largest |x| or |y| of a position, in map units: the model's covariances hold squared distances
#: summed over samples, which overflow float64 (1.8e308) beyond about 1e150.
MAX_COORDINATE = 1e150
#: Largest span (max − min of x or of y) of a home's positions, in map units. A region's covariance
#: holds x, y (squared: span²) beside sin θ, cos θ (about 1): beyond a span of ~1e7 its condition
#: number exceeds what float64 factorises (1e16). 1e6 is a 1,000 km map in metres — a home in
#: micrometres, or a position typed with a wrong exponent, is refused instead of learnt wrongly.
MAX_SPAN = 1e6
#: Largest visual count of one feature: counts are int64, summed over up to millions of samples.
MAX_COUNT = 1e12

Extent = tuple[float, float, float, float]  # x_min, x_max, y_min, y_max (metres)


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """Evaluation-only facts about a home. Never given to a learning algorithm.

    Attributes
    ----------
    labels:
        General place name of every sample (``None`` where unknown), length N, normalised.
    specific_labels:
        Place names with home-specific places (``"emma's-room"``), length N, or ``None``.
    specific_test:
        Boolean mask (N,) of the samples scored in the home-specific experiment, or ``None``.
    regions:
        Ground-truth area of each place, or ``None``.
    accepted_names:
        place -> the names counted right for it (``"bath"`` → ``("bath", "bathroom", "shower")``),
        normalised; ``None`` (or a place not listed): only the place's own name.
    """

    labels: tuple[str | None, ...] | None = None
    specific_labels: tuple[str | None, ...] | None = None
    specific_test: np.ndarray | None = None
    regions: PlaceRegions | None = None
    accepted_names: dict[str, tuple[str, ...]] | None = None

    def accepted(self, place: str) -> tuple[str, ...]:
        """The names counted right for ``place``: its own name first, then its accepted synonyms."""
        key = normalize_name(place)
        return tuple(dict.fromkeys([key, *(self.accepted_names or {}).get(key, ())]))

    @property
    def places(self) -> list[str]:
        """The general place names, in order of first appearance."""
        return list(dict.fromkeys(p for p in (self.labels or ()) if p is not None))


@dataclass(frozen=True, eq=False)
class TrainingData:
    """What a learner may see of a home: its training samples, nothing else.

    Attributes
    ----------
    name: the home's name.
    ids: (n,) sample ids of the training samples.
    positions: (n, 4) float64 poses ``(x, y, sin θ, cos θ)`` in metres.
    visual: (n, D) sparse int64 visual counts (the home's own array when it has no test samples:
        read it, do not modify it); the row of a sample without a view is all zero.
    sentences: length-n taught sentences (``None`` where nothing was taught).
    extent: map extent ``(x_min, x_max, y_min, y_max)`` or ``None``.
    view_missing: (n,) bool, True for a sample without a view (its visual likelihood is left out).
    """

    name: str
    ids: np.ndarray
    positions: np.ndarray
    visual: sp.csr_array
    sentences: tuple[str | None, ...]
    extent: Extent | None
    view_missing: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.view_missing is None:
            object.__setattr__(self, "view_missing", np.zeros(self.positions.shape[0], dtype=bool))

    @property
    def n_samples(self) -> int:
        """Number of training samples."""
        return int(self.positions.shape[0])

    @property
    def n_taught(self) -> int:
        """Number of training samples with a sentence."""
        return sum(s is not None for s in self.sentences)


def _checked_positions(where: str, raw: Any, ids: np.ndarray) -> np.ndarray:
    """A home's (N, 4) positions as float64, checked: finite, headings on the unit circle."""
    n = ids.size
    positions = np.asarray(raw, dtype=np.float64)
    if positions.shape != (n, 4):
        raise DataFormatError(where, f"positions must have shape ({n}, 4) "
                              f"(x, y, sin θ, cos θ), got {positions.shape}")
    bad = ~np.isfinite(positions).all(axis=1)
    if bad.any():
        raise DataFormatError(where, f"non-finite (NaN or inf) position for sample ids "
                              f"{ids[bad][:10].tolist()}")
    far = (np.abs(positions[:, :2]) > MAX_COORDINATE).any(axis=1)
    if far.any():
        raise DataFormatError(where, f"position beyond ±{MAX_COORDINATE:g} map units for sample ids "
                              f"{ids[far][:10].tolist()} (e.g. {positions[far][0, :2].tolist()}): squared "
                              "distances would overflow float64; give positions in metres")
    span = float(np.ptp(positions[:, :2], axis=0).max()) if n else 0.0
    if span > MAX_SPAN:
        axis = int(np.argmax(np.ptp(positions[:, :2], axis=0)))
        lo, hi = int(np.argmin(positions[:, axis])), int(np.argmax(positions[:, axis]))
        raise DataFormatError(where, f"the positions span {span:.3g} map units in {'xy'[axis]} (sample ids "
                              f"{int(ids[lo])} to {int(ids[hi])}), more than {MAX_SPAN:g}: a home's regions "
                              "can not be learnt at that scale in float64; give positions in metres")
    norm = positions[:, 2] ** 2 + positions[:, 3] ** 2
    off = np.abs(norm - 1.0) > HEADING_TOLERANCE
    if off.any():
        raise DataFormatError(where, f"sin²θ + cos²θ is far from 1 for sample ids "
                              f"{ids[off][:10].tolist()} (values {np.round(norm[off][:3], 3).tolist()})")
    return positions


def _checked_visual(where: str, raw: Any, view_missing: Any, n: int) -> tuple[sp.csr_array, np.ndarray]:
    """A home's (N, D) visual counts as an int64 CSR array (32-bit indices when they fit) and its
    missing-view mask, checked: whole non-negative numbers, no counts where a view is missing."""
    visual = raw
    if not sp.issparse(visual):
        visual = np.asarray(visual)
        if visual.ndim != 2:
            raise DataFormatError(where, "visual counts must be a 2-D array (samples × features)")
        if not np.issubdtype(visual.dtype, np.number):
            raise DataFormatError(where, "visual counts must be numeric")
    visual = sp.csr_array(visual)
    if visual.shape[0] != n:
        raise DataFormatError(where, f"visual counts have {visual.shape[0]} rows for {n} samples")
    missing = np.zeros(n, dtype=bool) if view_missing is None \
        else np.asarray(view_missing, dtype=bool)
    if missing.shape != (n,):
        raise DataFormatError(where, f"the missing-view mask must have shape ({n},), got {missing.shape}")
    if visual.shape[1] == 0 and not missing.all():
        raise DataFormatError(where, "visual feature vectors are empty (a home without views has every "
                              "view marked missing)")
    data = visual.data
    if data.size and not np.isfinite(data).all():
        raise DataFormatError(where, "visual counts contain NaN or inf")
    if data.size and (data < 0).any():
        raise DataFormatError(where, "visual counts must be non-negative")
    if data.size and (data > MAX_COUNT).any():
        raise DataFormatError(where, f"visual counts above {MAX_COUNT:g} (largest {float(data.max()):.3g}): "
                              "sums of counts would overflow int64; scale the counts down (a view's "
                              "evidence depends on its proportions only)")
    if data.size and not np.issubdtype(data.dtype, np.integer):
        if (data != np.round(data)).any():
            raise DataFormatError(where, "visual counts must be whole numbers (scale real-valued "
                                  "CNN features with spco.data.features_to_counts)")
    visual = sp.csr_array(visual, dtype=np.int64)
    if missing.any():  # a sample without a view has no counts: whatever the row held is left out
        keep = sp.diags_array((~missing).astype(np.int64), dtype=np.int64)
        visual = sp.csr_array(keep @ visual, dtype=np.int64)
    visual.eliminate_zeros()
    visual.sort_indices()
    # 32-bit index arrays (as SciPy itself chooses): the counts then take 12 bytes per non-zero,
    # not 16 (a loader may hand over int64 ones); the kernels get their own layout at fit time
    if max(visual.nnz, visual.shape[1]) < 2**31:
        visual.indices = visual.indices.astype(np.int32, copy=False)
        visual.indptr = visual.indptr.astype(np.int32, copy=False)
    return visual, missing


@dataclass(frozen=True, eq=False)
class Environment:
    """One home: observations of N samples, their taught sentences and a train/test split.

    Construct directly or with a loader (:func:`spco.data.load`); the constructor validates every
    field and raises :class:`~spco.errors.DataFormatError` naming ``source`` (or the home) and the
    problem.

    Attributes
    ----------
    name: the home's name (``"3LDK_9"``).
    ids: (N,) int64 sample ids, unique.
    positions: (N, 4) float64 poses ``(x, y, sin θ, cos θ)``, metres.
    visual: (N, D) ``scipy.sparse.csr_array`` of non-negative int64 counts (int32 index arrays
        whenever they fit). ``D`` may be 0 when no sample has a view (a home recorded without a
        camera); a :class:`Corpus` widens such a home to the other homes' ``D``.
    sentences: length-N taught sentence of each sample, or ``None``.
    is_test: (N,) bool, True for test samples (never learnt from).
    extent: ``(x_min, x_max, y_min, y_max)`` of the map in metres, or ``None``.
    ground_truth: evaluation-only :class:`GroundTruth`, or ``None``.
    source: where the home was read from (for messages), or ``None``.
    """

    name: str
    ids: np.ndarray
    positions: np.ndarray
    visual: sp.csr_array
    sentences: tuple[str | None, ...]
    is_test: np.ndarray
    extent: Extent | None = None
    ground_truth: GroundTruth | None = field(default=None, repr=False)
    source: str | None = None
    view_missing: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        where = self.source or f"home {self.name!r}"
        ids = np.asarray(self.ids)
        if ids.ndim != 1 or ids.size == 0:
            raise DataFormatError(where, "the home holds no samples")
        if not np.issubdtype(ids.dtype, np.integer):
            raise DataFormatError(where, "sample ids must be integers")
        n = ids.size
        uniq, counts = np.unique(ids, return_counts=True)
        if (counts > 1).any():
            raise DataFormatError(where, f"duplicate sample ids: {uniq[counts > 1][:10].tolist()}")
        positions = _checked_positions(where, self.positions, ids)
        visual, missing = _checked_visual(where, self.visual, self.view_missing, n)
        sentences = tuple(None if (s is None or not str(s).strip()) else str(s) for s in self.sentences)
        if len(sentences) != n:
            raise DataFormatError(where, f"{len(sentences)} sentences for {n} samples")
        is_test = np.asarray(self.is_test, dtype=bool)
        if is_test.shape != (n,):
            raise DataFormatError(where, f"test mask must have shape ({n},)")
        if self.extent is not None:
            ext = tuple(float(v) for v in self.extent)
            if len(ext) != 4 or not np.isfinite(ext).all() or (np.abs(ext) > MAX_COORDINATE).any():
                raise DataFormatError(where, f"invalid map extent {self.extent!r} (4 finite numbers within "
                                      f"±{MAX_COORDINATE:g} map units)")
            object.__setattr__(self, "extent", ext)
        gt = self.ground_truth
        if gt is not None:
            for label_set in (gt.labels, gt.specific_labels):
                if label_set is not None and len(label_set) != n:
                    raise DataFormatError(where, f"{len(label_set)} labels for {n} samples")
        object.__setattr__(self, "ids", ids.astype(np.int64))
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "visual", visual)
        object.__setattr__(self, "sentences", sentences)
        object.__setattr__(self, "is_test", is_test)
        object.__setattr__(self, "view_missing", missing)

    # ------------------------------------------------------------------ sizes
    @property
    def n_samples(self) -> int:
        """Number of samples N (train and test)."""
        return int(self.ids.size)

    @property
    def n_features(self) -> int:
        """Visual dimension D."""
        return int(self.visual.shape[1])

    @property
    def n_views(self) -> int:
        """Number of samples with a view."""
        return int((~self.view_missing).sum())

    @property
    def n_train(self) -> int:
        """Number of training samples."""
        return int((~self.is_test).sum())

    @property
    def n_test(self) -> int:
        """Number of test samples."""
        return int(self.is_test.sum())

    @property
    def n_taught(self) -> int:
        """Number of training samples with a taught sentence."""
        return sum(s is not None for s, t in zip(self.sentences, self.is_test, strict=True) if not t)

    def index_of(self, sample_id: int) -> int:
        """Row of sample ``sample_id``; raises ``KeyError`` if there is none."""
        rows = np.flatnonzero(self.ids == sample_id)
        if rows.size == 0:
            raise KeyError(f"home {self.name!r} has no sample with id {sample_id}")
        return int(rows[0])

    # ------------------------------------------------------------------ views
    def training_data(self) -> TrainingData:
        """The training samples' observations and sentences — all a learner may see."""
        train = ~self.is_test
        # a home without test samples lends its visual counts as they are (the largest array of a
        # home, read only by learners); otherwise its training rows are copied
        visual = self.visual if train.all() else self.visual[np.flatnonzero(train)]
        return TrainingData(
            name=self.name,
            ids=self.ids[train].copy(),
            positions=self.positions[train].copy(),
            visual=visual,
            sentences=tuple(s for s, t in zip(self.sentences, train, strict=True) if t),
            extent=self.extent,
            view_missing=self.view_missing[train].copy(),
        )

    def test_observations(self) -> tuple[np.ndarray, sp.csr_array]:
        """Positions ``(n_test, 4)`` and visual counts ``(n_test, D)`` of the test samples."""
        rows = np.flatnonzero(self.is_test)
        return self.positions[rows].copy(), self.visual[rows]

    def with_visual_dimension(self, n_features: int) -> Environment:
        """This home with views of ``n_features`` features: a home without any view is given that
        many columns (all zero, every view still missing: widened from ``D = 0``, or narrowed to
        it); a home of that dimension is returned as it is; any other dimension is an error."""
        if n_features == self.n_features:
            return self
        if self.view_missing.all():
            return replace(self, visual=sp.csr_array((self.n_samples, int(n_features)), dtype=np.int64))
        raise DataFormatError(self.source or self.name, f"views of {self.n_features} features, not "
                              f"{n_features}")

    def with_views_missing(self, missing: np.ndarray | Sequence[bool]) -> Environment:
        """A copy in which the samples of ``missing`` (N,) bool lose their view as well (a camera
        that dropped those frames)."""
        mask = np.asarray(missing, dtype=bool)
        if mask.shape != (self.n_samples,):
            raise ConfigurationError(f"missing must have shape ({self.n_samples},), got {mask.shape}")
        return replace(self, view_missing=self.view_missing | mask)

    def with_sentences(self, sentences: Sequence[str | None]) -> Environment:
        """A copy with other taught sentences (same samples, same split)."""
        return replace(self, sentences=tuple(sentences))

    def with_teaching_rate(self, rate: float, seed: int = 0) -> Environment:
        """A copy in which only ``rate`` percent of the taught training samples keep their sentence.

        The kept samples are a seeded random subset (the same ``seed`` keeps the same samples, and
        a lower rate keeps a subset of a higher one). ``rate = 0`` removes every sentence.
        """
        if not 0 <= rate <= 100:
            raise ConfigurationError(f"teaching rate must be within 0..100, got {rate}")
        taught = np.array([s is not None and not t for s, t in zip(self.sentences, self.is_test,
                                                                    strict=True)])
        rows = np.flatnonzero(taught)
        order = np.random.default_rng(seed).permutation(rows.size)
        keep = set(rows[order[: round(rows.size * rate / 100.0)]].tolist())
        return self.with_sentences([s if i in keep else None for i, s in enumerate(self.sentences)])

    def without_test_sentences(self) -> Environment:
        """A copy in which test samples carry no sentence."""
        return self.with_sentences([None if t else s for s, t in zip(self.sentences, self.is_test,
                                                                      strict=True)])

    def labels(self, specific: bool = False) -> tuple[str | None, ...]:
        """Evaluation labels (general or home-specific). Raises if the home has none."""
        gt = self.ground_truth
        chosen = None if gt is None else (gt.specific_labels if specific else gt.labels)
        if chosen is None:
            kind = "home-specific" if specific else "place"
            raise DataFormatError(self.source or self.name, f"this home has no {kind} labels")
        return chosen


def _normalised_labels(labels: Sequence[str | None] | None) -> tuple[str | None, ...] | None:
    if labels is None:
        return None
    return tuple(None if not lab else normalize_name(lab) or None for lab in labels)


def make_ground_truth(
    labels: Sequence[str | None] | None = None,
    specific_labels: Sequence[str | None] | None = None,
    specific_test: np.ndarray | None = None,
    regions: PlaceRegions | None = None,
    accepted_names: dict[str, Sequence[str]] | None = None,
) -> GroundTruth:
    """Build a :class:`GroundTruth` with labels (and accepted names) normalised like vocabulary words."""
    accepted = None
    if accepted_names is not None:
        accepted = {}
        for place, names in accepted_names.items():
            key = normalize_name(place)
            accepted[key] = tuple(dict.fromkeys([*accepted.get(key, ()),
                                                 *(n for n in map(normalize_name, names) if n)]))
    return GroundTruth(
        labels=_normalised_labels(labels),
        specific_labels=_normalised_labels(specific_labels),
        specific_test=None if specific_test is None else np.asarray(specific_test, dtype=bool),
        regions=regions,
        accepted_names=accepted,
    )


class Corpus(Sequence[Environment]):
    """Environments that share one vocabulary and one visual dimension.

    A home without any view (every sample's view missing) takes the other homes' dimension; when
    no home has a view, the dimension is 0 (the homes are learnt from poses and words).

    Parameters
    ----------
    environments:
        The homes, in order; home names must be unique.
    vocabulary:
        The word list. By default it is built from the *training* sentences of all homes.
    word_increment:
        Count added per word occurrence (S^w, default 5000).
    language:
        How a vocabulary built here treats text written without spaces (``"auto"``, ``"ja"``,
        ``"zh"``, ``"spaced"``; :func:`spco.data.segmentation.resolve`). Kept for the vocabularies
        of :meth:`subset` and :meth:`replace`.
    n_features:
        The visual dimension of every home (``None``: the homes' own; homes without any view take
        it). Homes read in shards (:class:`~spco.model.sources.FolderHomes`) pass the dimension of
        all homes, so that a shard of homes without views keeps it.
    """

    def __init__(
        self,
        environments: Sequence[Environment],
        vocabulary: Vocabulary | None = None,
        word_increment: int = DEFAULT_WORD_INCREMENT,
        language: str = "auto",
        n_features: int | None = None,
    ) -> None:
        envs = list(environments)
        if not envs:
            raise ConfigurationError("a corpus needs at least one environment")
        names = [e.name for e in envs]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ConfigurationError(f"home names must be unique in a corpus; repeated: {sorted(dup)}")
        # homes without any view take the others' dimension; without any view anywhere, D = 0
        dims = ({e.n_features for e in envs if not e.view_missing.all()} or {0}) if n_features is None \
            else {int(n_features)}
        if len(dims) == 1:
            envs = [e.with_visual_dimension(next(iter(dims))) if e.view_missing.all() else e for e in envs]
        dims = {e.n_features for e in envs}
        if len(dims) != 1:
            detail = ", ".join(f"{e.name}: {e.n_features}" for e in envs)
            raise DataFormatError(None, f"homes have different visual dimensions ({detail})")
        if word_increment < 1:
            raise ConfigurationError(f"word_increment must be >= 1, got {word_increment}")
        self.environments: tuple[Environment, ...] = tuple(envs)
        self.word_increment = int(word_increment)
        self.language = language
        if vocabulary is None:
            vocabulary = Vocabulary.from_sentences(
                (s for e in envs for s in e.training_data().sentences), language=language
            )
        self.vocabulary = vocabulary

    def __len__(self) -> int:
        return len(self.environments)

    def __getitem__(self, key):  # type: ignore[override]
        if isinstance(key, slice):
            return Corpus(self.environments[key], self.vocabulary, self.word_increment)
        if isinstance(key, str):
            return self.environments[self.names.index(key)] if key in self.names else self._missing(key)
        return self.environments[key]

    def _missing(self, name: str) -> Environment:
        raise KeyError(f"no home named {name!r}; homes: {', '.join(self.names)}")

    def __iter__(self) -> Iterator[Environment]:
        return iter(self.environments)

    def __repr__(self) -> str:
        return (f"Corpus({len(self)} homes, {sum(e.n_samples for e in self)} samples, "
                f"{len(self.vocabulary)} words, D={self.n_features})")

    @property
    def names(self) -> list[str]:
        """Home names, in order."""
        return [e.name for e in self.environments]

    @property
    def n_features(self) -> int:
        """Visual dimension D shared by all homes."""
        return self.environments[0].n_features

    def subset(self, names: Sequence[str]) -> Corpus:
        """The homes named ``names``, in that order (vocabulary rebuilt from their sentences)."""
        return Corpus([self[n] for n in names], word_increment=self.word_increment, language=self.language)

    def replace(self, name: str, environment: Environment) -> Corpus:
        """A corpus with home ``name`` replaced (vocabulary rebuilt)."""
        return Corpus([environment if e.name == name else e for e in self.environments],
                      word_increment=self.word_increment, language=self.language)

    def word_counts(self, sentences: Sequence[str | None]) -> sp.csr_array:
        """Bag-of-words counts of ``sentences`` in this corpus's vocabulary."""
        return self.vocabulary.encode(sentences, self.word_increment)

    def training_set(self) -> list[TrainingData]:
        """The training view of every home (what learners are given)."""
        return [e.training_data() for e in self.environments]
