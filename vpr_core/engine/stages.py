"""Pipeline glue of the engine: whole-image boxes, the shortlist stage and the matching stage.

:func:`vpr_core.pipeline.run_method` calls these so that its own code stays the exhaustive,
in-process path:

* :func:`with_whole_image_boxes` appends the box ``(0, 0, W, H)`` to every image's landmarks, so
  the whole-image descriptor of a shortlist is computed in the same encoder call as the
  landmarks (one backbone pass per image with ``pooling="roi"``) and cached in the same
  per-image store; :func:`split_whole_image` separates them again.
* :func:`match` runs Eq. (1) exhaustively, or on each query's shortlist, in-process or on a Dask
  client, and returns the ``(Nq, Nr)`` matrix (NaN off the shortlist).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..paper import SOFT_NMS_SIGMA
from ..utils import logger
from .blocks import similarity_blocks_distributed, similarity_pairs_distributed
from .shortlist import rerank, shortlist_pairs

__all__ = ["match", "split_whole_image", "whole_image_box", "with_whole_image_boxes"]

SIDES = ("query", "reference")


def whole_image_box(image_size: tuple[int, int]) -> np.ndarray:
    """``(1, 4)`` float64 box ``(0, 0, W, H)`` of an image of size ``(H, W)``."""
    h, w = image_size
    return np.array([[0.0, 0.0, float(w), float(h)]])


def with_whole_image_boxes(boxes: dict[str, Any], dataset) -> dict[str, Any]:
    """Landmarks with the whole-image box appended as each image's last row.

    Args:
        boxes: ``{"query": [(K_i, 4)], "reference": [...], ...}`` (other keys are kept).
        dataset: the :class:`~vpr_core.datasets.PlaceDataset` the boxes belong to.

    Returns:
        The same dict layout with ``(K_i + 1, 4)`` arrays.
    """
    out = dict(boxes)
    for side in SIDES:
        out[side] = [np.concatenate([np.asarray(b, dtype=np.float64).reshape(-1, 4),
                                     whole_image_box(dataset.image_size(side, i))])
                     for i, b in enumerate(boxes[side])]
    return out


def split_whole_image(feats: dict[str, Any]) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Undo :func:`with_whole_image_boxes` on descriptors.

    Args:
        feats: ``{"query": [(K_i + 1, D)], "reference": [...], "seconds": ...}``.

    Returns:
        ``(landmark feats in the same layout with (K_i, D) arrays, {side: (N, D) whole-image
        descriptors})``.
    """
    out = dict(feats)
    glob = {}
    for side in SIDES:
        out[side] = [d[:-1] for d in feats[side]]
        glob[side] = np.stack([d[-1] for d in feats[side]]).astype(np.float32)
    return out, glob


def match(boxes: dict[str, Any], feats: dict[str, Any], soft_nms_iou: float | None = None,
          sigma: float = SOFT_NMS_SIGMA, shortlist: int | None = None,
          global_desc: dict[str, np.ndarray] | None = None, client=None
          ) -> tuple[np.ndarray, dict[str, float]]:
    """Eq. (1) similarities, exhaustive or on each query's shortlist, in-process or on Dask.

    Args:
        boxes: ``{"query": [(K_i, 4)], "reference": [...]}`` landmarks.
        feats: ``{"query": [(K_i, D)], "reference": [...]}`` descriptors.
        soft_nms_iou, sigma: Algorithm 4 settings.
        shortlist: None (exhaustive) or k: Eq. (1) only on each query's top-k references by
            the cosine of ``global_desc``.
        global_desc: ``{"query": (Nq, D'), "reference": (Nr, D')}`` whole-image descriptors
            (needed with ``shortlist``).
        client: a ``dask.distributed.Client`` or None (in-process).

    Returns:
        ``(similarity (Nq, Nr) float64, info)``: NaN off the shortlist; ``info`` has
        ``pairs`` (image pairs scored by Eq. (1)), ``shortlist_s`` (global ranking seconds) and
        ``matching_s`` (Eq. (1) seconds).
    """
    args = (feats["query"], boxes["query"], feats["reference"], boxes["reference"])
    nq, nr = len(feats["query"]), len(feats["reference"])
    if shortlist is None:
        t0 = time.perf_counter()
        sim = similarity_blocks_distributed(client, *args, soft_nms_iou=soft_nms_iou,
                                            sigma=sigma)
        return sim, {"pairs": float(nq * nr), "shortlist_s": 0.0,
                     "matching_s": time.perf_counter() - t0}
    if global_desc is None:
        raise ValueError("shortlist=k needs the whole-image descriptors (global_desc)")
    t0 = time.perf_counter()
    pairs, _ = shortlist_pairs(global_desc["query"], global_desc["reference"], shortlist)
    t1 = time.perf_counter()
    vals = similarity_pairs_distributed(client, *args, pairs, soft_nms_iou=soft_nms_iou,
                                        sigma=sigma)
    sim = rerank(vals, pairs, nq, nr)
    t2 = time.perf_counter()
    logger.info("shortlist k=%d: Eq. (1) on %d of %d pairs (%.1f s ranking, %.1f s matching)",
                shortlist, len(pairs), nq * nr, t1 - t0, t2 - t1)
    return sim, {"pairs": float(len(pairs)), "shortlist_s": t1 - t0, "matching_s": t2 - t1}
