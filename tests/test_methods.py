"""Method presets: names, overrides, errors."""

import pytest

from vpr_core.methods import available_methods, get_method


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


def test_options_that_do_not_apply_are_refused_with_the_valid_list():
    with pytest.raises(ValueError, match="Options of 'dense': scales, per_scale"):
        get_method("dense", iou_threshold=0.1)
    with pytest.raises(ValueError, match="'iou_threshold' for method 'classical'"):
        get_method("classical", iou_threshold=0.1, min_index=7)
    with pytest.raises(ValueError, match="Options of 'global': none"):
        get_method("global", n=5)


@pytest.mark.parametrize("bad", [0.25, "0.25", (), (0.2, 1.5), ("a",)])
def test_bad_scales_are_named_before_any_label_is_made(bad):
    with pytest.raises(ValueError, match="option scales="):
        get_method("dense", scales=bad)


def test_bad_option_values_are_named():
    with pytest.raises(ValueError, match="iou_threshold=1.5"):
        get_method("overlap_scheme1", iou_threshold=1.5)
    with pytest.raises(ValueError, match="per_scale"):
        get_method("dense", per_scale="25")
    with pytest.raises(ValueError, match="order"):
        get_method("selection_scheme2", order="5,6")


def test_method_label_lives_in_methods_and_names_settings():
    from vpr_core.methods import method_label

    assert (
        method_label(get_method("overlap_scheme1", iou_threshold=0.4))
        == "overlap_scheme1 (IoU 0.4)"
    )
    assert method_label(get_method("dense")) == "dense"
    assert method_label(get_method("dense", scales=(0.25,), per_scale=100)) == "dense (0.25 x 100)"
    assert get_method("global")["landmarks"] == {"scheme": "whole_image"}
