"""Tests of vpr_core.labels: exact, geometric and file labels, the dispatcher, the CSV helper."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pytest

from vpr_core.boxes import paired_iou
from vpr_core.labels import (
    LABEL_METHODS,
    LabelRule,
    LabelUnavailableError,
    append_labels,
    estimate_pair_geometry,
    label_matches,
    label_matches_geometric,
    pair_matches,
    resolve_label_method,
)
from vpr_core.labels._exact import map_boxes
from vpr_core.labels._file import read_label_file
from vpr_core.labels._geometric import PairGeometry, Verification, _homography_is_sane

# ---------------------------------------------------------------------------------------------
# A tiny fake dataset with known geometry
# ---------------------------------------------------------------------------------------------


@dataclass
class FakeDataset:
    """Minimal PlaceDataset stand-in: 3 queries / 3 references, query i <-> reference i."""

    ground_truth: np.ndarray
    homographies: np.ndarray | None
    size: tuple[int, int] = (200, 300)
    name: str = "fake"
    tolerance: int | None = 0
    images: dict = field(default_factory=dict)

    def image_size(self, side: str, i: int) -> tuple[int, int]:
        return self.size

    def load_image(self, side: str, i: int) -> np.ndarray:
        return self.images[(side, i)]


def translation(tx: float, ty: float) -> np.ndarray:
    return np.array([[1.0, 0.0, tx], [0.0, 1.0, ty], [0.0, 0.0, 1.0]])


@pytest.fixture
def fake() -> FakeDataset:
    H = np.stack([translation(30, -10)] * 3)
    return FakeDataset(ground_truth=np.eye(3, dtype=bool), homographies=H)


# ---------------------------------------------------------------------------------------------
# exact labels
# ---------------------------------------------------------------------------------------------


def test_map_boxes_and_iou():
    b = np.array([[10.0, 20.0, 50.0, 40.0]])
    np.testing.assert_allclose(map_boxes(b, translation(5, -3)), [[15, 17, 50, 40]])
    # zoom 2 about the origin, clipped to a 60 x 80 image (H, W)
    np.testing.assert_allclose(map_boxes(b, np.diag([2.0, 2.0, 1.0]), (60, 80)), [[20, 40, 60, 20]])
    np.testing.assert_allclose(paired_iou(b, b + [[25, 0, 0, 0]]), [25 * 40 / (2 * 2000 - 1000)])


def test_exact_labels_translation(fake):
    boxes_q = np.array(
        [[50.0, 60.0, 100.0, 80.0], [10.0, 10.0, 40.0, 40.0], [280.0, 150.0, 60.0, 60.0]]
    )
    boxes_r = np.array(
        [
            [80.0, 50.0, 100.0, 80.0],  # box 0 shifted by (30, -10): IoU 1
            [200.0, 120.0, 60.0, 60.0],  # elsewhere
            [40.0, 0.0, 40.0, 40.0],  # box 1 shifted -> (40, 0, 40, 40), IoU 1
            [
                290.0,
                130.0,
                10.0,
                70.0,
            ],  # box 2 mapped (310, 140) clipped to (300, 200): (300,140,0,60)
            [100.0, 50.0, 100.0, 80.0],  # box 0 mapped vs this: IoU = 80*80/(2*8000-6400) = 0.667
            [120.0, 50.0, 100.0, 80.0],  # IoU = 60*80/(16000-4800) = 0.43
        ]
    )
    matches = np.array([[0, 0], [0, 1], [1, 2], [2, 3], [0, 4], [0, 5], [1, 0]])
    lab = label_matches(fake, 0, 0, boxes_q, boxes_r, matches)  # auto -> exact
    np.testing.assert_array_equal(lab, [True, False, True, False, True, False, False])
    # threshold is respected
    lab = label_matches(fake, 0, 0, boxes_q, boxes_r, matches, method="exact", iou_threshold=0.4)
    assert lab[5]
    # ... given as a LabelRule value too (not both)
    rule = LabelRule(iou_threshold=0.4)
    np.testing.assert_array_equal(
        label_matches(fake, 0, 0, boxes_q, boxes_r, matches, rule=rule), lab
    )
    with pytest.raises(ValueError, match="not both"):
        label_matches(fake, 0, 0, boxes_q, boxes_r, matches, rule=rule, iou_threshold=0.4)
    with pytest.raises(ValueError, match="iou_threshold must be in"):
        LabelRule(iou_threshold=1.5)
    # non-ground-truth pair: every match incorrect by definition
    assert not label_matches(fake, 0, 1, boxes_q, boxes_r, matches).any()
    # empty matches
    assert label_matches(fake, 0, 0, boxes_q, boxes_r, np.zeros((0, 2), int)).shape == (0,)


# ---------------------------------------------------------------------------------------------
# method dispatch
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# file labels
# ---------------------------------------------------------------------------------------------


def write_csv(path, text: str):
    path.write_text(text)
    return path


CSV = """query,reference,query_box_index,reference_box_index,correct
0,0,0,0,1
0,0,1,2,0
0,0,2,3,true
1,1,0,0,0
"""


def test_file_labels(tmp_path, fake):
    p = write_csv(tmp_path / "labels.csv", CSV)
    b = np.zeros((4, 4))
    lab = label_matches(fake, 0, 0, b, b, [[2, 3], [0, 0], [1, 2]], method="file", labels=p)
    np.testing.assert_array_equal(lab, [True, True, False])
    # auto picks file when there are no homographies and labels are given
    fake.homographies = None
    lab = label_matches(fake, 1, 1, b, b, [[0, 0]], labels=p)
    np.testing.assert_array_equal(lab, [False])
    # a labelled pair that is not among the matches -> warning only
    with pytest.warns(UserWarning, match="not among the matches"):
        lab = label_matches(fake, 0, 0, b, b, [[0, 0]], labels=p)
    assert lab.tolist() == [True]


# ---------------------------------------------------------------------------------------------
# geometric labels on a warped real texture (no dataset module needed)
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def warped_pair():
    import cv2
    from skimage import data

    img = data.astronaut()[:360:, :480]  # (360, 480, 3)
    img = np.ascontiguousarray(img)
    H = np.array([[0.95, 0.04, 18.0], [-0.03, 0.97, -12.0], [1e-5, 2e-5, 1.0]])
    h, w = img.shape[:2]
    warped = cv2.warpPerspective(img, H, (w, h))
    dark = (warped.astype(np.float32) * 0.45 + 10).clip(0, 255).astype(np.uint8)  # "night"
    return img, dark, H


def test_geometric_homography_matches_exact(warped_pair):
    img_q, img_r, H = warped_pair
    geo = estimate_pair_geometry(img_q, img_r)
    assert geo.kind == "homography" and geo.n_inliers_h >= 50
    # estimated homography maps points like the true one (within a few pixels)
    pts = np.array([[50.0, 50.0, 1.0], [400.0, 300.0, 1.0], [240.0, 180.0, 1.0]])
    a, b = pts @ H.T, pts @ geo.homography.T
    assert np.abs(a[:, :2] / a[:, 2:] - b[:, :2] / b[:, 2:]).max() < 3.0
    rng = np.random.default_rng(0)
    boxes_q = np.column_stack(
        [
            rng.uniform(0, 300, 40),
            rng.uniform(0, 200, 40),
            rng.uniform(40, 160, 40),
            rng.uniform(40, 140, 40),
        ]
    )
    true_r = map_boxes(boxes_q, H, (360, 480))
    boxes_r = np.concatenate([true_r, true_r[rng.permutation(40)] + rng.normal(0, 3, (40, 4))])
    matches = np.column_stack([np.r_[np.arange(40), np.arange(40)], np.arange(80)])
    ds = FakeDataset(np.eye(1, dtype=bool), H[None], size=(360, 480))
    exact = label_matches(ds, 0, 0, boxes_q, boxes_r, matches, method="exact")
    geom = label_matches(
        ds, 0, 0, boxes_q, boxes_r, matches, method="geometric", images=(img_q, img_r)
    )
    assert (exact == geom).mean() >= 0.95
    # the point rule (forced) agrees well too on this planar pair
    pts_lab = label_matches_geometric(boxes_q, boxes_r, matches, geo, LabelRule(model="points"))
    assert (exact == pts_lab).mean() >= 0.8
    # cache: a second call reuses the geometry
    cache: dict = {}
    label_matches(
        ds,
        0,
        0,
        boxes_q,
        boxes_r,
        matches,
        method="geometric",
        images=(img_q, img_r),
        geometry_cache=cache,
    )
    assert cache[(0, 0)].kind == "homography"
    # non-ground-truth pair: all incorrect without matching images
    ds.ground_truth = np.zeros((1, 1), dtype=bool)
    assert not label_matches(ds, 0, 0, boxes_q, boxes_r, matches, method="geometric").any()


def test_geometric_point_rule_by_hand():
    pq = np.array([[10.0, 10.0], [12, 14], [15, 11], [18, 18], [80, 80]])
    pr = pq + 100.0
    geo = PairGeometry("fundamental", None, np.eye(3), pq, pr, 5, 0, 5, (200, 200), (200, 200))
    bq = np.array([[5.0, 5.0, 20.0, 20.0], [70.0, 70.0, 20.0, 20.0]])
    br = np.array([[105.0, 105.0, 20.0, 20.0], [170.0, 170.0, 20.0, 20.0], [0, 0, 200, 200.0]])
    # (0,0): 4 inliers in both boxes, point-IoU 1 -> correct
    # (1,1): 1 inlier only (< min_points 3) -> incorrect
    # (0,2): 4 of 5 reference points inside the big box, point-IoU 4/5 -> correct
    # (0,1): none -> incorrect
    lab = label_matches_geometric(bq, br, [[0, 0], [1, 1], [0, 2], [0, 1]], geo)
    assert lab.tolist() == [True, False, True, False]
    lab = label_matches_geometric(bq, br, [[0, 2]], geo, LabelRule(point_iou=0.9))
    assert lab.tolist() == [False]


def test_geometric_unrelated_images_have_no_homography():
    from skimage import data

    a = np.ascontiguousarray(data.astronaut()[:300, :400])
    b = np.ascontiguousarray(data.coffee()[:300, :400])
    geo = estimate_pair_geometry(a, b)
    assert geo.kind in ("none", "fundamental")


def test_geometric_on_real_day_night_pairs(gardens_point_mini_root):
    """Real Gardens Point day-vs-night: irrelevant pairs must not get a geometry by chance; a
    ground-truth pair is either labelled or reported unlabelled (never a crash)."""
    from vpr_core.datasets import load_dataset

    ds = load_dataset("folder", gardens_point_mini_root)
    for q, r in ((0, 5), (3, 8)):
        geo = estimate_pair_geometry(ds.load_image("query", q), ds.load_image("reference", r))
        assert geo.kind == "none", (q, r, geo.n_putative, geo.n_inliers_h, geo.n_inliers_f)
    b = np.array([[100.0, 100.0, 300.0, 200.0]])
    try:
        lab = label_matches(ds, 0, 0, b, b * 2 / 3, [[0, 0]])  # auto -> geometric
        assert lab.dtype == bool and lab.shape == (1,)
    except LabelUnavailableError as e:
        assert "no two-view geometry" in str(e)


def test_labelling_helper_csv_round_trips_through_file_labels(tmp_path, tiny_synthetic):
    boxes = np.array([[0, 0, 10, 10], [5, 5, 20, 20], [30, 30, 5, 5]], float)
    matches = np.array([[0, 1], [2, 0]])
    path = append_labels(tmp_path / "labels.csv", 0, 0, matches, [True, False])
    got = label_matches(tiny_synthetic, 0, 0, boxes, boxes, matches, method="file", labels=path)
    assert got.tolist() == [True, False]


def test_resolve_label_method(fake):
    assert LABEL_METHODS == ("auto", "exact", "geometric", "file")
    assert resolve_label_method(fake, "auto", None) == "exact"
    fake.homographies = None
    assert resolve_label_method(fake, "auto", "labels.csv") == "file"
    assert resolve_label_method(fake, "auto", None) == "geometric"
    assert resolve_label_method(fake, "file", None) == "file"


def test_homography_sanity_rejects_degenerate_maps():
    size = (100, 200)
    assert _homography_is_sane(np.eye(3), size)
    assert not _homography_is_sane(np.diag([-1.0, 1.0, 1.0]), size)  # mirrored outline
    assert not _homography_is_sane(np.diag([10.0, 10.0, 1.0]), size)  # area x100
    assert not _homography_is_sane(np.full((3, 3), np.nan), size)


# ---------------------------------------------------------------------------------------------
# every bad input of the labels boundary: one clear error line each
# ---------------------------------------------------------------------------------------------

B1 = np.array([[0.0, 0.0, 10.0, 10.0]])
B3 = np.zeros((3, 4))
NO_GEOMETRY = PairGeometry(
    "none", None, None, np.zeros((0, 2)), np.zeros((0, 2)), 3, 0, 0, (200, 200), (200, 200)
)


def _file(tmp_path, text: str = CSV):
    return write_csv(tmp_path / "labels.csv", text)


def _tolerance_pair(fake, tmp_path):
    fake.ground_truth = np.array([[1, 1, 0], [1, 1, 1], [0, 1, 1]], dtype=bool)
    label_matches(fake, 0, 1, B1, B1, [[0, 0]], method="exact")


def _no_homographies(fake, tmp_path):
    fake.homographies = None
    label_matches(fake, 0, 0, B1, B1, [[0, 0]], method="exact")


def _no_descriptors(fake, tmp_path):
    pair_matches(fake, SimpleNamespace(descriptors=None, label="dense"))


def _no_ground_truth_reference(fake, tmp_path):
    fake.ground_truth = np.zeros((3, 3), dtype=bool)
    pair_matches(fake, SimpleNamespace(descriptors={}, boxes={}, label="dense"), query=1)


#: id -> (call(fake, tmp_path), exception, message)
BAD_LABEL_CALLS = {
    "method": (
        lambda f, t: label_matches(f, 0, 0, B1, B1, [[0, 0]], method="manual"),
        ValueError,
        "unknown label method 'manual'; valid: auto, exact, geometric, file",
    ),
    "resolve method": (
        lambda f, t: resolve_label_method(f, "hand", None),
        ValueError,
        "valid: auto, exact",
    ),
    "boxes shape": (
        lambda f, t: label_matches(f, 0, 0, B1[:, :3], B1, [[0, 0]]),
        ValueError,
        r"boxes_q must have shape \(K, 4\)",
    ),
    "boxes NaN": (
        lambda f, t: label_matches(f, 0, 0, B1, B1 * np.nan, [[0, 0]]),
        ValueError,
        "boxes_r contains NaN",
    ),
    "boxes negative": (
        lambda f, t: label_matches(f, 0, 0, [[0, 0, -1, 2]], B1, [[0, 0]]),
        ValueError,
        "boxes_q has negative width",
    ),
    "matches shape": (
        lambda f, t: label_matches(f, 0, 0, B1, B1, [0, 0, 0]),
        ValueError,
        r"matches must have shape \(P, 2\)",
    ),
    "match index": (
        lambda f, t: label_matches(f, 0, 0, B1, B1, [[0, 3]]),
        ValueError,
        r"reference boxes outside 0\.\.0",
    ),
    "pair outside ground truth": (
        lambda f, t: label_matches(f, 5, 0, B1, B1, [[0, 0]]),
        IndexError,
        r"pair \(q=5, r=0\) outside the ground truth of shape \(3, 3\)",
    ),
    "exact: option": (
        lambda f, t: label_matches(f, 0, 0, B1, B1, [[0, 0]], method="exact", on_unmatched="warn"),
        ValueError,
        "unknown exact label option\\(s\\) 'on_unmatched'; valid: image_size_r",
    ),
    "file: option": (
        lambda f, t: label_matches(
            f, 0, 0, B1, B1, [[0, 0]], method="file", labels="x.csv", model="points"
        ),
        ValueError,
        "unknown file label option\\(s\\) 'model'; valid: on_unmatched",
    ),
    "exact: tolerance pair": (_tolerance_pair, LabelUnavailableError, "homography is known for"),
    "exact: no homographies": (
        _no_homographies,
        LabelUnavailableError,
        "need dataset.homographies",
    ),
    "geometric: no geometry": (
        lambda f, t: label_matches_geometric(B1, B1, [[0, 0]], NO_GEOMETRY),
        LabelUnavailableError,
        "no two-view geometry",
    ),
    "geometric: model": (
        lambda f, t: label_matches_geometric(B1, B1, [[0, 0]], NO_GEOMETRY, LabelRule(model="box")),
        ValueError,
        "unknown model 'box'; valid: auto, homography, points",
    ),
    "geometric: estimator": (
        lambda f, t: Verification(robust="lmeds"),
        ValueError,
        "unknown robust estimator 'lmeds'; valid: ransac, magsac",
    ),
    "geometric: unknown option": (
        lambda f, t: label_matches(f, 0, 1, B3, B3, [[0, 0]], method="geometric", ratios=0.7),
        ValueError,
        r"unknown geometric label option\(s\) 'ratios'; valid: images, geometry, .*, ratio,",
    ),
    "geometric: option twice": (
        lambda f, t: label_matches(
            f, 0, 0, B3, B3, [[0, 0]], method="geometric", verification=Verification(), ratio=0.7
        ),
        ValueError,
        "give verification=Verification",
    ),
    "rule: not a LabelRule": (
        lambda f, t: label_matches(f, 0, 0, B1, B1, [[0, 0]], method="exact", rule=0.5),
        TypeError,
        r"rule must be a LabelRule\(...\), got float",
    ),
    "geometric: verification not a Verification": (
        lambda f, t: label_matches(
            f, 0, 0, B3, B3, [[0, 0]], method="geometric", verification={"ratio": 0.7}
        ),
        TypeError,
        r"verification must be a Verification\(...\), got dict",
    ),
    "file: no labels": (
        lambda f, t: label_matches(f, 0, 0, B3, B3, [[0, 0]], method="file"),
        ValueError,
        "method='file' needs labels=<path to CSV> with header",
    ),
    "file: on_unmatched": (
        lambda f, t: label_matches(
            f, 0, 0, B3, B3, [[0, 0]], method="file", labels=_file(t), on_unmatched="x"
        ),
        ValueError,
        "unknown on_unmatched 'x'; valid: warn, ignore, error",
    ),
    "file: no row": (
        lambda f, t: label_matches(
            f,
            0,
            0,
            np.zeros((4, 4)),
            np.zeros((4, 4)),
            [[0, 0], [3, 3]],
            labels=_file(t),
            method="file",
        ),
        ValueError,
        "1 of 2 matches of pair .* have no label row",
    ),
    "file: unmatched label": (
        lambda f, t: label_matches(
            f,
            0,
            0,
            np.zeros((4, 4)),
            np.zeros((4, 4)),
            [[0, 0]],
            method="file",
            labels=_file(t),
            on_unmatched="error",
        ),
        ValueError,
        "labelled pair.* are not among the matches",
    ),
    "file: index out of range": (
        lambda f, t: label_matches(f, 0, 0, B3, B3, [[0, 0]], method="file", labels=_file(t)),
        ValueError,
        "box index out of range .* labels of another landmark set",
    ),
    "file: header": (
        lambda f, t: read_label_file(_file(t, "q,r,i,j,ok\n0,0,0,0,1\n")),
        ValueError,
        "expected header 'query,reference,query_box_index,reference_box_index,correct'",
    ),
    "file: integers": (
        lambda f, t: read_label_file(_file(t, CSV.replace("1,1,0,0", "1,x,0,0"))),
        ValueError,
        "column 'reference' must hold integers",
    ),
    "file: boolean": (
        lambda f, t: read_label_file(_file(t, CSV.replace("true", "maybe"))),
        ValueError,
        "'correct' value 'maybe' is not a boolean",
    ),
    "file: contradiction": (
        lambda f, t: label_matches(
            f,
            0,
            0,
            np.zeros((4, 4)),
            np.zeros((4, 4)),
            [[0, 0]],
            method="file",
            labels=_file(t, CSV + "0,0,0,0,0\n"),
        ),
        ValueError,
        r"labels match \(0, 0\) both correct and incorrect",
    ),
    "append: label count": (
        lambda f, t: append_labels(t / "x.csv", 0, 0, [[0, 1], [2, 0]], [True]),
        ValueError,
        "2 matches but 1 labels: give one label per match",
    ),
    "pair: no descriptors": (
        _no_descriptors,
        ValueError,
        "pair_matches needs the landmark descriptors of 'dense': run it with run_method",
    ),
    "pair: no reference": (
        _no_ground_truth_reference,
        ValueError,
        "query 1 has no ground-truth reference; pick another query",
    ),
}


@pytest.mark.parametrize("case", BAD_LABEL_CALLS)
def test_bad_label_inputs_raise_one_clear_line(case, fake, tmp_path):
    call, exc, match = BAD_LABEL_CALLS[case]
    with pytest.raises(exc, match=match) as info:
        call(fake, tmp_path)
    assert "\n" not in str(info.value)
