"""Plot helpers (``plot_*``) and one deterministic ``save_figure``.

Every figure of the study is drawn here; notebooks only call these.
"""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib

if not os.environ.get("MPLBACKEND"):
    matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .utils import REPO_DIR  # noqa: E402

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


def save_figure(fig: "matplotlib.figure.Figure", name: str, dataset: str | None = None,
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

# --- plots: landmarks ----------------------------------------------------------------------

# --- plots: PR curves and metrics ----------------------------------------------------------

# --- plots: scale statistics (Fig. 4) and labelled matches (Fig. 1-2) ------------------------
