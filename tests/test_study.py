"""Study helpers: the paper's tables as data, outputs and their locations."""

import numpy as np
import pytest

from vpr_core import study


def test_table1_bins():
    t = study.table1()
    assert list(t.index) == [f"Scale {k}" for k in range(1, 10)]
    assert list(t["lower (incl.)"]) == [0, 0.02, 0.05, 0.09, 0.14, 0.23, 0.34, 0.5, 0.72]
    assert t["normalized scale"].iloc[-1] == "0.72~1"


@pytest.mark.parametrize("table,totals", [
    ("table2", [100, 100, 98, 98, 100, 96]),
    ("table3", [100, 102, 104, 99, 103]),
    ("table4", [100, 100, 100, 100]),
])
def test_dense_tables_are_the_papers(table, totals):
    assert list(study.Study.dense_settings(table)["total"]) == totals


def test_table4_scales_exact():
    assert study.TABLE4["Set 3"][0] == (0.09, 0.20, 0.32, 0.44)
    assert study.TABLE4["Set 4"][0] == (0.20, 0.32, 0.44, 0.54)


def test_unknown_table_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_FIGURES_DIR", str(tmp_path / "f"))
    monkeypatch.setenv("VPR_RESULTS_DIR", str(tmp_path / "r"))
    s = study.open_study("synthetic", quick=True, notebook="t", n_places=3)
    with pytest.raises(ValueError, match="table2, table3, table4"):
        s.dense_sweep("table9", figure="x")


def test_compare_writes_figure_and_metrics(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_FIGURES_DIR", str(tmp_path / "f"))
    monkeypatch.setenv("VPR_RESULTS_DIR", str(tmp_path / "r"))
    s = study.open_study("synthetic", quick=True, notebook="nbx", n_places=4)
    table = s.compare([("dense", {"scales": (0.25,), "per_scale": 4}, "tiny")], figure="figx")
    assert list(table.index) == ["tiny"]
    assert 0 <= table.loc["tiny", "AUC(ratio)"] <= 1
    png = tmp_path / "f" / "synthetic_quick" / "figx.png"
    first = png.read_bytes()
    csv = (tmp_path / "r" / "synthetic_quick" / "nbx.csv").read_text()
    assert csv.splitlines()[0].startswith("figure,method,AUC(ratio)")
    # the same call again gives byte-identical PNG output
    s.compare([("dense", {"scales": (0.25,), "per_scale": 4}, "tiny")], figure="figx")
    assert png.read_bytes() == first


def test_quick_subset_of_real_dataset(gardens_point_mini_root, tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_FIGURES_DIR", str(tmp_path / "f"))
    s = study.open_study("folder", root=str(gardens_point_mini_root), quick=True, notebook="t")
    assert s.label == "folder_quick"
    assert np.array_equal(s.dataset.ground_truth, np.eye(10, dtype=bool))
