"""Algorithms 1-3: choosing 100 landmarks from 1,000 Edge Box candidates (Sec. 3.2).

- :func:`select_min_scale` -- Landmark Selection Scheme 1 (Algorithm 1): drop small scales.
- :func:`select_scale_priority` -- Landmark Selection Scheme 2 (Algorithm 2): scale priority.
- :func:`reduce_overlap` -- Overlap Reduction Scheme 1 (Algorithm 3): greedy IoU filtering.

All walk the candidates in proposal order and return boxes ``(N, 4)`` float64 ``(x, y, w, h)``.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from ..boxes import box_iou
from ..checks import check_boxes
from ..checks import check_int as check_count
from ..paper import MIN_SCALE_INDEX, N_LANDMARKS, N_SCALES, NMS_IOU, SCALE_PRIORITY_ORDER
from .scales import scale_index

__all__ = [
    "reduce_overlap",
    "select_min_scale",
    "select_scale_priority",
]

logger = logging.getLogger("vpr_core")


def _result(boxes: np.ndarray, idx: list[int] | np.ndarray, return_indices: bool):
    idx = np.asarray(idx, dtype=np.int64)
    sel = boxes[idx] if idx.size else np.zeros((0, 4), dtype=np.float64)
    return (sel, idx) if return_indices else sel


def _warn_undersupply(name: str, got: int, n: int, k: int) -> None:
    if got < n:
        logger.warning(
            "%s: only %d of the requested %d landmarks qualify among %d candidates; returning %d",
            name,
            got,
            n,
            k,
            got,
        )


def select_min_scale(
    boxes: np.ndarray,
    image_size: Sequence[int],
    n: int = N_LANDMARKS,
    min_index: int = MIN_SCALE_INDEX,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Landmark Selection Scheme 1 (Algorithm 1).

    Walks the candidates in proposal order and keeps the first ``n`` whose Table-1 scale index is
    ``>= min_index`` (default 4, i.e. "> Scale 3"). If fewer than ``n`` qualify, all qualifying
    candidates are returned and a warning is logged (the paper's loop would not terminate).

    Args:
        boxes: ``(K, 4)`` candidates in proposal order (the paper uses K = 1000 Edge Boxes).
        image_size: ``(H, W)``.
        n: number of landmarks to select.
        min_index: smallest accepted scale index (1..9).
        return_indices: also return the selected candidates' indices into ``boxes``.

    Returns:
        ``(N, 4)`` selected boxes in proposal order, ``N = min(n, #qualifying)``; with
        ``return_indices`` a tuple ``(boxes, indices (N,) int64)``.
    """
    b = check_boxes(boxes)
    n = check_count(n)
    if not 1 <= int(min_index) <= N_SCALES:
        raise ValueError(f"min_index must be in 1..9, got {min_index}")
    idx = np.flatnonzero(scale_index(b, image_size) >= int(min_index))[:n]
    _warn_undersupply("select_min_scale", idx.size, n, b.shape[0])
    return _result(b, idx, return_indices)


def select_scale_priority(
    boxes: np.ndarray,
    image_size: Sequence[int],
    n: int = N_LANDMARKS,
    order: Sequence[int] = SCALE_PRIORITY_ORDER,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Landmark Selection Scheme 2 (Algorithm 2).

    Takes all candidates of scale ``order[0]`` in proposal order, then all of ``order[1]``, ...,
    stopping as soon as ``n`` are selected. Scales absent from ``order`` are never selected. If
    fewer than ``n`` qualify, all of them are returned (in the above order) and a warning logged.

    Args:
        boxes: ``(K, 4)`` candidates in proposal order.
        image_size: ``(H, W)``.
        n: number of landmarks to select.
        order: scale indices (1..9) by priority.
        return_indices: also return the selected candidates' indices into ``boxes``.

    Returns:
        ``(N, 4)`` selected boxes grouped by scale priority (proposal order within a scale);
        with ``return_indices`` a tuple ``(boxes, indices (N,) int64)``.
    """
    b = check_boxes(boxes)
    n = check_count(n)
    order = [int(s) for s in order]
    if any(not 1 <= s <= N_SCALES for s in order) or len(set(order)) != len(order):
        raise ValueError(f"order must hold distinct scale indices in 1..9, got {order}")
    sidx = scale_index(b, image_size)
    picked: list[np.ndarray] = []
    total = 0
    for s in order:
        if total >= n:
            break
        cand = np.flatnonzero(sidx == s)[: n - total]
        picked.append(cand)
        total += cand.size
    idx = np.concatenate(picked) if picked else np.zeros(0, dtype=np.int64)
    _warn_undersupply("select_scale_priority", idx.size, n, b.shape[0])
    return _result(b, idx, return_indices)


def reduce_overlap(
    boxes: np.ndarray,
    n: int = N_LANDMARKS,
    iou_threshold: float = NMS_IOU,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Overlap Reduction Scheme 1 (Algorithm 3): greedy IoU filtering in proposal order.

    The first candidate is always kept; a later candidate is kept if its IoU with every kept box
    is ``<= iou_threshold``; stops once ``n`` are kept. If fewer than ``n`` survive, all survivors
    are returned and a warning logged.

    Each kept box's IoU with all later candidates (:func:`vpr_core.boxes.box_iou`) is folded into
    a running maximum, so a candidate's test is one comparison.

    Args:
        boxes: ``(K, 4)`` candidates in proposal order.
        n: number of landmarks to keep.
        iou_threshold: IoU threshold ``t`` in ``[0, 1]``.
        return_indices: also return the kept candidates' indices into ``boxes``.

    Returns:
        ``(N, 4)`` kept boxes in proposal order; with ``return_indices`` ``(boxes, indices)``.
    """
    b = check_boxes(boxes)
    n = check_count(n)
    t = float(iou_threshold)
    if not 0.0 <= t <= 1.0:
        raise ValueError(f"iou_threshold must be in [0, 1], got {iou_threshold}")
    kept: list[int] = []
    max_iou = np.zeros(b.shape[0], dtype=np.float64)  # max IoU with the boxes kept so far
    for i in range(b.shape[0] if n > 0 else 0):
        if len(kept) >= n:
            break
        if i == 0 or max_iou[i] <= t:
            kept.append(i)
            np.maximum(max_iou[i + 1 :], box_iou(b[i : i + 1], b[i + 1 :])[0], out=max_iou[i + 1 :])
    _warn_undersupply("reduce_overlap", len(kept), n, b.shape[0])
    return _result(b, kept, return_indices)
