"""Issue 27.1-27.2 and 26.8: chance levels, the compact comparison table, the per-query view and
the disagreement figure; compare refuses runs of different datasets (24.4)."""

from __future__ import annotations

import math
import warnings

import matplotlib
import numpy as np
import pandas as pd
import pytest

from vpr_core import MethodResult, run_method
from vpr_core.evaluation import bootstrap_metrics, chance, compact, compare, evaluate
from vpr_core.evaluation.chance import chance_precision, saturation_notice
from vpr_core.evaluation.compare import CHANCE_ROW, compact_text
from vpr_core.evaluation.queries import per_query
from vpr_core.matching import Matching, match_landmarks
from vpr_core.notices import VPRWarning
from vpr_study.viz import plot_disagreements, plot_pr_curves

TIMINGS = {
    "landmarks_per_image": 1.0,
    "landmarks_s_per_image": 0.0,
    "features_s_per_image": 0.0,
    "matching_s_per_pair": 0.0,
    "pairs": 1.0,
}


def _result(sim, gt, label, fingerprint=None, dataset="toy", n=200) -> MethodResult:
    r = MethodResult(
        method=label,
        label=label,
        dataset=dataset,
        config={"name": label},
        encoder={},
        similarity=np.asarray(sim, dtype=float),
        ground_truth=gt,
        boxes={"query": [], "reference": []},
        metrics=evaluate(sim, gt),
        timings=TIMINGS,
        intervals=bootstrap_metrics(sim, gt, n=n),
        queries_with_gt=(int(gt.any(axis=1).sum()), gt.shape[0]),
        tolerance=0,
    )
    r.dataset_fingerprint = fingerprint  # recorded by run_method (issue 24.4)
    return r


def _frames(n: int, tolerance: int) -> np.ndarray:
    i = np.arange(n)
    return np.abs(i[:, None] - i[None, :]) <= tolerance


# ------------------------------------------------------------------------------------------
# chance
# ------------------------------------------------------------------------------------------


def test_chance_recall_is_the_hand_computation():
    gt = _frames(10, 2)  # 3, 4, 5, 5, 5, 5, 5, 5, 4, 3 correct references of 10
    level = chance(gt)
    assert level["r@1"] == pytest.approx(0.44)  # issue 27: 44 / 100
    want = np.mean([1 - math.comb(10 - c, 5) / math.comb(10, 5) for c in gt.sum(axis=1)])
    assert level["r@5"] == pytest.approx(want)
    assert want == pytest.approx((2 * (1 - 21 / 252) + 2 * (1 - 6 / 252) + 6 * (1 - 1 / 252)) / 10)
    assert chance(gt, ks=(10,))["r@10"] == 1.0
    one = chance(np.eye(8, dtype=bool))
    assert one["r@1"] == pytest.approx(1 / 8) and one["r@5"] == pytest.approx(5 / 8)


@pytest.mark.parametrize("protocol", ["ratio", "best_match", "vpr_bench"])
def test_chance_auc_is_the_mean_metric_of_random_rankings(protocol):
    gt = _frames(10, 1)
    gt[9] = False  # a query without ground truth (a negative for vpr_bench)
    rng = np.random.default_rng(0)
    draws = np.array(
        [list(evaluate(rng.random(gt.shape), gt, protocol).values()) for _ in range(3000)]
    )
    mean, se = draws.mean(axis=0), draws.std(axis=0) / np.sqrt(len(draws))
    level = chance(gt, protocol, n=3000)
    for i, key in enumerate(("auc", "r@100p", "r@1", "r@5")):
        assert abs(level[key] - mean[i]) < 4 * se[i] + 0.01, (key, level[key], mean[i])
    assert chance(gt, protocol) == chance(gt, protocol)  # seeded


def test_chance_multi_match_is_exact():
    gt = np.eye(6, 5, dtype=bool)
    gt[0, 1] = True
    rng = np.random.default_rng(1)
    draws = np.array(
        [list(evaluate(rng.random(gt.shape), gt, "multi_match").values()) for _ in range(6000)]
    )
    level = chance(gt, "multi_match")
    assert level["auc"] == pytest.approx(draws[:, 0].mean(), abs=0.006)
    assert level["r@100p"] == pytest.approx(draws[:, 1].mean(), abs=0.006)
    assert chance_precision(gt, "multi_match") == pytest.approx(6 / 30)
    all_right = chance(np.ones((3, 4), bool), "multi_match")
    assert all_right["auc"] == pytest.approx(1.0) and all_right["r@100p"] == pytest.approx(1.0)


def test_chance_refuses_what_it_cannot_compute():
    with pytest.raises(ValueError, match="no query has a ground-truth reference"):
        chance(np.zeros((3, 3), bool))
    with pytest.raises(ValueError, match="valid: ratio"):
        chance(np.eye(3, dtype=bool), "nope")
    with pytest.raises(ValueError, match="n \\(random rankings\\) must be a positive integer"):
        chance(np.eye(3, dtype=bool), n=0)
    with pytest.raises(ValueError, match="k must be a positive integer, got 0"):
        chance(np.eye(3, dtype=bool), ks=(1, 0))
    # the ground-truth rules of the datasets (one home), naming the argument
    with pytest.raises(ValueError, match=r"ground truth must have shape \(Nq, Nr\)"):
        chance(np.ones(3, dtype=bool))
    with pytest.raises(ValueError, match=r"\(ground_truth=\) must hold bools or 0/1"):
        chance(np.eye(3) * 2)
    with pytest.raises(ValueError, match=r"\(soft=, the dataset's ground_truth_soft\) has shape"):
        chance(np.eye(3, dtype=bool), soft=np.eye(2, dtype=bool))


def test_saturation_warns_when_chance_is_inside_every_run_interval():
    gt = np.eye(6, dtype=bool)  # chance: R@1 1/6, AUC about 0.2
    noise = {"auc": (0.2, 0.0, 0.5), "r@1": (0.17, 0.0, 0.5)}
    weak = {"auc": (0.3, 0.1, 0.6), "r@1": (0.33, 0.0, 0.67)}
    good = {"auc": (0.9, 0.7, 1.0), "r@1": (0.83, 0.5, 1.0)}
    with pytest.warns(VPRWarning, match="at chance level: .*AUC 0.*R@1 0.167"):
        assert "every run" in saturation_notice(gt, [noise, weak])
    with warnings.catch_warnings():
        warnings.simplefilter("error", VPRWarning)
        assert saturation_notice(gt, [noise, good]) is None  # one run is above chance
        assert saturation_notice(gt, noise) is None  # one run alone: its table says it
    with pytest.warns(VPRWarning, match="saturated ground truth"):
        saturation_notice(_frames(4, 2), {})


def test_notices_name_their_runs_and_agree_with_the_verdicts():
    """Issue 54 item 5: the chance notice names each run with its interval (it can be read
    against the table), a run without intervals makes it no "every run" claim, a perfect run's
    notice does not deny a verdict against a lower run, and tolerance=0 is never advised at 0."""
    gt = np.eye(6, dtype=bool)
    noise = {"auc": (0.2, 0.0, 0.5), "r@1": (0.17, 0.0, 0.5)}
    weak = {"auc": (0.3, 0.1, 0.6), "r@1": (0.33, 0.0, 0.67)}
    with pytest.warns(VPRWarning) as said:
        saturation_notice(gt, [noise, weak], labels=["dense", "mine"])
    text = str(said[0].message)
    assert "dense 0.200 [0.000, 0.500], mine 0.300 [0.100, 0.600]" in text
    assert "R@1: dense 0.170 [0.000, 0.500], mine 0.330 [0.000, 0.670]" in text
    with warnings.catch_warnings():
        warnings.simplefilter("error", VPRWarning)
        assert saturation_notice(gt, [noise, {}], labels=["dense", "no intervals"]) is None
    perfect = {"auc": (1.0, 1.0, 1.0), "r@1": (1.0, 1.0, 1.0)}
    with pytest.warns(VPRWarning) as said:
        saturation_notice(gt, perfect, tolerance=0)
    text = str(said[0].message)
    assert "cannot tell methods apart" not in text and "verdict against a run below" in text
    assert "tolerance=0" not in text
    with pytest.warns(VPRWarning) as said:
        saturation_notice(_frames(4, 2), {}, tolerance=0)
    assert "tolerance=0" not in str(said[0].message) and "already 0" in str(said[0].message)


# ------------------------------------------------------------------------------------------
# compare: chance columns, datasets, compact display
# ------------------------------------------------------------------------------------------


def _pair(fp_a="aaa", fp_b="aaa"):
    gt = np.eye(12, dtype=bool)
    rng = np.random.default_rng(3)
    a = _result(np.eye(12) + 0.5 * rng.random((12, 12)), gt, "dense", fp_a)
    b = _result(rng.random((12, 12)), gt, "classical (n=20)", fp_b)
    return a, b


def test_compare_has_chance_columns_and_refuses_another_dataset():
    a, b = _pair()
    table = compare([a, b], baseline="dense", n_bootstrap=100)
    level = chance(a.ground_truth)
    for name, key in (("AUC", "auc"), ("R@100P", "r@100p"), ("R@1", "r@1"), ("R@5", "r@5")):
        assert (table[f"{name} chance"] == level[key]).all()
        cols = list(table.columns)
        assert cols.index(f"{name} chance") == cols.index(f"{name} hi") + 1
    a, b = _pair("aaa", "bbb")
    b.dataset = "other_place"
    with pytest.raises(ValueError, match="'other_place'.*'toy'|'toy'.*'other_place'"):
        compare([a, b])
    with pytest.raises(ValueError, match=r"^per_query\(\): .*compare runs of one dataset"):
        per_query([a, b])  # the same rule, naming its caller
    for unset in (None, ""):  # a result without a fingerprint: the ground truth decides
        a, b = _pair("aaa", unset)
        assert len(compare([a, b], n_bootstrap=0)) == 2


def test_compact_shows_every_interval_verdict_and_chance_in_100_columns():
    a, b = _pair()
    table = compare([a, b], baseline="dense", n_bootstrap=100)
    view = compact(table)
    assert list(view.index) == ["dense", "classical (n=20)", CHANCE_ROW]
    r = table.loc["classical (n=20)"]
    assert view.loc["classical (n=20)", "R@1"] == (
        f"{r['R@1']:.3f} [{r['R@1 lo']:.3f}, {r['R@1 hi']:.3f}]"
    )
    assert view.loc["classical (n=20)", "dAUC vs dense"].endswith(r["dAUC verdict"])
    assert view.loc[CHANCE_ROW, "R@1"] == f"{1 / 12:.3f}"
    text = compact_text(table)
    assert max(len(line) for line in text.splitlines()) <= 100
    every, flat = compact_text(table, wide=True), " ".join(text.split())
    for col in view.columns:
        assert col in flat  # shown, or named on the last line as not shown: never cut
        for cell in view[col]:
            assert cell in every  # nothing cut or elided
    assert "..." not in text and repr(table) == text
    assert "dR@1 vs dense" in table._repr_html_()
    # issue 61: in a notebook each run's label stays on one line (it wrapped to five in Lab)
    html = table._repr_html_()
    for label in ("dense", "classical (n=20)", CHANCE_ROW):
        assert f'<th style="white-space: nowrap">{label}</th>' in html
    assert html == view._repr_html_() and type(view[["R@1"]]) is pd.DataFrame
    assert isinstance(table, pd.DataFrame) and "AUC lo" in table.columns  # full table for CSV
    assert type(table[["AUC"]]) is pd.DataFrame  # a derived frame is a plain one


# ------------------------------------------------------------------------------------------
# per-query view
# ------------------------------------------------------------------------------------------


def test_per_query_hand_example():
    nan = np.nan
    gt = np.eye(4, dtype=bool)
    gt[3] = False  # no ground truth: not listed
    sa = np.array([[0.9, 0.1, 0.3, 0], [0.2, 0.1, 0.8, 0], [0.1, 0.2, 0.9, 0], [1, 0, 0, 0]])
    sb = np.array([[0.2, 0.9, 0.1, 0], [0.1, 0.9, 0.3, 0], [nan, nan, nan, nan], [1, 0, 0, 0]])
    a, b = _result(sa, gt, "a", n=0), _result(sb, gt, "b", n=0)
    t = per_query([a, b])
    assert list(t["query"]) == [0, 0, 1, 1, 2, 2]  # all three disagree; by query, runs in order
    assert t["disagree"].all()
    first = t.set_index(["query", "run"])
    assert (
        first.loc[(0, "a"), "first correct rank"] == 1
        and first.loc[(0, "b"), "first correct rank"] == 2
    )
    assert first.loc[(1, "a"), "top-1"] == 2 and not first.loc[(1, "a"), "top-1 correct"]
    assert first.loc[(1, "a"), "ratio"] == pytest.approx(0.2 / 0.8)
    assert pd.isna(first.loc[(2, "b"), "top-1"]) and not first.loc[(2, "b"), "top-1 correct"]
    assert pd.isna(first.loc[(2, "b"), "first correct rank"])  # nothing ranked: not retrieved
    assert t["top-1 matches"].isna().all()  # no descriptors kept
    # (not in the paper) frames from a wrong top-1 to the nearest correct reference
    assert first.loc[(1, "a"), "wrong top-1 distance"] == 1  # top-1 2, correct 1
    assert first.loc[(0, "b"), "wrong top-1 distance"] == 1  # top-1 1, correct 0
    assert pd.isna(first.loc[(0, "a"), "wrong top-1 distance"])  # correct
    assert pd.isna(first.loc[(2, "b"), "wrong top-1 distance"])  # nothing retrieved
    assert "contrast zero share" not in t.columns  # only on request
    same = per_query([a, _result(sa, gt, "a2", n=0)])
    assert not same["disagree"].any()
    with pytest.raises(ValueError, match="unique"):
        per_query([a, a])


def test_per_query_wrong_top1_distance_is_the_nearest_correct_frame():
    n = 12
    gt = _frames(n, 1)
    sim = np.eye(n)
    sim[0] = 0
    sim[0, 9] = 1  # far along the route: aliasing
    sim[5] = 0
    sim[5, 7] = 1  # a neighbour of the correct 4..6
    t = per_query(_result(sim, gt, "a", n=0)).set_index("query")
    assert t.loc[0, "wrong top-1 distance"] == 8 and t.loc[5, "wrong top-1 distance"] == 1
    assert t["wrong top-1 distance"].notna().sum() == 2
    r = _result(sim, gt, "b", n=0)
    r.ground_truth_from_file = True  # no frame order: no distance
    assert per_query(r)["wrong top-1 distance"].isna().all()


@pytest.fixture(scope="module")
def kept(tiny_synthetic):
    return [
        run_method(m, tiny_synthetic, keep_descriptors=True)  # shares test_pipeline's cache
        for m in ("dense", "classical")
    ]


def test_per_query_counts_the_top1_matches(kept):
    dense = kept[0]
    t = per_query(kept)
    row = t[(t["run"] == "dense")].iloc[0]
    q, r = int(row["query"]), int(row["top-1"])
    m = match_landmarks(
        dense.descriptors["query"][q],
        dense.boxes["query"][q],
        dense.descriptors["reference"][r],
        dense.boxes["reference"][r],
    )
    assert row["top-1 matches"] == len(m.matches) > 0
    flips = t.groupby("query")["top-1 correct"].nunique() > 1
    assert list(t["disagree"]) == list(t["query"].map(flips))
    assert t["disagree"].is_monotonic_decreasing  # disagreements first


def test_per_query_contrast_zero_share(kept):
    from vpr_core.matching import weighted_matches

    t = per_query(kept, contrast=True)
    share = t["contrast zero share"]
    assert share.notna().all() and share.between(0, 1).all() and share.max() > 0
    dense = kept[0]
    row = t[t["run"] == dense.label].iloc[0]
    q, r = int(row["query"]), int(row["top-1"])
    d, b = dense.descriptors, dense.boxes
    m = weighted_matches(
        d["query"],
        b["query"],
        d["reference"],
        b["reference"],
        [[q, r]],
        Matching(weighting="contrast"),
    )[0]
    assert row["contrast zero share"] == pytest.approx(np.mean(m.weights == 0))
    # the same statistics as the weighted run: its top-1 score is that pair's similarity, to
    # float32 rounding (the pair and the block take their cosines from matmuls of other shapes,
    # which round differently by CPU: 1.5e-7 relative on an Intel Xeon, under 1e-9 on an AMD EPYC)
    w = run_method("dense", dense_set(kept), weighting="contrast", n_bootstrap=0).similarity
    assert m.similarity == pytest.approx(w[q, r], rel=1e-6)


def dense_set(kept):
    from vpr_core.datasets import load_dataset

    return load_dataset("synthetic", n_places=len(kept[0].ground_truth))


def test_plot_disagreements(tiny_synthetic, kept):
    fig = plot_disagreements(tiny_synthetic, *kept, n=3)
    table = fig.table  # the rows shown, in order
    assert isinstance(fig, matplotlib.figure.Figure)
    assert len(fig.axes) == 9 and table["query"].nunique() == 3
    assert table["disagree"].iloc[0]  # the first row shown is a disagreement
    assert "correct reference" in fig.axes[2].get_title()
    with pytest.raises(ValueError, match="keep_descriptors=True"):
        plot_disagreements(tiny_synthetic, run_method("dense", tiny_synthetic), kept[1])
    matplotlib.pyplot.close("all")


def test_pr_figure_draws_chance(kept):
    fig = plot_pr_curves(kept)
    dashed = [ln for ln in fig.axes[0].get_lines() if ln.get_linestyle() == "--"]
    assert len(dashed) == 1
    assert dashed[0].get_ydata()[0] == pytest.approx(chance_precision(kept[0].ground_truth))
    assert "chance" in dashed[0].get_label()
    matplotlib.pyplot.close("all")
