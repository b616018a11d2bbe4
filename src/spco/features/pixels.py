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
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from spco.errors import DataFormatError

__all__ = [
    "COMPRESSED_ENCODINGS",
    "DEFAULT_ENCODING",
    "RAW_ENCODINGS",
    "UndeclaredEncodingWarning",
    "check_encoding",
    "decode_compressed",
    "pixels_from_buffer",
    "to_bgr",
]

#: Encodings of pixel arrays (sensor_msgs/Image names) and their number of channels.
RAW_ENCODINGS: dict[str, int] = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono8": 1}
#: Encodings of encoded bytes (sensor_msgs/CompressedImage formats).
COMPRESSED_ENCODINGS = ("jpeg", "png")
#: The colour order of a colour array given without an encoding: OpenCV's.
DEFAULT_ENCODING = "bgr8"

_ALIASES = {"jpg": "jpeg", "8uc3": None, "8uc1": "mono8", "grey": "mono8", "gray": "mono8"}


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


def decode_compressed(data: bytes | bytearray | memoryview | np.ndarray | Any,
                      encoding: str | None = None) -> np.ndarray:
    """An (H, W, 3) uint8 BGR array of JPEG or PNG bytes (a ``sensor_msgs/CompressedImage``'s data).

    ``encoding`` (``jpeg``, ``png`` or ROS's format string) is checked against the bytes' own
    signature when given. Raises :class:`~spco.errors.DataFormatError` for other formats or bytes
    OpenCV cannot decode.
    """
    import cv2

    raw = np.frombuffer(data, dtype=np.uint8) if isinstance(data, bytes | bytearray | memoryview) \
        else np.asarray(data, dtype=np.uint8).ravel()
    head = raw[:8].tobytes()
    kind = "jpeg" if head.startswith(b"\xff\xd8") else "png" if head.startswith(b"\x89PNG") else None
    declared = check_encoding(encoding) if encoding is not None else None
    if kind is None:
        raise DataFormatError(None, "compressed image is empty" if raw.size == 0 else
                              f"compressed image format {encoding or 'unknown'!r} is not supported "
                              "(JPEG or PNG)")
    if declared is not None and declared in COMPRESSED_ENCODINGS and declared != kind:
        raise DataFormatError(None, f"compressed image declared {declared} holds {kind} data")
    array = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED)
    if array is None:
        raise DataFormatError(None, f"the {kind} image could not be decoded (truncated or corrupt?)")
    if array.dtype != np.uint8:  # 16-bit PNG
        array = (array // 257).astype(np.uint8)
    # OpenCV decodes colour files into BGR(A) and grey files into one channel
    channels = 1 if array.ndim == 2 else array.shape[2]
    return to_bgr(array, {1: "mono8", 3: "bgr8", 4: "bgra8"}.get(channels))
