"""Plot helpers (``plot_*``) and one deterministic ``save_figure``.

Every figure of the study is drawn here; notebooks only call these.
"""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib

if not os.environ.get("MPLBACKEND"):
    matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from .utils import REPO_DIR

FIGURES_DIR = REPO_DIR / "figures"

# Paper-like colours for methods (stable across figures).
METHOD_COLORS = {
    "dense": "tab:red",
    "classical": "tab:blue",
    "selection_scheme1": "tab:green",
    "selection_scheme2": "tab:orange",
    "overlap_scheme1": "tab:purple",
    "overlap_scheme2": "tab:brown",
}


def figures_dir(dataset: str | None = None) -> Path:
    """``figures/`` (or ``$VPR_FIGURES_DIR``), optionally the per-dataset subfolder, created."""
    root = Path(os.environ.get("VPR_FIGURES_DIR", FIGURES_DIR))
    d = root / dataset if dataset else root
    d.mkdir(parents=True, exist_ok=True)
    return d


def save_figure(fig: matplotlib.figure.Figure, name: str, dataset: str | None = None,
                dpi: int = 110) -> Path:
    """Save ``fig`` as ``figures/<dataset>/<name>.png`` byte-identically for identical inputs.

    PNG metadata (software/version stamp) is removed so the same plot gives the same bytes.
    ``name`` may carry an extension (``.png`` or ``.pdf``); default PNG.
    """
    path = Path(name)
    if path.suffix not in (".png", ".pdf"):
        path = path.with_suffix(path.suffix + ".png") if path.suffix else path.with_suffix(".png")
    if not path.is_absolute():
        path = figures_dir(dataset) / path
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"Software": None} if path.suffix == ".png" else {"CreationDate": None, "Producer": None}
    fig.savefig(path, dpi=dpi, metadata=meta, bbox_inches=None)
    return path


def draw_boxes(ax, boxes: np.ndarray, color="yellow", lw: float = 1.0, alpha: float = 0.9) -> None:
    """Draw ``(K, 4)`` ``(x, y, w, h)`` boxes on an axes."""
    from matplotlib.patches import Rectangle

    for x, y, w, h in np.asarray(boxes, dtype=float).reshape(-1, 4):
        ax.add_patch(Rectangle((x, y), w, h, fill=False, edgecolor=color, lw=lw, alpha=alpha))


# --- plots: datasets / examples ------------------------------------------------------------


def plot_examples(dataset, indices=(0, 1, 2), boxes=None,
                  title: str | None = None) -> matplotlib.figure.Figure:
    """Reference / query example pairs: one row per pair, columns ``reference | query``.

    Args:
        dataset: ``vpr_core.datasets.PlaceDataset``.
        indices: Query indices to show; each row shows query ``q`` and its first ground-truth
            reference (reference ``q`` when the query has none and ``q < Nr``).
        boxes: Optional callable ``(side, i, image_size) -> (K, 4)`` ``(x, y, w, h)`` boxes
            drawn on each image (``side`` is ``"query"`` or ``"reference"``), or None.
        title: Optional suptitle (default: dataset name and tolerance).

    Returns:
        A ``len(indices) x 2`` figure (deterministic for identical inputs).
    """
    indices = [int(i) for i in indices]
    if not indices:
        raise ValueError("plot_examples: indices is empty; pass at least one query index.")
    gt = np.asarray(dataset.ground_truth, bool)
    rows = []
    for q in indices:
        if not 0 <= q < gt.shape[0]:
            raise IndexError(f"plot_examples: query index {q} out of range 0..{gt.shape[0] - 1}.")
        hits = np.flatnonzero(gt[q])
        r = int(hits[np.argmin(np.abs(hits - q))]) if hits.size else q
        if not 0 <= r < gt.shape[1]:
            raise IndexError(f"plot_examples: query {q} has no ground-truth reference to show.")
        rows.append((q, r))
    fig, axes = plt.subplots(len(rows), 2, figsize=(9.0, 2.6 * len(rows)), squeeze=False)
    for (q, r), (ax_r, ax_q) in zip(rows, axes):
        for ax, side, i in ((ax_r, "reference", r), (ax_q, "query", q)):
            img = dataset.load_image(side, i)
            ax.imshow(img)
            if boxes is not None:
                b = np.asarray(boxes(side, i, img.shape[:2]), dtype=float).reshape(-1, 4)
                draw_boxes(ax, b, color="yellow" if side == "reference" else "cyan", lw=0.8)
            ax.set_title(f"{side} {i}", fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
    tol = getattr(dataset, "tolerance", None)
    fig.suptitle(title if title is not None else
                 f"{dataset.name}: reference | query (tolerance {tol})", fontsize=10)
    fig.tight_layout()
    return fig


def plot_dataset_overview(dataset, n: int = 6) -> matplotlib.figure.Figure:
    """Thumbnails of ``n`` evenly spaced places: reference row on top, query row below.

    Args:
        dataset: ``PlaceDataset``.
        n: Number of places (clipped to the dataset size).

    Returns:
        A ``2 x n`` figure.
    """
    m = min(len(dataset), getattr(dataset, "n_reference", len(dataset.reference_paths)))
    n = max(1, min(int(n), m))
    idx = np.unique(np.linspace(0, m - 1, n).round().astype(int))
    fig, axes = plt.subplots(2, len(idx), figsize=(2.4 * len(idx), 3.4), squeeze=False)
    for col, i in enumerate(idx):
        for row, side in enumerate(("reference", "query")):
            ax = axes[row, col]
            ax.imshow(dataset.load_image(side, int(i)))
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{side[0]}{int(i)}", fontsize=8)
    fig.suptitle(f"{dataset.name}: {len(dataset)} queries, {len(dataset.reference_paths)} "
                 "references (top: reference, bottom: query)", fontsize=9)
    fig.tight_layout()
    return fig


# --- plots: landmarks ----------------------------------------------------------------------


def _landmark_canvas(image_or_size) -> tuple[np.ndarray | None, tuple[int, int]]:
    """``(image or None, (H, W))`` from an image ``(H, W[, 3])`` or an ``(H, W)`` size."""
    arr = np.asarray(image_or_size) if isinstance(image_or_size, np.ndarray) else None
    if arr is not None and arr.ndim in (2, 3) and arr.shape[0] > 3:
        return arr, (int(arr.shape[0]), int(arr.shape[1]))
    size = tuple(int(v) for v in tuple(image_or_size)[:2])
    if len(size) != 2 or min(size) <= 0:
        raise ValueError(f"expected an image (H, W, 3) or a size (H, W), got {image_or_size!r}")
    return None, size


def _show_canvas(ax, image: np.ndarray | None, size: tuple[int, int], gray: bool = False) -> None:
    if image is None:
        ax.imshow(np.full(size + (3,), 235, np.uint8))
    elif gray and image.ndim == 3:
        ax.imshow(image.mean(axis=2), cmap="gray", vmin=0, vmax=255)
    else:
        ax.imshow(image, cmap="gray" if image.ndim == 2 else None)
    ax.set_xlim(-0.5, size[1] - 0.5)
    ax.set_ylim(size[0] - 0.5, -0.5)
    ax.set_xticks([])
    ax.set_yticks([])


def plot_landmarks(image: np.ndarray, boxes: np.ndarray, ax=None, color: str = "yellow",
                   title: str | None = None, lw: float = 1.0) -> matplotlib.figure.Figure:
    """Draw ``(K, 4)`` ``(x, y, w, h)`` landmark boxes on an ``(H, W, 3)`` image.

    Returns the figure (a new one when ``ax`` is None).
    """
    boxes = np.asarray(boxes, dtype=float)
    if boxes.size and (boxes.ndim != 2 or boxes.shape[1] != 4):
        raise ValueError(f"boxes must have shape (K, 4), got {boxes.shape}")
    img, size = _landmark_canvas(image)
    if ax is None:
        fig, ax = plt.subplots(figsize=(6.4, 6.4 * size[0] / size[1] + 0.4))
    else:
        fig = ax.figure
    _show_canvas(ax, img, size)
    draw_boxes(ax, boxes, color=color, lw=lw)
    ax.set_title(title if title is not None else f"{len(boxes.reshape(-1, 4))} landmarks")
    return fig


def plot_dense_scales(image_or_size, scales=(0.16, 0.25, 0.36, 0.49),
                      per_scale=25) -> matplotlib.figure.Figure:
    """Fig. 9: one panel per dense-sampling scale level with that level's boxes.

    Args:
        image_or_size: ``(H, W, 3)`` image or an ``(H, W)`` size (blank canvas).
        scales: normalized scales (area ratios), one panel each.
        per_scale: boxes per scale (int or one per scale), as in ``dense_sampling``.
    """
    from .landmarks import dense_sampling

    img, size = _landmark_canvas(image_or_size)
    scales = list(np.atleast_1d(np.asarray(scales, dtype=float)))
    counts = [per_scale] * len(scales) if np.ndim(per_scale) == 0 else list(per_scale)
    n = len(scales)
    ncols = 2 if n == 4 else min(n, 3)
    nrows = int(np.ceil(n / ncols))
    panel_w = 4.2
    fig, axes = plt.subplots(nrows, ncols, squeeze=False,
                             figsize=(panel_w * ncols, (panel_w * size[0] / size[1] + 0.5) * nrows))
    colors = plt.get_cmap("tab10").colors
    for k, ax in enumerate(axes.ravel()):
        if k >= n:
            ax.axis("off")
            continue
        boxes = dense_sampling(size, (scales[k],), counts[k])
        _show_canvas(ax, img, size)
        for j, box in enumerate(boxes):
            draw_boxes(ax, box[None], color=colors[j % len(colors)], lw=1.0)
        ax.set_title(f"({chr(ord('a') + k)}) scale {k + 1}: {len(boxes)} landmarks, "
                     f"{scales[k]:g} normalized scale", fontsize=9)
    fig.tight_layout()
    return fig


def plot_coverage(image: np.ndarray, boxes: np.ndarray, ax=None, cmap: str = "viridis",
                  alpha: float = 0.6, title: str | None = None) -> matplotlib.figure.Figure:
    """Fig. 14: how many landmarks cover each pixel, as a heatmap over the (grey) image.

    The default title gives the share of pixels covered by at least one box.
    """
    from .landmarks import landmark_coverage

    img, size = _landmark_canvas(image)
    cov = landmark_coverage(boxes, size)
    if ax is None:
        fig, ax = plt.subplots(figsize=(6.4, 6.4 * size[0] / size[1] + 0.4))
    else:
        fig = ax.figure
    _show_canvas(ax, img, size, gray=True)
    shown = np.ma.masked_where(cov <= 0, cov)  # uncovered pixels show the plain image
    im = ax.imshow(shown, cmap=cmap, alpha=alpha, vmin=0, vmax=max(1.0, float(cov.max())))
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02, label="boxes covering the pixel")
    covered = float((cov > 0).mean())
    ax.set_title(title if title is not None else
                 f"coverage of {len(np.asarray(boxes).reshape(-1, 4))} landmarks: "
                 f"{100 * covered:.0f}% of pixels")
    return fig


def plot_scale_distribution(hists: dict, title: str | None = None, ax=None,
                            normalize: bool = False) -> matplotlib.figure.Figure:
    """Fig. 6: landmark counts per Table-1 scale, bars grouped by label (e.g. query/reference).

    Args:
        hists: ``{label: (10,) counts indexed by scale 1..9}`` (``scale_histogram`` output; a
            ``(9,)`` array is read as scales 1..9).
        title: axes title.
        normalize: plot shares (each label sums to 1) instead of counts.
    """
    from .landmarks import SCALE_LABELS

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

# --- plots: PR curves and metrics ----------------------------------------------------------


def plot_pr_curves(curves: dict, title: str | None = None, ax=None,
                   colors: dict | None = None) -> matplotlib.figure.Figure:
    """Precision (y) against recall (x) for several methods; the legend gives each AUC.

    Args:
        curves: ``{label: PRCurve}`` (``vpr_core.evaluation.pr_curve`` results).
        title: axes title.
        ax: axes to draw on (default: a new 6 x 4.6 in figure).
        colors: ``{label: colour}``; default :data:`METHOD_COLORS`, then the matplotlib cycle.

    Returns:
        The figure.
    """
    from .evaluation import auc_pr

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
        ax.plot(curve.recall, curve.precision, lw=1.6, color=colors.get(label),
                label=f"{label} (AUC {auc_pr(curve):.3f})")
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

# --- plots: scale statistics (Fig. 4) and labelled matches (Fig. 1-2) ------------------------

_STATS_GT_COLOR = "tab:green"
_STATS_IRR_COLOR = "tab:gray"


def _stats_axes(ax):
    """``(fig, ax)``: the given axes or a new single-panel figure."""
    if ax is None:
        fig, ax = plt.subplots(figsize=(5.0, 3.4))
        return fig, ax
    return ax.figure, ax


def _stats_scale_axis(ax, stats, title: str, ylabel: str) -> None:
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


def plot_cmr(stats, ax=None, color: str = "tab:blue") -> matplotlib.figure.Figure:
    """Fig. 4a: correct landmark matching rate per scale (bars; empty scales left blank).

    Args:
        stats: ``vpr_core.statistics.ScaleStats`` (arrays of length 10, index = scale).
        ax: axes to draw on (default: a new figure).
        color: bar colour.

    Returns:
        The figure holding ``ax``. Each bar is annotated with its number of labelled matches.
    """
    fig, ax = _stats_axes(ax)
    scales = np.arange(1, 10)
    cmr = np.asarray(stats.cmr, dtype=float)[1:10]
    n = np.asarray(getattr(stats, "n_labelled", stats.n_matches))[1:10]
    ax.bar(scales, np.nan_to_num(cmr, nan=0.0), width=0.7, color=color)
    for s, v, k in zip(scales, cmr, n):
        if np.isfinite(v):
            ax.text(s, v + 0.01, f"{int(k)}", ha="center", va="bottom", fontsize=7)
    ax.set_ylim(0, 1.08)
    if not np.isfinite(cmr).any():
        ax.text(5, 0.5, "no labelled matches:\nthe pairs could not be verified\n"
                "(give manual labels: method='file')", ha="center", va="center", fontsize=8,
                color="0.35")
    _stats_scale_axis(ax, stats, "(a) correct matching rate (CMR)", "CMR")
    return fig


def _stats_grouped(ax, gt: np.ndarray, irr: np.ndarray) -> None:
    scales = np.arange(1, 10)
    w = 0.38
    ax.bar(scales - w / 2, np.nan_to_num(np.asarray(gt, float)[1:10], nan=0.0), width=w,
           color=_STATS_GT_COLOR, label="ground-truth pairs")
    ax.bar(scales + w / 2, np.nan_to_num(np.asarray(irr, float)[1:10], nan=0.0), width=w,
           color=_STATS_IRR_COLOR, label="query-irrelevant pairs")
    ax.legend(fontsize=7, loc="best", frameon=True, framealpha=0.8)


def plot_cls(stats, ax=None) -> matplotlib.figure.Figure:
    """Fig. 4b: contribution of each scale to the similarity (CLS), ground-truth vs
    query-irrelevant pairs (grouped bars; each group sums to 1 over the scales).

    Args:
        stats: ``ScaleStats``.
        ax: axes to draw on (default: a new figure).

    Returns:
        The figure holding ``ax``.
    """
    fig, ax = _stats_axes(ax)
    _stats_grouped(ax, stats.cls_gt, stats.cls_irrelevant)
    _stats_scale_axis(ax, stats, "(b) contribution to similarity (CLS)", "share of similarity")
    ax.set_ylim(bottom=0)
    return fig


def plot_asl(stats, ax=None) -> matplotlib.figure.Figure:
    """Fig. 4c: average pair score ``1 - d*s`` of the matched landmarks per scale (ASL),
    ground-truth vs query-irrelevant pairs (grouped bars).

    Args:
        stats: ``ScaleStats``.
        ax: axes to draw on (default: a new figure).

    Returns:
        The figure holding ``ax``.
    """
    fig, ax = _stats_axes(ax)
    _stats_grouped(ax, stats.asl_gt, stats.asl_irrelevant)
    _stats_scale_axis(ax, stats, "(c) average similarity of matches (ASL)", "mean 1 - d*s")
    return fig


def plot_scale_statistics(stats, title: str | None = None) -> matplotlib.figure.Figure:
    """Fig. 4: CMR, CLS and ASL side by side.

    Args:
        stats: ``vpr_core.statistics.ScaleStats``.
        title: optional suptitle (e.g. dataset, landmark method, label method).

    Returns:
        A 1x3-panel figure.
    """
    fig, axes = plt.subplots(1, 3, figsize=(14.0, 3.8))
    plot_cmr(stats, ax=axes[0])
    plot_cls(stats, ax=axes[1])
    plot_asl(stats, ax=axes[2])
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


def plot_labelled_matches(img_q: np.ndarray, img_r: np.ndarray, boxes_q: np.ndarray,
                          boxes_r: np.ndarray, matches: np.ndarray, labels: np.ndarray | None,
                          ax=None, gap: int = 12, lw: float = 1.2,
                          title: str | None = None) -> matplotlib.figure.Figure:
    """Fig. 1-2: query and reference side by side, matched landmark boxes coloured by label.

    Args:
        img_q: ``(Hq, Wq, 3)`` uint8 query image (left).
        img_r: ``(Hr, Wr, 3)`` uint8 reference image (right).
        boxes_q: ``(Kq, 4)`` ``(x, y, w, h)`` query boxes.
        boxes_r: ``(Kr, 4)`` reference boxes.
        matches: ``(P, 2)`` (query box index, reference box index).
        labels: ``(P,)`` bool (green = correct, red = incorrect) or ``None`` (all yellow).
        ax: axes to draw on (default: a new figure sized to the canvas).
        gap: white pixels between the two images.
        lw: box / line width.
        title: axes title (default: counts of correct / incorrect matches).

    Returns:
        The figure holding ``ax``. Boxes of each match and a line joining their centres.
    """
    iq = np.asarray(img_q)
    ir = np.asarray(img_r)
    if iq.ndim == 2:
        iq = np.repeat(iq[..., None], 3, axis=2)
    if ir.ndim == 2:
        ir = np.repeat(ir[..., None], 3, axis=2)
    hh = max(iq.shape[0], ir.shape[0])
    canvas = np.full((hh, iq.shape[1] + gap + ir.shape[1], 3), 255, dtype=np.uint8)
    canvas[: iq.shape[0], : iq.shape[1]] = iq[..., :3]
    off = iq.shape[1] + gap
    canvas[: ir.shape[0], off:] = ir[..., :3]
    if ax is None:
        fig, ax = plt.subplots(figsize=(min(16.0, canvas.shape[1] / 80), canvas.shape[0] / 80 + 0.5))
    else:
        fig = ax.figure
    ax.imshow(canvas)
    ax.set_axis_off()
    m = np.asarray(matches, dtype=np.int64).reshape(-1, 2)
    bq = np.asarray(boxes_q, dtype=float).reshape(-1, 4)
    br = np.asarray(boxes_r, dtype=float).reshape(-1, 4)
    lab = None if labels is None else np.asarray(labels, dtype=bool).reshape(-1)
    if lab is not None and len(lab) != len(m):
        raise ValueError(f"labels ({len(lab)}) must have one entry per match ({len(m)})")
    # incorrect first, correct on top
    order = np.arange(len(m)) if lab is None else np.argsort(lab, kind="stable")
    for k in order:
        i, j = m[k]
        color = "yellow" if lab is None else ("lime" if lab[k] else "red")
        a = bq[i]
        b = br[j] + np.array([off, 0.0, 0.0, 0.0])
        draw_boxes(ax, a[None], color=color, lw=lw)
        draw_boxes(ax, b[None], color=color, lw=lw)
        ax.plot([a[0] + a[2] / 2, b[0] + b[2] / 2], [a[1] + a[3] / 2, b[1] + b[3] / 2],
                color=color, lw=lw * 0.8, alpha=0.8)
    if title is None:
        if lab is None:
            title = f"{len(m)} matches (unlabelled)"
        else:
            title = f"{len(m)} matches: {int(lab.sum())} correct (green), " \
                    f"{int((~lab).sum())} incorrect (red)"
    ax.set_title(title, fontsize=9)
    return fig

