"""The study notebooks: paired with jupytext, stored without outputs, thin, executed headless
(quick) by the runner into a temporary output root."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pandas as pd
import pytest

from vpr_core import runner
from vpr_core.study import FIGURES, expected_figures

REPO = Path(__file__).resolve().parents[1]
NB_DIR = REPO / "notebooks"
NOTEBOOKS = sorted(NB_DIR.glob("[0-9][0-9]_*.ipynb"))


def test_six_numbered_notebooks_match_the_registry():
    assert [p.stem for p in NOTEBOOKS] == list(expected_figures())
    assert runner.notebooks_dir() == NB_DIR


def test_runner_needs_the_repository(monkeypatch):
    monkeypatch.setattr(runner, "source_checkout", lambda: None)
    with pytest.raises(FileNotFoundError, match="clone of the repository"):
        runner.notebook_paths()


def test_unknown_notebook_is_a_clear_error():
    with pytest.raises(ValueError, match="01_pipeline_tour"):
        runner.notebook_paths(["99_nothing"])


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_is_clean_paired_and_parametrised(path):
    import jupytext

    nb = json.loads(path.read_text())
    assert nb["metadata"]["kernelspec"]["name"] == "python3"
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert all(not c.get("outputs") and c.get("execution_count") is None for c in code), \
        "commit notebooks without outputs (nbstripout)"
    tagged = [c for c in code if "parameters" in c.get("metadata", {}).get("tags", [])]
    assert len(tagged) == 1
    for name in ("dataset", "root", "backbone", "quick"):
        assert f"{name} =" in "".join(tagged[0]["source"])
    # the .py twin holds the same cells (jupytext pairing)
    twin = jupytext.read(path.with_suffix(".py"))
    assert [c.source for c in twin.cells] == ["".join(c["source"]) for c in nb["cells"]]
    # figures are shown from the FigureResult, never re-read from disk by file name
    source = "".join("".join(c["source"]) for c in code)
    assert "Image(filename" not in source and ".png" not in source


def test_quick_study_runs_headless_and_writes_every_figure(tmp_path, monkeypatch):
    out = tmp_path / "out"
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(out))
    monkeypatch.setenv("VPR_CACHE_DIR", os.environ.get("VPR_CACHE_DIR", str(REPO / ".cache")))
    table = runner.run_study(dataset="synthetic", quick=True)
    figures = out / "figures" / "synthetic_quick"
    for spec in FIGURES:
        png = figures / f"{spec.stem}.png"
        assert png.stat().st_size > 1000, png
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (NB_DIR / "figures").exists() and not (NB_DIR / "results").exists()
    for nb in expected_figures():
        assert (out / "runs" / "synthetic_quick" / f"{nb}.ipynb").exists()
    for nb in ("03_landmark_selection", "04_overlap", "05_dense_sampling_parameters",
               "06_comparison"):
        assert (out / "results" / "synthetic_quick" / f"{nb}.csv").exists()
    assert (out / "results" / "synthetic_quick" / "06_comparison_table5_cost.csv").exists()
    assert {"AUC", "R@100P", "R@1"} <= set(table.columns)
    assert len(table) >= 3 + 5 + 6 + 15 + 3
    assert os.environ["VPR_OUTPUT_DIR"] == str(out)  # the runner restored the environment
    # executed again (features now cached): byte-identical figures
    before = {p.name: p.read_bytes() for p in figures.glob("fig0[56]*.png")}
    runner.run_study(dataset="synthetic", quick=True, notebooks=["03_landmark_selection"])
    after = {p.name: p.read_bytes() for p in figures.glob("fig0[56]*.png")}
    assert before and before == after


def test_real_datasets_beside_the_project_get_the_comparison(tmp_path, monkeypatch):
    from vpr_core.study import extra_datasets

    found = extra_datasets()
    if not found:
        pytest.skip("no real datasets beside the project (../shared/data)")
    out = tmp_path / "out"
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(out))
    monkeypatch.setenv("VPR_CACHE_DIR", os.environ.get("VPR_CACHE_DIR", str(REPO / ".cache")))
    runner.run_study(dataset="synthetic", quick=True, notebooks=["06_comparison"],
                     real_data=True)
    for name in found:
        label = f"{name}_quick"
        assert (out / "figures" / label / "fig13_comparison.png").stat().st_size > 1000
        table = pd.read_csv(out / "results" / label / "06_comparison.csv")
        assert {"dense", "selection_scheme1", "classical", "global"} <= set(table["method"])
        assert (table["AUC lo"] <= table["AUC"] + 1e-9).all()
        assert (out / "results" / label / "06_comparison_fig13_comparison_paired.csv").exists()
