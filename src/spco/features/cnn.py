"""A CNN extractor: activations of an ONNX network as counts, as Hagiwara et al. used fc7 × 5.

The user gives a ``.onnx`` file (any image network exported to ONNX: torchvision, timm, Places365
— nothing is fetched at run time). Each image is resized to ``size`` × ``size`` (or the input size
fixed in the model), converted to RGB floats in [0, 1], normalised with ``mean`` and ``std``
(ImageNet's by default), laid out NCHW and run with ONNX Runtime on the CPU; the output ``output``
(default: the model's first) is flattened and turned into counts
``floor(max(a, 0) × scale)`` with ``scale`` = 5 by default (S^v = 5 of the authors).

Needs the ``onnx`` extra (``pip install "spco[onnx]"``: onnxruntime). The model file's sha256 is
the extractor's checksum (with its ``<file>.data`` external weights, if any): a knowledge file
fitted with one network refuses another.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from spco.errors import ConfigurationError, DataFormatError
from spco.features.base import Extractor, register

__all__ = ["OnnxExtractor", "file_sha256"]

IMAGENET_MEAN = [0.485, 0.456, 0.406]
IMAGENET_STD = [0.229, 0.224, 0.225]


def file_sha256(path: Path) -> str:
    """sha256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


@register
class OnnxExtractor(Extractor):
    """Counts ``floor(max(a, 0) × scale)`` of an ONNX network's activations (module docstring)."""

    name: ClassVar[str] = "onnx"
    version: ClassVar[int] = 1
    defaults: ClassVar[dict[str, Any]] = {"model_path": None, "output": None, "size": 224, "scale": 5.0,
                                          "mean": IMAGENET_MEAN, "std": IMAGENET_STD, "threads": 0}

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        s = self.settings
        if s["model_path"] is None:
            raise ConfigurationError("the onnx extractor needs a model file (--onnx-model file.onnx)")
        path = Path(str(s["model_path"])).expanduser()
        if not path.is_file():
            raise DataFormatError(path, "no such ONNX model file (if it moved, give its new place with "
                                        "--onnx-model)")
        if not isinstance(s["scale"], int | float) or not s["scale"] > 0:
            raise ConfigurationError(f"onnx: scale must be a positive number, got {s['scale']!r}")
        if not isinstance(s["size"], int) or s["size"] < 8:
            raise ConfigurationError(f"onnx: size must be an integer >= 8, got {s['size']!r}")
        try:
            import onnxruntime as ort
        except ImportError:
            raise ConfigurationError("the onnx extractor needs ONNX Runtime: pip install 'spco[onnx]' "
                                     "(or pip install onnxruntime)") from None
        options = ort.SessionOptions()
        if s["threads"]:
            options.intra_op_num_threads = int(s["threads"])
        options.log_severity_level = 3
        try:
            self._session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception types for a bad model
            first = (str(exc).splitlines() or [""])[0][:200]
            raise DataFormatError(path, f"not a usable ONNX model ({first})") from None
        self._path = path
        self._checksum = file_sha256(path)
        external = path.with_name(path.name + ".data")  # torch.onnx.export's external weights
        if external.is_file():
            self._checksum = hashlib.sha256((self._checksum + file_sha256(external)).encode()).hexdigest()
        inputs = self._session.get_inputs()
        if len(inputs) != 1 or len(inputs[0].shape) != 4:
            raise DataFormatError(path, "the model must take one image input of shape (N, 3, H, W)")
        self._input = inputs[0].name
        shape = inputs[0].shape
        fixed = [d if isinstance(d, int) else None for d in shape[2:]]
        self._hw = (fixed[0] or s["size"], fixed[1] or s["size"])
        outputs = [o.name for o in self._session.get_outputs()]
        if s["output"] is None:
            s["output"] = outputs[0]
        if s["output"] not in outputs:
            raise ConfigurationError(f"{path}: the model has no output {s['output']!r}; outputs: "
                                     f"{', '.join(outputs)}")
        probe = self._run(np.zeros((self._hw[0], self._hw[1], 3), np.uint8))
        self._n_features = int(probe.size)

    @classmethod
    def from_parts(cls, settings: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> Extractor:
        return cls(**settings)

    @property
    def n_features(self) -> int:
        return self._n_features

    @property
    def checksum(self) -> str | None:
        return self._checksum

    def spec(self):  # type: ignore[no-untyped-def]
        """The description; ``model_path`` is stored absolute (``--model`` may point elsewhere later)."""
        spec = super().spec()
        spec.settings["model_path"] = str(self._path.resolve())
        return spec

    def _run(self, image: np.ndarray) -> np.ndarray:
        import cv2

        h, w = self._hw
        small = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA)
        rgb = cv2.cvtColor(small, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
        rgb = (rgb - np.asarray(self.settings["mean"], np.float32)) / np.asarray(self.settings["std"],
                                                                                 np.float32)
        batch = np.ascontiguousarray(rgb.transpose(2, 0, 1)[None])
        (out,) = self._session.run([self.settings["output"]], {self._input: batch})
        return np.asarray(out, dtype=np.float64).ravel()

    def _counts(self, image: np.ndarray) -> np.ndarray:
        a = self._run(image)
        if not np.isfinite(a).all():
            raise ConfigurationError(f"{self._path}: the network gave NaN or infinite activations")
        return np.floor(np.maximum(a, 0.0) * float(self.settings["scale"])).astype(np.int64)
