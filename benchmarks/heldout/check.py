"""Check the held-out evaluation files against each other and against the SIGVerse data set.

Needs only the standard library (no ``spco`` import). Checks:

- ``speech_heldout.csv``: header ``place,speaker,sentence``; only the eight general places; at least
  8 speakers per place, each with at least 8 different sentences there; at least 500 lines; no
  sentence twice in the file.
- ``accepted_names_heldout.json``: the eight places; no phrase accepted for two places; no phrase both
  accepted and in ``_not_accepted``.
- ``unheard_names_heldout.json``: the eight places, at least 5 names each unless its ``_membership``
  note says why some were removed; every name is accepted for its place (and so for no other); no
  word of a name was ever said in any home of the data set.
- ``specific_heldout.json``: at least 3 configurations over at least 2 homes and 5 rooms, one of them
  not a bedroom; no configuration in ``3LDK_9*``; every id exists in its home; train and test ids
  disjoint (within a room, across rooms, and train never in the home's published test list); every id
  of a room has the general label the room ``replaces``; published test ids come from ``test_num.txt``;
  taught counts follow the rule; seeds 100-119; personal names are never said in the data set and
  never accepted as a general name; regions are rectangles of the general place in
  ``sigverse_regions.json``, hold at least 60 % of the room's samples and none of another room's
  (the authors' rectangles are kept as they are: 1DK_8's dining rectangle holds 20 of its 30).

Usage::

    python benchmarks/heldout/check.py [--data /path/to/sigverse]

The data set is ``--data``, else ``$SPCO_SIGVERSE``, else ``/work/shared/datasets/sigverse``;
``sigverse_regions.json`` is read from its parent folder. Prints one line per check and exits 1 with
``error: ...`` lines if any check fails.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import re
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
PLACES = ("entrance", "toilet", "bath", "washroom", "kitchen", "dining", "living-room", "bedroom")
LEADING = ("the", "a", "an", "my", "our", "your")
STOP_WORDS = {"the", "a", "an", "and"}
RATES = (20, 40, 100)
SEEDS = list(range(100, 120))
DEFAULT_DATA = Path("/work/shared/datasets/sigverse")


class Checker:
    """Collects failures and prints passed checks.

    Attributes
    ----------
    errors : list of str
        One message per failed check, naming the file and field.
    """

    def __init__(self) -> None:
        self.errors: list[str] = []

    def require(self, condition: bool, message: str) -> bool:
        """Record ``message`` as an error unless ``condition`` holds.

        Parameters
        ----------
        condition : bool
            The checked fact.
        message : str
            What is wrong if it does not hold (file: field: problem).

        Returns
        -------
        bool
            ``condition``.
        """
        if not condition:
            self.errors.append(message)
        return condition

    def ok(self, message: str) -> None:
        """Print a passed check.

        Parameters
        ----------
        message : str
            What was checked and found right.
        """
        print(f"ok    {message}")


def normalise(phrase: str) -> str:
    """Normalise a name as ``accepted_names_heldout.json`` says.

    Parameters
    ----------
    phrase : str
        A name or phrase.

    Returns
    -------
    str
        Lower-case, '-' and '_' as spaces, spaces collapsed, one leading article or possessive
        pronoun dropped.
    """
    words = re.sub(r"[-_]", " ", phrase.lower()).split()
    if len(words) > 1 and words[0] in LEADING:
        words = words[1:]
    return " ".join(words)


def heard_words(data: Path) -> set[str]:
    """Every word said in any teaching sentence of the data set.

    Parameters
    ----------
    data : Path
        The SIGVerse folder (one folder per home).

    Returns
    -------
    set of str
        Lower-case words of all ``<home>/sentence/per_*/sentence<i>.txt`` files.
    """
    words: set[str] = set()
    for path in data.glob("*/sentence/per_*/sentence*.txt"):
        words.update(path.read_text(encoding="utf-8").lower().split())
    return words


def read_json(path: Path, check: Checker) -> Any:
    """Read a JSON file, recording an error if it is missing or malformed.

    Parameters
    ----------
    path : Path
        The file.
    check : Checker
        Where errors go.

    Returns
    -------
    Any
        The parsed document, or None on error.
    """
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        check.require(False, f"{path.name}: cannot read: {exc}")
        return None


def check_speech(path: Path, accepted: dict[str, list[str]], check: Checker) -> None:
    """Check ``speech_heldout.csv`` and print its counts.

    Parameters
    ----------
    path : Path
        The CSV file.
    accepted : dict of str to list of str
        Accepted names per place (for the informational naming rate).
    check : Checker
        Where results go.
    """
    with path.open(encoding="utf-8", newline="") as f:
        rows = list(csv.reader(f))
    if not check.require(
        bool(rows) and rows[0] == ["place", "speaker", "sentence"],
        f"{path.name}: header must be place,speaker,sentence, got {rows[:1]}",
    ):
        return
    per: dict[str, dict[str, set[str]]] = defaultdict(lambda: defaultdict(set))
    seen: dict[str, int] = {}
    for line, row in enumerate(rows[1:], start=2):
        if not check.require(
            len(row) == 3 and all(c.strip() for c in row),
            f"{path.name}: line {line}: need 3 non-empty fields, got {row}",
        ):
            continue
        place, speaker, sentence = row
        check.require(place in PLACES, f"{path.name}: line {line}: unknown place {place!r}")
        key = sentence.strip().lower()
        check.require(key not in seen, f"{path.name}: line {line}: sentence also on line {seen.get(key)}")
        seen.setdefault(key, line)
        per[place][speaker].add(sentence)
    total = len(rows) - 1
    check.require(total >= 500, f"{path.name}: {total} sentences, need >= 500")
    speakers = sorted({s for by in per.values() for s in by})
    for place in PLACES:
        by = per.get(place, {})
        thin = [s for s, sents in by.items() if len(sents) < 8]
        check.require(len(by) >= 8, f"{path.name}: place {place}: {len(by)} speakers, need >= 8")
        check.require(not thin, f"{path.name}: place {place}: speakers with < 8 sentences: {thin}")
        n = sum(len(s) for s in by.values())
        names = [normalise(a) for a in accepted.get(place, [])]
        named = sum(
            any(
                re.search(rf"(^| ){re.escape(a)}( |$)", " " + normalise(re.sub(r"[^\w' -]", " ", s)) + " ")
                for a in names
            )
            for sents in by.values()
            for s in sents
        )
        print(
            f"info  speech {place:12s} {n:3d} sentences, {len(by)} speakers, "
            f"{named} contain an accepted name spelled exactly (typos and loose words not counted)"
        )
    check.ok(f"{path.name}: {total} sentences, {len(speakers)} speakers ({', '.join(speakers)})")


def check_accepted(doc: dict[str, Any], check: Checker) -> dict[str, list[str]]:
    """Check ``accepted_names_heldout.json``.

    Parameters
    ----------
    doc : dict
        The parsed file.
    check : Checker
        Where results go.

    Returns
    -------
    dict of str to list of str
        Normalised accepted phrases per place.
    """
    name = "accepted_names_heldout.json"
    places = {k: v for k, v in doc.items() if not k.startswith("_")}
    check.require(set(places) == set(PLACES), f"{name}: places {sorted(places)} != {sorted(PLACES)}")
    check.require(isinstance(doc.get("_notes"), dict), f"{name}: _notes missing")
    owner: dict[str, str] = {}
    out: dict[str, list[str]] = {}
    for place, phrases in places.items():
        check.require(isinstance(phrases, list) and len(phrases) > 0, f"{name}: {place}: empty or not a list")
        out[place] = []
        for phrase in phrases:
            norm = normalise(phrase)
            check.require(
                norm not in owner or owner[norm] == place,
                f"{name}: {phrase!r} accepted for both {owner.get(norm)} and {place}",
            )
            check.require(norm not in out[place], f"{name}: {place}: {phrase!r} twice")
            owner[norm] = place
            out[place].append(norm)
    for word in doc.get("_not_accepted", {}):
        check.require(
            normalise(word) not in owner,
            f"{name}: _not_accepted {word!r} is accepted for {owner.get(normalise(word))}",
        )
    check.ok(
        f"{name}: {sum(len(v) for v in out.values())} phrases, each accepted for one place; "
        + ", ".join(f"{p} {len(out.get(p, []))}" for p in PLACES)
    )
    return out


def check_unheard(
    doc: dict[str, Any], accepted: dict[str, list[str]], heard: set[str], check: Checker
) -> None:
    """Check ``unheard_names_heldout.json``.

    Parameters
    ----------
    doc : dict
        The parsed file.
    accepted : dict of str to list of str
        Normalised accepted phrases per place.
    heard : set of str
        Words said anywhere in the data set.
    check : Checker
        Where results go.
    """
    name = "unheard_names_heldout.json"
    notes = {key for key in doc if key.startswith("_")}
    places = {key: names for key, names in doc.items() if key not in notes}
    check.require(set(places) == set(PLACES), f"{name}: keys {sorted(places)} != {sorted(PLACES)}")
    check.require(bool(notes) or all(len(n) >= 5 for n in places.values()),
                  f"{name}: a place with fewer than 5 names needs a '_membership' note saying why")
    for place, names in places.items():
        check.require(isinstance(names, list), f"{name}: {place}: names must be a list")
        for phrase in names:
            norm = normalise(phrase)
            check.require(
                norm in accepted.get(place, []),
                f"{name}: {place}: {phrase!r} is not accepted for {place} in accepted_names_heldout.json",
            )
            said = [w for w in norm.split() if w not in STOP_WORDS and w in heard]
            check.require(not said, f"{name}: {place}: {phrase!r} has words said in the data set: {said}")
    check.ok(
        f"{name}: "
        + ", ".join(f"{p} {len(doc.get(p, []))}" for p in PLACES)
        + f"; all accepted for their place; none of their words among the {len(heard)} words heard"
    )


def read_home(data: Path, home: str) -> tuple[list[str], set[int], list[tuple[float, float] | None]]:
    """Read a home's ground-truth labels, published test ids and positions.

    Parameters
    ----------
    data : Path
        The SIGVerse folder.
    home : str
        The home's directory name.

    Returns
    -------
    labels : list of str
        ``name_label`` of samples 0..N-1 (N = number of label files).
    tests : set of int
        Ids in ``test_num.txt`` (empty for ``999``).
    positions : list of (float, float) or None
        x, y of each sample (None if the file is unreadable).
    """
    folder = data / home
    n = len(list((folder / "name_label").glob("word*.txt")))
    labels = [(folder / "name_label" / f"word{i}.txt").read_text(encoding="utf-8").strip() for i in range(n)]
    raw = (folder / "test_num.txt").read_text(encoding="utf-8").strip().rstrip(",")
    tests = {int(t) for t in raw.split(",") if t.strip()} - {999}
    positions: list[tuple[float, float] | None] = []
    for i in range(n):
        try:
            first = (folder / "position" / f"{i}.txt").read_text(encoding="utf-8").splitlines()[0].split()
            positions.append((float(first[0]), float(first[1])))
        except (OSError, IndexError, ValueError):
            positions.append(None)
    return labels, tests, positions


def inside(point: tuple[float, float] | None, rects: list[list[float]]) -> bool:
    """Whether a point lies in any rectangle (bounds inclusive).

    Parameters
    ----------
    point : (float, float) or None
        x, y in metres.
    rects : list of [x_min, x_max, y_min, y_max]
        The rectangles.

    Returns
    -------
    bool
        True if inside one of them.
    """
    return point is not None and any(r[0] <= point[0] <= r[1] and r[2] <= point[1] <= r[3] for r in rects)


def _check_specific_header(doc: dict[str, Any], name: str, check: Checker) -> None:
    """Check the fields of ``specific_heldout.json`` around its configs: schema, seeds, rates, templates."""
    check.require(
        isinstance(doc.get("_schema"), dict) and next(iter(doc)) == "_schema",
        f"{name}: _schema must be the first field",
    )
    check.require(doc.get("seeds") == SEEDS, f"{name}: seeds must be 100..119")
    check.require(
        tuple(doc.get("teaching_rates", ())) == RATES, f"{name}: teaching_rates must be {list(RATES)}"
    )
    templates = doc.get("templates", [])
    check.require(
        len(templates) >= 4 and all("{name}" in t for t in templates),
        f"{name}: templates: need >= 4, each with {{name}}",
    )
    check.require(
        all("{owner}" in t for t in doc.get("possessive_templates", [])),
        f"{name}: possessive_templates: each needs {{owner}}",
    )


def _check_room_ids(
    room: dict[str, Any], rw: str, home: str, labels: list[str], published: set[int], from_file: bool,
    used: dict[int, str], check: Checker
) -> None:
    """Check a room's train and test ids: in the home, of the replaced place, used by no other room,
    and on the right side of ``test_num.txt``."""
    rname = room.get("name", "")
    train, test = room.get("train_ids", []), room.get("test_ids", [])
    check.require(bool(train) and bool(test), f"{rw}: train_ids and test_ids must be non-empty")
    check.require(
        not set(train) & set(test), f"{rw}: train and test share {sorted(set(train) & set(test))}"
    )
    for i in list(train) + list(test):
        if not check.require(
            isinstance(i, int) and 0 <= i < len(labels),
            f"{rw}: id {i} not in {home} (0..{len(labels) - 1})",
        ):
            continue
        check.require(
            labels[i] == room.get("replaces"),
            f"{rw}: id {i} is labelled {labels[i]!r}, not {room.get('replaces')!r}",
        )
        check.require(i not in used, f"{rw}: id {i} also used by room {used.get(i)!r}")
        used[i] = rname
    if from_file:
        check.require(
            set(test) <= published,
            f"{rw}: test ids not in test_num.txt: {sorted(set(test) - published)}",
        )
    check.require(
        not set(train) & published,
        f"{rw}: train ids in test_num.txt: {sorted(set(train) & published)}",
    )


def _check_room_names(
    room: dict[str, Any], rw: str, heard: set[str], general: set[str], phrases: dict[str, str],
    check: Checker
) -> None:
    """Check a room's name and accepted phrases: never said in the data set, not a general place
    name, accepted for no other room."""
    rname = room.get("name", "")
    check.require(
        "{owner}" not in rname and (room.get("owner") is None or room["owner"] in rname),
        f"{rw}: owner {room.get('owner')!r} not in the name",
    )
    said = [w for w in normalise(rname).split() if w not in STOP_WORDS and w in heard]
    check.require(not said, f"{rw}: words said in the data set: {said}")
    acc = [normalise(a) for a in room.get("accepted", [])]
    check.require(normalise(rname) in acc, f"{rw}: its own name is not in accepted")
    for a in acc:
        check.require(a not in general, f"{rw}: accepted {a!r} is also a general place name")
        check.require(
            a not in phrases, f"{rw}: accepted {a!r} also accepted for room {phrases.get(a)!r}"
        )
        phrases[a] = rname


def _check_room_region(
    room: dict[str, Any], rw: str, cid: Any, cfg: dict[str, Any], home: str, regions: dict[str, Any],
    positions: list[tuple[float, float] | None], check: Checker
) -> None:
    """Check a room's region: among the home's rectangles of the replaced place, holding >= 60 % of
    the room's samples and none of another room's."""
    region = room.get("region")
    if region is None:
        return
    rname = room.get("name", "")
    train, test = room.get("train_ids", []), room.get("test_ids", [])
    known = regions.get(home, {}).get(room.get("replaces"), [])
    check.require(
        all(r in known for r in region),
        f"{rw}: region rectangles not among {home}'s {room.get('replaces')} rectangles",
    )
    ins_train = sum(inside(positions[i], region) for i in train if 0 <= i < len(positions))
    ins_test = sum(inside(positions[i], region) for i in test if 0 <= i < len(positions))
    others = [r for o in cfg["rooms"] if o is not room and o.get("region") for r in o["region"]]
    stray = sum(
        inside(positions[i], others) for i in list(train) + list(test) if 0 <= i < len(positions)
    )
    print(
        f"info  {cid}: {rname}: {ins_train}/{len(train)} train and {ins_test}/{len(test)} test "
        f"positions inside its region, {stray} inside another room's"
    )
    check.require(
        ins_train + ins_test >= 0.6 * (len(train) + len(test)) and stray == 0,
        f"{rw}: region holds < 60 % of its samples or some lie in another room's",
    )


def check_specific(
    doc: dict[str, Any], data: Path, accepted: dict[str, list[str]], heard: set[str], check: Checker
) -> None:
    """Check ``specific_heldout.json`` against the data set.

    Parameters
    ----------
    doc : dict
        The parsed file.
    data : Path
        The SIGVerse folder.
    accepted : dict of str to list of str
        Normalised accepted general phrases per place.
    heard : set of str
        Words said anywhere in the data set.
    check : Checker
        Where results go.
    """
    name = "specific_heldout.json"
    _check_specific_header(doc, name, check)
    regions_path = data.parent / "sigverse_regions.json"
    regions = json.loads(regions_path.read_text(encoding="utf-8"))["homes"] if regions_path.exists() else {}
    general = {a for names in accepted.values() for a in names}
    configs = doc.get("configs", [])
    homes: set[str] = set()
    n_rooms = 0
    kinds: set[str] = set()
    ids_seen: set[str] = set()
    for cfg in configs:
        cid, home = cfg.get("id"), cfg.get("home", "")
        where = f"{name}: config {cid}"
        check.require(cid not in ids_seen, f"{where}: duplicate id")
        ids_seen.add(cid)
        check.require(not home.startswith("3LDK_9"), f"{where}: home {home} is development data")
        if not check.require((data / home / "name_label").is_dir(), f"{where}: home {home} not in {data}"):
            continue
        labels, published, positions = read_home(data, home)
        homes.add(home)
        from_file = cfg.get("test_source") == "test_num.txt"
        check.require(cfg.get("test_source") in ("test_num.txt", "defined-here"), f"{where}: bad test_source")
        check.require(
            not from_file or bool(published), f"{where}: test_source test_num.txt but {home} has none"
        )
        used: dict[int, str] = {}
        phrases: dict[str, str] = {}
        for room in cfg.get("rooms", []):
            rname = room.get("name", "")
            rw = f"{where}: room {rname!r}"
            n_rooms += 1
            kinds.add(room.get("replaces", ""))
            check.require(room.get("form") in ("possessive", "single-word", "multi-word"), f"{rw}: bad form")
            check.require(
                room.get("replaces") in PLACES, f"{rw}: replaces {room.get('replaces')!r} not a place"
            )
            _check_room_ids(room, rw, home, labels, published, from_file, used, check)
            train = room.get("train_ids", [])
            want = {str(r): max(1, int(r * len(train) / 100 + 0.5)) for r in RATES}
            check.require(
                room.get("taught_count") == want, f"{rw}: taught_count {room.get('taught_count')} != {want}"
            )
            _check_room_names(room, rw, heard, general, phrases, check)
            _check_room_region(room, rw, cid, cfg, home, regions, positions, check)
        check.ok(
            f"{cid} ({home}): {len(cfg.get('rooms', []))} rooms, "
            + "; ".join(
                f"{r['name']} <- {r['replaces']} train {len(r['train_ids'])} test {len(r['test_ids'])}"
                for r in cfg.get("rooms", [])
            )
        )
    check.require(
        len(configs) >= 3 and len(homes) >= 2 and n_rooms >= 5,
        f"{name}: need >= 3 configs, >= 2 homes, >= 5 rooms; have {len(configs)}, {len(homes)}, {n_rooms}",
    )
    check.require(bool(kinds - {"bedroom"}), f"{name}: need at least one room that is not a bedroom")
    check.ok(
        f"{name}: {len(configs)} configs, {len(homes)} homes ({', '.join(sorted(homes))}), {n_rooms} rooms "
        f"replacing {', '.join(sorted(kinds))}; ids exist, labels match, train/test disjoint"
    )


def main(argv: list[str] | None = None) -> int:
    """Run every check.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 if every check passed, 1 otherwise, 2 if the data set is missing.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=None, help="the SIGVerse data set folder")
    args = parser.parse_args(argv)
    data = args.data or Path(os.environ.get("SPCO_SIGVERSE") or DEFAULT_DATA)
    if not data.is_dir():
        print(f"error: SIGVerse data set not found at {data} (use --data or $SPCO_SIGVERSE)", file=sys.stderr)
        return 2
    check = Checker()
    heard = heard_words(data)
    accepted_doc = read_json(HERE / "accepted_names_heldout.json", check)
    accepted = check_accepted(accepted_doc, check) if accepted_doc else {}
    check_speech(HERE / "speech_heldout.csv", accepted, check)
    unheard = read_json(HERE / "unheard_names_heldout.json", check)
    if unheard is not None:
        check_unheard(unheard, accepted, heard, check)
    specific = read_json(HERE / "specific_heldout.json", check)
    if specific is not None:
        check_specific(specific, data, accepted, heard, check)
    for message in check.errors:
        print(f"error: {message}", file=sys.stderr)
    print(f"{'FAILED' if check.errors else 'PASSED'}: {len(check.errors)} errors")
    return 1 if check.errors else 0


if __name__ == "__main__":
    sys.exit(main())
