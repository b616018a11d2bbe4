"""Images to visual count vectors (``spco features``; views as images in every command).

An extractor (:class:`Extractor`) turns an image — a PNG/JPEG path or an array, any size, grey or
colour — into a non-negative integer count vector of fixed length, the form the model's visual
multinomials take. Its description (:class:`ExtractorSpec`: name, version, settings, checksum of
its weights) is stored in knowledge and home files; :func:`build_extractor` rebuilds it.

Built in: :data:`DEFAULT_EXTRACTOR` (OpenCV, nothing downloaded) and ``onnx`` (a CNN from a
user-given ``.onnx`` file, run with ONNX Runtime: the ``[onnx]`` extra).
"""

from spco.features.base import (
    IMAGE_SUFFIXES,
    Extractor,
    ExtractorSpec,
    ImageInput,
    array_checksum,
    read_image,
    register,
)
from spco.features.extractors import build_extractor, registered_extractors

#: The extractor used when none is named.
DEFAULT_EXTRACTOR = "colour-hog"

__all__ = [
    "DEFAULT_EXTRACTOR",
    "IMAGE_SUFFIXES",
    "Extractor",
    "ExtractorSpec",
    "ImageInput",
    "array_checksum",
    "build_extractor",
    "read_image",
    "register",
    "registered_extractors",
]
