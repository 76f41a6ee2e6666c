"""Curves and bar charts: PR curves (Fig. 5, 7, 10-13), metric bars, scale distributions
(Fig. 6)."""

from __future__ import annotations

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import to_hex

from ..datasets.ground_truth import ground_truth_text
from ..evaluation import auc_pr, chance, ground_truth_coverage
from ..evaluation.chance import chance_precision
from ..evaluation.compare import identical_to
from ..paper import SCALE_LABELS
from .base import METHOD_COLORS, curve_note

__all__ = ["dataset_line", "plot_metric_bars", "plot_pr_curves", "plot_scale_distribution"]


def plot_scale_distribution(
    hists: dict, title: str | None = None, ax=None, normalize: bool = False
) -> matplotlib.figure.Figure:
    """Fig. 6: landmark counts per Table-1 scale, bars grouped by label (e.g. query/reference).

    Args:
        hists: ``{label: (10,) counts indexed by scale 1..9}`` (``scale_histogram`` output; a
            ``(9,)`` array is read as scales 1..9).
        title: axes title.
        normalize: plot shares (each label sums to 1) instead of counts.
    """
    if ax is None:
        fig, ax = plt.subplots(figsize=(8.0, 3.6))
    else:
        fig = ax.figure
    labels = list(hists)
    width = 0.8 / max(1, len(labels))
    x = np.arange(1, 10)
    for k, label in enumerate(labels):
        h = np.asarray(hists[label], dtype=float).ravel()
        if h.shape == (10,):
            h = h[1:]
        elif h.shape != (9,):
            raise ValueError(f"hists[{label!r}] must have shape (10,) or (9,), got {h.shape}")
        if normalize and h.sum() > 0:
            h = h / h.sum()
        ax.bar(x + (k - (len(labels) - 1) / 2) * width, h, width=width, label=str(label))
    ax.set_xticks(x)
    ax.set_xticklabels([s.replace("Scale ", "S") for s in SCALE_LABELS])
    ax.set_xlabel("landmark scale (Table 1)")
    ax.set_ylabel("share of landmarks" if normalize else "number of landmarks")
    if title:  # left-aligned like the PR figures: a long dataset line stays on the canvas
        ax.set_title(title, loc="left", fontsize=10)
    if labels:  # headroom above the tallest bar: the legend never covers a bar
        top = max(float(np.nanmax(p.get_height())) for p in ax.patches) if ax.patches else 1.0
        ax.set_ylim(0, (top if top > 0 else 1.0) * 1.25)
        ax.legend(frameon=False, loc="upper center", ncol=len(labels))
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return fig


def dataset_line(results) -> str:
    """``"<dataset>: 18 of 20 queries with ground truth, tolerance 0, protocol ratio"``: the line
    every PR / statistics figure carries under its title (for ground truth read from a file,
    ``"ground truth from file: 1-5 correct references per query (median 5)"`` on a line of its
    own instead of the tolerance: :func:`~vpr_core.datasets.ground_truth.ground_truth_text`)."""

    r = results[0]
    n_gt, n_q = ground_truth_coverage(r.ground_truth)
    name = getattr(r, "dataset_title", "") or r.dataset
    from_file = getattr(r, "ground_truth_from_file", False)
    truth = ground_truth_text(r.ground_truth, r.tolerance, from_file)
    protocol = f"protocol {getattr(r, 'protocol', 'ratio')}"
    if from_file:  # the longer wording gets a line of its own
        return f"{name}: {n_gt} of {n_q} queries with ground truth, {protocol};\n{truth}"
    return f"{name}: {n_gt} of {n_q} queries with ground truth, {truth}, {protocol}"


def plot_pr_curves(
    results, title: str | None = None, colors: dict | None = None
) -> matplotlib.figure.Figure:
    """Precision (y) against recall (x) of several results; the legend (beside the axes, never
    over the curves) gives each AUC with its 95% bootstrap interval. A dashed grey line is the
    chance level: the precision a random ranking of the same ground truth keeps
    (:func:`~vpr_core.evaluation.chance.chance_precision`), with its AUC
    (:func:`~vpr_core.evaluation.chance`) in the legend.

    A result whose similarity matrix equals an earlier one's has the same curve: it is drawn
    once and its legend entry reads ``= <earlier label>``.

    Args:
        results: :class:`~vpr_core.pipeline.MethodResult` objects (``.label``, ``.curve()``,
            ``.intervals``, ``.similarity``, ``.ground_truth``, ``.dataset``, ``.tolerance``).
        title: the figure's title; the dataset line (:func:`dataset_line`) goes below it.
        colors: ``{label: colour}``; default :data:`METHOD_COLORS` by method, then the cycle.

    Returns:
        The figure.
    """

    results = list(results)
    if not results:
        raise ValueError("plot_pr_curves needs at least one result")
    fig, ax = plt.subplots(figsize=(8.6, 4.4), constrained_layout=True)
    colors = dict(colors or {})
    spare = iter([f"C{i}" for i in range(10)] + [plt.cm.tab20(i) for i in range(20)])
    used: set[str] = set()
    for r, twin in zip(results, identical_to(results), strict=False):
        iv = getattr(r, "intervals", {}).get("auc")
        auc = (
            f"AUC {iv[0]:.3f} [{iv[1]:.3f}, {iv[2]:.3f}]"
            if iv is not None
            else f"AUC {auc_pr(r.curve()):.3f}"
        )
        if twin is not None:  # same matrix: same curve; say so instead of hiding it
            ax.plot([], [], lw=0, label=f"{r.label} (= {twin}, {auc})")
            continue
        color = colors.get(r.label) or METHOD_COLORS.get(r.label)
        if color is None or to_hex(color) in used:
            color = next(c for c in spare if to_hex(c) not in used)
        used.add(to_hex(color))
        curve = r.curve()
        note = curve_note(curve.recall, curve.precision)  # an AUC-0 curve lies on the axis
        label = f"{r.label} ({auc}{note})"
        ax.plot(curve.recall, curve.precision, lw=1.6, color=color, label=label)
    protocol = getattr(results[0], "protocol", "ratio")
    level = chance_precision(results[0].ground_truth, protocol)
    chance_auc = chance(results[0].ground_truth, protocol, ks=(1,))["auc"]
    ax.axhline(
        level,
        color="0.45",
        ls="--",
        lw=1.0,
        label=f"chance (random ranking): precision {level:.3f}, AUC {chance_auc:.3f}",
    )
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("recall")
    ax.set_ylabel("precision")
    ax.grid(alpha=0.3)
    ax.legend(
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        fontsize=8,
        frameon=False,
        title="AUC with 95% CI",
        title_fontsize=8,
    )
    head = f"{title}\n" if title else ""
    ax.set_title(head + dataset_line(results), fontsize=9, loc="left")
    fig.draw_without_rendering()  # lay out once, then freeze: every later render is the same
    fig.set_layout_engine("none")
    return fig


def plot_metric_bars(
    table, metric: str = "auc", title: str | None = None, ax=None, colors: dict | None = None
) -> matplotlib.figure.Figure:
    """Bar chart of one metric column of ``evaluation.metrics_table`` (one bar per method).

    Args:
        table: ``pandas.DataFrame`` indexed by method, one column per metric.
        metric: column to plot (``auc``, ``r@100p``, ``r@1``, ``r@5``).
        title: axes title; ax: axes to draw on; colors: ``{method: colour}``.

    Returns:
        The figure.
    """
    if metric not in table.columns:
        raise ValueError(f"unknown metric {metric!r}; valid: {', '.join(map(str, table.columns))}")
    if ax is None:
        fig, ax = plt.subplots(figsize=(max(3.0, 0.8 * len(table) + 1.5), 3.2))
    else:
        fig = ax.figure
    colors = {**METHOD_COLORS, **(colors or {})}
    names = [str(i) for i in table.index]
    vals = table[metric].to_numpy(dtype=float)
    ax.bar(names, vals, color=[colors.get(n, "tab:gray") for n in names])
    for x, v in enumerate(vals):
        ax.text(x, v + 0.01, f"{v:.2f}", ha="center", va="bottom", fontsize=8)
    ax.set_ylim(0.0, 1.08)
    ax.set_ylabel(metric)
    if title:
        ax.set_title(title)
    ax.tick_params(axis="x", labelrotation=30)
    fig.tight_layout()
    return fig
