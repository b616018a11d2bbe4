"""Random states as every stochastic function of spco takes them: a seed, a Generator or ``None``."""

from __future__ import annotations

import copy

import numpy as np

__all__ = ["as_generator", "seed_of"]


def as_generator(random_state: int | np.random.Generator | None) -> np.random.Generator:
    """A Generator for ``random_state``: a new one from a seed (``None``: fresh entropy), or a copy of
    a Generator (the caller's Generator is never advanced)."""
    if isinstance(random_state, np.random.Generator):
        return copy.deepcopy(random_state)
    return np.random.default_rng(random_state)


def seed_of(random_state: object) -> int | None:
    """The seed of ``random_state`` for a file's provenance: the integer, or ``None`` for a Generator
    or fresh entropy."""
    if isinstance(random_state, bool) or not isinstance(random_state, int | np.integer):
        return None
    return int(random_state)
