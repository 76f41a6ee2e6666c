"""Exact match labels from a known homography (the ``synthetic`` generator knows each pair's).

A match is correct when the query box, mapped into the reference image by the pair's homography,
overlaps the matched reference box with IoU >= the threshold (:func:`vpr_core.boxes.paired_iou`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..boxes import check_boxes, paired_iou
from . import LabelUnavailableError, check_matches, dataset_image_size, is_ground_truth

__all__ = ["label_matches_exact", "map_boxes"]


def map_boxes(boxes: np.ndarray, homography: np.ndarray,
              image_size: tuple[int, int] | None = None) -> np.ndarray:
    """Map boxes through a homography: axis-aligned bounding box of the 4 mapped corners.

    Args:
        boxes: ``(K, 4)`` ``(x, y, w, h)`` boxes in the source image.
        homography: ``(3, 3)`` mapping source pixel ``(x, y, 1)`` to target pixel coordinates.
        image_size: ``(H, W)`` of the target image; when given the mapped box is clipped to
            ``[0, W] x [0, H]``.

    Returns:
        ``(K, 4)`` boxes in the target image. A box with a corner mapped to or behind the line at
        infinity (projective scale <= 0), or clipped away entirely, gets width = height = 0.
    """
    b = check_boxes(boxes, "boxes")
    H = np.asarray(homography, dtype=np.float64).reshape(3, 3)
    if len(b) == 0:
        return b.copy()
    x, y, w, h = b.T
    cx = np.stack([x, x + w, x, x + w], axis=1)  # (K, 4)
    cy = np.stack([y, y, y + h, y + h], axis=1)
    pts = np.stack([cx, cy, np.ones_like(cx)], axis=-1) @ H.T  # (K, 4, 3)
    z = pts[..., 2]
    valid = (z > 1e-12).all(axis=1)
    zs = np.where(z > 1e-12, z, 1.0)
    mx, my = pts[..., 0] / zs, pts[..., 1] / zs
    x1, x2 = mx.min(axis=1), mx.max(axis=1)
    y1, y2 = my.min(axis=1), my.max(axis=1)
    if image_size is not None:
        Hh, Ww = float(image_size[0]), float(image_size[1])
        x1, x2 = np.clip(x1, 0, Ww), np.clip(x2, 0, Ww)
        y1, y2 = np.clip(y1, 0, Hh), np.clip(y2, 0, Hh)
    out = np.stack([x1, y1, x2 - x1, y2 - y1], axis=1)
    out[~valid, 2:] = 0.0
    out[~valid, :2] = 0.0
    return out


def label_matches_exact(dataset: Any, q: int, r: int, boxes_q: np.ndarray, boxes_r: np.ndarray,
                        matches: np.ndarray, iou_threshold: float = 0.5,
                        image_size_r: tuple[int, int] | None = None) -> np.ndarray:
    """Exact labels from the generator's homography (``synthetic``).

    See :func:`vpr_core.labels.label_matches` (``method="exact"``) for the rule.

    Args:
        dataset: a dataset with ``homographies (N, 3, 3)`` (query i -> reference i) and
            ``ground_truth (Nq, Nr)``.
        q: query index.
        r: reference index.
        boxes_q: ``(Kq, 4)`` query boxes.
        boxes_r: ``(Kr, 4)`` reference boxes.
        matches: ``(P, 2)`` (query box index, reference box index).
        iou_threshold: minimum IoU of mapped query box and reference box.
        image_size_r: ``(H, W)`` of reference ``r`` (default: asked from the dataset).

    Returns:
        ``(P,)`` bool labels.

    Raises:
        LabelUnavailableError: no homographies, or (q, r) is a ground-truth pair with ``r != q``
            (the generator only knows the geometry of the pair (i, i)).
    """
    bq, br = check_boxes(boxes_q, "boxes_q"), check_boxes(boxes_r, "boxes_r")
    m = check_matches(matches, len(bq), len(br))
    Hs = getattr(dataset, "homographies", None)
    if Hs is None:
        raise LabelUnavailableError(
            f"exact labels need dataset.homographies; dataset {getattr(dataset, 'name', '?')!r} "
            "has none: use method='geometric' or method='file'")
    if not is_ground_truth(dataset, q, r):
        return np.zeros(len(m), dtype=bool)  # not the same place: every match is wrong
    if r != q:
        raise LabelUnavailableError(
            f"pair (q={q}, r={r}) is ground truth only through the tolerance; the generator's "
            f"homography is known for (q, q) only. Label (q={q}, r={q}), or use "
            "method='geometric' for neighbouring references")
    if len(m) == 0:
        return np.zeros(0, dtype=bool)
    size_r = image_size_r if image_size_r is not None else dataset_image_size(dataset,
                                                                              "reference", r)
    mapped = map_boxes(bq[m[:, 0]], np.asarray(Hs)[q], size_r)
    return paired_iou(mapped, br[m[:, 1]]) >= iou_threshold
