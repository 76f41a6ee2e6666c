"""Landmark stage: the boxes of every image for a landmark scheme, cached per image in
``landmarks/<scheme slug>/<image key>.npz`` (Edge Box schemes share one entry of 1,000 candidates
per image and edge model; size-only schemes such as the dense grid are computed on the fly)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..cache import SIDES, atomic_savez, load_npz, n_images
from ..checks import check_boxes
from ..paper import N_CANDIDATES
from ..utils import cache_dir, code_version, config_slug, logger, progress
from .edge_boxes import edge_boxes, edge_model_id
from .schemes import CandidateScheme, SizeScheme, scheme_identity

__all__ = ["edge_box_candidates", "extract_landmarks", "landmarks_for_image"]


def _check_boxes_entry(arrays: dict) -> str | None:
    b = arrays["boxes"]
    if b.ndim != 2 or b.shape[1] != 4 or not np.isfinite(b).all():
        return f"boxes of shape {b.shape}, expected (K, 4) finite"
    return None


def _cached_boxes(
    stage: str, params: dict[str, Any], dataset, side: str, i: int, compute, overwrite: bool
) -> tuple[np.ndarray, float]:
    """``(boxes (K, 4), seconds)`` of one image from ``landmarks/<stage slug>/``, or computed
    by ``compute(image) -> boxes`` (timed) and stored."""
    slug = config_slug(stage, params)
    key = dataset.image_key(side, i)
    path = cache_dir("landmarks", slug) / f"{key}.npz"
    identity = f"{stage} {slug} {key}"
    cached = (
        None
        if overwrite
        else load_npz(path, ("boxes", "seconds"), identity=identity, check=_check_boxes_entry)
    )
    if cached is not None:
        return cached["boxes"].astype(np.float64).reshape(-1, 4), float(cached["seconds"])
    image = dataset.load_image(side, i)
    t0 = time.perf_counter()
    boxes = compute(image)
    seconds = time.perf_counter() - t0
    atomic_savez(path, identity=identity, boxes=boxes, seconds=np.array(seconds))
    return boxes, seconds


def edge_box_candidates(
    dataset,
    side: str,
    i: int,
    n_candidates: int = N_CANDIDATES,
    overwrite: bool = False,
    edge_model: str | None = None,
) -> tuple[np.ndarray, float]:
    """The ``n_candidates`` Edge Box proposals of one image, cached.

    Args:
        edge_model: :func:`~vpr_core.landmarks.edge_boxes.edge_model_id` (None: computed here).

    Returns:
        ``(boxes (K, 4), seconds)``: proposals in proposal order (descending score) and the
        seconds the extraction took when it was computed.
    """
    params = {
        "n_candidates": int(n_candidates),
        "edge_model": edge_model or edge_model_id(),
        "code": code_version("landmarks"),
    }

    def compute(image: np.ndarray) -> np.ndarray:
        res = edge_boxes(image, max_boxes=n_candidates)
        return np.asarray(res.boxes, dtype=np.float64).reshape(-1, 4)

    return _cached_boxes("edge_boxes", params, dataset, side, i, compute, overwrite)


def _image_name(dataset, side: str, i: int) -> str:
    paths = dataset.query_paths if side == "query" else dataset.reference_paths
    return f"{side} image {i} ({paths[i]})"


def landmarks_for_image(
    scheme: Any, dataset, side: str, i: int, fresh: bool = False, edge_model: str | None = None
) -> tuple[np.ndarray, float]:
    """Landmarks of one image for a landmark scheme.

    Edge Box schemes (:class:`~vpr_core.landmarks.schemes.CandidateScheme`) select from the
    image's cached candidates; size-only schemes are computed from the image size; any other
    scheme's ``boxes(image)`` is cached under its class, field values and version
    (:func:`~vpr_core.landmarks.schemes.scheme_identity`), or computed on every call when its
    class declares no version (a user's code may read globals that changed). A scheme that
    ``fresh=True`` computes the boxes again (and rewrites their cache entry), so the seconds
    are measured now.

    Args:
        scheme: a landmark scheme (:mod:`vpr_core.landmarks.schemes` or a user's).
        edge_model: :func:`~vpr_core.landmarks.edge_boxes.edge_model_id` (None: computed here).

    Returns:
        ``(boxes (K, 4), seconds)``: seconds is the landmark-extraction cost of this image.
    """
    if isinstance(scheme, SizeScheme):
        t0 = time.perf_counter()
        boxes = scheme.for_size(dataset.image_size(side, i))
        return np.asarray(boxes, dtype=np.float64).reshape(-1, 4), time.perf_counter() - t0
    if not isinstance(scheme, CandidateScheme):
        ident = scheme_identity(scheme)

        def compute(image: np.ndarray) -> np.ndarray:
            return _user_boxes(scheme, image, dataset, side, i)

        if ident["version"] is None:
            image = dataset.load_image(side, i)
            t0 = time.perf_counter()
            return compute(image), time.perf_counter() - t0
        return _cached_boxes(ident["scheme"], ident, dataset, side, i, compute, fresh)
    cands, seconds = edge_box_candidates(
        dataset, side, i, scheme.n_candidates, overwrite=fresh, edge_model=edge_model
    )
    t0 = time.perf_counter()
    boxes = np.asarray(scheme.select(cands, dataset.image_size(side, i)), dtype=np.float64)
    seconds += time.perf_counter() - t0
    return boxes.reshape(-1, 4), seconds


def _user_boxes(scheme: Any, image: np.ndarray, dataset, side: str, i: int) -> np.ndarray:
    """A user scheme's boxes of one image, checked once: finite ``(K, 4)``, positive width and
    height, each overlapping the image (the message names the scheme class and the image)."""
    where = f"{type(scheme).__qualname__}.boxes() on {_image_name(dataset, side, i)}"
    try:
        boxes = check_boxes(scheme.boxes(image), positive=True)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None
    h, w = image.shape[:2]
    x, y, bw, bh = boxes.T
    outside = np.flatnonzero((x >= w) | (y >= h) | (x + bw <= 0) | (y + bh <= 0))
    if outside.size:
        raise ValueError(
            f"{where}: boxes outside the {w} x {h} image, bad rows: {outside[:10]} (boxes are "
            "(x, y, w, h) in pixels)"
        )
    return boxes


def extract_landmarks(scheme: Any, dataset) -> dict[str, Any]:
    """Landmarks of every image of a dataset for a landmark scheme.

    Returns:
        ``{"query": [ (K_i, 4) ... ], "reference": [...], "seconds": {"query": [...], ...}}``.
    """
    edge_model = edge_model_id() if isinstance(scheme, CandidateScheme) else None
    out: dict[str, Any] = {"seconds": {}}
    for side in SIDES:
        boxes, secs = [], []
        for i in progress(range(n_images(dataset, side)), desc=f"landmarks {side}"):
            b, s = landmarks_for_image(scheme, dataset, side, i, edge_model=edge_model)
            boxes.append(b)
            secs.append(s)
        out[side] = boxes
        out["seconds"][side] = secs
    n = getattr(scheme, "n", None)
    if isinstance(scheme, CandidateScheme) and n is not None:
        _report_short(type(scheme).__name__, n, dataset, out)
    return out


def _report_short(name: str, n: int, dataset, out: dict[str, Any], shown: int = 3) -> None:
    """One warning for all images where an Edge Box scheme found fewer than its ``n`` landmarks
    (small or plain images give few candidates), the ``shown`` with the fewest named."""
    short = [(side, i, len(b)) for side in SIDES for i, b in enumerate(out[side]) if len(b) < n]
    short.sort(key=lambda item: item[2])  # stable: sides and images in order within a count
    if not short:
        return
    counts = [k for _, _, k in short]
    total = sum(len(out[side]) for side in SIDES)
    spread = (
        f" ({min(counts)} to {max(counts)}, median {np.median(counts):g})" if counts[1:] else ""
    )
    named = "; ".join(f"{_image_name(dataset, side, i)}: {k}" for side, i, k in short[:shown])
    more = f"; {len(short) - shown} more" if len(short) > shown else ""
    logger.warning(
        "%s gave fewer than the %d landmarks asked for %d of %d images%s: %s%s",
        name,
        n,
        len(short),
        total,
        spread,
        named,
        more,
    )
