"""Precision-recall evaluation of a query x reference similarity matrix.

Protocols (``pr_curve(..., protocol=...)``):

``ratio`` (the paper's, after Sunderhauf et al., IROS 2015)
    Queries without any ground-truth reference are dropped. For each kept query: best reference
    ``b1`` (highest similarity ``S1``; ties: lowest index), ``S2`` = best similarity among all
    other references, score ``r = S2 / S1`` (1.0 when ``S1 <= 0``), clipped to ``[0, 1]``.
    A query is *accepted* when ``r <= tau``; accepted and ``gt[q, b1]`` -> TP, accepted otherwise
    -> FP, rejected -> FN. ``tau`` takes every distinct ``r`` (ascending; queries with equal ``r``
    are accepted together). Recall denominator: ``TP + FN`` = kept queries minus the accepted
    wrong ones (a wrongly accepted query is an FP, not an FN), so once every query is accepted
    recall is 1 if any TP exists. Precision ``TP / (TP + FP)``, 1 when nothing is accepted.
``best_match``
    Same rules, thresholding ``S1`` instead: accepted when ``S1 >= tau``; ``tau`` takes every
    distinct ``S1`` (descending). Same recall denominator ``TP + FN``.
``multi_match``
    Every (query, reference) pair is a decision: accepted when ``S[q, r] >= tau`` (``tau``: every
    distinct similarity, descending); accepted and ground truth -> TP, accepted otherwise -> FP;
    ground-truth pairs not accepted -> FN. Recall denominator: all ground-truth pairs. All queries
    are kept (pairs of queries without ground truth can only be FPs).

Every curve starts at ``(recall 0, precision 1)`` with a sentinel threshold (``-inf`` for
``ratio``, ``+inf`` for the others) meaning "nothing accepted".
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "PROTOCOLS",
    "PRCurve",
    "auc_pr",
    "evaluate",
    "metrics_table",
    "pr_curve",
    "recall_at_100_precision",
    "recall_at_k",
]

PROTOCOLS = ("ratio", "best_match", "multi_match")


@dataclass
class PRCurve:
    """A precision-recall curve.

    Attributes:
        recall: ``(T + 1,)`` recall, non-decreasing, ``recall[0] = 0``.
        precision: ``(T + 1,)`` precision, ``precision[0] = 1``.
        thresholds: ``(T + 1,)`` the ``tau`` of each point (``thresholds[0]`` is the sentinel).
        protocol: protocol name.
        n_queries: queries (``ratio``/``best_match``: kept queries) or pairs (``multi_match``)
            the curve is computed on.
        tp, fp, fn: ``(T + 1,)`` int counts at each point.
    """

    recall: np.ndarray
    precision: np.ndarray
    thresholds: np.ndarray
    protocol: str = "ratio"
    n_queries: int = 0
    tp: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    fp: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    fn: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __iter__(self):
        """Unpack as ``recall, precision, thresholds``."""
        return iter((self.recall, self.precision, self.thresholds))


def _check(similarity, ground_truth) -> tuple[np.ndarray, np.ndarray]:
    s = np.asarray(similarity, dtype=np.float64)
    gt = np.asarray(ground_truth)
    if s.ndim != 2:
        raise ValueError(f"similarity must be a (Nq, Nr) matrix, got shape {s.shape}")
    if gt.shape != s.shape:
        raise ValueError(f"ground_truth shape {gt.shape} differs from similarity shape {s.shape}")
    if gt.dtype != bool:
        if not np.isin(gt, (0, 1)).all():
            raise ValueError("ground_truth must be boolean (or 0/1)")
        gt = gt.astype(bool)
    if np.isnan(s).any():
        raise ValueError("similarity contains NaN")
    return s, gt


def _best_two(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Best index (ties: lowest), best value and second best value (any other reference)."""
    b1 = np.argmax(s, axis=1)
    rows = np.arange(s.shape[0])
    s1 = s[rows, b1]
    rest = s.copy()
    rest[rows, b1] = -np.inf
    s2 = rest.max(axis=1)
    return b1, s1, s2


def _curve_from_scores(score: np.ndarray, correct: np.ndarray, ascending: bool, protocol: str,
                       n_pos: int | None = None) -> PRCurve:
    """Sweep a threshold over per-decision scores (accept ``score <= tau`` if ascending)."""
    n = score.shape[0]
    order = np.argsort(score if ascending else -score, kind="stable")
    sc, ok = score[order], correct[order]
    tp_cum = np.cumsum(ok)
    # last index of each run of equal scores: equal scores are accepted together
    last = np.flatnonzero(np.r_[sc[1:] != sc[:-1], True]) if n else np.zeros(0, dtype=int)
    tp = tp_cum[last].astype(np.int64)
    acc = last + 1
    fp = acc - tp
    fn = (n - acc) if n_pos is None else (n_pos - tp)
    fn = np.asarray(fn, dtype=np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        recall = np.where(tp + fn > 0, tp / np.maximum(tp + fn, 1), 0.0)
        precision = np.where(acc > 0, tp / np.maximum(acc, 1), 1.0)
    sentinel = -np.inf if ascending else np.inf
    fn0 = n if n_pos is None else n_pos
    return PRCurve(
        recall=np.r_[0.0, recall],
        precision=np.r_[1.0, precision],
        thresholds=np.r_[sentinel, sc[last]],
        protocol=protocol,
        n_queries=int(n),
        tp=np.r_[0, tp].astype(np.int64),
        fp=np.r_[0, fp].astype(np.int64),
        fn=np.r_[fn0, fn].astype(np.int64),
    )


def pr_curve(similarity: np.ndarray, ground_truth: np.ndarray, protocol: str = "ratio") -> PRCurve:
    """Precision-recall curve of a similarity matrix (see the module docstring for protocols).

    Args:
        similarity: ``(Nq, Nr)`` float, higher = more similar.
        ground_truth: ``(Nq, Nr)`` bool, True where reference r shows query q's place.
        protocol: ``"ratio"`` (paper), ``"best_match"`` or ``"multi_match"``.

    Returns:
        :class:`PRCurve` starting at ``(R=0, P=1)``.
    """
    if protocol not in PROTOCOLS:
        raise ValueError(f"unknown protocol {protocol!r}; valid: {', '.join(PROTOCOLS)}")
    s, gt = _check(similarity, ground_truth)
    if protocol == "multi_match":
        return _curve_from_scores(s.ravel(), gt.ravel(), False, protocol, n_pos=int(gt.sum()))
    if protocol == "ratio" and s.shape[1] < 2:
        raise ValueError(f"the ratio protocol needs at least 2 references, got {s.shape[1]}")
    if s.shape[1] < 1:
        raise ValueError("similarity has no reference column")
    keep = gt.any(axis=1)
    s, gt = s[keep], gt[keep]
    b1, s1, s2 = _best_two(s)
    correct = gt[np.arange(s.shape[0]), b1]
    if protocol == "ratio":
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.where(s1 > 0, s2 / np.where(s1 > 0, s1, 1.0), 1.0)
        r = np.clip(r, 0.0, 1.0)
        return _curve_from_scores(r, correct, True, protocol)
    return _curve_from_scores(s1, correct, False, protocol)


def auc_pr(curve: PRCurve) -> float:
    """Area under the PR curve: trapezoid rule over recall (``np.trapezoid``)."""
    return float(np.trapezoid(curve.precision, curve.recall))


def recall_at_100_precision(curve: PRCurve) -> float:
    """Highest recall reached with precision exactly 1 (0 if none beyond the start point)."""
    ok = curve.precision >= 1.0
    return float(curve.recall[ok].max()) if ok.any() else 0.0


def recall_at_k(similarity: np.ndarray, ground_truth: np.ndarray, k: int) -> float:
    """Fraction of queries (with ground truth) whose top-k references include a true one.

    Args:
        similarity: ``(Nq, Nr)``.
        ground_truth: ``(Nq, Nr)`` bool.
        k: list length (>= 1; capped at Nr). Ties: stable by reference index.

    Returns:
        Recall@k in ``[0, 1]`` (0 if no query has ground truth).
    """
    if int(k) < 1:
        raise ValueError(f"k must be >= 1, got {k}")
    s, gt = _check(similarity, ground_truth)
    keep = gt.any(axis=1)
    if not keep.any():
        return 0.0
    s, gt = s[keep], gt[keep]
    top = np.argsort(-s, axis=1, kind="stable")[:, : min(int(k), s.shape[1])]
    return float(np.take_along_axis(gt, top, axis=1).any(axis=1).mean())


def evaluate(similarity: np.ndarray, ground_truth: np.ndarray, protocol: str = "ratio"
             ) -> dict[str, float]:
    """Table metrics: ``{"auc", "r_at_100p", "r_at_1", "r_at_5"}`` (PR metrics per ``protocol``)."""
    curve = pr_curve(similarity, ground_truth, protocol)
    return {
        "auc": auc_pr(curve),
        "r_at_100p": recall_at_100_precision(curve),
        "r_at_1": recall_at_k(similarity, ground_truth, 1),
        "r_at_5": recall_at_k(similarity, ground_truth, 5),
    }


def metrics_table(results: Mapping[str, Mapping[str, float]]):
    """``pandas.DataFrame`` with one row per method name and one column per metric."""
    import pandas as pd

    df = pd.DataFrame.from_dict({k: dict(v) for k, v in results.items()}, orient="index")
    df.index.name = "method"
    return df
