"""Study layer: the paper's tables as data, FigureResult, the figure registry, outputs under the
output root, the pipeline tour and Table 5."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vpr_core import paper, study
from vpr_core.study import FigureResult

REPO = Path(__file__).resolve().parents[1]
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture
def out_root(tmp_path, monkeypatch):
    """Outputs in a temporary root; the repository's cache is reused (it is keyed by content)."""
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path / "out"))
    monkeypatch.setenv("VPR_CACHE_DIR", os.environ.get("VPR_CACHE_DIR", str(REPO / ".cache")))
    return tmp_path / "out"


@pytest.fixture
def tiny(out_root):
    return study.open_study("synthetic", quick=True, notebook="nbx", n_places=3)


def test_table1_bins():
    t = study.table1()
    assert list(t.index) == [f"Scale {k}" for k in range(1, 10)]
    assert list(t["lower (incl.)"]) == [0, 0.02, 0.05, 0.09, 0.14, 0.23, 0.34, 0.5, 0.72]
    assert t["normalized scale"].iloc[-1] == "0.72~1"
    assert t["normalized scale"].iloc[0] == "0~0.02"


@pytest.mark.parametrize("table,totals", [
    ("table2", [100, 100, 98, 98, 100, 96]),
    ("table3", [100, 102, 104, 99, 103]),
    ("table4", [100, 100, 100, 100]),
])
def test_dense_tables_are_the_papers(table, totals):
    assert list(study.Study.dense_settings(table)["total"]) == totals


def test_paper_settings_are_reexported_not_copied():
    assert study.TABLE4 is paper.TABLE4 and study.DENSE_TABLES is paper.DENSE_TABLES
    assert study.FIG7_NMS_THRESHOLDS is paper.FIG7_NMS_THRESHOLDS
    assert study.TABLE4["Set 3"][0] == (0.09, 0.20, 0.32, 0.44)


def test_dead_code_is_gone():
    assert not hasattr(study.Study, "pipeline_figure")
    assert "quick" not in {f for f in study.Study.__dataclass_fields__}


def test_registry_is_one_list():
    stems = [s.stem for s in study.FIGURES]
    assert len(stems) == len(set(stems)), "a figure stem is registered twice"
    by_nb = study.expected_figures()
    assert list(by_nb) == sorted(by_nb)
    assert study.figure_spec("fig05_selection").notebook == "03_landmark_selection"
    with pytest.raises(KeyError, match="fig05_selection"):
        study.figure_spec("fig99")


def test_unknown_table_is_a_clear_error(tiny):
    with pytest.raises(ValueError, match="table2, table3, table4"):
        tiny.dense_sweep("table9", figure="x")
    with pytest.raises(ValueError, match="table2, table3, table4"):
        study.Study.dense_settings("table9")


def test_compare_returns_figure_result_under_output_root(tiny, out_root):
    res = tiny.compare([("dense", {"scales": (0.25,), "per_scale": 4}, "tiny")], figure="figx")
    assert isinstance(res, FigureResult)
    assert res.path == out_root / "figures" / "synthetic_quick" / "figx.png"
    assert list(res.table.index) == ["tiny"]
    assert 0 <= res.table.loc["tiny", "AUC"] <= 1
    first = res.path.read_bytes()
    # the inline picture is the saved file, byte for byte
    assert res.png() == first and res._repr_png_()[:8] == PNG
    csv = (out_root / "results" / "synthetic_quick" / "nbx.csv").read_text()
    assert csv.splitlines()[0].startswith("figure,method,run,AUC,")
    again = tiny.compare([("dense", {"scales": (0.25,), "per_scale": 4}, "tiny")], figure="figx")
    assert again.path.read_bytes() == first
    # a finished result can be passed again (peers, results from elsewhere)
    mixed = tiny.compare([tiny.run("dense", label="tiny", scales=(0.25,), per_scale=4)], "figy")
    assert list(mixed.table.index) == ["tiny"]


def test_compare_rejects_unknown_entries(tiny):
    with pytest.raises(TypeError, match="method name"):
        tiny.compare([42], figure="figz")
    with pytest.raises(TypeError, match="name, overrides"):
        tiny.compare([("dense", {}, "a", "b")], figure="figz")


def test_figure_result_displays_figure_and_table(tiny, monkeypatch):
    import IPython.display as disp

    shown = []
    monkeypatch.setattr(disp, "display", lambda obj: shown.append(obj))
    res = tiny.fig09_dense_scales()
    assert res.stem == "fig09_dense_scales" and res.table is None
    res._ipython_display_()
    assert len(shown) == 1 and shown[0].data[:8] == PNG
    shown.clear()
    cov = tiny.fig14_coverage()
    cov._ipython_display_()
    assert len(shown) == 2 and shown[1] is cov.table
    assert set(cov.table.index) == {"classical", "dense"}
    assert ((cov.table > 0) & (cov.table <= 1)).all().all()


def test_pipeline_tour_steps_use_the_library(tiny):
    from vpr_core.matching import match_landmarks

    step1 = tiny.tour_dense_sampling(0)
    assert np.allclose(step1.table["normalized scale (Eq. 3)"], paper.DENSE_SCALES)
    assert list(step1.table["landmarks"]) == [paper.DENSE_PER_SCALE] * len(paper.DENSE_SCALES)
    step2 = tiny.tour_descriptors(0)
    assert list(step2.table["landmarks"]) == [paper.N_LANDMARKS] * 2
    step3 = tiny.tour_reciprocal_matches(0)
    step4 = tiny.tour_image_similarity(0)
    st = tiny._tour(0)
    ref = match_landmarks(st["desc"]["query"], st["boxes"]["query"],
                          st["desc"]["reference"], st["boxes"]["reference"])
    assert np.array_equal(step3.table[["query landmark", "reference landmark"]].to_numpy(),
                          ref.matches)
    terms = step4.table["1 - d*s"].to_numpy()
    assert math.isclose(terms.sum() / paper.N_LANDMARKS, ref.similarity, rel_tol=1e-6)
    for r in (step1, step2, step3, step4):
        assert r.path.read_bytes()[:8] == PNG and r.path.stem.startswith("tour")
    with pytest.raises(IndexError, match="out of range"):
        tiny.tour_dense_sampling(99)


def test_cost_table_times_fresh_pipeline_stages(tiny):
    before = os.environ.get("VPR_CACHE_DIR")
    t = tiny.cost_table(n_images=1, methods=("dense", "classical"))
    assert os.environ.get("VPR_CACHE_DIR") == before
    assert list(t.columns) == list(study.COST_COLUMNS)
    assert (t.to_numpy() > 0).all()
    # Edge Boxes over 1,000 candidates is far slower than laying out the dense grid
    assert t.loc["classical", "extract landmarks (s/img)"] > \
        10 * t.loc["dense", "extract landmarks (s/img)"]
    assert (tiny.results_dir / "nbx_table5_cost.csv").exists()
    with pytest.raises(ValueError, match="n_images"):
        tiny.cost_table(n_images=0)


def test_outputs_default_to_the_working_directory(tmp_path, monkeypatch):
    monkeypatch.delenv("VPR_OUTPUT_DIR", raising=False)
    monkeypatch.setenv("VPR_CACHE_DIR", os.environ.get("VPR_CACHE_DIR", str(REPO / ".cache")))
    monkeypatch.chdir(tmp_path)
    s = study.open_study("synthetic", quick=True, notebook="t", n_places=3)
    res = s.fig09_dense_scales()
    assert res.path == tmp_path / "figures" / "synthetic_quick" / "fig09_dense_scales.png"


def test_extra_datasets_rejects_malformed_entries(monkeypatch):
    monkeypatch.setenv("VPR_DATASETS", "gardens_point=/data/gp;oops")
    with pytest.raises(ValueError, match="name=root"):
        study.extra_datasets()
    monkeypatch.setenv("VPR_DATASETS", "gardens_point=/data/gp")
    assert study.extra_datasets()["gardens_point"] == {"dataset": "gardens_point",
                                                       "root": "/data/gp", "options": {},
                                                       "pooling": "crop"}


def test_quick_subset_of_real_dataset(gardens_point_mini_root, out_root):
    s = study.open_study("folder", root=str(gardens_point_mini_root), quick=True, notebook="t")
    assert s.label == "folder_quick"
    assert np.array_equal(s.dataset.ground_truth, np.eye(10, dtype=bool))


def test_compare_writes_paired_differences_with_verdicts(out_root):
    s = study.open_study("synthetic", quick=True, notebook="nbp", n_places=6)
    runs = [("dense", {"scales": (0.25,), "per_scale": 4}, "a"),
            ("dense", {"scales": (0.49,), "per_scale": 4}, "b"), "global"]
    res = s.compare(runs, "figp")
    assert {"AUC lo", "AUC hi", "R@1 lo", "R@1 hi", "queries"} <= set(res.table.columns)
    assert (res.table["AUC lo"] <= res.table["AUC"] + 1e-12).all()
    paired = pd.read_csv(out_root / "results" / "synthetic_quick" / "nbp_figp_paired.csv")
    assert list(paired["method"]) == ["b", "global"] and set(paired["baseline"]) == {"a"}
    for name in ("dAUC", "dR@1"):
        assert set(paired[f"{name} verdict"]) <= {"finding", "inconclusive"}
        finding = (paired[f"{name} lo"] > 0) | (paired[f"{name} hi"] < 0)
        assert ((paired[f"{name} verdict"] == "finding") == finding).all()
    again = s.paired_differences("figp", baseline="global")
    assert set(again.index) == {"a", "b"}
    with pytest.raises(ValueError, match="baseline 'nope'"):
        s.paired_differences("figp", baseline="nope")
    with pytest.raises(KeyError, match="not been compared"):
        s.paired_differences("fig99")


def test_open_study_passes_loader_options_and_pooling(out_root, gardens_point_mini_root):
    s = study.open_study("folder", root=str(gardens_point_mini_root), notebook="t",
                         label="gp", pooling="roi", tolerance=1)
    assert s.label == "gp" and s.pooling == "roi" and s.dataset.tolerance == 1
    assert s.encoder.config["pooling"] == "roi"
