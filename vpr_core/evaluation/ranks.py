"""Per-query ranking of a checked similarity matrix: which queries ranked anything, each query's
best two references and its score under a protocol, and where its true reference ranks (the one
computation behind R@K, RecallRate@N and the per-query tables).

Every function takes parsed input: ``s`` a float64 ``(Nq, Nr)`` matrix without inf (NaN = not
ranked) and ``gt`` a bool matrix of the same shape, as :meth:`~.curves.Scored.parse` returns
them; nothing is checked again here."""

from __future__ import annotations

import numpy as np

__all__ = ["best_two", "query_scores", "ranked", "true_rank"]


def ranked(s: np.ndarray) -> np.ndarray:
    """``(Nq,)`` bool: the row has a ranked (non-NaN) reference (else it retrieved nothing)."""
    if not s.shape[1]:
        return np.zeros(s.shape[0], dtype=bool)
    return np.asarray(~np.isnan(s).all(axis=1))


def best_two(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Best index (ties: lowest), best value and second best value among ranked references.

    NaN entries are never chosen; with a single ranked reference the second best is the best
    (``S2 := S1``). Every row must have at least one non-NaN entry.
    """
    nan = np.isnan(s)
    if nan.any():
        s = np.where(nan, -np.inf, s)
    b1 = np.argmax(s, axis=1)
    rows = np.arange(s.shape[0])
    s1 = s[rows, b1]
    rest = s.copy()
    rest[rows, b1] = -np.inf
    s2 = rest.max(axis=1)
    if nan.any():
        s2 = np.where(np.isneginf(s2), s1, s2)
    return b1, s1, s2


def query_scores(s: np.ndarray, gt: np.ndarray, ratio: bool) -> tuple[np.ndarray, np.ndarray]:
    """Per-query score and correctness of the best match.

    Args:
        s: ``(n, Nr)`` similarities of queries with a ranked reference; gt: ``(n, Nr)`` bool.
        ratio: score ``r = S2 / S1`` in ``[0, 1]``, accepted if ``r <= tau`` (the ``ratio``
            protocol); else score ``S1``, accepted if ``S1 >= tau`` (``best_match``,
            ``vpr_bench``).

    Returns:
        ``(score (n,), correct (n,) bool)``.
    """
    b1, s1, s2 = best_two(s)
    correct = gt[np.arange(s.shape[0]), b1]
    if not ratio:
        return s1, correct
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(s1 > 0, s2 / np.where(s1 > 0, s1, 1.0), 1.0)
    return np.clip(r, 0.0, 1.0), correct


def true_rank(s: np.ndarray, gt: np.ndarray) -> np.ndarray:
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
