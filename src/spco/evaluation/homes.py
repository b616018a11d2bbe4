"""The homes of an experiment (:class:`ExperimentData`): experienced and new homes read from a
data set on disk or generated, their place regions checked, the word list."""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.environment import Environment, make_ground_truth
from spco.data.language import Vocabulary
from spco.data.regions import PlaceRegions, load_region_file
from spco.errors import ConfigurationError, DataFormatError
from spco.evaluation.config import (
    PAPER_EXPERIENCED_HOMES,
    PAPER_NEW_HOMES,
    PAPER_SPECIFIC_HOME,
    SYNTHETIC_NEW_HOMES,
    ExperimentConfig,
)


# ------------------------------------------------------------------------------------ data
@dataclass(frozen=True)
class _DataSpec:
    """Picklable recipe of an :class:`ExperimentData` (rebuilt in every worker process)."""

    experiment: str
    source: str  # "synthetic" or a resolved path
    regions: str | None
    seed: int
    n_needed: int  # experienced homes the settings need
    experienced_homes: tuple[str, ...] | None
    new_homes: tuple[str, ...] | None
    specific_home: str | None
    language: str = "templates"  # sentences of synthetic homes
    shown_source: str | None = None  # --data as given (for result files; no absolute path)
    shown_regions: str | None = None  # --regions as given
    images: str | None = None
    extractor: str | None = None
    shown_images: str | None = None  # --images as given
    text_language: str = "auto"


class _HomeSource:
    """A home that can be given at any teaching rate (experienced: all places; new: as the data
    says, or the synthetic home-specific rooms taught with :func:`~spco.data.synthetic.teach`)."""

    def __init__(self, at_rate: Callable[[int], Environment]) -> None:
        self._at_rate = at_rate
        self._cache: dict[int, Environment] = {}

    def at_rate(self, rate: int) -> Environment:
        if rate not in self._cache:
            self._cache[rate] = self._at_rate(rate)
        return self._cache[rate]


def _untaught(env: Environment) -> Environment:
    return env if all(s is None for s in env.sentences) else env.with_sentences((None,) * env.n_samples)


@dataclass
class ExperimentData:
    """The homes of an experiment, ready to be combined into each run's corpus.

    Use :func:`load_experiment_data`. ``experienced`` is the ordered list of experienced homes (the
    first ``n`` are used with ``n`` homes), ``new_homes`` the evaluated homes of the general experiment,
    ``specific_home`` the new home of the specific experiment, ``vocabulary`` the experiment's word list
    (general: the experienced homes' words; specific: those and the new home's at the highest rate),
    ``vocabularies`` the word list of each teaching rate of the specific experiment
    (:meth:`vocabulary_for`).
    """

    experiment: str
    experienced: tuple[str, ...]
    new_homes: tuple[str, ...]
    specific_home: str | None
    sources: dict[str, _HomeSource]
    regions: dict[str, PlaceRegions] = field(default_factory=dict)
    description: dict[str, Any] = field(default_factory=dict)
    vocabulary: Vocabulary = field(default_factory=lambda: Vocabulary(()))
    #: specific experiment: rate -> the words of the experienced homes and of the new home taught at
    #: that rate (a run at 20 % has no column for a name taught only at higher rates)
    vocabularies: dict[int, Vocabulary] = field(default_factory=dict)
    #: the homes as read, when their views were computed from images (handed to worker processes as
    #: a cache file, so that the images are not read and extracted again in each of them)
    view_records: list[Any] = field(default_factory=list, repr=False)
    _evaluated: dict[tuple[str, int], Environment] = field(default_factory=dict)

    @property
    def evaluated_homes(self) -> tuple[str, ...]:
        """The new homes scored by this experiment."""
        if self.experiment == "specific":
            return (self.specific_home,) if self.specific_home else ()
        return self.new_homes

    def experienced_home(self, name: str) -> Environment:
        """An experienced home, taught at rate 100."""
        return self.sources[name].at_rate(100)

    def new_home(self, name: str, rate: int = 0) -> Environment:
        """A new home taught at ``rate`` (0 in the general experiment), with its regions attached."""
        key = (name, rate)
        if key not in self._evaluated:
            env = self.sources[name].at_rate(rate)
            regions = self.regions.get(name)
            if regions is not None:
                gt = env.ground_truth or make_ground_truth()
                env = replace(env, ground_truth=replace(gt, regions=regions))
            self._evaluated[key] = env
        return self._evaluated[key]

    def vocabulary_for(self, setting: int) -> Vocabulary:
        """The word list of the runs of ``setting``: the experiment's (general), or the words the
        homes of that teaching rate were taught (specific)."""
        return self.vocabularies.get(setting, self.vocabulary)

    def homes_for(self, setting: int, home: str) -> list[Environment]:
        """The homes of one run, new home last: ``(experienced…, new)``."""
        if self.experiment == "general":
            return [*(self.experienced_home(n) for n in self.experienced[:setting]), self.new_home(home, 0)]
        return [*(self.experienced_home(n) for n in self.experienced), self.new_home(home, setting)]


def _read_path_sources(spec: _DataSpec) -> tuple[tuple[str, ...], tuple[str, ...], str | None,
                                                     dict[str, _HomeSource], list[Any], Any]:
    """The homes of a data set on disk: experienced, new and specific home names, their sources, the
    records read and the image extractor (``None`` for count vectors)."""
    from spco.data.loading import read_records

    experienced = spec.experienced_homes or PAPER_EXPERIENCED_HOMES
    if spec.experiment == "general":
        new = spec.new_homes or PAPER_NEW_HOMES
        specific = None
    else:
        if spec.new_homes is not None and spec.specific_home is None and len(spec.new_homes) != 1:
            raise ConfigurationError("the specific experiment has one new home; pass it as "
                                     "specific_home (--new-home)")
        specific = spec.specific_home or (spec.new_homes[0] if spec.new_homes else PAPER_SPECIFIC_HOME)
        new = (specific,)
    overlap = sorted(set(experienced) & set(new))
    if overlap:
        raise ConfigurationError(f"home(s) {', '.join(overlap)} listed both as experienced and as new")
    names = list(dict.fromkeys([*experienced, *new]))
    extractor = _image_extractor(spec, experienced)
    try:
        records = read_records(spec.source, names=names, extractor=extractor, images=spec.images)
    except DataFormatError as exc:
        if "no home named" in exc.problem and spec.experienced_homes is None:
            raise DataFormatError(exc.path, f"{exc.problem}. The experiments use the homes of the "
                                  "paper's SIGVerse data set by default; for other data pass "
                                  "--experienced-homes and --new-homes") from None
        raise
    sources: dict[str, _HomeSource] = {}
    for name, rec in zip(names, records, strict=True):
        sources[name] = _HomeSource(rec.at_rate)
    return tuple(experienced), tuple(new), specific, sources, records, extractor


def _image_extractor(spec: _DataSpec, experienced: Sequence[str]) -> Any:
    """The extractor of views given as images (``None`` for count vectors); a codebook it needs is
    learnt from the experienced homes' training images."""
    if spec.images is None and spec.extractor is None:
        return None
    from spco.data.loading import training_image_files
    from spco.features import DEFAULT_EXTRACTOR, build_extractor

    extractor = build_extractor(spec.extractor or DEFAULT_EXTRACTOR)
    if extractor.needs_fit:
        files = training_image_files(spec.source, list(experienced), spec.images)
        extractor = extractor.fitted(files, random_state=spec.seed)
    return extractor


def _synthetic_sources(spec: _DataSpec) -> tuple[tuple[str, ...], tuple[str, ...], str | None,
                                                    dict[str, _HomeSource], dict[str, PlaceRegions]]:
    from spco.data.synthetic import SyntheticConfig, generate_homes, teach

    if spec.experienced_homes is not None:
        raise ConfigurationError("experienced_homes cannot be chosen for synthetic data (they are "
                                 "the first generated homes)")
    n_exp = max(len(PAPER_EXPERIENCED_HOMES), spec.n_needed)
    language = SyntheticConfig(language=spec.language)
    corpus = generate_homes(n_exp + SYNTHETIC_NEW_HOMES, seed=spec.seed, new_homes=SYNTHETIC_NEW_HOMES,
                            config=language)
    names = corpus.names
    experienced, all_new = tuple(names[:n_exp]), tuple(names[n_exp:])
    sources: dict[str, _HomeSource] = {}
    for name in experienced:
        env = corpus[name]
        sources[name] = _HomeSource(lambda rate, env=env: env if rate == 100 else
                                    env.with_teaching_rate(rate, seed=spec.seed))
    specific_home = all_new[-1]
    specific_names = None
    for name in all_new:
        env = corpus[name]
        gt = env.ground_truth
        if gt is not None and gt.specific_labels is not None and gt.specific_test is not None:
            specific_names = sorted({gt.specific_labels[i] for i in np.flatnonzero(gt.specific_test)
                                     if gt.specific_labels[i] is not None})

            def taught(rate: int, env: Environment = env, places: list[str] = specific_names) -> Environment:
                return (teach(env, rate, places=places, seed=spec.seed, config=language) if rate > 0
                        else _untaught(env))
        else:
            def taught(rate: int, env: Environment = env) -> Environment:
                return _untaught(env)
        sources[name] = _HomeSource(taught)
    if spec.experiment == "general":
        new = all_new
        if spec.new_homes is not None:
            unknown = [n for n in spec.new_homes if n not in all_new]
            if unknown:
                raise ConfigurationError(f"no synthetic new home {', '.join(map(repr, unknown))}; the "
                                         f"synthetic new homes (seed {spec.seed}): {', '.join(all_new)}")
            new = tuple(spec.new_homes)
        specific = None
    else:
        new = (specific_home,)
        specific = specific_home
        if spec.specific_home not in (None, specific_home) or spec.new_homes not in (None, new):
            raise ConfigurationError(f"the synthetic home-specific experiment uses {specific_home!r}")
    regions = {n: corpus[n].ground_truth.regions for n in all_new
               if corpus[n].ground_truth is not None and corpus[n].ground_truth.regions is not None}
    return experienced, new, specific, sources, regions


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _build_data(spec: _DataSpec, settings: Sequence[int]) -> ExperimentData:
    regions: dict[str, PlaceRegions] = {}
    records: list[Any] = []
    extractor = None
    if spec.source == "synthetic":
        experienced, new, specific, sources, regions = _synthetic_sources(spec)
    else:
        experienced, new, specific, sources, records, extractor = _read_path_sources(spec)
    if spec.regions is not None:
        regions = load_region_file(spec.regions)
    data = ExperimentData(experiment=spec.experiment, experienced=experienced, new_homes=new,
                          specific_home=specific, sources=sources)
    if spec.experiment == "general" and max(settings) > len(experienced):
        raise ConfigurationError(f"--envs asks for {max(settings)} experienced homes but the experiment "
                                 f"has {len(experienced)}: {', '.join(experienced)}")
    data.regions = _check_regions(data, regions, spec, settings)
    sentences = [s for n in experienced for s in data.experienced_home(n).training_data().sentences]
    if spec.experiment == "specific":
        # one word list per teaching rate, from the sentences taught at that rate only
        data.vocabularies = {rate: Vocabulary.from_sentences(
            sentences + list(data.new_home(specific, rate).training_data().sentences),  # type: ignore[arg-type]
            language=spec.text_language)
            for rate in settings}
        data.vocabulary = data.vocabularies[max(settings)]
    else:
        data.vocabulary = Vocabulary.from_sentences(sentences, language=spec.text_language)
    if len(data.vocabulary) == 0:
        raise DataFormatError(spec.source, "no taught sentence in any experienced home: there are no "
                              "place names to learn")
    data.description = {
        "source": spec.shown_source or spec.source,
        "language": spec.language,
        "experienced_homes": list(experienced),
        "new_homes": list(new),
        "specific_home": specific,
        "regions": spec.shown_regions or spec.regions,
        "regions_sha256": _file_digest(Path(spec.regions)) if spec.regions else None,
        "vocabulary": list(data.vocabulary.words),
    }
    if data.vocabulary.segmentation is not None:  # (absent otherwise: earlier results resume)
        data.description["segmentation"] = data.vocabulary.segmentation.to_dict()
    if data.vocabularies:
        data.description["vocabulary_by_rate"] = {str(r): list(v.words) for r, v in
                                                  sorted(data.vocabularies.items())}
    if spec.images is not None or spec.extractor is not None:
        from spco.features import DEFAULT_EXTRACTOR

        # the extractor's full description (version, settings, checksum of a learnt codebook): a
        # resumed experiment whose views would be computed differently is another experiment
        data.description["views"] = {"images": spec.shown_images or spec.images,
                                     "extractor": spec.extractor or DEFAULT_EXTRACTOR,
                                     "extractor_spec": extractor.spec().to_dict()}
        data.view_records = records
    return data


def _check_regions(data: ExperimentData, regions: dict[str, PlaceRegions], spec: _DataSpec,
                   settings: Sequence[int]) -> dict[str, PlaceRegions]:
    """Every evaluated home must have labels, scored samples and a region for every scored place."""
    where = spec.regions or spec.source
    out: dict[str, PlaceRegions] = {}
    specific = spec.experiment == "specific"
    for home in data.evaluated_homes:
        rates = settings if specific else (0,)
        for rate in rates:
            data.sources[home].at_rate(rate)  # a missing teaching rate fails here, before any run
        env = data.sources[home].at_rate(rates[0])
        gt = env.ground_truth
        own = regions.get(home)
        if own is None and spec.regions is None and gt is not None:
            own = gt.regions
        if own is None:
            if spec.regions is not None:
                raise DataFormatError(spec.regions, f"no regions for new home {home!r}; the file covers "
                                      f"{', '.join(regions) or 'no home'}")
            raise DataFormatError(spec.source, f"new home {home!r} has no ground-truth regions: pass a "
                                  "region file (--regions, e.g. sigverse_regions.json)")
        if gt is None or (gt.specific_labels if specific else gt.labels) is None:
            kind = "home-specific labels" if specific else "place labels"
            raise DataFormatError(env.source or spec.source, f"new home {home!r} has no {kind} to "
                                  "score predictions against")
        if specific:
            if gt.specific_test is None or not np.asarray(gt.specific_test).any():
                raise DataFormatError(env.source or spec.source, f"new home {home!r} has no "
                                      "home-specific test samples (test_num_specific.txt)")
            rows = np.flatnonzero(np.asarray(gt.specific_test, dtype=bool))
            places = {gt.specific_labels[i] for i in rows}  # type: ignore[index]
        else:
            if env.n_test == 0:
                raise DataFormatError(env.source or spec.source, f"new home {home!r} has no test samples")
            places = set(gt.labels)  # type: ignore[arg-type]
        missing = sorted(p for p in places if p is not None and p not in own.places)
        if missing:
            raise DataFormatError(where, f"the regions of new home {home!r} lack place(s) "
                                  f"{', '.join(missing)} (they have {', '.join(own.places)})")
        out[home] = own
    return out


def _data_spec(config: ExperimentConfig) -> _DataSpec:
    source = config.data
    if source != "synthetic":
        path = Path(source).expanduser()
        if not path.exists():
            raise DataFormatError(path, "no such data folder or file (--data); pass a folder of homes, "
                                  "an spco cache file, or 'synthetic'")
        source = str(path.resolve())
    regions = None
    if config.regions is not None:
        rpath = Path(config.regions).expanduser()
        if not rpath.is_file():
            raise DataFormatError(rpath, "region file not found (--regions)")
        regions = str(rpath.resolve())
    settings = config.settings or ()
    n_needed = max(settings) if config.experiment == "general" and settings else 0
    if config.language != "templates" and source != "synthetic":
        raise ConfigurationError(f"--language {config.language} applies to synthetic homes only (--data "
                                 "synthetic); a data set's sentences are what its people said")
    images = None
    if config.images is not None:
        ipath = Path(config.images).expanduser()
        if not ipath.is_dir():
            raise DataFormatError(ipath, "no such folder of images (--images)")
        images = str(ipath.resolve())
    if source == "synthetic" and (images is not None or config.extractor is not None):
        raise ConfigurationError("synthetic homes have no images; --images and --extractor need --data")
    return _DataSpec(config.experiment, source, regions, config.seed, n_needed,
                     config.experienced_homes, config.new_homes, config.specific_home, config.language,
                     shown_source=str(config.data),
                     shown_regions=None if config.regions is None else str(config.regions),
                     images=images, extractor=config.extractor,
                     shown_images=None if config.images is None else str(config.images),
                     text_language=config.text_language)


def load_experiment_data(config: ExperimentConfig) -> ExperimentData:
    """Load (or generate) the homes of ``config`` and check them: home lists, teaching rates,
    labels and ground-truth regions of the new homes. Raises :class:`~spco.errors.SpcoError`
    subclasses with a message naming the file or option at fault."""
    config = config.validated()
    return _build_data(_data_spec(config), config.settings or ())
