"""Every figure of the study (``plot_*``), the labelling widget and :func:`save`."""

from __future__ import annotations

from .base import METHOD_COLORS, SAVE_DPI, draw_boxes, layout_problems, save, save_figure
from .carried import plot_carried_landmarks
from .curves import dataset_line, plot_pr_curves, plot_scale_distribution
from .disagreements import plot_disagreements
from .images import (
    plot_coverage,
    plot_coverage_comparison,
    plot_dense_scales,
    plot_examples,
    plot_landmark_panels,
)
from .matches import (
    plot_descriptor_matrices,
    plot_labelled_matches,
    plot_pair,
    plot_pair_terms,
)
from .statistics import plot_asl, plot_cls, plot_cmr, plot_scale_statistics
from .steps import plot_paired_differences, plot_step_changes
from .whitening import plot_whitening
from .widgets import label_widget, pair_label_widget

__all__ = [
    "METHOD_COLORS",
    "SAVE_DPI",
    "dataset_line",
    "draw_boxes",
    "label_widget",
    "layout_problems",
    "plot_asl",
    "plot_carried_landmarks",
    "plot_cls",
    "plot_cmr",
    "plot_coverage",
    "plot_coverage_comparison",
    "plot_dense_scales",
    "plot_descriptor_matrices",
    "plot_disagreements",
    "plot_examples",
    "plot_labelled_matches",
    "plot_landmark_panels",
    "pair_label_widget",
    "plot_pair",
    "plot_paired_differences",
    "plot_pair_terms",
    "plot_pr_curves",
    "plot_scale_distribution",
    "plot_scale_statistics",
    "plot_step_changes",
    "plot_whitening",
    "save",
    "save_figure",
]
