"""What several figure modules of :mod:`vpr_study.viz` share (internal to the package): the
width and caption size of the per-query figures, their heading wrap, the checks of the runs they
are given and a weighted run's matches."""

from __future__ import annotations

import dataclasses
import textwrap
from typing import Any

import numpy as np

from vpr_core import dataset_fingerprint
from vpr_core.matching import weighted_matches

__all__ = ["FIG_WIDTH", "FONT", "check_runs_on", "run_matches", "weighting_of", "wrapped"]

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


def weighting_of(run: Any) -> str:
    """The database weighting ``run`` matched with; refuses a run without one."""
    matching = getattr(getattr(run, "config", None), "matching", None)
    if matching is None or not matching.weighting:
        raise ValueError(
            f"{getattr(run, 'label', run)!r} has no weighting: pass the run of "
            "run_method(..., weighting='contrast', keep_descriptors=True) as `weighted`"
        )
    return str(matching.weighting)


def run_matches(run: Any, pairs: list[tuple[int, int]], weighting: str) -> list:
    """Each pair's matches with the weights the weighted ``run`` (parsed: it kept its
    descriptors, whitened where it was: ``whiten`` is then already applied) used."""
    d, b = run.descriptors, run.boxes
    sample = None if run.shortlist else np.arange(len(d["reference"]))
    m = run.config.matching
    return weighted_matches(
        d["query"],
        b["query"],
        d["reference"],
        b["reference"],
        pairs,
        dataclasses.replace(m, weighting=weighting, whiten=None),
        sample,
    )
