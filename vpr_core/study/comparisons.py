"""PR-curve comparisons (ratio protocol): Fig. 5, 7, 10-13 and the dense sweeps of Tables 2-4.

:meth:`ComparisonFigures.compare` is the one place that turns a list of runs into a PR figure
and a metrics table; the paper's figures call it with the paper's settings
(:mod:`vpr_core.paper`) and their registered titles (:mod:`vpr_core.study.registry`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pandas as pd

from ..paper import DENSE_TABLES, FIG7_NMS_THRESHOLDS, FIG7_SOFT_NMS_THRESHOLDS
from .registry import figure_spec
from .result import FigureResult

__all__ = ["ComparisonFigures", "RunSpec", "dense_run", "dense_set_label"]

#: One entry of :meth:`ComparisonFigures.compare`: a method name, ``(name, overrides)``,
#: ``(name, overrides, label)``, or a finished result with ``.label``, ``.curve()`` and
#: ``.row()`` (e.g. a :class:`~vpr_core.pipeline.MethodResult` from elsewhere).
RunSpec = Any


def _per_scale_text(per_scale: int | tuple[int, ...]) -> str:
    return "/".join(map(str, per_scale)) if isinstance(per_scale, tuple) else str(per_scale)


def dense_set_label(set_name: str, scales: Sequence[float], per_scale) -> str:
    """Legend label of a dense setting, e.g. ``"Set 3: 0.25/0.49 x 49"``."""
    return f"{set_name}: {'/'.join(f'{s:g}' for s in scales)} x {_per_scale_text(per_scale)}"


def dense_run(set_name: str, scales: Sequence[float], per_scale) -> tuple[str, dict, str]:
    """The :meth:`ComparisonFigures.compare` entry of one dense-sampling setting."""
    return ("dense", {"scales": scales, "per_scale": per_scale},
            dense_set_label(set_name, scales, per_scale))


def _check_table(table: str) -> dict:
    if table not in DENSE_TABLES:
        raise ValueError(f"Unknown table {table!r}; valid: {', '.join(DENSE_TABLES)}.")
    return DENSE_TABLES[table]


class ComparisonFigures:
    """Study methods for the PR-curve figures (mixed into :class:`~vpr_core.study.Study`)."""

    def resolve_run(self, item: RunSpec):
        """One :data:`RunSpec` -> a result with ``.label``, ``.curve()``, ``.row()``."""
        if isinstance(item, str):
            return self.run(item)
        if isinstance(item, tuple) and item and isinstance(item[0], str):
            name, overrides, *rest = item
            if len(rest) > 1 or not isinstance(overrides, dict):
                raise TypeError(f"compare entry {item!r}: write (name, overrides) or "
                                "(name, overrides, label)")
            return self.run(name, label=rest[0] if rest else None, **overrides)
        if all(hasattr(item, a) for a in ("label", "curve", "row")):
            return item
        raise TypeError(f"compare entry {item!r} is not a method name, a (name, overrides[, "
                        "label]) tuple or a result with .label, .curve() and .row()")

    def compare(self, runs: Sequence[RunSpec], figure: str,
                title: str | None = None) -> FigureResult:
        """Run several methods, plot their PR curves (ratio protocol) and record the metrics.

        Args:
            runs: :data:`RunSpec` entries, drawn in this order.
            figure: figure file stem, e.g. ``"fig05_selection"``; its rows in
                ``results/<label>/<notebook>.csv`` carry this name.
            title: plot title (default: the figure stem). The dataset label, query count and
                tolerance are added below it.

        Returns:
            The PR figure and the metrics table (one row per run, indexed by label).
        """
        from ..viz import plot_pr_curves

        results = [self.resolve_run(item) for item in runs]
        fig = plot_pr_curves(results, title=f"{title or figure} ({self.label})")
        table = self.record(figure, results)
        self._figure_results[figure] = results
        if len(results) > 1:
            self.paired_differences(figure)
        return self.save(fig, figure, table=table)

    def paired_differences(self, figure: str, baseline: str | None = None) -> pd.DataFrame:
        """Paired bootstrap of every run of a compared figure against one of them.

        Same resampled queries for both methods (:func:`~vpr_core.evaluation.paired_bootstrap`,
        1,000 resamples, seed 0). A difference is a ``finding`` only when its 95% interval
        excludes 0, else ``inconclusive``. Written to
        ``results/<label>/<notebook>_<figure>_paired.csv``.

        Args:
            figure: a figure stem already drawn by :meth:`compare` in this study.
            baseline: the label of the run to compare against (default: the figure's first).

        Returns:
            One row per other run: ``dAUC``, ``dR@100P``, ``dR@1`` with ``lo``, ``hi``, ``p``
            and a verdict per metric.
        """
        from ..evaluation import bootstrap_columns, difference_verdict, paired_bootstrap

        if figure not in self._figure_results:
            raise KeyError(f"figure {figure!r} has not been compared in this study yet; drawn: "
                           f"{', '.join(self._figure_results) or 'none'}")
        results = self._figure_results[figure]
        labels = [r.label for r in results]
        base_label = labels[0] if baseline is None else baseline
        if base_label not in labels:
            raise ValueError(f"baseline {baseline!r} is not a run of {figure}; runs: "
                             f"{', '.join(labels)}")
        base = results[labels.index(base_label)]
        rows = []
        for r in results:
            if r is base:
                continue
            d = paired_bootstrap(r.similarity, base.similarity, base.ground_truth,
                                 ks=(1,), seed=0)
            row = {"figure": figure, "method": r.label, "baseline": base.label,
                   **bootstrap_columns(d, prefix="d")}
            for name in ("dAUC", "dR@100P", "dR@1"):
                lo, hi = row[f"{name} lo"], row[f"{name} hi"]
                row[f"{name} verdict"] = difference_verdict(lo, hi)
            rows.append(row)
        table = pd.DataFrame(rows)
        table.to_csv(self.results_dir / f"{self.notebook}_{figure}_paired.csv", index=False,
                     float_format="%.6f")
        return table.set_index("method") if len(table) else table

    def vprbench_peers(self, root: str | None = None, dataset: str | None = None) -> list:
        """VPR-Bench's precomputed techniques on this study's images, as results for
        :meth:`compare` (``extra=``).

        Args:
            root: a VPR-Bench checkout or its ``precomputed_matches/`` (None:
                ``$VPR_BENCH_ROOT``).
            dataset: its dataset folder (e.g. ``"GardensPointWalking"``); None: no peers.

        Returns:
            One result per technique (empty when ``dataset`` is None or no root is known).
        """
        import os

        from ..baselines import VPR_BENCH_ROOT_ENV, find_vprbench_peers
        from ..pipeline import peer_result

        if dataset is None or (root is None and not os.environ.get(VPR_BENCH_ROOT_ENV)):
            return []
        return [peer_result(p, self.dataset) for p in find_vprbench_peers(root, dataset)]

    def _paper_compare(self, runs: Sequence[RunSpec], stem: str,
                       note: str | None = None) -> FigureResult:
        title = figure_spec(stem).title
        return self.compare(runs, stem, title=f"{title} ({note})" if note else title)

    def dense_sweep(self, table: str, figure: str) -> FigureResult:
        """Dense-sampling settings of the paper's Table 2, 3 or 4 as PR curves (Fig. 10-12).

        Raises:
            ValueError: unknown table (the message lists ``table2, table3, table4``).
        """
        settings = _check_table(table)
        runs = [dense_run(name, scales, per_scale)
                for name, (scales, per_scale) in settings.items()]
        return self.compare(runs, figure, title=f"{figure} ({table.replace('table', 'Table ')})")

    @staticmethod
    def dense_settings(table: str) -> pd.DataFrame:
        """The paper's Table 2/3/4 as a DataFrame (setting, scales, per scale, total)."""
        rows = []
        for set_name, (scales, per_scale) in _check_table(table).items():
            counts = per_scale if isinstance(per_scale, tuple) else (per_scale,) * len(scales)
            rows.append({"setting": set_name, "normalized scales": scales,
                         "landmarks per scale": counts, "total": int(sum(counts))})
        return pd.DataFrame(rows).set_index("setting")

    # ---- the paper's figures ---------------------------------------------------------------
    def fig05_selection(self) -> FigureResult:
        """Fig. 5: classical vs selection Scheme 1 (Alg. 1) vs Scheme 2 (Alg. 2)."""
        return self._paper_compare(["classical", "selection_scheme1", "selection_scheme2"],
                                   "fig05_selection")

    def fig07a_overlap_nms(self, thresholds: Sequence[float] = FIG7_NMS_THRESHOLDS
                           ) -> FigureResult:
        """Fig. 7a: classical vs NMS on the landmarks (Alg. 3) at each IoU threshold."""
        runs = ["classical"] + [("overlap_scheme1", {"iou_threshold": t}) for t in thresholds]
        return self._paper_compare(runs, "fig07a_overlap_nms")

    def fig07b_overlap_soft_nms(self, thresholds: Sequence[float] = FIG7_SOFT_NMS_THRESHOLDS
                                ) -> FigureResult:
        """Fig. 7b: classical vs soft-NMS on the match scores (Alg. 4) at each threshold."""
        runs = ["classical"] + [("overlap_scheme2", {"soft_nms_iou": t}) for t in thresholds]
        return self._paper_compare(runs, "fig07b_overlap_soft_nms")

    def fig10_scale_levels(self) -> FigureResult:
        """Fig. 10: Table 2, single vs multiple scale levels."""
        return self.dense_sweep("table2", "fig10_scale_levels")

    def fig11_landmarks_per_scale(self) -> FigureResult:
        """Fig. 11: Table 3, landmarks per scale."""
        return self.dense_sweep("table3", "fig11_landmarks_per_scale")

    def fig12_normalized_scales(self) -> FigureResult:
        """Fig. 12: Table 4, normalised scales."""
        return self.dense_sweep("table4", "fig12_normalized_scales")

    def fig13_comparison(self, note: str | None = None, extra: Sequence[RunSpec] = ()
                         ) -> FigureResult:
        """Fig. 13: dense sampling vs selection Scheme 1 vs classical.

        Args:
            note: appended to the title in brackets (e.g. the dataset's name).
            extra: further :data:`RunSpec` entries drawn after the paper's three (peers).
        """
        runs = ["dense", "selection_scheme1", "classical", *extra]
        return self._paper_compare(runs, "fig13_comparison", note=note)
