"""Algorithms 1-3: 100 landmarks from 1,000 Edge Box candidates (Sec. 3.2) in proposal order;
``return_indices`` adds the kept candidates' ``(N,)`` int64 indices. Fewer than ``n`` qualifying:
all of them (a run names such images once, :func:`vpr_core.pipeline.extract_landmarks`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..boxes import _box_iou
from ..checks import check_boxes, check_image_size, check_int, check_range
from ..paper import MIN_SCALE_INDEX, N_LANDMARKS, N_SCALES, NMS_IOU, SCALE_PRIORITY_ORDER
from .scales import _box_scale_index


def _result(boxes: np.ndarray, idx: list[int] | np.ndarray, return_indices: bool):
    idx = np.asarray(idx, dtype=np.int64)
    sel = boxes[idx] if idx.size else np.zeros((0, 4), dtype=np.float64)
    return (sel, idx) if return_indices else sel


def select_min_scale(
    boxes: np.ndarray,
    image_size: Sequence[int],
    n: int = N_LANDMARKS,
    min_index: int = MIN_SCALE_INDEX,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Landmark Selection Scheme 1 (Algorithm 1): the first ``n`` candidates ``(K, 4)`` whose
    Table-1 scale index is ``>= min_index`` (default 4, i.e. "> Scale 3")."""
    b, size, n = check_boxes(boxes), check_image_size(image_size), check_int(n)
    if not 1 <= int(min_index) <= N_SCALES:
        raise ValueError(f"min_index must be in 1..9, got {min_index}")
    idx = np.flatnonzero(_box_scale_index(b, size) >= int(min_index))[:n]
    return _result(b, idx, return_indices)


def select_scale_priority(
    boxes: np.ndarray,
    image_size: Sequence[int],
    n: int = N_LANDMARKS,
    order: Sequence[int] = SCALE_PRIORITY_ORDER,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Landmark Selection Scheme 2 (Algorithm 2): all candidates of scale ``order[0]``, then all
    of ``order[1]``, ..., until ``n`` are selected; scales absent from ``order`` never are."""
    b, size, n = check_boxes(boxes), check_image_size(image_size), check_int(n)
    order = [int(s) for s in order]
    if any(not 1 <= s <= N_SCALES for s in order) or len(set(order)) != len(order):
        raise ValueError(f"order must hold distinct scale indices in 1..9, got {order}")
    sidx = _box_scale_index(b, size)
    picked: list[np.ndarray] = []
    total = 0
    for s in order:
        if total >= n:
            break
        cand = np.flatnonzero(sidx == s)[: n - total]
        picked.append(cand)
        total += cand.size
    idx = np.concatenate(picked) if picked else np.zeros(0, dtype=np.int64)
    return _result(b, idx, return_indices)


def reduce_overlap(
    boxes: np.ndarray,
    n: int = N_LANDMARKS,
    iou_threshold: float = NMS_IOU,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Overlap Reduction Scheme 1 (Algorithm 3): the first candidate is kept, then each one whose
    IoU with every kept box is ``<= iou_threshold``, until ``n`` are kept. Each kept box's IoU
    with the later candidates is folded into a running maximum: a candidate's test is one compare.
    """
    b, n = check_boxes(boxes), check_int(n)
    t = check_range(iou_threshold, "iou_threshold", 0.0, 1.0)
    kept: list[int] = []
    max_iou = np.zeros(b.shape[0], dtype=np.float64)  # max IoU with the boxes kept so far
    for i in range(b.shape[0] if n > 0 else 0):
        if len(kept) >= n:
            break
        if i == 0 or max_iou[i] <= t:
            kept.append(i)
            np.maximum(
                max_iou[i + 1 :], _box_iou(b[i : i + 1], b[i + 1 :])[0], out=max_iou[i + 1 :]
            )
    return _result(b, kept, return_indices)
