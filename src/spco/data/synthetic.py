"""Synthetic homes: a seeded generator of realistic data, so spco runs without any data set.

The generator imitates the SIGVerse data of Hagiwara et al. (2021): homes of several layouts
(``1K`` … ``3LDK``), 20 training samples per room in consecutive blocks, new homes with 10 test
samples per room, poses ``(x, y, sin θ, cos θ)`` in metres, sparse bag-of-features visual counts
with about the density of the authors' CaffeNet fc7 × 5 counts, and sentences from the paper's five
templates. One home can hold home-specific bedrooms (``"Emma's-room"`` …) like ``3LDK_9``.

How a home is made
------------------
*Floor plan.* The rooms of a layout get a target area each (``SyntheticConfig.room_areas``, jittered
by ±20 %); the house rectangle, centred on the origin, has their total area. A guillotine split cuts it
recursively across its longer side into two parts whose areas match two groups of rooms, until every
room has its own rectangle; plans with slivers (a side under 1 m or an aspect ratio over 3) are redrawn.
The rectangles tile the house without overlap; they are the ground-truth
:class:`~spco.data.regions.PlaceRegions` (a place with several rooms, such as ``bedroom``, is the union
of its rooms), and the house rectangle is the map extent.

*Positions.* Uniform inside the room, ``wall_margin`` metres away from its walls, heading uniform.

*Vision* (a topic model of what a camera sees, read out like a CNN's ReLU layer). A fixed *visual
world* holds ``n_topics`` sparse distributions over the ``n_features`` features ("visual motifs": a
sink, a bed, tiles …) and, for every place type, a distribution over topics made of a part shared by all
places, a part shared with similar places (``similar_places``: bath/washroom/toilet look alike) and a
part of its own (``place_distinctness``). Every room of every home draws its own topic weights around
its type's (Dirichlet with concentration ``home_concentration``: a home's kitchen is like, not equal
to, the world's kitchen; two bedrooms of a home differ), and every home multiplies the features by a
home style (log-normal, ``home_style``). An image mixes its room's topics with those of a neighbouring
room the robot faces (seen through a door, ``view_mixing``) and draws its own topic weights from that
mix (``image_concentration``). Its activation is the log of the resulting feature profile plus
Gaussian noise (``feature_noise``); the features above the image's ``1 - active_fraction`` quantile
(jittered by ``active_spread``) fire, by how much they exceed it, scaled to a total of about
``counts_per_image`` (±``count_spread``) and truncated to integers — as the fc7 × 5 counts are.

With the defaults, the statistics match the SIGVerse counts: ~19 % non-zero features per image,
non-zero values with quantiles 2 / 7 / 19 / 33 (10, 50, 90, 99 %; the real data: 2 / 7 / 18 / 33),
cosine similarity of two images ~0.6 within a room and ~0.3 across rooms (real: 0.7 and 0.33). A
nearest-centroid classifier trained on experienced homes names the rooms of a new home from vision
alone with ~0.88 accuracy at D = 1024 (~0.9 at 4096; the real data: ~0.99), its mistakes mostly
between similar places (toilet/bath, living-room/bedroom, dining/kitchen): vision carries most of
the transfer, position and language still matter.

*The visual world and the seed.* The world is drawn from ``SyntheticConfig.world_seed`` alone (0 by
default), not from the per-call seed: homes of every call and every seed share one world, as real
homes share what kitchens look like. So knowledge learnt from ``generate_homes(16, seed=0)`` transfers
to a home of ``generate_homes(1, seed=7)``. Set ``world_seed=None`` to draw the world from the
call's seed instead (a different world per seed). Each place type's part of the world is drawn from
its own name-keyed stream, so adding a place type leaves the others unchanged.

*Sentences.* Taught training samples get one of the five templates of the paper ("this is the X",
"the X is here", "this place is the X", "this space is the X", "this location is the X"; no article
before possessive names: "this is Emma's-room"). Optionally a fraction of free-form sentences
("hey robot, we call this area the kitchen") and of sentences naming a wrong place. With
``SyntheticConfig(language="free")`` a household of one to three people speaks instead, as people do
(:mod:`spco.data.speech`: synonyms, multi-word names, objects, fillers, typos, the room next door),
and the ground truth lists each place's accepted names.

Everything is driven by :class:`numpy.random.Generator` streams: the same seed gives bitwise
identical homes (with the same NumPy and BLAS: image profiles go through a matrix product).
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from spco.data.environment import Corpus, Environment, make_ground_truth
from spco.data.floorplans import _adjacent, _plan, floor_plan
from spco.data.language import DEFAULT_WORD_INCREMENT, normalize_name
from spco.data.regions import PlaceRegions, Rectangle
from spco.data.speech import Household, accepted_names
from spco.data.synthetic_config import (
    _PART_CONCENTRATION,
    _POPULARITY_SIGMA,
    _TOPIC_SIGMA,
    DEFAULT_LAYOUTS,
    FREE_FORM_TEMPLATES,
    GENERAL_PLACES,
    SENTENCE_TEMPLATES,
    SPECIFIC_ROOM_NAMES,
    Layout,
    SyntheticConfig,
    _is_seed,
)
from spco.errors import ConfigurationError

__all__ = [
    "DEFAULT_LAYOUTS",
    "FREE_FORM_TEMPLATES",
    "GENERAL_PLACES",
    "SENTENCE_TEMPLATES",
    "SPECIFIC_ROOM_NAMES",
    "Layout",
    "SyntheticConfig",
    "VisualWorld",
    "floor_plan",
    "generate_home",
    "generate_homes",
    "make_sentence",
    "make_world",
    "teach",
]

# --------------------------------------------------------------------------------------- the world
@dataclass(frozen=True, eq=False)
class VisualWorld:
    """What places look like, shared by all homes.

    Attributes
    ----------
    place_types: normalised place type names, length T.
    topics: (K, D) float64, each row a distribution over the D visual features.
    place_topics: (T, K) float64, each row a place type's distribution over the K topics.
    """

    place_types: tuple[str, ...]
    topics: np.ndarray
    place_topics: np.ndarray
    _index: dict[str, int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_index", {t: k for k, t in enumerate(self.place_types)})

    @property
    def n_features(self) -> int:
        """Visual dimension D."""
        return int(self.topics.shape[1])

    def type_index(self, place_type: str) -> int:
        """Row of ``place_type`` in :attr:`place_topics`."""
        try:
            return self._index[normalize_name(place_type)]
        except KeyError:
            raise ConfigurationError(f"unknown place type {place_type!r}; known: "
                                     f"{', '.join(self.place_types)}") from None

    def prototype(self, place_type: str) -> np.ndarray:
        """Mean feature distribution (D,) of ``place_type`` over all homes (before home styles)."""
        return self.place_topics[self.type_index(place_type)] @ self.topics


def _stream(*keys: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(k) for k in keys]))


def _key(text: str) -> int:
    return zlib.crc32(text.encode("utf-8"))


def make_world(config: SyntheticConfig | None = None, seed: int | None = None) -> VisualWorld:
    """The visual world of ``config``: drawn from ``config.world_seed``, or from ``seed`` if that is
    ``None`` (then ``seed`` must be given).

    The topics depend on the seed, ``n_features``, ``n_topics`` and ``topic_support``; each place
    type's topic weights depend on the seed, its own name and its group of similar places.
    """
    config = config or SyntheticConfig()
    world_seed = config.world_seed if config.world_seed is not None else seed
    if world_seed is None:
        raise ConfigurationError("make_world needs a seed when config.world_seed is None")
    if not _is_seed(world_seed):
        raise ConfigurationError(f"a seed must be a non-negative integer, got {world_seed!r}")
    d, k = config.n_features, config.n_topics
    rng = _stream(world_seed, 1, d, k)
    popularity = rng.lognormal(0.0, _POPULARITY_SIGMA, size=d)  # some features fire more in every image
    support = rng.random((k, d)) < config.topic_support
    topics = (support * rng.lognormal(0.0, _TOPIC_SIGMA, size=(k, d)) + 1e-3) * popularity
    topics /= topics.sum(axis=1, keepdims=True)

    types = tuple(normalize_name(t) for t in config.place_types)
    group_of = {t: (t,) for t in types}
    for group in config.similar_places:
        members = tuple(sorted(normalize_name(t) for t in group))
        for t in members:
            group_of[t] = members

    def part(*keys: int) -> np.ndarray:
        return _stream(world_seed, *keys).dirichlet(np.full(k, _PART_CONCENTRATION))

    shared = part(2, k)
    distinct, similar = config.place_distinctness, config.group_similarity
    place_topics = np.empty((len(types), k))
    for row, t in enumerate(types):
        group = part(3, k, _key("|".join(group_of[t])))
        own = part(4, k, _key(t))
        place_topics[row] = (1.0 - distinct - similar) * shared + similar * group + distinct * own
    return VisualWorld(types, topics, place_topics)


# -------------------------------------------------------------------------------------- sentences
def make_sentence(name: str, rng: np.random.Generator, free_form: bool = False) -> str:
    """A sentence naming place ``name``: one of the paper's five templates, or a free-form one.

    No article goes before a possessive name (``"this is Emma's-room"``).
    """
    templates = FREE_FORM_TEMPLATES if free_form else SENTENCE_TEMPLATES
    template = templates[int(rng.integers(len(templates)))]
    the = "" if "'s" in name else "the "
    return template.format(the=the, name=name)


def _sentences(rng: np.random.Generator, names: Sequence[str], candidates: Sequence[str],
               config: SyntheticConfig, neighbours: Sequence[Sequence[str]] | None = None) -> list[str]:
    """One sentence per entry of ``names``; wrong names are drawn from ``candidates``. With
    ``config.language == "free"`` a :class:`~spco.data.speech.Household` speaks, and may name one of
    ``neighbours[i]`` (the places next to sample ``i``) instead."""
    n = len(names)
    if config.language == "free":
        household = Household(rng)
        return [household.sentence(name, () if neighbours is None else neighbours[i])
                for i, name in enumerate(names)]
    free = rng.random(n) < config.free_form_rate
    wrong = rng.random(n) < config.wrong_name_rate
    pick = rng.integers(0, max(len(candidates) - 1, 1), size=n)
    out = []
    for i, name in enumerate(names):
        if wrong[i]:
            others = [c for c in candidates if normalize_name(c) != normalize_name(name)]
            if others:
                name = others[int(pick[i]) % len(others)]
        out.append(make_sentence(name, rng, free_form=bool(free[i])))
    return out


# --------------------------------------------------------------------------------------- one home
def _looked_into(rng: np.random.Generator, config: SyntheticConfig, rects: Sequence[Rectangle],
                 room_of: np.ndarray, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The neighbouring room each image looks into (N,), and how much of the image it fills (N,):
    more of the room the camera faces, none for a room without neighbours."""
    n = room_of.size
    centres = np.array([((r[0] + r[1]) / 2, (r[2] + r[3]) / 2) for r in rects])
    neighbours = _adjacent(rects)
    other = room_of.copy()
    share = np.zeros(n)
    mix = rng.beta(1.0, 1.0 / config.view_mixing - 1.0, size=n) if config.view_mixing > 0 else share
    u = rng.random(n)
    heading = positions[:, [3, 2]]  # (cos θ, sin θ)
    for r in range(len(rects)):
        rows = np.flatnonzero(room_of == r)
        adj = neighbours[r]
        if not adj or rows.size == 0:
            continue
        to = centres[adj][None, :, :] - positions[rows, None, :2]  # (n_r, A, 2)
        to /= np.maximum(np.linalg.norm(to, axis=2, keepdims=True), 1e-9)
        facing = np.clip(np.einsum("nad,nd->na", to, heading[rows]), 0.0, None)  # (n_r, A)
        weight = facing + 0.1
        cdf = np.cumsum(weight, axis=1) / weight.sum(axis=1, keepdims=True)
        choice = np.minimum((u[rows, None] > cdf).sum(axis=1), len(adj) - 1)
        other[rows] = np.asarray(adj)[choice]
        share[rows] = mix[rows] * facing[np.arange(rows.size), choice]
    return other, share


def _visual(rng: np.random.Generator, world: VisualWorld, config: SyntheticConfig,
            room_types: Sequence[str], rects: Sequence[Rectangle], room_of: np.ndarray,
            positions: np.ndarray) -> sp.csr_array:
    """Visual counts (N, D) of samples in rooms ``room_of`` (N,) at ``positions`` (N, 4)."""
    n = room_of.size
    base = world.place_topics[[world.type_index(t) for t in room_types]]  # (R, K)
    room_topics = rng.gamma(config.home_concentration * base + 1e-3)
    room_topics /= room_topics.sum(axis=1, keepdims=True)
    style = rng.lognormal(-config.home_style ** 2 / 2, config.home_style, size=world.n_features)

    other, share = _looked_into(rng, config, rects, room_of, positions)
    mixed = (1.0 - share)[:, None] * room_topics[room_of] + share[:, None] * room_topics[other]
    image_topics = rng.gamma(config.image_concentration * mixed + 1e-4)
    image_topics /= image_topics.sum(axis=1, keepdims=True)

    # a ReLU-like activation: log of the expected profile plus noise, above a per-image threshold
    act = image_topics.astype(np.float32) @ world.topics.astype(np.float32)  # (N, D), rows sum to 1
    act *= (style * world.n_features).astype(np.float32)
    act += np.float32(1e-6)
    np.log(act, out=act)
    if config.feature_noise > 0:
        noise = rng.standard_normal(act.shape, dtype=np.float32)
        noise *= np.float32(config.feature_noise)
        act += noise
        del noise
    kth = min(max(round((1.0 - config.active_fraction) * world.n_features), 0), world.n_features - 1)
    threshold = np.partition(act, kth, axis=1)[:, kth].astype(np.float64)
    threshold += config.active_spread * rng.standard_normal(n)
    act -= threshold[:, None].astype(np.float32)
    np.maximum(act, 0, out=act)
    # scale each image to its total count, then truncate (the sum of the truncated counts ≈ total)
    totals = config.mean_counts * rng.lognormal(-config.count_spread ** 2 / 2, config.count_spread, n)
    active = np.count_nonzero(act, axis=1)
    scale = (totals + 0.5 * active) / np.maximum(act.sum(axis=1, dtype=np.float64), 1e-12)
    act *= scale[:, None].astype(np.float32)
    fires = act >= 1
    flat = np.flatnonzero(fires)  # row-major: sorted by row, then column
    data = act.ravel()[flat].astype(np.int64)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.count_nonzero(fires, axis=1), out=indptr[1:])
    return sp.csr_array((data, flat % world.n_features, indptr), shape=act.shape)


def _room_types(rng: np.random.Generator, layout: Layout, config: SyntheticConfig) -> list[str]:
    """The place type of each room of a home: the layout's rooms and the optional rooms drawn, in a
    random order with the entrance first."""
    present = rng.random(len(layout.optional)) < config.optional_room_probability
    rooms = [normalize_name(t) for t in layout.rooms]
    rooms += [normalize_name(t) for t, keep in zip(layout.optional, present, strict=True) if keep]
    order = rng.permutation(len(rooms))
    rooms = [rooms[i] for i in order]
    if "entrance" in rooms:
        rooms.insert(0, rooms.pop(rooms.index("entrance")))
    return rooms


def _room_names(rooms: Sequence[str], layout: Layout, config: SyntheticConfig,
                specific_names: Sequence[str]) -> tuple[dict[int, str], dict[int, str]]:
    """(room -> the name its sentences use, room -> home-specific name): the first rooms of
    ``config.specific_place_type`` take ``specific_names``, checked."""
    specific_type = normalize_name(config.specific_place_type)
    of_type = [i for i, t in enumerate(rooms) if t == specific_type]
    special = [normalize_name(s) for s in specific_names]
    if any(not s for s in special) or len(set(special)) != len(special) or set(special) & set(rooms):
        raise ConfigurationError(f"home-specific names must be distinct, non-empty and differ from "
                                 f"the place types, got {list(specific_names)}")
    if len(specific_names) > len(of_type):
        raise ConfigurationError(f"layout {layout.name!r} has {len(of_type)} room(s) of type "
                                 f"{specific_type!r}, too few for {len(specific_names)} "
                                 "home-specific rooms")
    type_names = {normalize_name(t): t for t in config.place_types}
    display = {i: type_names.get(t, t) for i, t in enumerate(rooms)}
    specific_rooms = dict(zip(of_type, specific_names, strict=False))
    display.update(specific_rooms)
    return display, specific_rooms


def _sample_blocks(n_rooms: int, config: SyntheticConfig, new: bool,
                   specific_rooms: Mapping[int, str]) -> tuple[np.ndarray, np.ndarray]:
    """(room of each sample, whether it is a test sample): blocks of training samples per room, then
    test samples (new homes), then extra training samples of the home-specific rooms."""
    blocks: list[tuple[int, int, bool]] = [(r, config.n_train, False) for r in range(n_rooms)]
    if new and config.n_test > 0:
        blocks += [(r, config.n_test, True) for r in range(n_rooms)]
    if config.specific_extra_train > 0:
        blocks += [(r, config.specific_extra_train, False) for r in specific_rooms]
    room_of = np.concatenate([np.full(size, r) for r, size, _ in blocks])
    is_test = np.concatenate([np.full(size, test) for _, size, test in blocks])
    return room_of, is_test


def generate_home(
    rng: np.random.Generator | int | None = None,
    *,
    layout: Layout | str = "2LDK",
    name: str | None = None,
    config: SyntheticConfig | None = None,
    world: VisualWorld | None = None,
    new: bool = False,
    specific_names: Sequence[str] = (),
    teaching_rate: float = 100.0,
) -> Environment:
    """One synthetic home.

    Parameters
    ----------
    rng:
        A generator, or a seed for one (``None``: fresh entropy). Drives everything but the world.
    layout:
        A :class:`Layout`, or the name of one of ``config.layouts``.
    name:
        The home's name (default ``"synthetic_<layout>"``).
    config:
        Generator settings (default :class:`SyntheticConfig`).
    world:
        The visual world (default :func:`make_world` of ``config``; needs ``config.world_seed``).
    new:
        A *new* home: it also has ``config.n_test`` test samples per room (after the training
        blocks), and nothing is taught.
    specific_names:
        Names of home-specific rooms: the first ``len(specific_names)`` rooms of type
        ``config.specific_place_type`` take them (in ``specific_labels`` and in sentences) and get
        ``config.specific_extra_train`` more training samples, appended last.
    teaching_rate:
        Percent of the training samples of an experienced home that carry a sentence (a random
        subset); ignored for new homes.

    Returns
    -------
    An :class:`~spco.data.environment.Environment` with N samples: training blocks of
    ``config.n_train`` per room (entrance first, then the rooms in random order), test blocks, extra
    blocks. Its ground truth holds the general labels, the specific labels and test mask (home-specific
    rooms only, else ``None``) and the room rectangles as :class:`PlaceRegions`.
    """
    config = config or SyntheticConfig()
    if not (rng is None or isinstance(rng, np.random.Generator) or _is_seed(rng)):
        raise ConfigurationError(f"rng must be a numpy Generator, a non-negative seed or None, got {rng!r}")
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    world = world or make_world(config)
    if world.n_features != config.n_features:
        raise ConfigurationError(f"the world has {world.n_features} features, the config "
                                 f"{config.n_features}")
    if not 0 <= teaching_rate <= 100:
        raise ConfigurationError(f"teaching rate must be within 0..100, got {teaching_rate}")
    layout = config.layout(layout) if isinstance(layout, str) else layout
    name = name or f"synthetic_{layout.name}"

    rooms = _room_types(rng, layout, config)
    display, specific_rooms = _room_names(rooms, layout, config, specific_names)

    rects, extent = _plan(rng, rooms, config)

    room_of, is_test = _sample_blocks(len(rooms), config, new, specific_rooms)
    n = room_of.size

    box = np.asarray(rects)[room_of]  # (N, 4)
    span = np.stack([box[:, 1] - box[:, 0], box[:, 3] - box[:, 2]], axis=1)  # (N, 2)
    margin = np.minimum(config.wall_margin, span / 4)
    low = box[:, [0, 2]] + margin
    xy = low + rng.random((n, 2)) * (span - 2 * margin)
    theta = rng.uniform(0.0, 2 * np.pi, n)
    positions = np.column_stack([xy, np.sin(theta), np.cos(theta)])

    visual = _visual(rng, world, config, rooms, rects, room_of, positions)

    sentences: list[str | None] = [None] * n
    if not new and teaching_rate > 0:
        train_rows = np.flatnonzero(~is_test)
        chosen = np.sort(rng.permutation(train_rows)[: round(train_rows.size * teaching_rate / 100)])
        candidates = list(dict.fromkeys(display.values()))
        next_door = None
        if config.language == "free":
            adjacent = _adjacent(rects)
            next_door = [[display[j] for j in adjacent[int(room_of[i])] if rooms[j] != rooms[int(room_of[i])]]
                         for i in chosen]
        said = _sentences(rng, [display[int(room_of[i])] for i in chosen], candidates, config, next_door)
        for i, sentence in zip(chosen, said, strict=True):
            sentences[int(i)] = sentence

    labels = [rooms[int(r)] for r in room_of]
    specific_labels = specific_test = None
    if specific_rooms:
        specific_labels = [display[int(r)] if int(r) in specific_rooms else rooms[int(r)]
                           for r in room_of]
        specific_test = is_test & np.isin(room_of, list(specific_rooms))
    regions: dict[str, list[Rectangle]] = {}
    for r, t in enumerate(rooms):
        regions.setdefault(t, []).append(rects[r])
    for r, special in specific_rooms.items():
        regions[normalize_name(special)] = [rects[r]]
    accepted = None
    if config.language == "free":
        accepted = {normalize_name(p): accepted_names(p) for p in (*display.values(), *rooms)}
    ground_truth = make_ground_truth(
        labels, specific_labels, specific_test,
        PlaceRegions({p: tuple(rs) for p, rs in regions.items()}), accepted_names=accepted,
    )
    return Environment(
        name=name, ids=np.arange(n, dtype=np.int64), positions=positions, visual=visual,
        sentences=tuple(sentences), is_test=is_test, extent=extent, ground_truth=ground_truth,
        source=None,
    )


# ------------------------------------------------------------------------------------ many homes
def generate_homes(
    n_homes: int,
    seed: int = 0,
    config: SyntheticConfig | None = None,
    new_homes: int = 0,
    specific_rooms: bool | Sequence[str] = True,
    teaching_rate: float = 100.0,
    word_increment: int = DEFAULT_WORD_INCREMENT,
    name_prefix: str = "synthetic",
) -> Corpus:
    """A corpus of ``n_homes`` synthetic homes; the last ``new_homes`` are *new* homes.

    Parameters
    ----------
    n_homes:
        Number of homes (≥ 1).
    seed:
        Seed of the homes (and of the visual world if ``config.world_seed`` is ``None``). Home ``i``
        is drawn from its own stream ``SeedSequence(seed).spawn(n_homes)[i]``.
    config:
        Generator settings (default :class:`SyntheticConfig`).
    new_homes:
        How many of the homes, at the end, are new: 10 test samples per room, nothing taught.
    specific_rooms:
        ``True``: the last home gets the home-specific bedrooms ``config.specific_names`` (its layout
        is the one with the most rooms of ``config.specific_place_type``); a sequence of names: those
        names instead; ``False``: no home-specific rooms.
    teaching_rate:
        Percent of each experienced home's training samples that carry a sentence (0–100).
    word_increment:
        S^w of the corpus.
    name_prefix:
        The start of every home's name.

    Returns
    -------
    A :class:`~spco.data.environment.Corpus`; homes are named ``<name_prefix>_<layout>_<i>`` (``i`` from
    1, zero-padded to two digits or more), e.g. ``synthetic_3LDK_01``.
    """
    config = config or SyntheticConfig()
    if not _is_seed(seed):
        raise ConfigurationError(f"seed must be a non-negative integer, got {seed!r}")
    if n_homes < 1:
        raise ConfigurationError(f"n_homes must be at least 1, got {n_homes}")
    if not 0 <= new_homes <= n_homes:
        raise ConfigurationError(f"new_homes must be within 0..{n_homes}, got {new_homes}")
    if not 0 <= teaching_rate <= 100:
        raise ConfigurationError(f"teaching rate must be within 0..100, got {teaching_rate}")
    if specific_rooms is True:
        names: tuple[str, ...] = config.specific_names
    elif specific_rooms is False:
        names = ()
    elif isinstance(specific_rooms, str):
        raise ConfigurationError("specific_rooms must be True, False or a sequence of names")
    else:
        names = tuple(specific_rooms)
    world = make_world(config, seed)
    specific_type = normalize_name(config.specific_place_type)
    roomiest = max(config.layouts,
                   key=lambda lay: sum(normalize_name(r) == specific_type for r in lay.rooms))
    width = max(2, len(str(n_homes)))
    homes = []
    for i, stream in enumerate(np.random.SeedSequence(seed).spawn(n_homes)):
        rng = np.random.default_rng(stream)
        layout = config.layouts[int(rng.integers(len(config.layouts)))]
        special = names if (names and i == n_homes - 1) else ()
        if special:
            layout = roomiest
        homes.append(generate_home(
            rng, layout=layout, name=f"{name_prefix}_{layout.name}_{i + 1:0{width}d}", config=config,
            world=world, new=i >= n_homes - new_homes, specific_names=special,
            teaching_rate=teaching_rate,
        ))
    return Corpus(homes, word_increment=word_increment)


# -------------------------------------------------------------------------------------- teaching
def teach(
    environment: Environment,
    rate: float = 100.0,
    *,
    places: Sequence[str] | None = None,
    specific: bool = True,
    seed: int = 0,
    config: SyntheticConfig | None = None,
) -> Environment:
    """A copy of a labelled home whose training samples are taught from its ground-truth labels.

    For every place (restricted to ``places`` if given), ``round(rate % × its training samples)``
    samples, chosen at random, get a sentence naming it; every other sample gets none. With
    ``specific`` the home-specific labels are used where the home has them. This reproduces the
    home-specific experiment: ``teach(home, 20, places=SPECIFIC_ROOM_NAMES)`` teaches 8 of each
    bedroom's 40 training samples, as 3LDK_9's ``per_20``.

    ``config`` gives the sentence style (``language``) and the free-form and wrong-name rates
    (default: templates only, correct names). Free sentences said here never name a neighbouring place
    (the home's floor plan is not known here).
    """
    if not 0 <= rate <= 100:
        raise ConfigurationError(f"teaching rate must be within 0..100, got {rate}")
    config = config or SyntheticConfig()
    gt = environment.ground_truth
    labels = None
    if gt is not None:
        labels = (gt.specific_labels if specific and gt.specific_labels is not None else gt.labels)
    if labels is None:
        raise ConfigurationError(f"home {environment.name!r} has no labels to teach from")
    wanted = None if places is None else {normalize_name(p) for p in places}
    rng = np.random.default_rng(seed)
    lab = np.array([lab or "" for lab in labels], dtype=object)
    chosen: list[int] = []
    for place in dict.fromkeys(p for p in labels if p):
        if wanted is not None and place not in wanted:
            continue
        rows = np.flatnonzero((lab == place) & ~environment.is_test)
        chosen += rng.permutation(rows)[: round(rows.size * rate / 100)].tolist()
    chosen.sort()
    candidates = list(dict.fromkeys(p for p in labels if p))
    # labels are normalised ("emma's room"); a template sentence writes a name of several words
    # hyphenated, as generate_home does ("this is emma's-room"), so that it is one token
    candidates = ["-".join(c.split()) for c in candidates]
    said = _sentences(rng, ["-".join((labels[i] or "").split()) for i in chosen], candidates, config)
    sentences: list[str | None] = [None] * environment.n_samples
    for i, sentence in zip(chosen, said, strict=True):
        sentences[i] = sentence
    return environment.with_sentences(sentences)
