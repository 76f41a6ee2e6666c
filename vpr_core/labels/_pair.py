"""What every labeller shares: the error for an unlabelable pair and the pair/match checks."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["LabelUnavailableError", "check_matches", "dataset_image_size", "is_ground_truth"]


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
