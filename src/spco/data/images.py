"""Views given as images: find each sample's image file and turn a home's images into counts.

A plain home may hold ``images/<id>.jpg`` (or ``.jpeg``, ``.png``) in place of ``visual.npz``; a
SIGVerse home's images live in a separate folder (``sigverse_images/<home>/<i>.jpg``, given as
``--images``). :func:`with_image_features` replaces a home's visual counts by those an
:class:`~spco.features.Extractor` computes from its images.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from spco.data.environment import Environment
from spco.errors import DataFormatError
from spco.features import IMAGE_SUFFIXES

__all__ = ["IMAGES_DIR", "image_files", "with_image_features"]

#: The folder of a plain home that holds its views as images.
IMAGES_DIR = "images"


def image_files(folder: str | os.PathLike[str], ids: Sequence[int]) -> list[Path]:
    """The image file ``<folder>/<id>.jpg|jpeg|png`` of each sample id, in order.

    Raises :class:`~spco.errors.DataFormatError` naming the folder and the first missing ids.
    """
    root = Path(folder)
    try:
        names = os.listdir(root)
    except OSError as exc:
        raise DataFormatError(root, f"cannot list the image folder ({exc.strerror})") from None
    by_stem: dict[str, str] = {}
    for name in sorted(names):
        stem, suffix = os.path.splitext(name)
        if suffix.lower() in IMAGE_SUFFIXES:
            if stem in by_stem:
                raise DataFormatError(root / name, f"a second image for sample {stem} ({by_stem[stem]}); "
                                      "keep one")
            by_stem[stem] = name
    missing = [int(i) for i in ids if str(int(i)) not in by_stem]
    if missing:
        raise DataFormatError(root, f"no image for {len(missing)} of {len(ids)} samples (ids "
                              f"{', '.join(map(str, missing[:8]))}{', …' if len(missing) > 8 else ''}); "
                              f"expected <id>{'|'.join(IMAGE_SUFFIXES)}")
    return [root / by_stem[str(int(i))] for i in ids]


def with_image_features(env: Environment, files: Sequence[Path], extractor: Any,
                        jobs: int | None = None) -> Environment:
    """``env`` with its visual counts computed by ``extractor`` from ``files`` (one per sample)."""
    if len(files) != env.n_samples:
        raise DataFormatError(env.source or env.name, f"{len(files)} images for {env.n_samples} samples")
    visual = extractor.extract_many(files, jobs=jobs)
    return dataclasses.replace(env, visual=visual)
