"""Known-answer tests for vpr_core.landmarks (dense sampling, Table 1, Algorithms 1-3, IoU,
Edge Boxes)."""

from __future__ import annotations

import gzip

import numpy as np
import pytest

from vpr_core import landmarks as L
from vpr_core import paper
from vpr_core.boxes import paired_iou
from vpr_core.landmarks.edge_boxes import EdgeBoxes, edge_model_id
from vpr_core.landmarks.scales import scale_histogram

H, W = 360, 640
SIZE = (H, W)


# ------------------------------------------------------------------------------------------
# helpers / fixtures (kept local: tests/conftest.py belongs to another module owner)
# ------------------------------------------------------------------------------------------


def box_of_ratio(r: float, size=SIZE, x: float = 0.0, y: float = 0.0) -> list[float]:
    """A box whose area / image area is exactly ``r`` (full image width, height r*H)."""
    h_img, w_img = size
    return [x, y, float(w_img), r * h_img]


def boxes_of_ratios(ratios, size=SIZE) -> np.ndarray:
    return np.array([box_of_ratio(r, size) for r in ratios], dtype=float)


# Ratios chosen in the middle of each Table-1 bin.
MID = {1: 0.01, 2: 0.03, 3: 0.07, 4: 0.12, 5: 0.2, 6: 0.3, 7: 0.4, 8: 0.6, 9: 0.8}


@pytest.fixture(scope="module")
def synthetic_image() -> np.ndarray:
    """A 360x640 RGB image with a few filled / outlined rectangles on a grey background."""
    cv2 = pytest.importorskip("cv2")
    img = np.full((H, W, 3), 90, np.uint8)
    cv2.rectangle(img, (40, 40), (200, 160), (230, 40, 40), -1)
    cv2.rectangle(img, (260, 60), (420, 300), (20, 200, 60), -1)
    cv2.rectangle(img, (470, 120), (600, 330), (250, 250, 250), 3)
    cv2.rectangle(img, (80, 220), (220, 330), (10, 10, 120), -1)
    cv2.circle(img, (520, 60), 35, (240, 220, 0), -1)
    return img


@pytest.fixture(scope="module")
def eb_result(synthetic_image):
    return L.edge_boxes(synthetic_image, max_boxes=300, model="gradient")


def naive_iou(a, b):
    out = np.zeros((len(a), len(b)))
    for i, (x1, y1, w1, h1) in enumerate(a):
        for j, (x2, y2, w2, h2) in enumerate(b):
            iw = max(0.0, min(x1 + w1, x2 + w2) - max(x1, x2))
            ih = max(0.0, min(y1 + h1, y2 + h2) - max(y1, y2))
            inter = iw * ih
            union = w1 * h1 + w2 * h2 - inter
            out[i, j] = inter / union if union > 0 else 0.0
    return out


# ------------------------------------------------------------------------------------------
# dense sampling
# ------------------------------------------------------------------------------------------


def test_dense_known_answer_016_25():
    boxes = L.dense_sampling(SIZE, scales=(0.16,), per_scale=25)
    assert boxes.shape == (25, 4) and boxes.dtype == np.float64
    xs = [0, 96, 192, 288, 384]
    ys = [0, 54, 108, 162, 216]
    expected = np.array([[x, y, 256, 144] for y in ys for x in xs], dtype=float)
    np.testing.assert_allclose(boxes, expected, atol=1e-9)


def test_dense_default_paper_setting():
    boxes = L.dense_sampling(SIZE)
    assert boxes.shape == (100, 4)
    ratios = L.normalized_scale(boxes, SIZE)
    for k, a in enumerate((0.16, 0.25, 0.36, 0.49)):
        np.testing.assert_allclose(ratios[25 * k : 25 * (k + 1)], a, rtol=1e-12)
        blk = boxes[25 * k : 25 * (k + 1)]
        # first box at top-left, last flush with the far edges
        np.testing.assert_allclose(blk[0, :2], [0, 0], atol=1e-9)
        np.testing.assert_allclose(blk[-1, 0] + blk[-1, 2], W, atol=1e-9)
        np.testing.assert_allclose(blk[-1, 1] + blk[-1, 3], H, atol=1e-9)
        # aspect ratio of the image kept
        np.testing.assert_allclose(blk[:, 2] / blk[:, 3], W / H, rtol=1e-12)
    # all inside the image
    assert np.all(boxes[:, :2] >= -1e-9)
    assert np.all(boxes[:, 0] + boxes[:, 2] <= W + 1e-9)
    assert np.all(boxes[:, 1] + boxes[:, 3] <= H + 1e-9)


def test_dense_order_scale_then_row_then_x():
    boxes = L.dense_sampling(SIZE, scales=(0.25, 0.49), per_scale=9)
    assert boxes.shape == (18, 4)
    assert np.all(boxes[:9, 2] < boxes[9:, 2])  # scale by scale
    for blk in (boxes[:9], boxes[9:]):
        grid = blk.reshape(3, 3, 4)
        # within a row: y constant, x increasing; rows: y increasing
        assert np.all(np.diff(grid[:, :, 1], axis=1) == 0)
        assert np.all(np.diff(grid[:, :, 0], axis=1) > 0)
        assert np.all(np.diff(grid[:, 0, 1]) > 0)


def test_dense_single_box_is_centred():
    boxes = L.dense_sampling(SIZE, scales=(0.25,), per_scale=1)
    np.testing.assert_allclose(boxes, [[160, 90, 320, 180]], atol=1e-9)


def test_dense_per_scale_sequence_table3():
    boxes = L.dense_sampling(SIZE, per_scale=(36, 25, 25, 16))
    assert boxes.shape == (102, 4)
    ratios = L.normalized_scale(boxes, SIZE)
    np.testing.assert_allclose(ratios[:36], 0.16)
    np.testing.assert_allclose(ratios[-16:], 0.49)


BOX = np.array([[0.0, 0.0, 10.0, 10.0]])

#: (call, message) of every bad input of dense sampling, Table-1 scales, IoU and coverage.
BAD_LANDMARK_CALLS = {
    "dense: not square": (lambda: L.dense_sampling(SIZE, per_scale=24), "perfect square"),
    "dense: one not square": (
        lambda: L.dense_sampling(SIZE, per_scale=(25, 25, 20, 25)),
        r"Dense.per_scale must be perfect squares .*, got \(25, 25, 20, 25\)",
    ),
    "dense: zero": (lambda: L.dense_sampling(SIZE, per_scale=0), "per_scale must be a positive"),
    "dense: counts": (lambda: L.dense_sampling(SIZE, per_scale=(25, 25)), "one count per scale"),
    "dense: scale 0": (lambda: L.dense_sampling(SIZE, scales=(0.0, 0.5)), r"in \(0, 1\]"),
    "dense: scale > 1": (lambda: L.dense_sampling(SIZE, scales=(1.2,)), r"\(0, 1\]"),
    "dense: no scales": (lambda: L.dense_sampling(SIZE, scales=()), "non-empty sequence"),
    "size: one number": (lambda: L.dense_sampling((360,)), r"image_size must be a \(H, W\) pair"),
    "size: zero": (lambda: L.dense_sampling((0, 640)), "image_size must be positive integers"),
    "size: negative": (lambda: L.dense_sampling((-1, 5)), "image_size must be positive"),
    "size: fraction": (lambda: L.dense_sampling((360.5, 640)), "image_size must be positive"),
    "size: text": (lambda: L.dense_sampling("ab"), "image_size must hold integers"),
    "size: an image": (
        lambda: L.dense_sampling(np.zeros((H, W, 3), np.uint8)),
        r"pass image.shape\[:2\]",
    ),
    "select: min_index": (
        lambda: L.select_min_scale(BOX, SIZE, min_index=0),
        "MinScale.min_index must be a Table-1 scale index 1..9 .*, got 0",
    ),
    "select: order": (
        lambda: L.select_scale_priority(BOX, SIZE, order=(5, 5)),
        "ScalePriority.order must be a non-empty sequence of distinct",
    ),
    "select: n": (lambda: L.reduce_overlap(BOX, n=0), "ReduceOverlap.n must be a positive integer"),
    "select: boxes": (lambda: L.select_min_scale(np.zeros(7), SIZE), r"boxes must have shape"),
    "scale: no size": (lambda: L.scale_index(np.zeros((2, 4))), "pass image_size=\\(H, W\\)"),
    "scale: 2-D ratios": (lambda: L.scale_index(np.zeros((2, 3))), "1-D ratios"),
    "scale: negative": (lambda: L.scale_index(np.array([-0.1])), "finite and >= 0"),
    "scale: boxes": (
        lambda: L.normalized_scale(np.zeros((3, 3)), SIZE),
        r"boxes must have shape \(K, 4\)",
    ),
    "iou: shape": (lambda: L.box_iou(np.zeros((2, 5)), BOX), r"a must have shape \(K, 4\)"),
    "iou: negative": (lambda: L.box_iou(BOX, [[0, 0, -1, 2]]), "b has negative width"),
    "iou: NaN": (lambda: L.box_iou(BOX * np.nan, BOX), "a contains NaN"),
    "paired iou: rows": (
        lambda: paired_iou(BOX, np.zeros((2, 4))),
        "as many boxes in a as in b, got 1 and 2",
    ),
    "coverage: boxes": (
        lambda: L.landmark_coverage(np.zeros(7), SIZE),
        r"boxes must have shape \(K, 4\)",
    ),
    "coverage: size": (lambda: L.landmark_coverage(BOX, (0, 5)), "image_size must be positive"),
}


@pytest.mark.parametrize("case", BAD_LANDMARK_CALLS)
def test_bad_landmark_inputs_raise_one_clear_line(case):
    call, match = BAD_LANDMARK_CALLS[case]
    with pytest.raises(ValueError, match=match) as info:
        call()
    assert "\n" not in str(info.value)


def test_dense_accepts_image_shape():
    img = np.zeros((H, W, 3), np.uint8)
    np.testing.assert_array_equal(L.dense_sampling(img.shape), L.dense_sampling(SIZE))


# ------------------------------------------------------------------------------------------
# Table 1
# ------------------------------------------------------------------------------------------


def test_scale_edges_exported():
    assert paper.SCALE_EDGES == (0.02, 0.05, 0.09, 0.14, 0.23, 0.34, 0.5, 0.72)
    assert len(paper.SCALE_LABELS) == 9 and paper.SCALE_LABELS[0] == "Scale 1"
    assert paper.SCALE_RANGES[0] == (0.0, 0.02) and paper.SCALE_RANGES[-1] == (0.72, 1.0)


def test_scale_index_edges_lower_inclusive():
    edges = np.array(paper.SCALE_EDGES)
    np.testing.assert_array_equal(L.scale_index(edges), np.arange(2, 10))
    np.testing.assert_array_equal(L.scale_index(np.nextafter(edges, 0)), np.arange(1, 9))
    np.testing.assert_array_equal(L.scale_index(edges - 1e-9), np.arange(1, 9))
    assert L.scale_index(0.0) == 1
    assert L.scale_index(1.0) == 9
    assert L.scale_index(0.72) == 9
    assert L.scale_index(0.02) == 2
    assert L.scale_index(0.0199) == 1
    np.testing.assert_array_equal(L.scale_index(np.array(list(MID.values()))), list(MID))


def test_scale_index_from_boxes():
    # boxes with exact ratios: 0.5 * 0.5 = 0.25 -> scale 6; full image -> 9; 0.1 * 0.1 -> 1
    boxes = np.array([[0, 0, W / 2, H / 2], [0, 0, W, H], [5, 5, W / 10, H / 10]])
    np.testing.assert_array_equal(L.scale_index(boxes, SIZE), [6, 9, 1])
    np.testing.assert_allclose(L.normalized_scale(boxes, SIZE), [0.25, 1.0, 0.01])


def test_scale_histogram():
    ratios = [0.01, 0.01, 0.03, 0.2, 0.8, 0.72]
    hist = scale_histogram(boxes_of_ratios(ratios), SIZE)
    assert hist.shape == (10,)
    np.testing.assert_array_equal(hist, [0, 2, 1, 0, 0, 1, 0, 0, 0, 2])
    np.testing.assert_array_equal(scale_histogram(np.array(ratios)), hist)
    assert scale_histogram(np.zeros((0, 4)), SIZE).sum() == 0


# ------------------------------------------------------------------------------------------
# IoU
# ------------------------------------------------------------------------------------------


def test_box_iou_known_values():
    a = np.array([[0, 0, 10, 10]], float)
    b = np.array(
        [
            [0, 0, 10, 10],  # identical -> 1
            [20, 20, 5, 5],  # disjoint -> 0
            [5, 0, 10, 10],  # half overlap: inter 50, union 150 -> 1/3
            [10, 0, 10, 10],  # touching edge -> 0
            [0, 0, 5, 10],  # contained half -> 0.5
        ],
        float,
    )
    np.testing.assert_allclose(L.box_iou(a, b), [[1, 0, 1 / 3, 0, 0.5]], atol=1e-12)
    assert L.box_iou(a, np.zeros((0, 4))).shape == (1, 0)
    assert L.box_iou(np.zeros((0, 4)), b).shape == (0, 5)
    # two empty boxes: union 0 -> IoU 0 (no NaN)
    assert L.box_iou([[1, 1, 0, 0]], [[1, 1, 0, 0]])[0, 0] == 0.0


def test_box_iou_matches_naive_loop():
    rng = np.random.default_rng(0)

    def rand_boxes(k):
        xy = rng.uniform(0, 100, (k, 2))
        wh = rng.uniform(0, 60, (k, 2))
        return np.hstack([xy, wh])

    a, b = rand_boxes(37), rand_boxes(23)
    iou = L.box_iou(a, b)
    assert iou.shape == (37, 23)
    np.testing.assert_allclose(iou, naive_iou(a, b), atol=1e-12)
    np.testing.assert_allclose(L.box_iou(a, a).diagonal(), 1.0)
    np.testing.assert_allclose(L.box_iou(b, a), iou.T, atol=1e-12)


# ------------------------------------------------------------------------------------------
# Algorithm 1
# ------------------------------------------------------------------------------------------

# candidate scale indices in proposal order
CAND_SCALES = [1, 5, 2, 4, 9, 3, 6, 1, 7, 4, 8, 5]


def cand_boxes():
    return boxes_of_ratios([MID[s] for s in CAND_SCALES])


def test_select_min_scale_known_answer():
    boxes = cand_boxes()
    sel, idx = L.select_min_scale(boxes, SIZE, n=4, return_indices=True)
    np.testing.assert_array_equal(idx, [1, 3, 4, 6])
    np.testing.assert_array_equal(sel, boxes[idx])
    assert sel.shape == (4, 4)
    sel2 = L.select_min_scale(boxes, SIZE, n=3, min_index=6)
    np.testing.assert_array_equal(sel2, boxes[[4, 6, 8]])


def test_select_min_scale_undersupply():
    boxes = cand_boxes()
    sel, idx = L.select_min_scale(boxes, SIZE, n=100, return_indices=True)
    np.testing.assert_array_equal(idx, [1, 3, 4, 6, 8, 9, 10, 11])
    assert sel.shape == (8, 4)


def test_select_min_scale_edge_ratio_counts_as_scale4():
    # exactly 0.09 is Scale 4 (lower edge inclusive) -> selected; just below is Scale 3
    boxes = boxes_of_ratios([0.09 - 1e-6, 0.09, 0.14])
    _, idx = L.select_min_scale(boxes, SIZE, n=5, return_indices=True)
    np.testing.assert_array_equal(idx, [1, 2])


# ------------------------------------------------------------------------------------------
# Algorithm 2
# ------------------------------------------------------------------------------------------


def test_select_scale_priority_known_answer():
    boxes = cand_boxes()
    # order (5,6,7,8,9,4): scale 5 -> [1, 11], 6 -> [6], 7 -> [8], 8 -> [10], 9 -> [4], 4 -> [3, 9]
    sel, idx = L.select_scale_priority(boxes, SIZE, n=7, return_indices=True)
    np.testing.assert_array_equal(idx, [1, 11, 6, 8, 10, 4, 3])
    np.testing.assert_array_equal(sel, boxes[idx])
    # stops at n exactly, even in the middle of a scale
    _, idx = L.select_scale_priority(boxes, SIZE, n=1, return_indices=True)
    np.testing.assert_array_equal(idx, [1])
    _, idx = L.select_scale_priority(boxes, SIZE, n=3, order=(4, 1), return_indices=True)
    np.testing.assert_array_equal(idx, [3, 9, 0])


def test_select_scale_priority_undersupply():
    boxes = cand_boxes()
    sel, idx = L.select_scale_priority(boxes, SIZE, n=50, return_indices=True)
    np.testing.assert_array_equal(idx, [1, 11, 6, 8, 10, 4, 3, 9])  # scales 1-3 never taken
    assert sel.shape == (8, 4)
    with pytest.raises(ValueError, match="order"):
        L.select_scale_priority(boxes, SIZE, order=(5, 10))


# ------------------------------------------------------------------------------------------
# Algorithm 3
# ------------------------------------------------------------------------------------------


def test_reduce_overlap_known_answer():
    boxes = np.array(
        [
            [0, 0, 10, 10],  # 0 kept (first)
            [0, 0, 10, 10],  # 1 IoU 1 with 0 -> dropped
            [5, 0, 10, 10],  # 2 IoU 1/3 with 0 -> kept at t=0.5
            [50, 50, 10, 10],  # 3 disjoint -> kept
            [0, 0, 5, 10],  # 4 IoU 0.5 with 0 -> kept (<= t inclusive)
            [51, 50, 10, 10],  # 5 IoU 0.818 with 3 -> dropped
        ],
        float,
    )
    sel, idx = L.reduce_overlap(boxes, n=10, iou_threshold=0.5, return_indices=True)
    np.testing.assert_array_equal(idx, [0, 2, 3, 4])
    np.testing.assert_array_equal(sel, boxes[idx])
    _, idx = L.reduce_overlap(boxes, n=10, iou_threshold=0.3, return_indices=True)
    np.testing.assert_array_equal(idx, [0, 3])
    # stops at n
    _, idx = L.reduce_overlap(boxes, n=2, iou_threshold=0.5, return_indices=True)
    np.testing.assert_array_equal(idx, [0, 2])
    # t = 1 keeps everything
    _, idx = L.reduce_overlap(boxes, n=10, iou_threshold=1.0, return_indices=True)
    np.testing.assert_array_equal(idx, np.arange(6))


def test_reduce_overlap_matches_naive_greedy():
    rng = np.random.default_rng(1)
    boxes = np.hstack([rng.uniform(0, 200, (300, 2)), rng.uniform(5, 120, (300, 2))])
    iou = naive_iou(boxes, boxes)
    kept = []
    for i in range(len(boxes)):
        if len(kept) == 40:
            break
        if not kept or all(iou[i, j] <= 0.4 for j in kept):
            kept.append(i)
    _, idx = L.reduce_overlap(boxes, n=40, iou_threshold=0.4, return_indices=True)
    np.testing.assert_array_equal(idx, kept)


def test_reduce_overlap_empty_and_bad():
    sel, idx = L.reduce_overlap(np.zeros((0, 4)), n=5, return_indices=True)
    assert sel.shape == (0, 4) and idx.shape == (0,)
    with pytest.raises(ValueError, match="iou_threshold"):
        L.reduce_overlap(cand_boxes(), iou_threshold=1.5)
    with pytest.raises(ValueError, match=r"\(K, 4\)"):
        L.reduce_overlap(np.zeros(7))


# ------------------------------------------------------------------------------------------
# coverage
# ------------------------------------------------------------------------------------------


def test_landmark_coverage():
    cov = L.landmark_coverage([[0, 0, 4, 2], [2, 1, 4, 3]], (5, 8))
    expected = np.zeros((5, 8))
    expected[0:2, 0:4] += 1
    expected[1:4, 2:6] += 1
    np.testing.assert_array_equal(cov, expected)
    dense = L.landmark_coverage(L.dense_sampling(SIZE), SIZE)
    assert dense.shape == SIZE
    assert dense.min() >= 1  # dense sampling covers the whole image
    # total coverage equals the sum of (integer) box areas
    np.testing.assert_allclose(
        dense.sum(), (L.dense_sampling(SIZE)[:, 2:].prod(1)).sum(), rtol=0.02
    )


# ------------------------------------------------------------------------------------------
# Edge Boxes
# ------------------------------------------------------------------------------------------


def test_edge_boxes_synthetic(eb_result, synthetic_image):
    res = eb_result
    assert isinstance(res, EdgeBoxes)
    assert res.edge_source == "gradient"
    assert len(res) >= 20
    assert res.boxes.shape == (len(res), 4) and res.boxes.dtype == np.float64
    assert res.scores.shape == (len(res),)
    assert np.all(np.diff(res.scores) <= 0)  # proposal order = descending score
    b = np.asarray(res)
    np.testing.assert_array_equal(b, res.boxes)
    assert np.all(b[:, :2] >= 0)
    assert np.all(b[:, 2:] > 0)
    assert np.all(b[:, 0] + b[:, 2] <= W) and np.all(b[:, 1] + b[:, 3] <= H)
    # one of the proposals should hug the big green rectangle (260..420, 60..300)
    target = np.array([[260, 60, 161, 241]], float)
    assert L.box_iou(target, b).max() > 0.7


def test_edge_boxes_deterministic_and_prefix(eb_result, synthetic_image):
    again = L.edge_boxes(synthetic_image, max_boxes=300, model="gradient")
    np.testing.assert_array_equal(again.boxes, eb_result.boxes)
    np.testing.assert_array_equal(again.scores, eb_result.scores)
    top = L.edge_boxes(synthetic_image, max_boxes=20, model="gradient")
    assert len(top) == 20
    np.testing.assert_array_equal(top.boxes, eb_result.boxes[:20])


def test_edge_boxes_grayscale_and_env(synthetic_image, monkeypatch):
    monkeypatch.delenv("VPR_SED_MODEL", raising=False)
    gray = synthetic_image.mean(axis=2).astype(np.uint8)
    res = L.edge_boxes(gray, max_boxes=10)
    assert res.edge_source == "gradient" and 0 < len(res) <= 10


def test_edge_boxes_missing_model(synthetic_image, tmp_path, monkeypatch):
    missing = tmp_path / "nope" / "model.yml.gz"
    with pytest.raises(FileNotFoundError, match="model.yml.gz") as exc:
        L.edge_boxes(synthetic_image, model=missing)
    assert str(missing) in str(exc.value) and "opencv_extra" in str(exc.value)
    monkeypatch.setenv("VPR_SED_MODEL", str(missing))
    with pytest.raises(FileNotFoundError, match="VPR_SED_MODEL"):
        L.edge_boxes(synthetic_image)


def write_sed_model(path, n_trees: int = 1) -> None:
    """A tiny structured-edge forest in the opencv_extra ``model.yml.gz`` format: each tree splits
    on the gradient magnitude at the patch centre and paints a line through the inner patch."""
    bins = [y * 16 + 8 for y in range(16)] * 4  # repeated: a strong line
    trees = lambda row: "".join(f"   - {row}\n" for _ in range(n_trees))  # noqa: E731
    text = (
        "%YAML:1.0\noptions:\n"
        "   stride: 2\n   shrinkNumber: 2\n   patchSize: 32\n   patchInnerSize: 16\n"
        "   numberOfGradientOrientations: 4\n   gradientSmoothingRadius: 0\n"
        "   regFeatureSmoothingRadius: 2\n   ssFeatureSmoothingRadius: 8\n"
        "   gradientNormalizationRadius: 4\n   selfsimilarityGridSize: 5\n"
        f"   numberOfTrees: {n_trees}\n   numberOfTreesToEvaluate: {n_trees}\n"
        "childs:\n"
        + trees("[ 2, 0, 0 ]")
        + "featureIds:\n"
        + trees("[ 904, 0, 0 ]")
        + "thresholds:\n"
        + trees("[ 0.05, 0., 0. ]")
        + "edgeBoundaries:\n"
        + trees(f"[ 0, 0, 0, {len(bins)} ]")
        + "edgeBins:\n"
        + trees(str(bins))
    )
    with gzip.open(path, "wt") as fh:
        fh.write(text)


def test_edge_boxes_structured_model_end_to_end(synthetic_image, tmp_path, monkeypatch):
    model = tmp_path / "model.yml.gz"
    write_sed_model(model, n_trees=2)
    res = L.edge_boxes(synthetic_image, max_boxes=50, model=model)
    assert res.edge_source == "structured" and 0 < len(res) <= 50
    b = res.boxes
    assert np.all(b[:, :2] >= 0) and np.all(b[:, 0] + b[:, 2] <= W)
    assert np.all(np.diff(res.scores) <= 0)
    monkeypatch.setenv("VPR_SED_MODEL", str(model))
    again = L.edge_boxes(synthetic_image, max_boxes=50)
    np.testing.assert_array_equal(again.boxes, res.boxes)
    assert edge_model_id() == edge_model_id(model) != "gradient"
    assert edge_model_id("gradient") == "gradient"


@pytest.mark.parametrize(
    "content",
    [
        b"garbage \x00\xff{{[",  # not a FileStorage
        b"%YAML:1.0\nfoo: 1\n",  # no options (OpenCV would divide by zero and kill the process)
        b"%YAML:1.0\noptions:\n   numberOfTrees: 0\n",
    ],
)
def test_edge_boxes_unreadable_model_names_file_and_variable(synthetic_image, tmp_path, content):
    model = tmp_path / "model.yml"
    model.write_bytes(content)
    with pytest.raises(ValueError, match="VPR_SED_MODEL") as exc:
        L.edge_boxes(synthetic_image, model=model)
    assert str(model) in str(exc.value) and "\n" not in str(exc.value)


def test_edge_boxes_model_with_missing_trees_refused(synthetic_image, tmp_path):
    model = tmp_path / "model.yml.gz"
    write_sed_model(model, n_trees=1)
    with gzip.open(model, "rt") as fh:
        text = fh.read().replace("numberOfTrees: 1", "numberOfTrees: 3")
    text = text.replace("numberOfTreesToEvaluate: 1", "numberOfTreesToEvaluate: 3")
    with gzip.open(model, "wt") as fh:
        fh.write(text)
    with pytest.raises(ValueError, match="childs"):
        L.edge_boxes(synthetic_image, model=model)


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((10, 10, 4), np.uint8),
        np.zeros((10, 10, 3), np.float32),
        np.zeros((10,), np.uint8),
        np.zeros((2, 10, 10, 3), np.uint8),
    ],
)
def test_edge_boxes_bad_image(bad):
    with pytest.raises(ValueError, match="image"):
        L.edge_boxes(bad)


def test_edge_boxes_bad_params(synthetic_image):
    with pytest.raises(ValueError, match="unknown edge_boxes option"):
        L.edge_boxes(synthetic_image, alhpa=0.5)


def test_edge_boxes_blank_image():
    res = L.edge_boxes(np.full((60, 80, 3), 128, np.uint8), max_boxes=10)
    assert len(res) == 0 and res.boxes.shape == (0, 4)


# ------------------------------------------------------------------------------------------
# the paper's defaults (vpr_core.paper) on real Edge Box candidates
# ------------------------------------------------------------------------------------------


def test_dense_defaults_are_the_papers():
    from vpr_core.paper import DENSE_PER_SCALE, DENSE_SCALES

    b = L.dense_sampling(SIZE)
    np.testing.assert_array_equal(b, L.dense_sampling(SIZE, DENSE_SCALES, DENSE_PER_SCALE))
    assert b.shape == (len(DENSE_SCALES) * DENSE_PER_SCALE, 4)
    np.testing.assert_allclose(np.unique(L.normalized_scale(b, SIZE)), DENSE_SCALES)
    assert L.dense_sampling(SIZE, per_scale=16).shape == (16 * len(DENSE_SCALES), 4)


def test_box_iou_is_the_one_in_vpr_core_boxes():
    from vpr_core import boxes

    assert L.box_iou is boxes.box_iou


# ------------------------------------------------------------------------------------------
# plots (vpr_study.viz, landmarks section)
# ------------------------------------------------------------------------------------------


def test_landmark_plots(synthetic_image, tmp_path):
    viz = pytest.importorskip("vpr_study.viz")
    import matplotlib.pyplot as plt

    boxes = L.dense_sampling(SIZE)
    figs = [
        viz.plot_dense_scales(SIZE),
        viz.plot_dense_scales(synthetic_image, scales=(0.25, 0.49), per_scale=(16, 9)),
        viz.plot_coverage(synthetic_image, boxes),
        viz.plot_scale_distribution(
            {"query": scale_histogram(boxes, SIZE), "reference": np.arange(10)}, "dist"
        ),
    ]
    assert len(figs[0].axes) == 4
    a = viz.save_figure(viz.plot_dense_scales(SIZE), tmp_path / "a.png")
    b = viz.save_figure(viz.plot_dense_scales(SIZE), tmp_path / "b.png")
    assert a.read_bytes() == b.read_bytes()  # deterministic
    with pytest.raises(ValueError):
        viz.plot_scale_distribution({"q": np.ones(5)})
    plt.close("all")


def test_gradient_edge_map_is_the_same_bits_on_every_simd_path():
    """OpenCV's float filters differ in the last bit between its SIMD paths, and that moved Edge
    Boxes proposals from one CPU to another; the gradient map is filtered in float64 by numpy, so
    turning OpenCV's optimised paths off changes no bit. Same operator as cv2's, to float32."""
    import cv2

    from vpr_core.landmarks import _edge_map as eb

    rng = np.random.default_rng(3)
    img = cv2.GaussianBlur(rng.integers(0, 256, (90, 160, 3), dtype=np.uint8), (0, 0), 3)
    base = L.edge_boxes(img).boxes, *eb.gradient_edges(img, nms=False)
    cv2.setUseOptimized(False)
    try:
        plain = L.edge_boxes(img).boxes, *eb.gradient_edges(img, nms=False)
    finally:
        cv2.setUseOptimized(True)
    for a, b in zip(base, plain, strict=True):
        np.testing.assert_array_equal(a, b)
    g = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float64) / 255.0
    ours = eb._correlate(eb._correlate(g, eb._gaussian_taps(2.0), 1), eb._gaussian_taps(2.0), 0)
    theirs = cv2.GaussianBlur(g, (0, 0), 2.0)
    np.testing.assert_allclose(ours, theirs, atol=1e-9)
    dx = eb._correlate(eb._correlate(ours, eb.SCHARR_DIFF, 1), eb.SCHARR_SMOOTH, 0)
    np.testing.assert_allclose(dx, cv2.Scharr(theirs, cv2.CV_64F, 1, 0), atol=1e-8)
