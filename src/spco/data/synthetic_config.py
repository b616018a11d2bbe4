"""What synthetic homes are made of (:mod:`spco.data.synthetic`): the places and their names, the
sentence templates, the layouts (:class:`Layout`) and the generator's settings
(:class:`SyntheticConfig`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spco.data.language import normalize_name
from spco.errors import ConfigurationError

#: The eight general places of the SIGVerse homes.
GENERAL_PLACES: tuple[str, ...] = (
    "entrance", "living-room", "dining", "kitchen", "bedroom", "bath", "washroom", "toilet",
)

#: Groups of place types that look alike (they share a part of their visual topics).
SIMILAR_PLACES: tuple[tuple[str, ...], ...] = (
    ("bath", "washroom", "toilet"),
    ("kitchen", "dining"),
    ("living-room", "bedroom"),
)

#: Target floor area of a room of each type, in square metres.
ROOM_AREAS: tuple[tuple[str, float], ...] = (
    ("entrance", 4.0), ("living-room", 20.0), ("dining", 11.0), ("kitchen", 10.0),
    ("bedroom", 13.0), ("bath", 5.0), ("washroom", 4.5), ("toilet", 2.5),
)

#: The home-specific bedroom names of ``3LDK_9``.
SPECIFIC_ROOM_NAMES: tuple[str, ...] = ("Emma's-room", "mother's-room", "father's-room")

#: The five sentence templates of the paper; ``{the}`` is ``"the "``, or nothing before a
#: possessive name ("this is Emma's-room").
SENTENCE_TEMPLATES: tuple[str, ...] = (
    "this is {the}{name}",
    "{the}{name} is here",
    "this place is {the}{name}",
    "this space is {the}{name}",
    "this location is {the}{name}",
)

#: Free-form sentences, for ``SyntheticConfig.free_form_rate``.
FREE_FORM_TEMPLATES: tuple[str, ...] = (
    "hey robot, we call this area {the}{name}",
    "okay, this part of the house is {the}{name}",
    "you are in {the}{name} now",
    "remember that this room is {the}{name}",
    "look around, this is {the}{name}",
    "we usually call this place {the}{name}",
    "please remember, this is {the}{name}",
    "so this is where {the}{name} is",
    "here we are, {the}{name}",
    "this spot is {the}{name}, okay?",
    "robot, {the}{name} is right here",
    "we are standing in {the}{name}",
)

#: Sentence styles of :attr:`SyntheticConfig.language`.
LANGUAGES: tuple[str, ...] = ("templates", "free")

#: Visual counts per feature of the SIGVerse data (~7,300 counts over 4,096 features per image).
_COUNTS_PER_FEATURE = 7300.0 / 4096.0
_MIN_ROOM_SIDE = 1.0  # metres
_MAX_ASPECT = 3.0
_PLAN_ATTEMPTS = 60
_GRID = 0.05  # cut positions are rounded to 5 cm
_POPULARITY_SIGMA = 0.5  # log-normal spread of how often each feature fires in any image
_PART_CONCENTRATION = 0.2  # Dirichlet concentration of the parts of a place's topic weights
_TOPIC_SIGMA = 0.7  # log-normal spread of a topic's weights on its features


def _is_seed(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool) and int(value) >= 0


@dataclass(frozen=True)
class Layout:
    """A kind of home: which rooms it has.

    Attributes
    ----------
    name: the layout's name, used in home names (``"2LDK"`` → ``"synthetic_2LDK_03"``).
    rooms: place type of every room the layout always has; a type may repeat (several bedrooms).
    optional: rooms each present with probability ``SyntheticConfig.optional_room_probability``.
    """

    name: str
    rooms: tuple[str, ...]
    optional: tuple[str, ...] = ()


#: Layouts like the SIGVerse homes' (1K has no living room or dining, 1DK no living room).
DEFAULT_LAYOUTS: tuple[Layout, ...] = (
    Layout("1K", ("entrance", "kitchen", "bedroom", "bath", "toilet"), ("washroom",)),
    Layout("1DK", ("entrance", "dining", "kitchen", "bedroom", "bath", "toilet"), ("washroom",)),
    Layout("1LDK", ("entrance", "living-room", "kitchen", "bedroom", "bath", "toilet"),
           ("dining", "washroom")),
    Layout("2LDK", ("entrance", "living-room", "dining", "kitchen", "bedroom", "bedroom", "bath",
                    "toilet"), ("washroom",)),
    Layout("3LDK", ("entrance", "living-room", "dining", "kitchen", "bedroom", "bedroom", "bedroom",
                    "bath", "washroom", "toilet")),
)


@dataclass(frozen=True)
class SyntheticConfig:
    """Everything that shapes synthetic homes (all fields have defaults).

    Places and layouts
    ------------------
    place_types: the place types of the visual world (default: the 8 general SIGVerse places).
    similar_places: groups of place types that look alike (share ``group_similarity`` of their topics).
    layouts: the kinds of home, each chosen with equal probability.
    optional_room_probability: probability that each optional room of a layout is present.
    room_areas: ``(place type, m²)`` target area of a room; others get ``default_room_area``.
    default_room_area: area of a room whose type is not in ``room_areas`` (m²).
    wall_margin: minimal distance of a sample position from the walls (m; at most a quarter of the
        room's side).

    Samples
    -------
    n_train: training samples per room (20 as in SIGVerse).
    n_test: test samples per room of a new home (10 as in SIGVerse).
    specific_extra_train: extra training samples of each home-specific room (20, as 3LDK_9's
        samples 300–359), appended after all other blocks.
    specific_place_type: the general type of home-specific rooms (their general label).
    specific_names: names of the home-specific rooms (3LDK_9's by default).

    Vision
    ------
    n_features: visual dimension D. 1024 by default: 4× faster to learn from than the real 4096 with
        the same count density, sparsity and difficulty; 4096 works as well.
    counts_per_image: mean total count per image; ``None``: the real data's density,
        ``7300 × n_features / 4096`` (1825 at 1024, 7300 at 4096).
    count_spread: relative standard deviation of an image's total count (~0.1 in the real data).
    n_topics: number of visual topics (motifs) of the world.
    topic_support: fraction of the features a topic puts weight on.
    place_distinctness: share of a place type's topic weights that is its own; the rest is shared
        with similar places (``group_similarity``) and with all places.
    group_similarity: share of a place type's topic weights shared with its similar places.
    home_concentration: Dirichlet concentration of a room's topic weights around its type's; larger
        = homes look more alike (transfer easier).
    home_style: log-normal standard deviation of a home's per-feature style, shared by its rooms.
    image_concentration: Dirichlet concentration of an image's topic weights around its room's;
        smaller = views of one room differ more.
    feature_noise: standard deviation of the per-image, per-feature noise of the log activation.
    active_fraction: mean fraction of non-zero features of an image (0.21 in the real data).
    active_spread: standard deviation of an image's activation threshold (varies its sparsity).
    view_mixing: mean share of an image showing the neighbouring room the robot faces.

    Language
    --------
    language: ``"templates"`` — the paper's five templates (default); ``"free"`` — sentences as people
        speak (:mod:`spco.data.speech`: synonyms, multi-word names, objects and activities instead of
        names, fillers, typos, neighbouring places, one to three people per home with their own
        habits); the ground truth then lists each place's accepted names.
    free_form_rate: fraction of template sentences replaced by one of :data:`FREE_FORM_TEMPLATES`
        (0–1; ``language="templates"`` only).
    wrong_name_rate: fraction of taught sentences naming another place of the home (0–1).

    World
    -----
    world_seed: seed of the visual world shared by all homes; ``None`` draws it from each call's seed.
    """

    place_types: tuple[str, ...] = GENERAL_PLACES
    similar_places: tuple[tuple[str, ...], ...] = SIMILAR_PLACES
    layouts: tuple[Layout, ...] = DEFAULT_LAYOUTS
    optional_room_probability: float = 0.5
    room_areas: tuple[tuple[str, float], ...] = ROOM_AREAS
    default_room_area: float = 10.0
    wall_margin: float = 0.3
    n_train: int = 20
    n_test: int = 10
    specific_extra_train: int = 20
    specific_place_type: str = "bedroom"
    specific_names: tuple[str, ...] = SPECIFIC_ROOM_NAMES
    n_features: int = 1024
    counts_per_image: int | None = None
    count_spread: float = 0.1
    n_topics: int = 128
    topic_support: float = 0.06
    place_distinctness: float = 0.55
    group_similarity: float = 0.3
    home_concentration: float = 25.0
    home_style: float = 0.3
    image_concentration: float = 60.0
    feature_noise: float = 0.4
    active_fraction: float = 0.21
    active_spread: float = 0.15
    view_mixing: float = 0.15
    free_form_rate: float = 0.0
    wrong_name_rate: float = 0.0
    world_seed: int | None = 0
    language: str = "templates"

    def __post_init__(self) -> None:
        def fail(message: str) -> None:
            raise ConfigurationError(f"SyntheticConfig: {message}")

        types = tuple(normalize_name(t) for t in self.place_types)
        if not types or any(not t for t in types) or len(set(types)) != len(types):
            fail(f"place_types must be distinct non-empty names, got {self.place_types!r}")
        known = set(types)
        for group in self.similar_places:
            unknown = [t for t in group if normalize_name(t) not in known]
            if unknown:
                fail(f"similar_places names unknown place types {unknown}")
        seen = [normalize_name(t) for group in self.similar_places for t in group]
        if len(set(seen)) != len(seen):
            fail("a place type may belong to at most one group of similar_places")
        if not self.layouts:
            fail("at least one layout is needed")
        for layout in self.layouts:
            if not layout.rooms:
                fail(f"layout {layout.name!r} has no rooms")
            unknown = [r for r in (*layout.rooms, *layout.optional) if normalize_name(r) not in known]
            if unknown:
                fail(f"layout {layout.name!r} uses unknown place types {unknown}")
        if len({lay.name for lay in self.layouts}) != len(self.layouts):
            fail("layout names must be unique")
        if normalize_name(self.specific_place_type) not in known:
            fail(f"specific_place_type {self.specific_place_type!r} is not a place type")
        specific = [normalize_name(n) for n in self.specific_names]
        if any(not n for n in specific) or len(set(specific)) != len(specific) or known & set(specific):
            fail("specific_names must be distinct, non-empty and differ from the place types")
        for name, area in self.room_areas:
            if not area > 0:
                fail(f"room area of {name!r} must be positive, got {area}")
        positive = {
            "default_room_area": self.default_room_area, "n_features": self.n_features,
            "n_topics": self.n_topics,
            "home_concentration": self.home_concentration,
            "image_concentration": self.image_concentration, "n_train": self.n_train,
        }
        for key, value in positive.items():
            if not value > 0:
                fail(f"{key} must be positive, got {value}")
        if self.counts_per_image is not None and self.counts_per_image < 1:
            fail(f"counts_per_image must be >= 1, got {self.counts_per_image}")
        non_negative = {
            "wall_margin": self.wall_margin, "n_test": self.n_test,
            "specific_extra_train": self.specific_extra_train, "count_spread": self.count_spread,
            "home_style": self.home_style, "feature_noise": self.feature_noise,
            "active_spread": self.active_spread,
        }
        for key, value in non_negative.items():
            if not value >= 0:
                fail(f"{key} must be >= 0, got {value}")
        fractions = {
            "optional_room_probability": self.optional_room_probability,
            "place_distinctness": self.place_distinctness, "group_similarity": self.group_similarity,
            "view_mixing": self.view_mixing, "free_form_rate": self.free_form_rate,
            "active_fraction": self.active_fraction, "topic_support": self.topic_support,
            "wrong_name_rate": self.wrong_name_rate,
        }
        for key, value in fractions.items():
            if not 0 <= value <= 1:
                fail(f"{key} must be within 0..1, got {value}")
        if self.place_distinctness + self.group_similarity > 1:
            fail("place_distinctness + group_similarity must be at most 1")
        if self.view_mixing >= 1:
            fail("view_mixing must be below 1")
        if self.language not in LANGUAGES:
            fail(f"language must be one of {', '.join(LANGUAGES)}, got {self.language!r}")
        if self.world_seed is not None and not _is_seed(self.world_seed):
            fail(f"world_seed must be a non-negative integer or None, got {self.world_seed!r}")

    @property
    def mean_counts(self) -> float:
        """Mean total visual count of an image."""
        if self.counts_per_image is not None:
            return float(self.counts_per_image)
        return float(round(_COUNTS_PER_FEATURE * self.n_features))

    def area_of(self, place_type: str) -> float:
        """Target area (m²) of a room of type ``place_type``."""
        areas = {normalize_name(name): area for name, area in self.room_areas}
        return float(areas.get(normalize_name(place_type), self.default_room_area))

    def layout(self, name: str) -> Layout:
        """The layout called ``name``; raises :class:`ConfigurationError` if there is none."""
        for layout in self.layouts:
            if layout.name == name:
                return layout
        raise ConfigurationError(f"no layout named {name!r}; layouts: "
                                 f"{', '.join(lay.name for lay in self.layouts)}")
