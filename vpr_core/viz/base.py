"""Shared plotting pieces: the deterministic :func:`save_figure`, box drawing, image canvases."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ..paths import figures_dir, results_dir

__all__ = ["METHOD_COLORS", "SAVE_DPI", "draw_boxes", "save", "save_figure"]

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


def save_figure(fig: matplotlib.figure.Figure, name: str | Path, dataset: str | None = None,
                dpi: int = SAVE_DPI) -> Path:
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
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, metadata=png_metadata(path.suffix), bbox_inches=None)
    return path


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
        raise ValueError(f"save(): label must name the dataset (a non-empty string), got "
                         f"{label!r}")
    root = None if out is None else Path(out).expanduser().resolve()
    if isinstance(obj, matplotlib.figure.Figure):
        folder = figures_dir(label) if root is None else root / "figures" / label
        return save_figure(obj, folder / f"{name}.png")
    if isinstance(obj, pd.DataFrame):
        folder = results_dir(label) if root is None else root / "results" / label
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{name}.csv"
        tmp = path.with_name(path.name + ".tmp")
        obj.to_csv(tmp, float_format="%.6f", index=not isinstance(obj.index, pd.RangeIndex))
        tmp.replace(path)
        return path
    raise TypeError(f"save() writes a matplotlib Figure or a pandas DataFrame, got "
                    f"{type(obj).__name__}")


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
