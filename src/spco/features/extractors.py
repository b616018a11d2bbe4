"""Every extractor by name: the built-in ones (:mod:`~spco.features.classic`,
:mod:`~spco.features.cnn`, registered as they are imported, with :func:`~spco.features.base.register`)
and any registered since, and an extractor rebuilt from its description (:func:`build_extractor`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from spco.errors import ConfigurationError
from spco.features import classic, cnn
from spco.features.base import REGISTRY, Extractor, ExtractorSpec

__all__ = ["build_extractor", "registered_extractors"]

#: The built-in extractors' modules (imported for their registrations; their heavy libraries, OpenCV
#: and ONNX Runtime, are imported when an extractor first runs).
BUILT_IN = (classic, cnn)


def registered_extractors() -> dict[str, type[Extractor]]:
    """Name -> extractor class of every registered extractor."""
    return dict(REGISTRY)


def build_extractor(spec: ExtractorSpec | Mapping[str, Any] | str,
                    arrays: Mapping[str, np.ndarray] | None = None, **overrides: Any) -> Extractor:
    """Rebuild an extractor from its description (and stored weights); refuse a mismatch.

    ``spec`` may be a name (default settings), a dict (:meth:`ExtractorSpec.to_dict`) or a spec.
    ``arrays``: the weights stored with it (a codebook). ``overrides``: settings that may differ
    from the stored ones without changing the counts (e.g. where the ONNX model file now is).
    Raises ConfigurationError for an unknown name, a newer version, or weights whose checksum
    differs from the description's.
    """
    if isinstance(spec, str):
        spec = ExtractorSpec(spec)
    elif not isinstance(spec, ExtractorSpec):
        spec = ExtractorSpec.from_dict(spec)
    known = registered_extractors()
    if spec.name not in known:
        raise ConfigurationError(f"unknown image extractor {spec.name!r}; known: {', '.join(sorted(known))}")
    cls = known[spec.name]
    if spec.version is not None and spec.version != cls.version:
        raise ConfigurationError(f"the extractor {spec.name!r} was version {spec.version}, this spco has "
                                 f"version {cls.version}: its counts would differ; fit the knowledge again")
    settings = {**spec.settings, **{k: v for k, v in overrides.items() if v is not None}}
    extractor = cls.from_parts(settings, dict(arrays or {}))  # type: ignore[attr-defined]
    if spec.checksum is not None and extractor.checksum is None:
        raise ConfigurationError(f"the weights (codebook) of extractor {spec.name!r} are missing")
    if spec.checksum is not None and extractor.checksum != spec.checksum:
        raise ConfigurationError(f"the weights of extractor {spec.name!r} do not match its description "
                                 f"(sha256 {str(extractor.checksum)[:12]}…, expected {spec.checksum[:12]}…): "
                                 "another codebook or model file than the one the knowledge was fitted with")
    return extractor
