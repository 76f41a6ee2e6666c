"""Algorithms 1-3: 100 landmarks from 1,000 Edge Box candidates (Sec. 3.2) in proposal order;
``return_indices`` adds the kept candidates' ``(N,)`` int64 indices. Fewer than ``n`` qualifying:
all of them (a run names such images once, :func:`vpr_core.extract_landmarks`).

Each function checks its input once and runs the algorithm of its scheme value
(:class:`~vpr_core.landmarks.MinScale`, ``ScalePriority``, ``ReduceOverlap``), whose
constructor checks the options: a run's per-image path calls the scheme, which trusts them."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..checks import check_boxes, check_image_size
from ..paper import MIN_SCALE_INDEX, N_LANDMARKS, NMS_IOU, SCALE_PRIORITY_ORDER
from .schemes import MinScale, ReduceOverlap, ScalePriority

__all__ = ["reduce_overlap", "select_min_scale", "select_scale_priority"]


def _result(b: np.ndarray, idx: np.ndarray, return_indices: bool):
    return (b[idx], idx) if return_indices else b[idx]


def select_min_scale(
    boxes: np.ndarray,
    image_size: Sequence[int],
    n: int = N_LANDMARKS,
    min_index: int = MIN_SCALE_INDEX,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Landmark Selection Scheme 1 (Algorithm 1, :meth:`MinScale.indices`): the first ``n``
    candidates ``(K, 4)`` whose Table-1 scale index is ``>= min_index`` (default 4, i.e.
    "> Scale 3")."""
    scheme = MinScale(n=n, min_index=min_index)
    b = check_boxes(boxes)
    return _result(b, scheme.indices(b, check_image_size(image_size)), return_indices)


def select_scale_priority(
    boxes: np.ndarray,
    image_size: Sequence[int],
    n: int = N_LANDMARKS,
    order: Sequence[int] = SCALE_PRIORITY_ORDER,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Landmark Selection Scheme 2 (Algorithm 2, :meth:`ScalePriority.indices`): all candidates
    of scale ``order[0]``, then all of ``order[1]``, ..., until ``n`` are selected; scales absent
    from ``order`` never are."""
    given = tuple(order) if isinstance(order, np.ndarray) else order
    scheme = ScalePriority(n=n, order=given)  # type: ignore[arg-type]
    b = check_boxes(boxes)
    return _result(b, scheme.indices(b, check_image_size(image_size)), return_indices)


def reduce_overlap(
    boxes: np.ndarray,
    n: int = N_LANDMARKS,
    iou_threshold: float = NMS_IOU,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Overlap Reduction Scheme 1 (Algorithm 3, :meth:`ReduceOverlap.indices`): the first
    candidate is kept, then each one whose IoU with every kept box is ``<= iou_threshold``,
    until ``n`` are kept."""
    scheme = ReduceOverlap(n=n, iou_threshold=iou_threshold)
    b = check_boxes(boxes)
    return _result(b, scheme.indices(b), return_indices)
