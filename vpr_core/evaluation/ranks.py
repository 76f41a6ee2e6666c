"""Where each query's true reference ranks: the one computation behind R@K
(:func:`~.curves.recall_at_k`), RecallRate@N and the per-query tables."""

from __future__ import annotations

import numpy as np


def _true_rank(s: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """``(n,)`` 0-based rank of each row's best-ranked true reference (int64 max if none is ranked).

    The rank in the order of ``np.argsort(-s, kind="stable")`` (descending similarity, ties by
    reference index) with NaN entries unranked: the number of entries above the best true
    similarity ``t`` plus the entries equal to ``t`` at a lower index than the first true one.
    Computed by comparisons (no sort); ``rank < k`` is "a true reference in the top k".
    """
    nan = np.isnan(s)
    true_vals = np.where(gt & ~nan, s, -np.inf)
    j = np.argmax(true_vals, axis=1)  # lowest index among the best true ones
    rows = np.arange(s.shape[0])
    t = true_vals[rows, j]
    with np.errstate(invalid="ignore"):
        above = (s > t[:, None]).sum(axis=1)
        tied_before = ((s == t[:, None]) & (np.arange(s.shape[1]) < j[:, None])).sum(axis=1)
    return np.where(np.isneginf(t), np.iinfo(np.int64).max, above + tied_before)


def _topk_hits(s: np.ndarray, gt: np.ndarray, k: int) -> np.ndarray:
    """``(n,)`` bool: a true reference among the top-k ranked (non-NaN) references of each row."""
    return _true_rank(s, gt) < int(k)


def _recall(s: np.ndarray, gt: np.ndarray, keep: np.ndarray, k: int) -> float:
    """:func:`recall_at_k` of checked inputs over the queries ``keep``."""
    return float(_topk_hits(s[keep], gt[keep], k).mean())
