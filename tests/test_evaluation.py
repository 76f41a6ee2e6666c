"""Known-answer tests of vpr_core.evaluation (PR curves, AUC, R@100P, R@K, bootstrap intervals)."""

from __future__ import annotations

import numpy as np
import pytest

from vpr_core.evaluation import (
    N_BOOTSTRAP,
    Evaluation,
    PRCurve,
    auc_pr,
    bootstrap_metrics,
    chance,
    evaluate,
    format_interval,
    ground_truth_coverage,
    paired_bootstrap,
    pr_curve,
    recall_at_100_precision,
    recall_at_k,
    recall_rate_at_n,
)
from vpr_core.evaluation.bootstrap import _per_query, _prepare, _resample_metrics, bootstrap_columns
from vpr_core.evaluation.curves import metrics_table

# 5 queries x 3 references.
S = np.array(
    [
        [0.9, 0.3, 0.1],  # q0 gt b0: b1=0, r = .3/.9 = 1/3, correct
        [0.2, 0.8, 0.6],  # q1 gt b1: b1=1, r = .6/.8 = .75, correct
        [0.5, 0.1, 0.4],  # q2 gt b2: b1=0, r = .4/.5 = .8, wrong
        [0.0, 0.0, 0.0],  # q3 gt b2: S1 <= 0 -> r = 1; b1 = 0 (tie, lowest), wrong
        [1.0, 0.0, 0.0],  # q4 has no ground truth: dropped
    ]
)
GT = np.zeros((5, 3), dtype=bool)
GT[0, 0] = GT[1, 1] = GT[2, 2] = GT[3, 2] = True
# sorted r: 1/3 TP, .75 TP, .8 FP, 1 FP  (4 kept queries)
#   tau=1/3: TP1 FP0 FN3 -> R 1/4, P 1
#   tau=.75: TP2 FP0 FN2 -> R 1/2, P 1
#   tau=.8 : TP2 FP1 FN1 -> R 2/3, P 2/3   (the FP query is not an FN)
#   tau=1  : TP2 FP2 FN0 -> R 1,   P 1/2
R_WANT = [0, 1 / 4, 1 / 2, 2 / 3, 1]
P_WANT = [1, 1, 1, 2 / 3, 1 / 2]


def test_ratio_curve_known_answer():
    c = pr_curve(S, GT)
    assert isinstance(c, PRCurve) and c.protocol == "ratio" and c.n_queries == 4
    np.testing.assert_allclose(c.recall, R_WANT)
    np.testing.assert_allclose(c.precision, P_WANT)
    np.testing.assert_allclose(c.thresholds, [-np.inf, 1 / 3, 0.75, 0.8, 1.0])
    np.testing.assert_array_equal(c.tp, [0, 1, 2, 2, 2])
    np.testing.assert_array_equal(c.fp, [0, 0, 0, 1, 2])
    np.testing.assert_array_equal(c.fn, [4, 3, 2, 1, 0])
    recall, precision, _thresholds = c  # unpacks like a tuple
    assert recall[0] == 0 and precision[0] == 1


def test_metrics_known_answer():
    c = pr_curve(S, GT)
    # trapezoids: .25*1 + .25*1 + (1/6)*(1 + 2/3)/2 + (1/3)*(2/3 + 1/2)/2 = 5/6
    assert auc_pr(c) == pytest.approx(5 / 6)
    assert recall_at_100_precision(c) == pytest.approx(0.5)
    # R@1: q0, q1 right; q2 top1 b0 wrong; q3 ties -> b0 wrong  -> 2/4
    assert recall_at_k(S, GT, 1) == pytest.approx(0.5)
    # R@2: q2 top2 {b0, b2} right; q3 top2 {b0, b1} (stable ties) wrong -> 3/4
    assert recall_at_k(S, GT, 2) == pytest.approx(0.75)
    assert recall_at_k(S, GT, 3) == recall_at_k(S, GT, 99) == 1.0
    m = evaluate(S, GT)
    assert set(m) == {"auc", "r@100p", "r@1", "r@5"}
    assert m["auc"] == pytest.approx(5 / 6) and m["r@5"] == 1.0
    assert list(evaluate(S, GT, ks=(1, 2, 3))) == ["auc", "r@100p", "r@1", "r@2", "r@3"]


def test_ratio_ties_accepted_together_and_clipping():
    s = np.array([[0.8, 0.4], [0.6, 0.3], [0.5, -0.2], [-0.1, -0.5]])
    gt = np.array([[1, 0], [0, 1], [1, 0], [1, 0]], dtype=bool)
    # r: .5 TP, .5 FP (tied: accepted together), -.4 -> clipped 0 TP, S1 = -.1 <= 0 -> 1 TP
    c = pr_curve(s, gt)
    np.testing.assert_allclose(c.thresholds, [-np.inf, 0.0, 0.5, 1.0])
    np.testing.assert_array_equal(c.tp, [0, 1, 2, 3])
    np.testing.assert_array_equal(c.fp, [0, 0, 1, 1])
    np.testing.assert_allclose(c.recall, [0, 1 / 4, 2 / 3, 1])
    np.testing.assert_allclose(c.precision, [1, 1, 2 / 3, 3 / 4])


def test_nothing_correct():
    s = np.array([[0.9, 0.1], [0.1, 0.9]])
    gt = np.array([[0, 1], [1, 0]], dtype=bool)  # best always wrong
    c = pr_curve(s, gt)
    np.testing.assert_allclose(c.recall, [0, 0])  # TP + FN = 0 -> recall 0
    np.testing.assert_allclose(c.precision, [1, 0])
    assert auc_pr(c) == 0.0 and recall_at_100_precision(c) == 0.0
    assert ground_truth_coverage(gt) == (2, 2)


def test_best_match_protocol():
    c = pr_curve(S, GT, protocol="best_match")
    # S1: q0 .9 TP, q1 .8 TP, q2 .5 FP, q3 0 FP; VPR_Tutorial: recall = TP / 4 kept queries
    np.testing.assert_allclose(c.thresholds, [np.inf, 0.9, 0.8, 0.5, 0.0])
    np.testing.assert_allclose(c.recall, [0, 1 / 4, 1 / 2, 1 / 2, 1 / 2])
    np.testing.assert_allclose(c.precision, P_WANT)
    np.testing.assert_array_equal(c.fn, [4, 3, 2, 2, 2])


def test_multi_match_protocol():
    s = np.array([[0.9, 0.5], [0.7, 0.2]])
    gt = np.array([[1, 1], [0, 0]], dtype=bool)
    # pairs by score: .9 TP, .7 FP, .5 TP, .2 FP; 2 gt pairs
    c = pr_curve(s, gt, protocol="multi_match")
    np.testing.assert_allclose(c.recall, [0, 0.5, 0.5, 1, 1])
    np.testing.assert_allclose(c.precision, [1, 1, 0.5, 2 / 3, 0.5])


def test_bad_inputs():
    with pytest.raises(ValueError, match="valid: ratio, best_match, vpr_bench, multi_match"):
        pr_curve(S, GT, protocol="nope")
    with pytest.raises(ValueError, match="shape"):
        pr_curve(S, GT[:4])
    with pytest.raises(ValueError, match=r"\(Nq, Nr\)"):
        pr_curve(S.ravel(), GT.ravel())
    with pytest.raises(ValueError, match="at least 2 references"):
        pr_curve(S[:, :1], GT[:, :1])
    with pytest.raises(ValueError, match=r"ground truth \(ground_truth=\).*bools or 0/1"):
        pr_curve(S, GT * 2)
    with pytest.raises(ValueError, match="no ranked reference"):
        pr_curve(np.full((2, 2), np.nan), np.eye(2, dtype=bool))
    with pytest.raises(ValueError, match="inf"):
        pr_curve(np.array([[np.inf, 0.0], [0.0, 1.0]]), np.eye(2, dtype=bool))
    with pytest.raises(ValueError, match="k must be a positive integer, got 0"):
        recall_at_k(S, GT, 0)
    with pytest.raises(ValueError, match="k must be a positive integer, got 0"):
        evaluate(S, GT, ks=(1, 0))  # one rule, one wording for every k
    with pytest.raises(ValueError, match="n_max must be a positive integer, got 0"):
        recall_rate_at_n(S, GT, 0)


def test_metrics_table_and_perfect_matrix():
    rng = np.random.default_rng(0)
    s = rng.uniform(0, 0.5, (20, 20)) + np.eye(20)
    perfect = evaluate(s, np.eye(20, dtype=bool))
    assert perfect == {"auc": 1.0, "r@100p": 1.0, "r@1": 1.0, "r@5": 1.0}
    df = metrics_table({"dense": perfect, "classical": evaluate(S, GT)})
    assert list(df.index) == ["dense", "classical"]
    assert list(df.columns) == ["auc", "r@100p", "r@1", "r@5"]
    assert df.loc["classical", "auc"] == pytest.approx(5 / 6)


# ------------------------------------------------------------------------------------------
# bootstrap intervals
# ------------------------------------------------------------------------------------------


def _noisy(rng, n, signal, nr=None):
    """A similarity matrix whose diagonal (the ground truth) stands out by ``signal``."""
    nr = nr or n
    s = rng.random((n, nr))
    s[np.arange(n), np.arange(n) % nr] += signal * rng.random(n)
    return s


def test_bootstrap_point_values_are_the_table_metrics():
    rng = np.random.default_rng(1)
    s = _noisy(rng, 80, 0.6).round(2)  # rounded: ties in the scores
    gt = np.eye(80, dtype=bool)
    gt[3] = False  # a query without ground truth (dropped)
    s[5] = np.nan  # a query with nothing ranked (not retrieved: a miss)
    s[7, 10:] = np.nan  # a query with few ranked references
    b = bootstrap_metrics(s, gt, n=200, seed=0, ks=(1, 5, 10))
    c = pr_curve(s, gt)
    assert b["auc"][0] == auc_pr(c)
    assert b["r@100p"][0] == recall_at_100_precision(c)
    for k in (1, 5, 10):
        assert b[f"r@{k}"][0] == recall_at_k(s, gt, k)
    for value, lo, hi in b.values():
        assert lo <= value <= hi and lo < hi
    bm = bootstrap_metrics(s, gt, n=50, protocol="best_match")
    assert bm["auc"][0] == auc_pr(pr_curve(s, gt, "best_match"))


def test_bootstrap_resample_equals_metrics_of_repeated_rows():
    rng = np.random.default_rng(2)
    s = _noisy(rng, 60, 0.5).round(2)
    gt = np.eye(60, dtype=bool)
    s[4] = np.nan
    s[9, 1:] = np.nan  # one ranked reference: S2 := S1
    gt[20] = False  # vpr_bench resamples it too (a negative); the others never see it
    for protocol in ("ratio", "best_match", "vpr_bench"):
        rows = np.ones(60, bool) if protocol == "vpr_bench" else gt.any(axis=1)
        pq = _per_query(_prepare(s, gt, Evaluation(protocol, n_bootstrap=0)), (1, 5))
        n = int(rows.sum())
        for seed in range(5):
            idx = np.flatnonzero(rows)[np.random.default_rng(seed).integers(0, n, n)]
            w = np.bincount(np.searchsorted(np.flatnonzero(rows), idx), minlength=n)[None]
            got = {k: float(v[0]) for k, v in _resample_metrics(pq, w.astype(float)).items()}
            want = evaluate(s[idx], gt[idx], protocol)
            assert got == pytest.approx(want)
            for key in want:
                assert got[key] == pytest.approx(want[key], abs=1e-12), (protocol, key)


def test_bootstrap_seeds_reproduce_and_differ():
    rng = np.random.default_rng(3)
    s, gt = _noisy(rng, 50, 0.5), np.eye(50, dtype=bool)
    a = bootstrap_metrics(s, gt, n=100, seed=7)
    assert a == bootstrap_metrics(s, gt, n=100, seed=7)
    assert a != bootstrap_metrics(s, gt, n=100, seed=8)


def test_paired_bootstrap_identical_and_clearly_better():
    rng = np.random.default_rng(4)
    gt = np.eye(120, dtype=bool)
    weak = _noisy(rng, 120, 0.3)
    strong = _noisy(rng, 120, 3.0)
    same = paired_bootstrap(weak, weak.copy(), gt, n=200)
    for delta, lo, hi, p in same.values():
        assert (delta, lo, hi, p) == (0.0, 0.0, 0.0, 1.0)
    better = paired_bootstrap(strong, weak, gt, n=300, seed=1)
    for key in ("auc", "r@1"):
        delta, lo, hi, p = better[key]
        assert 0 < lo <= delta <= hi and p < 0.05
        a, b = (
            bootstrap_metrics(strong, gt, n=10)[key][0],
            bootstrap_metrics(weak, gt, n=10)[key][0],
        )
        assert delta == pytest.approx(a - b, abs=1e-15)
    worse = paired_bootstrap(weak, strong, gt, n=300, seed=1)
    assert worse["auc"][2] < 0 and worse["auc"][3] < 0.05


def test_bootstrap_is_fast_on_nordland_size():
    import time

    rng = np.random.default_rng(5)
    n = 3576
    s, gt = _noisy(rng, n, 0.3), np.eye(n, dtype=bool)
    t = time.process_time()
    bootstrap_metrics(s, gt, n=N_BOOTSTRAP)
    assert time.process_time() - t < 60  # ~3 s idle; a per-resample sort loop takes minutes


def test_format_interval_and_columns():
    assert format_interval(0.8123, 0.7509, 0.8661) == "0.812 [0.751, 0.866]"
    cols = bootstrap_columns(
        {"auc": (0.8, 0.7, 0.9), "r@100p": (0.1, 0.0, 0.2), "r@1": (0.5, 0.4, 0.6)}
    )
    assert list(cols) == [
        "AUC",
        "AUC lo",
        "AUC hi",
        "R@100P",
        "R@100P lo",
        "R@100P hi",
        "R@1",
        "R@1 lo",
        "R@1 hi",
    ]
    paired = bootstrap_columns({"auc": (0.1, 0.05, 0.15, 0.002)}, prefix="d")
    assert paired == {"dAUC": 0.1, "dAUC lo": 0.05, "dAUC hi": 0.15, "dAUC p": 0.002}
    with pytest.raises(ValueError, match="value, low, high"):
        bootstrap_columns({"auc": (0.1, 0.2)})


def test_bootstrap_bad_arguments():
    with pytest.raises(ValueError, match="resamples"):
        bootstrap_metrics(S, GT, n=-1)
    with pytest.raises(ValueError, match="protocol"):
        bootstrap_metrics(S, GT, protocol="multi_match")
    with pytest.raises(ValueError, match="k must be a positive integer, got 0"):
        bootstrap_metrics(S, GT, ks=(0,))
    # without resamples too: the resampled rows are per query, multi_match decides per pair
    with pytest.raises(ValueError, match="'multi_match' has no bootstrap intervals.*use a protoc"):
        paired_bootstrap(S, S, GT, n=0, protocol="multi_match")
    with pytest.raises(ValueError, match="shape"):
        paired_bootstrap(S, S[:, :2], GT)


def test_a_runs_evaluation_value_stands_for_its_protocol_name():
    """evaluate, chance and the saturation check take a run's Evaluation or the protocol's name;
    a bad name is refused by the value, naming the valid ones."""
    ev = Evaluation("best_match", n_bootstrap=0)
    assert evaluate(S, GT, ev) == evaluate(S, GT, "best_match") != evaluate(S, GT)
    assert chance(GT, ev) == chance(GT, "best_match")
    with pytest.raises(ValueError, match="ratio, best_match, vpr_bench, multi_match"):
        evaluate(S, GT, "best-match")
    with pytest.raises(ValueError, match="n_bootstrap"):  # multi_match has no intervals
        bootstrap_metrics(S, GT, n=10, protocol="multi_match")
