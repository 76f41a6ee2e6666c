"""The Gaussian random projection of Sec. 2.1 (conv3 features -> ``paper.PROJECTION_DIM``)."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import torch

from ..checks import check_int

__all__ = ["random_projection"]


@lru_cache(maxsize=4)
def _projection_cached(raw_dim: int, dim: int, seed: int) -> torch.Tensor:
    rng = np.random.default_rng(seed)
    mat = rng.standard_normal((raw_dim, dim), dtype=np.float32)
    mat *= np.float32(1.0 / math.sqrt(dim))
    return torch.from_numpy(mat)


def random_projection(raw_dim: int, dim: int, seed: int = 0) -> torch.Tensor:
    """Gaussian random projection matrix.

    Args:
        raw_dim: input dimension.
        dim: output dimension.
        seed: seed of ``numpy.random.default_rng`` (PCG64).

    Returns:
        ``(raw_dim, dim)`` float32 CPU tensor with i.i.d. ``N(0, 1/dim)`` entries (read-only:
        shared between encoders with the same arguments; ``.to(device)`` makes a copy).
    """
    raw_dim, dim = check_int(raw_dim, "raw_dim", 1), check_int(dim, "dim", 1)
    return _projection_cached(raw_dim, dim, int(seed))
