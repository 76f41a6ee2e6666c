"""Edge Boxes (Zitnick & Dollar, ECCV 2014), the classical landmark proposals (Sec. 2.1): OpenCV-
contrib ``ximgproc`` on a structured-edge map (when the user supplies the model) or a gradient
edge map; boxes in proposal order (descending objectness score)."""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .. import settings
from ..checks import check_image
from ..checks import check_int as check_count
from ..paper import N_LANDMARKS
from ..utils import file_sha256

__all__ = ["EDGE_BOXES_DEFAULTS", "EdgeBoxes", "edge_boxes", "edge_model_id"]

logger = logging.getLogger("vpr_core")

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
        env = settings.sed_model()
        if not env:
            return None
        model = env
    path = Path(model).expanduser()
    if not path.is_file():
        raise FileNotFoundError(_missing_model_message(path))
    return path


def edge_model_id(model: str | os.PathLike | None = None) -> str:
    """Identity of the edge map Edge Boxes will use: ``"gradient"`` or ``"sha256:<hex>"`` of the
    structured-edge model file's contents (``model``, else ``$VPR_SED_MODEL``)."""
    path = _resolve_model(model)
    if path is None:
        return "gradient"
    return f"sha256:{file_sha256(path)}"


#: ``options`` of a structured-edge model file that must be positive integers.
_SED_OPTIONS = (
    "stride",
    "shrinkNumber",
    "patchSize",
    "patchInnerSize",
    "numberOfGradientOrientations",
    "gradientNormalizationRadius",
    "selfsimilarityGridSize",
    "numberOfTrees",
    "numberOfTreesToEvaluate",
)
_SED_TREES = ("childs", "featureIds", "thresholds", "edgeBoundaries", "edgeBins")


def _bad_model(path: Path, why: str) -> ValueError:
    return ValueError(
        f"structured-edge model {path} cannot be used ({why}); pass the 'model.yml.gz' of "
        "opencv_extra (testdata/cv/ximgproc) as model=... or in VPR_SED_MODEL, or unset "
        "VPR_SED_MODEL to use the gradient edge map."
    )


def _tree_sizes(node: Any) -> list[int]:
    """Lengths of the per-tree sequences of one model field (``[]`` when absent or not a list)."""
    if node.empty() or not node.isSeq():
        return []
    return [node.at(i).size() for i in range(node.size())]


def _check_model(path: Path) -> None:
    """Refuse a structured-edge model file OpenCV would crash on (it divides by the tree count and
    indexes the trees unchecked): readable FileStorage, positive options, consistent tree arrays."""
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:  # the binding wraps a parse error in SystemError
        reason = str(exc.__cause__ or exc.__context__ or exc).strip().splitlines()[-1][-120:]
        raise _bad_model(path, f"not a readable OpenCV FileStorage: {reason}") from None
    try:
        if not fs.isOpened():
            raise _bad_model(path, "not a readable OpenCV FileStorage")
        options = fs.getNode("options")
        if options.empty() or not options.isMap():
            raise _bad_model(path, "no 'options' map")
        opt = {}
        for key in _SED_OPTIONS:
            node = options.getNode(key)
            value = node.real() if node.isInt() or node.isReal() else 0.0
            if value < 1 or value != int(value):
                raise _bad_model(path, f"options.{key} must be a positive integer")
            opt[key] = int(value)
        if opt["patchInnerSize"] > opt["patchSize"] or (
            opt["numberOfTreesToEvaluate"] > opt["numberOfTrees"]
        ):
            raise _bad_model(path, "inconsistent options (patch sizes or tree counts)")
        sizes = {key: _tree_sizes(fs.getNode(key)) for key in _SED_TREES}
        if len(sizes["childs"]) != opt["numberOfTrees"] or not all(sizes["childs"]):
            raise _bad_model(path, f"'childs' must hold {opt['numberOfTrees']} non-empty trees")
        for key in ("featureIds", "thresholds"):
            if sizes[key] != sizes["childs"]:
                raise _bad_model(path, f"'{key}' does not match the trees of 'childs'")
        if sum(sizes["edgeBoundaries"]) < sum(sizes["childs"]) or not sizes["edgeBins"]:
            raise _bad_model(path, "'edgeBoundaries' / 'edgeBins' missing or too short")
    finally:
        fs.release()


def _structured_edges(image: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Structured-edge map and orientation, both ``(H, W)`` float32, NMS-thinned.

    Raises:
        ValueError: the model file cannot be read or is not a structured-edge model (names the
            file and ``VPR_SED_MODEL``).
    """
    key = str(path.resolve())
    sed = _SED_CACHE.get(key)
    if sed is None:
        _check_model(path)
        try:
            sed = cv2.ximgproc.createStructuredEdgeDetection(key)
        except cv2.error as exc:
            raise _bad_model(path, str(exc).strip().splitlines()[-1][-160:]) from None
        _SED_CACHE[key] = sed
    rgb = image if image.ndim == 3 else np.repeat(image[:, :, None], 3, axis=2)
    edges = sed.detectEdges(np.ascontiguousarray(rgb, dtype=np.float32) / 255.0)
    orient = sed.computeOrientation(edges)
    # keywords: OpenCV 5's Python signature is edgesNms(edge, orient[, dst[, r[, s[, m[, par]]]]])
    edges = sed.edgesNms(edges, orient, r=2, s=0, m=1.0, isParallel=True)
    return edges.astype(np.float32), orient.astype(np.float32)


def _edge_nms(mag: np.ndarray, orient: np.ndarray) -> np.ndarray:
    """Zero every pixel of ``mag (H, W)`` that is not a maximum along its edge normal."""
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
    return np.where(keep, mag, 0.0)


def _gradient_edges(
    image: np.ndarray, blur_sigma: float = 2.0, nms: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Gradient edge map in ``[0, 1]`` and edge orientation map, both ``(H, W)`` float32.

    Scharr gradient magnitude of the lightly blurred float32 grayscale image, divided by a robust
    maximum (99th percentile of the non-flat pixels) and clipped to ``[0, 1]``; optionally thinned
    by non-maximum suppression across the edge. The orientation is the gradient (edge-normal)
    direction modulo pi, the convention of ``StructuredEdgeDetection.computeOrientation``.
    """
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    g: np.ndarray = gray.astype(np.float32) / 255.0
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
        mag = _edge_nms(mag, orient)
    return mag.astype(np.float32), orient


def _proposals(
    edges: np.ndarray,
    orient: np.ndarray,
    p: dict[str, Any],
    max_boxes: int,
    image_size: tuple[int, int],
) -> tuple[np.ndarray, np.ndarray]:
    """Run ``cv2.ximgproc`` Edge Boxes on an edge map.

    Args:
        edges: ``(H, W)`` float32 edge map in ``[0, 1]``.
        orient: ``(H, W)`` float32 edge orientation.
        p: the merged :data:`EDGE_BOXES_DEFAULTS`.
        max_boxes: OpenCV ``maxBoxes``.
        image_size: ``(H, W)``.

    Returns:
        ``(K, 4)`` float64 0-based boxes clipped to the image, sorted by descending score, and
        their ``(K,)`` scores; ``K <= max_boxes``.
    """
    H, W = image_size
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
    return boxes[order][:max_boxes], scores[order][:max_boxes]


def edge_boxes(
    image: np.ndarray,
    max_boxes: int = N_LANDMARKS,
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
        max_boxes: maximum number of proposals (OpenCV ``maxBoxes``; default
            :data:`vpr_core.paper.N_LANDMARKS`).
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
        ValueError: the model file is not a readable structured-edge model.
    """
    image = check_image(image, allow_gray=True, min_size=2)
    max_boxes = check_count(max_boxes, "max_boxes")
    unknown = set(params) - set(EDGE_BOXES_DEFAULTS)
    if unknown:
        raise ValueError(
            f"unknown edge_boxes parameter(s) {sorted(unknown)}; "
            f"valid: {sorted(EDGE_BOXES_DEFAULTS)}"
        )
    p = {**EDGE_BOXES_DEFAULTS, **params}
    model_path = _resolve_model(model)
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
        detail = (
            f"structured-edge model {model_path}" if model_path else "gradient (Scharr) edge map"
        )
        logger.info("edge_boxes: using %s", detail)
    boxes, scores = _proposals(edges, orient, p, max_boxes, image.shape[:2])
    return EdgeBoxes(boxes, scores, source)
