"""Section 4: the proposed dense multi-scale landmarks (Fig. 9, Tables 2-4)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, cast

import numpy as np

from ..checks import check_image_size
from ..paper import DENSE_PER_SCALE, DENSE_SCALES


def _grid_side(count: Any) -> int:
    """Side ``g`` of the ``g x g`` grid holding ``count`` boxes; ValueError if not a square."""
    if isinstance(count, bool) or int(count) != count or count < 1:
        raise ValueError(f"per_scale must be a positive perfect square (g*g), got {count!r}")
    g = math.isqrt(int(count))
    if g * g != int(count):
        raise ValueError(
            f"per_scale={count} is not a perfect square: dense sampling puts g*g boxes on a "
            f"g x g grid (e.g. 9, 16, 25, 36, 49)"
        )
    return g


def _grid_boxes(area_ratio: float, g: int, H: int, W: int) -> np.ndarray:
    """``(g*g, 4)`` boxes of one scale on a ``g x g`` grid, row by row."""
    s = math.sqrt(float(area_ratio))
    w, h = s * W, s * H
    if g == 1:
        xs = np.array([(W - w) / 2.0])
        ys = np.array([(H - h) / 2.0])
    else:
        xs = np.arange(g) * ((W - w) / (g - 1))
        ys = np.arange(g) * ((H - h) / (g - 1))
    yy, xx = np.meshgrid(ys, xs, indexing="ij")  # row-major: y outer, x inner
    return np.stack([xx.ravel(), yy.ravel(), np.full(g * g, w), np.full(g * g, h)], axis=1)


def dense_sampling(
    image_size: Sequence[int],
    scales: Sequence[float] = DENSE_SCALES,
    per_scale: int | Sequence[int] = DENSE_PER_SCALE,
) -> np.ndarray:
    """Dense multi-scale landmarks (Section 4, Fig. 9; the grid is in docs/DEFINITIONS.md).

    ``scales``: area ratios in ``(0, 1]``; ``per_scale``: a perfect square, one or one per scale.
    Returns ``(sum(per_scale), 4)`` boxes, scale by scale, row by row, by increasing ``x``.
    """
    H, W = check_image_size(image_size)
    scales_arr = np.atleast_1d(np.asarray(scales, dtype=np.float64))
    if scales_arr.ndim != 1 or scales_arr.size == 0:
        raise ValueError(f"scales must be a non-empty 1-D sequence of area ratios, got {scales!r}")
    if not np.all(np.isfinite(scales_arr)) or np.any(scales_arr <= 0) or np.any(scales_arr > 1):
        raise ValueError(f"every scale (area ratio) must lie in (0, 1], got {list(scales_arr)}")
    if np.ndim(per_scale) == 0:
        counts = [per_scale] * scales_arr.size
    else:
        counts = list(cast(Sequence[int], per_scale))
        if len(counts) != scales_arr.size:
            raise ValueError(
                f"per_scale has {len(counts)} counts but there are {scales_arr.size} scales; "
                "give one count per scale or a single int"
            )
    blocks = [_grid_boxes(a, _grid_side(c), H, W) for a, c in zip(scales_arr, counts, strict=False)]
    return np.concatenate(blocks, axis=0)
