"""Notebook 07's step figures (issue 55): each paired difference drawn at its value with its
interval in its verdict's colour; each changed query's references at their ranks before and
after, the correct ones green; bad tables refused with the call that makes a good one."""

from __future__ import annotations

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from vpr_study.viz import plot_paired_differences, plot_step_changes
from vpr_study.viz.steps import VERDICT_COLORS

GREEN, RED = (matplotlib.colors.to_rgba(VERDICT_COLORS[w]) for w in ("higher", "lower"))


def _steps_table() -> pd.DataFrame:
    rows = [{"method": "dense", "run": "dense", "baseline": None}]
    for name, d, lo, hi, verdict in (
        ("dense (weighting: two_sided)", 0.10, 0.05, 0.15, "higher"),
        ("dense (normalised: database)", -0.20, -0.30, -0.10, "lower"),
        ("dense (normalised: query_batch, needs the query batch)", 0.01, -0.02, 0.04,
         "inconclusive"),
    ):  # fmt: skip
        rows.append(
            {"method": name, "run": name, "baseline": "dense"}
            | {
                f"{m}{s}": v
                for m in ("dAUC", "dR@1")
                for s, v in (("", d), (" lo", lo), (" hi", hi))
            }
            | {f"{m} verdict": verdict for m in ("dAUC", "dR@1")}
        )
    return pd.DataFrame(rows)


def _segments(ax) -> list[tuple[tuple, tuple, tuple]]:
    """``(xdata, ydata, rgba)`` of every two-point line (the intervals)."""
    return [
        (tuple(ln.get_xdata()), tuple(ln.get_ydata()), matplotlib.colors.to_rgba(ln.get_color()))
        for ln in ax.lines
        if len(ln.get_xdata()) == 2 and ln.get_linestyle() == "-"
    ]


def test_paired_differences_draw_each_interval_in_its_verdicts_colour():
    fig = plot_paired_differences(_steps_table(), title="t")
    ax_auc, ax_r1 = fig.axes[:2]
    segs = {(x, c) for x, _, c in _segments(ax_auc)}
    assert ((0.05, 0.15), GREEN) in segs  # higher: green, at its interval
    assert ((-0.30, -0.10), RED) in segs  # lower: red
    grey = [c for x, _, c in _segments(ax_auc) if x == (-0.02, 0.04)]
    assert grey and grey[0] not in (GREEN, RED)  # inconclusive: neither
    # the rows keep the table's order, top to bottom, named by their step
    labels = [t.get_text().replace("\n", " ") for t in ax_auc.get_yticklabels()]
    assert labels[0] == "dense: weighting: two_sided"
    assert labels[1] == "dense: normalised: database"
    assert ax_auc.get_xlabel().startswith("dAUC minus the method without the step")
    assert ax_r1.get_xlabel().startswith("dR@1")
    plt.close(fig)
    # compare() returns the method as the index: the same figure
    again = plot_paired_differences(_steps_table().set_index("method"), title="t")
    assert _segments(again.axes[0]) == _segments(ax_auc)
    plt.close(again)


def test_paired_differences_name_each_row_by_its_method_and_step_against_any_baseline():
    t = _steps_table()
    t.loc[1:, "baseline"] = "dense (weighting: contrast)"  # paired against today's contrast
    fig = plot_paired_differences(t, baseline="the method with contrast")
    labels = [x.get_text().replace("\n", " ") for x in fig.axes[0].get_yticklabels()]
    assert labels[0] == "dense: weighting: two_sided"
    assert labels[2] == "dense: normalised: query_batch, needs the query batch"
    assert "minus the method with contrast" in fig.axes[0].get_xlabel().replace("\n", " ")
    plt.close(fig)


def test_paired_differences_refuse_tables_without_a_baseline_or_metric():
    t = _steps_table()
    with pytest.raises(ValueError, match="compare\\(runs, baseline=...\\)"):
        plot_paired_differences(t.iloc[:1])
    with pytest.raises(ValueError, match="lacks dR@5, dR@5 lo, dR@5 hi, dR@5 verdict"):
        plot_paired_differences(t, metrics=("dR@5",))


def _changes() -> pd.DataFrame:
    rows = [
        (3, "fixed", 7, True, 4, 1, "two_sided"),
        (3, "fixed", 2, False, 1, 3, "two_sided"),
        (5, "broken", 9, True, 1, 40, "two_sided"),
        (3, "fixed", 7, True, 2, 1, "database"),
    ]
    cols = ["query", "case", "reference", "correct", "rank before", "rank after", "step"]
    return pd.DataFrame(rows, columns=cols).assign(why="w")


def test_step_changes_draw_each_reference_from_its_rank_before_to_after():
    fig = plot_step_changes(_changes(), title="t")
    panels = [ax for ax in fig.axes if ax.axison]
    assert len(panels) == 3  # two_sided: queries 3 and 5; database: query 3 (its 2nd panel off)
    lines = {
        p.get_title(): {(tuple(ln.get_ydata()), ln.get_color()) for ln in p.lines} for p in panels
    }
    assert lines["two_sided\nquery 3: fixed"] == {((4, 1), "tab:green"), ((1, 3), "0.55")}
    assert lines["two_sided\nquery 5: broken"] == {((1, 40), "tab:green")}
    assert lines["database\nquery 3: fixed"] == {((2, 1), "tab:green")}
    assert all(p.get_yscale() == "log" and p.get_ylim()[0] > p.get_ylim()[1] for p in panels)
    names = {t.get_text() for p in panels for t in p.texts}
    assert {"r7", "r2", "r9"} <= names
    plt.close(fig)


def test_step_changes_refuse_a_table_that_is_not_one():
    with pytest.raises(ValueError, match="pass step_changes\\(plain, stepped\\)"):
        plot_step_changes(pd.DataFrame({"query": [1]}))
    with pytest.raises(ValueError, match="no query changed"):
        plot_step_changes(_changes().iloc[:0])
    # without a step column: one row of panels
    fig = plot_step_changes(_changes().drop(columns="step").iloc[:2])
    assert sum(ax.axison for ax in fig.axes) == 1
    assert np.isclose(fig.get_figwidth(), 9.5)
    plt.close(fig)


def test_paired_differences_mark_methods_whose_rows_are_the_same_results():
    """Issue 61: where Scheme 1 keeps classical's boxes (Nordland) every step gives the same
    numbers for both; the figure says so (``(= classical)``, hollow dots), other blocks not."""
    blocks = []
    for method in ("classical", "selection_scheme1", "dense"):
        t = _steps_table()
        t["method"] = t["method"].str.replace("dense", method)
        t["baseline"] = t["baseline"].where(t["baseline"].isna(), method)
        if method == "dense":  # other numbers
            t["dAUC"] = t["dAUC"] + 0.01
        blocks.append(t)
    fig = plot_paired_differences(pd.concat(blocks))
    ax = fig.axes[0]
    labels = [x.get_text().replace("\n", " ") for x in ax.get_yticklabels()]
    assert labels[0] == "classical: weighting: two_sided"
    assert labels[3] == "selection_scheme1 (= classical): weighting: two_sided"
    assert labels[6] == "dense: weighting: two_sided"
    dots = [ln for ln in ax.lines if len(ln.get_xdata()) == 1]
    assert [d.get_fillstyle() for d in dots] == ["full"] * 3 + ["none"] * 3 + ["full"] * 3
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "(= classical): the same results as classical's rows" in legend
    plt.close(fig)
    # no block alike: no mark
    plain = plot_paired_differences(_steps_table())
    assert len(plain.legends[0].get_texts()) == 3
    plt.close(plain)


def test_step_changes_names_at_close_ranks_never_overlap():
    """Issue 61: ``r52`` and ``r1`` at ranks 21 and 22 printed over each other."""
    rows = [(6, "fixed", ref, False, 2, after, "database") for ref, after in
            ((52, 21), (1, 22), (14, 20), (53, 3))]  # fmt: skip
    rows += [(6, "fixed", 6, True, 2, 1, "database")]
    cols = ["query", "case", "reference", "correct", "rank before", "rank after", "step"]
    fig = plot_step_changes(pd.DataFrame(rows, columns=cols).assign(why="w"))
    fig.canvas.draw()
    ax = fig.axes[0]
    for side in ("left", "right"):
        boxes = [t.get_window_extent() for t in ax.texts if t.get_ha() == side]
        for i, a in enumerate(boxes):
            for b in boxes[i + 1 :]:
                assert a.y1 <= b.y0 or b.y1 <= a.y0, side  # no two names share a line
    plt.close(fig)
