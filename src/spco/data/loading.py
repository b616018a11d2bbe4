"""One entry point for every data layout: :func:`load` finds out what a path holds and reads it.

A path may be

- an spco cache file (a ``.npz`` written by :func:`write_cache` / ``spco import``);
- one home in the authors' SIGVerse layout (a folder with ``position/``);
- one home in spco's plain format (a folder with ``samples.csv`` or ``samples.jsonl``);
- a folder of homes in either layout (mixed is fine): every subfolder that is a home, sorted by
  name; other files and folders (``.DS_Store``, ``maps/``, hidden folders) are ignored.

Views given as images (plain homes' ``images/``, or ``images=`` a folder ``<home>/<id>.jpg`` such
as ``sigverse_images``) are turned into counts by an ``extractor`` (:mod:`spco.features`).

The teaching rate selects the sentences: SIGVerse homes read ``sentence/per_<rate>``; plain homes keep
a seeded random ``rate`` percent of their taught samples (:meth:`Environment.with_teaching_rate`).
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypeVar

from spco.data.cache import read_cache_records, write_records
from spco.data.environment import Corpus, Environment
from spco.data.plain import VISUAL_NPY, VISUAL_NPZ, has_images, is_plain_home, plain_home_name, read_home
from spco.data.records import HomeRecord
from spco.data.sigverse import is_sigverse_home, read_sigverse_home
from spco.errors import ConfigurationError, DataFormatError

T = TypeVar("T")
_EXPECTED = ("expected an spco cache file (.npz), a SIGVerse home (a folder with position/ and "
             "vision_fc7_normalized/), a plain home (a folder with samples.csv or samples.jsonl and "
             "visual.npz), or a folder of such homes")


def _check_rate(teaching_rate: int) -> None:
    if isinstance(teaching_rate, bool) or not isinstance(teaching_rate, int) \
            or not 0 <= teaching_rate <= 100:
        raise ConfigurationError(f"teaching rate must be an integer percentage within 0..100, got "
                                 f"{teaching_rate!r}")


def home_kind(path: str | os.PathLike[str]) -> str | None:
    """``"sigverse"`` or ``"plain"`` if ``path`` is a home folder of that layout, else ``None``."""
    if is_sigverse_home(path):
        return "sigverse"
    if is_plain_home(path):
        return "plain"
    return None


def find_homes(path: str | os.PathLike[str]) -> list[Path]:
    """The home folders of folder ``path`` (subfolders of either layout), sorted by name."""
    folder = Path(path)
    try:
        names = sorted(os.listdir(folder))
    except OSError as exc:
        raise DataFormatError(folder, f"cannot be listed ({exc.strerror})") from None
    return [folder / n for n in names
            if not n.startswith(".") and (folder / n).is_dir() and home_kind(folder / n) is not None]



def views_are_images(path: str | os.PathLike[str]) -> bool:
    """Whether a plain home at ``path``, or one of the homes in the folder ``path``, gives its views as
    images only (``images/``, no visual.npz): they need an image extractor to become counts."""
    path = Path(path)
    if not path.is_dir():
        return False
    homes = [path] if home_kind(path) is not None else find_homes(path)
    return any(home_kind(h) == "plain" and has_images(h) and not (h / VISUAL_NPZ).exists()
               and not (h / VISUAL_NPY).exists() for h in homes)

def _no_homes(folder: Path) -> DataFormatError:
    """The error for a folder that holds no home, saying what seems to be missing."""
    from spco.data.plain import SAMPLES_CSV, SAMPLES_JSONL, VISUAL_NPY, VISUAL_NPZ

    if any((folder / f).exists() for f in (VISUAL_NPZ, VISUAL_NPY, "home.json", "test.txt")):
        return DataFormatError(folder / SAMPLES_CSV, f"missing: a plain home needs {SAMPLES_CSV} or "
                               f"{SAMPLES_JSONL} (one row per sample)")
    if (folder / "vision_fc7_normalized").is_dir() or (folder / "Environment_parameter.txt").exists():
        return DataFormatError(folder / "position", "missing: a SIGVerse home needs position/<i>.txt")
    return DataFormatError(folder, f"holds no homes; {_EXPECTED}")


def _read_record(home: Path, extractor: Any = None, images: Path | None = None) -> HomeRecord:
    if home_kind(home) == "sigverse":
        env, rates = read_sigverse_home(home)
        if extractor is not None:
            env = _sigverse_images(env, home, extractor, images)
        return HomeRecord(env, rates, str(home / "sentence"))
    if extractor is not None and images is not None and not has_images(home):
        from spco.data.image_views import image_files, with_image_features

        env = read_home(home)  # its images are in the --images folder
        env = with_image_features(env, image_files(images / env.name, env.ids.tolist()), extractor)
        return HomeRecord(env, None, str(home))
    return HomeRecord(read_home(home, extractor=extractor), None, str(home))


def _sigverse_images(env: Environment, home: Path, extractor: Any, images: Path | None) -> Environment:
    """A SIGVerse home with counts computed from ``images/<home>/<i>.jpg`` instead of its fc7 files."""
    from spco.data.image_views import image_files, with_image_features

    if images is None:
        raise DataFormatError(home, f"a SIGVerse home holds CNN features, not images: give the folder of "
                              f"its images (--images, e.g. sigverse_images) for the extractor "
                              f"{extractor.name!r}")
    return with_image_features(env, image_files(images / env.name, env.ids.tolist()), extractor)


def training_image_files(path: str | os.PathLike[str], names: Sequence[str] | None = None,
                         images: str | os.PathLike[str] | None = None) -> list[Path]:
    """The image files of the training samples of the homes at ``path`` (a folder of homes or a home):
    plain homes' ``images/``, or ``images/<home>/<id>.jpg`` for the others. For learning a codebook."""
    from spco.data.image_views import image_files
    from spco.data.plain import plain_training_images

    src = Path(path)
    if not src.is_dir():
        raise DataFormatError(src, "views as images need a folder of homes (not a cache file)")
    homes = [src] if home_kind(src) is not None else find_homes(src)
    if names is not None:
        homes = _select([(_home_name(h), h) for h in homes], names, src)
    files: list[Path] = []
    for home in homes:
        if home_kind(home) == "plain" and has_images(home):
            files += plain_training_images(home)
        elif images is None:
            raise DataFormatError(home, "holds no images/ folder; give the folder of the homes' images "
                                  "(--images)")
        else:
            env = _read_record(home).environment
            files += image_files(Path(images) / env.name, env.ids[~env.is_test].tolist())
    return files


def home_folders(path: str | os.PathLike[str], names: Sequence[str] | None = None) -> list[Path]:
    """The home folders at ``path`` (a home folder, or a folder of homes), restricted to and ordered
    by ``names`` if given, without reading the homes (a cache file is an error: it holds no folders)."""
    src = Path(path)
    if not src.exists():
        raise DataFormatError(src, "no such file or folder")
    if not src.is_dir():
        raise DataFormatError(src, f"not a folder of homes; {_EXPECTED}")
    if home_kind(src) is not None:
        homes = [src]
    else:
        homes = find_homes(src)
        if not homes:
            raise _no_homes(src)
    if names is not None:
        homes = _select([(_home_name(h), h) for h in homes], names, src)
    return homes


def _home_name(home: Path) -> str:
    """A home's name without reading it (plain homes may rename themselves in home.json)."""
    return plain_home_name(home) if home_kind(home) == "plain" else home.resolve().name


def read_records(
    path: str | os.PathLike[str],
    names: Sequence[str] | None = None,
    progress: bool = False,
    extractor: Any = None,
    images: str | os.PathLike[str] | None = None,
) -> list[HomeRecord]:
    """Read the homes at ``path`` (any layout) with the sentences of every teaching rate.

    ``names`` restricts (and orders) the homes. This is what :func:`load_homes` and the cache use.
    With ``extractor`` the views are images (a plain home's ``images/``, else
    ``images/<home name>/<id>.jpg|png``) turned into counts by it.
    """
    from spco.progress import progress_bar

    src = Path(path)
    if not src.exists():
        raise DataFormatError(src, "no such file or folder")
    if src.is_file():
        try:
            with open(src, "rb") as fh:
                is_zip = fh.read(2) == b"PK"
        except OSError as exc:
            raise DataFormatError(src, f"cannot be read ({exc.strerror})") from None
        if not is_zip:
            raise DataFormatError(src, f"not an spco cache file; {_EXPECTED}")
        if extractor is not None:
            raise DataFormatError(src, "a cache file holds count vectors, not images; give the folder of "
                                  "homes for views as images")
        records = read_cache_records(src)  # explains a damaged or foreign .npz
        return _select([(r.environment.name, r) for r in records], names, src)
    if not src.is_dir():
        raise DataFormatError(src, f"neither a file nor a folder; {_EXPECTED}")
    homes = home_folders(src, names)
    # the bar shows on a terminal only, and is wiped when done (or when a home fails to load)
    with progress_bar(homes, desc="reading homes", unit="home", leave=False,
                      disable=None if progress else True) as bar:
        folder = None if images is None else Path(images).expanduser()
        if folder is not None and not folder.is_dir():
            raise DataFormatError(folder, "no such folder of images (--images)")
        return [_read_record(h, extractor, folder) for h in bar]


def _select(items: list[tuple[str, T]], names: Sequence[str] | None, src: Path) -> list[T]:
    if names is None:
        return [item for _, item in items]
    by_name = dict(items)
    unknown = [n for n in names if n not in by_name]
    if unknown:
        raise DataFormatError(src, f"no home named {', '.join(map(repr, unknown))}; homes: "
                              f"{', '.join(by_name)}")
    return [by_name[n] for n in names]


def load_homes(
    path: str | os.PathLike[str],
    names: Sequence[str] | None = None,
    teaching_rate: int = 100,
    progress: bool = False,
    extractor: Any = None,
    images: str | os.PathLike[str] | None = None,
) -> list[Environment]:
    """The homes at ``path`` (any layout, see the module docstring) as taught at ``teaching_rate``.

    ``names`` restricts the result to those homes, in that order (an unknown name is an error listing
    the homes there are). For callers that build their own :class:`Corpus`.
    """
    _check_rate(teaching_rate)
    return [r.at_rate(teaching_rate) for r in read_records(path, names=names, progress=progress,
                                                           extractor=extractor, images=images)]


def load_home(path: str | os.PathLike[str], teaching_rate: int = 100, extractor: Any = None,
              images: str | os.PathLike[str] | None = None) -> Environment:
    """The single home at ``path`` (a home folder, or a cache holding exactly one home); views as
    images with ``extractor`` (see :func:`read_records`)."""
    homes = load_homes(path, teaching_rate=teaching_rate, extractor=extractor, images=images)
    if len(homes) != 1:
        raise DataFormatError(path, f"holds {len(homes)} homes, expected one: "
                              f"{', '.join(e.name for e in homes[:10])}")
    return homes[0]


def load(path: str | os.PathLike[str], teaching_rate: int = 100, progress: bool = False) -> Corpus:
    """Load the homes at ``path`` — a cache file, a home, or a folder of homes — as a :class:`Corpus`.

    ``progress=True`` shows a progress bar on standard error when it is a terminal.

    Raises :class:`~spco.errors.DataFormatError` naming the file at fault when something is missing
    or malformed, and :class:`~spco.errors.ConfigurationError` for a teaching rate outside 0..100.
    """
    return Corpus(load_homes(path, teaching_rate=teaching_rate, progress=progress))


def write_cache(
    src: str | os.PathLike[str],
    out: str | os.PathLike[str],
    teaching_rate: int | None = None,
    overwrite: bool = False,
    progress: bool = False,
) -> str:
    """Read the homes at ``src`` (any layout :func:`spco.data.load` accepts) into one cache file.

    Parameters
    ----------
    src:
        A home, a folder of homes, or another cache file.
    out:
        The cache file to write (the name is kept as given; ``.npz`` is customary).
    teaching_rate:
        ``None`` (default) stores every teaching rate the homes have (all ``sentence/per_XX`` folders
        of SIGVerse homes; plain homes keep all their sentences and are subsampled when read). A
        number stores only the sentences of that rate, and the cache then only serves that rate.
    overwrite:
        Replace ``out`` if it exists (otherwise :class:`~spco.errors.ConfigurationError`).
    progress:
        Show a progress bar on standard error while reading.

    Returns a one-line human summary of what was written.
    """
    start = time.perf_counter()
    target = Path(out)
    if target.is_dir():
        raise ConfigurationError(f"{target} is a folder; give the path of the cache file to write")
    if target.exists() and not overwrite:
        raise ConfigurationError(f"{target} already exists; use --force (overwrite=True) to replace it")
    if teaching_rate is not None and (isinstance(teaching_rate, bool) or not isinstance(teaching_rate, int)
                                      or not 0 <= teaching_rate <= 100):
        raise ConfigurationError(f"teaching rate must be an integer within 0..100, got {teaching_rate!r}")
    if not target.parent.is_dir():
        raise ConfigurationError(f"folder {target.parent} does not exist")
    records = read_records(src, progress=progress)
    names = [r.environment.name for r in records]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ConfigurationError(f"home names must be unique in a cache; repeated: {', '.join(repeated)}")
    write_records(records, target, teaching_rate)
    n = sum(r.environment.n_samples for r in records)
    if teaching_rate is not None:
        rates = f"teaching rate {teaching_rate}%"
    else:
        stored = sorted({rate for r in records if r.rates for rate in r.rates})
        parts = ["teaching rates " + ", ".join(map(str, stored)) + "%"] if stored else []
        if any(r.rates is None for r in records):
            parts.append("plain homes at any teaching rate")
        rates = "; ".join(parts) or "nothing taught"
    size = target.stat().st_size / 1e6
    return (f"wrote {len(records)} homes ({n} samples, {rates}) to {target} ({size:.1f} MB) in "
            f"{time.perf_counter() - start:.1f} s")
