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

import numpy as np
import scipy.sparse as sp

from spco.data.environment import Environment
from spco.errors import DataFormatError
from spco.features import IMAGE_SUFFIXES

__all__ = ["IMAGES_DIR", "extract_views", "image_files", "with_image_features"]

#: The folder of a plain home that holds its views as images.
IMAGES_DIR = "images"


def image_files(folder: str | os.PathLike[str], ids: Sequence[int],
                missing_ok: bool = False) -> list[Path | None]:
    """The image file ``<folder>/<id>.jpg|jpeg|png`` of each sample id, in order.

    A sample without an image raises :class:`~spco.errors.DataFormatError` naming the folder and
    the first missing ids, or with ``missing_ok`` gets ``None`` (a sample without a view).
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
    if missing_ok:
        return [None if str(int(i)) not in by_stem else root / by_stem[str(int(i))] for i in ids]
    if missing:
        raise DataFormatError(root, f"no image for {len(missing)} of {len(ids)} samples (ids "
                              f"{', '.join(map(str, missing[:8]))}{', …' if len(missing) > 8 else ''}); "
                              f"expected <id>{'|'.join(IMAGE_SUFFIXES)}")
    return [root / by_stem[str(int(i))] for i in ids]


def extract_views(files: Sequence[Path | None], extractor: Any,
                  jobs: int | None = None) -> tuple[sp.csr_array, np.ndarray]:
    """The counts ``extractor`` computes from ``files`` (one per sample; ``None``: a sample without
    a view, an all-zero row) and the (N,) bool mask of the samples without a view."""
    missing = np.array([f is None for f in files], dtype=bool)
    present = [f for f in files if f is not None]
    counts = extractor.extract_many(present, jobs=jobs) if present else \
        sp.csr_array((0, extractor.n_features), dtype=np.int64)
    if not missing.any():
        return counts, missing
    rows = np.flatnonzero(~missing)
    widen = sp.csr_array((np.ones(rows.size, dtype=np.int64), (rows, np.arange(rows.size))),
                         shape=(len(files), rows.size))
    return sp.csr_array(widen @ counts), missing


def with_image_features(env: Environment, files: Sequence[Path | None], extractor: Any,
                        jobs: int | None = None) -> Environment:
    """``env`` with its visual counts computed by ``extractor`` from ``files`` (one per sample;
    ``None``: the sample has no view)."""
    if len(files) != env.n_samples:
        raise DataFormatError(env.source or env.name, f"{len(files)} images for {env.n_samples} samples")
    visual, missing = extract_views(files, extractor, jobs)
    return dataclasses.replace(env, visual=visual, view_missing=env.view_missing | missing)
