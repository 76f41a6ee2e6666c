"""Section 4: the proposed dense multi-scale landmarks (Fig. 9, Tables 2-4); the grid is
:meth:`Dense.for_size <vpr_core.landmarks.Dense.for_size>` (docs/DEFINITIONS.md)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..checks import check_image_size
from ..paper import DENSE_PER_SCALE, DENSE_SCALES
from .schemes import Dense

__all__ = ["dense_sampling"]


def dense_sampling(
    image_size: Sequence[int],
    scales: float | Sequence[float] = DENSE_SCALES,
    per_scale: int | Sequence[int] = DENSE_PER_SCALE,
) -> np.ndarray:
    """Dense multi-scale landmarks (Section 4, Fig. 9; the grid is in docs/DEFINITIONS.md).

    ``scales``: area ratios in ``(0, 1]``; ``per_scale``: a perfect square, one or one per scale
    (checked as :class:`~vpr_core.landmarks.Dense` checks them).
    Returns ``(sum(per_scale), 4)`` boxes, scale by scale, row by row, by increasing ``x``.
    """
    size = check_image_size(image_size)
    scheme = Dense(
        scales=(scales,) if np.ndim(scales) == 0 else tuple(scales),  # type: ignore[arg-type]
        per_scale=per_scale if np.ndim(per_scale) == 0 else tuple(per_scale),  # type: ignore[arg-type]
    )
    return scheme.for_size(size)
