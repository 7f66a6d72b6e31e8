"""Random-number conventions: every stochastic function takes a seed or a Generator."""

from __future__ import annotations

import numpy as np

__all__ = ["as_generator"]


def as_generator(rng=None) -> np.random.Generator:
    """``rng`` itself if it is a numpy Generator, else ``numpy.random.default_rng(rng)``
    (None, an int seed or a SeedSequence)."""
    if isinstance(rng, np.random.Generator):
        return rng
    return np.random.default_rng(rng)
