"""Camera views given to a served home: encoded JPEG/PNG bytes or raw pixels, checked before decoding.

An image is either *encoded* (the bytes of a JPEG or PNG file; ``encoding`` ``None``) or *raw*
pixels with an explicit ``encoding`` named as ROS names them (``sensor_msgs/Image``): ``rgb8``,
``bgr8`` (H × W × 3) or ``mono8`` (H × W). A NumPy array without ``encoding`` is ``bgr8`` when it
has three channels (OpenCV's order, as :func:`spco.features.read_image` takes arrays) and
``mono8`` when it has none. Encoded images are measured from their header before they are
decoded, so a small file that would decode to a huge image is refused
(:class:`ImageTooLargeError`); broken ones are refused with one clear :class:`ImageError`.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from spco.errors import ConfigurationError
from spco.knowledge.requests import ENCODINGS

__all__ = ["DEFAULT_MAX_PIXELS", "ENCODINGS", "ImageError", "ImageTooLargeError", "decode_image",
           "encoded_size"]

#: The largest image accepted, in pixels (2048 × 2048: a 1080p camera fits; one decode of it is
#: 12.6 MB, where a 4096 × 4096 image would be 50 MB).
DEFAULT_MAX_PIXELS = 2048 * 2048


class ImageError(ConfigurationError):
    """A view that is not a usable image: not JPEG/PNG, corrupt, or raw pixels of the wrong size."""


class ImageTooLargeError(ImageError):
    """An image with more pixels than the server accepts."""


def encoded_size(data: bytes) -> tuple[str, int, int]:
    """``(format, width, height)`` of JPEG or PNG bytes, read from the header without decoding.

    Raises :class:`ImageError` for other bytes or a header cut short.
    """
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        if len(data) < 24 or data[12:16] != b"IHDR":
            raise ImageError("image: a PNG without its IHDR header (cut short?)")
        width, height = struct.unpack(">II", data[16:24])
        return "png", width, height
    if data[:3] == b"\xff\xd8\xff":
        i = 2
        while i + 4 <= len(data):
            if data[i] != 0xFF:
                i += 1
                continue
            marker = data[i + 1]
            if marker == 0xFF:  # fill byte
                i += 1
                continue
            if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:  # no length
                i += 2
                continue
            (length,) = struct.unpack(">H", data[i + 2:i + 4])
            if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):  # start of frame
                if i + 9 > len(data):
                    break
                height, width = struct.unpack(">HH", data[i + 5:i + 9])
                return "jpeg", width, height
            if marker == 0xDA:  # start of scan before any frame header
                break
            i += 2 + length
        raise ImageError("image: a JPEG without a frame header (cut short or corrupt?)")
    raise ImageError("image: not a JPEG or PNG (give raw pixels with an encoding: rgb8, bgr8 or mono8)")


def _check_pixels(width: int, height: int, max_pixels: int) -> None:
    if width < 8 or height < 8:
        raise ImageError(f"image: {width}×{height} pixels is too small (at least 8×8)")
    if width * height > max_pixels:
        raise ImageTooLargeError(f"image: {width}×{height} pixels is more than the {max_pixels} accepted")


def decode_image(image: Any, encoding: str | None = None, width: int | None = None, height: int | None = None,
                 max_pixels: int = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """The view as an (H, W, 3) BGR or (H, W) grey uint8 array, ready for an extractor.

    Parameters
    ----------
    image: JPEG/PNG bytes (``encoding`` ``None``); raw pixel bytes (``encoding`` and ``width``,
        ``height`` given); or a uint8 array (H, W, 3) or (H, W).
    encoding: ``rgb8``, ``bgr8``, ``mono8`` for raw pixels; for an array, default ``bgr8`` with three
        channels and ``mono8`` with none.
    max_pixels: the largest image accepted.

    Raises :class:`ImageError` (or :class:`ImageTooLargeError`) naming the problem.
    """
    import cv2

    if encoding is not None and encoding not in ENCODINGS:
        raise ImageError(f"encoding: expected one of {', '.join(ENCODINGS)} (or none for JPEG/PNG bytes), "
                         f"got {encoding!r}")
    if isinstance(image, bytes | bytearray | memoryview):
        data = bytes(image)
        if encoding is None:
            kind, w, h = encoded_size(data)
            _check_pixels(w, h, max_pixels)
            array = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
            if array is None or array.shape[:2] != (h, w):
                raise ImageError(f"image: a broken {kind.upper()} ({w}×{h} in its header, but it does not "
                                 "decode)")
            return array
        if width is None or height is None:
            raise ImageError(f"image: raw {encoding} pixels need their width and height")
        for name, value in (("width", width), ("height", height)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ImageError(f"{name}: expected a whole number of pixels >= 1, got {value!r}")
        _check_pixels(width, height, max_pixels)
        channels = ENCODINGS[encoding]
        expected = width * height * channels
        if len(data) != expected:
            raise ImageError(f"image: {len(data)} bytes of {encoding} pixels, but {width}×{height}"
                             f"×{channels} = {expected} expected")
        shape = (height, width) if channels == 1 else (height, width, channels)
        image = np.frombuffer(data, dtype=np.uint8).reshape(shape)
    elif not isinstance(image, np.ndarray):
        raise ImageError(f"image: expected JPEG/PNG bytes, raw pixel bytes or a uint8 array, got "
                         f"{type(image).__name__}")
    if image.dtype != np.uint8:
        raise ImageError(f"image: a pixel array must be uint8, got {image.dtype}")
    if encoding is None:
        encoding = "mono8" if image.ndim == 2 else "bgr8"
    channels = ENCODINGS[encoding]
    if (channels == 1 and image.ndim != 2) or (channels == 3 and (image.ndim != 3 or image.shape[2] != 3)):
        raise ImageError(f"image: an array of shape {image.shape} is not {encoding} "
                         f"({'H×W' if channels == 1 else 'H×W×3'})")
    _check_pixels(image.shape[1], image.shape[0], max_pixels)
    if encoding == "rgb8":
        return np.ascontiguousarray(image[:, :, ::-1])
    return np.ascontiguousarray(image)
