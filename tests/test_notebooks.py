"""The study notebooks: paired with jupytext, stored without outputs, thin, executed headless
(quick) by the runner into a temporary output root."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vpr_study import runner
from vpr_study.figures import FIGURES, expected_figures

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
    assert all(not c.get("outputs") and c.get("execution_count") is None for c in code), (
        "commit notebooks without outputs (nbstripout)"
    )
    tagged = [c for c in code if "parameters" in c.get("metadata", {}).get("tags", [])]
    assert len(tagged) == 1
    params = "".join(tagged[0]["source"])
    for name in ("dataset", "root", "options", "limit", "label", "backbone", "pooling"):
        assert f"\n{name} =" in "\n" + params, name
    from vpr_core.datasets import DATASETS

    listed = params.split("\n")[0].split("#")[1].replace("|", " ").split()
    assert set(listed) == set(DATASETS), listed  # the dataset line names every loader
    # the .py twin in notebooks/scripts/ holds the same cells (jupytext pairing; Lab lists
    # each notebook once)
    assert nb["metadata"]["jupytext"]["formats"] == "ipynb,scripts//py:percent"
    assert not path.with_suffix(".py").exists()
    twin = jupytext.read(NB_DIR / "scripts" / f"{path.stem}.py")
    assert twin.metadata["jupytext"]["formats"] == "ipynb,scripts//py:percent"
    assert [c.source for c in twin.cells] == ["".join(c["source"]) for c in nb["cells"]]
    # the notebook is the experiment: it calls the pipeline, no facade, and stays thin
    source = "".join("".join(c["source"]) for c in code)
    assert "Image(filename" not in source and ".png" not in source
    assert "open_study" not in source and "vpr_core.study" not in source
    lines = [ln for ln in source.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    assert len(lines) <= 80, f"{path.name}: {len(lines)} code lines"
    assert "save(" in source


#: Every metric column of the quick study's tables as this code computes them (AUC, R@100P, R@K
#: with intervals and chance levels, the paired differences and verdicts).
PINNED = Path(__file__).parent / "data" / "quick_study_metrics.csv"


def assert_metrics_as_pinned(table: pd.DataFrame) -> None:
    """The quick study's metric columns equal :data:`PINNED` (to 1e-6; verdicts exactly). A
    change meant to move a number rewrites PINNED from ``runner.summary_table("synthetic_quick")``
    with its columns, and says which numbers moved and why in its commit."""
    want = pd.read_csv(PINNED).set_index(["figure", "run"])
    got = table.set_index(["figure", "run"])[want.columns]
    assert sorted(got.index) == sorted(want.index)
    got = got.loc[want.index]
    for col in want.columns:
        if pd.api.types.is_numeric_dtype(want[col]):
            moved = ~np.isclose(got[col].astype(float), want[col], atol=1e-6, equal_nan=True)
        else:
            moved = want[col].fillna("") != got[col].fillna("")
        assert not moved.any(), f"{col} moved: {list(want.index[moved])}"


def test_the_pinned_metrics_catch_a_moved_number_or_verdict():
    table = pd.read_csv(PINNED)
    assert_metrics_as_pinned(table.iloc[::-1])  # row order does not matter
    for col, value in (("R@1 hi", 0.6251), ("dAUC verdict", "inconclusive")):
        moved = table.copy()
        moved.loc[1, col] = value
        with pytest.raises(AssertionError, match=f"{col} moved"):
            assert_metrics_as_pinned(moved)
    with pytest.raises(AssertionError):
        assert_metrics_as_pinned(table.iloc[1:])  # a run missing


def test_quick_study_runs_headless_and_writes_every_figure(tmp_path, monkeypatch):
    out = tmp_path / "out"
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(out))
    monkeypatch.setenv("VPR_CACHE_DIR", os.environ.get("VPR_CACHE_DIR", str(REPO / ".cache")))
    monkeypatch.delenv("TQDM_DISABLE", raising=False)  # the kernels' bars, as a user sees them
    table = runner.run_study(dataset="synthetic", quick=True)
    figures = out / "figures" / "synthetic_quick"
    for spec in FIGURES:
        png = figures / f"{spec.stem}.png"
        assert png.stat().st_size > 1000, png
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (NB_DIR / "figures").exists() and not (NB_DIR / "results").exists()
    bars = {}
    for nb in expected_figures():
        executed = (out / "runs" / "synthetic_quick" / f"{nb}.ipynb").read_text()
        # every figure passed viz.layout_problems when saved (no cut text, no legend on data)
        assert "layout of " not in executed, nb
        # the executed notebook shows its figures inline and stays small enough to share
        assert '"image/' in executed and len(executed.encode()) < 3_000_000, nb
        # log lines and warnings are plain stdout lines; bars are text, never a frozen widget
        streams = [
            o
            for c in json.loads(executed)["cells"]
            for o in c.get("outputs", [])
            if o.get("output_type") == "stream"
        ]
        stderr = "".join("".join(o["text"]) for o in streams if o["name"] == "stderr")
        assert "vpr_core" not in stderr and "VPRWarning" not in stderr, (nb, stderr[:300])
        assert "application/vnd.jupyter.widget-view+json" not in executed, nb
        bars[nb] = "".join("".join(o["text"]) for o in streams if o["name"] == "stdout")
    assert "100%|" in bars["01_pipeline_tour"] and "[vpr_core INFO]" in bars["01_pipeline_tour"]
    results = out / "results" / "synthetic_quick"
    for stem in (
        "fig05_selection",
        "fig07a_overlap_nms",
        "fig07b_overlap_soft_nms",
        "fig10_scale_levels",
        "fig11_landmarks_per_scale",
        "fig12_normalized_scales",
        "fig13_comparison",
    ):
        saved = pd.read_csv(results / f"{stem}.csv")
        assert {"run", "AUC", "AUC lo", "baseline", "dAUC verdict", "dataset"} <= set(saved)
    assert (results / "table5_cost.timings.csv").exists() and (
        results / "fig04_matches.csv"
    ).exists()
    assert {"AUC", "R@100P", "R@1"} <= set(table.columns)
    assert len(table) == 3 + 5 + 6 + 6 + 5 + 4 + 4  # runs of Fig. 5, 7a, 7b, 10, 11, 12, 13
    # the pinned quick numbers (same as tests/test_pipeline.py's end-to-end test)
    fig13 = table[table["figure"] == "fig13_comparison"].set_index("run")
    assert round(fig13.loc["classical", "AUC"], 4) == 0.3544
    assert round(fig13.loc["dense", "AUC"], 4) == 0.9643
    assert_metrics_as_pinned(table)
    findings = (out / "results" / "findings.md").read_text()
    assert "selection Scheme 1 beats classical" in findings
    assert os.environ["VPR_OUTPUT_DIR"] == str(out)  # the runner restored the environment
    # executed again (features now cached): byte-identical figures
    before = {p.name: p.read_bytes() for p in figures.glob("fig04*.png")}
    runner.run_study(dataset="synthetic", quick=True, notebooks=["02_scale_statistics"], force=True)
    after = {p.name: p.read_bytes() for p in figures.glob("fig04*.png")}
    assert before and before == after


def test_real_datasets_beside_the_project_get_the_comparison(tmp_path, monkeypatch, capsys):
    """Three labels, two kernels side by side (``jobs=2``): a label's tables are the same as
    those of a run of that label alone, and each label's output lines name it."""
    found = runner.study_datasets()
    if not found:
        pytest.skip("no real datasets beside the project (../shared/data)")
    out = tmp_path / "out"
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(out))
    monkeypatch.setenv("VPR_CACHE_DIR", os.environ.get("VPR_CACHE_DIR", str(REPO / ".cache")))
    run = dict(dataset="synthetic", quick=True, notebooks=["06_comparison"], real_data=True)
    runner.run_study(**run, jobs=2)
    printed = capsys.readouterr().out
    tables = {p: p.read_bytes() for p in (out / "results").glob("*/fig13_comparison*.csv")}
    assert len(tables) == 2 * (len(found) + 1)  # the table and its .timings, per label
    runner.run_study(**{**run, "real_data": False}, force=True)  # synthetic_quick alone
    alone = out / "results" / "synthetic_quick" / "fig13_comparison.csv"
    assert alone.read_bytes() == tables[alone]
    for label in ["synthetic_quick", *(f"{name}_quick" for name in found)]:
        assert f"[{label}] " in printed
    for name in found:
        label = f"{name}_quick"
        assert (out / "figures" / label / "fig13_comparison.png").stat().st_size > 1000
        table = pd.read_csv(out / "results" / label / "fig13_comparison.csv")
        assert {"dense", "selection_scheme1", "classical", "global"} <= set(table["run"])
        assert table["dataset"].nunique() == 1 and table["root"].nunique() == 1
        assert (table["AUC lo"] <= table["AUC"] + 1e-9).all()
        assert set(table["baseline"].dropna()) == {"dense"}
        assert table["dAUC verdict"].notna().sum() == len(table) - 1


def test_notebook_07_shows_its_main_table_formatted_with_the_verdicts():
    """Issue 54 item 4: the 9-run table shows as ``compact`` (one column per metric, the paired
    difference with its verdict), not the raw 51-column frame whose ``...`` hid the verdicts."""
    import jupytext

    nb = jupytext.read(NB_DIR / "07_places_alike.ipynb")
    (cell,) = [c for c in nb.cells if 'save(table, "places_alike", label)' in c.source]
    assert cell.source.strip().splitlines()[-1].startswith("compact(table)")
    from vpr_core.evaluation import compact

    rows = {
        "queries": [8, 8],
        "protocol": ["ratio"] * 2,
        "baseline": ["dense", "dense"],
        **{
            f"{m}{s}": [0.5, 0.6]
            for m in ("AUC", "R@100P", "R@1", "R@5")
            for s in ("", " lo", " hi")
        },
        **{f"d{m}{s}": [None, 0.1] for m in ("AUC", "R@100P", "R@1") for s in ("", " lo", " hi")},
        **{f"d{m} verdict": [None, "higher"] for m in ("AUC", "R@100P", "R@1")},
    }
    shown = compact(pd.DataFrame(rows, index=["dense", "dense (weighting: contrast)"]))
    assert len(shown.columns) < 12 and "higher" in shown.to_string()


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_no_markdown_cell_breaks_off_mid_sentence(path):
    """Issue 54 item 6: notebook 01's introduction ended in "Every figure cell shows the"."""
    import jupytext

    for cell in jupytext.read(path).cells:
        if cell.cell_type != "markdown":
            continue
        last = cell.source.rstrip().splitlines()[-1].strip()
        assert last.startswith(("#", "|", "-", "*", "!")) or last.endswith(
            (".", ":", "!", "?", ")", "`", "*", "|", "$")
        ), f"{path.name}: a Markdown cell ends mid-sentence: {last!r}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_no_wrapped_markdown_line_starts_a_list(path):
    """Issue 61: notebook 07's wrapped line "+ query batch 0.955." rendered as a bullet and split
    its sentence: a line starting with ``-``, ``+`` or ``*`` right after a paragraph's line
    (not a list's) starts a list in Markdown."""
    import re

    import jupytext

    for cell in jupytext.read(path).cells:
        if cell.cell_type != "markdown":
            continue
        prev, in_list = "", False
        for line in cell.source.splitlines():
            item = re.match(r"[-+*] ", line) is not None
            assert not (item and prev.strip() and not in_list), (
                f"{path.name}: {line!r} follows a paragraph line and renders as a bullet"
            )
            in_list = (in_list or item) and bool(line.strip())
            prev = line
