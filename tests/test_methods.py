"""Methods as values: presets, options, run keys and labels derived from the value."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vpr_core import paper
from vpr_core.landmarks import Dense, EdgeBoxesTop, MinScale, ReduceOverlap, WholeImage
from vpr_core.methods import (
    METHODS,
    Matching,
    Method,
    _method_options,
    as_method,
    available_methods,
    get_method,
    method_label,
    run_key,
)


def test_all_paper_methods_present():
    assert set(available_methods()) == {
        "classical",
        "selection_scheme1",
        "selection_scheme2",
        "overlap_scheme1",
        "overlap_scheme2",
        "dense",
        "global",
    }


def test_presets_are_scheme_and_matching_values():
    assert get_method("classical") == Method("classical", EdgeBoxesTop(100, 1000), Matching())
    assert get_method("classical").matching == Matching(None, 0.5)
    assert get_method("selection_scheme1").landmarks == MinScale(100, 4, 1000)
    assert get_method("selection_scheme2").landmarks.order == (5, 6, 7, 8, 9, 4)
    assert get_method("overlap_scheme2").matching.soft_nms_iou == paper.SOFT_NMS_IOU
    assert get_method("global").landmarks == WholeImage()


# The run keys and labels of the committed results (findings match on the keys).
KEYS = [
    (("classical", {}), "classical", "classical"),
    (("selection_scheme1", {}), "selection_scheme1", "selection_scheme1"),
    (("selection_scheme2", {}), "selection_scheme2", "selection_scheme2"),
    (("global", {}), "global", "global"),
    (("dense", {}), "dense", "dense"),
    (("overlap_scheme1", {}), "overlap_scheme1", "overlap_scheme1 (IoU 0.5)"),
    (
        ("overlap_scheme1", {"iou_threshold": 0.4}),
        "overlap_scheme1(iou_threshold=0.4)",
        "overlap_scheme1 (IoU 0.4)",
    ),
    (("overlap_scheme2", {}), "overlap_scheme2", "overlap_scheme2 (IoU 0.5)"),
    (
        ("overlap_scheme2", {"soft_nms_iou": 0.3}),
        "overlap_scheme2(soft_nms_iou=0.3)",
        "overlap_scheme2 (IoU 0.3)",
    ),
    (
        ("dense", {"scales": [0.25, 0.49], "per_scale": 49}),
        "dense(per_scale=49, scales=0.25/0.49)",
        "dense (0.25/0.49 x 49)",
    ),
    (("dense", {"scales": (0.25,), "per_scale": 100}), "dense(per_scale=100, scales=0.25)", None),
    (
        ("dense", {"per_scale": (25, 25, 25, 25)}),
        "dense(per_scale=25/25/25/25)",
        "dense (0.16/0.25/0.36/0.49 x 25/25/25/25)",
    ),
    (("dense", {"scales": paper.DENSE_SCALES, "per_scale": 25}), "dense", "dense"),
    (("classical", {"n": 50}), "classical(n=50)", "classical (n=50)"),
]


@pytest.mark.parametrize(("call", "key", "label"), KEYS, ids=[k for _, k, _ in KEYS])
def test_run_keys_and_labels_derive_from_the_value(call, key, label):
    method = get_method(call[0], **call[1])
    assert run_key(method) == key
    if label is not None:
        assert method_label(method) == label


def test_every_committed_run_key_is_reproduced():
    """Each ``run`` in results/*/*.csv is the key of a preset call of the study."""
    import csv
    from pathlib import Path

    made = set(available_methods())
    for table in (paper.TABLE2, paper.TABLE3, paper.TABLE4):
        made |= {run_key(get_method("dense", scales=s, per_scale=n)) for s, n in table.values()}
    made |= {run_key(get_method("overlap_scheme1", iou_threshold=t)) for t in (0.4, 0.6, 0.7)}
    made |= {run_key(get_method("overlap_scheme2", soft_nms_iou=t)) for t in (0.3, 0.4, 0.6)}
    made |= {run_key(get_method("overlap_scheme2", soft_nms_iou=0.7))}
    made |= {run_key(get_method(m, spatial="consistency")) for m in ("dense", "classical")}
    made |= {
        run_key(get_method(m, weighting=w))
        for m in ("dense", "classical", "selection_scheme1")  # notebooks 06 and 07
        for w in ("contrast", "idf")
    }
    from vpr_study.findings import STEPS

    made |= {  # notebook 07's steps (issue 55)
        run_key(get_method(m, **opts))
        for m in ("dense", "classical", "selection_scheme1")
        for opts in [*STEPS.values(), {"weighting": "two_sided", "normalise": "database"}]
    }
    made.add("CentreGrid")  # the scheme class written in notebook 05's "try your own" cell
    results = Path(__file__).resolve().parents[1] / "results"
    committed = {
        row["run"]
        for path in results.glob("*/*.csv")
        for row in csv.DictReader(path.open())
        if "run" in row
    }
    assert committed and committed <= made, committed - made


def test_overrides_are_routed_to_scheme_and_matching():
    o = get_method("overlap_scheme1", iou_threshold=0.4)
    assert o.landmarks == ReduceOverlap(iou_threshold=0.4)
    s = get_method("overlap_scheme2", soft_nms_iou=0.3, sigma=0.2)
    assert s.matching == Matching(0.3, 0.2) and s.landmarks == EdgeBoxesTop()
    assert get_method("overlap_scheme2", soft_nms_iou=None).matching.soft_nms_iou is None
    d = get_method(
        "dense",
        scales=[0.25, 0.49],
        per_scale=49,
    )
    assert d.landmarks == Dense((0.25, 0.49), 49)
    assert get_method("dense", scales=None).landmarks == Dense()  # None: not set
    assert METHODS["dense"].landmarks == Dense()  # presets are values: never changed


def test_options_derive_from_the_fields():
    assert _method_options(get_method("selection_scheme1")) == (
        "n",
        "min_index",
        "n_candidates",
        "spatial",
        "weighting",
        "normalise",
        "whiten",
    )
    assert _method_options(get_method("overlap_scheme2")) == (
        "n",
        "n_candidates",
        "soft_nms_iou",
        "sigma",
        "spatial",
        "weighting",
        "normalise",
        "whiten",
    )
    assert _method_options(get_method("global")) == ("spatial", "weighting", "normalise", "whiten")


@pytest.mark.parametrize(
    ("name", "options", "match"),
    [
        ("edgebox", {}, "unknown method 'edgebox'; valid: classical, dense"),
        ("overlap_scheme1", {"threshold": 0.4}, "unknown method 'overlap_scheme1' option"),
        (
            "dense",
            {"iou_threshold": 0.1},
            "'iou_threshold'; valid: scales, per_scale, spatial, weighting, normalise, whiten$",
        ),
        (
            "classical",
            {"min_index": 7},
            "'min_index'; valid: n, n_candidates, spatial, weighting, normalise, whiten$",
        ),
        ("classical", {"soft_nms_iou": 0.3}, "method 'classical' option\\(s\\) 'soft_nms_iou'"),
        ("global", {"n": 5}, "'n'; valid: spatial, weighting, normalise, whiten$"),
        ("dense", {"scales": 0.25}, "method 'dense': Dense.scales must be .*, got 0.25"),
        ("overlap_scheme1", {"iou_threshold": 1.5}, "ReduceOverlap.iou_threshold .*, got 1.5"),
        ("dense", {"per_scale": "25"}, "Dense.per_scale must be .*, got '25'"),
        ("selection_scheme2", {"order": "5,6"}, "ScalePriority.order must be .*, got '5,6'"),
        ("overlap_scheme2", {"soft_nms_iou": 2}, "Matching: option soft_nms_iou=2"),
        ("overlap_scheme2", {"sigma": 0}, "Matching: option sigma=0 .* positive"),
    ],
)
def test_get_method_refuses_bad_names_options_and_values(name, options, match):
    with pytest.raises(ValueError, match=match):
        get_method(name, **options)


@dataclasses.dataclass(frozen=True)
class Stripes:
    """A user scheme: ``k`` vertical stripes."""

    k: int
    margin: float = 0.0

    def boxes(self, image: np.ndarray) -> np.ndarray:
        h, w = image.shape[:2]
        return np.array([[i * w / self.k, self.margin, w / self.k, h] for i in range(self.k)])


def test_as_method_takes_a_name_a_method_or_a_bare_scheme():
    assert as_method("dense", per_scale=9) == get_method("dense", per_scale=9)
    m = Method("mine", Stripes(3), Matching(soft_nms_iou=0.4))
    assert as_method(m) is m
    assert as_method(Dense(per_scale=9)) == get_method("dense", per_scale=9)
    assert as_method(EdgeBoxesTop(n=5)).name == "classical"
    user = as_method(Stripes(3))
    assert user.name == "Stripes" and user.matching == Matching()
    # a field without a default is always part of the key; the others when they differ
    assert run_key(user) == "Stripes(k=3)" and method_label(user) == "Stripes (k=3)"
    assert run_key(as_method(Stripes(3, 1.5))) == "Stripes(k=3, margin=1.5)"
    assert run_key(m) == "mine(k=3, soft_nms_iou=0.4)" and method_label(m) == "mine (k=3; IoU 0.4)"


@pytest.mark.parametrize(
    ("value", "options", "error", "match"),
    [
        (Stripes(3), {"k": 4}, ValueError, "apply to a preset name only"),
        (object(), {}, TypeError, "frozen dataclass"),
        (3, {}, TypeError, "frozen dataclass"),
    ],
)
def test_as_method_refuses(value, options, error, match):
    with pytest.raises(error, match=match):
        as_method(value, **options)


def test_method_refuses_a_bad_name_or_matching():
    with pytest.raises(ValueError, match="name must be a non-empty string"):
        Method("", Dense())
    with pytest.raises(TypeError, match="matching must be a vpr_core.matching.Matching"):
        Method("x", Dense(), {"soft_nms_iou": None})  # type: ignore[arg-type]


def test_spatial_is_a_matching_option_of_every_method():
    from vpr_core.landmarks.schemes import Dense
    from vpr_core.methods import as_method, available_methods, get_method, method_label, run_key

    for name in available_methods():
        m = get_method(name, spatial="consistency")
        assert m.matching.spatial == "consistency"
        assert run_key(m).startswith(f"{name}(") and "spatial=consistency" in run_key(m)
        assert "geometry: consistency" in method_label(m)
        assert run_key(get_method(name, spatial=None)) == name  # None: off, the paper's Eq. (1)
    assert run_key(as_method(Dense(), spatial="consistency")) == "dense(spatial=consistency)"
    with pytest.raises(ValueError, match="spatial='ransac'.*consistency"):
        get_method("dense", spatial="ransac")
