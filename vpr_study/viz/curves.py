"""Curves and bar charts: PR curves (Fig. 5, 7, 10-13), metric bars, scale distributions
(Fig. 6)."""

from __future__ import annotations

import textwrap

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import to_hex, to_rgba
from matplotlib.lines import Line2D

from vpr_core import checks, identical_to, paper

from ._shared import wrapped
from .base import SAVE_DPI
from .styles import (
    DEFAULT_SETTINGS,
    MARKERS,
    METHOD_COLORS,
    WEIGHTING_STYLES,
    method_color,
    run_styles,
)

__all__ = [
    "METHOD_COLORS",
    "WEIGHTING_STYLES",
    "dataset_line",
    "plot_pr_curves",
    "plot_scale_distribution",
]


def plot_scale_distribution(
    hists: dict,
    title: str | None = None,
    ax=None,
    normalize: bool = False,
    method: str | None = None,
) -> matplotlib.figure.Figure:
    """Fig. 6: landmark counts per Table-1 scale, bars grouped by label (e.g. query/reference).

    Args:
        hists: ``{label: (10,) counts indexed by scale 1..9}`` (``scale_histogram`` output; a
            ``(9,)`` array is read as scales 1..9).
        title: axes title.
        normalize: plot shares (each label sums to 1) instead of counts.
        method: the landmarks' method: the first label's bars in its colour
            (:func:`~vpr_study.viz.styles.method_color`, as in every figure), the others lighter and
            hatched; None: greys.
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
        color = None if method is None else method_color(method)
        base = color or "0.3"
        face = base if k == 0 else to_rgba(base, 0.35 if color else 0.5 - 0.15 * (k - 1))
        ax.bar(
            x + (k - (len(labels) - 1) / 2) * width,
            h,
            width=width,
            label=str(label),
            color=face,
            edgecolor=base,
            linewidth=0.8,
            hatch=None if k == 0 else "//" if k == 1 else "..",
        )
    ax.set_xticks(x)
    ax.set_xticklabels([s.replace("Scale ", "S") for s in paper.SCALE_LABELS])
    ax.set_xlabel("landmark scale (Table 1)")
    ax.set_ylabel("share of landmarks" if normalize else "number of landmarks")
    if title:  # left-aligned like the PR figures, a line longer than the figure wrapped
        chars = int(fig.get_figwidth() * 72 / 6.2)  # 10-point text: about 6.2 points a character
        lines = [w for line in title.split("\n") for w in textwrap.wrap(line, chars) or [""]]
        ax.set_title("\n".join(lines), loc="left", fontsize=10)
    if labels:  # headroom above the tallest bar: the legend never covers a bar
        top = max(float(np.nanmax(p.get_height())) for p in ax.patches) if ax.patches else 1.0
        ax.set_ylim(0, (top if top > 0 else 1.0) * 1.25)
        ax.legend(frameon=False, loc="upper center", ncol=len(labels))
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return fig


def _settings_text(results) -> str:
    """``"backbone hog, pooling roi, shortlist k=25"``: the run settings every result shares that
    differ from :data:`DEFAULT_SETTINGS` (and a shortlist), or ``""``; peers are left out."""
    runs = [r for r in results if isinstance(getattr(r, "encoder", None), dict) and r.encoder]
    parts = []
    for key, default in DEFAULT_SETTINGS.items():
        values = {str(r.encoder.get(key)) for r in runs if r.encoder.get(key) is not None}
        if len(values) == 1 and (value := values.pop()) != str(default):
            parts.append(f"{key} {value}")
    shortlists = {getattr(r, "shortlist", None) for r in runs}
    if len(shortlists) == 1 and (k := shortlists.pop()) is not None:
        parts.append(f"shortlist k={k}")
    return ", ".join(parts)


def dataset_line(results, pr: bool = True) -> str:
    """``"<dataset>: 18 of 20 queries with ground truth, tolerance 0, protocol ratio"``: the line
    every PR / statistics figure carries under its title, then the non-default run settings
    (:func:`_settings_text`; e.g. ``pooling roi``). For ground truth read from a file,
    ``"ground truth from file: 1-5 correct references per query (median 5)"`` on a line of its
    own instead of the tolerance: :attr:`~vpr_core.MethodResult.truth_text`).

    ``pr=False``: the line of a figure of landmarks (coverage, scales), which neither the ground
    truth, the protocol nor the features change: ``"<dataset>: 60 queries, 60 references"``."""

    r = results[0]
    name = r.dataset_title or r.dataset
    if not pr:
        nq, nr = np.shape(r.similarity)
        return f"{name}: {nq} queries, {nr} references"
    n_gt, n_q = r.queries_with_gt
    from_file = r.ground_truth_from_file
    truth = r.truth_text
    protocol = f"protocol {getattr(r, 'protocol', 'ratio')}"
    extra = _settings_text(results)
    protocol += f", {extra}" if extra else ""
    if from_file:  # the longer wording gets a line of its own
        return f"{name}: {n_gt} of {n_q} queries with ground truth, {protocol};\n{truth}"
    return f"{name}: {n_gt} of {n_q} queries with ground truth, {truth}, {protocol}"


#: PR figure geometry in inches: the axes keep this size whatever the legend holds.
PR_AXES = (6.2, 3.2)
#: Width (inches) of a PR figure: at the inline backend's 100 dpi it shows unscaled in a
#: JupyterLab output column (about 760 px), so its 9-point text reads as 9 points.
PR_WIDTH = 7.6
#: Text size (points) of the PR figures' legend and heading.
PR_FONT = 9
_LEFT, _GAP, _LINE, _MARGIN, _XLABEL = 0.72, 0.12, 0.18, 0.1, 0.58


def _heading(text: str) -> str:
    """``text`` with each line wrapped at the width from the axes' left edge to the figure's
    right edge (:data:`PR_WIDTH`)."""
    return wrapped(text, PR_WIDTH - _LEFT - _MARGIN, PR_FONT)


def _curve_note(recall: np.ndarray, precision: np.ndarray) -> str:
    """Why a PR curve cannot be seen in a plot, for its legend entry, or ``""``.

    Args:
        recall, precision: ``(T + 1,)`` curve points (``recall[0] = 0``).

    Returns:
        ``"; no curve: no query correctly matched at any threshold"`` when the curve never
        leaves recall 0 (AUC 0: it lies on the axis), else ``""``.
    """
    r = np.asarray(recall, dtype=float)
    p = np.asarray(precision, dtype=float)
    seen = np.isfinite(r) & np.isfinite(p) & (r > 0) & (p > 0)
    return "" if seen.any() else "; no curve: no query correctly matched at any threshold"


def _from_last_zero(recall: np.ndarray, precision: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The curve from its last point at recall 0: the earlier ones (thresholds accepting no
    correct match) are a vertical segment that adds no area; the drawn area is the AUC."""
    r = np.asarray(recall, dtype=float)
    start = int(np.flatnonzero(r <= 0)[-1]) if (r <= 0).any() else 0
    return r[start:], np.asarray(precision, dtype=float)[start:]


class _Indexed:
    """A result seen under another label (its position), so runs of one label stay apart."""

    def __init__(self, result: object, label: str) -> None:
        self._result, self.label = result, label

    def __getattr__(self, name: str) -> object:
        return getattr(self._result, name)


def _same_xy(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> bool:
    """Two drawn curves that coincide point for point (one would hide the other)."""
    return all(
        len(x) == len(y) and np.allclose(x, y, rtol=0, atol=1e-9) for x, y in zip(a, b, strict=True)
    )


def plot_pr_curves(
    results, title: str | None = None, colors: dict | None = None
) -> matplotlib.figure.Figure:
    """Precision (y) against recall (x) of several results; the legend, below the axes in as
    many columns as fit the figure's width (never over the curves, never beside them: the
    axes keep :data:`PR_AXES` and the figure :data:`PR_WIDTH`; a longer legend makes the figure
    taller), gives each run's AUC with its 95% bootstrap interval on one line with the run's
    line sample (``dense  0.446 [0.106, 0.803]``; the legend's title names the metric). A
    dashed grey line is the chance level: the precision a random ranking of the same ground
    truth keeps (:meth:`~vpr_core.MethodResult.chance`), with its AUC in the legend. Each curve
    starts at its last point at recall 0 (the thresholds before it accept no correct match and
    add no area; the legend says so): the area under the drawn curve is its AUC.

    Every run is told apart (:func:`~vpr_study.viz.styles.run_styles`): its colour is its
    method's, the same in every figure (:data:`METHOD_COLORS`; peers and a user's methods from
    :data:`~vpr_study.viz.styles.OTHER_COLORS`), its line style its weighting
    (:data:`WEIGHTING_STYLES`), its marker its other settings (scheme options, backbone,
    normalisation...; none at the defaults), and its legend label says what differs from the
    other runs (:func:`~vpr_study.viz.styles.run_labels`). A run whose curve coincides with an
    earlier one's (the same similarity matrix, or another with the same curve) is drawn as its
    thin line in its own style with its own hollow markers over that curve, its legend entry
    saying ``same curve as <earlier label>``.

    Args:
        results: :class:`~vpr_core.MethodResult` objects (``.label``, ``.curve()``,
            ``.intervals``, ``.similarity``, ``.ground_truth``, ``.dataset``, ``.tolerance``).
        title: the figure's title; the dataset line (:func:`dataset_line`) goes below it
            (lines longer than the figure wrapped).
        colors: ``{label: colour}``; default: the method's colour.

    Returns:
        The figure.

    Raises:
        ValueError, TypeError: ``results`` is empty, one result or holds something else
            (:func:`vpr_core.checks.check_results`).
    """

    results = checks.check_results(results, "plot_pr_curves")
    head = f"{title}\n" if title else ""
    heading = _heading(head + dataset_line(results))
    top = _GAP + _LINE * (heading.count("\n") + 1)
    fig = plt.figure(figsize=(PR_WIDTH, 6.0))
    ax = fig.add_axes((0, 0, 1, 1))
    styles = run_styles(results, colors)
    twins = identical_to([_Indexed(r, str(i)) for i, r in enumerate(results)])  # by position
    curves: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    handles: list[Line2D] = []
    used = {(to_hex(st.color), str(st.linestyle), st.marker) for st in styles}
    for k, (r, st, twin) in enumerate(zip(results, styles, twins, strict=True)):
        iv = getattr(r, "intervals", {}).get("auc")
        auc = (
            f"{iv[0]:.3f} [{iv[1]:.3f}, {iv[2]:.3f}]"
            if iv is not None
            else f"{r.metrics['auc']:.3f}"
        )
        curve = r.curve()
        xy = _from_last_zero(curve.recall, curve.precision)
        note = _curve_note(curve.recall, curve.precision)  # an AUC-0 curve lies on the axis
        alike = styles[int(twin)].label if twin is not None else None
        if alike not in curves:  # a same matrix drawn as a same curve itself: the one drawn
            alike = next((name for name, c in curves.items() if _same_xy(c, xy)), None)
        start = 0.02 + 0.03 * (k % 5)  # the markers of two runs never on one spot
        if alike is not None:  # the same curve as an earlier run: thin, hollow markers over it
            marker = st.marker or next(
                (m for m in MARKERS if (to_hex(st.color), str(st.linestyle), m) not in used),
                "o",
            )
            used.add((to_hex(st.color), str(st.linestyle), marker))
            (line,) = ax.plot(
                *xy,
                color=st.color,
                ls=st.linestyle,
                lw=0.9,
                marker=marker,
                fillstyle="none",
                ms=6.5,
                mew=1.3,
                markevery=(start, 0.07),
                label=f"{st.label}  {auc}{note}, same curve as {alike}",
            )
        else:
            (line,) = ax.plot(
                *xy,
                lw=1.6,
                ms=5,
                markevery=(start, 0.1),
                label=f"{st.label}  {auc}{note}",
                **st.line(),
            )
            curves[st.label] = xy
        handles.append(line)
    at_chance = results[0].chance()
    level, chance_auc = at_chance["precision"], at_chance["auc"]
    handles.append(
        ax.axhline(
            level,
            color="0.45",
            ls="--",
            lw=1.0,
            label=f"chance (random ranking)  {chance_auc:.3f}; precision {level:.3f}",
        )
    )
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("recall")
    ax.set_ylabel("precision")
    ax.grid(alpha=0.3)
    ax.set_title(heading, fontsize=PR_FONT, loc="left")
    legend, wide, height = _legend_below(fig, ax, handles)
    width = max(PR_WIDTH, _LEFT + wide)
    bottom = _MARGIN + height + _XLABEL
    fig.set_size_inches(width, bottom + PR_AXES[1] + top)
    ax.set_position(
        (
            _LEFT / width,
            bottom / (bottom + PR_AXES[1] + top),
            PR_AXES[0] / width,
            PR_AXES[1] / (bottom + PR_AXES[1] + top),
        )
    )
    legend.set_bbox_to_anchor((_LEFT - 0.1, _MARGIN + height), transform=fig.dpi_scale_trans)
    return fig


def _legend_below(fig, ax, handles: list) -> tuple[matplotlib.legend.Legend, float, float]:
    """The legend of ``handles`` below ``ax`` in the most columns (3 at most) that fit the
    axes' width, one line per entry; ``(legend, its width and height in inches)``, measured at the
    saving resolution (text extents do not scale exactly with the resolution)."""
    legend = None
    dpi = fig.get_dpi()
    fig.set_dpi(SAVE_DPI)
    try:
        for ncol in range(min(3, len(handles)), 0, -1):
            if legend is not None:
                legend.remove()
            legend = ax.legend(
                handles=handles,
                loc="upper left",
                bbox_to_anchor=(_LEFT - 0.1, 0.0),
                bbox_transform=fig.dpi_scale_trans,
                ncol=ncol,
                fontsize=PR_FONT,
                frameon=False,
                title="AUC [95% CI]; each curve starts at its last point at recall 0 (area = AUC)",
                title_fontsize=PR_FONT,
                borderaxespad=0.0,
                borderpad=0.2,
                columnspacing=1.6,
                handlelength=1.8,
            )
            legend._legend_box.align = "left"  # type: ignore[attr-defined]
            fig.draw_without_rendering()
            if legend.get_window_extent().width / SAVE_DPI <= PR_WIDTH - _LEFT:
                break
        assert legend is not None
        bb = legend.get_window_extent()
        return legend, bb.width / SAVE_DPI, bb.height / SAVE_DPI
    finally:
        fig.set_dpi(dpi)
