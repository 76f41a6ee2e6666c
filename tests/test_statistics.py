"""Tests of vpr_core.statistics (CMR / CLS / ASL from labelled matches) and its Fig. 4 plots."""

from __future__ import annotations

import hashlib
from types import SimpleNamespace

import numpy as np
import pytest

from vpr_core.paper import SCALE_RANGE_LABELS
from vpr_core.statistics import (
    MatchRecord,
    label_matches,
    scale_statistics_from_matches,
)

nan = np.nan


def test_label_matches_is_the_labellers_own():
    """DESIGN names ``vpr_core.statistics.label_matches``: the same object as the labellers'."""
    from vpr_core import labels
    from vpr_core import statistics as stats

    assert stats.label_matches is labels.label_matches
    assert set(stats.__all__) <= set(dir(stats))


# ---------------------------------------------------------------------------------------------
# CMR / CLS / ASL from hand-built matches
# ---------------------------------------------------------------------------------------------


def hand_records() -> list[MatchRecord]:
    return [
        # ground-truth pair A: scales 1,1,5,7
        MatchRecord([1, 1, 5, 7], [0.9, 0.8, 0.5, 0.6], [False, True, True, True], True, 0, 0),
        # ground-truth pair B: one scale-5 match, wrong
        MatchRecord([5], [0.4], [False], True, 1, 1),
        # query-irrelevant pair: scales 1,1,6
        MatchRecord([1, 1, 6], [0.7, 0.7, 0.2], None, False, 0, 2),
    ]


def test_hand_built_cmr_cls_asl():
    st = scale_statistics_from_matches(hand_records())
    # n_matches (gt pairs): S1 = 2, S5 = 2 (A and B), S7 = 1
    np.testing.assert_array_equal(st.n_matches, [0, 2, 0, 0, 0, 2, 0, 1, 0, 0])
    np.testing.assert_array_equal(st.n_matches_irrelevant, [0, 2, 0, 0, 0, 0, 1, 0, 0, 0])
    # CMR: S1 1/2 (one of the two scale-1 matches correct), S5 1/2 (A right, B wrong), S7 1/1
    np.testing.assert_allclose(st.cmr[1:], [0.5, nan, nan, nan, 0.5, nan, 1.0, nan, nan])
    # CLS gt: masses S1 0.9+0.8 = 1.7, S5 0.5+0.4 = 0.9, S7 0.6; total 3.2
    np.testing.assert_allclose(st.cls_gt[1:], [1.7 / 3.2, 0, 0, 0, 0.9 / 3.2, 0, 0.6 / 3.2, 0, 0])
    # CLS irrelevant: S1 1.4, S6 0.2; total 1.6 -> 0.875, 0.125
    np.testing.assert_allclose(st.cls_irrelevant[1:], [0.875, 0, 0, 0, 0, 0.125, 0, 0, 0])
    # ASL gt: S1 1.7/2 = 0.85, S5 0.9/2 = 0.45, S7 0.6
    np.testing.assert_allclose(st.asl_gt[1:], [0.85, nan, nan, nan, 0.45, nan, 0.6, nan, nan])
    np.testing.assert_allclose(st.asl_irrelevant[1:], [0.7, nan, nan, nan, nan, 0.2, nan, nan, nan])
    assert (st.n_gt_pairs, st.n_irrelevant_pairs, st.n_unlabelled_pairs) == (2, 1, 0)
    assert np.isclose(np.nansum(st.cls_gt[1:]), 1.0)
    assert np.isclose(np.nansum(st.cls_irrelevant[1:]), 1.0)
    df = st.to_frame()
    assert list(df.index) == list(range(1, 10))
    assert df.loc[1, "range"] == "0~0.02" and df.loc[9, "range"] == "0.72~1"
    assert tuple(df["range"]) == SCALE_RANGE_LABELS
    assert df.loc[5, "n_correct"] == 1


def test_cls_sums_to_one_random():
    rng = np.random.default_rng(3)
    recs = [
        MatchRecord(
            rng.integers(1, 10, 40),
            rng.uniform(-0.2, 1.0, 40),
            rng.random(40) < 0.5,
            bool(i % 2),
            i,
            i,
        )
        for i in range(12)
    ]
    st = scale_statistics_from_matches(recs)
    assert np.isclose(np.nansum(st.cls_gt[1:]), 1.0)
    assert np.isclose(np.nansum(st.cls_irrelevant[1:]), 1.0)
    assert np.nanmin(st.cmr) >= 0 and np.nanmax(st.cmr) <= 1


def test_empty_scales_are_nan_not_crash():
    st = scale_statistics_from_matches([])
    assert np.isnan(st.cmr).all() and np.isnan(st.cls_gt).all() and np.isnan(st.asl_gt).all()
    assert st.n_matches.sum() == 0
    st = scale_statistics_from_matches(
        [MatchRecord([], [], [], True), MatchRecord([], [], None, False)]
    )
    assert np.isnan(st.cmr).all() and np.isnan(st.cls_irrelevant).all()
    # unlabelled gt pair: enters counts / CLS / ASL, not CMR
    st = scale_statistics_from_matches([MatchRecord([4, 4], [0.5, 0.3], None, True)])
    assert st.n_matches[4] == 2 and st.n_labelled[4] == 0 and np.isnan(st.cmr[4])
    assert st.n_unlabelled_pairs == 1 and np.isclose(st.cls_gt[4], 1.0)
    assert np.isclose(st.asl_gt[4], 0.4)


# ---------------------------------------------------------------------------------------------
# plots
# ---------------------------------------------------------------------------------------------


def _png_hash(fig, tmp_path, name):
    from vpr_study.viz import save_figure

    p = save_figure(fig, tmp_path / name)
    return hashlib.sha1(p.read_bytes()).hexdigest()


def test_plots_deterministic(tmp_path):
    import matplotlib.pyplot as plt

    from vpr_study import viz

    st = scale_statistics_from_matches(hand_records())
    h1 = _png_hash(viz.plot_scale_statistics(st, title="hand"), tmp_path, "a.png")
    h2 = _png_hash(viz.plot_scale_statistics(st, title="hand"), tmp_path, "b.png")
    assert h1 == h2
    for fn in (viz.plot_cmr, viz.plot_cls, viz.plot_asl):
        fig = fn(st)
        assert len(fig.axes) == 1
        fn(scale_statistics_from_matches([]))  # all-NaN stats draw without error
    img = np.zeros((40, 60, 3), np.uint8)
    boxes = np.array([[5.0, 5.0, 20, 20], [30, 10, 20, 20]])
    fig = viz.plot_labelled_matches(img, img[:30], boxes, boxes, [[0, 0], [1, 0]], [True, False])
    assert "1 correct" in fig.axes[0].get_title()
    assert _png_hash(fig, tmp_path, "m1.png") == _png_hash(
        viz.plot_labelled_matches(img, img[:30], boxes, boxes, [[0, 0], [1, 0]], [True, False]),
        tmp_path,
        "m2.png",
    )
    plt.close("all")


# ---------------------------------------------------------------------------------------------
# end to end on `synthetic`
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def synthetic_small():
    """6 synthetic places (seed 11: not a seed the labeller was tuned on), dense landmarks,
    HOG landmark descriptors (fast; the labels do not depend on the descriptor)."""
    from vpr_core.datasets import load_dataset
    from vpr_core.features import LandmarkEncoder
    from vpr_core.landmarks import dense_sampling

    ds = load_dataset("synthetic", n_places=6, seed=11)
    enc = LandmarkEncoder(backbone="hog", dim=256, seed=0)
    out = {"dataset": ds}
    for side in ("query", "reference"):
        imgs = [ds.load_image(side, i) for i in range(6)]
        out[f"img_{side}"] = imgs
        out[f"boxes_{side}"] = [dense_sampling(im.shape[:2]) for im in imgs]
        out[f"desc_{side}"] = [
            enc.encode(im, b) for im, b in zip(imgs, out[f"boxes_{side}"], strict=False)
        ]
    return out


def _landmarks(boxes_q, boxes_r, desc_q, desc_r):
    """A run's landmarks as scale_statistics reads them (``boxes``, ``descriptors``)."""
    return SimpleNamespace(
        boxes={"query": boxes_q, "reference": boxes_r},
        descriptors={"query": desc_q, "reference": desc_r},
    )


def test_scale_statistics_end_to_end(synthetic_small):
    from vpr_core.matching import match_landmarks
    from vpr_core.statistics import scale_statistics

    s = synthetic_small
    ds = s["dataset"]
    st = scale_statistics(
        ds,
        _landmarks(s["boxes_query"], s["boxes_reference"], s["desc_query"], s["desc_reference"]),
        n_irrelevant=2,
        seed=0,
    )
    assert st.meta["label_method"] == "exact"
    assert (st.n_gt_pairs, st.n_irrelevant_pairs, st.n_unlabelled_pairs) == (6, 12, 0)
    # dense areas 0.16, 0.25, 0.36, 0.49 -> Table-1 scales 5, 6, 7, 7
    assert set(np.flatnonzero(st.n_matches)) <= {5, 6, 7}
    assert np.isnan(st.cmr[[1, 2, 3, 4, 8, 9]]).all()
    assert np.isclose(np.nansum(st.cls_gt[1:]), 1.0)
    assert np.isclose(np.nansum(st.cls_irrelevant[1:]), 1.0)
    # cross-check against the pair-by-pair computation
    n = np.zeros(10, int)
    ok = np.zeros(10, int)
    for q in range(6):
        res = match_landmarks(
            s["desc_query"][q], s["boxes_query"][q], s["desc_reference"][q], s["boxes_reference"][q]
        )
        lab = label_matches(ds, q, q, s["boxes_query"][q], s["boxes_reference"][q], res.matches)
        sc = np.array([5, 6, 7, 7]).repeat(25)[res.matches[:, 0]]
        np.add.at(n, sc, 1)
        np.add.at(ok, sc, lab.astype(int))
    np.testing.assert_array_equal(st.n_matches, n)
    np.testing.assert_array_equal(st.n_correct, ok)
    assert st.n_matches.sum() > 0 and np.nanmax(st.cmr) > 0.5
    # same seed -> same irrelevant pairs -> same statistics
    st2 = scale_statistics(
        ds,
        _landmarks(s["boxes_query"], s["boxes_reference"], s["desc_query"], s["desc_reference"]),
        n_irrelevant=2,
        seed=0,
    )
    np.testing.assert_array_equal(st.asl_irrelevant, st2.asl_irrelevant)


def test_geometric_agrees_with_exact_on_synthetic(synthetic_small):
    """``benchmarks/bench_labelling.py --pairs 20 --seed 11`` measured, geometric vs exact:
    auto rule accuracy 1.000 (dense, 728 matches; edge_boxes, 169 matches), point rule forced
    0.964 (dense) / 0.953 (edge_boxes). Here: 6 pairs of the same seed, HOG descriptors."""
    from vpr_core.matching import match_landmarks

    s = synthetic_small
    ds = s["dataset"]
    agree_auto, agree_pts, n = 0, 0, 0
    cache: dict = {}
    for q in range(6):
        bq, br = s["boxes_query"][q], s["boxes_reference"][q]
        m = match_landmarks(s["desc_query"][q], bq, s["desc_reference"][q], br).matches
        exact = label_matches(ds, q, q, bq, br, m, method="exact")
        geo = label_matches(
            ds,
            q,
            q,
            bq,
            br,
            m,
            method="geometric",
            geometry_cache=cache,
            images=(s["img_query"][q], s["img_reference"][q]),
        )
        pts = label_matches(
            ds, q, q, bq, br, m, method="geometric", geometry_cache=cache, model="points"
        )
        agree_auto += int((geo == exact).sum())
        agree_pts += int((pts == exact).sum())
        n += len(m)
    assert n > 50 and len(cache) == 6
    assert agree_auto / n >= 1.0 - 0.05
    assert agree_pts / n >= 0.96 - 0.08


def test_scale_statistics_geometric_labels(synthetic_small):
    from vpr_core.statistics import scale_statistics

    s = synthetic_small
    st = scale_statistics(
        s["dataset"],
        _landmarks(s["boxes_query"], s["boxes_reference"], s["desc_query"], s["desc_reference"]),
        label_method="geometric",
        n_irrelevant=1,
        queries=[0, 1],
    )
    assert st.meta["label_method"] == "geometric"
    assert (st.n_gt_pairs, st.n_irrelevant_pairs) == (2, 2)
    if st.n_unlabelled_pairs == 0:  # every ground-truth match labelled
        np.testing.assert_array_equal(st.n_labelled, st.n_matches)
    assert st.n_matches.sum() > 0


def test_statistics_recomputed_independently_from_the_match_table(tiny_synthetic):
    """CMR / CLS / ASL recomputed with pandas from ``matches_frame`` agree with ScaleStats."""
    from vpr_core import run_method
    from vpr_core.statistics import scale_statistics

    res = run_method(
        "dense", tiny_synthetic, keep_descriptors=True, scales=(0.16, 0.36), per_scale=9
    )
    st = scale_statistics(tiny_synthetic, res, n_irrelevant=3)
    df = st.matches_frame()
    assert len(df) == st.n_matches.sum() + st.n_matches_irrelevant.sum()
    gt, irr = df[df.pair == "gt"], df[df.pair == "irrelevant"]
    for k in range(1, 10):
        g = gt[gt.scale == k]
        if len(g):
            assert st.cmr[k] == pytest.approx(g.correct.mean())
            assert st.asl_gt[k] == pytest.approx(g.score.mean())
            assert st.cls_gt[k] == pytest.approx(
                g.score.clip(lower=0).sum() / gt.score.clip(lower=0).sum()
            )
        else:
            assert np.isnan(st.cmr[k])
        i = irr[irr.scale == k]
        if len(i):
            assert st.asl_irrelevant[k] == pytest.approx(i.score.mean())
    # box indices refer to the landmarks: the scale column is the query box's Table-1 index
    from vpr_core.landmarks import scale_index

    row = gt.iloc[0]
    box = res.boxes["query"][int(row["query"])][int(row.query_box_index)]
    assert scale_index(box[None], tiny_synthetic.image_size("query", 0))[0] == row.scale


def test_pair_matches_and_scale_distribution_of_a_run(tiny_synthetic):
    from vpr_core import run_method
    from vpr_core.labels import pair_matches
    from vpr_core.landmarks import scale_distribution

    res = run_method("dense", tiny_synthetic, keep_descriptors=True, backbone="hog", n_bootstrap=0)
    gt = pair_matches(tiny_synthetic, res, query=0)
    assert gt.ground_truth and gt.reference == 0 and gt.labels is not None
    assert len(gt.labels) == len(gt.matches) > 0 and 0 < gt.similarity <= 1
    assert "matches correct" in gt.summary()
    irr = pair_matches(tiny_synthetic, res, query=0, reference=4)
    assert not irr.ground_truth and not irr.labels.any()  # every match of an irrelevant pair
    counts = scale_distribution(res, tiny_synthetic)
    assert list(counts.columns) == ["query", "reference"] and len(counts) == 9
    assert (counts.sum() == 100 * tiny_synthetic.n_query).all()


def test_cmr_intervals_bootstrap_over_queries():
    from vpr_core.statistics import MatchRecord, scale_statistics_from_matches

    rng = np.random.default_rng(0)
    recs = []
    for q in range(40):
        scales = np.array([1] * 5 + [6] * 5)
        labels = np.concatenate([rng.random(5) < 0.2, rng.random(5) < 0.8])
        recs.append(
            MatchRecord(
                q=q, r=q, is_gt_pair=True, scales=scales, scores=np.full(10, 0.5), labels=labels
            )
        )
    stats = scale_statistics_from_matches(recs)
    iv = stats.cmr_intervals()
    for k in (1, 6):
        assert iv[k, 0] <= stats.cmr[k] <= iv[k, 1] and iv[k, 1] - iv[k, 0] < 0.35
    assert iv[6, 0] > iv[1, 1]  # the two scales' intervals separate
    assert np.isnan(iv[3]).all()  # no match at scale 3
    assert np.array_equal(iv, stats.cmr_intervals(), equal_nan=True)  # seeded
    frame = stats.to_frame()
    assert frame.loc[6, "cmr lo"] == iv[6, 0] and frame.loc[6, "cmr hi"] == iv[6, 1]


# ---------------------------------------------------------------------------------------------
# every bad input of the statistics boundary: one clear error line each
# ---------------------------------------------------------------------------------------------


class _TwoPlaces:
    """Two places whose query i is reference i (identity homographies), 100 x 100 images."""

    name, tolerance = "two", 0
    ground_truth = np.eye(2, dtype=bool)
    homographies = np.stack([np.eye(3)] * 2)

    def image_size(self, side: str, i: int) -> tuple[int, int]:
        return (100, 100)


_B = [np.array([[0.0, 0.0, 50.0, 50.0]]) for _ in range(2)]
_D = [np.ones((1, 4)) for _ in range(2)]


def _stats(**kwargs):
    from vpr_core.statistics import scale_statistics

    sides = {"boxes_q": _B, "boxes_r": _B, "desc_q": _D, "desc_r": _D}
    sides.update({k: kwargs.pop(k) for k in list(kwargs) if k in sides})
    return scale_statistics(_TwoPlaces(), _landmarks(*sides.values()), **kwargs)


#: id -> (call, exception, message)
BAD_STATISTICS_CALLS = {
    "record: scale": (
        lambda: MatchRecord([0], [0.5], None, True),
        ValueError,
        "scales must be Table-1 indices 1..9",
    ),
    "record: scores": (
        lambda: MatchRecord([1, 2], [0.5], None, True),
        ValueError,
        r"scores \(1\) must have one entry per match \(2\)",
    ),
    "record: labels": (
        lambda: MatchRecord([1, 2], [0.5, 0.1], [True], True),
        ValueError,
        r"labels \(1\) must have one entry per match \(2\)",
    ),
    "queries": (
        lambda: _stats(boxes_q=_B[:1]),
        ValueError,
        r"boxes_q/desc_q need one entry per query \(2\), got 1/2",
    ),
    "references": (
        lambda: _stats(desc_r=_D[:1]),
        ValueError,
        r"boxes_r/desc_r need one entry per reference \(2\), got 2/1",
    ),
    "method keyword": (
        lambda: _stats(method="exact"),
        TypeError,
        r"takes the labeller as label_method=\.\.\., not method=",
    ),
    "label method": (
        lambda: _stats(label_method="hand"),
        ValueError,
        "unknown label method 'hand'; valid: auto, exact, geometric, file",
    ),
    "boxes": (
        lambda: _stats(boxes_q=[_B[0], _B[0][:, :3]]),
        ValueError,
        r"boxes_q\[1\] must have shape \(K, 4\)",
    ),
    "image size": (
        lambda: _stats(image_sizes=[(0, 5), (0, 5)]),
        ValueError,
        r"image_sizes\[0\] must be positive integers \(H, W\)",
    ),
}


@pytest.mark.parametrize("case", BAD_STATISTICS_CALLS)
def test_bad_statistics_inputs_raise_one_clear_line(case):
    call, exc, match = BAD_STATISTICS_CALLS[case]
    with pytest.raises(exc, match=match) as info:
        call()
    assert "\n" not in str(info.value)


def test_statistics_of_two_places_check_each_box_at_most_twice(monkeypatch):
    """Parse once at the boundary: along the path of one pair the same boxes pass a boxes check
    twice (the statistics' own and the matcher's), never in the scales or the labellers."""
    import sys

    from vpr_core import checks

    seen: list[int] = []
    original = checks.check_boxes

    def counting(boxes, *args, **kwargs):
        seen.append(id(boxes))
        return original(boxes, *args, **kwargs)

    for module in list(sys.modules.values()):
        if getattr(module, "check_boxes", None) is original and module.__name__.startswith(
            "vpr_core"
        ):
            monkeypatch.setattr(module, "check_boxes", counting)
    boxes_q = [b.copy() for b in _B]
    boxes_r = [b.copy() for b in _B]
    st = _stats(boxes_q=boxes_q, boxes_r=boxes_r, n_irrelevant=1)
    assert st.n_gt_pairs == 2 and st.n_irrelevant_pairs == 2
    assert st.meta["label_method"] == "exact" and st.n_labelled.sum() == 2
    # each query's boxes: the statistics' own check, then the matcher's once per pair (its
    # ground-truth and its irrelevant reference); scales and labels trust the parsed boxes
    assert [seen.count(id(b)) for b in boxes_q] == [3, 3]


def test_scale_statistics_reads_the_runs_landmarks_and_matching(synthetic_small):
    """The run carries its boxes, descriptors and Matching: a soft-NMS run's statistics use
    Algorithm 4 (a bare landmark set, Eq. (1)); a run without descriptors is refused."""
    from vpr_core.matching import Matching, match_landmarks
    from vpr_core.statistics import scale_statistics

    s = synthetic_small
    lm = _landmarks(s["boxes_query"], s["boxes_reference"], s["desc_query"], s["desc_reference"])
    nms = Matching(soft_nms_iou=0.3)
    run = SimpleNamespace(**vars(lm), config=SimpleNamespace(matching=nms))
    plain, soft = (scale_statistics(s["dataset"], r, n_irrelevant=1) for r in (lm, run))
    assert plain.meta["soft_nms_iou"] is None and soft.meta["soft_nms_iou"] == 0.3
    for st, m in ((plain, Matching()), (soft, nms)):
        df = st.matches_frame()
        got = df[(df.pair == "gt") & (df["query"] == 0)].score.to_numpy()
        args = (s["desc_query"][0], s["boxes_query"][0], s["desc_reference"][0])
        want = match_landmarks(*args, s["boxes_reference"][0], m).scores
        np.testing.assert_allclose(got, want)
    assert not np.allclose(
        plain.matches_frame().score.to_numpy()[:50], soft.matches_frame().score.to_numpy()[:50]
    )
    with pytest.raises(ValueError, match=r"keep_descriptors=True"):
        scale_statistics(s["dataset"], SimpleNamespace(boxes=lm.boxes, descriptors=None))
