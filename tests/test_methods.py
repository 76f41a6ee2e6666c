"""Method presets: names, overrides, errors."""

import pytest

from vpr_core.methods import available_methods, get_method


def test_all_paper_methods_present():
    assert set(available_methods()) == {"classical", "selection_scheme1", "selection_scheme2",
                                        "overlap_scheme1", "overlap_scheme2", "dense"}


def test_classical_is_top100_edge_boxes_without_soft_nms():
    c = get_method("classical")
    assert c["landmarks"]["scheme"] == "edge_boxes" and c["landmarks"]["n"] == 100
    assert c["landmarks"]["n_candidates"] == 1000
    assert c["matching"]["soft_nms_iou"] is None and c["matching"]["sigma"] == 0.5


def test_selection_scheme_parameters_follow_algorithms():
    assert get_method("selection_scheme1")["landmarks"]["min_index"] == 4
    assert get_method("selection_scheme2")["landmarks"]["order"] == (5, 6, 7, 8, 9, 4)


def test_overrides_are_routed():
    o = get_method("overlap_scheme1", iou_threshold=0.4)
    assert o["landmarks"]["iou_threshold"] == 0.4
    s = get_method("overlap_scheme2", soft_nms_iou=0.3)
    assert s["matching"]["soft_nms_iou"] == 0.3
    assert s["landmarks"]["scheme"] == "edge_boxes"
    d = get_method("dense", scales=[0.25, 0.49], per_scale=49)
    assert d["landmarks"]["scales"] == (0.25, 0.49) and d["landmarks"]["per_scale"] == 49
    assert "n" not in d["landmarks"]


def test_presets_are_not_mutated_by_overrides():
    get_method("dense", scales=(0.5,))
    assert get_method("dense")["landmarks"]["scales"] == (0.16, 0.25, 0.36, 0.49)


def test_unknown_method_lists_valid_names():
    with pytest.raises(ValueError, match="Valid methods: classical, dense"):
        get_method("edgebox")


def test_unknown_override_is_an_error():
    with pytest.raises(ValueError, match="Unknown option 'threshold'"):
        get_method("overlap_scheme1", threshold=0.4)
