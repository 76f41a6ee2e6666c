"""(Not in the paper.) What whitening the landmark descriptors on the reference database does
(notebook 07): the frame of :func:`vpr_core.whitening_changes`, drawn."""

from __future__ import annotations

from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.ticker import FormatStrFormatter, MaxNLocator, NullLocator

from vpr_core import whitening_changes

from ._shared import FIG_WIDTH, FONT, check_runs_on, wrapped
from .curves import dataset_line

__all__ = ["plot_whitening"]


def plot_whitening(
    ds: Any, plain: Any, whitened: Any, n_queries: int = 2, shared: int = 10
) -> tuple[matplotlib.figure.Figure, pd.DataFrame]:
    """(Not in the paper) What whitening on the reference database did (docs/DEFINITIONS.md).

    Draws the frame of :func:`vpr_core.whitening_changes`. Left, (a): the share of the plain
    cosine of the shown pairs' reciprocal matches (the plain run's) carried by the database
    mean, by its ``shared`` largest principal components, by the next ones to 50, by the rest
    kept and by the components beyond (dropped), and the same matches' whitened cosine by the
    same groups: what many places share loses its weight. Then one panel per chosen query: the
    rank of each shown reference before and after whitening, green for a correct reference, red
    for a wrong one, each labelled with the share of its plain match cosine that the mean and
    the ``shared`` largest components carried.

    Args:
        ds: the runs' dataset; plain: a method's run without whitening and ``whitened`` the same
            with ``whiten=k``, both with ``keep_descriptors=True``.
        n_queries: queries shown (1 to 3); shared: the components called shared (1 to 50).

    Returns:
        ``(figure, table)``: the frame, one row per query and reference shown.

    Raises:
        ValueError: as :func:`vpr_core.whitening_changes`; runs of another dataset.
    """
    check_runs_on(ds, (plain, whitened), "plot_whitening")
    table = whitening_changes(plain, whitened, n_queries, shared)
    at = table.attrs
    panels = [(q, case, table[table["query"] == q].to_dict("records")) for q, case in at["queries"]]
    head = wrapped(
        f"(not in the paper) What whitening the landmark descriptors on the reference database "
        f"({at['kept']} components, fitted on {at['landmarks']:,} reference landmarks) does: "
        f"{plain.label} without and with it; top-1 changed for {at['changed']} of "
        f"{at['with_gt']} queries\n{dataset_line([plain])}\n(a) the plain cosine of the "
        "shown pairs' reciprocal matches (grey) and the same matches' whitened cosine (blue), "
        "by what carries them: the mean of every reference landmark and the database's "
        "principal components, largest first; then each shown reference's rank before and after "
        f"(green: correct, red: wrong); shared = the share of the pair's plain match cosine "
        f"carried by the mean and the {at['shared']} largest components",
        FIG_WIDTH - 0.2,
    )
    line = FONT * 1.25 / 72
    top = (head.count("\n") + 2) * line + 0.35
    panel_h = 2.6
    height = top + panel_h + 1.0
    fig = plt.figure(figsize=(FIG_WIDTH, height))
    fig.suptitle(head, fontsize=FONT, x=0.1 / FIG_WIDTH, y=1 - 0.08 / height, ha="left", va="top")
    n_p = 1 + len(panels)
    grid = fig.add_gridspec(
        1,
        n_p,
        left=0.07,
        right=0.99,
        bottom=0.9 / height,
        top=1 - top / height,
        wspace=0.35,
        width_ratios=[1.3] + [1.0] * len(panels),
    )
    ax = fig.add_subplot(grid[0, 0])
    names = at["parts"]
    pos = np.arange(len(names))
    ax.bar(pos - 0.2, at["before"], 0.4, color="0.55", label="plain cosine")
    ax.bar(pos + 0.2, at["after"], 0.4, color="tab:blue", label="whitened cosine")
    ax.axhline(0, color="k", lw=0.6)
    top_bar = float(np.nanmax([*at["before"], *at["after"], 0.0]))
    ax.set_ylim(top=1.3 * top_bar if top_bar > 0 else 1.0)  # room for the legend above the bars
    ax.set_xticks(pos, names, rotation=35, ha="right", fontsize=FONT - 1)
    ax.set_ylabel("share of the matches' cosine", fontsize=FONT)
    ax.set_title(wrapped("(a) what carries a match's cosine", 3.0), fontsize=FONT)
    ax.legend(fontsize=FONT - 1, frameon=False, loc="upper center", ncol=2)
    ax.tick_params(labelsize=FONT - 1)
    for c, (q, case, points) in enumerate(panels, start=1):
        ax = fig.add_subplot(grid[0, c])
        for row in points:
            r, ok, r_b, r_a = (
                row["reference"],
                row["correct"],
                row["rank before"],
                row["rank after"],
            )
            share = row["shared share"]
            colour = "tab:green" if ok else "tab:red"
            ax.plot([0, 1], [r_b, r_a], color=colour, marker="o", lw=2 if ok else 1.2)
            ax.annotate(
                f"r{r}{' correct' if ok else ''}\nshared {share:.0%}",
                (1, r_a),
                xytext=(6, 0),
                textcoords="offset points",
                va="center",
                fontsize=FONT,
                color=colour,
            )
        worst = max(max(p["rank before"], p["rank after"]) for p in points)
        if worst > 10:  # ranks 1, 2, 5, 10, 20, ... written as integers
            ax.set_yscale("log")
            ticks = [t * 10**e for e in range(len(str(worst)) + 1) for t in (1, 2, 5)]
            ax.set_yticks([t for t in ticks if t <= worst * 1.6], minor=False)
            ax.yaxis.set_major_formatter(FormatStrFormatter("%d"))
            ax.yaxis.set_minor_locator(NullLocator())
        else:
            ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_ylim(worst * (1.6 if worst > 10 else 1) + 0.5, 0.6)
        ax.set_xlim(-0.15, 2.1)
        ax.set_xticks([0, 1], ["plain", "whitened"], fontsize=FONT - 1)
        ax.set_ylabel("rank of the reference" if c == 1 else "", fontsize=FONT)
        ax.set_title(f"({chr(97 + c)}) query {q}: {case}", fontsize=FONT)
        ax.tick_params(labelsize=FONT - 1)
        ax.spines[["top", "right"]].set_visible(False)
    return fig, table
