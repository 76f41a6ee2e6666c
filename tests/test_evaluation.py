"""Known-answer tests of vpr_core.evaluation (PR curves, AUC, R@100P, R@K)."""

from __future__ import annotations

import numpy as np
import pytest

from vpr_core.evaluation import (
    PRCurve,
    auc_pr,
    evaluate,
    metrics_table,
    pr_curve,
    recall_at_100_precision,
    recall_at_k,
)

# 5 queries x 3 references.
S = np.array([
    [0.9, 0.3, 0.1],  # q0 gt b0: b1=0, r = .3/.9 = 1/3, correct
    [0.2, 0.8, 0.6],  # q1 gt b1: b1=1, r = .6/.8 = .75, correct
    [0.5, 0.1, 0.4],  # q2 gt b2: b1=0, r = .4/.5 = .8, wrong
    [0.0, 0.0, 0.0],  # q3 gt b2: S1 <= 0 -> r = 1; b1 = 0 (tie, lowest), wrong
    [1.0, 0.0, 0.0],  # q4 has no ground truth: dropped
])
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
    assert set(m) == {"auc", "r_at_100p", "r_at_1", "r_at_5"}
    assert m["auc"] == pytest.approx(5 / 6) and m["r_at_5"] == 1.0


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


def test_nothing_correct_and_no_ground_truth():
    s = np.array([[0.9, 0.1], [0.1, 0.9]])
    gt = np.array([[0, 1], [1, 0]], dtype=bool)  # best always wrong
    c = pr_curve(s, gt)
    np.testing.assert_allclose(c.recall, [0, 0])  # TP + FN = 0 -> recall 0
    np.testing.assert_allclose(c.precision, [1, 0])
    assert auc_pr(c) == 0.0 and recall_at_100_precision(c) == 0.0
    c = pr_curve(s, np.zeros((2, 2), dtype=bool))  # no query kept
    assert c.n_queries == 0
    np.testing.assert_allclose(c.recall, [0]) and np.testing.assert_allclose(c.precision, [1])
    assert recall_at_k(s, np.zeros((2, 2), bool), 1) == 0.0


def test_best_match_protocol():
    c = pr_curve(S, GT, protocol="best_match")
    # S1: q0 .9 TP, q1 .8 TP, q2 .5 FP, q3 0 FP -> same order as ratio here
    np.testing.assert_allclose(c.thresholds, [np.inf, 0.9, 0.8, 0.5, 0.0])
    np.testing.assert_allclose(c.recall, R_WANT)
    np.testing.assert_allclose(c.precision, P_WANT)


def test_multi_match_protocol():
    s = np.array([[0.9, 0.5], [0.7, 0.2]])
    gt = np.array([[1, 1], [0, 0]], dtype=bool)
    # pairs by score: .9 TP, .7 FP, .5 TP, .2 FP; 2 gt pairs
    c = pr_curve(s, gt, protocol="multi_match")
    np.testing.assert_allclose(c.recall, [0, 0.5, 0.5, 1, 1])
    np.testing.assert_allclose(c.precision, [1, 1, 0.5, 2 / 3, 0.5])


def test_bad_inputs():
    with pytest.raises(ValueError, match="valid: ratio, best_match, multi_match"):
        pr_curve(S, GT, protocol="nope")
    with pytest.raises(ValueError, match="shape"):
        pr_curve(S, GT[:4])
    with pytest.raises(ValueError, match=r"\(Nq, Nr\)"):
        pr_curve(S.ravel(), GT.ravel())
    with pytest.raises(ValueError, match="at least 2 references"):
        pr_curve(S[:, :1], GT[:, :1])
    with pytest.raises(ValueError, match="boolean"):
        pr_curve(S, GT * 2)
    with pytest.raises(ValueError, match="NaN"):
        pr_curve(np.full((2, 2), np.nan), np.eye(2, dtype=bool))
    with pytest.raises(ValueError, match="k must be"):
        recall_at_k(S, GT, 0)


def test_metrics_table_and_perfect_matrix():
    rng = np.random.default_rng(0)
    s = rng.uniform(0, 0.5, (20, 20)) + np.eye(20)
    perfect = evaluate(s, np.eye(20, dtype=bool))
    assert perfect == {"auc": 1.0, "r_at_100p": 1.0, "r_at_1": 1.0, "r_at_5": 1.0}
    df = metrics_table({"dense": perfect, "classical": evaluate(S, GT)})
    assert list(df.index) == ["dense", "classical"]
    assert list(df.columns) == ["auc", "r_at_100p", "r_at_1", "r_at_5"]
    assert df.loc["classical", "auc"] == pytest.approx(5 / 6)


def test_plot_pr_curves():
    from vpr_core import viz

    if not hasattr(viz, "plot_pr_curves"):
        pytest.skip("viz.plot_pr_curves not present")
    fig = viz.plot_pr_curves({"a": pr_curve(S, GT), "b": pr_curve(S, GT, "best_match")},
                             title="t")
    ax = fig.axes[0]
    assert ax.get_xlim() == (0.0, 1.0) and ax.get_ylim() == (0.0, 1.02)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0].startswith("a") and "0.83" in labels[0]
    fig2 = viz.plot_metric_bars(metrics_table({"a": evaluate(S, GT)}), metric="auc")
    assert fig2.axes
