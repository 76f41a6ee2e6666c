"""What several figure modules of :mod:`vpr_study.viz` share (internal to the package): the
width and caption size of the per-query figures, their heading wrap and the check of the runs
they are given."""

from __future__ import annotations

import textwrap
from typing import Any

import numpy as np

from vpr_core import dataset_fingerprint

__all__ = ["FIG_WIDTH", "FONT", "check_runs_on", "wrapped"]

#: Width (inches) of the per-query figures (disagreements, weighted matches, carried landmarks):
#: at the inline backend's 100 dpi they show unscaled in a JupyterLab output column (about
#: 950 px), so their captions read at :data:`FONT` points.
FIG_WIDTH = 9.5

#: Size (points) of every caption of those figures.
FONT = 9


def wrapped(text: str, width: float, font: float = FONT) -> str:
    """``text`` with each line wrapped at ``width`` inches of ``font``-point text (at most
    0.56 em a character; an empty line kept)."""
    chars = int(width * 72 / (0.56 * font))
    return "\n".join(w for ln in text.split("\n") for w in textwrap.wrap(ln, chars) or [""])


def check_runs_on(ds: Any, runs: tuple, caller: str) -> None:
    """Refuse a run that was not computed on ``ds``: its dataset fingerprint (the images and the
    ground truth) or its ground truth differs; ``caller`` names the figure."""
    fingerprint = dataset_fingerprint(ds)
    gt = np.asarray(ds.ground_truth, dtype=bool)
    for run in runs:
        theirs = getattr(run, "dataset_fingerprint", None)
        truth = np.asarray(run.ground_truth, dtype=bool)
        if (theirs and theirs != fingerprint) or truth.shape != gt.shape or (truth != gt).any():
            raise ValueError(
                f"{caller}: {run.label!r} was run on another dataset than {ds.name!r} (it ran "
                f"on {getattr(run, 'dataset', '?')!r}; the images or the ground truth differ): "
                "pass the dataset the runs were computed on"
            )
