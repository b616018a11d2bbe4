"""Statistics that add up over homes: a shard's sums are the sum of its homes', the fit's the sum of
its shards'."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Self

__all__ = ["AdditiveCounts"]


@dataclass
class AdditiveCounts:
    """A dataclass of count arrays that add field by field: ``a + b`` is a new one of the same class
    whose every array is the sum of ``a``'s and ``b``'s (each a token or sample counted once)."""

    def __add__(self, other: Self) -> Self:
        if type(other) is not type(self):
            return NotImplemented
        return type(self)(*(getattr(self, f.name) + getattr(other, f.name) for f in fields(self)))

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays."""
        return sum(getattr(self, f.name).nbytes for f in fields(self))
