"""The extractor interface: an image in, a non-negative integer count vector of fixed length out.

An :class:`Extractor` has a ``name`` and a ``version`` (of its algorithm; a change of the version
means other counts), ``settings`` (JSON values that fix what it computes) and, if it carries
learnt or downloaded weights (a codebook, a network), their sha256 ``checksum``. Together they
form its :class:`ExtractorSpec`, which knowledge and home files store so that ``adapt``, ``teach``
and ``what`` compute a view's counts exactly as ``fit`` did. :func:`register` makes an extractor
buildable by name; :func:`~spco.features.extractors.build_extractor` (over the built-in extractors,
which register themselves here) rebuilds one from a spec (and the arrays stored with it), and
refuses one whose weights do not match.
"""

from __future__ import annotations

import hashlib
import os
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import scipy.sparse as sp

from spco.errors import ConfigurationError, DataFormatError
from spco.features.pixels import (
    DEFAULT_MAX_PIXELS,
    check_encoding,
    check_size,
    decode_compressed,
    read_image_file,
    to_bgr,
)

__all__ = [
    "IMAGE_SUFFIXES",
    "REGISTRY",
    "Extractor",
    "ExtractorSpec",
    "ImageInput",
    "array_checksum",
    "read_image",
    "register",
]

#: File name endings read as images.
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")

#: An image: a file path, the bytes of a JPEG or PNG file, or an array of pixels — (H, W) grey,
#: (H, W, 3) colour, (H, W, 4) colour with alpha — whose colour order its ``encoding`` gives
#: (:mod:`spco.features.pixels`: rgb8, bgr8, mono8, rgba8, bgra8; default bgr8, OpenCV's order).
ImageInput = str | os.PathLike[str] | bytes | np.ndarray


def read_image(image: ImageInput, encoding: str | None = None, *,
               max_pixels: int | None = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """The image as an (H, W, 3) uint8 BGR array (grey and alpha images are converted).

    Parameters
    ----------
    image: a path (PNG or JPEG, decoded with OpenCV), the bytes of such a file, or an array of pixels
        (uint8, or float in [0, 1]).
    encoding: the colour order of an array: ``rgb8`` (PIL, matplotlib, ``cv_bridge``'s rgb8),
        ``bgr8`` (OpenCV), ``mono8``, ``rgba8``, ``bgra8``; ``None``: ``bgr8`` for colour (with an
        :class:`~spco.features.pixels.UndeclaredEncodingWarning`), ``mono8`` for grey. For bytes:
        ``jpeg`` or ``png`` (checked against the bytes) or ``None``; for a path, ``None`` (a file
        carries its own).
    max_pixels: the largest file or bytes accepted, checked from the header before decoding
        (:func:`spco.features.pixels.decode_compressed`; ``None``: no limit).

    Raises :class:`~spco.errors.DataFormatError` for an unreadable, empty or corrupt file or bytes
    (naming the file), an unknown encoding or one the array's shape does not match;
    :class:`~spco.features.pixels.ImageTooLargeError` for more than ``max_pixels`` pixels.
    """
    if isinstance(image, np.ndarray):
        array = to_bgr(image, encoding)
        where = "image array"
    elif isinstance(image, bytes | bytearray | memoryview):
        array = decode_compressed(bytes(image), encoding, max_pixels=max_pixels)
        where = "image array"
    else:
        if encoding is not None and check_encoding(encoding) not in ("jpeg", "png"):
            raise DataFormatError(str(image), f"encoding {encoding!r} is for arrays of pixels; an image file "
                                  "carries its own colour order")
        where = str(Path(image).expanduser())
        array = read_image_file(where, max_pixels)
    check_size(array.shape[1], array.shape[0], None, None if where == "image array" else where)
    return np.ascontiguousarray(array)


def array_checksum(arrays: Mapping[str, np.ndarray]) -> str | None:
    """sha256 of named arrays (names, dtypes, shapes and bytes), or ``None`` for none."""
    if not arrays:
        return None
    digest = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        digest.update(a.tobytes())
    return digest.hexdigest()


@dataclass(frozen=True)
class ExtractorSpec:
    """What identifies an extractor: name, version, settings and the checksum of its weights."""

    name: str
    version: int | None = None
    settings: dict[str, Any] = field(default_factory=dict)
    checksum: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON form (stored in knowledge and home file headers)."""
        return {"name": self.name, "version": self.version, "settings": dict(self.settings),
                "checksum": self.checksum}

    @classmethod
    def from_dict(cls, value: Any) -> ExtractorSpec:
        """Inverse of :meth:`to_dict`; raises ConfigurationError for a malformed description."""
        if not isinstance(value, Mapping) or not isinstance(value.get("name"), str) \
                or not isinstance(value.get("settings", {}), Mapping):
            raise ConfigurationError(f"malformed extractor description {value!r}")
        version = value.get("version")
        return cls(name=value["name"], version=None if version is None else int(version),
                   settings=dict(value.get("settings") or {}), checksum=value.get("checksum"))

    def describe(self) -> str:
        """One line for people."""
        settings = ", ".join(f"{k}={v}" for k, v in sorted(self.settings.items()) if k != "model_path")
        checksum = f", weights sha256 {self.checksum[:12]}…" if self.checksum else ""
        return f"{self.name} v{self.version} ({settings}{checksum})"


class Extractor(ABC):
    """Base class: turns images into (D,) int64 counts. Subclasses set ``name``, ``version``,
    ``defaults`` and implement :meth:`_counts` (one BGR image -> (D,) non-negative integers)."""

    name: ClassVar[str] = ""
    version: ClassVar[int] = 1
    defaults: ClassVar[dict[str, Any]] = {}
    #: True for extractors whose weights are learnt from images (:meth:`fitted`).
    learns: ClassVar[bool] = False

    def __init__(self, **settings: Any) -> None:
        unknown = sorted(set(settings) - set(self.defaults))
        if unknown:
            raise ConfigurationError(f"extractor {self.name!r} has no setting {', '.join(unknown)}; its "
                                     f"settings: {', '.join(self.defaults) or 'none'}")
        self.settings: dict[str, Any] = {**self.defaults, **settings}

    @classmethod
    def from_parts(cls, settings: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> Extractor:
        """Rebuild from stored settings and weights (:func:`~spco.features.extractors.build_extractor`)."""
        return cls(**settings)

    # ------------------------------------------------------------------ description
    @property
    @abstractmethod
    def n_features(self) -> int:
        """D, the length of the count vectors."""

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        """Weights to store with the description (e.g. a codebook); empty if none."""
        return {}

    @property
    def checksum(self) -> str | None:
        """sha256 of the weights (None without weights)."""
        return array_checksum(self.arrays)

    @property
    def needs_fit(self) -> bool:
        """Whether the weights must first be learnt from images (:meth:`fitted`)."""
        return False

    def spec(self) -> ExtractorSpec:
        """The description stored in knowledge and home files."""
        return ExtractorSpec(self.name, self.version, dict(self.settings), self.checksum)

    def fitted(self, images: Sequence[ImageInput], random_state: int | None = 0) -> Extractor:
        """An extractor with weights learnt from ``images`` (itself if it learns nothing)."""
        return self

    # ------------------------------------------------------------------ extraction
    @abstractmethod
    def _counts(self, image: np.ndarray) -> np.ndarray:
        """(D,) non-negative integer counts of one BGR image."""

    def extract(self, image: ImageInput, encoding: str | None = None) -> np.ndarray:
        """The (D,) int64 counts of one image (path, file bytes or pixel array, any size, grey or
        colour); ``encoding``: an array's colour order (:func:`read_image`)."""
        if self.needs_fit:
            raise ConfigurationError(f"extractor {self.name!r} has no codebook yet: learn it from images "
                                     "first (spco fit on homes with images does)")
        counts = self._counts(read_image(image, encoding))
        return np.asarray(counts, dtype=np.int64)

    def extract_many(self, images: Sequence[ImageInput], jobs: int | None = None,
                     progress: Callable[[int], None] | None = None, encoding: str | None = None
                     ) -> sp.csr_array:
        """(N, D) int64 sparse counts of ``images``, in order; ``jobs`` threads (default: the CPUs);
        ``encoding``: the colour order of the arrays among them (:func:`read_image`)."""
        images = list(images)
        if not images:
            return sp.csr_array((0, self.n_features), dtype=np.int64)
        jobs = max(1, min(jobs or os.cpu_count() or 1, len(images)))
        rows: list[np.ndarray]
        if jobs == 1:
            rows = []
            for image in images:
                rows.append(self.extract(image, encoding))
                if progress is not None:
                    progress(1)
        else:
            with ThreadPoolExecutor(jobs) as pool:  # OpenCV and ONNX Runtime release the GIL
                rows = []
                for row in pool.map(lambda im: self.extract(im, encoding), images):
                    rows.append(row)
                    if progress is not None:
                        progress(1)
        out = sp.csr_array(np.vstack(rows), dtype=np.int64)
        out.eliminate_zeros()
        return out

    def __repr__(self) -> str:
        return f"<extractor {self.spec().describe()}>"


#: Name -> extractor class of every extractor made buildable by name (:func:`register`).
REGISTRY: dict[str, type[Extractor]] = {}


def register(cls: type[Extractor]) -> type[Extractor]:
    """Class decorator: make an extractor buildable by name
    (:func:`~spco.features.extractors.build_extractor`)."""
    REGISTRY[cls.name] = cls
    return cls
