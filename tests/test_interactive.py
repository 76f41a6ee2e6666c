"""The workbook used the way a user works in JupyterLab (issue 44 items 1, 7, 8; issue 45 item 1):
a figure shown in one cell is saved in the next, a closed figure saves, a save without a label
goes to the user's area and says where, a file name never leaves its folder, and the PR legend
and the disagreement captions read at the size Lab shows them."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from vpr_study import viz
from vpr_study.viz.base import DEFAULT_LABEL, save_all

REPO = Path(__file__).resolve().parents[1]

#: A user's notebook: a figure shown by the inline backend in one cell, saved in the next
#: beside a table (the issue's crash: the inline backend closes a shown figure, leaving it
#: a canvas without a renderer, and the table of the same line was never written).
USER_CELLS = [
    "%matplotlib inline\n"
    "import matplotlib.pyplot as plt\n"
    "import numpy as np\n"
    "import pandas as pd\n"
    "import dataclasses\n"
    "from vpr_core import Evaluation, MethodResult, result_from_matrix\n"
    "from vpr_study.viz import plot_pr_curves, save",
    "fig, ax = plt.subplots(figsize=(5, 3))\n"
    "ax.plot([0, 1], [1, 0], label='mine')\n"
    "ax.set_title('my own figure')\n"
    "ax.legend(loc='upper right')\n"
    "fig",
    "gt = np.eye(6, dtype=bool)\n"
    "sim = gt + np.random.default_rng(0).random((6, 6))\n"
    "made = MethodResult('dense', 'dense', 'toy', {'name': 'dense'}, {}, sim, gt,\n"
    "                    {'query': [], 'reference': []}, {}, {}, tolerance=0)\n"
    "run = result_from_matrix(sim, made, Evaluation(n_bootstrap=0))\n"
    "run = dataclasses.replace(run, intervals={'auc': (0.5, 0.25, 0.75)})\n"
    "pr = plot_pr_curves([run], title='my PR figure')",
    "print(plt.get_backend(), type(fig.canvas).__name__)\n"
    "save(fig, 'x', 'mine'), save(pd.DataFrame({'a': [1.0]}), 'x', 'mine')\n"
    "save(pr, 'pr', 'mine')",
    "from matplotlib_inline.backend_inline import set_matplotlib_formats\n"
    "set_matplotlib_formats('jpeg')\n"  # as notebooks 01 and 07 do: shown once, as JPEG
    "plot_pr_curves([run], title='the value of its cell')",  # issue 54: shown once
    "try:\n"  # issue 54: a plt.gcf() of a later cell is empty: refused, the fix named
    "    save(plt.gcf(), 'blank', 'mine')\n"
    "except ValueError as exc:\n"
    "    print(exc)",
]


def test_a_figure_shown_in_one_cell_saves_in_the_next_with_its_table(tmp_path, monkeypatch):
    """Executed with nbclient on the inline backend, as JupyterLab runs a user's cells; the
    kernel writes under VPR_OUTPUT_DIR (a temporary folder), never into the checkout."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(src) for src in USER_CELLS]
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3"}
    client = nbclient.NotebookClient(
        nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()  # a cell's error raises CellExecutionError, naming it
    shown = [o for o in nb.cells[1].outputs if "image/png" in o.get("data", {})]
    assert len(shown) == 1, "the figure, the cell's value, was displayed once in its cell"
    for cell, kind in (nb.cells[2], "png"), (nb.cells[4], "jpeg"):  # assigned, or the value
        assert len([o for o in cell.outputs if f"image/{kind}" in o.get("data", {})]) == 1
    refused = "".join(o.get("text", "") for o in nb.cells[5].outputs)
    assert "has no axes" in refused and "fig = plot_pr_curves(runs); save(fig" in refused
    assert not (tmp_path / "figures" / "mine" / "blank.png").exists()
    printed = "".join(o.get("text", "") for o in nb.cells[3].outputs)
    assert "inline" in printed and "FigureCanvasBase" in printed  # the state of the issue
    png = tmp_path / "figures" / "mine" / "x.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "results" / "mine" / "x.csv").read_text().startswith("a\n1.0")
    assert (tmp_path / "figures" / "mine" / "pr.png").stat().st_size > 1000
    assert (
        not (REPO / "figures" / "mine").exists()
        and not (REPO / "user" / "figures" / "mine").exists()
    )


CLOSED = """
import matplotlib
matplotlib.use("module://matplotlib_inline.backend_inline")
import sys
import matplotlib.pyplot as plt
import pandas as pd
from vpr_study.viz.base import save_all

def figure():
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot([0, 1], [0, 1], label="a")
    ax.set_title("closed")
    ax.legend(loc="upper left")
    return fig

open_fig = figure()
save_all([("open", open_fig)], "mine", out=sys.argv[1])
closed = figure()
plt.close(closed)
print(type(closed.canvas).__name__)
save_all([("closed", closed), ("table", pd.DataFrame({"a": [1]}))], "mine", out=sys.argv[1])
"""


def test_a_closed_figure_saves_with_its_table_and_the_same_bytes(tmp_path):
    """``plt.close(fig)`` under the inline backend (a script, as the issue ran it) leaves a
    bare FigureCanvasBase: the layout check used to crash on it, and the table of the same
    call was lost. The saved PNG is the one of the same figure saved open."""
    script = tmp_path / "closed.py"
    script.write_text(CLOSED)
    done = subprocess.run(
        [sys.executable, str(script), str(tmp_path / "out")],
        capture_output=True,
        text=True,
        env={**os.environ, "MPLBACKEND": "Agg"},
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "FigureCanvasBase"
    figures = tmp_path / "out" / "figures" / "mine"
    assert (figures / "closed.png").read_bytes() == (figures / "open.png").read_bytes()
    assert (tmp_path / "out" / "results" / "mine" / "table.csv").exists()


def test_a_closed_figure_saves_in_this_process_too(tmp_path):
    from matplotlib.backend_bases import FigureCanvasBase

    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot([0, 1], [0, 1])
    FigureCanvasBase(fig)  # what the inline backend leaves on a shown or closed figure
    plt.close(fig)
    assert not hasattr(fig.canvas, "get_renderer")
    paths = save_all([("f", fig), ("t", pd.DataFrame({"a": [1]}))], "mine", out=tmp_path)
    assert [p.exists() for p in paths] == [True, True]


def test_a_save_without_a_label_goes_to_the_user_area_and_says_where(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path))
    records: list[logging.LogRecord] = []
    handler = logging.Handler(logging.INFO)
    handler.emit = records.append  # type: ignore[method-assign]
    log = logging.getLogger("vpr_core")
    level = log.level
    log.addHandler(handler)
    log.setLevel(logging.INFO)
    try:
        fig, ax = plt.subplots(figsize=(4, 3))
        ax.plot([0, 1], [0, 1])
        png = viz.save(fig, "my_try")
        csv = viz.save(pd.DataFrame({"a": [1.0]}), "my_table")
    finally:
        log.removeHandler(handler)
        log.setLevel(level)
        plt.close("all")
    assert png == tmp_path / "user" / "figures" / DEFAULT_LABEL / "my_try.png" and png.exists()
    assert csv == tmp_path / "user" / "results" / DEFAULT_LABEL / "my_table.csv" and csv.exists()
    assert not (tmp_path / "figures").exists()  # never among the study's outputs
    said = [r.getMessage() for r in records]
    assert any(repr(DEFAULT_LABEL) in m and str(png) in m for m in said), said
    assert any(str(csv) in m for m in said), said


@pytest.mark.parametrize("name", ["../x", "../../../../x", "/abs/x", "a/b", "..", "a\\b", "x\ny"])
def test_a_name_is_one_file_name(tmp_path, name):
    """``save(obj, name, label)`` confines ``name`` as it confines ``label`` (issue 45)."""
    if name.startswith("/abs"):
        name = str(tmp_path / "escaped" / "x")  # an absolute name, where an escape would land
    out = tmp_path / "out"
    fig, _ = plt.subplots(figsize=(3, 2))
    for obj in (fig, pd.DataFrame({"a": [1.0]})):
        with pytest.raises(ValueError, match="must be one file name without folders") as info:
            viz.save(obj, name, "mine", out=out)
        assert repr(name) in str(info.value)
    plt.close(fig)
    written = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert written == [], written  # nothing written anywhere


def test_a_bad_name_in_save_all_writes_nothing(tmp_path):
    fig, _ = plt.subplots(figsize=(3, 2))
    with pytest.raises(ValueError, match="one file name"):
        save_all([("fine", fig), ("../bad", pd.DataFrame({"a": [1]}))], "mine", out=tmp_path)
    plt.close(fig)
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []


def test_pr_legend_takes_no_width_from_the_plot_one_line_per_entry_each_with_its_line(
    tiny_synthetic,
):
    """The PR legend of a tiny synthetic run: below the axes (the axes keep at least three
    quarters of the figure's width, the legend takes none of it: it was a column of 40% beside
    them), every entry one line, every entry with a visible line sample (the repeated curve's
    entry had none)."""
    from matplotlib.lines import Line2D

    from vpr_core import run_method

    runs = [
        run_method(m, tiny_synthetic, backbone="hog", n_bootstrap=50)
        for m in ("dense", "classical", "global")
    ]
    runs.append(
        run_method(
            "global",
            tiny_synthetic,
            backbone="hog",
            n_bootstrap=50,
            label="global with a long label: the same matrix again",
        )
    )
    fig = viz.plot_pr_curves(runs, title="a tiny run")
    fig.canvas.draw()
    ax = fig.axes[0]
    legend = ax.get_legend()
    width = fig.bbox.width
    box, axes_box = legend.get_window_extent(), ax.get_window_extent()
    assert axes_box.width >= 0.75 * width  # the plot keeps the figure's width
    assert box.y1 <= axes_box.y0 and box.x0 >= 0 and box.x1 <= width  # below it, inside
    texts = [t.get_text() for t in legend.get_texts()]
    assert len(texts) == 5 and all("\n" not in t for t in texts), texts
    assert "same curve as global" in texts[3]
    assert texts[0].startswith("dense  0.") and "AUC" not in texts[0]  # the title names it
    assert legend.get_title().get_text().startswith("AUC [95% CI]")
    for handle in legend.legend_handles:
        assert isinstance(handle, Line2D)
        assert handle.get_linewidth() > 0 and handle.get_linestyle() not in ("None", "")
    assert viz.layout_problems(fig) == []
    plt.close(fig)


def test_disagreement_captions_read_at_the_displayed_size_and_the_title_says_what_it_shows(
    tiny_synthetic,
):
    """Lab shows a figure at 100 dpi, scaled down to its output column (about 950 px): the
    captions were 8 points on a 14-inch figure (about 6 px high). Every caption is now at
    least 9 points at the displayed size; the title counts the wins and losses and each row
    says which it is; both are shown when both exist."""
    import re

    from vpr_core import run_method

    runs = [
        run_method(m, tiny_synthetic, keep_descriptors=True, backbone="hog", n_bootstrap=0)
        for m in ("dense", "classical")
    ]
    fig = viz.plot_disagreements(tiny_synthetic, *runs, n=4)
    table = fig.table  # the rows shown, in order
    lab_column = 9.5  # inches at 100 dpi
    shown_at = min(1.0, lab_column / fig.get_figwidth())
    texts = [t for ax in fig.axes for t in (ax.title,)] + [fig._suptitle]
    assert all(t.get_fontsize() * shown_at >= 9 for t in texts if t.get_text())
    head = fig._suptitle.get_text()
    found = re.search(r"dense wins (\d+), loses (\d+)", head)
    assert found, head
    wins, losses = int(found[1]), int(found[2])
    ok = table.pivot(index="query", columns="run", values="top-1 correct").astype(bool)
    rows = [ax.get_title() for ax in fig.axes[2::3]]
    kinds = [re.search(r"QUERY \d+: (dense wins|dense loses|the runs agree)", r)[1] for r in rows]
    for q, kind in zip(list(dict.fromkeys(table["query"])), kinds, strict=True):
        assert kind == (
            "dense wins"
            if ok.loc[q, "dense"] and not ok.loc[q, "classical"]
            else "dense loses"
            if ok.loc[q, "classical"] and not ok.loc[q, "dense"]
            else "the runs agree"
        )
    if wins and losses:
        assert "dense wins" in kinds and "dense loses" in kinds
    assert f"{kinds.count('dense wins')} where dense wins" in head
    assert viz.layout_problems(fig) == []
    plt.close(fig)


def _fake(label, sim, gt):
    from vpr_core.evaluation import evaluate, pr_curve

    return SimpleNamespace(
        label=label,
        similarity=sim,
        ground_truth=gt,
        dataset="toy",
        tolerance=0,
        protocol="ratio",
        metrics=evaluate(sim, gt),
        intervals={},
        curve=lambda: pr_curve(sim, gt, warn=False),
    )


@pytest.mark.filterwarnings("ignore:per_query")
def test_disagreements_show_wins_and_losses_when_both_exist():
    """Six wins shown under a title promising wins and losses (Nordland): the pick takes both
    kinds when both exist, and the title counts them."""
    from vpr_core.evaluation.queries import per_query
    from vpr_study.viz.disagreements import _pick

    gt = np.eye(10, dtype=bool)
    a = gt * 2.0 + 0.1
    b = gt * 2.0 + 0.1
    a[[0, 1, 2, 3, 4, 5, 6], 9] = 5.0  # a wrong on 7 queries: b wins there
    b[[7, 8], 0] = 5.0  # b wrong on 2 queries: a wins there
    full = per_query([_fake("a", a, gt), _fake("b", b, gt)])
    shown, kind, wins, losses = _pick(full, "a", "b", 6)
    assert (wins, losses) == (2, 7)
    assert [kind[q] for q in shown] == ["a wins"] * 2 + ["a loses"] * 4
    shown, kind, *_ = _pick(full, "a", "b", 12)  # every disagreement, then agreeing ones
    assert len(shown) == 10 and list(kind.values()).count("the runs agree") == 1
