"""Eq. (3) and Table 1: the normalised scale of a landmark and its nine scale bins.

The normalised scale of a box is its area divided by the image area; Table 1 bins it into
Scales 1..9 with the lower edge inclusive (:data:`vpr_core.paper.SCALE_EDGES`). The Table-1
constants are re-exported here from :mod:`vpr_core.paper`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..boxes import check_boxes, check_image_size
from ..paper import N_SCALES, SCALE_EDGES, SCALE_LABELS, SCALE_RANGE_LABELS, SCALE_RANGES

__all__ = [
    "N_SCALES",
    "SCALE_EDGES",
    "SCALE_LABELS",
    "SCALE_RANGES",
    "SCALE_RANGE_LABELS",
    "normalized_scale",
    "scale_distribution",
    "scale_histogram",
    "scale_index",
]


def normalized_scale(boxes: np.ndarray, image_size: Sequence[int]) -> np.ndarray:
    """Normalized scale (Eq. 3): box area / image area.

    Args:
        boxes: ``(K, 4)`` ``(x, y, w, h)``.
        image_size: ``(H, W)``.

    Returns:
        ``(K,)`` float64 area ratios (not clipped; boxes inside the image give ``[0, 1]``).
    """
    b = check_boxes(boxes)
    H, W = check_image_size(image_size)
    return b[:, 2] * b[:, 3] / float(H * W)


def scale_index(
    boxes_or_ratios: np.ndarray | float, image_size: Sequence[int] | None = None
) -> np.ndarray | int:
    """Table-1 scale index (1..9) of boxes or of normalized scales.

    Bins are lower-edge inclusive with edges :data:`SCALE_EDGES` (0.02, 0.05, 0.09, 0.14, 0.23,
    0.34, 0.5, 0.72): ratio 0 -> 1, exactly 0.02 -> 2, exactly 0.72 -> 9, 1.0 -> 9. Ratios above 1
    (boxes larger than the image) also give 9.

    Args:
        boxes_or_ratios: ``(K, 4)`` boxes (then ``image_size`` is required) or a 1-D ``(K,)`` array
            (or a scalar) of normalized scales (then ``image_size`` must be None).
        image_size: ``(H, W)`` when boxes are given.

    Returns:
        ``(K,)`` int64 scale indices in 1..9 (a Python int for a scalar ratio).
    """
    if image_size is not None:
        ratios = normalized_scale(boxes_or_ratios, image_size)
        scalar = False
    else:
        ratios = np.asarray(boxes_or_ratios, dtype=np.float64)
        scalar = ratios.ndim == 0
        if ratios.ndim == 2 and ratios.shape[1] == 4:
            raise ValueError(
                "scale_index got (K, 4) boxes without image_size; pass image_size=(H, W)"
            )
        if ratios.ndim > 1:
            raise ValueError(
                f"scale_index expects (K, 4) boxes with image_size or 1-D ratios, got {ratios.shape}"
            )
        ratios = np.atleast_1d(ratios)
        if not np.all(np.isfinite(ratios)) or np.any(ratios < 0):
            raise ValueError("normalized scales must be finite and >= 0")
    idx = np.searchsorted(np.asarray(SCALE_EDGES), ratios, side="right").astype(np.int64) + 1
    return int(idx[0]) if scalar else idx


def scale_histogram(boxes: np.ndarray, image_size: Sequence[int] | None = None) -> np.ndarray:
    """Count of boxes per Table-1 scale (Fig. 6).

    Args:
        boxes: ``(K, 4)`` boxes (with ``image_size``) or ``(K,)`` normalized scales.
        image_size: ``(H, W)`` when boxes are given.

    Returns:
        ``(10,)`` int64 counts indexed by scale 1..9 (index 0 unused, always 0).
    """
    idx = np.atleast_1d(scale_index(boxes, image_size))
    return np.bincount(idx, minlength=N_SCALES + 1).astype(np.int64)


def scale_distribution(result: Any, dataset: Any) -> Any:
    """Landmark counts per Table-1 scale of a run, query and reference side (the data of Fig. 6).

    Returns:
        ``(9, 2)`` pandas DataFrame indexed ``Scale 1`` .. ``Scale 9``, columns ``query`` and
        ``reference``.
    """
    import pandas as pd

    counts = {}
    for side in ("query", "reference"):
        h = np.zeros(N_SCALES + 1, dtype=np.int64)
        for i, b in enumerate(result.boxes[side]):
            h += scale_histogram(b, dataset.image_size(side, i))
        counts[side] = h[1:]
    return pd.DataFrame(counts, index=list(SCALE_LABELS))
