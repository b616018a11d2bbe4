"""Built-in extractors on OpenCV: global colour + gradient histograms, and bags of visual words.

``colour-hog`` (codebook-free)
    The image is resized to ``width`` × ``height``; an HSV colour histogram (``hue_bins`` ×
    ``sat_bins`` × ``val_bins``) of the whole image and of each cell of a 2×2 grid (a two-level
    spatial pyramid), and a HOG descriptor (9 orientations, 16-pixel cells, 2×2-cell blocks). Each
    part is normalised to sum one and scaled to ``colour_counts`` and ``hog_counts`` counts
    (rounded); so every image gives about ``colour_counts + hog_counts`` counts.
``bovw-orb`` / ``bovw-sift``
    A bag of visual words: ORB (or SIFT) keypoints of the image resized to ``width`` pixels wide,
    each descriptor assigned to its nearest of ``words`` codebook words (k-means on up to
    ``training_descriptors`` descriptors of training images, :meth:`BagOfWords.fitted`); counts =
    how many keypoints fell on each word, times ``repeat`` (the count mass per image).
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from spco.errors import ConfigurationError
from spco.features.base import Extractor, ImageInput, read_image, register

__all__ = ["BagOfWords", "ColourHog", "OrbBagOfWords", "SiftBagOfWords"]


def _proportional_counts(values: np.ndarray, total: int) -> np.ndarray:
    """Non-negative ``values`` as whole counts summing to about ``total`` (rounded shares)."""
    values = np.maximum(np.asarray(values, dtype=np.float64), 0.0)
    s = values.sum()
    if s <= 0 or total <= 0:
        return np.zeros(values.shape, dtype=np.int64)
    return np.rint(values * (total / s)).astype(np.int64)


_HOG_BINS = 9
_HOG_CELL = 16


def _hog(grey: np.ndarray) -> np.ndarray:
    """HOG of a grey image (H, W multiples of 16): unsigned gradients in 9 orientation bins per
    16-pixel cell, blocks of 2×2 cells with a one-cell stride, L2-Hys normalised (Dalal & Triggs).
    Returns ((H/16 - 1) · (W/16 - 1) · 36,) floats."""
    import cv2

    g = grey.astype(np.float32)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=1)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=1)
    magnitude, angle = cv2.cartToPolar(gx, gy, angleInDegrees=True)
    bins = (np.floor((angle % 180.0) / (180.0 / _HOG_BINS)).astype(np.int64)) % _HOG_BINS
    h, w = grey.shape
    ch, cw = h // _HOG_CELL, w // _HOG_CELL
    cell = (np.arange(h)[:, None] // _HOG_CELL) * cw + (np.arange(w)[None, :] // _HOG_CELL)
    hist = np.bincount((cell * _HOG_BINS + bins).ravel(), weights=magnitude.ravel(),
                       minlength=ch * cw * _HOG_BINS).reshape(ch, cw, _HOG_BINS)
    blocks = np.concatenate([hist[:-1, :-1], hist[:-1, 1:], hist[1:, :-1], hist[1:, 1:]], axis=2)
    blocks /= np.sqrt((blocks**2).sum(2, keepdims=True)) + 1e-6
    blocks = np.minimum(blocks, 0.2)
    blocks /= np.sqrt((blocks**2).sum(2, keepdims=True)) + 1e-6
    return blocks.ravel()


def _nearest(points: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """(n,) index of the nearest centre (squared Euclidean distance) of each of (n, d) points."""
    d2 = (centres * centres).sum(1)[None, :] - 2.0 * points @ centres.T
    return d2.argmin(1)


def _kmeans(points: np.ndarray, k: int, rng: np.random.Generator, iterations: int = 20) -> np.ndarray:
    """(k, d) float32 centres by Lloyd's k-means from k distinct random points (seeded by ``rng``);
    a centre left empty is moved to a random point. Distances by matrix products (BLAS)."""
    x = np.ascontiguousarray(points, dtype=np.float32)
    centres = x[rng.choice(x.shape[0], k, replace=False)].copy()
    for _ in range(iterations):
        labels = _nearest(x, centres)
        counts = np.bincount(labels, minlength=k)
        sums = np.zeros_like(centres)
        np.add.at(sums, labels, x)
        empty = counts == 0
        new = sums / np.maximum(counts, 1)[:, None]
        new[empty] = x[rng.choice(x.shape[0], int(empty.sum()), replace=False)]
        if np.array_equal(new, centres):
            break
        centres = new
    return centres


@register
class ColourHog(Extractor):
    """HSV colour histograms on a two-level spatial pyramid + HOG (module docstring)."""

    name: ClassVar[str] = "colour-hog"
    version: ClassVar[int] = 1
    defaults: ClassVar[dict[str, Any]] = {"width": 128, "height": 96, "hue_bins": 8, "sat_bins": 4,
                                          "val_bins": 4, "colour_counts": 1000, "hog_counts": 1000}

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        s = self.settings
        for key in ("width", "height"):
            if not isinstance(s[key], int) or s[key] < 32 or s[key] % 16:
                raise ConfigurationError(f"colour-hog: {key} must be a multiple of 16, at least 32")
        for key in ("hue_bins", "sat_bins", "val_bins", "colour_counts", "hog_counts"):
            if not isinstance(s[key], int) or s[key] < (1 if "bins" in key else 0):
                raise ConfigurationError(f"colour-hog: {key} must be a non-negative integer")
        self._n_hog = (s["width"] // 16 - 1) * (s["height"] // 16 - 1) * 4 * _HOG_BINS

    @property
    def n_features(self) -> int:
        s = self.settings
        return 5 * s["hue_bins"] * s["sat_bins"] * s["val_bins"] + self._n_hog

    def _counts(self, image: np.ndarray) -> np.ndarray:
        import cv2

        s = self.settings
        w, h = s["width"], s["height"]
        small = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA)
        hsv = cv2.cvtColor(small, cv2.COLOR_BGR2HSV)
        bins = [s["hue_bins"], s["sat_bins"], s["val_bins"]]
        cells = [hsv, hsv[: h // 2, : w // 2], hsv[: h // 2, w // 2:], hsv[h // 2:, : w // 2],
                 hsv[h // 2:, w // 2:]]
        hists = [cv2.calcHist([c], [0, 1, 2], None, bins, [0, 180, 0, 256, 0, 256]).ravel() for c in cells]
        # the whole image weighs as much as its four cells together (pyramid match weights)
        colour = np.concatenate([hists[0] * 4.0, *hists[1:]])
        hog = _hog(cv2.cvtColor(small, cv2.COLOR_BGR2GRAY))
        return np.concatenate([_proportional_counts(colour, s["colour_counts"]),
                               _proportional_counts(hog, s["hog_counts"])])


class BagOfWords(Extractor):
    """Bag of visual words over OpenCV local descriptors with a k-means codebook (module docstring)."""

    learns: ClassVar[bool] = True
    defaults: ClassVar[dict[str, Any]] = {"width": 336, "keypoints": 500, "words": 512, "repeat": 4,
                                          "training_descriptors": 50000}

    def __init__(self, codebook: np.ndarray | None = None, **settings: Any) -> None:
        super().__init__(**settings)
        for key in ("width", "keypoints", "words", "repeat", "training_descriptors"):
            if not isinstance(self.settings[key], int) or self.settings[key] < 1:
                raise ConfigurationError(f"{self.name}: {key} must be a positive integer")
        self.codebook = None if codebook is None else np.ascontiguousarray(codebook, dtype=np.float32)
        if self.codebook is not None and (self.codebook.ndim != 2
                                          or self.codebook.shape[0] != self.settings["words"]):
            raise ConfigurationError(f"{self.name}: the codebook has shape {self.codebook.shape}, expected "
                                     f"{self.settings['words']} words")
        self._matcher: Any = None

    @classmethod
    def from_parts(cls, settings: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> Extractor:
        return cls(codebook=arrays.get("codebook"), **settings)

    @property
    def n_features(self) -> int:
        return int(self.settings["words"])

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        return {} if self.codebook is None else {"codebook": self.codebook}

    @property
    def needs_fit(self) -> bool:
        return self.codebook is None

    @abstractmethod
    def _detector(self) -> Any:
        """The OpenCV keypoint detector and descriptor."""

    def _descriptors(self, image: np.ndarray) -> np.ndarray:
        """(n, d) float32 descriptors of one BGR image (ORB bits unpacked to 0/1)."""
        import cv2

        width = self.settings["width"]
        if image.shape[1] != width:
            height = max(8, round(image.shape[0] * width / image.shape[1]))
            image = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
        grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        _, desc = self._detector().detectAndCompute(grey, None)
        if desc is None:
            return np.zeros((0, self._descriptor_size), dtype=np.float32)
        if desc.dtype == np.uint8:
            return np.unpackbits(desc, axis=1).astype(np.float32)
        return desc.astype(np.float32)

    _descriptor_size: ClassVar[int] = 0

    def fitted(self, images: Sequence[ImageInput], random_state: int | None = 0) -> Extractor:
        """This extractor with a codebook learnt by k-means on descriptors of ``images``."""
        rng = np.random.default_rng(random_state)
        chunks = [self._descriptors(read_image(im)) for im in images]
        desc = np.vstack([c for c in chunks if c.size] or [np.zeros((0, self._descriptor_size), np.float32)])
        words = self.settings["words"]
        if desc.shape[0] < words:
            raise ConfigurationError(f"{self.name}: {desc.shape[0]} descriptors in {len(chunks)} images are "
                                     f"too few to learn {words} visual words")
        limit = self.settings["training_descriptors"]
        if desc.shape[0] > limit:
            desc = desc[np.sort(rng.choice(desc.shape[0], limit, replace=False))]
        return type(self)(codebook=_kmeans(desc, words, rng), **self.settings)

    def _counts(self, image: np.ndarray) -> np.ndarray:
        desc = self._descriptors(image)
        if desc.shape[0] == 0:
            return np.zeros(self.n_features, dtype=np.int64)
        assert self.codebook is not None
        nearest = _nearest(desc, self.codebook)
        return np.bincount(nearest, minlength=self.n_features).astype(np.int64) * self.settings["repeat"]


@register
class OrbBagOfWords(BagOfWords):
    """Bag of visual words over ORB descriptors (binary, 256 bits)."""

    name: ClassVar[str] = "bovw-orb"
    version: ClassVar[int] = 1
    _descriptor_size: ClassVar[int] = 256

    def _detector(self) -> Any:
        import cv2

        return cv2.ORB_create(nfeatures=self.settings["keypoints"], fastThreshold=5)


@register
class SiftBagOfWords(BagOfWords):
    """Bag of visual words over SIFT descriptors (128 floats)."""

    name: ClassVar[str] = "bovw-sift"
    version: ClassVar[int] = 1
    _descriptor_size: ClassVar[int] = 128

    def _detector(self) -> Any:
        import cv2

        return cv2.SIFT_create(nfeatures=self.settings["keypoints"])
