"""Images and landmarks: dataset examples, boxes, dense scales (Fig. 9), coverage (Fig. 14)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.cm import ScalarMappable
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from vpr_core import dense_sampling, landmark_coverage, paper

from .base import draw_boxes
from .curves import dataset_line

#: matplotlib's ten categorical colours.
_TAB10: list[Any] = list(plt.get_cmap("tab10").colors)  # type: ignore[attr-defined]

__all__ = [
    "plot_coverage",
    "plot_coverage_comparison",
    "plot_dense_scales",
    "plot_examples",
    "plot_landmark_panels",
]


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
    """Show ``image`` (or a blank ``size`` canvas) on ``ax`` without ticks, pixel-exact limits."""
    if image is None:
        ax.imshow(np.full(size + (3,), 235, np.uint8))
    elif gray and image.ndim == 3:  # its grey levels stretched (1st-99th percentile): a dim
        grey = image.mean(axis=2)  # frame (Nordland's 64 x 32) stays readable under an overlay
        lo, hi = np.percentile(grey, (1, 99))
        ax.imshow(grey, cmap="gray", vmin=lo if hi > lo else 0, vmax=hi if hi > lo else 255)
    else:
        ax.imshow(image, cmap="gray" if image.ndim == 2 else None)
    ax.set_xlim(-0.5, size[1] - 0.5)
    ax.set_ylim(size[0] - 0.5, -0.5)
    ax.set_xticks([])
    ax.set_yticks([])


def plot_examples(
    dataset: Any, indices: Sequence[int] = (0, 1, 2), boxes: Any = None, title: str | None = None
) -> Figure:
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
    for (q, r), (ax_r, ax_q) in zip(rows, axes, strict=False):
        for ax, side, i in ((ax_r, "reference", r), (ax_q, "query", q)):
            img = dataset.load_image(side, i)
            ax.imshow(img)
            if boxes is not None:
                b = np.asarray(boxes(side, i, img.shape[:2]), dtype=float).reshape(-1, 4)
                draw_boxes(ax, b, color="yellow" if side == "reference" else "cyan", lw=0.8)
            ax.set_title(f"{side} {i}", fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
    truth = dataset.truth_text
    fig.suptitle(
        title if title is not None else f"{dataset.title}: reference | query ({truth})",
        fontsize=10,
    )
    fig.tight_layout()
    return fig


def plot_dense_scales(
    image_or_size, scales=paper.DENSE_SCALES, per_scale=paper.DENSE_PER_SCALE
) -> Figure:
    """Fig. 9: one panel per dense-sampling scale level with that level's boxes.

    Args:
        image_or_size: ``(H, W, 3)`` image or an ``(H, W)`` size (blank canvas).
        scales: normalized scales (area ratios), one panel each.
        per_scale: boxes per scale (int or one per scale), as in ``dense_sampling``.
    """
    img, size = _landmark_canvas(image_or_size)
    scales = list(np.atleast_1d(np.asarray(scales, dtype=float)))
    counts = [per_scale] * len(scales) if np.ndim(per_scale) == 0 else list(per_scale)
    n = len(scales)
    ncols = 2 if n == 4 else min(n, 3)
    nrows = int(np.ceil(n / ncols))
    panel_w = 4.2
    fig, axes = plt.subplots(
        nrows,
        ncols,
        squeeze=False,
        figsize=(panel_w * ncols, (panel_w * size[0] / size[1] + 0.5) * nrows),
    )
    colors = _TAB10
    for k, ax in enumerate(axes.ravel()):
        if k >= n:
            ax.axis("off")
            continue
        boxes = dense_sampling(size, (scales[k],), counts[k])
        _show_canvas(ax, img, size)
        for j, box in enumerate(boxes):
            draw_boxes(ax, box[None], color=colors[j % len(colors)], lw=1.0)
        ax.set_title(
            f"({chr(ord('a') + k)}) scale {k + 1}: {len(boxes)} landmarks, "
            f"{scales[k]:g} normalized scale",
            fontsize=9,
        )
    fig.tight_layout()
    return fig


def _contour_levels(top: float) -> np.ndarray:
    """The coverage outlines of a colour scale ``0..top``: at most 4 box counts, as contour
    levels half a box below each (the outline encloses the pixels with at least that many)."""
    return np.unique(np.linspace(0.5, top - 0.5, 4).round() + 0.5) if top > 1 else np.array([0.5])


def plot_coverage(
    image: np.ndarray,
    boxes: np.ndarray,
    ax: Any = None,
    cmap: str = "viridis",
    alpha: float = 0.35,
    title: str | None = None,
    vmax: float | None = None,
) -> Figure:
    """Fig. 14: how many landmarks cover each pixel, as a translucent heatmap over the (grey,
    contrast-stretched) image with white outlines at a few coverage levels (marked on the colour
    bar, which says what they are), so the image stays visible: the tint grows with the coverage
    up to ``alpha``. ``vmax``: the top of the colour
    scale (default this image's most-covered pixel; panels that are compared share one).

    The default title gives the share of pixels covered by at least one box.
    """
    img, size = _landmark_canvas(image)
    cov = landmark_coverage(boxes, size)
    if ax is None:
        fig, ax = plt.subplots(figsize=(6.4, 6.4 * size[0] / size[1] + 0.4))
    else:
        fig = ax.figure
    _show_canvas(ax, img, size, gray=True)
    shown = np.ma.masked_where(cov <= 0, cov)  # uncovered pixels show the plain image
    top = max(1.0, float(cov.max()) if vmax is None else float(vmax))
    # the tint grows with the coverage (``alpha`` at the top): a pixel under few boxes shows
    # the image almost as it is, a dim frame included
    ramp = np.clip(alpha * (0.3 + 0.7 * cov / top), 0.0, 1.0)
    im = ax.imshow(shown, cmap=cmap, alpha=ramp, vmin=0, vmax=top)
    levels = _contour_levels(top)
    counts = ", ".join(f"{int(v + 0.5)}" for v in levels)
    bar = fig.colorbar(
        ScalarMappable(norm=im.norm, cmap=im.get_cmap()),
        ax=ax,
        alpha=alpha,  # the colours as the most-covered pixels show them
        fraction=0.046,
        pad=0.02,
        label=f"boxes covering the pixel\n(white outlines: at least {counts})",
    )
    if cov.max() > levels.min():
        lines = ax.contour(cov, levels=levels, colors="white", linewidths=0.8, alpha=0.9)
        bar.add_lines(lines)
    covered = float((cov > 0).mean())
    ax.set_title(
        title
        if title is not None
        else f"coverage of {len(np.asarray(boxes).reshape(-1, 4))} landmarks: "
        f"{100 * covered:.0f}% of pixels"
    )
    return fig


#: An image a coverage figure shows by default has at least this mean and spread of grey (of
#: 255): not a black, blank or tunnel frame (Nordland's first summer frames are black).
SHOWN_GREY = (32.0, 16.0)


def _first_visible(dataset: Any, side: str, n: int = 50) -> int:
    """The first of the first ``n`` images of ``side`` that shows a scene (:data:`SHOWN_GREY`),
    else 0."""
    count = len(dataset.query_paths if side == "query" else dataset.reference_paths)
    for i in range(min(n, count)):
        grey = np.asarray(dataset.load_image(side, i), dtype=float).mean(axis=-1)
        if grey.mean() >= SHOWN_GREY[0] and grey.std() >= SHOWN_GREY[1]:
            return i
    return 0


def plot_coverage_comparison(
    dataset: Any, results: Any, index: int | None = None, side: str = "reference"
) -> tuple[Figure, pd.DataFrame]:
    """Fig. 14: coverage heatmaps of several runs' landmarks on one image, side by side.

    Args:
        dataset: the runs' dataset; results: the runs.
        index: the image shown; None: the first that shows a scene (not a black or blank
            frame: :data:`SHOWN_GREY`), the title says which.
        side: ``"reference"`` or ``"query"``.

    Returns:
        ``(figure, table)``: per run, the share of the image covered by at least one landmark
        for this image and averaged over the dataset's images of that side.
    """
    index = _first_visible(dataset, side) if index is None else int(index)
    image = dataset.load_image(side, index)
    fig, axes = plt.subplots(1, len(results), figsize=(5.5 * len(results), 3.4), squeeze=False)
    size = _landmark_canvas(image)[1]
    top = max(float(landmark_coverage(r.boxes[side][index], size).max()) for r in results)
    rows = []
    for k, (ax, res) in enumerate(zip(axes[0], results, strict=False)):
        plot_coverage(image, res.boxes[side][index], ax=ax, vmax=top)  # one colour scale
        ax.set_title(f"({chr(ord('a') + k)}) {res.label}: {len(res.boxes[side][index])} landmarks")
        shares = [
            float((landmark_coverage(b, dataset.image_size(side, i)) > 0).mean())
            for i, b in enumerate(res.boxes[side])
        ]
        rows.append(
            {
                "method": res.label,
                "covered share (this image)": shares[index],
                "covered share (mean)": float(np.mean(shares)),
            }
        )
    note = ""
    shortlists = {getattr(r, "shortlist", None) for r in results}
    if shortlists != {None}:  # a shortlist re-ranks matches: it never changes the landmarks
        note = (
            "\nthe shortlist does not change the landmarks: the exhaustive run's figure is the same"
        )
    fig.suptitle(
        f"landmark coverage of {side} {index}, one colour scale (0-{max(1, round(top))} boxes) "
        f"in every panel\n{dataset_line(results, pr=False)}{note}",
        fontsize=9,
    )
    fig.tight_layout()
    return fig, pd.DataFrame(rows).set_index("method")


def plot_landmark_panels(
    panels: dict,
    colors_by: np.ndarray | None = None,
    title: str | None = None,
    group_labels: dict | None = None,
) -> Figure:
    """Several images side by side, each with its landmark boxes (pipeline tour, step 1).

    Args:
        panels: ``{panel title: (image (H, W, 3) uint8, boxes (K, 4) (x, y, w, h))}``.
        colors_by: optional ``(K,)`` integer group of each box (e.g. its dense scale level);
            boxes of one group share a colour. Applies to every panel (same K each).
        title: optional suptitle.
        group_labels: ``{group: legend text}`` (e.g. ``{1: "scale 0.16"}``); with ``colors_by``
            a legend below the panels says which colour is which (default: ``"group N"``).

    Returns:
        A ``1 x len(panels)`` figure.
    """
    if not panels:
        raise ValueError("plot_landmark_panels: panels is empty; pass {title: (image, boxes)}.")
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 3.6), squeeze=False)
    palette = _TAB10
    for ax, (name, (image, boxes)) in zip(axes[0], panels.items(), strict=False):
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        img, size = _landmark_canvas(image)
        _show_canvas(ax, img, size)
        if colors_by is None:
            draw_boxes(ax, boxes, color="yellow", lw=0.8)
        else:
            groups = np.asarray(colors_by).reshape(-1)
            if len(groups) != len(boxes):
                raise ValueError(
                    f"colors_by has {len(groups)} entries for {len(boxes)} boxes "
                    f"in panel {name!r}; give one group per box."
                )
            for g in np.unique(groups):
                draw_boxes(ax, boxes[groups == g], color=palette[int(g) % len(palette)], lw=0.8)
        ax.set_title(f"{name}: {len(boxes)} landmarks", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    if colors_by is not None:
        groups = np.unique(np.asarray(colors_by).reshape(-1))
        names = group_labels or {}
        handles = [
            Patch(
                facecolor="none",
                edgecolor=palette[int(g) % len(palette)],
                lw=1.5,
                label=names.get(int(g), f"group {int(g)}"),
            )
            for g in groups
        ]
        fig.subplots_adjust(bottom=0.16)
        fig.legend(
            handles=handles, loc="lower center", ncol=len(handles), frameon=False, fontsize=9
        )
    return fig
