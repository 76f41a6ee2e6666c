"""Eq. (3) and Table 1: a box's normalised scale and its scale index 1..9 (docs/DEFINITIONS.md)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from ..checks import check_boxes, check_image_size
from ..paper import N_SCALES, SCALE_EDGES, SCALE_LABELS

__all__ = [
    "normalized_scale",
    "scale_distribution",
    "scale_histogram",
    "scale_index",
    "scale_index_parsed",
]


def normalized_scale(boxes: np.ndarray, image_size: Sequence[int]) -> np.ndarray:
    """Normalized scale (Eq. 3) ``(K,)``: box area / image area, not clipped."""
    return _normalized_scale(check_boxes(boxes), check_image_size(image_size))


def _normalized_scale(b: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """:func:`normalized_scale` of parsed boxes and ``(H, W)`` (no checks)."""
    return b[:, 2] * b[:, 3] / float(image_size[0] * image_size[1])


def _bin(ratios: np.ndarray) -> np.ndarray:
    """``(K,)`` int64 Table-1 index of finite, non-negative ratios (lower edge inclusive)."""
    return np.searchsorted(np.asarray(SCALE_EDGES), ratios, side="right").astype(np.int64) + 1


def scale_index_parsed(b: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """``(K,)`` :func:`scale_index` of boxes and ``(H, W)`` a caller already parsed (no checks)."""
    return _bin(_normalized_scale(b, image_size))


def scale_index(
    boxes_or_ratios: np.ndarray | float, image_size: Sequence[int] | None = None
) -> np.ndarray | int:
    """Table-1 scale index (1..9) ``(K,)`` of ``(K, 4)`` boxes (with ``image_size``) or of
    ``(K,)`` normalized scales (ratios above 1 give 9; a scalar ratio gives an int)."""
    if image_size is not None:
        return scale_index_parsed(check_boxes(boxes_or_ratios), check_image_size(image_size))
    ratios = np.asarray(boxes_or_ratios, dtype=np.float64)
    if ratios.ndim == 2 and ratios.shape[1] == 4:
        raise ValueError("scale_index got (K, 4) boxes without image_size; pass image_size=(H, W)")
    if ratios.ndim > 1:
        raise ValueError(
            f"scale_index expects (K, 4) boxes with image_size or 1-D ratios, got {ratios.shape}"
        )
    if not np.all(np.isfinite(ratios)) or np.any(ratios < 0):
        raise ValueError("normalized scales must be finite and >= 0")
    idx = _bin(np.atleast_1d(ratios))
    return int(idx[0]) if ratios.ndim == 0 else idx


def scale_histogram(boxes: np.ndarray, image_size: Sequence[int] | None = None) -> np.ndarray:
    """``(10,)`` counts of boxes (or ratios, as :func:`scale_index`) per Table-1 scale 1..9
    (Fig. 6; index 0 unused)."""
    idx = np.atleast_1d(scale_index(boxes, image_size))
    return np.bincount(idx, minlength=N_SCALES + 1).astype(np.int64)


def scale_distribution(result: Any, dataset: Any) -> Any:
    """Landmark counts per Table-1 scale of a run (Fig. 6): ``(9, 2)`` DataFrame indexed
    ``Scale 1`` .. ``Scale 9``, columns ``query``, ``reference``."""
    counts = {}
    for side in ("query", "reference"):
        h = np.zeros(N_SCALES + 1, dtype=np.int64)
        for i, b in enumerate(result.boxes[side]):
            h += scale_histogram(b, dataset.image_size(side, i))
        counts[side] = h[1:]
    return pd.DataFrame(counts, index=list(SCALE_LABELS))
