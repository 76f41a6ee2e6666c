"""(Not in the paper) What a step (a weighting, a normalisation) does: each method's paired
differences with their 95% intervals (:func:`plot_paired_differences`, from ``compare``
tables) and, for chosen queries, the references that rose or fell (:func:`plot_step_changes`,
from ``step_changes``)."""

from __future__ import annotations

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.lines import Line2D

from ..tables import CHANGES, COMPARISON, check_table
from ._shared import FIG_WIDTH, FONT, wrapped

__all__ = ["VERDICT_COLORS", "plot_paired_differences", "plot_step_changes"]

#: Colour of a paired difference by its verdict's first word; every other verdict grey.
VERDICT_COLORS = {"higher": "tab:green", "lower": "tab:red"}
_OTHER = "0.45"


def _row_text(method: str, baseline: str, same_as: str | None = None) -> str:
    """A row's name: ``"dense (weighting: two_sided)"`` beside baseline ``dense`` or ``"dense
    (weighting: contrast)"`` -> ``"dense: weighting: two_sided"`` (the method, then its step);
    ``same_as``: the method whose block gives the same numbers (``"selection_scheme1 (=
    classical): weighting: two_sided"``)."""
    name = baseline.split(" (", 1)[0]
    head = f"{name} ("
    said = f"{name} (= {same_as})" if same_as else name
    if method.startswith(head) and method.endswith(")"):
        return f"{said}: {method[len(head) : -1]}"
    return f"{method} (= {same_as})" if same_as else method


#: The columns whose values make a block of rows "the same results" as another's: every metric
#: with its interval and every paired difference with its interval and p.
_RESULT_COLUMNS = ("AUC", "R@100P", "R@1", "R@5", "dAUC", "dR@100P", "dR@1")


def _same_blocks(rows: pd.DataFrame) -> dict[str, str]:
    """``{baseline: earlier baseline}`` for each block of rows (one baseline) whose numbers
    (:data:`_RESULT_COLUMNS` with their ``lo``, ``hi``, ``p``) equal an earlier block's, row for
    row: two methods that gave identical results on this dataset (e.g. Scheme 1 keeping the
    boxes of classical)."""
    cols = [
        c
        for c in rows.columns
        if c.split(" ")[0] in _RESULT_COLUMNS
        and c.split(" ", 1)[-1] in (c, "lo", "hi", "p")
        and pd.api.types.is_numeric_dtype(rows[c])
    ]
    if not cols:
        return {}
    blocks = {b: rows.loc[rows["baseline"] == b, cols].to_numpy(dtype=float) for b in
              dict.fromkeys(rows["baseline"])}  # fmt: skip
    out: dict[str, str] = {}
    seen: list[str] = []
    for b, values in blocks.items():
        twin = next(
            (
                e
                for e in seen
                if blocks[e].shape == values.shape
                and np.array_equal(blocks[e], values, equal_nan=True)
            ),
            None,
        )
        if twin is not None:
            out[str(b)] = str(twin).split(" (", 1)[0]
        else:
            seen.append(b)
    return out


def _verdict_colour(verdict: object) -> str:
    word = str(verdict).split(" ", 1)[0]
    return VERDICT_COLORS.get(word, _OTHER)


def plot_paired_differences(
    table: pd.DataFrame,
    metrics: tuple[str, ...] = ("dAUC", "dR@1"),
    title: str | None = None,
    baseline: str = "the method without the step",
) -> matplotlib.figure.Figure:
    """Each row of ``compare`` tables (several concatenated: one block per baseline) that has a
    baseline, as its paired difference with the 95% interval, one panel per metric; green:
    ``higher``, red: ``lower``, grey: any other verdict (the interval holds 0, too few queries,
    identical results). Rows of one baseline are grouped, separated by a line; a group whose
    numbers equal an earlier group's, row for row (two methods with identical results on this
    dataset), says so in its row names (``selection_scheme1 (= classical): ...``) and is drawn
    with hollow dots.

    Args:
        table: ``compare`` output(s) (``method`` the index, as ``compare`` returns them, or a
            column, as their CSV reads) with the ``baseline`` column and, per metric, its
            value, ``lo``, ``hi`` and ``verdict`` columns.
        metrics: the difference columns drawn (``dAUC``, ``dR@100P``, ``dR@1``, ...).
        title: the figure's title.
        baseline: what the rows are paired against, in the axis labels.
    """
    if "method" not in table.columns and table.index.name == "method":  # as compare() returns
        table = table.reset_index()
    rows = table[table["baseline"].notna()] if "baseline" in table.columns else table.iloc[:0]
    if rows.empty:
        raise ValueError(
            "plot_paired_differences needs compare() tables with a baseline: pass "
            "compare(runs, baseline=...)"
        )
    for m in metrics:
        missing = [c for c in (m, f"{m} lo", f"{m} hi", f"{m} verdict") if c not in rows.columns]
        if missing:
            raise ValueError(
                f"the table lacks {', '.join(missing)}: metrics must be difference columns of "
                f"compare(), e.g. ('dAUC', 'dR@1'); it has "
                f"{', '.join(c for c in rows.columns if c.startswith('d') and ' ' not in c)}"
            )
    check_table(rows, COMPARISON)  # intervals ordered, p in [0, 1], ... (one schema per table)
    same = _same_blocks(rows)
    labels = [
        wrapped(_row_text(str(m), str(b), same.get(str(b))), 3.6, FONT - 1)
        for m, b in zip(rows["method"], rows["baseline"], strict=True)
    ]
    hollow = [str(b) in same for b in rows["baseline"]]
    n = len(rows)
    y = np.arange(n)[::-1]
    row_h = 0.14 * max(t.count("\n") + 1 for t in labels) + 0.14
    height = row_h * n + 1.6 + 0.2 * (title or "").count("\n")
    fig, axes = plt.subplots(1, len(metrics), figsize=(FIG_WIDTH, height), sharey=True)
    axes = np.atleast_1d(axes)
    groups = np.flatnonzero(rows["baseline"].to_numpy()[1:] != rows["baseline"].to_numpy()[:-1])
    for ax, m in zip(axes, metrics, strict=True):
        d = rows[m].to_numpy(dtype=float)
        lo, hi = rows[f"{m} lo"].to_numpy(dtype=float), rows[f"{m} hi"].to_numpy(dtype=float)
        colours = [_verdict_colour(v) for v in rows[f"{m} verdict"]]
        ax.axvline(0.0, color="black", lw=0.8)
        for k in range(n):
            ax.plot([lo[k], hi[k]], [y[k], y[k]], color=colours[k], lw=2.0)
            fill = "none" if hollow[k] else "full"  # the same numbers as an earlier block
            ax.plot(d[k], y[k], "o", color=colours[k], ms=4, fillstyle=fill)
        for g in groups:
            ax.axhline(y[g] - 0.5, color="0.8", lw=0.6)
        ax.set_xlabel(wrapped(f"{m} minus {baseline}, 95% paired interval", 3.0), fontsize=FONT)
        ax.tick_params(labelsize=FONT - 1)
        ax.grid(axis="x", alpha=0.3)
        ax.set_ylim(-0.7, n - 0.3)
    axes[0].set_yticks(y)
    axes[0].set_yticklabels(labels, fontsize=FONT - 1)
    handles = [
        Line2D([], [], color=c, marker="o", lw=2.0, label=w)
        for w, c in (*VERDICT_COLORS.items(), ("inconclusive or not testable", _OTHER))
    ]
    if same:
        names = sorted(set(same.values()))
        m = names[0] if len(names) == 1 else "m"
        handles.append(
            Line2D([], [], color=_OTHER, marker="o", fillstyle="none", lw=0,
                   label=f"(= {m}): the same results as {m}'s rows")
        )  # fmt: skip
    fig.legend(
        handles=handles, loc="lower center", ncol=min(len(handles), 4 if same else 3),
        frameon=False, fontsize=FONT, bbox_to_anchor=(0.5, 0.0),
    )  # fmt: skip
    if title:
        fig.suptitle(title, fontsize=FONT + 1)
    fig.tight_layout(rect=(0.0, 0.45 / height, 1.0, 1.0))
    return fig


def plot_step_changes(changes: pd.DataFrame, title: str | None = None) -> matplotlib.figure.Figure:
    """``step_changes`` tables (one or several, concatenated with a ``step`` column) as slope
    charts: one panel per step and query, each reference's rank before and after the step (log
    scale, rank 1 on top), the correct references in green and labelled ``rN``; the ``why``
    column says what moved them.

    Args:
        changes: :func:`vpr_core.step_changes` output(s); a ``step`` column names the
            step of each row (one panel row per step), else one step.
        title: the figure's title.
    """
    need = ["query", "case", "reference", "correct", "rank before", "rank after"]
    missing = [c for c in need if c not in changes.columns]
    if missing:
        raise ValueError(
            f"the table lacks {', '.join(missing)}: pass step_changes(plain, stepped) (several "
            "concatenated with a 'step' column)"
        )
    if changes.empty:
        raise ValueError("no query changed under the step: nothing to plot")
    check_table(changes, CHANGES)  # ranks >= 1 (a log axis), integer indices, ...
    frame = changes if "step" in changes.columns else changes.assign(step="step")
    steps = list(dict.fromkeys(frame["step"]))
    panels = [
        [(q, g) for q, g in frame[frame["step"] == s].groupby("query", sort=False)] for s in steps
    ]
    cols = max(len(p) for p in panels)
    top = 0.5 + 0.2 * (title or "").count("\n") if title else 0.2
    height = 2.6 * len(steps) + top + 0.45
    fig, axes = plt.subplots(
        len(steps), cols, figsize=(FIG_WIDTH, height), squeeze=False, sharey=True
    )
    worst = float(max(frame["rank before"].max(), frame["rank after"].max()))
    labelled: list[tuple] = []  # each panel's reference names, spread apart once laid out
    for i, (step, row) in enumerate(zip(steps, panels, strict=True)):
        for j in range(cols):
            ax = axes[i, j]
            if j >= len(row):
                ax.set_axis_off()
                continue
            q, g = row[j]
            cols_ = ("reference", "correct", "rank before", "rank after")
            names: list = []
            for ref, ok, before, after in zip(*(g[c] for c in cols_), strict=True):
                colour, lw, z = ("tab:green", 2.2, 3) if ok else ("0.55", 1.0, 2)
                ax.plot([0, 1], [before, after], "-o", color=colour, lw=lw, ms=3, zorder=z)
                if ok or min(before, after) <= 3:  # the correct ones and the top 3 named
                    for x, v, ha in ((-0.04, before, "right"), (1.04, after, "left")):
                        names.append(ax.text(x, v, f"r{ref}", ha=ha, va="center",
                                             color=colour, fontsize=FONT - 2))  # fmt: skip
            labelled.append((ax, names))
            ax.set_yscale("log")
            ax.set_ylim(worst * 1.4, 0.8)
            ax.set_xlim(-0.45, 1.45)
            ax.set_xticks([0, 1], ["before", "after"], fontsize=FONT - 1)
            ax.tick_params(axis="y", labelsize=FONT - 1)
            ax.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            case = str(g["case"].iloc[0])
            ax.set_title(wrapped(f"{step}\nquery {q}: {case}", FIG_WIDTH / cols), fontsize=FONT)
            if j == 0:
                ax.set_ylabel("rank (log)", fontsize=FONT)
    handles = [
        Line2D([], [], color="tab:green", lw=2.2, marker="o", label="a correct reference"),
        Line2D([], [], color="0.55", lw=1.0, marker="o", label="another reference"),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=2, frameon=False, fontsize=FONT)
    if title:
        fig.suptitle(title, fontsize=FONT + 1)
    fig.tight_layout(rect=(0.0, 0.35 / height, 1.0, 1.0))
    for ax, names in labelled:
        _spread(ax, names, 1.45 * (FONT - 2) * fig.dpi / 72)  # a line and a half
    return fig


def _spread(ax, texts: list, gap: float) -> None:
    """Move the names of one side of a panel apart vertically until each pair is at least
    ``gap`` display units apart (an overlapping group centred on where its names were), so
    two references at close ranks never print over each other."""
    to_display = ax.transData
    for side in ("left", "right"):
        items = sorted(
            ((to_display.transform(t.get_position()), t) for t in texts if t.get_ha() == side),
            key=lambda item: -item[0][1],
        )
        groups = [[xy[1]] for xy, _ in items]  # the names' own heights, top first
        merged = True
        while merged:
            merged = False
            for i in range(len(groups) - 1):
                top = np.mean(groups[i]) - (len(groups[i]) - 1) * gap / 2  # group i's lowest
                below = np.mean(groups[i + 1]) + (len(groups[i + 1]) - 1) * gap / 2
                if top - below < gap:
                    groups[i : i + 2] = [groups[i] + groups[i + 1]]
                    merged = True
                    break
        ys = [np.mean(g) + ((len(g) - 1) / 2 - k) * gap for g in groups for k in range(len(g))]
        for (xy, text), y in zip(items, ys, strict=True):
            text.set_position(to_display.inverted().transform((xy[0], y)))
