"""The study notebooks: paired with jupytext, stored without outputs, executed headless (quick)."""

import json
from pathlib import Path

import pytest

from vpr_core import runner

NB_DIR = Path(__file__).resolve().parents[1] / "notebooks"
NOTEBOOKS = sorted(NB_DIR.glob("[0-9][0-9]_*.ipynb"))


def test_six_numbered_notebooks():
    assert [p.stem for p in NOTEBOOKS] == list(runner.EXPECTED_FIGURES)


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


def test_quick_study_runs_headless_and_writes_every_figure(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_FIGURES_DIR", str(tmp_path / "figures"))
    monkeypatch.setenv("VPR_RESULTS_DIR", str(tmp_path / "results"))
    table = runner.run_study(dataset="synthetic", quick=True)
    for nb, stems in runner.EXPECTED_FIGURES.items():
        for stem in stems:
            png = tmp_path / "figures" / "synthetic_quick" / f"{stem}.png"
            assert png.stat().st_size > 1000, png
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for nb in ("03_landmark_selection", "04_overlap", "05_dense_sampling_parameters",
               "06_comparison"):
        assert (tmp_path / "results" / "synthetic_quick" / f"{nb}.csv").exists()
    assert {"AUC(ratio)", "R@100P", "R@1"} <= set(table.columns)
    assert len(table) >= 3 + 5 + 6 + 15 + 3
    # executed again (features now cached): byte-identical figures
    before = {p.name: p.read_bytes()
              for p in (tmp_path / "figures" / "synthetic_quick").glob("fig0[56]*.png")}
    runner.run_study(dataset="synthetic", quick=True, notebooks=["03_landmark_selection"])
    after = {p.name: p.read_bytes()
             for p in (tmp_path / "figures" / "synthetic_quick").glob("fig0[56]*.png")}
    assert before and before == after
