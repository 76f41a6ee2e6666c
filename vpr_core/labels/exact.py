"""Exact match labels from a known homography (the ``synthetic`` generator knows each pair's).

A match is correct when the query box, mapped into the reference image by the pair's homography,
overlaps the matched reference box with IoU >= the threshold (:func:`vpr_core.boxes.paired_iou`).

Exact labels are the reference every other labeller is measured against, so this module also
holds what every labeller shares: the error for a pair that cannot be labelled and the
pair / match checks (``geometric`` and ``file`` import them from here).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..boxes import check_boxes, paired_iou

__all__ = [
    "LabelUnavailableError",
    "check_matches",
    "dataset_image_size",
    "is_ground_truth",
    "label_matches_exact",
    "map_boxes",
]


# ---- what every labeller shares (exact, geometric, file) ------------------------------------
class LabelUnavailableError(ValueError):
    """The chosen labeller cannot label this pair (e.g. no known geometry for it).

    :func:`vpr_core.statistics.scale_statistics` catches it and counts the pair as *unlabelled*
    (its matches still enter ``n_matches``, CLS and ASL, but not CMR).
    """


def check_matches(matches: Any, n_q: int, n_r: int) -> np.ndarray:
    """Return ``matches`` as int64 ``(P, 2)`` (query box index, reference box index).

    Args:
        matches: array-like ``(P, 2)``; an empty input gives ``(0, 2)``.
        n_q: number of query boxes (valid first column: ``0..n_q - 1``).
        n_r: number of reference boxes (valid second column: ``0..n_r - 1``).

    Raises:
        ValueError: wrong shape or an index outside its boxes.
    """
    m = np.asarray(matches)
    if m.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if m.ndim != 2 or m.shape[1] != 2:
        raise ValueError(f"matches must be (P, 2) index pairs, got shape {m.shape}")
    m = m.astype(np.int64)
    if (m[:, 0] < 0).any() or (m[:, 0] >= n_q).any():
        raise ValueError(f"matches reference query boxes outside 0..{n_q - 1}")
    if (m[:, 1] < 0).any() or (m[:, 1] >= n_r).any():
        raise ValueError(f"matches reference reference boxes outside 0..{n_r - 1}")
    return m


def dataset_image_size(dataset: Any, side: str, i: int) -> tuple[int, int]:
    """``(H, W)`` of image ``i`` of ``side`` (``dataset.image_size`` if it has one, else loaded)."""
    fn = getattr(dataset, "image_size", None)
    if callable(fn):
        hw = fn(side, i)
        return int(hw[0]), int(hw[1])
    img = dataset.load_image(side, i)
    return int(img.shape[0]), int(img.shape[1])


def is_ground_truth(dataset: Any, q: int, r: int) -> bool:
    """``dataset.ground_truth[q, r]``; IndexError naming the shape when (q, r) is outside it."""
    gt = np.asarray(dataset.ground_truth, dtype=bool)
    if not (0 <= q < gt.shape[0] and 0 <= r < gt.shape[1]):
        raise IndexError(f"pair (q={q}, r={r}) outside the ground truth of shape {gt.shape}")
    return bool(gt[q, r])


# ---- exact labels -----------------------------------------------------------------------------
def map_boxes(
    boxes: np.ndarray, homography: np.ndarray, image_size: tuple[int, int] | None = None
) -> np.ndarray:
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


def label_matches_exact(
    dataset: Any,
    q: int,
    r: int,
    boxes_q: np.ndarray,
    boxes_r: np.ndarray,
    matches: np.ndarray,
    iou_threshold: float = 0.5,
    image_size_r: tuple[int, int] | None = None,
) -> np.ndarray:
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
            "has none: use method='geometric' or method='file'"
        )
    if not is_ground_truth(dataset, q, r):
        return np.zeros(len(m), dtype=bool)  # not the same place: every match is wrong
    if r != q:
        raise LabelUnavailableError(
            f"pair (q={q}, r={r}) is ground truth only through the tolerance; the generator's "
            f"homography is known for (q, q) only. Label (q={q}, r={q}), or use "
            "method='geometric' for neighbouring references"
        )
    if len(m) == 0:
        return np.zeros(0, dtype=bool)
    size_r = (
        image_size_r if image_size_r is not None else dataset_image_size(dataset, "reference", r)
    )
    mapped = map_boxes(bq[m[:, 0]], np.asarray(Hs)[q], size_r)
    return paired_iou(mapped, br[m[:, 1]]) >= iou_threshold
