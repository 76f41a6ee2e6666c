"""Issue 19 items 1 and 4, issue 17 item 7: vpr_bench / best_match protocols against
independent implementations (and scikit-learn when installed), RecallRate@N, soft ground
truth, no-resample intervals, and the queries a verdict needs."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from vpr_core.evaluation import (
    auc_pr,
    bootstrap_metrics,
    difference_verdict,
    evaluate,
    format_interval,
    needs_text,
    paired_bootstrap,
    pr_curve,
    recall_at_100_precision,
    recall_rate_at_n,
)
from vpr_core.evaluation.bootstrap import Difference


def _matrix(seed, nq=60, nr=40, signal=0.5, no_gt=3, rounded=True):
    rng = np.random.default_rng(seed)
    s = rng.random((nq, nr))
    gt = np.zeros((nq, nr), bool)
    gt[np.arange(nq), np.arange(nq) % nr] = True
    s[gt] += signal * rng.random(nq)
    gt[:no_gt] = False  # queries without ground truth: VPR-Bench's negatives
    return (s.round(2) if rounded else s), gt


def _vprbench_auc_reference(s, gt):
    """VPR-Bench's compute_matches + old sklearn precision_recall_curve + auc, by loops."""
    top = s.argmax(axis=1)
    score = s.max(axis=1)
    y = np.array([gt[q, top[q]] for q in range(len(top))], dtype=int)
    thresholds = sorted(set(score.tolist()), reverse=True)
    precision, recall = [], []
    for t in thresholds:
        acc = score >= t
        tp = int((y * acc).sum())
        precision.append(tp / int(acc.sum()))
        recall.append(tp / y.sum())
        if tp == y.sum():  # old sklearn stopped at full recall
            break
    x = [0.0] + recall
    p = [1.0] + precision
    return sum((x[i + 1] - x[i]) * (p[i + 1] + p[i]) / 2 for i in range(len(x) - 1))


@pytest.mark.parametrize("seed", range(4))
def test_vpr_bench_auc_matches_independent_reading(seed):
    s, gt = _matrix(seed, rounded=seed % 2 == 0)
    c = pr_curve(s, gt, "vpr_bench")
    assert c.n_queries == 60  # queries without ground truth kept as negatives
    assert c.recall[-1] == 1.0 and (c.recall[:-1] < 1).all()  # truncated at full recall
    assert auc_pr(c) == pytest.approx(_vprbench_auc_reference(s, gt), abs=1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_vpr_bench_auc_matches_sklearn(seed):
    metrics = pytest.importorskip("sklearn.metrics")
    s, gt = _matrix(seed, rounded=seed % 2 == 0)
    y = gt[np.arange(60), s.argmax(axis=1)].astype(int)
    prec, rec, _ = metrics.precision_recall_curve(y, s.max(axis=1))
    # sklearn >= 1.1 no longer stops at full recall: cut where recall first reaches 1 (from
    # the high-threshold end, which is the end of sklearn's arrays)
    first_full = np.flatnonzero(rec[::-1] == 1.0)[0]
    keep = len(rec) - 1 - first_full
    prec, rec = prec[keep:], rec[keep:]
    c = pr_curve(s, gt, "vpr_bench")
    assert auc_pr(c) == pytest.approx(metrics.auc(rec, prec), abs=1e-9)
    np.testing.assert_allclose(c.recall, rec[::-1])
    np.testing.assert_allclose(c.precision, prec[::-1])


def test_vpr_bench_nothing_correct_and_bootstrap():
    s, gt = _matrix(0, nq=20, nr=20)
    gt_wrong = np.roll(gt, 7, axis=1)
    s2 = np.where(gt_wrong, -1.0, s)
    s2[np.arange(20), np.arange(20)] = 5.0  # top-1 always the diagonal
    gt2 = np.zeros_like(gt)
    gt2[5:, 0] = True
    assert auc_pr(pr_curve(s2, gt2, "vpr_bench")) == 0.0
    b = bootstrap_metrics(s, gt, n=100, protocol="vpr_bench")
    assert b["auc"][0] == auc_pr(pr_curve(s, gt, "vpr_bench"))
    assert b["auc"][1] <= b["auc"][0] <= b["auc"][2]


def test_best_match_is_vpr_tutorial():
    s, gt = _matrix(1, no_gt=0)

    def tutorial(s, gt):  # createPR(matching="single") on every distinct S1, by loops
        score, ok = s.max(axis=1), gt[np.arange(len(s)), s.argmax(axis=1)]
        r, p = [0.0], [1.0]
        for t in sorted(set(score.tolist()), reverse=True):
            acc = score >= t
            r.append((ok & acc).sum() / gt.any(axis=1).sum())
            p.append((ok & acc).sum() / acc.sum())
        return np.array(r), np.array(p)

    r, p = tutorial(s, gt)
    c = pr_curve(s, gt, "best_match")
    np.testing.assert_allclose(c.recall, r)
    np.testing.assert_allclose(c.precision, p)
    assert auc_pr(c) == pytest.approx(np.trapezoid(p, r))
    assert recall_at_100_precision(c) == r[p == 1].max()
    assert set(evaluate(s, gt, "best_match", ks=(1, 5, 10))) == {
        "auc",
        "r@100p",
        "r@1",
        "r@5",
        "r@10",
    }


def test_soft_ground_truth_is_neither_right_nor_wrong():
    s = np.array([[0.9, 0.8, 0.1], [0.2, 0.9, 0.3]])
    gt = np.array([[0, 1, 0], [0, 1, 0]], dtype=bool)
    soft = np.array([[1, 1, 0], [0, 1, 0]], dtype=bool)  # ref 0 a soft positive of query 0
    assert evaluate(s, gt, ks=(1,))["r@1"] == 0.5
    m = evaluate(s, gt, "best_match", ks=(1,), ignore=soft)
    assert m["r@1"] == 1.0 and m["auc"] == 1.0
    assert bootstrap_metrics(s, gt, n=20, ignore=soft, ks=(1,))["r@1"][0] == 1.0
    with pytest.raises(ValueError, match="ignore"):
        evaluate(s, gt, ignore=soft[:, :2])


def test_recall_rate_at_n_is_vpr_benchs():
    s, gt = _matrix(2, no_gt=2)
    got = recall_rate_at_n(s, gt, n_max=20)
    assert got.shape == (20,) and (np.diff(got) >= 0).all()
    for n in (1, 5, 19):  # VPR-Bench's compute_RecallRateAtN: over all queries
        want = np.mean(
            [
                bool(set(np.argsort(-s[q], kind="stable")[:n]) & set(np.flatnonzero(gt[q])))
                for q in range(len(s))
            ]
        )
        assert got[n - 1] == pytest.approx(want)


def test_no_resamples_no_interval_no_verdict():
    s, gt = _matrix(4, no_gt=0)
    b = bootstrap_metrics(s, gt, n=0)
    assert all(np.isnan(lo) and np.isnan(hi) for _, lo, hi in b.values())
    d = paired_bootstrap(s, s[:, ::-1], gt, n=0)
    for delta, lo, hi, p in d.values():
        assert np.isfinite(delta) and np.isnan(lo) and np.isnan(hi) and np.isnan(p)
        assert difference_verdict(lo, hi) == "not computed"
    assert format_interval(0.8123, np.nan, np.nan) == "0.812 [not computed]"
    assert (
        difference_verdict(0.1, 0.2) == "higher"
        and difference_verdict(-0.2, -0.1) == "lower"
        and difference_verdict(-0.1, 0.2) == "inconclusive"
        and difference_verdict(0.0, 0.2) == "inconclusive"  # touching 0 is not excluding it
    )


def test_queries_needed_and_difference_tuple():
    s, gt = _matrix(5, nq=200, nr=200, no_gt=0, rounded=False)
    s2 = s + np.random.default_rng(9).normal(0, 0.05, s.shape)
    d = paired_bootstrap(s, s2, gt, n=300, seed=1)
    delta, lo, hi, p = d["auc"]  # still a 4-tuple
    assert lo <= hi and 0 < p <= 1
    x = d["auc"]
    assert isinstance(x, Difference) and x.se > 0
    assert x.queries_needed == max(1, math.ceil(200 * (1.96 * x.se / abs(delta)) ** 2))
    assert pickle.loads(pickle.dumps(x)).queries_needed == x.queries_needed
    same = paired_bootstrap(s, s.copy(), gt, n=50)["auc"]
    assert same == (0.0, 0.0, 0.0, 1.0) and same.queries_needed == math.inf
    assert needs_text(1234) == "needs ~1,200 queries" and needs_text(57) == "needs ~57 queries"
    assert (
        needs_text(2e5)
        == needs_text(math.inf)
        == ("needs over 100,000 queries: not decidable on any realistic set")
    )
    assert needs_text(float("nan")) == "not computed"
