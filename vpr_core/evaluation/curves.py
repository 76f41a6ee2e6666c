"""Precision-recall curves and the table metrics (AUC, R@100P, R@K); protocols and NaN = not
ranked: docs/DEFINITIONS.md; chance levels: :mod:`vpr_core.evaluation.chance`."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from ..checks import check_int
from ..datasets.ground_truth import check_ground_truth, ground_truth_coverage
from .ranks import query_scores, ranked, true_rank
from .spec import PROTOCOLS, Evaluation, as_evaluation

__all__ = [
    "PROTOCOLS",
    "PRCurve",
    "Scored",
    "auc_pr",
    "evaluate",
    "ground_truth_coverage",
    "metrics_table",
    "pr_curve",
    "queries_with_ground_truth",
    "recall_at_100_precision",
    "recall_at_k",
    "recall_rate_at_n",
]

logger = logging.getLogger("vpr_core")


@dataclass
class PRCurve:
    """A precision-recall curve.

    Attributes:
        recall: ``(T + 1,)`` recall, non-decreasing, ``recall[0] = 0``.
        precision: ``(T + 1,)`` precision, ``precision[0] = 1``.
        thresholds: ``(T + 1,)`` the ``tau`` of each point (``thresholds[0]`` is the sentinel).
        protocol: protocol name.
        n_queries: queries the curve counts (``ratio``/``best_match``: those with ground truth,
            not-retrieved ones included; ``vpr_bench``: those with a ranked reference) or pairs
            (``multi_match``).
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

    @classmethod
    def from_query_scores(
        cls, score: np.ndarray, correct: np.ndarray, evaluation: Evaluation, n_missed: int
    ) -> PRCurve:
        """The curve of per-query decisions (``ratio``, ``best_match``, ``vpr_bench``), from
        parsed input.

        Args:
            score, correct: ``(n,)`` score and top-1 correctness of the queries with a ranked
                reference (:func:`~.ranks.query_scores`); evaluation: the protocol;
                n_missed: counted queries that retrieved nothing (never accepted).
        """
        protocol = evaluation.protocol
        # recall denominators: ratio TP + FN (None), best_match all counted queries, vpr_bench
        # sum(y)
        n_pos = {
            "ratio": None,
            "best_match": score.size + n_missed,
            "vpr_bench": int(correct.sum()),
        }[protocol]
        curve = _curve_from_scores(score, correct, protocol == "ratio", n_pos, n_missed)
        curve.protocol = protocol
        if protocol == "vpr_bench" and n_pos:  # stop at the first point of full recall
            end = int(np.searchsorted(curve.tp, n_pos)) + 1
            for name in ("recall", "precision", "thresholds", "tp", "fp", "fn"):
                setattr(curve, name, getattr(curve, name)[:end])
        return curve


def _check(similarity, ground_truth, ignore=None) -> tuple[np.ndarray, np.ndarray]:
    """Validate shapes and dtypes; NaN similarities are allowed (unranked), inf is not.

    ``ignore`` ``(Nq, Nr)`` bool (soft ground truth): entries ``ignore & ~gt`` become NaN.
    """
    s = np.asarray(similarity, dtype=np.float64)
    if s.ndim != 2:
        raise ValueError(f"similarity must be a (Nq, Nr) matrix, got shape {s.shape}")
    gt = check_ground_truth(ground_truth, s.shape, f"(ground_truth=) of the {s.shape} similarity")
    if np.isinf(s).any():
        raise ValueError("similarity contains inf; use NaN to mark a pair that is not ranked")
    if ignore is not None:
        ig = check_ground_truth(ignore, s.shape, "(ignore=, the soft ground truth)")
        s = np.where(ig & ~gt, np.nan, s)
    return s, gt


def queries_with_ground_truth(gt: np.ndarray) -> np.ndarray:
    """``(Nq,)`` bool: the queries of a parsed ``bool (Nq, Nr)`` ground truth that have a true
    reference; refuses a ground truth where none has (no metric can be computed)."""
    has_gt = np.asarray(gt.any(axis=1))
    if not has_gt.any():
        raise ValueError(
            f"no query has a ground-truth reference (0 of {gt.shape[0]} queries), so no metric "
            "can be computed. Check the ground-truth file (query/reference indices, 0- or "
            "1-based) or widen the tolerance (e.g. load_dataset(..., tolerance=2))."
        )
    return has_gt


def _kept_queries(
    s: np.ndarray, gt: np.ndarray, warn: bool = True, need_gt: bool = True
) -> np.ndarray:
    """``(Nq,)`` bool: the queries the metrics count.

    ``need_gt``: the queries with ground truth (an all-NaN row among them counts as not
    retrieved); else (``vpr_bench``) the queries with a ranked reference. Raises a ValueError
    when no query has ground truth or none of them has a ranked reference; logs one warning
    with the counts when queries are left out or not retrieved (``warn``).
    """
    has_gt, any_ranked = queries_with_ground_truth(gt), ranked(s)
    n_total, n_gt = s.shape[0], int(has_gt.sum())
    n_missed = int((has_gt & ~any_ranked).sum())
    if n_missed == n_gt:
        raise ValueError(
            f"every query with ground truth ({n_gt} of {n_total}) has no ranked reference (all "
            "similarities NaN: images without landmarks). Check the landmark settings."
        )
    keep = has_gt if need_gt else any_ranked
    if warn and (n_missed or not keep.all()):
        parts = []
        if need_gt and n_gt < n_total:
            parts.append(f"{n_total - n_gt} have no ground-truth reference (left out)")
        if not need_gt and not any_ranked.all():
            parts.append(f"{int((~any_ranked).sum())} have no ranked reference (left out)")
        if n_missed:
            parts.append(
                f"{n_missed} with ground truth have no ranked reference (all NaN) and count as "
                "not retrieved"
            )
        logger.warning(
            "metrics count %d of %d queries: %s", int(keep.sum()), n_total, "; ".join(parts)
        )
    return keep


def _curve_from_scores(
    score: np.ndarray,
    correct: np.ndarray,
    ascending: bool,
    n_pos: int | None = None,
    n_missed: int = 0,
) -> PRCurve:
    """Sweep a threshold over per-decision scores (accept ``score <= tau`` if ascending); the
    caller names the curve's protocol.

    ``n_pos``: the recall denominator (None: ``TP + FN``, FN = rejected decisions plus
    ``n_missed``, the decisions never offered: queries that retrieved nothing).
    """
    n = score.shape[0]
    order = np.argsort(score if ascending else -score, kind="stable")
    sc, ok = score[order], correct[order]
    tp_cum = np.cumsum(ok)
    # last index of each run of equal scores: equal scores are accepted together
    last = np.flatnonzero(np.r_[sc[1:] != sc[:-1], True]) if n else np.zeros(0, dtype=int)
    tp = tp_cum[last].astype(np.int64)
    acc = last + 1
    fp = acc - tp
    fn = (n + n_missed - acc) if n_pos is None else (n_pos - tp)
    fn = np.asarray(fn, dtype=np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        recall = np.where(tp + fn > 0, tp / np.maximum(tp + fn, 1), 0.0)
        precision = np.where(acc > 0, tp / np.maximum(acc, 1), 1.0)
    sentinel = -np.inf if ascending else np.inf
    fn0 = n + n_missed if n_pos is None else n_pos
    return PRCurve(
        recall=np.r_[0.0, recall],
        precision=np.r_[1.0, precision],
        thresholds=np.r_[sentinel, sc[last]],
        n_queries=int(n + n_missed),
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
    return Scored.parse(
        similarity, ground_truth, Evaluation(protocol, n_bootstrap=0), ignore, warn
    ).curve()


class Scored(NamedTuple):
    """Checked inputs of a metric: ``(Nq, Nr)`` similarities and ground truth, the ``(Nq,)``
    queries the protocol counts (``multi_match`` counts pairs: every query) and the
    :class:`~vpr_core.evaluation.Evaluation`. Made by :meth:`parse` (the one check); its
    methods trust it."""

    s: np.ndarray
    gt: np.ndarray
    keep: np.ndarray
    evaluation: Evaluation

    @property
    def protocol(self) -> str:
        return self.evaluation.protocol

    @classmethod
    def parse(
        cls,
        similarity: Any,
        ground_truth: Any,
        evaluation: Evaluation,
        ignore: Any = None,
        warn: bool = True,
    ) -> Scored:
        """The checked inputs of ``evaluation``'s curve (refusals: :func:`pr_curve`)."""
        protocol = evaluation.protocol
        s, gt = _check(similarity, ground_truth, ignore)
        if protocol == "multi_match":
            queries_with_ground_truth(gt)  # raises without ground truth
            return cls(s, gt, np.ones(s.shape[0], dtype=bool), evaluation)
        if protocol == "ratio" and s.shape[1] < 2:
            raise ValueError(f"the ratio protocol needs at least 2 references, got {s.shape[1]}")
        if s.shape[1] < 1:
            raise ValueError("similarity has no reference column")
        keep = _kept_queries(s, gt, warn, need_gt=protocol != "vpr_bench")
        return cls(s, gt, keep, evaluation)

    def curve(self) -> PRCurve:
        """:func:`pr_curve` of these inputs."""
        s, gt, keep, evaluation = self
        if self.protocol == "multi_match":
            counted = ~np.isnan(s).ravel()
            curve = _curve_from_scores(
                s.ravel()[counted], gt.ravel()[counted], False, int(gt.sum())
            )
            curve.protocol = self.protocol
            return curve
        rows = keep & ranked(s)
        score, correct = query_scores(s[rows], gt[rows], self.protocol == "ratio")
        return PRCurve.from_query_scores(score, correct, evaluation, int(keep.sum() - rows.sum()))

    def metrics(self, ks: Sequence[int], warn: bool) -> dict[str, float]:
        """:func:`evaluate` of these inputs and checked ``ks``; R@K counts the queries with
        ground truth (its own coverage warning only where the curve counted others:
        ``multi_match``, ``vpr_bench``)."""
        s, gt = self.s, self.gt
        curve = self.curve()
        out = {"auc": auc_pr(curve), "r@100p": recall_at_100_precision(curve)}
        with_gt = _kept_queries(s, gt, warn and self.protocol in ("multi_match", "vpr_bench"))
        for k in ks:
            out[f"r@{k}"] = _recall(s, gt, with_gt, k)
        return out


def auc_pr(curve: PRCurve) -> float:
    """Area under the PR curve: trapezoid rule over recall (``np.trapezoid``)."""
    return float(np.trapezoid(curve.precision, curve.recall))


def recall_at_100_precision(curve: PRCurve) -> float:
    """Highest recall reached with precision exactly 1 (0 if none beyond the start point)."""
    ok = curve.precision >= 1.0
    return float(curve.recall[ok].max()) if ok.any() else 0.0


def recall_at_k(
    similarity: np.ndarray,
    ground_truth: np.ndarray,
    k: int,
    warn: bool = True,
    ignore: np.ndarray | None = None,
) -> float:
    """Fraction of queries (with ground truth) whose top-k references include a true one (a
    query that retrieved nothing, its row all NaN, is a miss).

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
    k = check_int(k, "k", 1)
    s, gt = _check(similarity, ground_truth, ignore)
    return _recall(s, gt, _kept_queries(s, gt, warn), k)


def _recall(s: np.ndarray, gt: np.ndarray, keep: np.ndarray, k: int) -> float:
    """:func:`recall_at_k` of checked inputs over the queries ``keep``."""
    return float((true_rank(s[keep], gt[keep]) < k).mean())


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
    n_max = check_int(n_max, "n_max", 1)
    s, gt = _check(similarity, ground_truth, ignore)
    _kept_queries(s, gt, warn=False)  # raises without ground truth
    rank = true_rank(s, gt)
    never = int((rank == np.iinfo(np.int64).max).sum())
    if never:
        logger.warning(
            "RecallRate@N divides by all %d queries as VPR-Bench does: %d of them "
            "have no ranked ground-truth reference and count as misses",
            s.shape[0],
            never,
        )
    return (rank[:, None] < np.arange(1, n_max + 1)).mean(axis=0)


def evaluate(
    similarity: np.ndarray,
    ground_truth: np.ndarray,
    evaluation: Evaluation | str = "ratio",
    ks: Sequence[int] = (1, 5),
    ignore: np.ndarray | None = None,
) -> dict[str, float]:
    """Table metrics ``{"auc", "r@100p", "r@K" for K in ks}`` (the keys of ``bootstrap_metrics``).

    ``auc`` and ``r@100p`` follow the protocol (``evaluation``: a protocol name or an
    :class:`~vpr_core.evaluation.Evaluation`, e.g. a run's); R@K is protocol-free
    (:func:`recall_at_k`).
    ``ignore``: optional ``(Nq, Nr)`` bool soft ground truth (see the module docstring). Logs at
    most one coverage warning; raises a ValueError when no query has ground truth.
    """
    evaluation = as_evaluation(evaluation)
    ks = tuple(check_int(k, "k", 1) for k in ks)
    return Scored.parse(similarity, ground_truth, evaluation, ignore).metrics(ks, warn=True)


def metrics_table(results: Mapping[str, Mapping[str, float]]):
    """``pandas.DataFrame`` with one row per method name and one column per metric."""
    df = pd.DataFrame.from_dict({k: dict(v) for k, v in results.items()}, orient="index")
    df.index.name = "method"
    return df
