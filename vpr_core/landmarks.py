"""Landmark proposals: dense sampling, Edge Boxes, Table-1 scales, Algorithms 1-3, IoU.

Boxes are ``np.ndarray (K, 4)`` float64 ``(x, y, w, h)`` in pixels (continuous coordinates: a box
covers ``[x, x + w) x [y, y + h)``; area ``w * h``, no ``+1``), always in *proposal order* (for
Edge Boxes: descending objectness score). ``image_size`` is always ``(H, W)``.

Contents (paper section in brackets):

- :func:`dense_sampling` -- the proposed dense landmarks (Sec. 4, Fig. 9, Tables 2-4).
- :func:`edge_boxes` -- OpenCV-contrib ``ximgproc`` Edge Boxes, the classical proposals (Sec. 2.1).
- :func:`normalized_scale`, :func:`scale_index`, :data:`SCALE_EDGES` -- Eq. (3) and Table 1.
- :func:`select_min_scale` (Algorithm 1), :func:`select_scale_priority` (Algorithm 2),
  :func:`reduce_overlap` (Algorithm 3), :func:`box_iou`.
- :func:`landmark_coverage` (Fig. 14), :func:`scale_histogram` (Fig. 6).
- :data:`LANDMARK_SCHEMES`, :func:`get_landmark_scheme`, :func:`generate_landmarks` -- landmark
  schemes looked up by name.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .utils import logger

__all__ = [
    "EDGE_BOXES_DEFAULTS",
    "LANDMARK_SCHEMES",
    "N_SCALES",
    "SCALE_EDGES",
    "SCALE_LABELS",
    "SCALE_RANGES",
    "SCALE_RANGE_LABELS",
    "SCHEME_DEFAULTS",
    "EdgeBoxes",
    "box_iou",
    "dense_sampling",
    "edge_boxes",
    "generate_landmarks",
    "get_landmark_scheme",
    "landmark_coverage",
    "normalized_scale",
    "reduce_overlap",
    "scale_histogram",
    "scale_index",
    "select_from_candidates",
    "select_min_scale",
    "select_scale_priority",
]

# ------------------------------------------------------------------------------------------
# Table 1: nine landmark scales
# ------------------------------------------------------------------------------------------

#: Inner bin edges of Table 1 (normalized scale = box area / image area). Lower edge inclusive.
SCALE_EDGES: tuple[float, ...] = (0.02, 0.05, 0.09, 0.14, 0.23, 0.34, 0.5, 0.72)
#: Number of Table-1 scales (indices 1..9).
N_SCALES: int = 9
#: ``(low, high)`` normalized-scale range of Scale 1..9 (``SCALE_RANGES[i - 1]`` for Scale i).
SCALE_RANGES: tuple[tuple[float, float], ...] = tuple(
    zip((0.0,) + SCALE_EDGES, SCALE_EDGES + (1.0,))
)
#: Plot labels ``"Scale 1"`` .. ``"Scale 9"`` (``SCALE_LABELS[i - 1]`` for Scale i).
SCALE_LABELS: tuple[str, ...] = tuple(f"Scale {i}" for i in range(1, N_SCALES + 1))
#: Range labels as in Table 1, e.g. ``"0.02~0.05"``.
SCALE_RANGE_LABELS: tuple[str, ...] = tuple(f"{lo:g}~{hi:g}" for lo, hi in SCALE_RANGES)


# ------------------------------------------------------------------------------------------
# input checks
# ------------------------------------------------------------------------------------------


def _check_image_size(image_size: Any, name: str = "image_size") -> tuple[int, int]:
    """Validate ``(H, W)`` (a 3-tuple ``image.shape`` is accepted too) and return ints."""
    if isinstance(image_size, np.ndarray) and image_size.ndim >= 2:
        raise ValueError(
            f"{name} must be (H, W), got an array of shape {image_size.shape}; "
            "pass image.shape[:2]"
        )
    try:
        seq = tuple(image_size)
    except TypeError:
        raise ValueError(f"{name} must be a (H, W) pair, got {image_size!r}") from None
    if len(seq) not in (2, 3):
        raise ValueError(f"{name} must be a (H, W) pair, got {image_size!r}")
    h, w = seq[0], seq[1]
    try:
        hi, wi = int(h), int(w)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must hold integers (H, W), got {image_size!r}") from None
    if hi != h or wi != w or hi <= 0 or wi <= 0:
        raise ValueError(f"{name} must be positive integers (H, W), got {image_size!r}")
    return hi, wi


def _check_boxes(boxes: Any, name: str = "boxes") -> np.ndarray:
    """Return ``boxes`` as float64 ``(K, 4)``; raise a clear ValueError otherwise."""
    arr = np.asarray(boxes, dtype=np.float64)
    if arr.size == 0:
        return np.zeros((0, 4), dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise ValueError(f"{name} must have shape (K, 4) as (x, y, w, h), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf")
    if np.any(arr[:, 2:] < 0):
        raise ValueError(f"{name} has negative width or height (expected (x, y, w, h))")
    return arr


def _check_n(n: Any, name: str = "n") -> int:
    if isinstance(n, bool) or int(n) != n or n < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {n!r}")
    return int(n)


def _check_image(image: Any) -> np.ndarray:
    """Validate an ``(H, W, 3)`` uint8 RGB (or ``(H, W)`` uint8 grayscale) image."""
    if not isinstance(image, np.ndarray):
        raise TypeError(f"image must be a numpy array (H, W, 3) uint8 RGB, got {type(image)}")
    if image.dtype != np.uint8:
        raise ValueError(
            f"image must be uint8 (H, W, 3) RGB or (H, W) grayscale, got dtype {image.dtype}"
        )
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)):
        raise ValueError(
            f"image must have shape (H, W, 3) RGB or (H, W) grayscale, got {image.shape}"
        )
    if image.shape[0] < 2 or image.shape[1] < 2:
        raise ValueError(f"image is too small: {image.shape}")
    return image


# ------------------------------------------------------------------------------------------
# dense sampling (Section 4)
# ------------------------------------------------------------------------------------------


def _grid_side(count: Any) -> int:
    if isinstance(count, bool) or int(count) != count or count < 1:
        raise ValueError(f"per_scale must be a positive perfect square (g*g), got {count!r}")
    g = math.isqrt(int(count))
    if g * g != int(count):
        raise ValueError(
            f"per_scale={count} is not a perfect square: dense sampling puts g*g boxes on a "
            f"g x g grid (e.g. 9, 16, 25, 36, 49)"
        )
    return g


def dense_sampling(
    image_size: Sequence[int],
    scales: Sequence[float] = (0.16, 0.25, 0.36, 0.49),
    per_scale: int | Sequence[int] = 25,
) -> np.ndarray:
    """Dense multi-scale landmarks (paper Section 4, Fig. 9).

    For each normalized scale (area ratio) ``a`` the box is ``w = sqrt(a) * W``,
    ``h = sqrt(a) * H`` (image aspect kept). ``g * g`` boxes are laid on a ``g x g`` grid, evenly
    spaced: the first at the top-left corner ``(0, 0)``, the last flush with the far edges
    (``x = W - w``, ``y = H - h``); with ``g = 1`` the box is centred.

    Args:
        image_size: ``(H, W)`` in pixels.
        scales: area ratios in ``(0, 1]``, one per scale level.
        per_scale: boxes per scale, a perfect square; an int (same for every scale) or one count
            per scale (e.g. Table 3 Set 2: ``(36, 25, 25, 16)``).

    Returns:
        ``(K, 4)`` float64 ``(x, y, w, h)``, ``K = sum(per_scale)``; ordered scale by scale, then
        row by row (increasing ``y``), and within a row by increasing ``x``.

    Raises:
        ValueError: bad ``image_size``, a scale outside ``(0, 1]``, a non-square count or a
            ``per_scale`` sequence whose length differs from ``scales``.
    """
    H, W = _check_image_size(image_size)
    scales_arr = np.atleast_1d(np.asarray(scales, dtype=np.float64))
    if scales_arr.ndim != 1 or scales_arr.size == 0:
        raise ValueError(f"scales must be a non-empty 1-D sequence of area ratios, got {scales!r}")
    if not np.all(np.isfinite(scales_arr)) or np.any(scales_arr <= 0) or np.any(scales_arr > 1):
        raise ValueError(f"every scale (area ratio) must lie in (0, 1], got {list(scales_arr)}")
    if np.ndim(per_scale) == 0:
        counts = [per_scale] * scales_arr.size
    else:
        counts = list(per_scale)
        if len(counts) != scales_arr.size:
            raise ValueError(
                f"per_scale has {len(counts)} counts but there are {scales_arr.size} scales; "
                "give one count per scale or a single int"
            )
    out = []
    for a, count in zip(scales_arr, counts):
        g = _grid_side(count)
        s = math.sqrt(float(a))
        w, h = s * W, s * H
        if g == 1:
            xs = np.array([(W - w) / 2.0])
            ys = np.array([(H - h) / 2.0])
        else:
            xs = np.arange(g) * ((W - w) / (g - 1))
            ys = np.arange(g) * ((H - h) / (g - 1))
        yy, xx = np.meshgrid(ys, xs, indexing="ij")  # row-major: y outer, x inner
        block = np.empty((g * g, 4), dtype=np.float64)
        block[:, 0] = xx.ravel()
        block[:, 1] = yy.ravel()
        block[:, 2] = w
        block[:, 3] = h
        out.append(block)
    return np.concatenate(out, axis=0)


# ------------------------------------------------------------------------------------------
# Edge Boxes
# ------------------------------------------------------------------------------------------

#: Defaults of the ``**params`` of :func:`edge_boxes`. ``alpha``..``kappa`` are the parameters of
#: ``cv2.ximgproc.createEdgeBoxes`` (snake_case); ``min_score`` is lowered from OpenCV's 0.01 so
#: that 1,000 candidates are available for the selection schemes. ``blur_sigma`` and
#: ``edge_nms`` only concern the gradient edge map (used when no structured-edge model is given).
EDGE_BOXES_DEFAULTS: dict[str, float | bool] = {
    "alpha": 0.65,
    "beta": 0.75,
    "eta": 1.0,
    "min_score": 0.001,
    "edge_min_mag": 0.1,
    "edge_merge_thr": 0.5,
    "cluster_min_mag": 0.5,
    "max_aspect_ratio": 3.0,
    "min_box_area": 1000.0,
    "gamma": 2.0,
    "kappa": 1.5,
    "blur_sigma": 2.0,
    "edge_nms": True,
}

_SED_CACHE: dict[str, Any] = {}
_LOGGED_SOURCES: set[str] = set()


@dataclass
class EdgeBoxes:
    """Result of :func:`edge_boxes`.

    Attributes:
        boxes: ``(K, 4)`` float64 ``(x, y, w, h)`` in pixels, in proposal order (descending score).
        scores: ``(K,)`` float64 Edge Boxes objectness scores.
        edge_source: ``"structured"`` (structured-edge model) or ``"gradient"`` (gradient map).
    """

    boxes: np.ndarray
    scores: np.ndarray
    edge_source: str

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        return self.boxes if dtype is None else self.boxes.astype(dtype)

    def __len__(self) -> int:
        return int(self.boxes.shape[0])


def _missing_model_message(path: Path) -> str:
    return (
        f"structured-edge model file not found: {path}. Download 'model.yml.gz' from opencv_extra "
        "(https://github.com/opencv/opencv_extra/raw/4.x/testdata/cv/ximgproc/model.yml.gz) and "
        "pass its path as model=... or set VPR_SED_MODEL; or pass model=None (with VPR_SED_MODEL "
        "unset) to use the gradient edge map."
    )


def _resolve_model(model: str | os.PathLike | None) -> Path | None:
    """The structured-edge model path to use, or None for the gradient edge map."""
    if model is not None and str(model).lower() == "gradient":
        return None
    if model is None:
        env = os.environ.get("VPR_SED_MODEL")
        if not env:
            return None
        model = env
    path = Path(model).expanduser()
    if not path.is_file():
        raise FileNotFoundError(_missing_model_message(path))
    return path


def _structured_edges(image: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray]:
    import cv2

    key = str(path.resolve())
    sed = _SED_CACHE.get(key)
    if sed is None:
        sed = cv2.ximgproc.createStructuredEdgeDetection(key)
        _SED_CACHE[key] = sed
    rgb = image if image.ndim == 3 else np.repeat(image[:, :, None], 3, axis=2)
    edges = sed.detectEdges(rgb.astype(np.float32) / 255.0)
    orient = sed.computeOrientation(edges)
    edges = sed.edgesNms(edges, orient, 2, 0, 1, True)
    return edges.astype(np.float32), orient.astype(np.float32)


def _gradient_edges(
    image: np.ndarray, blur_sigma: float = 2.0, nms: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Gradient edge map in ``[0, 1]`` and edge orientation map, both ``(H, W)`` float32.

    Scharr gradient magnitude of the lightly blurred float32 grayscale image, divided by a robust
    maximum (99th percentile of the non-flat pixels) and clipped to ``[0, 1]``; optionally thinned
    by non-maximum suppression across the edge. The orientation is the gradient (edge-normal)
    direction modulo pi, the convention of ``StructuredEdgeDetection.computeOrientation``.
    """
    import cv2

    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    g = gray.astype(np.float32) / 255.0
    if blur_sigma and blur_sigma > 0:
        g = cv2.GaussianBlur(g, (0, 0), float(blur_sigma))
    gx = cv2.Scharr(g, cv2.CV_32F, 1, 0)
    gy = cv2.Scharr(g, cv2.CV_32F, 0, 1)
    mag = np.sqrt(gx * gx + gy * gy)
    peak = float(mag.max())
    if peak <= 0:
        return np.zeros_like(mag), np.zeros_like(mag)
    active = mag[mag > 0.01 * peak]
    scale = float(np.percentile(active, 99)) if active.size else peak
    mag = np.clip(mag / max(scale, 1e-12), 0.0, 1.0)
    orient = np.mod(np.arctan2(gy, gx), np.pi).astype(np.float32)
    if nms:
        q = np.rint(orient / (np.pi / 4)).astype(np.int64) % 4
        H, W = mag.shape
        pad = np.pad(mag, 1)

        def shifted(dy: int, dx: int) -> np.ndarray:
            return pad[1 + dy : 1 + dy + H, 1 + dx : 1 + dx + W]

        # neighbours along the edge normal for angle bins 0, 45, 90, 135 degrees
        neighbours = (((0, 1), (0, -1)), ((1, 1), (-1, -1)), ((1, 0), (-1, 0)), ((1, -1), (-1, 1)))
        keep = np.zeros(mag.shape, dtype=bool)
        for k, (a, b) in enumerate(neighbours):
            keep |= (q == k) & (mag >= shifted(*a)) & (mag >= shifted(*b))
        mag = np.where(keep, mag, 0.0)
    return mag.astype(np.float32), orient


def edge_boxes(
    image: np.ndarray,
    max_boxes: int = 100,
    model: str | os.PathLike | None = None,
    **params: Any,
) -> EdgeBoxes:
    """Edge Boxes object proposals (Zitnick & Dollar, ECCV 2014) via OpenCV-contrib ``ximgproc``.

    The edge map is the structured-edge detector's (``cv2.ximgproc.createStructuredEdgeDetection``)
    when a model file is given (``model=`` path, else ``$VPR_SED_MODEL``), otherwise a gradient
    edge map (Scharr magnitude, non-maximum suppressed). ``.edge_source`` records which; it is
    logged once per source. ``model="gradient"`` forces the gradient map even when
    ``VPR_SED_MODEL`` is set. The result is deterministic.

    Args:
        image: ``(H, W, 3)`` uint8 RGB (or ``(H, W)`` uint8 grayscale).
        max_boxes: maximum number of proposals (OpenCV ``maxBoxes``).
        model: path to the structured-edge model ``model.yml.gz`` (opencv_extra), ``None`` (use
            ``$VPR_SED_MODEL`` if set, else the gradient map) or ``"gradient"``.
        **params: overrides of :data:`EDGE_BOXES_DEFAULTS` (``alpha``, ``beta``, ``eta``,
            ``min_score``, ``edge_min_mag``, ``edge_merge_thr``, ``cluster_min_mag``,
            ``max_aspect_ratio``, ``min_box_area``, ``gamma``, ``kappa``, ``blur_sigma``,
            ``edge_nms``).

    Returns:
        :class:`EdgeBoxes` with ``.boxes (K, 4)`` float64 ``(x, y, w, h)`` (0-based pixels, inside
        the image), ``.scores (K,)`` in descending order, ``.edge_source``; ``K <= max_boxes``.

    Raises:
        ValueError / TypeError: bad image shape or dtype, bad ``max_boxes``, unknown params.
        FileNotFoundError: the model file does not exist (message says how to get it).
    """
    import cv2

    image = _check_image(image)
    max_boxes = _check_n(max_boxes, "max_boxes")
    unknown = set(params) - set(EDGE_BOXES_DEFAULTS)
    if unknown:
        raise ValueError(
            f"unknown edge_boxes parameter(s) {sorted(unknown)}; valid: {sorted(EDGE_BOXES_DEFAULTS)}"
        )
    p = {**EDGE_BOXES_DEFAULTS, **params}
    model_path = _resolve_model(model)
    H, W = image.shape[:2]
    if max_boxes == 0:
        source = "structured" if model_path is not None else "gradient"
        return EdgeBoxes(np.zeros((0, 4)), np.zeros(0), source)

    if model_path is not None:
        edges, orient = _structured_edges(image, model_path)
        source = "structured"
    else:
        edges, orient = _gradient_edges(image, float(p["blur_sigma"]), bool(p["edge_nms"]))
        source = "gradient"
    if source not in _LOGGED_SOURCES:
        _LOGGED_SOURCES.add(source)
        detail = f"structured-edge model {model_path}" if model_path else "gradient (Scharr) edge map"
        logger.info("edge_boxes: using %s", detail)

    eb = cv2.ximgproc.createEdgeBoxes(
        alpha=float(p["alpha"]),
        beta=float(p["beta"]),
        eta=float(p["eta"]),
        minScore=float(p["min_score"]),
        maxBoxes=int(max_boxes),
        edgeMinMag=float(p["edge_min_mag"]),
        edgeMergeThr=float(p["edge_merge_thr"]),
        clusterMinMag=float(p["cluster_min_mag"]),
        maxAspectRatio=float(p["max_aspect_ratio"]),
        minBoxArea=float(p["min_box_area"]),
        gamma=float(p["gamma"]),
        kappa=float(p["kappa"]),
    )
    result = eb.getBoundingBoxes(np.ascontiguousarray(edges), np.ascontiguousarray(orient))
    if isinstance(result, tuple):  # OpenCV >= 4.5: (boxes, scores); older: boxes only
        raw_boxes, raw_scores = result[0], (result[1] if len(result) > 1 else None)
    else:
        raw_boxes, raw_scores = result, None
    boxes = np.asarray(raw_boxes, dtype=np.float64).reshape(-1, 4)
    if raw_scores is None or np.asarray(raw_scores).size != boxes.shape[0]:
        # no scores from this OpenCV build: keep the (already score-sorted) order
        scores = np.linspace(1.0, 0.0, boxes.shape[0], endpoint=False)
    else:
        scores = np.asarray(raw_scores, dtype=np.float64).ravel()
    # OpenCV reports MATLAB-style 1-based corners (x + 1, y + 1); convert to 0-based and clip.
    x0 = np.clip(boxes[:, 0] - 1.0, 0, W)
    y0 = np.clip(boxes[:, 1] - 1.0, 0, H)
    x1 = np.clip(boxes[:, 0] - 1.0 + boxes[:, 2], 0, W)
    y1 = np.clip(boxes[:, 1] - 1.0 + boxes[:, 3], 0, H)
    boxes = np.stack([x0, y0, x1 - x0, y1 - y0], axis=1)
    # stable sort by descending score (OpenCV already returns them sorted; make it explicit)
    order = np.argsort(-scores, kind="stable")
    return EdgeBoxes(boxes[order][:max_boxes], scores[order][:max_boxes], source)


# ------------------------------------------------------------------------------------------
# Eq. (3) and Table 1
# ------------------------------------------------------------------------------------------


def normalized_scale(boxes: np.ndarray, image_size: Sequence[int]) -> np.ndarray:
    """Normalized scale (Eq. 3): box area / image area.

    Args:
        boxes: ``(K, 4)`` ``(x, y, w, h)``.
        image_size: ``(H, W)``.

    Returns:
        ``(K,)`` float64 area ratios (not clipped; boxes inside the image give ``[0, 1]``).
    """
    b = _check_boxes(boxes)
    H, W = _check_image_size(image_size)
    return b[:, 2] * b[:, 3] / float(H * W)


def scale_index(
    boxes_or_ratios: np.ndarray | float, image_size: Sequence[int] | None = None
) -> np.ndarray | int:
    """Table-1 scale index (1..9) of boxes or of normalized scales.

    Bins are lower-edge inclusive with edges :data:`SCALE_EDGES` (0.02, 0.05, 0.09, 0.14, 0.23,
    0.34, 0.5, 0.72): ratio 0 -> 1, exactly 0.02 -> 2, exactly 0.72 -> 9, 1.0 -> 9. Ratios above 1
    (boxes larger than the image) also give 9.

    Args:
        boxes_or_ratios: ``(K, 4)`` boxes (then ``image_size`` is required) or a 1-D ``(K,)`` array
            (or a scalar) of normalized scales (then ``image_size`` must be None).
        image_size: ``(H, W)`` when boxes are given.

    Returns:
        ``(K,)`` int64 scale indices in 1..9 (a Python int for a scalar ratio).
    """
    if image_size is not None:
        ratios = normalized_scale(boxes_or_ratios, image_size)
        scalar = False
    else:
        ratios = np.asarray(boxes_or_ratios, dtype=np.float64)
        scalar = ratios.ndim == 0
        if ratios.ndim == 2 and ratios.shape[1] == 4:
            raise ValueError("scale_index got (K, 4) boxes without image_size; pass image_size=(H, W)")
        if ratios.ndim > 1:
            raise ValueError(
                f"scale_index expects (K, 4) boxes with image_size or 1-D ratios, got {ratios.shape}"
            )
        ratios = np.atleast_1d(ratios)
        if not np.all(np.isfinite(ratios)) or np.any(ratios < 0):
            raise ValueError("normalized scales must be finite and >= 0")
    idx = np.searchsorted(np.asarray(SCALE_EDGES), ratios, side="right").astype(np.int64) + 1
    return int(idx[0]) if scalar else idx


def scale_histogram(
    boxes: np.ndarray, image_size: Sequence[int] | None = None
) -> np.ndarray:
    """Count of boxes per Table-1 scale (Fig. 6).

    Args:
        boxes: ``(K, 4)`` boxes (with ``image_size``) or ``(K,)`` normalized scales.
        image_size: ``(H, W)`` when boxes are given.

    Returns:
        ``(10,)`` int64 counts indexed by scale 1..9 (index 0 unused, always 0).
    """
    idx = np.atleast_1d(scale_index(boxes, image_size))
    return np.bincount(idx, minlength=N_SCALES + 1).astype(np.int64)


# ------------------------------------------------------------------------------------------
# IoU
# ------------------------------------------------------------------------------------------


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pairwise intersection over union of ``(x, y, w, h)`` boxes.

    Continuous coordinates: area ``w * h`` (no ``+1``). A pair whose union is 0 (two empty boxes)
    has IoU 0.

    Args:
        a: ``(Ka, 4)`` boxes.
        b: ``(Kb, 4)`` boxes.

    Returns:
        ``(Ka, Kb)`` float64 IoU in ``[0, 1]``.
    """
    a = _check_boxes(a, "a")
    b = _check_boxes(b, "b")
    ax0, ay0 = a[:, 0:1], a[:, 1:2]
    ax1, ay1 = ax0 + a[:, 2:3], ay0 + a[:, 3:4]
    bx0, by0 = b[None, :, 0], b[None, :, 1]
    bx1, by1 = bx0 + b[None, :, 2], by0 + b[None, :, 3]
    iw = np.clip(np.minimum(ax1, bx1) - np.maximum(ax0, bx0), 0, None)
    ih = np.clip(np.minimum(ay1, by1) - np.maximum(ay0, by0), 0, None)
    inter = iw * ih
    union = (a[:, 2] * a[:, 3])[:, None] + (b[:, 2] * b[:, 3])[None, :] - inter
    out = np.zeros_like(inter)
    np.divide(inter, union, out=out, where=union > 0)
    return np.clip(out, 0.0, 1.0)


# ------------------------------------------------------------------------------------------
# Algorithms 1-3
# ------------------------------------------------------------------------------------------


def _result(boxes: np.ndarray, idx: list[int] | np.ndarray, return_indices: bool):
    idx = np.asarray(idx, dtype=np.int64)
    sel = boxes[idx] if idx.size else np.zeros((0, 4), dtype=np.float64)
    return (sel, idx) if return_indices else sel


def _warn_undersupply(name: str, got: int, n: int, k: int) -> None:
    if got < n:
        logger.warning(
            "%s: only %d of the requested %d landmarks qualify among %d candidates; "
            "returning %d", name, got, n, k, got
        )


def select_min_scale(
    boxes: np.ndarray,
    image_size: Sequence[int],
    n: int = 100,
    min_index: int = 4,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Landmark Selection Scheme 1 (Algorithm 1).

    Walks the candidates in proposal order and keeps the first ``n`` whose Table-1 scale index is
    ``>= min_index`` (default 4, i.e. "> Scale 3"). If fewer than ``n`` qualify, all qualifying
    candidates are returned and a warning is logged (the paper's loop would not terminate).

    Args:
        boxes: ``(K, 4)`` candidates in proposal order (the paper uses K = 1000 Edge Boxes).
        image_size: ``(H, W)``.
        n: number of landmarks to select.
        min_index: smallest accepted scale index (1..9).
        return_indices: also return the selected candidates' indices into ``boxes``.

    Returns:
        ``(N, 4)`` selected boxes in proposal order, ``N = min(n, #qualifying)``; with
        ``return_indices`` a tuple ``(boxes, indices (N,) int64)``.
    """
    b = _check_boxes(boxes)
    n = _check_n(n)
    if not 1 <= int(min_index) <= N_SCALES:
        raise ValueError(f"min_index must be in 1..9, got {min_index}")
    idx = np.flatnonzero(scale_index(b, image_size) >= int(min_index))[:n]
    _warn_undersupply("select_min_scale", idx.size, n, b.shape[0])
    return _result(b, idx, return_indices)


def select_scale_priority(
    boxes: np.ndarray,
    image_size: Sequence[int],
    n: int = 100,
    order: Sequence[int] = (5, 6, 7, 8, 9, 4),
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Landmark Selection Scheme 2 (Algorithm 2).

    Takes all candidates of scale ``order[0]`` in proposal order, then all of ``order[1]``, ...,
    stopping as soon as ``n`` are selected. Scales absent from ``order`` are never selected. If
    fewer than ``n`` qualify, all of them are returned (in the above order) and a warning logged.

    Args:
        boxes: ``(K, 4)`` candidates in proposal order.
        image_size: ``(H, W)``.
        n: number of landmarks to select.
        order: scale indices (1..9) by priority.
        return_indices: also return the selected candidates' indices into ``boxes``.

    Returns:
        ``(N, 4)`` selected boxes grouped by scale priority (proposal order within a scale);
        with ``return_indices`` a tuple ``(boxes, indices (N,) int64)``.
    """
    b = _check_boxes(boxes)
    n = _check_n(n)
    order = [int(s) for s in order]
    if any(not 1 <= s <= N_SCALES for s in order) or len(set(order)) != len(order):
        raise ValueError(f"order must hold distinct scale indices in 1..9, got {order}")
    sidx = scale_index(b, image_size)
    picked: list[np.ndarray] = []
    total = 0
    for s in order:
        if total >= n:
            break
        cand = np.flatnonzero(sidx == s)[: n - total]
        picked.append(cand)
        total += cand.size
    idx = np.concatenate(picked) if picked else np.zeros(0, dtype=np.int64)
    _warn_undersupply("select_scale_priority", idx.size, n, b.shape[0])
    return _result(b, idx, return_indices)


def reduce_overlap(
    boxes: np.ndarray,
    n: int = 100,
    iou_threshold: float = 0.5,
    return_indices: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Overlap Reduction Scheme 1 (Algorithm 3): greedy IoU filtering in proposal order.

    The first candidate is always kept; a later candidate is kept if its IoU with every kept box
    is ``<= iou_threshold``; stops once ``n`` are kept. If fewer than ``n`` survive, all survivors
    are returned and a warning logged.

    Args:
        boxes: ``(K, 4)`` candidates in proposal order.
        n: number of landmarks to keep.
        iou_threshold: IoU threshold ``t`` in ``[0, 1]``.
        return_indices: also return the kept candidates' indices into ``boxes``.

    Returns:
        ``(N, 4)`` kept boxes in proposal order; with ``return_indices`` ``(boxes, indices)``.
    """
    b = _check_boxes(boxes)
    n = _check_n(n)
    t = float(iou_threshold)
    if not 0.0 <= t <= 1.0:
        raise ValueError(f"iou_threshold must be in [0, 1], got {iou_threshold}")
    kept: list[int] = []
    if n > 0 and b.shape[0] > 0:
        x0, y0 = b[:, 0], b[:, 1]
        x1, y1 = x0 + b[:, 2], y0 + b[:, 3]
        area = b[:, 2] * b[:, 3]
        kept = [0]
        for i in range(1, b.shape[0]):
            if len(kept) >= n:
                break
            k = np.asarray(kept)
            iw = np.clip(np.minimum(x1[i], x1[k]) - np.maximum(x0[i], x0[k]), 0, None)
            ih = np.clip(np.minimum(y1[i], y1[k]) - np.maximum(y0[i], y0[k]), 0, None)
            inter = iw * ih
            union = area[i] + area[k] - inter
            iou = np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)
            if np.all(iou <= t):
                kept.append(i)
    _warn_undersupply("reduce_overlap", len(kept), n, b.shape[0])
    return _result(b, kept, return_indices)


# ------------------------------------------------------------------------------------------
# coverage (Fig. 14)
# ------------------------------------------------------------------------------------------


def landmark_coverage(boxes: np.ndarray, image_size: Sequence[int]) -> np.ndarray:
    """How many boxes cover each pixel (Fig. 14).

    Pixel ``(r, c)`` is covered by a box when its centre ``(c + 0.5, r + 0.5)`` lies in
    ``[x, x + w) x [y, y + h)``; boxes are clipped to the image.

    Args:
        boxes: ``(K, 4)`` ``(x, y, w, h)``.
        image_size: ``(H, W)``.

    Returns:
        ``(H, W)`` float64 count map.
    """
    b = _check_boxes(boxes)
    H, W = _check_image_size(image_size)
    diff = np.zeros((H + 1, W + 1), dtype=np.float64)
    if b.shape[0]:
        c0 = np.clip(np.ceil(b[:, 0] - 0.5), 0, W).astype(np.int64)
        c1 = np.clip(np.ceil(b[:, 0] + b[:, 2] - 0.5), 0, W).astype(np.int64)
        r0 = np.clip(np.ceil(b[:, 1] - 0.5), 0, H).astype(np.int64)
        r1 = np.clip(np.ceil(b[:, 1] + b[:, 3] - 0.5), 0, H).astype(np.int64)
        ok = (c1 > c0) & (r1 > r0)
        c0, c1, r0, r1 = c0[ok], c1[ok], r0[ok], r1[ok]
        np.add.at(diff, (r0, c0), 1.0)
        np.add.at(diff, (r0, c1), -1.0)
        np.add.at(diff, (r1, c0), -1.0)
        np.add.at(diff, (r1, c1), 1.0)
    return np.cumsum(np.cumsum(diff, axis=0), axis=1)[:H, :W]


# ------------------------------------------------------------------------------------------
# named landmark schemes
# ------------------------------------------------------------------------------------------

#: Default configuration of each landmark scheme (merged under the user's ``conf``).
SCHEME_DEFAULTS: dict[str, dict[str, Any]] = {
    "edge_boxes": {"max_boxes": 100},
    "dense": {"scales": (0.16, 0.25, 0.36, 0.49), "per_scale": 25},
    "selection_scheme1": {"n_candidates": 1000, "n": 100, "min_index": 4},
    "selection_scheme2": {"n_candidates": 1000, "n": 100, "order": (5, 6, 7, 8, 9, 4)},
    "overlap_scheme1": {"n_candidates": 1000, "n": 100, "iou_threshold": 0.5},
}


def _split_conf(name: str, conf: Mapping[str, Any], own: Sequence[str]) -> tuple[dict, dict]:
    """Merge ``conf`` over the scheme defaults; split into (scheme keys, edge_boxes keys)."""
    merged = {**SCHEME_DEFAULTS[name], **dict(conf or {})}
    mine = {k: merged.pop(k) for k in list(merged) if k in own}
    eb_keys = set(EDGE_BOXES_DEFAULTS) | {"model"}
    unknown = set(merged) - eb_keys
    if unknown:
        raise ValueError(
            f"unknown option(s) {sorted(unknown)} for landmark scheme '{name}'; valid: "
            f"{sorted(set(own) | eb_keys)}"
        )
    return mine, merged


def select_from_candidates(candidates: np.ndarray, image_size: Any, scheme: str, n: int = 100,
                           min_index: int = 4, order: Sequence[int] = (5, 6, 7, 8, 9, 4),
                           iou_threshold: float = 0.5) -> np.ndarray:
    """The landmarks an Edge Box scheme keeps from a list of proposals.

    Args:
        candidates: ``(M, 4)`` proposals in proposal order (e.g. 1,000 Edge Boxes).
        image_size: ``(H, W)`` of the image.
        scheme: ``edge_boxes`` (first ``n``), ``selection_scheme1`` (Algorithm 1,
            ``min_index``), ``selection_scheme2`` (Algorithm 2, ``order``) or
            ``overlap_scheme1`` (Algorithm 3, ``iou_threshold``).
        n: landmarks to keep.

    Returns:
        ``(K, 4)`` float64 boxes, ``K <= n``.

    Raises:
        ValueError: unknown scheme (the message lists the valid ones).
    """
    cand = _check_boxes(candidates, "candidates")
    if scheme == "edge_boxes":
        return cand[: _check_n(n)].copy()
    if scheme == "selection_scheme1":
        return select_min_scale(cand, image_size, n=n, min_index=min_index)
    if scheme == "selection_scheme2":
        return select_scale_priority(cand, image_size, n=n, order=tuple(order))
    if scheme == "overlap_scheme1":
        return reduce_overlap(cand, n=n, iou_threshold=iou_threshold)
    raise ValueError(f"unknown Edge Box scheme {scheme!r}; valid: edge_boxes, selection_scheme1, "
                     "selection_scheme2, overlap_scheme1")


def _scheme_edge_boxes(image: np.ndarray, conf: Mapping[str, Any]) -> np.ndarray:
    mine, eb = _split_conf("edge_boxes", conf, ("max_boxes",))
    return edge_boxes(image, max_boxes=mine["max_boxes"], **eb).boxes


def _scheme_dense(image: np.ndarray, conf: Mapping[str, Any]) -> np.ndarray:
    merged = {**SCHEME_DEFAULTS["dense"], **dict(conf or {})}
    unknown = set(merged) - {"scales", "per_scale"}
    if unknown:
        raise ValueError(
            f"unknown option(s) {sorted(unknown)} for landmark scheme 'dense'; "
            "valid: ['per_scale', 'scales']"
        )
    size = image.shape[:2] if isinstance(image, np.ndarray) and image.ndim >= 2 else image
    return dense_sampling(size, merged["scales"], merged["per_scale"])


def _scheme_selection1(image: np.ndarray, conf: Mapping[str, Any]) -> np.ndarray:
    mine, eb = _split_conf("selection_scheme1", conf, ("n_candidates", "n", "min_index"))
    cand = edge_boxes(image, max_boxes=mine.pop("n_candidates"), **eb).boxes
    return select_from_candidates(cand, image.shape[:2], "selection_scheme1", **mine)


def _scheme_selection2(image: np.ndarray, conf: Mapping[str, Any]) -> np.ndarray:
    mine, eb = _split_conf("selection_scheme2", conf, ("n_candidates", "n", "order"))
    cand = edge_boxes(image, max_boxes=mine.pop("n_candidates"), **eb).boxes
    return select_from_candidates(cand, image.shape[:2], "selection_scheme2", **mine)


def _scheme_overlap1(image: np.ndarray, conf: Mapping[str, Any]) -> np.ndarray:
    mine, eb = _split_conf("overlap_scheme1", conf, ("n_candidates", "n", "iou_threshold"))
    cand = edge_boxes(image, max_boxes=mine.pop("n_candidates"), **eb).boxes
    return select_from_candidates(cand, image.shape[:2], "overlap_scheme1", **mine)


#: Landmark schemes by name: ``fn(image (H, W, 3) uint8, conf: dict) -> boxes (K, 4)``.
#: ``edge_boxes``: top ``max_boxes`` (100) Edge Boxes (the classical method, also used by overlap
#: scheme 2 whose soft-NMS acts on match scores); ``dense``: :func:`dense_sampling`;
#: ``selection_scheme1/2``: ``n_candidates`` (1000) Edge Boxes then Algorithm 1/2 to ``n`` (100);
#: ``overlap_scheme1``: 1000 Edge Boxes then Algorithm 3 with ``conf["iou_threshold"]``.
#: Edge Boxes schemes also accept ``model`` and the keys of :data:`EDGE_BOXES_DEFAULTS`.
LANDMARK_SCHEMES: dict[str, Callable[[np.ndarray, Mapping[str, Any]], np.ndarray]] = {
    "edge_boxes": _scheme_edge_boxes,
    "dense": _scheme_dense,
    "selection_scheme1": _scheme_selection1,
    "selection_scheme2": _scheme_selection2,
    "overlap_scheme1": _scheme_overlap1,
}


def get_landmark_scheme(
    name: str,
) -> Callable[[np.ndarray, Mapping[str, Any]], np.ndarray]:
    """Look up a landmark scheme by name.

    Args:
        name: one of :data:`LANDMARK_SCHEMES` (``edge_boxes``, ``dense``, ``selection_scheme1``,
            ``selection_scheme2``, ``overlap_scheme1``).

    Returns:
        ``fn(image, conf) -> boxes (K, 4)`` float64.

    Raises:
        ValueError: unknown name (the message lists the valid names).
    """
    try:
        return LANDMARK_SCHEMES[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown landmark scheme {name!r}; valid: {sorted(LANDMARK_SCHEMES)}"
        ) from None


def generate_landmarks(image: np.ndarray, scheme: str, **conf: Any) -> np.ndarray:
    """Landmarks of one image by a named scheme.

    Args:
        image: ``(H, W, 3)`` uint8 RGB (for ``dense`` only its shape is used).
        scheme: a name of :data:`LANDMARK_SCHEMES`.
        **conf: scheme options merged over :data:`SCHEME_DEFAULTS` ``[scheme]``.

    Returns:
        ``(K, 4)`` float64 boxes in proposal order.
    """
    fn = get_landmark_scheme(scheme)
    if scheme != "dense":
        _check_image(image)
    elif not isinstance(image, np.ndarray) or image.ndim not in (2, 3):
        raise ValueError("image must be an (H, W, 3) or (H, W) array")
    return fn(image, conf)
