"""The pipeline tour (notebook 01): one image pair through the four steps of the method, each
step calling the library function that the results use, each with its picture.

1. :func:`~vpr_core.landmarks.dense_sampling` -> the boxes on both images;
2. :meth:`~vpr_core.features.LandmarkEncoder.encode` -> the ``(K, D)`` descriptor matrices;
3. :func:`~vpr_core.matching.reciprocal_matches` -> the matched pairs between the images;
4. :func:`~vpr_core.matching.image_similarity` -> Eq. (1), with every pair's term ``1 - d*s``.

A step computes what an earlier step left undone, so any cell can run first.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from ..paper import DENSE_PER_SCALE, DENSE_SCALES
from .result import FigureResult

__all__ = ["TourSteps"]

_SIDES = ("query", "reference")


class TourSteps:
    """Study methods ``tour_*`` for the pipeline tour (mixed into ``Study``)."""

    # ---- state, computed once per pair ------------------------------------------------------
    def _tour(self, pair: int) -> dict[str, Any]:
        key = ("tour", int(pair))
        if key not in self._cache:
            q = int(pair)
            gt = np.asarray(self.dataset.ground_truth, dtype=bool)
            if not 0 <= q < gt.shape[0]:
                raise IndexError(f"tour: pair {q} out of range 0..{gt.shape[0] - 1} (queries).")
            hits = np.flatnonzero(gt[q])
            if hits.size == 0:
                raise ValueError(f"tour: query {q} has no ground-truth reference; pick another "
                                 "pair.")
            r = q if q < gt.shape[1] and gt[q, q] else int(hits[0])
            self._cache[key] = {"index": {"query": q, "reference": r},
                                "image": {s: self.dataset.load_image(s, i)
                                          for s, i in (("query", q), ("reference", r))}}
        return self._cache[key]

    def _tour_boxes(self, pair: int) -> dict[str, np.ndarray]:
        from ..landmarks import dense_sampling

        st = self._tour(pair)
        if "boxes" not in st:
            st["boxes"] = {s: np.asarray(dense_sampling(st["image"][s].shape[:2],
                                                        scales=DENSE_SCALES,
                                                        per_scale=DENSE_PER_SCALE))
                           for s in _SIDES}
        return st["boxes"]

    def _tour_descriptors(self, pair: int) -> dict[str, np.ndarray]:
        st, boxes = self._tour(pair), self._tour_boxes(pair)
        if "desc" not in st:
            st["desc"] = {s: self.encoder.encode(st["image"][s], boxes[s]) for s in _SIDES}
        return st["desc"]

    def _tour_matches(self, pair: int) -> np.ndarray:
        from ..matching import reciprocal_matches

        st, desc = self._tour(pair), self._tour_descriptors(pair)
        if "matches" not in st:
            st["matches"] = np.asarray(reciprocal_matches(desc["query"], desc["reference"]))
        return st["matches"]

    def _tour_caption(self, pair: int) -> str:
        idx = self._tour(pair)["index"]
        return f"{self.dataset.name}: query {idx['query']} / reference {idx['reference']}"

    # ---- the four steps ----------------------------------------------------------------------
    def tour_dense_sampling(self, pair: int = 0) -> FigureResult:
        """Step 1: ``dense_sampling`` on the query and its reference (4 scales x 25 boxes).

        Returns:
            Both images with their boxes coloured by scale level, and per level the normalised
            scale (Eq. 3) of the boxes, their size in pixels and their number.
        """
        from ..landmarks import normalized_scale

        st, boxes = self._tour(pair), self._tour_boxes(pair)
        level = np.repeat(np.arange(len(DENSE_SCALES)), DENSE_PER_SCALE)
        q_boxes, size = boxes["query"], st["image"]["query"].shape[:2]
        scale = normalized_scale(q_boxes, size)
        table = pd.DataFrame({
            "requested scale": list(DENSE_SCALES),
            "normalized scale (Eq. 3)": [float(scale[level == k].mean())
                                         for k in range(len(DENSE_SCALES))],
            "w (px)": [float(q_boxes[level == k, 2][0]) for k in range(len(DENSE_SCALES))],
            "h (px)": [float(q_boxes[level == k, 3][0]) for k in range(len(DENSE_SCALES))],
            "landmarks": [int((level == k).sum()) for k in range(len(DENSE_SCALES))],
        }, index=pd.Index(range(1, len(DENSE_SCALES) + 1), name="level"))
        from ..viz import plot_landmark_panels

        fig = plot_landmark_panels({s: (st["image"][s], boxes[s]) for s in _SIDES},
                                   colors_by=level,
                                   title=f"step 1, dense_sampling: {self._tour_caption(pair)}")
        return self.save(fig, "tour1_dense_sampling", table=table)

    def tour_descriptors(self, pair: int = 0) -> FigureResult:
        """Step 2: ``LandmarkEncoder.encode`` -> one ``(K, D)`` descriptor matrix per image."""
        from ..viz import plot_descriptor_matrices

        desc = self._tour_descriptors(pair)
        cfg = self.encoder.config
        table = pd.DataFrame({
            "landmarks": [d.shape[0] for d in desc.values()],
            "dimensions": [d.shape[1] for d in desc.values()],
            "mean L2 norm": [float(np.linalg.norm(d, axis=1).mean()) for d in desc.values()],
        }, index=pd.Index(list(desc), name="image"))
        table["backbone"] = cfg.get("backbone")
        table["weights"] = cfg.get("weights")
        fig = plot_descriptor_matrices(
            desc, title=f"step 2, LandmarkEncoder.encode ({cfg.get('backbone')}): "
                        f"{self._tour_caption(pair)}")
        return self.save(fig, "tour2_descriptors", table=table)

    def tour_reciprocal_matches(self, pair: int = 0) -> FigureResult:
        """Step 3: ``reciprocal_matches`` -> pairs (i, j) where i's nearest neighbour (cosine)
        is j and j's is i, drawn between the two images with their cosine distances."""
        from ..matching import cosine_distance
        from ..viz import plot_labelled_matches

        st, desc, m = self._tour(pair), self._tour_descriptors(pair), self._tour_matches(pair)
        boxes = self._tour_boxes(pair)
        d = cosine_distance(desc["query"], desc["reference"])[m[:, 0], m[:, 1]]
        table = pd.DataFrame({"query landmark": m[:, 0], "reference landmark": m[:, 1],
                              "cosine distance d": d})
        fig = plot_labelled_matches(
            st["image"]["query"], st["image"]["reference"], boxes["query"], boxes["reference"],
            m, None, title=f"step 3, reciprocal_matches: {len(m)} mutual nearest neighbours of "
                           f"{len(desc['query'])} x {len(desc['reference'])} landmarks "
                           f"({self._tour_caption(pair)})")
        return self.save(fig, "tour3_reciprocal_matches", table=table)

    def tour_image_similarity(self, pair: int = 0) -> FigureResult:
        """Step 4: ``image_similarity`` -> Eq. (1) ``S = sum(1 - d*s) / sqrt(na*nb)``, shown
        with every reciprocal pair's term; ``s`` is the shape penalty of Eq. (2).

        Raises:
            RuntimeError: the per-pair terms do not add up to ``image_similarity`` (would mean
                the tour and the library disagree).
        """
        from ..matching import cosine_distance, image_similarity, shape_penalty
        from ..viz import plot_pair_terms

        desc, boxes, m = (self._tour_descriptors(pair), self._tour_boxes(pair),
                          self._tour_matches(pair))
        dq, dr, bq, br = desc["query"], desc["reference"], boxes["query"], boxes["reference"]
        sim = image_similarity(dq, bq, dr, br)
        d = cosine_distance(dq, dr)[m[:, 0], m[:, 1]]
        s = shape_penalty(bq, br)[m[:, 0], m[:, 1]]
        terms = 1.0 - d * s
        from_terms = float(terms.sum() / math.sqrt(len(dq) * len(dr)))
        if not math.isclose(from_terms, sim, rel_tol=1e-6, abs_tol=1e-9):
            raise RuntimeError(f"tour: pair terms give S = {from_terms!r} but image_similarity "
                               f"returned {sim!r}")
        table = pd.DataFrame({"query landmark": m[:, 0], "reference landmark": m[:, 1],
                              "d": d, "s (Eq. 2)": s, "1 - d*s": terms})
        fig = plot_pair_terms(d, s, len(dq), len(dr), sim,
                              title=f"step 4, image_similarity (Eq. 1): "
                                    f"{self._tour_caption(pair)}")
        return self.save(fig, "tour4_image_similarity", table=table)
