"""Landmark schemes as values: parameter checks, the paper's algorithms, a user's scheme run
end to end."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vpr_core import run_method
from vpr_core.datasets import load_dataset
from vpr_core.evaluation import compare
from vpr_core.features import get_encoder
from vpr_core.landmarks import (
    Dense,
    EdgeBoxesTop,
    MinScale,
    ReduceOverlap,
    ScalePriority,
    WholeImage,
    dense_sampling,
    edge_boxes,
    extract_landmarks,
    reduce_overlap,
    scale_index,
    select_min_scale,
    select_scale_priority,
)
from vpr_core.landmarks.schemes import check_scheme, scheme_identity
from vpr_core.utils import code_version
from vpr_study.peers import peer_result

SIZE = (360, 640)


@pytest.mark.parametrize(
    ("cls", "kwargs", "match"),
    [
        (EdgeBoxesTop, {"n": 0}, "EdgeBoxesTop.n must be a positive integer, got 0"),
        (EdgeBoxesTop, {"n": 2.5}, "EdgeBoxesTop.n must be .*, got 2.5"),
        (EdgeBoxesTop, {"n": True}, "EdgeBoxesTop.n must be .*, got True"),
        (EdgeBoxesTop, {"n_candidates": -1}, "EdgeBoxesTop.n_candidates must be .*, got -1"),
        (MinScale, {"min_index": 0}, "MinScale.min_index must be a Table-1 scale index 1..9"),
        (MinScale, {"min_index": 10}, "MinScale.min_index must be .*, got 10"),
        (ScalePriority, {"order": "5,6"}, "ScalePriority.order must be .*, got '5,6'"),
        (ScalePriority, {"order": ()}, "ScalePriority.order must be .*, got \\(\\)"),
        (ScalePriority, {"order": (5, 5)}, "distinct"),
        (ScalePriority, {"order": (0, 5)}, "ScalePriority.order must be .*, got \\(0, 5\\)"),
        (
            ReduceOverlap,
            {"iou_threshold": 1.5},
            "ReduceOverlap.iou_threshold must be a number in \\[0, 1\\], got 1.5",
        ),
        (ReduceOverlap, {"iou_threshold": "0.4"}, "ReduceOverlap.iou_threshold .*, got '0.4'"),
        (ReduceOverlap, {"n": None}, "ReduceOverlap.n must be a positive integer, got None"),
        (Dense, {"scales": 0.25}, "Dense.scales must be .*normalised scales .*, got 0.25"),
        (Dense, {"scales": ()}, "Dense.scales must be .*, got \\(\\)"),
        (Dense, {"scales": (0.2, 1.5)}, "in \\(0, 1\\]"),
        (Dense, {"scales": ("a",)}, "Dense.scales must be"),
        (Dense, {"scales": (float("nan"),)}, "Dense.scales must be"),
        (Dense, {"per_scale": "25"}, "Dense.per_scale must be a positive integer, got '25'"),
        (Dense, {"per_scale": 24}, "perfect squares"),
        (Dense, {"per_scale": (25, 16)}, "one count per scale \\(4\\)"),
        (Dense, {"scales": (0.25,), "per_scale": (24,)}, "perfect squares"),
    ],
)
def test_every_scheme_refuses_bad_parameters_when_made(cls, kwargs, match):
    with pytest.raises(ValueError, match=match):
        cls(**kwargs)


def test_schemes_parse_their_options_into_hashable_values():
    d = Dense(scales=[0.25, 0.49], per_scale=[49, 36])
    assert d.scales == (0.25, 0.49) and d.per_scale == (49, 36)
    assert Dense(scales=[1], per_scale=np.int64(4)) == Dense(scales=(1.0,), per_scale=4)
    assert ScalePriority(order=[6, 5]).order == (6, 5)
    assert ReduceOverlap(iou_threshold=1).iou_threshold == 1.0
    assert len({Dense(), Dense(), WholeImage(), EdgeBoxesTop()}) == 3
    with pytest.raises(dataclasses.FrozenInstanceError):
        Dense().per_scale = 9  # type: ignore[misc]


def test_defaults_are_the_papers():
    from vpr_core import paper

    assert EdgeBoxesTop() == EdgeBoxesTop(paper.N_LANDMARKS, paper.N_CANDIDATES)
    assert MinScale() == MinScale(100, paper.MIN_SCALE_INDEX, 1000)
    assert ScalePriority().order == paper.SCALE_PRIORITY_ORDER
    assert ReduceOverlap().iou_threshold == paper.NMS_IOU
    assert Dense() == Dense(paper.DENSE_SCALES, paper.DENSE_PER_SCALE)


def test_candidate_schemes_select_by_their_algorithm():
    rng = np.random.default_rng(3)
    cands = np.concatenate([rng.uniform(0, 300, (200, 2)), rng.uniform(10, 300, (200, 2))], 1)
    np.testing.assert_array_equal(EdgeBoxesTop(n=7).select(cands, SIZE), cands[:7])
    np.testing.assert_array_equal(
        MinScale(n=20).select(cands, SIZE), select_min_scale(cands, SIZE, n=20)
    )
    np.testing.assert_array_equal(
        ScalePriority(n=20, order=(6, 5)).select(cands, SIZE),
        select_scale_priority(cands, SIZE, n=20, order=(6, 5)),
    )
    o = ReduceOverlap(n=20, iou_threshold=0.3).select(cands, SIZE)
    np.testing.assert_array_equal(o, reduce_overlap(cands, n=20, iou_threshold=0.3))
    assert (scale_index(MinScale(n=20).select(cands, SIZE), SIZE) >= 4).all()


def test_a_scheme_checks_once_when_made_and_trusts_its_options_per_image(monkeypatch):
    """Issue 47: the per-image path (``select`` / ``for_size``) runs no check again."""
    import vpr_core.boxes
    import vpr_core.landmarks.scales
    import vpr_core.landmarks.schemes

    rng = np.random.default_rng(4)
    cands = np.concatenate([rng.uniform(0, 300, (200, 2)), rng.uniform(10, 300, (200, 2))], 1)
    made = (EdgeBoxesTop(n=7), MinScale(n=20), ScalePriority(n=20), ReduceOverlap(n=20))
    dense = Dense(scales=(0.25, 0.49), per_scale=(16, 9))
    expected = [s.select(cands, SIZE) for s in made] + [dense.for_size(SIZE)]

    def checked(*args, **kwargs):
        raise AssertionError("a per-image call re-checked a parsed value")

    for module in (vpr_core.landmarks.schemes, vpr_core.landmarks.scales, vpr_core.boxes):
        for name in dir(module):
            if name.startswith(("check_", "is_")):
                monkeypatch.setattr(module, name, checked)
    got = [s.select(cands, SIZE) for s in made] + [dense.for_size(SIZE)]
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_array_equal(a, b)


def test_boxes_of_an_image(synthetic_image_small):
    image = synthetic_image_small
    size = image.shape[:2]
    cands = edge_boxes(image, max_boxes=300).boxes
    np.testing.assert_array_equal(
        MinScale(n_candidates=300).boxes(image), select_min_scale(cands, size)
    )
    np.testing.assert_array_equal(Dense().boxes(image), dense_sampling(size))
    np.testing.assert_array_equal(WholeImage().boxes(image), [[0, 0, size[1], size[0]]])


@pytest.fixture(scope="module")
def synthetic_image_small():
    return load_dataset("synthetic", n_places=2, image_size=(96, 128)).load_image("query", 0)


def _grid_class(offset: float):
    """A user scheme class named ``Grid``; ``offset`` is compiled into its code."""

    @dataclasses.dataclass(frozen=True)
    class Grid:
        g: int = 2

        def boxes(self, image):
            h, w = image.shape[:2]
            s = 1.0 / self.g
            return np.array(
                [
                    [offset + x * w * s, y * h * s, w * s, h * s]
                    for y in range(self.g)
                    for x in range(self.g)
                ]
            )

    return Grid


def test_a_user_schemes_identity_is_class_fields_and_declared_version():
    a, b = _grid_class(0.0), _grid_class(0.0)
    ident = scheme_identity(a(g=3))
    assert ident["scheme"].endswith("_grid_class.<locals>.Grid") and ident["params"] == {"g": 3}
    assert ident["version"] is None  # no declared version: its boxes are never stored
    assert scheme_identity(b(g=3)) == ident and scheme_identity(a(g=2)) != ident
    b.version = "2"  # a class attribute (ClassVar[str]): the user's promise
    assert scheme_identity(b(g=3))["version"] == "user 2"
    assert scheme_identity(Dense())["version"] == code_version("landmarks")  # the package's


@pytest.mark.parametrize(
    "bad",
    [object(), Dense, np.zeros(3)],
    ids=["object", "a class", "array"],
)
def test_anything_but_a_frozen_dataclass_with_boxes_is_refused(bad):
    with pytest.raises(TypeError, match="frozen dataclass"):
        check_scheme(bad)


def test_a_mutable_dataclass_is_refused():
    @dataclasses.dataclass
    class Loose:
        def boxes(self, image):
            return np.zeros((1, 4))

    with pytest.raises(TypeError, match="frozen dataclass"):
        run_method(Loose(), load_dataset("synthetic", n_places=2))


# ---------------------------------------------------------------------------------------------
# a user's scheme through the whole pipeline
# ---------------------------------------------------------------------------------------------

CALLS: list[int] = []


@dataclasses.dataclass(frozen=True)
class CentreGrid:
    """A user scheme: a g x g grid of boxes of half the image side, around the centre."""

    g: int = 2

    def boxes(self, image: np.ndarray) -> np.ndarray:
        CALLS.append(1)
        h, w = image.shape[:2]
        xs = np.linspace(0, w / 2, self.g)
        ys = np.linspace(0, h / 2, self.g)
        return np.array([[x, y, w / 2, h / 2] for y in ys for x in xs])


@pytest.fixture()
def small(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    return load_dataset("synthetic", n_places=6, image_size=(96, 128))


def test_a_user_scheme_runs_is_cached_compared_and_plotted(small, caplog):
    import logging

    import matplotlib.pyplot as plt

    from vpr_study.viz import plot_pr_curves

    CALLS.clear()
    mine = run_method(CentreGrid(g=3), small, backbone="hog", n_bootstrap=20)
    assert len(CALLS) == 12 and all(b.shape == (9, 4) for b in mine.boxes["query"])
    assert mine.method == "CentreGrid" and mine.run == "CentreGrid(g=3)"
    assert mine.label == "CentreGrid (g=3)" and mine.edge_model == "none"
    assert isinstance(mine.config.landmarks, CentreGrid)
    with caplog.at_level(logging.INFO, logger="vpr_core"):
        again = run_method(CentreGrid(g=3), small, backbone="hog", n_bootstrap=20)
    assert len(CALLS) == 24, "a user scheme without a version is recomputed on every run"
    assert "(read from the cache)" in caplog.text  # the same boxes: the results cache
    np.testing.assert_array_equal(again.similarity, mine.similarity)
    other = run_method(CentreGrid(), small, backbone="hog", n_bootstrap=20)
    assert len(CALLS) == 36 and other.run == "CentreGrid"
    dense = run_method("dense", small, backbone="hog", n_bootstrap=20, scales=(0.25,), per_scale=4)
    table = compare([dense, mine, other])
    assert list(table["run"]) == [
        "dense(per_scale=4, scales=0.25)",
        "CentreGrid(g=3)",
        "CentreGrid",
    ]
    fig = plot_pr_curves([dense, mine, other])
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert any(t.startswith("CentreGrid (g=3)") for t in legend)
    plt.close(fig)


def test_a_user_scheme_returning_bad_boxes_names_itself_and_the_image(small):
    @dataclasses.dataclass(frozen=True)
    class Broken:
        def boxes(self, image):
            return np.zeros((3, 5))

    with pytest.raises(ValueError, match=r"Broken.boxes\(\) on query image 0 .*shape \(K, 4\)"):
        run_method(Broken(), small, backbone="hog", n_bootstrap=0)


@pytest.mark.parametrize(
    ("box", "problem"),
    [
        ([10, 10, 0, 20], "positive width and height; bad rows: \\[0\\]"),
        ([10, np.nan, 20, 20], "NaN or inf"),
        ([500, 10, 20, 20], "outside the 128 x 96 image, bad rows: \\[0\\]"),
        ([-40, 10, 20, 20], "outside the 128 x 96 image"),
    ],
    ids=["zero_width", "nan", "right_of_the_image", "left_of_the_image"],
)
def test_a_user_schemes_bad_box_is_refused_at_the_landmark_stage(small, box, problem):
    @dataclasses.dataclass(frozen=True)
    class BadBox:
        def boxes(self, image):
            return np.array([box, [0, 0, 20, 20]], dtype=float)

    where = r"BadBox.boxes\(\) on query image 0 \(.*\.png\): .*"
    with pytest.raises(ValueError, match=where + problem):
        extract_landmarks(BadBox(), small)


def test_a_scheme_field_must_be_a_plain_value():
    @dataclasses.dataclass(frozen=True)
    class Weighted:
        w: object = (1.0, 2.0)

        def boxes(self, image):
            return np.zeros((1, 4))

    check_scheme(Weighted())
    with pytest.raises(TypeError, match="Weighted: field w holds a ndarray; .*a tuple instead"):
        check_scheme(Weighted(np.ones(3)))
    Weighted.version = 2  # type: ignore[attr-defined]
    with pytest.raises(TypeError, match="Weighted.version must be a non-empty string, got 2"):
        check_scheme(Weighted())


def test_a_bare_paper_scheme_is_named_after_its_preset(small):
    r = run_method(Dense(scales=(0.25,), per_scale=4), small, backbone="hog", n_bootstrap=0)
    s = run_method("dense", small, backbone="hog", n_bootstrap=0, scales=(0.25,), per_scale=4)
    assert r.run == s.run == "dense(per_scale=4, scales=0.25)"
    np.testing.assert_array_equal(r.similarity, s.similarity)


def test_the_result_records_what_determines_its_numbers(small, tmp_path):
    from test_baselines import _write

    from vpr_core.cache import dataset_fingerprint
    from vpr_core.landmarks.edge_boxes import edge_model_id
    from vpr_study.peers import load_vprbench_precomputed

    enc = get_encoder()
    r = run_method(EdgeBoxesTop(n=4), small, n_bootstrap=0)  # default backbone: shipped weights
    assert r.run == "classical(n=4)"
    assert r.dataset_fingerprint == dataset_fingerprint(small) != ""
    assert r.weights_sha256 == enc.config["weights_sha256"] and len(r.weights_sha256) >= 64
    assert r.edge_model == edge_model_id()
    other = load_dataset("synthetic", n_places=6, image_size=(96, 128), seed=1)
    assert dataset_fingerprint(other) != r.dataset_fingerprint  # other pixels, same names
    peer = load_vprbench_precomputed(_write(tmp_path / "NetVLAD" / "x.npy", small.ground_truth))
    assert peer_result(peer, small, n_bootstrap=0).dataset_fingerprint == (r.dataset_fingerprint)
