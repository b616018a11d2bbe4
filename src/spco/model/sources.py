"""Where a fleet fit's shards get their homes: each shard prepares its own homes' data.

A :class:`HomeSource` describes all homes of a fit and cuts them into parts
(:meth:`HomeSource.parts`), one per shard; a part is small to send and its :meth:`HomesPart.prepare`
builds the shard's :class:`~spco.model.state.PreparedData` (home indices 0..E_s − 1) where the
shard runs. So the driver never holds every home's data:

- :class:`PreparedHomes`: data already prepared in the driver (a corpus loaded there), cut into
  slices of about equal samples;
- :class:`SyntheticHomes`: synthetic homes that each shard generates itself, home i from its own
  stream ``SeedSequence(seed).spawn(n_homes)[i]`` (as :func:`spco.data.synthetic.generate_homes`
  draws it), so a part is a seed and a range of home indices;
- :class:`FolderHomes`: home folders on disk (plain or SIGVerse layout) that each shard reads
  itself, so a part is a list of paths; the driver only fixes the vocabulary (from the homes'
  sentences, one home at a time) so that every shard counts words in the same columns.
"""

from __future__ import annotations

import itertools
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from spco.model.kernels.counts import stack_counts
from spco.model.state import PreparedData


class HomesPart(ABC):
    """One shard's homes, to be prepared where the shard runs."""

    n_homes: int

    @abstractmethod
    def prepare(self) -> PreparedData:
        """The part's homes as :class:`~spco.model.state.PreparedData` (homes numbered from 0)."""


class HomeSource(ABC):
    """All homes of a fit: ``n_homes`` homes, ``n_words`` words in the shared vocabulary."""

    n_homes: int
    n_words: int

    @abstractmethod
    def parts(self, n_shards: int) -> list[HomesPart]:
        """The homes cut into ``n_shards`` consecutive parts (every part at least one home)."""


def even_bounds(n_homes: int, n_shards: int) -> list[tuple[int, int]]:
    """Consecutive home ranges [first, last) of ``n_shards`` parts whose sizes differ by at most 1."""
    if not 1 <= n_shards <= n_homes:
        raise ValueError(f"the number of shards must be within 1..{n_homes} (the homes), got {n_shards}")
    edges = [round(i * n_homes / n_shards) for i in range(n_shards + 1)]
    return list(itertools.pairwise(edges))


def concatenate_data(parts: list[PreparedData]) -> PreparedData:
    """Consecutive groups of homes as one :class:`PreparedData` (homes renumbered in order)."""
    if len(parts) == 1:
        return parts[0]
    home_starts = np.cumsum([0, *[p.n_homes for p in parts]])
    sample_starts = np.cumsum([0, *[p.n_samples for p in parts]])
    offsets = np.concatenate([parts[0].offsets[:1], *[p.offsets[1:] + s for p, s in zip(parts, sample_starts,
                                                                                          strict=False)]])
    return PreparedData(positions=np.concatenate([p.positions for p in parts]),
                        homes=np.concatenate([p.homes + h for p, h in zip(parts, home_starts, strict=False)]),
                        visual=stack_counts(*(p.visual for p in parts)),
                        words=stack_counts(*(p.words for p in parts)),
                        n_homes=int(home_starts[-1]), offsets=offsets.astype(np.int64),
                        position_scale=parts[0].position_scale,
                        map_centres=np.concatenate([p.map_centres for p in parts]),
                        view_missing=np.concatenate([p.view_missing for p in parts]))


# ----------------------------------------------------------------------------- prepared in the shards

#: Homes prepared at a time by :class:`RangePart` (bounds the memory of the intermediate arrays: a
#: generator's dense draws, or the environments read next to their prepared data).
PREPARE_CHUNK = 32


class RangeSource(HomeSource):
    """Homes that a shard prepares itself by index (generated or read where it runs)."""

    @abstractmethod
    def prepare_homes(self, first: int, last: int) -> PreparedData:
        """Homes first..last − 1 as :class:`~spco.model.state.PreparedData` (numbered from 0)."""


@dataclass
class RangePart(HomesPart):
    """Homes first..last − 1 of a :class:`RangeSource`, prepared on :meth:`prepare`,
    :data:`PREPARE_CHUNK` at a time."""

    source: RangeSource
    first: int
    last: int

    @property
    def n_homes(self) -> int:  # type: ignore[override]
        return self.last - self.first

    def prepare(self) -> PreparedData:
        chunks = [self.source.prepare_homes(a, min(a + PREPARE_CHUNK, self.last))
                  for a in range(self.first, self.last, PREPARE_CHUNK)]
        return concatenate_data(chunks)


# ----------------------------------------------------------------------------- prepared in the driver


@dataclass
class PreparedPart(HomesPart):
    """A slice of data prepared in the driver."""

    data: PreparedData

    @property
    def n_homes(self) -> int:  # type: ignore[override]
        return self.data.n_homes

    def prepare(self) -> PreparedData:
        return self.data


@dataclass
class PreparedHomes(HomeSource):
    """Homes prepared in the driver (``data``, ``n_words`` words): parts of about equal samples."""

    data: PreparedData
    n_words: int

    @property
    def n_homes(self) -> int:  # type: ignore[override]
        return self.data.n_homes

    def parts(self, n_shards: int) -> list[HomesPart]:
        from spco.model.shard import data_of_homes, shard_bounds

        if n_shards == 1:
            return [PreparedPart(self.data)]
        return [PreparedPart(data_of_homes(self.data, a, b)) for a, b in shard_bounds(self.data, n_shards)]


# ----------------------------------------------------------------------------- synthetic, made in the shards

@dataclass
class SyntheticHomes(RangeSource):
    """``n_homes`` synthetic homes (:func:`spco.data.synthetic.generate_homes` with
    ``specific_rooms=False``), the last ``new_homes`` new (nothing taught), generated in the shards.

    Home i is the home ``generate_homes(n_homes, seed, config, new_homes, specific_rooms=False)``
    makes at index i. The vocabulary is learnt from the training sentences of the first
    ``vocabulary_homes`` homes (the driver generates those once, :meth:`create`); with the template
    language every home says words of the same small set, so these homes hold them all (a word
    only later homes said would be left out of their counts, as any word outside a fit's
    vocabulary is)."""

    n_homes: int
    seed: int
    config: object  # SyntheticConfig
    new_homes: int
    vocabulary: object  # Vocabulary
    word_increment: int
    teaching_rate: float = 100.0
    _world: object = field(default=None, repr=False, compare=False)
    position_scale: float = 1.0
    #: (ν, a) of the vocabulary's words (spco.model.name_evidence.channel_evidence) from the sentences
    #: the vocabulary was learnt from; ``None`` when none holds an English function word
    channel_evidence: tuple[np.ndarray, np.ndarray] | None = None
    _scales: tuple[tuple[float, float, int], ...] | None = field(default=None, repr=False, compare=False)

    @classmethod
    def create(cls, n_homes: int, seed: int = 0, config=None, new_homes: int = 0,
               teaching_rate: float = 100.0, vocabulary_homes: int = 16) -> SyntheticHomes:
        """The fleet, with its vocabulary learnt from its first ``vocabulary_homes`` homes."""
        from spco.data.language import DEFAULT_WORD_INCREMENT, Vocabulary
        from spco.data.synthetic import SyntheticConfig

        if n_homes < 1 or not 0 <= new_homes <= n_homes:
            raise ValueError(f"need n_homes >= 1 and 0 <= new_homes <= n_homes, got {n_homes}, {new_homes}")
        source = cls(n_homes, int(seed), config or SyntheticConfig(), new_homes, None, DEFAULT_WORD_INCREMENT,
                     teaching_rate)
        sentences = [s for i in range(min(vocabulary_homes, n_homes))
                     for s in source.home(i).training_data().sentences]
        source.vocabulary = Vocabulary.from_sentences(sentences)
        source.channel_evidence = _channel_evidence(source.vocabulary, sentences)
        return source

    @property
    def n_words(self) -> int:  # type: ignore[override]
        return len(self.vocabulary)

    @property
    def n_features(self) -> int:
        """The homes' visual dimension D."""
        return int(self.config.n_features)

    def _layout(self, index: int):
        """Home ``index``'s layout and the generator :func:`generate_home` continues with."""
        rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(index,)))
        return self.config.layouts[int(rng.integers(len(self.config.layouts)))], rng

    def _name(self, index: int, layout) -> str:
        return f"synthetic_{layout.name}_{index + 1:0{max(2, len(str(self.n_homes)))}d}"

    @property
    def names(self) -> list[str]:
        """The homes' names, in order (from each home's first draw: its layout)."""
        return [self._name(i, self._layout(i)[0]) for i in range(self.n_homes)]

    @property
    def n_samples(self) -> int:
        """Training samples over all homes: ``config.n_train`` per room, the optional rooms drawn
        as :func:`~spco.data.synthetic.generate_home` draws them first."""
        total = 0
        for i in range(self.n_homes):
            layout, rng = self._layout(i)
            optional = int((rng.random(len(layout.optional)) < self.config.optional_room_probability).sum())
            total += self.config.n_train * (len(layout.rooms) + optional)
        return total

    @property
    def scales(self) -> tuple[tuple[float, float, int], ...]:
        """(R, s, n) of each home's training samples (:func:`spco.model.hyperparameters.home_scales`,
        their words in the fleet's vocabulary), for the scaled prior: what
        :func:`~spco.model.hyperparameters.scaled_hyperparameters` reads from the
        :class:`~spco.data.environment.Corpus` of the same homes. Measured on first use, generating the
        homes one at a time in this process (a few milliseconds each; only the scales are kept)."""
        if self._scales is None:
            from spco.model.hyperparameters import home_scales

            measured = []
            for i in range(self.n_homes):
                training = self.home(i).training_data()
                measured.append(home_scales(training.positions,
                                            self.vocabulary.encode(training.sentences, self.word_increment)))
            self._scales = tuple(measured)
        return self._scales

    def __getstate__(self) -> dict:  # the world is rebuilt where the part is prepared
        state = dict(self.__dict__)
        state["_world"] = None
        return state

    def home(self, index: int):
        """Home ``index`` (an :class:`~spco.data.environment.Environment`)."""
        from spco.data.synthetic import generate_home, make_world

        if self._world is None:
            self._world = make_world(self.config, self.seed)
        layout, rng = self._layout(index)
        return generate_home(rng, layout=layout, name=self._name(index, layout), config=self.config,
                             world=self._world, new=index >= self.n_homes - self.new_homes,
                             teaching_rate=self.teaching_rate)

    def prepare_homes(self, first: int, last: int) -> PreparedData:
        """Homes first..last − 1 generated and prepared (homes numbered from 0)."""
        from spco.data.environment import Corpus

        corpus = Corpus([self.home(i) for i in range(first, last)], vocabulary=self.vocabulary,
                        word_increment=self.word_increment)
        return PreparedData.from_corpus(corpus, self.position_scale)

    def parts(self, n_shards: int) -> list[HomesPart]:
        return [RangePart(self, a, b) for a, b in even_bounds(self.n_homes, n_shards)]


# ----------------------------------------------------------------------------- home folders, read in shards

@dataclass
class FolderHomes(RangeSource):
    """Homes in folders on disk (plain or SIGVerse layout, :func:`spco.data.loading.load_homes`),
    read where the shards run: the driver keeps paths, names, per-home sample counts and the
    vocabulary, never the homes' samples.

    Made by :meth:`create`, which reads every home once, one at a time, to check it (a missing or
    broken home is an error naming the file before any shard starts), to learn the vocabulary
    from the training sentences (as :class:`~spco.data.environment.Corpus` does: the same words in
    the same columns) and to count each home's training samples (the shards are cut as
    :class:`PreparedHomes` cuts them, so the chain is the same). Home folders must be reachable
    at the same paths from every shard (on a cluster: shared storage). Views given as images are
    not supported here (load them in the driver with an extractor)."""

    paths: list[str]
    names: list[str]
    teaching_rate: int
    vocabulary: object  # Vocabulary
    word_increment: int
    n_samples_per_home: np.ndarray  # (E,) training samples
    n_taught: int
    n_features: int
    position_scale: float = 1.0
    name_prior: np.ndarray | None = None  # (V,) spco.model.name_evidence.name_prior of the sentences
    #: (R, s, n) of each home (spco.model.hyperparameters.home_scales), for the scaled prior
    scales: tuple[tuple[float, float, int], ...] = ()
    #: (ν, a) of the vocabulary's words (spco.model.name_evidence.channel_evidence); ``None`` when no
    #: sentence holds an English function word
    channel_evidence: tuple[np.ndarray, np.ndarray] | None = None

    @classmethod
    def create(cls, path, names=None, teaching_rate: int = 100, position_scale: float = 1.0,
               progress: bool = False, language: str = "auto") -> FolderHomes:
        """The homes of folder ``path`` (a home, or a folder of homes; ``names`` selects and orders
        them, as in :func:`~spco.data.loading.load_homes`) taught at ``teaching_rate`` percent;
        ``language`` as in :meth:`~spco.data.language.Vocabulary.from_sentences`."""
        from spco.data.language import DEFAULT_WORD_INCREMENT, Vocabulary
        from spco.data.loading import home_folders, load_homes, views_are_images
        from spco.errors import DataFormatError
        from spco.progress import progress_bar

        folders = home_folders(path, names)
        for folder in folders:
            if views_are_images(folder):
                raise DataFormatError(folder, "holds its views as images: homes read in the shards must "
                                      "hold count vectors (visual.npz); load image homes in the driver "
                                      "with an extractor (spco fit does)")
        sentences: list[str | None] = []
        home_names, sizes, taught, dims, views = [], [], 0, set(), 0
        positions: list[np.ndarray] = []
        for folder in progress_bar(folders, desc="reading sentences", unit="home", leave=False,
                                   disable=None if progress else True):
            env = load_homes(folder, teaching_rate=teaching_rate)[0]  # one home at a time
            training = env.training_data()
            if training.n_samples == 0:
                raise DataFormatError(folder, f"home {env.name!r} has no training samples: all its "
                                      f"{env.n_samples} samples are in its test split")
            sentences += training.sentences
            positions.append(training.positions[:, :2].copy())
            home_names.append(env.name)
            sizes.append(training.n_samples)
            taught += env.n_taught
            views += env.n_views
            if env.n_features:  # a home without any view takes the others' dimension
                dims.add(env.n_features)
            if len(dims) > 1:
                raise DataFormatError(folder, f"views of {env.n_features} features, the homes before it "
                                      f"have {min(dims - {env.n_features})}")
        from spco.model.hyperparameters import home_scales
        from spco.model.name_evidence import name_prior

        vocabulary = Vocabulary.from_sentences(sentences, language=language)
        bounds = np.cumsum([0, *sizes])
        scales = tuple(home_scales(xy, vocabulary.encode(sentences[a:b], DEFAULT_WORD_INCREMENT))
                       for xy, a, b in zip(positions, bounds[:-1], bounds[1:], strict=True))
        return cls([str(f) for f in folders], home_names, int(teaching_rate), vocabulary,
                   DEFAULT_WORD_INCREMENT, np.array(sizes, dtype=np.int64), taught,
                   dims.pop() if dims and views else 0, float(position_scale),
                   name_prior(vocabulary, sentences), scales, _channel_evidence(vocabulary, sentences))

    @property
    def n_homes(self) -> int:  # type: ignore[override]
        return len(self.paths)

    @property
    def n_words(self) -> int:  # type: ignore[override]
        return len(self.vocabulary)

    @property
    def n_samples(self) -> int:
        """Training samples over all homes."""
        return int(self.n_samples_per_home.sum())

    def prepare_homes(self, first: int, last: int) -> PreparedData:
        """Homes first..last − 1 read and prepared (homes numbered from 0)."""
        from spco.data.environment import Corpus
        from spco.data.loading import load_homes

        envs = [load_homes(p, teaching_rate=self.teaching_rate)[0] for p in self.paths[first:last]]
        corpus = Corpus(envs, vocabulary=self.vocabulary, word_increment=self.word_increment,
                        n_features=self.n_features)
        return PreparedData.from_corpus(corpus, self.position_scale)

    def parts(self, n_shards: int) -> list[HomesPart]:
        from types import SimpleNamespace

        from spco.model.shard import shard_bounds

        # the cuts of PreparedHomes (about equal samples), from the sample counts alone
        offsets = np.concatenate([[0], np.cumsum(self.n_samples_per_home)])
        sizes = SimpleNamespace(offsets=offsets, n_homes=self.n_homes)
        bounds = shard_bounds(sizes, n_shards)  # type: ignore[arg-type]
        return [RangePart(self, a, b) for a, b in bounds]


def _channel_evidence(vocabulary, sentences) -> tuple[np.ndarray, np.ndarray] | None:
    """The word channels' evidence (ν, a) of ``vocabulary``'s words said in ``sentences``, or ``None``
    when no sentence holds an English function word (:func:`spco.model.name_evidence.has_english`)."""
    from spco.model.name_evidence import channel_evidence, has_english

    if not has_english(vocabulary, sentences):
        return None
    return channel_evidence(vocabulary, sentences)
