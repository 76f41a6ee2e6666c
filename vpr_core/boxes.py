"""Boxes and images: the one IoU, paired IoU, and the input checks every stage shares.

Boxes are ``np.ndarray (K, 4)`` float64 ``(x, y, w, h)`` in pixels, continuous coordinates: a box
covers ``[x, x + w) x [y, y + h)``, its area is ``w * h`` (no ``+1``). Images are
``np.ndarray (H, W, 3)`` uint8 RGB; ``image_size`` is always ``(H, W)``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = [
    "box_iou",
    "check_boxes",
    "check_image",
    "check_image_size",
    "paired_iou",
]


def check_boxes(
    boxes: Any, name: str = "boxes", k: int | None = None, positive: bool = False
) -> np.ndarray:
    """Return ``boxes`` as float64 ``(K, 4)``; raise a ValueError naming the problem otherwise.

    Args:
        boxes: anything array-like of shape ``(K, 4)``; an empty input gives ``(0, 4)``.
        name: the argument's name, used in the message.
        k: if given, the number of rows the boxes must have (e.g. the descriptor count).
        positive: require ``w > 0`` and ``h > 0`` (else ``w, h >= 0``).

    Returns:
        ``(K, 4)`` float64 array.
    """
    arr = np.asarray(boxes, dtype=np.float64)
    if arr.size == 0:
        arr = arr.reshape(0, 4)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise ValueError(f"{name} must have shape (K, 4) as (x, y, w, h), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf")
    if positive:
        bad = np.flatnonzero((arr[:, 2] <= 0) | (arr[:, 3] <= 0))
        if bad.size:
            raise ValueError(f"{name} must have positive width and height; bad rows: {bad[:10]}")
    elif np.any(arr[:, 2:] < 0):
        raise ValueError(f"{name} has negative width or height (expected (x, y, w, h))")
    if k is not None and arr.shape[0] != k:
        raise ValueError(f"{name} has {arr.shape[0]} boxes but the descriptors have {k} rows")
    return arr


def check_image(image: Any, allow_gray: bool = False, min_size: int = 1) -> np.ndarray:
    """Validate an ``(H, W, 3)`` uint8 RGB image (``(H, W)`` uint8 too with ``allow_gray``).

    Args:
        image: the image.
        allow_gray: accept a 2-D grayscale image.
        min_size: smallest accepted height and width in pixels.

    Returns:
        The image itself.
    """
    what = "(H, W, 3) uint8 RGB" + (" or (H, W) uint8 grayscale" if allow_gray else "")
    if not isinstance(image, np.ndarray):
        raise TypeError(f"image must be a numpy array {what}, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise ValueError(f"image must be {what}, got dtype {image.dtype}")
    if not ((image.ndim == 3 and image.shape[2] == 3) or (allow_gray and image.ndim == 2)):
        raise ValueError(f"image must have shape {what}, got {image.shape}")
    if image.shape[0] < min_size or image.shape[1] < min_size:
        raise ValueError(
            f"image is too small: shape {image.shape}, need at least {min_size} x {min_size} pixels"
        )
    return image


def check_image_size(image_size: Any, name: str = "image_size") -> tuple[int, int]:
    """Validate ``(H, W)`` (a 3-tuple ``image.shape`` is accepted too) and return ints."""
    if isinstance(image_size, np.ndarray) and image_size.ndim >= 2:
        raise ValueError(
            f"{name} must be (H, W), got an array of shape {image_size.shape}; pass image.shape[:2]"
        )
    try:
        seq = tuple(image_size)
    except TypeError:
        raise ValueError(f"{name} must be a (H, W) pair, got {image_size!r}") from None
    if len(seq) not in (2, 3):
        raise ValueError(f"{name} must be a (H, W) pair, got {image_size!r}")
    h, w = seq[0], seq[1]
    try:
        hi, wi = int(h), int(w)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must hold integers (H, W), got {image_size!r}") from None
    if hi != h or wi != w or hi <= 0 or wi <= 0:
        raise ValueError(f"{name} must be positive integers (H, W), got {image_size!r}")
    return hi, wi


def _iou_from_corners(ax0, ay0, ax1, ay1, aarea, bx0, by0, bx1, by1, barea) -> np.ndarray:
    iw = np.clip(np.minimum(ax1, bx1) - np.maximum(ax0, bx0), 0, None)
    ih = np.clip(np.minimum(ay1, by1) - np.maximum(ay0, by0), 0, None)
    inter = iw * ih
    union = aarea + barea - inter
    out = np.zeros_like(inter)
    np.divide(inter, union, out=out, where=union > 0)
    return np.clip(out, 0.0, 1.0)


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pairwise intersection over union of ``(x, y, w, h)`` boxes.

    A pair whose union is 0 (two empty boxes) has IoU 0.

    Args:
        a: ``(Ka, 4)`` boxes.
        b: ``(Kb, 4)`` boxes.

    Returns:
        ``(Ka, Kb)`` float64 IoU in ``[0, 1]``.
    """
    a = check_boxes(a, "a")
    b = check_boxes(b, "b")
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
