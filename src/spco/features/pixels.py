"""Pixel arrays and their colour order: ROS's encoding names, and the conversion to OpenCV's BGR.

A camera frame given as an array of pixels does not say in which order its channels are: OpenCV
(``cv2.imread``) gives BGR, PIL, matplotlib and ``cv_bridge``'s ``rgb8`` give RGB. Read as BGR, an
RGB frame swaps red and blue, and a colour descriptor then sees another room. So wherever spco
takes an array of pixels it takes its **encoding** too, with the names ROS uses in
``sensor_msgs/Image``:

========  ======================================================
rgb8      (H, W, 3) uint8, red, green, blue
bgr8      (H, W, 3) uint8, blue, green, red — OpenCV's order
rgba8     (H, W, 4) uint8, RGB with alpha
bgra8     (H, W, 4) uint8, BGR with alpha
mono8     (H, W) or (H, W, 1) uint8, grey
========  ======================================================

and, for encoded bytes (a ``sensor_msgs/CompressedImage`` or a file's contents), ``jpeg`` and
``png``. :data:`DEFAULT_ENCODING` (``bgr8``, OpenCV's order) is used for a colour array given
without one, with a :class:`UndeclaredEncodingWarning`: declare the encoding of frames that come
from PIL, matplotlib or ``cv_bridge`` (``rgb8``).

This module is the one place where image bytes and pixels become an array: encoded bytes (files,
``sensor_msgs/CompressedImage``, the service's views, bags) are measured from their header
(:func:`encoded_size`) and refused above ``max_pixels`` (:class:`ImageTooLargeError`) **before**
they are decoded, so a small file that would decode to a huge image costs nothing; bytes that are
not a usable image are refused with an :class:`ImageError` naming the problem.
"""

from __future__ import annotations

import struct
import warnings
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from spco.errors import DataFormatError

__all__ = [
    "COMPRESSED_ENCODINGS",
    "DEFAULT_ENCODING",
    "DEFAULT_MAX_PIXELS",
    "MIN_SIDE",
    "RAW_ENCODINGS",
    "SERVED_MAX_PIXELS",
    "ImageError",
    "ImageTooLargeError",
    "UndeclaredEncodingWarning",
    "check_encoding",
    "check_size",
    "decode_compressed",
    "decode_grey",
    "decode_image",
    "encoded_size",
    "pixels_from_buffer",
    "read_image_file",
    "to_bgr",
]

#: Encodings of pixel arrays (sensor_msgs/Image names) and their number of channels.
RAW_ENCODINGS: dict[str, int] = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono8": 1}
#: Encodings of encoded bytes (sensor_msgs/CompressedImage formats).
COMPRESSED_ENCODINGS = ("jpeg", "png")
#: The colour order of a colour array given without an encoding: OpenCV's.
DEFAULT_ENCODING = "bgr8"

#: The largest image accepted by default from the robot's own files, bags and topics, in pixels
#: (8192 × 8192: an 8K camera fits; one decode of it is 201 MB): a bound on what a corrupt or hostile
#: header can make spco allocate.
DEFAULT_MAX_PIXELS = 8192 * 8192
#: The largest image `spco serve` accepts over HTTP by default, in pixels (2048 × 2048: a 1080p
#: camera fits; one decode of it is 12.6 MB), where any client on the network may send one.
SERVED_MAX_PIXELS = 2048 * 2048
#: The smallest side of a view, in pixels.
MIN_SIDE = 8

_ALIASES = {"jpg": "jpeg", "8uc3": None, "8uc1": "mono8", "grey": "mono8", "gray": "mono8"}


class ImageError(DataFormatError):
    """Bytes or pixels that are not a usable view: not JPEG/PNG, corrupt, too small, or raw pixels of
    the wrong size. ``path`` names where the image came from (a file, or a request's field such as
    ``image``), ``None`` when unknown."""


class ImageTooLargeError(ImageError):
    """An image with more pixels than accepted (``max_pixels``), refused from its header before it is
    decoded."""


class UndeclaredEncodingWarning(UserWarning):
    """A colour pixel array was given without its encoding and read as :data:`DEFAULT_ENCODING`."""


def check_encoding(encoding: str | None, *, compressed_ok: bool = True) -> str | None:
    """The canonical name of ``encoding`` (case-insensitive; ``jpg`` → ``jpeg``, ``8UC1`` → ``mono8``),
    or ``None`` for ``None``.

    Raises :class:`~spco.errors.DataFormatError` for a name spco cannot read (e.g. ``bayer_rggb8``,
    ``16UC1`` or ``32FC1`` depth, ``8UC3`` whose colour order is unknown), naming the accepted ones.
    """
    if encoding is None:
        return None
    if not isinstance(encoding, str):
        raise DataFormatError(None, f"an image encoding is a name such as 'rgb8', got {encoding!r}")
    name = encoding.strip().lower()
    name = _ALIASES.get(name, name) or ""
    if compressed_ok and "compresseddepth" not in name:
        # a CompressedImage format: "jpeg", "png", or ROS's "rgb8; jpeg compressed bgr8"
        for kind in COMPRESSED_ENCODINGS:
            if kind in name or (kind == "jpeg" and "jpg" in name):
                return kind
    if name in RAW_ENCODINGS:
        return name
    accepted = ", ".join([*RAW_ENCODINGS, *(COMPRESSED_ENCODINGS if compressed_ok else ())])
    raise DataFormatError(None, f"image encoding {encoding!r} is not supported (accepted: {accepted}); "
                          "depth, Bayer and 16-bit images are not views: give an 8-bit colour or grey image")


def to_bgr(pixels: np.ndarray, encoding: str | None = None) -> np.ndarray:
    """An (H, W, 3) uint8 BGR array of a pixel array in ``encoding``.

    Parameters
    ----------
    pixels: (H, W) or (H, W, 1) grey, (H, W, 3) colour or (H, W, 4) colour with alpha; uint8, or
        float in [0, 1].
    encoding: one of :data:`RAW_ENCODINGS`; ``None``: ``mono8`` for one channel, else
        :data:`DEFAULT_ENCODING` (``bgr8``; ``bgra8`` for 4 channels) with an
        :class:`UndeclaredEncodingWarning`.

    Returns
    -------
    (H, W, 3) uint8 C-contiguous array in OpenCV's BGR order.

    Raises :class:`~spco.errors.DataFormatError` when the array's shape does not match the encoding.
    """
    import cv2

    array = np.asarray(pixels)
    if array.dtype != np.uint8:
        if not np.issubdtype(array.dtype, np.floating) or not np.isfinite(array).all():
            raise DataFormatError(None, f"an image array must be uint8 (0-255) or float (0-1), got "
                                  f"{array.dtype}")
        array = np.clip(np.rint(array * 255.0), 0, 255).astype(np.uint8)
    if array.ndim == 3 and array.shape[2] == 1:
        array = array[:, :, 0]
    channels = 1 if array.ndim == 2 else (array.shape[2] if array.ndim == 3 else -1)
    if channels not in (1, 3, 4):
        raise DataFormatError(None, f"an image must be grey, colour or colour with alpha, got shape "
                              f"{array.shape}")
    name = check_encoding(encoding, compressed_ok=False)
    if name is None:
        name = {1: "mono8", 3: DEFAULT_ENCODING, 4: DEFAULT_ENCODING.replace("8", "a8")}[channels]
        if channels > 1:
            warnings.warn(f"an image array of {channels} channels without its encoding is read as {name} "
                          "(OpenCV's order); declare encoding='rgb8' for frames from PIL, matplotlib or "
                          "cv_bridge's rgb8", UndeclaredEncodingWarning, stacklevel=3)
    if RAW_ENCODINGS[name] != channels:
        raise DataFormatError(None, f"an image declared {name} has {RAW_ENCODINGS[name]} channel(s), the "
                              f"array has shape {array.shape}")
    conversion = {"mono8": cv2.COLOR_GRAY2BGR, "rgb8": cv2.COLOR_RGB2BGR, "rgba8": cv2.COLOR_RGBA2BGR,
                  "bgra8": cv2.COLOR_BGRA2BGR}.get(name)
    out = array if conversion is None else cv2.cvtColor(np.ascontiguousarray(array), conversion)
    return np.ascontiguousarray(out)


def pixels_from_buffer(data: bytes | bytearray | memoryview | np.ndarray, height: int, width: int, step: int,
                       encoding: str) -> np.ndarray:
    """The pixel array of a raw ``sensor_msgs/Image``: its ``data`` bytes, size, row ``step`` and encoding.

    Parameters
    ----------
    data: the image's bytes (``bytes``, a uint8 array, or a list of ints).
    height, width: pixels; step: bytes per row (≥ width × channels; rows may be padded).
    encoding: one of :data:`RAW_ENCODINGS`.

    Returns
    -------
    (height, width) uint8 for ``mono8``, else (height, width, channels) uint8, in the message's own
    channel order (convert with :func:`to_bgr`).

    Raises :class:`~spco.errors.DataFormatError` when the bytes do not match the size.
    """
    name = check_encoding(encoding, compressed_ok=False)
    assert name is not None
    channels = RAW_ENCODINGS[name]
    raw = np.frombuffer(data, dtype=np.uint8) if isinstance(data, bytes | bytearray | memoryview) \
        else np.asarray(data, dtype=np.uint8).ravel()
    height, width, step = int(height), int(width), int(step)
    if height <= 0 or width <= 0 or step < width * channels or raw.size < height * step:
        raise DataFormatError(None, f"image data do not match its size: {raw.size} bytes for {height} rows "
                              f"of {step} bytes ({width} pixels × {channels} channel(s) of {name})")
    pixels = raw[: height * step].reshape(height, step)[:, : width * channels]
    return pixels.reshape(height, width) if channels == 1 else pixels.reshape(height, width, channels)


def encoded_size(data: bytes | bytearray | memoryview | np.ndarray, where: str | PathLike[str] | None = None
                 ) -> tuple[str, int, int]:
    """``(format, width, height)`` of JPEG or PNG bytes, read from the header without decoding.

    ``where`` names the image in the error (a file, or a request's field). Raises :class:`ImageError`
    for empty bytes, other formats, or a header cut short.
    """
    data = memoryview(np.ascontiguousarray(_as_uint8(data)))
    if len(data) == 0:
        raise ImageError(where, "an empty image (no bytes)")
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        if len(data) < 24 or data[12:16] != b"IHDR":
            raise ImageError(where, "a PNG without its IHDR header (cut short?)")
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
        raise ImageError(where, "a JPEG without a frame header (cut short or corrupt?)")
    raise ImageError(where, "not a JPEG or PNG (give raw pixels with an encoding: rgb8, bgr8 or mono8)")


def check_size(width: int, height: int, max_pixels: int | None = DEFAULT_MAX_PIXELS,
               where: str | PathLike[str] | None = None) -> None:
    """Refuse an image of ``width`` × ``height`` pixels smaller than :data:`MIN_SIDE` on a side
    (:class:`ImageError`) or of more than ``max_pixels`` pixels (:class:`ImageTooLargeError`;
    ``None``: no limit)."""
    if width < MIN_SIDE or height < MIN_SIDE:
        raise ImageError(where, f"{width}×{height} pixels is too small (at least {MIN_SIDE}×{MIN_SIDE})")
    if max_pixels is not None and width * height > max_pixels:
        raise ImageTooLargeError(where, f"{width}×{height} pixels is more than the {max_pixels} accepted")


def _as_uint8(data: Any) -> np.ndarray:
    return np.frombuffer(data, dtype=np.uint8) if isinstance(data, bytes | bytearray | memoryview) \
        else np.asarray(data, dtype=np.uint8).ravel()


def _opencv_decode(raw: np.ndarray, grey: bool = False) -> np.ndarray | None:
    """OpenCV's decoder (the one call of it in spco): the array, or ``None`` for bytes it cannot decode."""
    import cv2

    return cv2.imdecode(raw, cv2.IMREAD_GRAYSCALE if grey else cv2.IMREAD_UNCHANGED) if raw.size else None


def decode_compressed(data: bytes | bytearray | memoryview | np.ndarray | Any, encoding: str | None = None, *,
                      max_pixels: int | None = DEFAULT_MAX_PIXELS,
                      where: str | PathLike[str] | None = None) -> np.ndarray:
    """An (H, W, 3) uint8 BGR array of JPEG or PNG bytes (a file's contents, a
    ``sensor_msgs/CompressedImage``'s data, a served view).

    The size is read from the header first (:func:`encoded_size`) and checked (:func:`check_size`:
    at least :data:`MIN_SIDE` a side, at most ``max_pixels``, ``None`` for no limit) before anything is
    decoded. ``encoding`` (``jpeg``, ``png`` or ROS's format string) is checked against the bytes' own
    signature when given; ``where`` names the image in errors.

    Raises :class:`ImageTooLargeError` for too many pixels, :class:`ImageError` for other formats,
    a wrong declared format, or bytes that do not decode to the size in their header.
    """
    raw = _as_uint8(data)
    kind, width, height = encoded_size(raw, where)
    declared = check_encoding(encoding) if encoding is not None else None
    if declared is not None and declared in COMPRESSED_ENCODINGS and declared != kind:
        raise ImageError(where, f"compressed image declared {declared} holds {kind} data")
    check_size(width, height, max_pixels, where)
    array = _opencv_decode(raw)
    if array is None or array.shape[:2] != (height, width):
        raise ImageError(where, f"a broken {kind.upper()} ({width}×{height} in its header, but it could not "
                         "be decoded: cut short or corrupt?)")
    if array.dtype != np.uint8:  # 16-bit PNG
        array = (array // 257).astype(np.uint8)
    # OpenCV decodes colour files into BGR(A) and grey files into one channel
    channels = 1 if array.ndim == 2 else array.shape[2]
    return to_bgr(array, {1: "mono8", 3: "bgr8", 4: "bgra8"}.get(channels))


def decode_grey(data: bytes | bytearray | memoryview | np.ndarray, where: str | PathLike[str] | None = None
                ) -> np.ndarray:
    """An (H, W) uint8 grey array of an image file's bytes (a map: PGM or PNG), without a pixel limit
    (maps are the operator's own files, and large). Raises :class:`ImageError` for bytes that do not
    decode."""
    image = _opencv_decode(_as_uint8(data), grey=True)
    if image is None:
        raise ImageError(where, "not a readable map image (PGM or PNG)")
    return image


def decode_image(image: Any, encoding: str | None = None, *, width: int | None = None,
                 height: int | None = None, max_pixels: int | None = DEFAULT_MAX_PIXELS,
                 where: str | PathLike[str] | None = "image") -> np.ndarray:
    """A view as an (H, W, 3) uint8 BGR array, its size checked (:func:`check_size`) before decoding.

    Parameters
    ----------
    image: JPEG/PNG bytes (``encoding`` ``None``, ``jpeg`` or ``png``); raw pixel bytes, rows unpadded
        (``encoding`` one of :data:`RAW_ENCODINGS`, ``width`` and ``height`` given); or a uint8 array
        (H, W), (H, W, 3) or (H, W, 4) in ``encoding`` (default ``bgr8`` for colour, ``mono8`` for grey).
    max_pixels: the largest image accepted (``None``: no limit).
    where: names the image in errors (default ``image``, the field of a request).

    Raises :class:`ImageTooLargeError` or :class:`ImageError` naming the problem.
    """
    name = check_encoding(encoding) if encoding is not None else None
    if isinstance(image, bytes | bytearray | memoryview):
        if name is None or name in COMPRESSED_ENCODINGS:
            return decode_compressed(image, name, max_pixels=max_pixels, where=where)
        if width is None or height is None:
            raise ImageError(where, f"raw {name} pixels need their width and height")
        for field, value in (("width", width), ("height", height)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ImageError(field, f"expected a whole number of pixels >= 1, got {value!r}")
        check_size(width, height, max_pixels, where)
        channels = RAW_ENCODINGS[name]
        expected = width * height * channels
        if len(image) != expected:
            raise ImageError(where, f"{len(image)} bytes of {name} pixels, but {width}×{height}×{channels} = "
                             f"{expected} expected")
        image = pixels_from_buffer(image, height, width, width * channels, name)
    elif not isinstance(image, np.ndarray):
        raise ImageError(where, f"expected JPEG/PNG bytes, raw pixel bytes or a uint8 array, got "
                         f"{type(image).__name__}")
    elif name in COMPRESSED_ENCODINGS:
        raise ImageError(where, f"an array of pixels is not {name} bytes: give its encoding (rgb8, bgr8, "
                         "mono8)")
    if image.dtype != np.uint8:
        raise ImageError(where, f"a pixel array must be uint8, got {image.dtype}")
    if image.ndim not in (2, 3):
        raise ImageError(where, f"an array of shape {image.shape} is not an image (H×W or H×W×channels)")
    check_size(image.shape[1], image.shape[0], max_pixels, where)
    if name is None:
        name = "mono8" if image.ndim == 2 else DEFAULT_ENCODING
    try:
        return to_bgr(image, name)
    except DataFormatError as exc:
        raise ImageError(where, exc.problem) from None


def read_image_file(path: str | PathLike[str], max_pixels: int | None = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """An (H, W, 3) uint8 BGR array of a PNG or JPEG file (:func:`decode_compressed`, the file named in
    errors). Raises :class:`ImageError` (:class:`ImageTooLargeError`) for a missing, unreadable, corrupt
    or too large file."""
    path = Path(path).expanduser()
    if not path.is_file():
        raise ImageError(path, "no such image file")
    try:
        raw = np.fromfile(path, dtype=np.uint8)
    except OSError as exc:
        raise ImageError(path, f"cannot be read ({exc.strerror})") from None
    try:
        return decode_compressed(raw, max_pixels=max_pixels)
    except ImageTooLargeError as exc:
        raise ImageTooLargeError(path, exc.problem) from None
    except ImageError as exc:
        raise ImageError(path, f"not a readable image (expected a PNG or JPEG file): {exc.problem}") from None
