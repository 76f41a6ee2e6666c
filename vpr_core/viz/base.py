"""Shared plotting pieces: the deterministic :func:`save_figure`, box drawing, image canvases."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ..paths import figures_dir, results_dir

__all__ = ["METHOD_COLORS", "SAVE_DPI", "draw_boxes", "layout_problems", "save", "save_figure"]

#: Resolution of every saved study figure (dots per inch).
SAVE_DPI = 110

#: Paper-like colours for methods (stable across figures).
METHOD_COLORS = {
    "dense": "tab:red",
    "classical": "tab:blue",
    "selection_scheme1": "tab:green",
    "selection_scheme2": "tab:orange",
    "overlap_scheme1": "tab:purple",
    "overlap_scheme2": "tab:brown",
}


def png_metadata(suffix: str) -> dict:
    """Metadata that keeps saved files byte-identical: no software/version or date stamp."""
    return {"Software": None} if suffix == ".png" else {"CreationDate": None, "Producer": None}


def save_figure(
    fig: matplotlib.figure.Figure, name: str | Path, dataset: str | None = None, dpi: int = SAVE_DPI
) -> Path:
    """Save ``fig`` as ``<output root>/figures/<dataset>/<name>.png``, byte-identical for
    identical inputs.

    Args:
        fig: the figure.
        name: file stem, or a file name with ``.png`` / ``.pdf``, or an absolute path (then
            ``dataset`` is ignored).
        dataset: output label (subfolder of :func:`vpr_core.paths.figures_dir`).
        dpi: resolution.

    Returns:
        The written path.
    """
    path = Path(name)
    if path.suffix not in (".png", ".pdf"):
        path = path.with_suffix(path.suffix + ".png") if path.suffix else path.with_suffix(".png")
    if not path.is_absolute():
        path = figures_dir(dataset) / path
    from ..paths import make_dir

    make_dir(path.parent, "--out / VPR_OUTPUT_DIR (default: the current folder)")
    tmp = path.with_name(path.name + ".tmp")
    try:  # written whole or not at all (a full disk leaves no half PNG)
        fig.savefig(
            tmp,
            dpi=dpi,
            metadata=png_metadata(path.suffix),
            bbox_inches=None,
            format=path.suffix[1:],
        )
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def _legend_boxes(fig) -> list:
    out = list(fig.legends)
    for ax in fig.axes:
        leg = ax.get_legend()
        if leg is not None:
            out.append(leg)
    return out


def _data_points(ax) -> np.ndarray:
    """Display coordinates of an axes' plotted data: line vertices and bar tops/corners."""
    from matplotlib.patches import Rectangle

    pts = []
    for line in ax.get_lines():
        xy = np.asarray(line.get_xydata(), dtype=float).reshape(-1, 2)
        xy = xy[np.isfinite(xy).all(axis=1)]
        if len(xy) and line.get_visible() and line.get_linewidth() > 0:
            pts.append(ax.transData.transform(xy))
    for patch in ax.patches:
        if isinstance(patch, Rectangle) and patch.get_visible() and patch.get_height() > 0:
            x, y, w, h = patch.get_x(), patch.get_y(), patch.get_width(), patch.get_height()
            corners = np.array([[x, y + h], [x + w, y + h], [x + w / 2, y + h]])
            pts.append(ax.transData.transform(corners))
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def layout_problems(fig: matplotlib.figure.Figure) -> list[str]:
    """What a reader would see as broken in a figure: text cut by the canvas edge, a legend
    drawn over the plotted data (line vertices, bar tops).

    Returns:
        One sentence per problem (empty: the figure passes).
    """
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    canvas = fig.bbox
    problems = []
    parts = [
        (
            f"axes {ax.get_title()[:50]!r} (its title, tick or axis labels)",
            ax.get_tightbbox(renderer),
        )
        for ax in fig.axes
        if ax.get_visible()
    ]
    parts += [
        (f"text {t.get_text()[:50]!r}", t.get_window_extent(renderer))
        for t in fig.texts
        if t.get_visible() and t.get_text().strip()
    ]
    parts += [("a figure legend", leg.get_window_extent(renderer)) for leg in fig.legends]
    for what, bb in parts:
        if bb is None:
            continue
        if (
            bb.x0 < canvas.x0 - 1
            or bb.y0 < canvas.y0 - 1
            or bb.x1 > canvas.x1 + 1
            or bb.y1 > canvas.y1 + 1
        ):
            problems.append(f"{what} extends beyond the canvas")
    for leg in _legend_boxes(fig):
        bb = leg.get_window_extent(renderer)
        for ax in fig.axes:
            pts = _data_points(ax)
            inside = (
                (pts[:, 0] > bb.x0)
                & (pts[:, 0] < bb.x1)
                & (pts[:, 1] > bb.y0)
                & (pts[:, 1] < bb.y1)
            )
            if inside.any():
                problems.append(
                    f"the legend covers {int(inside.sum())} data point(s) of the "
                    f"axes {ax.get_title()[:40]!r}"
                )
    return problems


def save(obj, name: str, label: str, out: str | Path | None = None) -> Path:
    """Write a figure or a table of the study under its dataset label (the one output writer).

    A matplotlib Figure goes to ``figures/<label>/<name>.png`` (byte-identical for identical
    inputs, :func:`save_figure`); a pandas DataFrame to ``results/<label>/<name>.csv`` (floats
    with 6 decimals, the index kept). Both folders are under the output root
    (:func:`vpr_core.paths.output_root`) or under ``out`` when given.

    Args:
        obj: ``matplotlib.figure.Figure`` or ``pandas.DataFrame``.
        name: file stem, e.g. ``"fig05_selection"``.
        label: the dataset label (subfolder), e.g. ``"synthetic"``, ``"gardens_point_mini"``.
        out: another output root.

    Returns:
        The written path.

    Raises:
        TypeError: ``obj`` is neither a Figure nor a DataFrame.
    """
    import pandas as pd

    if not label or not isinstance(label, str):
        raise ValueError(f"save(): label must name the dataset (a non-empty string), got {label!r}")
    root = None if out is None else Path(out).expanduser().resolve()
    from ..paths import make_dir

    setting = "--out / VPR_OUTPUT_DIR (default: the current folder)"
    if isinstance(obj, matplotlib.figure.Figure):
        folder = figures_dir(label) if root is None else make_dir(root / "figures" / label, setting)
        from ..notices import notice

        for problem in layout_problems(obj):
            notice(f"layout of {name}: {problem}")
        return save_figure(obj, folder / f"{name}.png")
    if isinstance(obj, pd.DataFrame):
        folder = results_dir(label) if root is None else make_dir(root / "results" / label, setting)
        path = folder / f"{name}.csv"
        tmp = path.with_name(path.name + ".tmp")
        try:
            obj.to_csv(tmp, float_format="%.6f", index=not isinstance(obj.index, pd.RangeIndex))
            tmp.replace(path)
        finally:
            tmp.unlink(missing_ok=True)
        return path
    raise TypeError(
        f"save() writes a matplotlib Figure or a pandas DataFrame, got {type(obj).__name__}"
    )


def draw_boxes(ax, boxes: np.ndarray, color="yellow", lw: float = 1.0, alpha: float = 0.9) -> None:
    """Draw ``(K, 4)`` ``(x, y, w, h)`` boxes on an axes."""
    from matplotlib.patches import Rectangle

    for x, y, w, h in np.asarray(boxes, dtype=float).reshape(-1, 4):
        ax.add_patch(Rectangle((x, y), w, h, fill=False, edgecolor=color, lw=lw, alpha=alpha))


def landmark_canvas(image_or_size) -> tuple[np.ndarray | None, tuple[int, int]]:
    """``(image or None, (H, W))`` from an image ``(H, W[, 3])`` or an ``(H, W)`` size."""
    arr = np.asarray(image_or_size) if isinstance(image_or_size, np.ndarray) else None
    if arr is not None and arr.ndim in (2, 3) and arr.shape[0] > 3:
        return arr, (int(arr.shape[0]), int(arr.shape[1]))
    size = tuple(int(v) for v in tuple(image_or_size)[:2])
    if len(size) != 2 or min(size) <= 0:
        raise ValueError(f"expected an image (H, W, 3) or a size (H, W), got {image_or_size!r}")
    return None, size


def show_canvas(ax, image: np.ndarray | None, size: tuple[int, int], gray: bool = False) -> None:
    """Show ``image`` (or a blank ``size`` canvas) on ``ax`` without ticks, pixel-exact limits."""
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


def new_axes(ax, figsize: tuple[float, float]):
    """``(fig, ax)``: the given axes and its figure, or a new single-panel figure."""
    if ax is None:
        fig, ax = plt.subplots(figsize=figsize)
        return fig, ax
    return ax.figure, ax
