"""Precision-recall curves and the table metrics (AUC, R@100P, R@K) of a similarity matrix.

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
``best_match`` (VPR_Tutorial's ``createPR(..., matching="single")``, Schubert et al. 2023)
    Same queries and decisions, thresholding ``S1`` instead: accepted when ``S1 >= tau``;
    ``tau`` takes every distinct ``S1`` (descending). Recall denominator: all kept queries
    (``recall = TP / n``, so the last point is ``(R@1, R@1)``, not recall 1).
``vpr_bench`` (VPR-Bench's AUC-PR, Zaffar et al. IJCV 2021, as its code computes it)
    Every query with a ranked reference is kept, *with or without* ground truth (a query without
    ground truth is a negative); per query the top-1 ``b1`` and ``S1``; ``y = gt[q, b1]``;
    scikit-learn's ``precision_recall_curve(y, S1)``: ``tau`` = every distinct ``S1``
    (descending), accepted when ``S1 >= tau``. Recall denominator: the queries whose top-1 is
    correct (``recall = TP / sum(y)``: VPR-Bench's known quirk, recall is relative to the
    correctly retrieved queries and always reaches 1). The curve stops at the first point of full
    recall (scikit-learn < 1.1, the versions of VPR-Bench's time) and starts at ``(0, 1)``.
    AUC: trapezoids over recall (= ``sklearn.metrics.auc(recall, precision)``). When no top-1 is
    correct the curve is ``(0, 1), (0, 0)...`` and the AUC 0 (VPR-Bench's code gives NaN).
``multi_match``
    Every (query, reference) pair is a decision: accepted when ``S[q, r] >= tau`` (``tau``: every
    distinct similarity, descending); accepted and ground truth -> TP, accepted otherwise -> FP;
    ground-truth pairs not accepted -> FN. Recall denominator: all ground-truth pairs. All queries
    are kept (pairs of queries without ground truth can only be FPs).

Soft ground truth (``ignore=``, VPR_Tutorial's GTsoft)
    ``ignore[q, r]`` and not ``gt[q, r]``: reference r is neither right nor wrong for q; it is
    treated as unranked (NaN) in every protocol and in R@K. (VPR_Tutorial sets these entries to
    ``min(S)`` instead; the two differ only for a query whose hard references are all unranked.)

Every curve starts at ``(recall 0, precision 1)`` with a sentinel threshold (``-inf`` for
``ratio``, ``+inf`` for the others) meaning "nothing accepted".

Unranked references (NaN)
    A NaN similarity means "not ranked" (e.g. an image without landmarks is excluded from
    matching, never scored as 0). A NaN reference is never a query's best or second best and never
    in its top k. A query whose row is entirely NaN is dropped like a query without ground truth
    (``ratio``, ``best_match``, R@K) and counted in the coverage warning. A ``ratio`` query with only
    one ranked reference has no second best: ``S2 := S1``, so ``r = 1`` (the least confident score,
    accepted only at the last threshold) -- the choice that cannot inflate the metrics. In
    ``multi_match`` a NaN pair is never accepted (a ground-truth NaN pair is an FN).

Ground-truth coverage
    Queries without any ground-truth reference are left out (``ratio``, ``best_match``, R@K). When
    no query is left, every metric raises a ValueError (a metric over nothing is not 0); when some
    are left out, the ``vpr_core`` logger warns with the count
    (:func:`~vpr_core.datasets.ground_truth.ground_truth_coverage`, re-exported here).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..datasets.ground_truth import ground_truth_coverage

__all__ = [
    "PROTOCOLS",
    "SATURATION_SHARE",
    "PRCurve",
    "auc_pr",
    "evaluate",
    "ground_truth_coverage",
    "metrics_table",
    "pr_curve",
    "recall_at_100_precision",
    "recall_at_k",
    "recall_rate_at_n",
    "saturation_notice",
]

logger = logging.getLogger("vpr_core")

PROTOCOLS = ("ratio", "best_match", "vpr_bench", "multi_match")


@dataclass
class PRCurve:
    """A precision-recall curve.

    Attributes:
        recall: ``(T + 1,)`` recall, non-decreasing, ``recall[0] = 0``.
        precision: ``(T + 1,)`` precision, ``precision[0] = 1``.
        thresholds: ``(T + 1,)`` the ``tau`` of each point (``thresholds[0]`` is the sentinel).
        protocol: protocol name.
        n_queries: queries (``ratio``/``best_match``/``vpr_bench``: kept queries) or pairs
            (``multi_match``) the curve is computed on.
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


def _check(similarity, ground_truth, ignore=None) -> tuple[np.ndarray, np.ndarray]:
    """Validate shapes and dtypes; NaN similarities are allowed (unranked), inf is not.

    ``ignore`` ``(Nq, Nr)`` bool (soft ground truth): entries ``ignore & ~gt`` become NaN.
    """
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
    if np.isinf(s).any():
        raise ValueError("similarity contains inf; use NaN to mark a pair that is not ranked")
    if ignore is not None:
        ig = np.asarray(ignore)
        if ig.shape != s.shape or not np.isin(ig, (0, 1)).all():
            raise ValueError(
                f"ignore must be a bool matrix of shape {s.shape} (soft ground "
                f"truth), got shape {ig.shape} dtype {ig.dtype}"
            )
        s = np.where(ig.astype(bool) & ~gt, np.nan, s)
    return s, gt


def _kept_queries(
    s: np.ndarray, gt: np.ndarray, warn: bool = True, need_gt: bool = True
) -> np.ndarray:
    """``(Nq,)`` bool: queries with ground truth (if ``need_gt``) and a ranked (non-NaN) reference.

    Raises a ValueError when no query has ground truth or none is left; logs one warning with
    the counts when some are left out (``warn``).
    """
    has_gt = gt.any(axis=1)
    ranked = ~np.isnan(s).all(axis=1) if s.shape[1] else np.zeros(s.shape[0], dtype=bool)
    keep = has_gt & ranked
    n_total, n_gt, n_kept = s.shape[0], int(has_gt.sum()), int(keep.sum())
    if n_gt == 0:
        raise ValueError(
            f"no query has a ground-truth reference (0 of {n_total} queries), so no metric can be "
            "computed. Check the ground-truth file (query/reference indices, 0- or 1-based) or "
            "widen the tolerance (e.g. load_dataset(..., tolerance=2))."
        )
    if n_kept == 0:
        raise ValueError(
            f"every query with ground truth ({n_gt} of {n_total}) has no ranked reference (all "
            "similarities NaN: images without landmarks). Check the landmark settings."
        )
    if not need_gt:  # vpr_bench: a query without ground truth is a negative, not left out
        keep = ranked
        if warn and not ranked.all():
            logger.warning(
                "metrics use %d of %d queries: %d have no ranked reference (all NaN)",
                int(ranked.sum()),
                n_total,
                int((~ranked).sum()),
            )
    elif warn and n_kept < n_total:
        logger.warning(
            "metrics use %d of %d queries: %d have no ground-truth reference%s",
            n_kept,
            n_total,
            n_total - n_gt,
            f", {n_gt - n_kept} have no ranked reference (all NaN)" if n_gt > n_kept else "",
        )
    return keep


def _best_two(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


def _query_scores(s: np.ndarray, gt: np.ndarray, protocol: str) -> tuple[np.ndarray, np.ndarray]:
    """Per-query score and correctness of the best match (``ratio`` / ``best_match``).

    Args:
        s: ``(n, Nr)`` similarities of kept queries; gt: ``(n, Nr)`` bool.
        protocol: ``"ratio"`` (score ``r = S2 / S1`` in ``[0, 1]``, accept ``r <= tau``) or
            ``"best_match"`` / ``"vpr_bench"`` (score ``S1``, accept ``S1 >= tau``).

    Returns:
        ``(score (n,), correct (n,) bool)``.
    """
    b1, s1, s2 = _best_two(s)
    correct = gt[np.arange(s.shape[0]), b1]
    if protocol != "ratio":
        return s1, correct
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(s1 > 0, s2 / np.where(s1 > 0, s1, 1.0), 1.0)
    return np.clip(r, 0.0, 1.0), correct


def _curve_from_scores(
    score: np.ndarray, correct: np.ndarray, ascending: bool, protocol: str, n_pos: int | None = None
) -> PRCurve:
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


def pr_curve(
    similarity: np.ndarray,
    ground_truth: np.ndarray,
    protocol: str = "ratio",
    warn: bool = True,
    ignore: np.ndarray | None = None,
) -> PRCurve:
    """Precision-recall curve of a similarity matrix (see the module docstring for protocols).

    Args:
        similarity: ``(Nq, Nr)`` float, higher = more similar; NaN = not ranked.
        ground_truth: ``(Nq, Nr)`` bool, True where reference r shows query q's place.
        protocol: ``"ratio"`` (paper), ``"best_match"`` (VPR_Tutorial), ``"vpr_bench"``
            (VPR-Bench) or ``"multi_match"``.
        warn: log a warning when queries are left out (no ground truth / nothing ranked).
        ignore: optional ``(Nq, Nr)`` bool soft ground truth: neither right nor wrong (NaN).

    Returns:
        :class:`PRCurve` starting at ``(R=0, P=1)``.

    Raises:
        ValueError: bad shapes or protocol, or no query with ground truth (no pair for
            ``multi_match``).
    """
    if protocol not in PROTOCOLS:
        raise ValueError(f"unknown protocol {protocol!r}; valid: {', '.join(PROTOCOLS)}")
    s, gt = _check(similarity, ground_truth, ignore)
    if protocol == "multi_match":
        if not gt.any():
            _kept_queries(s, gt)  # raises: no ground truth
        ranked = ~np.isnan(s).ravel()
        return _curve_from_scores(
            s.ravel()[ranked], gt.ravel()[ranked], False, protocol, n_pos=int(gt.sum())
        )
    if protocol == "ratio" and s.shape[1] < 2:
        raise ValueError(f"the ratio protocol needs at least 2 references, got {s.shape[1]}")
    if s.shape[1] < 1:
        raise ValueError("similarity has no reference column")
    keep = _kept_queries(s, gt, warn, need_gt=protocol != "vpr_bench")
    score, correct = _query_scores(s[keep], gt[keep], protocol)
    # recall denominators: ratio TP + FN (None), best_match all kept queries, vpr_bench sum(y)
    n_pos = {"ratio": None, "best_match": score.size, "vpr_bench": int(correct.sum())}[protocol]
    curve = _curve_from_scores(score, correct, protocol == "ratio", protocol, n_pos)
    if protocol == "vpr_bench" and n_pos:  # stop at the first point of full recall
        end = int(np.searchsorted(curve.tp, n_pos)) + 1
        curve = PRCurve(
            curve.recall[:end],
            curve.precision[:end],
            curve.thresholds[:end],
            protocol,
            curve.n_queries,
            curve.tp[:end],
            curve.fp[:end],
            curve.fn[:end],
        )
    return curve


def auc_pr(curve: PRCurve) -> float:
    """Area under the PR curve: trapezoid rule over recall (``np.trapezoid``)."""
    return float(np.trapezoid(curve.precision, curve.recall))


def recall_at_100_precision(curve: PRCurve) -> float:
    """Highest recall reached with precision exactly 1 (0 if none beyond the start point)."""
    ok = curve.precision >= 1.0
    return float(curve.recall[ok].max()) if ok.any() else 0.0


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


def recall_at_k(
    similarity: np.ndarray,
    ground_truth: np.ndarray,
    k: int,
    warn: bool = True,
    ignore: np.ndarray | None = None,
) -> float:
    """Fraction of queries (with ground truth) whose top-k references include a true one.

    Args:
        similarity: ``(Nq, Nr)``; NaN = not ranked (never in the top k).
        ground_truth: ``(Nq, Nr)`` bool.
        k: list length (>= 1; capped at Nr). Ties: stable by reference index.
        warn: log a warning when queries are left out.
        ignore: optional ``(Nq, Nr)`` bool soft ground truth (treated as unranked).

    Returns:
        Recall@k in ``[0, 1]``.

    Raises:
        ValueError: no query with ground truth (or none with a ranked reference).
    """
    if int(k) < 1:
        raise ValueError(f"k must be >= 1, got {k}")
    s, gt = _check(similarity, ground_truth, ignore)
    keep = _kept_queries(s, gt, warn)
    return float(_topk_hits(s[keep], gt[keep], k).mean())


def recall_rate_at_n(
    similarity: np.ndarray,
    ground_truth: np.ndarray,
    n_max: int = 20,
    ignore: np.ndarray | None = None,
) -> np.ndarray:
    """VPR-Bench's RecallRate@N for N = 1..n_max (its ``compute_RecallRateAtN``).

    The share of *all* queries whose top-N references contain a ground-truth one: VPR-Bench
    divides by every query, so a query without ground truth counts as a miss (a warning says
    how many); :func:`recall_at_k` leaves such queries out. Ties: stable by reference index
    (VPR-Bench's ``argpartition`` breaks them arbitrarily); NaN is never in the top N.
    VPR-Bench's own loop stops at N = 19 (``range(1, 20)``); the values agree up to there.

    Args:
        similarity: ``(Nq, Nr)``; NaN = not ranked.
        ground_truth: ``(Nq, Nr)`` bool.
        n_max: largest N (>= 1).
        ignore: optional ``(Nq, Nr)`` bool soft ground truth (treated as unranked).

    Returns:
        ``(n_max,)`` float, entry ``N - 1`` is RecallRate@N (non-decreasing).
    """
    if int(n_max) < 1:
        raise ValueError(f"n_max must be >= 1, got {n_max}")
    s, gt = _check(similarity, ground_truth, ignore)
    _kept_queries(s, gt, warn=False)  # raises without ground truth
    rank = _true_rank(s, gt)
    never = int((rank == np.iinfo(np.int64).max).sum())
    if never:
        logger.warning(
            "RecallRate@N divides by all %d queries as VPR-Bench does: %d of them "
            "have no ranked ground-truth reference and count as misses",
            s.shape[0],
            never,
        )
    return (rank[:, None] < np.arange(1, int(n_max) + 1)).mean(axis=0)


def evaluate(
    similarity: np.ndarray,
    ground_truth: np.ndarray,
    protocol: str = "ratio",
    ks: Sequence[int] = (1, 5),
    ignore: np.ndarray | None = None,
) -> dict[str, float]:
    """Table metrics ``{"auc", "r@100p", "r@K" for K in ks}`` (the keys of ``bootstrap_metrics``).

    ``auc`` and ``r@100p`` follow ``protocol``; R@K is protocol-free (:func:`recall_at_k`).
    ``ignore``: optional ``(Nq, Nr)`` bool soft ground truth (see the module docstring). Logs at
    most one coverage warning; raises a ValueError when no query has ground truth.
    """
    s, gt = _check(similarity, ground_truth, ignore)
    curve = pr_curve(s, gt, protocol)
    out = {"auc": auc_pr(curve), "r@100p": recall_at_100_precision(curve)}
    for i, k in enumerate(ks):
        out[f"r@{int(k)}"] = recall_at_k(
            s, gt, k, warn=i == 0 and protocol in ("multi_match", "vpr_bench")
        )
    return out


#: A ground truth where a random ranking's expected R@1 reaches this share saturates the metrics.
SATURATION_SHARE = 0.5


def saturation_notice(ground_truth: np.ndarray, intervals: Mapping | None = None) -> str | None:
    """Warn (:func:`~vpr_core.notices.notice`) when the ground truth makes the metrics meaningless.

    Two cases: the mean share of references that count as correct for a query (= the expected
    R@1 of a random ranking) is at least :data:`SATURATION_SHARE`; or every interval given is
    ``[1, 1]`` (no resample can tell methods apart).

    Args:
        ground_truth: ``bool (Nq, Nr)``.
        intervals: ``{"auc": (value, lo, hi), ...}`` as :func:`bootstrap_metrics` returns them.

    Returns:
        The message, or None when the metrics are not saturated.
    """
    from ..notices import notice

    gt = np.asarray(ground_truth, dtype=bool)
    rows = gt[gt.any(axis=1)]
    if rows.size == 0:
        return None
    share = float(rows.mean(axis=1).mean())
    if share >= SATURATION_SHARE:
        return notice(
            f"saturated ground truth: on average {share:.0%} of the {gt.shape[1]} "
            f"references count as correct for a query, so a random ranking gets R@1 "
            f"~{share:.2f} and AUC near 1; the metrics cannot rank methods. Use a smaller "
            "tolerance (e.g. tolerance=0) or a larger set.",
            stacklevel=4,
        )
    ivs = [v for v in (intervals or {}).values() if len(v) == 3 and np.isfinite(v[1])]
    if ivs and all(lo == 1.0 and hi == 1.0 for _, lo, hi in ivs):
        return notice(
            "saturated result: every metric is 1.0 with interval [1.0, 1.0]; this set "
            "cannot tell methods apart. Use a harder set, more places, or tolerance=0.",
            stacklevel=4,
        )
    return None


def metrics_table(results: Mapping[str, Mapping[str, float]]):
    """``pandas.DataFrame`` with one row per method name and one column per metric."""
    import pandas as pd

    df = pd.DataFrame.from_dict({k: dict(v) for k, v in results.items()}, orient="index")
    df.index.name = "method"
    return df
