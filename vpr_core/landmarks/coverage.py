"""Fig. 14: how many landmarks cover each pixel."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..checks import check_boxes, check_image_size

__all__ = ["landmark_coverage"]


def landmark_coverage(boxes: np.ndarray, image_size: Sequence[int]) -> np.ndarray:
    """``(H, W)`` count of boxes covering each pixel (Fig. 14): pixel ``(r, c)`` is covered when
    its centre ``(c + 0.5, r + 0.5)`` lies in ``[x, x + w) x [y, y + h)`` (boxes clipped)."""
    b = check_boxes(boxes)
    H, W = check_image_size(image_size)
    diff = np.zeros((H + 1, W + 1), dtype=np.float64)
    if b.shape[0]:
        c0 = np.clip(np.ceil(b[:, 0] - 0.5), 0, W).astype(np.int64)
        c1 = np.clip(np.ceil(b[:, 0] + b[:, 2] - 0.5), 0, W).astype(np.int64)
        r0 = np.clip(np.ceil(b[:, 1] - 0.5), 0, H).astype(np.int64)
        r1 = np.clip(np.ceil(b[:, 1] + b[:, 3] - 0.5), 0, H).astype(np.int64)
        ok = (c1 > c0) & (r1 > r0)
        c0, c1, r0, r1 = c0[ok], c1[ok], r0[ok], r1[ok]
        np.add.at(diff, (r0, c0), 1.0)
        np.add.at(diff, (r0, c1), -1.0)
        np.add.at(diff, (r1, c0), -1.0)
        np.add.at(diff, (r1, c1), 1.0)
    return np.cumsum(np.cumsum(diff, axis=0), axis=1)[:H, :W]
