"""Fig. 4: the scale statistics CMR (a), CLS (b) and ASL (c) per Table-1 scale."""

from __future__ import annotations

from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

__all__ = ["plot_asl", "plot_cls", "plot_cmr", "plot_scale_statistics"]

_STATS_GT_COLOR = "tab:green"
_STATS_IRR_COLOR = "tab:gray"
_PANEL_SIZE = (5.0, 3.4)


def _stats_line(stats: Any, wrap: bool = False) -> str:
    """``"<dataset>: 18 of 20 queries with ground truth, tolerance 0; labels exact; 90 ground-truth
    / 450 irrelevant pairs"``: the line every statistics figure carries (``wrap``: the labels on
    a second line; a file-based ground truth's longer wording always gets a line of its own)."""
    m = stats.meta or {}
    n_gt, n_q = m.get("queries_with_gt", ("?", "?"))
    truth = m.get("ground_truth") or f"tolerance {m.get('tolerance')}"
    own_line = not truth.startswith("tolerance")
    return (
        f"{m.get('dataset', '?')}: {n_gt} of {n_q} queries with ground truth"
        f"{';' + chr(10) if own_line else ', '}{truth};"
        f"{chr(10) if wrap else ' '}labels {m.get('label_method', '?')}; "
        f"{stats.n_gt_pairs} ground-truth / {stats.n_irrelevant_pairs} irrelevant pairs"
    )


def _new_axes(ax, figsize: tuple[float, float]):
    """``(fig, ax)``: the given axes and its figure, or a new single-panel figure."""
    if ax is None:
        fig, ax = plt.subplots(figsize=figsize)
        return fig, ax
    return ax.figure, ax


def _standalone(fig: Figure, ax: Any, stats: Any, own: bool) -> None:
    """A panel drawn in its own figure names its data in a suptitle."""
    if own:
        fig.suptitle(_stats_line(stats, wrap=True), fontsize=8)
        fig.tight_layout()


def _stats_scale_axis(ax: Any, stats: Any, title: str, ylabel: str) -> None:
    """Common x axis (Table-1 scales 1..9) of the Fig. 4 panels."""
    scales = np.arange(1, 10)
    ax.set_xticks(scales)
    ax.set_xticklabels([f"S{s}" for s in scales])
    ax.set_xlim(0.4, 9.6)
    ax.set_xlabel("landmark scale (Table 1)")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    ax.set_axisbelow(True)


def plot_cmr(stats: Any, ax: Any = None, color: str = "tab:blue") -> Figure:
    """Fig. 4a: correct landmark matching rate per scale of a ``ScaleStats`` (bars, empty scales
    blank), each with its 95% bootstrap interval over query images and its labelled matches."""
    own = ax is None
    fig, ax = _new_axes(ax, _PANEL_SIZE)
    scales = np.arange(1, 10)
    cmr = np.asarray(stats.cmr, dtype=float)[1:10]
    n = np.asarray(getattr(stats, "n_labelled", stats.n_matches))[1:10]
    iv = stats.cmr_intervals()[1:10]
    ax.bar(scales, np.nan_to_num(cmr, nan=0.0), width=0.7, color=color)
    ok = np.isfinite(cmr) & np.isfinite(iv).all(axis=1)
    if ok.any():
        err = np.vstack([cmr[ok] - iv[ok, 0], iv[ok, 1] - cmr[ok]]).clip(min=0)
        ax.errorbar(
            scales[ok], cmr[ok], yerr=err, fmt="none", ecolor="0.2", elinewidth=0.9, capsize=2.5
        )
    for s, v, k, top in zip(scales, cmr, n, iv[:, 1], strict=False):
        if np.isfinite(v):
            y = max(v, top) if np.isfinite(top) else v
            ax.text(s, y + 0.01, f"{int(k)}", ha="center", va="bottom", fontsize=7)
    ax.set_ylim(0, 1.15)
    if not np.isfinite(cmr).any():
        ax.text(
            5,
            0.5,
            "no labelled matches:\nthe pairs could not be verified\n"
            "(give manual labels: method='file')",
            ha="center",
            va="center",
            fontsize=8,
            color="0.35",
        )
    _stats_scale_axis(
        ax, stats, "(a) correct matching rate (CMR)", "CMR (bars: 95% CI over queries)"
    )
    _standalone(fig, ax, stats, own)
    return fig


def _stats_grouped(ax: Any, gt: np.ndarray, irr: np.ndarray) -> None:
    scales = np.arange(1, 10)
    w = 0.38
    ax.bar(
        scales - w / 2,
        np.nan_to_num(np.asarray(gt, float)[1:10], nan=0.0),
        width=w,
        color=_STATS_GT_COLOR,
        label="ground-truth pairs",
    )
    ax.bar(
        scales + w / 2,
        np.nan_to_num(np.asarray(irr, float)[1:10], nan=0.0),
        width=w,
        color=_STATS_IRR_COLOR,
        label="query-irrelevant pairs",
    )
    top = np.nanmax(
        np.concatenate([np.asarray(gt, float)[1:10], np.asarray(irr, float)[1:10], [0.0]])
    )
    ax.set_ylim(0, (top if top > 0 else 1.0) * 1.3)  # headroom: the legend sits above the bars
    ax.legend(fontsize=7, loc="upper center", ncol=2, frameon=False)


def plot_cls(stats: Any, ax: Any = None) -> Figure:
    """Fig. 4b: contribution of each scale to the similarity (CLS), ground-truth vs
    query-irrelevant pairs (grouped bars; each group sums to 1 over the scales)."""
    own = ax is None
    fig, ax = _new_axes(ax, _PANEL_SIZE)
    _stats_grouped(ax, stats.cls_gt, stats.cls_irrelevant)
    _stats_scale_axis(ax, stats, "(b) contribution to similarity (CLS)", "share of similarity")
    _standalone(fig, ax, stats, own)
    return fig


def plot_asl(stats: Any, ax: Any = None) -> Figure:
    """Fig. 4c: average pair score ``1 - d*s`` of the matched landmarks per scale (ASL),
    ground-truth vs query-irrelevant pairs (grouped bars)."""
    own = ax is None
    fig, ax = _new_axes(ax, _PANEL_SIZE)
    _stats_grouped(ax, stats.asl_gt, stats.asl_irrelevant)
    _stats_scale_axis(ax, stats, "(c) average similarity of matches (ASL)", "mean 1 - d*s")
    _standalone(fig, ax, stats, own)
    return fig


def plot_scale_statistics(stats: Any, title: str | None = None) -> Figure:
    """Fig. 4: CMR, CLS and ASL side by side; ``title`` (e.g. the method) above the data line
    (:func:`_stats_line`)."""
    fig, axes = plt.subplots(1, 3, figsize=(14.0, 3.9))
    plot_cmr(stats, ax=axes[0])
    plot_cls(stats, ax=axes[1])
    plot_asl(stats, ax=axes[2])
    fig.suptitle((f"{title}\n" if title else "") + _stats_line(stats), fontsize=10)
    fig.tight_layout()
    return fig
