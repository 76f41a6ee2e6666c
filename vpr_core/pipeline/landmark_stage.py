"""Landmark stage: the boxes of every image for a method's landmark config, cached.

``landmarks/edge_boxes-<hash>/<image key>.npz`` holds the 1,000 Edge Box candidates of one image
with their scores, the edge-map source and the seconds it took. Every Edge Box scheme
(classical, Algorithms 1-3) selects from these, so candidates are computed once per image.
Dense grids and the whole-image box are computed on the fly (they cost microseconds).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .. import landmarks as lm
from .. import settings
from ..methods import EDGE_BOX_SCHEMES
from ..paper import N_CANDIDATES
from ..utils import cache_dir, code_version, config_slug, logger, progress
from .cache import SIDES, atomic_savez, load_npz, n_images

__all__ = ["LANDMARK_SCHEMES", "edge_box_candidates", "extract_landmarks", "landmarks_for_image"]

#: Landmark schemes the pipeline knows.
LANDMARK_SCHEMES = EDGE_BOX_SCHEMES + ("dense", "whole_image")


def _check_boxes_entry(arrays: dict) -> str | None:
    b = arrays["boxes"]
    if b.ndim != 2 or b.shape[1] != 4 or not np.isfinite(b).all():
        return f"boxes of shape {b.shape}, expected (K, 4) finite"
    return None


def edge_box_candidates(
    dataset, side: str, i: int, n_candidates: int = N_CANDIDATES, overwrite: bool = False
) -> tuple[np.ndarray, float]:
    """The ``n_candidates`` Edge Box proposals of one image, cached.

    Returns:
        ``(boxes (K, 4), seconds)``: proposals in proposal order (descending score) and the
        seconds the extraction took when it was computed.
    """
    params = {
        "n_candidates": int(n_candidates),
        "sed": settings.sed_model() or "",
        "code": code_version("landmarks"),
    }
    folder = cache_dir("landmarks", config_slug("edge_boxes", params))
    key = dataset.image_key(side, i)
    path = folder / f"{key}.npz"
    identity = f"edge_boxes {config_slug('edge_boxes', params)} {key}"
    cached = (
        None
        if overwrite
        else load_npz(path, ("boxes", "seconds"), identity=identity, check=_check_boxes_entry)
    )
    if cached is not None:
        return cached["boxes"].astype(np.float64).reshape(-1, 4), float(cached["seconds"])
    image = dataset.load_image(side, i)
    t0 = time.perf_counter()
    res = lm.edge_boxes(image, max_boxes=n_candidates)
    seconds = time.perf_counter() - t0
    atomic_savez(
        path,
        identity=identity,
        boxes=np.asarray(res.boxes, dtype=np.float64).reshape(-1, 4),
        scores=np.asarray(res.scores, dtype=np.float64),
        edge_source=np.array(res.edge_source),
        seconds=np.array(seconds),
    )
    return np.asarray(res.boxes, dtype=np.float64).reshape(-1, 4), seconds


def _image_name(dataset, side: str, i: int) -> str:
    paths = dataset.query_paths if side == "query" else dataset.reference_paths
    return f"{side} image {i} ({paths[i]})"


def landmarks_for_image(
    conf: dict[str, Any], dataset, side: str, i: int, fresh: bool = False
) -> tuple[np.ndarray, float]:
    """Landmarks of one image for a method's landmark config.

    A scheme that yields fewer landmarks than asked logs a warning naming the image.
    ``fresh=True`` computes the Edge Box candidates again (and rewrites their cache entry)
    instead of reading them, so the seconds are measured now (Table 5).

    Returns:
        ``(boxes (K, 4), seconds)`` where seconds is the landmark-extraction cost of this image
        (Edge Box time for proposal schemes, the grid computation for ``dense``).
    """
    lconf = conf.get("landmarks", conf)
    scheme = lconf["scheme"]
    size = dataset.image_size(side, i)
    t0 = time.perf_counter()
    if scheme == "dense":
        boxes = lm.dense_sampling(size, scales=lconf["scales"], per_scale=lconf["per_scale"])
        return np.asarray(boxes, dtype=np.float64), time.perf_counter() - t0
    if scheme == "whole_image":
        h, w = size
        return np.array([[0.0, 0.0, float(w), float(h)]]), time.perf_counter() - t0
    if scheme not in EDGE_BOX_SCHEMES:
        raise ValueError(
            f"Unknown landmark scheme {scheme!r}; valid: {', '.join(LANDMARK_SCHEMES)}."
        )
    cands, seconds = edge_box_candidates(
        dataset, side, i, lconf.get("n_candidates", N_CANDIDATES), overwrite=fresh
    )
    options = {k: lconf[k] for k in ("n", "min_index", "order", "iou_threshold") if k in lconf}
    t0 = time.perf_counter()
    boxes = np.asarray(
        lm.select_from_candidates(cands, size, scheme, **options), dtype=np.float64
    ).reshape(-1, 4)
    seconds += time.perf_counter() - t0
    n = lconf.get("n")
    if n is not None and len(boxes) < n:
        logger.warning(
            "%s gave %d of the %d landmarks asked for %s (%d Edge Box candidates)",
            scheme,
            len(boxes),
            n,
            _image_name(dataset, side, i),
            len(cands),
        )
    return boxes, seconds


def extract_landmarks(conf: dict[str, Any], dataset) -> dict[str, Any]:
    """Landmarks of every image of a dataset.

    Returns:
        ``{"query": [ (K_i, 4) ... ], "reference": [...], "seconds": {"query": [...], ...}}``.
    """
    out: dict[str, Any] = {"seconds": {}}
    for side in SIDES:
        boxes, secs = [], []
        for i in progress(range(n_images(dataset, side)), desc=f"landmarks {side}"):
            b, s = landmarks_for_image(conf, dataset, side, i)
            boxes.append(b)
            secs.append(s)
        out[side] = boxes
        out["seconds"][side] = secs
    return out
