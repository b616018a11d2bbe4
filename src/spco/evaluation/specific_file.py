"""A configuration file of named rooms (format ``heldout-specific/1``): reading and checking it,
and the sentences a run teaches. The experiment that runs such a file is
:mod:`spco.evaluation.specific_config`, which describes the file and the runs."""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from spco.data.function_words import NAME_LEADING_WORDS
from spco.data.language import normalize_name
from spco.data.regions import PlaceRegions
from spco.errors import ConfigurationError, DataFormatError

__all__ = ["CONFIG_FORMAT", "LEADING_WORDS", "Room", "SpecificConfigFile", "SpecificConfiguration",
           "load_specific_config", "normalize_phrase", "taught_count", "teaching_sentences"]

#: Format of a configuration file (its ``_format`` field).
CONFIG_FORMAT = "heldout-specific/1"
#: Words dropped at the start of a phrase before comparing names (the file's normalisation).
LEADING_WORDS = NAME_LEADING_WORDS


def normalize_phrase(text: str) -> str:
    """A name as the configuration files compare names: its words as the model's tokenizer writes
    them (:func:`spco.data.language.normalize_name`: lower case, ``-`` and ``_`` as spaces, runs of
    spaces collapsed, a plural possessive's apostrophe dropped as the tokenizer drops it: ``"kids'"``
    → ``"kids"``, so the name the robot learnt from "the kids' bedroom" compares equal to it), a
    leading ``the``/``a``/``an``/``my``/``our``/``your`` dropped (when another word follows); a
    trailing ``'s`` is kept (``"The Nursery"`` → ``"nursery"``)."""
    words = normalize_name(str(text).replace("_", " ")).split()
    if len(words) > 1 and words[0] in LEADING_WORDS:
        words = words[1:]
    return " ".join(words)


def taught_count(rate: int, n_train: int) -> int:
    """The file's rule: ``k = max(1, floor(rate * n_train / 100 + 0.5))`` for a rate > 0, 0 at rate 0."""
    if rate <= 0:
        return 0
    return max(1, min(n_train, math.floor(rate * n_train / 100 + 0.5)))


# ------------------------------------------------------------------------------------ the file
@dataclass(frozen=True)
class Room:
    """A room with a personal name.

    Attributes
    ----------
    name: the name users teach (``"the piano room"``), lower case.
    form: ``"possessive"``, ``"single-word"`` or ``"multi-word"``.
    owner: the person of a possessive name, or ``None``.
    replaces: the general place of the room's samples (``"bedroom"``).
    accepted: phrases counted right (normalised with :func:`normalize_phrase`).
    train_ids, test_ids: sample ids (disjoint).
    taught: rate -> number of train samples taught.
    region: ground-truth area (``PlaceRegions`` with one place, the room's name), or ``None``.
    """

    name: str
    form: str
    owner: str | None
    replaces: str
    accepted: tuple[str, ...]
    train_ids: tuple[int, ...]
    test_ids: tuple[int, ...]
    taught: Mapping[int, int]
    region: PlaceRegions | None

    def count_at(self, rate: int) -> int:
        """Train samples taught at ``rate`` (the file's count, or the rule for a rate it lacks)."""
        return self.taught.get(rate, taught_count(rate, len(self.train_ids)))

    def is_accepted(self, word: str | None) -> bool:
        """Whether a predicted name counts as this room's name."""
        return word is not None and normalize_phrase(word) in self.accepted


@dataclass(frozen=True)
class SpecificConfiguration:
    """One configuration: a new home and its named rooms."""

    id: str
    home: str
    test_source: str
    rooms: tuple[Room, ...]
    experienced_homes: tuple[str, ...]


@dataclass(frozen=True)
class SpecificConfigFile:
    """A configuration file as read by :func:`load_specific_config`."""

    path: str
    sha256: str
    templates: tuple[str, ...]
    possessive_templates: tuple[str, ...]
    rates: tuple[int, ...]
    seeds: tuple[int, ...]
    experienced_homes: tuple[str, ...]
    configurations: tuple[SpecificConfiguration, ...]

    def configuration(self, name: str) -> SpecificConfiguration:
        """The configuration called ``name`` (ConfigurationError listing the others if none)."""
        for conf in self.configurations:
            if conf.id == name:
                return conf
        raise ConfigurationError(f"{self.path} has no configuration {name!r}; it has "
                                 f"{', '.join(c.id for c in self.configurations)}")

    def select(self, names: Sequence[str] | None) -> tuple[SpecificConfiguration, ...]:
        """The configurations called ``names`` (all with ``None``), in the order asked."""
        if not names:
            return self.configurations
        return tuple(self.configuration(n) for n in dict.fromkeys(names))


def _fail(path: Path, where: str, problem: str) -> DataFormatError:
    return DataFormatError(path, f"{where}: {problem}")


def _str(path: Path, where: str, value: Any, allow_none: bool = False) -> str | None:
    if value is None and allow_none:
        return None
    if not isinstance(value, str) or not value.strip():
        raise _fail(path, where, f"must be a non-empty string, got {value!r}")
    return value


def _ids(path: Path, where: str, value: Any) -> tuple[int, ...]:
    if not isinstance(value, list) or not value or any(isinstance(v, bool) or not isinstance(v, int)
                                                       or v < 0 for v in value):
        raise _fail(path, where, f"must be a non-empty list of sample ids (integers >= 0), got "
                    f"{json.dumps(value)[:60]}")
    if len(set(value)) != len(value):
        raise _fail(path, where, "repeats an id")
    return tuple(int(v) for v in value)


def _strings(path: Path, where: str, value: Any, allow_empty: bool = False) -> tuple[str, ...]:
    if not isinstance(value, list) or (not value and not allow_empty) or any(
            not isinstance(v, str) or not v.strip() for v in value):
        raise _fail(path, where, f"must be a {'' if allow_empty else 'non-empty '}list of strings")
    return tuple(value)


def _room(path: Path, where: str, raw: Any, rates: Sequence[int]) -> Room:
    if not isinstance(raw, dict):
        raise _fail(path, where, "must be an object")
    name = _str(path, f"{where}.name", raw.get("name"))
    owner = _str(path, f"{where}.owner", raw.get("owner"), allow_none=True)
    train = _ids(path, f"{where}.train_ids", raw.get("train_ids"))
    test = _ids(path, f"{where}.test_ids", raw.get("test_ids"))
    both = sorted(set(train) & set(test))
    if both:
        raise _fail(path, f"{where}.test_ids", f"id(s) {', '.join(map(str, both))} are also train ids")
    accepted = tuple(dict.fromkeys(normalize_phrase(a) for a in
                                   _strings(path, f"{where}.accepted", raw.get("accepted"))))
    counts = raw.get("taught_count")
    if not isinstance(counts, dict):
        raise _fail(path, f"{where}.taught_count", "must be an object rate -> count")
    taught: dict[int, int] = {}
    for key, value in counts.items():
        if not str(key).isdigit() or isinstance(value, bool) or not isinstance(value, int) \
                or not 0 <= value <= len(train):
            raise _fail(path, f"{where}.taught_count", f"{key!r}: {value!r} is not a count of "
                        f"0..{len(train)} train samples for a rate")
        taught[int(key)] = value
    missing = [r for r in rates if r not in taught]
    if missing:
        raise _fail(path, f"{where}.taught_count", f"no count for rate(s) {', '.join(map(str, missing))}")
    for rate, k in taught.items():
        if k != taught_count(rate, len(train)):
            raise _fail(path, f"{where}.taught_count", f"rate {rate}: {k} samples, but the rule gives "
                        f"{taught_count(rate, len(train))} of {len(train)}")
    region = raw.get("region")
    regions = None
    if region is not None:
        if not isinstance(region, list) or not region or any(
                not isinstance(r, list) or len(r) != 4 or any(isinstance(v, bool) or
                                                               not isinstance(v, int | float) for v in r)
                for r in region):
            raise _fail(path, f"{where}.region", "must be null or a list of [x_min, x_max, y_min, y_max]")
        try:
            regions = PlaceRegions({name: tuple(tuple(float(v) for v in r) for r in region)})
        except DataFormatError as exc:
            raise _fail(path, f"{where}.region", exc.problem) from None
    return Room(name=name.strip().lower(), form=str(raw.get("form") or ""), owner=owner,
                replaces=_str(path, f"{where}.replaces", raw.get("replaces")),
                accepted=accepted, train_ids=train, test_ids=test, taught=taught, region=regions)


def _configuration(p: Path, i: int, conf: Any, rates: list[int],
                   experienced: tuple[str, ...]) -> SpecificConfiguration:
    """Configuration ``i`` of the file, checked: its rooms and their samples, which no two rooms share."""
    where = f"configs[{i}]"
    if not isinstance(conf, dict):
        raise _fail(p, where, "must be an object")
    cid = _str(p, f"{where}.id", conf.get("id"))
    home = _str(p, f"{where}.home", conf.get("home"))
    source = conf.get("test_source")
    if source not in ("test_num.txt", "test_num_specific.txt", "defined-here"):
        raise _fail(p, f"{where}.test_source", "must be 'test_num.txt', 'test_num_specific.txt' or "
                    f"'defined-here', got {source!r}")
    exp = _strings(p, f"{where}.experienced_homes", conf["experienced_homes"]) \
        if conf.get("experienced_homes") is not None else experienced
    if home in exp:
        raise _fail(p, f"{where}.home", f"{home!r} is also an experienced home")
    rooms_raw = conf.get("rooms")
    if not isinstance(rooms_raw, list) or not rooms_raw:
        raise _fail(p, f"{where}.rooms", "must be a non-empty list")
    rooms = tuple(_room(p, f"{where}.rooms[{j}]", r, rates) for j, r in enumerate(rooms_raw))
    seen: dict[int, str] = {}
    for room in rooms:
        for sid in (*room.train_ids, *room.test_ids):
            if sid in seen:
                raise _fail(p, f"{where}.rooms", f"sample {sid} belongs to {seen[sid]!r} and "
                            f"{room.name!r}")
            seen[sid] = room.name
    names = [r.name for r in rooms]
    if len(set(names)) != len(names):
        raise _fail(p, f"{where}.rooms", "two rooms have the same name")
    return SpecificConfiguration(cid, home, source, rooms, tuple(exp))


def load_specific_config(path: str | os.PathLike[str]) -> SpecificConfigFile:
    """Read and check a configuration file (format :data:`CONFIG_FORMAT`).

    Raises :class:`~spco.errors.DataFormatError` naming the file and the field at fault (a missing
    file, invalid JSON, an unknown format, ids shared by two rooms, counts that break the file's
    rule, ...). Whether the ids exist in the homes is checked when the homes are read
    (:class:`ConfiguredData`).
    """
    p = Path(path).expanduser()
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise DataFormatError(p, f"cannot read the configuration file ({exc.strerror or exc})") from None
    try:
        raw = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise DataFormatError(p, f"not a JSON file ({exc})") from None
    if not isinstance(raw, dict):
        raise DataFormatError(p, "must hold a JSON object")
    if raw.get("_format") != CONFIG_FORMAT:
        raise _fail(p, "_format", f"expected {CONFIG_FORMAT!r}, got {raw.get('_format')!r}")
    templates = _strings(p, "templates", raw.get("templates"))
    possessive = _strings(p, "possessive_templates", raw.get("possessive_templates", []), allow_empty=True)
    for where, group in (("templates", templates), ("possessive_templates", possessive)):
        for t in group:
            if "{name}" not in t and "{owner}" not in t:
                raise _fail(p, where, f"template {t!r} holds neither {{name}} nor {{owner}}")
    rates = raw.get("teaching_rates")
    if not isinstance(rates, list) or not rates or any(isinstance(r, bool) or not isinstance(r, int)
                                                       or not 0 < r <= 100 for r in rates):
        raise _fail(p, "teaching_rates", "must be a non-empty list of percentages 1..100")
    seeds = raw.get("seeds")
    if not isinstance(seeds, list) or not seeds or any(isinstance(s, bool) or not isinstance(s, int)
                                                       or s < 0 for s in seeds) \
            or len(set(seeds)) != len(seeds):
        raise _fail(p, "seeds", "must be a non-empty list of distinct integers >= 0")
    experienced = _strings(p, "experienced_homes", raw.get("experienced_homes"))
    configs_raw = raw.get("configs")
    if not isinstance(configs_raw, list) or not configs_raw:
        raise _fail(p, "configs", "must be a non-empty list")
    configurations = [_configuration(p, i, conf, rates, experienced) for i, conf in enumerate(configs_raw)]
    ids = [c.id for c in configurations]
    if len(set(ids)) != len(ids):
        raise _fail(p, "configs", "two configurations have the same id")
    return SpecificConfigFile(path=str(path), sha256=hashlib.sha256(data).hexdigest(),
                              templates=templates, possessive_templates=possessive,
                              rates=tuple(sorted(rates)), seeds=tuple(seeds),
                              experienced_homes=experienced, configurations=tuple(configurations))


def teaching_sentences(file: SpecificConfigFile, conf: SpecificConfiguration, rate: int,
                       seed: int) -> dict[int, str]:
    """The taught samples of one run: sample id -> sentence, drawn by the file's selection rule
    (see the module docstring). The same (configuration, rate, seed) gives the same draw."""
    rng = np.random.default_rng(seed)
    out: dict[int, str] = {}
    for room in conf.rooms:
        k = room.count_at(rate)
        if k == 0:
            continue
        drawn = rng.choice(np.asarray(room.train_ids, dtype=np.int64), size=k, replace=False)
        pool = file.templates + (file.possessive_templates if room.owner else ())
        for sid in drawn:
            template = pool[int(rng.integers(len(pool)))]
            out[int(sid)] = template.replace("{owner}", room.owner or "").replace("{name}", room.name)
    return out
