"""What several figure modules of :mod:`vpr_core.viz` share (internal to the package): the width and
caption size of the per-query figures, their heading wrap, and a weighted run's matches."""

from __future__ import annotations

import dataclasses
import textwrap
from typing import Any

import numpy as np

from ..matching import weighted_matches

__all__ = ["FIG_WIDTH", "FONT", "run_matches", "wrapped"]

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


def run_matches(run: Any, pairs: list[tuple[int, int]], weighting: str) -> list:
    """Each pair's matches with the weights the weighted ``run`` (parsed: it kept its
    descriptors) used."""
    d, b = run.descriptors, run.boxes
    sample = None if run.shortlist else np.arange(len(d["reference"]))
    m = run.config.matching
    return weighted_matches(
        d["query"],
        b["query"],
        d["reference"],
        b["reference"],
        pairs,
        dataclasses.replace(m, weighting=weighting),
        sample,
    )
