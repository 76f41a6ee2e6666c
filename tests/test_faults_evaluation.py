"""Issue 11, item 2 (evaluation side) and item 4 (unranked images): one test per protection.

Each test fails if its protection is removed: ground truth that supports no metric is an error,
partial coverage is a logged warning with the count, NaN similarities are never ranked and never
scored as zeros, and a query image without landmarks counts as not retrieved (issue 25.3).
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from vpr_core.evaluation import (
    Evaluation,
    auc_pr,
    bootstrap_metrics,
    evaluate,
    ground_truth_coverage,
    paired_bootstrap,
    pr_curve,
    recall_at_100_precision,
    recall_at_k,
)
from vpr_core.evaluation.bootstrap import _per_query, _prepare, _resample_metrics


class _Records(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record):
        self.messages.append(record.getMessage())


@pytest.fixture
def warnings_log():
    """Warnings of the ``vpr_core`` logger (whatever handlers the library or CLI installed)."""
    log = logging.getLogger("vpr_core")
    h = _Records()
    old = log.level
    log.addHandler(h)
    log.setLevel(logging.WARNING)
    yield h.messages
    log.removeHandler(h)
    log.setLevel(old)


RNG = np.random.default_rng(0)
S = RNG.random((10, 6))


@pytest.mark.parametrize(
    "metric",
    [
        lambda s, gt: pr_curve(s, gt),
        lambda s, gt: pr_curve(s, gt, "best_match"),
        lambda s, gt: pr_curve(s, gt, "multi_match"),
        lambda s, gt: evaluate(s, gt),
        lambda s, gt: recall_at_k(s, gt, 1),
        lambda s, gt: bootstrap_metrics(s, gt, n=10),
        lambda s, gt: paired_bootstrap(s, s, gt, n=10),
    ],
    ids=["ratio", "best_match", "multi_match", "evaluate", "recall_at_k", "bootstrap", "paired"],
)
def test_all_false_ground_truth_is_an_error(metric):
    # before: every metric 0.0000 and exit code 0
    with pytest.raises(
        ValueError, match=r"no query has a ground-truth reference \(0 of 10.*tolerance"
    ):
        metric(S, np.zeros(S.shape, dtype=bool))


def test_partial_coverage_warns_once_with_the_count(warnings_log):
    gt = np.zeros(S.shape, dtype=bool)
    gt[0, 0] = gt[1, 1] = True  # a ground truth covering 2 of 10 queries
    m = evaluate(S, gt)
    assert len(warnings_log) == 1 and "2 of 10 queries" in warnings_log[0]
    assert "8 have no ground-truth reference" in warnings_log[0]
    assert pr_curve(S, gt).n_queries == 2 and 0 <= m["auc"] <= 1
    warnings_log.clear()
    bootstrap_metrics(S, gt, n=20)
    assert len(warnings_log) == 1 and "2 of 10" in warnings_log[0]


def test_full_coverage_does_not_warn(warnings_log):
    gt = np.eye(10, 6, dtype=bool)
    gt[6:, 0] = True
    evaluate(S, gt)
    assert warnings_log == []
    assert ground_truth_coverage(gt) == (10, 10)
    assert ground_truth_coverage(np.zeros((4, 3), bool)) == (0, 4)


def test_nan_reference_is_never_the_best_match():
    # reference 0 has no landmarks (NaN); numpy's argmax would pick the NaN as the best
    s = np.array([[np.nan, 0.5, 0.2], [np.nan, 0.2, 0.6]])
    gt = np.array([[1, 0, 0], [1, 0, 0]], dtype=bool)
    assert recall_at_k(s, gt, 1) == 0.0
    c = pr_curve(s, gt)
    assert c.tp.max() == 0 and c.fp[-1] == 2  # both best matches wrong, none "found" via NaN


def test_nan_reference_is_never_the_second_best():
    s = np.array([[0.8, np.nan, 0.4], [0.2, 0.9, 0.1]])
    gt = np.array([[1, 0, 0], [0, 1, 0]], dtype=bool)
    c = pr_curve(s, gt)
    np.testing.assert_allclose(c.thresholds[1:], [0.2 / 0.9, 0.5])  # S2 = 0.4, not NaN


def test_nan_is_never_in_the_top_k():
    s = np.array([[np.nan, 0.1, 0.2, 0.3], [0.1, 0.9, 0.3, 0.2]])
    gt = np.array([[1, 0, 0, 0], [0, 1, 0, 0]], dtype=bool)
    # the true reference of query 0 is unranked: a miss even with k = Nr
    assert recall_at_k(s, gt, 4) == 0.5
    assert evaluate(s, gt)["r@5"] == 0.5


def test_query_without_landmarks_counts_as_not_retrieved(warnings_log):
    # issue 25.3: 4 queries; query 3 has no landmarks (its row is NaN); of the others, one right
    nan = np.nan
    s = np.array(
        [[0.9, 0.1, 0.2, 0.3], [0.8, 0.1, 0.2, 0.3], [0.1, 0.9, 0.2, 0.4], [nan, nan, nan, nan]]
    )
    gt = np.eye(4, dtype=bool)
    m = evaluate(s, gt)
    assert m["r@1"] == 0.25  # 1/4, not 1/3: the query is a miss
    assert m["r@5"] == 0.75  # every ranked query has its reference in the top 4, query 3 not
    assert len(warnings_log) == 1 and "count as not retrieved" in warnings_log[0]
    c = pr_curve(s, gt)
    assert c.n_queries == 4
    np.testing.assert_array_equal(c.fn, [4, 3, 2, 1])  # query 3 is an FN at every threshold
    assert c.recall[-1] == 0.5  # TP 1 / (TP 1 + FN 1): never 1 while a query is not retrieved
    assert pr_curve(s, gt, "best_match").recall[-1] == 0.25  # TP / all 4 queries
    # vpr_bench: no top-1, a rejected negative: the curve is that of the other queries
    assert evaluate(s, gt, "vpr_bench")["auc"] == evaluate(s[:3], gt[:3], "vpr_bench")["auc"]
    b = bootstrap_metrics(s, gt, n=30)
    assert b["r@1"][0] == 0.25 and b["auc"][0] == auc_pr(c)
    # the paired difference is computed on the same 4 queries for both methods
    right = np.where(gt, 1.0, 0.1)
    d = paired_bootstrap(right, s, gt, n=30)
    assert d["r@1"][0] == pytest.approx(1.0 - 0.25)


def test_not_retrieved_resamples_equal_metrics_of_repeated_rows():
    rng = np.random.default_rng(3)
    s = rng.random((12, 6))
    gt = np.eye(12, 6, dtype=bool) | np.eye(12, 6, k=-6, dtype=bool)
    s[[2, 7]] = np.nan  # two query images without landmarks
    s[5, 2:] = np.nan  # a shortlist-like row: a few ranked references, still a query
    b = bootstrap_metrics(s, gt, n=20, seed=1)
    for protocol in ("ratio", "best_match"):
        pq = _per_query(_prepare(s, gt, Evaluation(protocol, n_bootstrap=0)), (1, 5))
        for seed in range(6):
            idx = np.random.default_rng(seed).integers(0, 12, 12)
            if np.isnan(s[idx]).all(axis=1).all():
                continue
            w = np.bincount(idx, minlength=12)[None].astype(float)
            got = {k: float(v[0]) for k, v in _resample_metrics(pq, w).items()}
            assert got == pytest.approx(evaluate(s[idx], gt[idx], protocol))
    assert b["r@1"][0] == recall_at_k(s, gt, 1)


def test_single_ranked_reference_cannot_look_confident():
    # query 0: only one ranked reference (right). S2 := S1 gives r = 1 (least confident);
    # S2 := 0 would give r = 0 and put it first, ahead of query 1's confident right match.
    s = np.array([[np.nan, 0.9, np.nan], [0.9, 0.1, 0.2], [0.3, 0.1, 0.25]])
    gt = np.array([[0, 1, 0], [1, 0, 0], [0, 1, 0]], dtype=bool)
    c = pr_curve(s, gt)
    np.testing.assert_allclose(c.thresholds[1:], [0.2 / 0.9, 0.25 / 0.3, 1.0])
    assert recall_at_100_precision(c) == pytest.approx(1 / 3)


def test_multi_match_nan_pair_is_never_accepted():
    s = np.array([[np.nan, 0.2], [0.7, np.nan]])
    gt = np.array([[1, 0], [1, 0]], dtype=bool)
    c = pr_curve(s, gt, "multi_match")
    assert c.tp[-1] == 1 and c.fn[-1] == 1  # the NaN ground-truth pair is missed
    assert c.tp[-1] + c.fp[-1] == 2  # two ranked pairs decided, the NaNs never accepted


def test_inf_is_refused_with_the_fix():
    s = S.copy()
    s[0, 0] = -np.inf
    with pytest.raises(ValueError, match="use NaN"):
        evaluate(s, np.eye(10, 6, dtype=bool))
