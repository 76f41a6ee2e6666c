"""Curves and bar charts: PR curves (Fig. 5, 7, 10-13), metric bars, scale distributions
(Fig. 6)."""

from __future__ import annotations

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ..paper import SCALE_LABELS
from .base import METHOD_COLORS

__all__ = ["plot_metric_bars", "plot_pr_curves", "plot_scale_distribution"]


def plot_scale_distribution(hists: dict, title: str | None = None, ax=None,
                            normalize: bool = False) -> matplotlib.figure.Figure:
    """Fig. 6: landmark counts per Table-1 scale, bars grouped by label (e.g. query/reference).

    Args:
        hists: ``{label: (10,) counts indexed by scale 1..9}`` (``scale_histogram`` output; a
            ``(9,)`` array is read as scales 1..9).
        title: axes title.
        normalize: plot shares (each label sums to 1) instead of counts.
    """
    if ax is None:
        fig, ax = plt.subplots(figsize=(7.0, 3.6))
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
    if title:
        ax.set_title(title)
    if labels:
        ax.legend(frameon=False)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return fig


def plot_pr_curves(curves: dict, title: str | None = None, ax=None,
                   colors: dict | None = None, intervals: dict | None = None
                   ) -> matplotlib.figure.Figure:
    """Precision (y) against recall (x) for several methods; the legend gives each AUC.

    Args:
        curves: ``{label: PRCurve}`` (``vpr_core.evaluation.pr_curve`` results).
        title: axes title.
        ax: axes to draw on (default: a new 6 x 4.6 in figure).
        colors: ``{label: colour}``; default :data:`METHOD_COLORS`, then the matplotlib cycle.
        intervals: ``{label: (auc, low, high)}``: the legend shows ``AUC v [low, high]`` (95%
            bootstrap interval) for these labels instead of the bare AUC.

    Returns:
        The figure.
    """
    from ..evaluation import auc_pr

    if ax is None:
        fig, ax = plt.subplots(figsize=(6.0, 4.6))
    else:
        fig = ax.figure
    colors = {**METHOD_COLORS, **(colors or {})}
    from matplotlib.colors import to_hex

    used = {to_hex(colors[k]) for k in curves if k in colors}
    spare = iter([c for c in (f"C{i}" for i in range(10)) if to_hex(c) not in used]
                 + [plt.cm.tab20(i) for i in range(20)])
    colors.update({k: next(spare) for k in curves if k not in colors})
    for label, curve in curves.items():
        iv = (intervals or {}).get(label)
        text = (f"AUC {iv[0]:.3f} [{iv[1]:.3f}, {iv[2]:.3f}]" if iv is not None
                else f"AUC {auc_pr(curve):.3f}")
        ax.plot(curve.recall, curve.precision, lw=1.6, color=colors.get(label),
                label=f"{label} ({text})")
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("recall")
    ax.set_ylabel("precision")
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=7.5, frameon=True, framealpha=0.8)
    fig.tight_layout()
    return fig


def plot_metric_bars(table, metric: str = "auc", title: str | None = None, ax=None,
                     colors: dict | None = None) -> matplotlib.figure.Figure:
    """Bar chart of one metric column of ``evaluation.metrics_table`` (one bar per method).

    Args:
        table: ``pandas.DataFrame`` indexed by method, one column per metric.
        metric: column to plot (``auc``, ``r_at_100p``, ``r_at_1``, ``r_at_5``).
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
