"""Matched landmarks of one image pair, coloured correct / incorrect: Fig. 1, 2, 3 and 8."""

from __future__ import annotations

import logging

import numpy as np

from .result import FigureResult

__all__ = ["MatchFigures"]

logger = logging.getLogger("vpr_core")


class MatchFigures:
    """Study methods for Fig. 1-3 and 8 (mixed into :class:`~vpr_core.study.Study`)."""

    def labelled_matches(self, pair: int = 0, method: str = "classical",
                         reference: int | None = None,
                         figure: str = "fig01_labelled_matches") -> FigureResult:
        """Matched landmarks of one image pair coloured correct/incorrect (Fig. 1-2).

        Args:
            pair: query index.
            method: landmark method whose matches are drawn.
            reference: reference index; None uses the query's ground-truth reference (Fig. 1);
                another index shows a query-irrelevant pair, where every match is wrong
                (Fig. 2).
            figure: file stem.

        Returns:
            The figure (no table). Labels: ``exact`` on ``synthetic``, ``geometric`` (SIFT +
            RANSAC) on real images; a pair that cannot be verified is drawn unlabelled and
            the title says why.
        """
        from ..matching import match_landmarks
        from ..statistics import LabelUnavailableError, label_matches
        from ..viz import plot_labelled_matches

        res = self.run(method, keep_descriptors=True)
        q = int(pair)
        gt = np.asarray(self.dataset.ground_truth, dtype=bool)
        if reference is None:
            r = q if q < gt.shape[1] and gt[q, q] else int(np.flatnonzero(gt[q])[0])
        else:
            r = int(reference)
        m = match_landmarks(res.descriptors["query"][q], res.boxes["query"][q],
                            res.descriptors["reference"][r], res.boxes["reference"][r])
        note = ""
        if bool(gt[q, r]):
            try:
                labels = label_matches(self.dataset, q, r, res.boxes["query"][q],
                                       res.boxes["reference"][r], m.matches)
            except LabelUnavailableError as exc:
                labels, note = None, f" (labels unavailable: {exc})"
                logger.warning("pair (%d, %d) cannot be labelled: %s", q, r, exc)
        else:
            labels = np.zeros(len(m.matches), dtype=bool)
        fig = plot_labelled_matches(self.dataset.load_image("query", q),
                                    self.dataset.load_image("reference", r),
                                    res.boxes["query"][q], res.boxes["reference"][r],
                                    m.matches, labels)
        counts = (f"{int(labels.sum())}/{len(labels)} matches correct" if labels is not None
                  else f"{len(m.matches)} matches, unlabelled{note[:80]}")
        fig.suptitle(f"{res.label}: query {q} vs reference {r} "
                     f"({'ground truth' if gt[q, r] else 'irrelevant'}); {counts}; "
                     f"S = {m.similarity:.3f}", fontsize=9)
        return self.save(fig, figure)

    def fig01_labelled_matches(self, pair: int = 0, method: str = "classical") -> FigureResult:
        """Fig. 1: matches between a query and its ground-truth reference, labelled."""
        return self.labelled_matches(pair=pair, method=method, figure="fig01_labelled_matches")

    def fig02_irrelevant_matches(self, pair: int = 0, method: str = "classical",
                                 reference: int | None = None) -> FigureResult:
        """Fig. 2: matches between a query and an irrelevant reference (default: the middle
        reference), all wrong by definition."""
        if reference is None:
            reference = len(self.dataset.reference_paths) // 2
        return self.labelled_matches(pair=pair, method=method, reference=reference,
                                     figure="fig02_irrelevant_matches")

    def fig03_classical_pipeline(self, pair: int = 0) -> FigureResult:
        """Fig. 3: the classical pipeline (top-100 Edge Boxes) on one ground-truth pair."""
        return self.labelled_matches(pair=pair, method="classical",
                                     figure="fig03_classical_pipeline")

    def fig08_dense_pipeline(self, pair: int = 0) -> FigureResult:
        """Fig. 8: the dense-sampling pipeline (4 scales x 25) on the same pair."""
        return self.labelled_matches(pair=pair, method="dense", figure="fig08_dense_pipeline")
