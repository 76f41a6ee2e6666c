"""Plot helpers (``plot_*``) and one deterministic :func:`save_figure`.

Every figure of the study is drawn here; notebooks call these and save with :func:`save`.

- :mod:`~vpr_core.viz.base`: :func:`save` (figures and tables), :func:`save_figure`
  (byte-identical PNGs), :func:`draw_boxes`.
- :mod:`~vpr_core.viz.images`: dataset examples, landmarks, dense scales (Fig. 9), coverage
  (Fig. 14).
- :mod:`~vpr_core.viz.curves`: PR curves (Fig. 5, 7, 10-13), metric bars, scale distributions
  (Fig. 6).
- :mod:`~vpr_core.viz.statistics`: CMR / CLS / ASL (Fig. 4).
- :mod:`~vpr_core.viz.matches`: labelled matches (Fig. 1-3, 8), descriptor matrices and Eq. (1)
  pair terms (pipeline tour).
"""

from __future__ import annotations

from .base import METHOD_COLORS, SAVE_DPI, draw_boxes, layout_problems, save, save_figure
from .curves import dataset_line, plot_metric_bars, plot_pr_curves, plot_scale_distribution
from .images import (
    plot_coverage,
    plot_coverage_comparison,
    plot_dataset_overview,
    plot_dense_scales,
    plot_examples,
    plot_landmark_panels,
    plot_landmarks,
)
from .matches import (
    plot_descriptor_matrices,
    plot_labelled_matches,
    plot_pair,
    plot_pair_terms,
)
from .recall import plot_recall_at_n
from .statistics import plot_asl, plot_cls, plot_cmr, plot_scale_statistics

__all__ = [
    "METHOD_COLORS",
    "SAVE_DPI",
    "dataset_line",
    "draw_boxes",
    "layout_problems",
    "plot_asl",
    "plot_cls",
    "plot_cmr",
    "plot_coverage",
    "plot_coverage_comparison",
    "plot_dataset_overview",
    "plot_dense_scales",
    "plot_descriptor_matrices",
    "plot_examples",
    "plot_labelled_matches",
    "plot_landmark_panels",
    "plot_landmarks",
    "plot_metric_bars",
    "plot_pair",
    "plot_pair_terms",
    "plot_pr_curves",
    "plot_recall_at_n",
    "plot_scale_distribution",
    "plot_scale_statistics",
    "save",
    "save_figure",
]
