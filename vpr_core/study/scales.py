"""Section 3.1, the impact of scale: CMR / CLS / ASL per Table-1 scale (Fig. 4) and the scale
distribution of selected landmarks (Fig. 6)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..paper import N_SCALES, SCALE_LABELS
from .result import FigureResult

__all__ = ["ScaleFigures"]


class ScaleFigures:
    """Study methods for Fig. 4 and 6 (mixed into :class:`~vpr_core.study.Study`)."""

    def scale_statistics(self, method: str = "classical", n_irrelevant: int = 5, **overrides):
        """CMR / CLS / ASL per Table-1 scale for a method's landmarks (the data of Fig. 4).

        Labels: ``exact`` on ``synthetic`` (generator geometry), ``geometric`` (SIFT + RANSAC)
        on real datasets. Writes ``results/<label>/<notebook>_scale_statistics_<method>.csv``
        and, with every match (pair, box indices, scale, score, label), ``..._matches.csv``.
        Computed once per study and arguments.

        Returns:
            :class:`~vpr_core.statistics.ScaleStats`.
        """
        from ..statistics import scale_statistics

        key = ("scale_statistics", method, n_irrelevant, tuple(sorted(overrides.items())))
        if key in self._cache:
            return self._cache[key]
        res = self.run(method, keep_descriptors=True, **overrides)
        stats = scale_statistics(self.dataset, res.boxes["query"], res.boxes["reference"],
                                 res.descriptors["query"], res.descriptors["reference"],
                                 n_irrelevant=n_irrelevant, seed=self.seed)
        stats.to_frame().to_csv(
            self.results_dir / f"{self.notebook}_scale_statistics_{method}.csv",
            float_format="%.6f")
        stats.matches_frame().to_csv(
            self.results_dir / f"{self.notebook}_scale_statistics_{method}_matches.csv",
            index=False, float_format="%.8f")
        self._cache[key] = stats
        return stats

    def fig04_scale_statistics(self, method: str = "classical", n_irrelevant: int = 5,
                               **overrides) -> FigureResult:
        """Fig. 4: (a) CMR, (b) CLS, (c) ASL per scale.

        Saves the three panels as ``fig04a_cmr``, ``fig04b_cls``, ``fig04c_asl`` and the
        combined ``fig04_scale_statistics``.

        Returns:
            The combined figure, the per-scale table (:meth:`ScaleStats.to_frame`) and the
            panel files in ``panels``.
        """
        import matplotlib.pyplot as plt

        from ..viz import plot_asl, plot_cls, plot_cmr, plot_scale_statistics

        stats = self.scale_statistics(method, n_irrelevant=n_irrelevant, **overrides)
        panels = []
        for suffix, fn in (("a_cmr", plot_cmr), ("b_cls", plot_cls), ("c_asl", plot_asl)):
            fig, ax = plt.subplots(figsize=(5.5, 3.6))
            fn(stats, ax=ax)
            fig.tight_layout()
            panels.append(self.save(fig, f"fig04{suffix}").path)
        return self.save(plot_scale_statistics(stats), "fig04_scale_statistics",
                         table=stats.to_frame(), panels=panels)

    def scale_distribution(self, method: str, figure: str) -> FigureResult:
        """Landmark counts per Table-1 scale for query and reference images (Fig. 6).

        Also writes ``results/<label>/<notebook>_<figure>.csv``.

        Returns:
            The bar chart and a ``(9, 2)`` table (scale x side).
        """
        from ..landmarks import scale_histogram
        from ..viz import plot_scale_distribution

        res = self.run(method)
        hists = {}
        for side in ("query", "reference"):
            h = np.zeros(N_SCALES + 1, dtype=np.int64)
            for i, b in enumerate(res.boxes[side]):
                h += scale_histogram(b, self.dataset.image_size(side, i))
            hists[side] = h
        fig = plot_scale_distribution(hists, title=f"{res.label}: landmarks per scale "
                                                    f"({self.dataset.name})")
        frame = pd.DataFrame({k: v[1:] for k, v in hists.items()}, index=list(SCALE_LABELS))
        frame.to_csv(self.results_dir / f"{self.notebook}_{figure}.csv")
        return self.save(fig, figure, table=frame)

    def fig06a_scheme1_scales(self) -> FigureResult:
        """Fig. 6a: scale distribution of selection Scheme 1 (Algorithm 1)."""
        return self.scale_distribution("selection_scheme1", "fig06a_scheme1_scales")

    def fig06b_scheme2_scales(self) -> FigureResult:
        """Fig. 6b: scale distribution of selection Scheme 2 (Algorithm 2)."""
        return self.scale_distribution("selection_scheme2", "fig06b_scheme2_scales")
