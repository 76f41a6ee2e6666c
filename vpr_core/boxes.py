"""The one IoU of the code base: all pairs (:func:`box_iou`) and row by row (:func:`paired_iou`)
of ``(K, 4)`` ``(x, y, w, h)`` boxes (docs/DEFINITIONS.md, "Images and boxes")."""

from __future__ import annotations

import numpy as np

from .checks import check_boxes

__all__ = ["box_iou", "box_iou_parsed", "paired_iou", "paired_iou_parsed"]


def _iou_from_corners(*c: np.ndarray) -> np.ndarray:
    """IoU from ``(ax0, ay0, ax1, ay1, a_area, bx0, by0, bx1, by1, b_area)``, broadcast."""
    ax0, ay0, ax1, ay1, aarea, bx0, by0, bx1, by1, barea = c
    iw = np.clip(np.minimum(ax1, bx1) - np.maximum(ax0, bx0), 0, None)
    ih = np.clip(np.minimum(ay1, by1) - np.maximum(ay0, by0), 0, None)
    inter = iw * ih
    union = aarea + barea - inter
    out = np.zeros_like(inter)
    np.divide(inter, union, out=out, where=union > 0)
    return np.clip(out, 0.0, 1.0)


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union of every pair of boxes (0 where the union is empty).

    Args:
        a: ``(Ka, 4)`` boxes.
        b: ``(Kb, 4)`` boxes.

    Returns:
        ``(Ka, Kb)`` float64 IoU in ``[0, 1]``.
    """
    return box_iou_parsed(check_boxes(a, "a"), check_boxes(b, "b"))


def box_iou_parsed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:func:`box_iou` of boxes a caller already parsed (float64 ``(K, 4)``; no checks)."""
    return _iou_from_corners(
        a[:, 0:1],
        a[:, 1:2],
        a[:, 0:1] + a[:, 2:3],
        a[:, 1:2] + a[:, 3:4],
        (a[:, 2] * a[:, 3])[:, None],
        b[None, :, 0],
        b[None, :, 1],
        b[None, :, 0] + b[None, :, 2],
        b[None, :, 1] + b[None, :, 3],
        (b[:, 2] * b[:, 3])[None, :],
    )


def paired_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of row-wise paired boxes: ``out[k] = IoU(a[k], b[k])``.

    Args:
        a: ``(P, 4)`` boxes.
        b: ``(P, 4)`` boxes.

    Returns:
        ``(P,)`` float64 IoU in ``[0, 1]`` (0 where the union is empty).
    """
    a = check_boxes(np.asarray(a, dtype=np.float64).reshape(-1, 4), "a")
    b = check_boxes(np.asarray(b, dtype=np.float64).reshape(-1, 4), "b")
    if a.shape[0] != b.shape[0]:
        raise ValueError(
            f"paired_iou needs as many boxes in a as in b, got {a.shape[0]} and {b.shape[0]}"
        )
    return paired_iou_parsed(a, b)


def paired_iou_parsed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:func:`paired_iou` of boxes a caller already parsed (float64 ``(P, 4)`` each; no checks)."""
    return _iou_from_corners(
        a[:, 0],
        a[:, 1],
        a[:, 0] + a[:, 2],
        a[:, 1] + a[:, 3],
        a[:, 2] * a[:, 3],
        b[:, 0],
        b[:, 1],
        b[:, 0] + b[:, 2],
        b[:, 1] + b[:, 3],
        b[:, 2] * b[:, 3],
    )
