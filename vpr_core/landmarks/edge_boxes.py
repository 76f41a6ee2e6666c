"""Edge Boxes (Zitnick & Dollar, ECCV 2014), the classical landmark proposals (Sec. 2.1): OpenCV-
contrib ``ximgproc`` on a structured-edge map (when the user supplies the model) or a gradient
edge map; boxes in proposal order (descending objectness score)."""

from __future__ import annotations

import hashlib
import logging
import os
import re
import tempfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .. import settings
from ..checks import check_file, check_image, check_int, check_options
from ..notices import notice
from ..paper import N_LANDMARKS
from ..utils import file_sha256
from ._edge_map import gradient_edges

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

#: Loaded structured-edge detectors by the sha256 of their model file's bytes (oldest first).
_SED_CACHE: dict[str, Any] = {}
_SED_CACHE_SIZE = 4
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
    if not check_file(path, "structured-edge model"):
        raise FileNotFoundError(_missing_model_message(path))
    return path


def edge_model_id(model: str | os.PathLike | None = None) -> str:
    """Identity of the edge map Edge Boxes will use: ``"gradient"`` or ``"sha256:<hex>"`` of the
    structured-edge model file's contents (``model``, else ``$VPR_SED_MODEL``)."""
    path = _resolve_model(model)
    if path is None:
        return "gradient"
    return f"sha256:{file_sha256(path)}"


#: ``options`` of a structured-edge model file that must be positive integers, with the largest
#: value accepted (opencv_extra's model: stride 2, shrink 2, patch 32 / 16, 4 orientations,
#: radius 4, grid 5, 8 trees); larger ones only make OpenCV allocate without bound.
_SED_OPTIONS = {
    "stride": 64,
    "shrinkNumber": 16,
    "patchSize": 256,
    "patchInnerSize": 256,
    "numberOfGradientOrientations": 64,
    "gradientNormalizationRadius": 64,
    "selfsimilarityGridSize": 64,
    "numberOfTrees": 1024,
    "numberOfTreesToEvaluate": 1024,
}
#: ``options`` that may be 0 (OpenCV reads a missing one as 0): smoothing radii.
_SED_RADII = ("gradientSmoothingRadius", "regFeatureSmoothingRadius", "ssFeatureSmoothingRadius")
_SED_TREES = ("childs", "featureIds", "thresholds", "edgeBoundaries", "edgeBins")
_FLOW_LIST = re.compile(r"\[([^\[\]]*)\]")


def _bad_model(path: Path, why: str) -> ValueError:
    return ValueError(
        f"structured-edge model {path} cannot be used ({why}); pass the 'model.yml.gz' of "
        "opencv_extra (testdata/cv/ximgproc) as model=... or in VPR_SED_MODEL, or unset "
        "VPR_SED_MODEL to use the gradient edge map."
    )


def _model_options(fs: Any, path: Path) -> dict[str, int]:
    """The model's options as OpenCV reads them, each checked against :data:`_SED_OPTIONS`."""
    options = fs.getNode("options")
    if options.empty() or not options.isMap():
        raise _bad_model(path, "no 'options' map")
    opt = {}
    for key in (*_SED_OPTIONS, *_SED_RADII):
        node = options.getNode(key)
        value = node.real() if node.isInt() or node.isReal() else (0.0 if key in _SED_RADII else -1)
        low, high = (0, 256) if key in _SED_RADII else (1, _SED_OPTIONS[key])
        if not low <= value <= high or value != int(value):
            raise _bad_model(path, f"options.{key} must be an integer in [{low}, {high}]")
        opt[key] = int(value)
    if (
        opt["patchInnerSize"] > opt["patchSize"]
        or opt["numberOfTreesToEvaluate"] > opt["numberOfTrees"]
        or opt["patchSize"] % opt["shrinkNumber"]
        or opt["selfsimilarityGridSize"] > opt["patchSize"] // opt["shrinkNumber"]
    ):
        raise _bad_model(path, "inconsistent options (patch sizes, shrink, grid or tree counts)")
    return opt


#: Largest model text accepted, in bytes (opencv_extra's model.yml.gz unpacks to about 20 MB).
MAX_MODEL_BYTES = 1 << 30


def _model_text(path: Path, raw: bytes | None = None) -> str:
    """The model file's text (``raw``: its bytes, read once by the caller), unpacked when
    gzip'd, refused beyond :data:`MAX_MODEL_BYTES` (a small archive that unpacks to gigabytes)
    before OpenCV reads it."""
    raw = path.read_bytes() if raw is None else raw
    if raw[:2] == b"\x1f\x8b":
        unpack = zlib.decompressobj(16 + zlib.MAX_WBITS)
        try:
            raw = unpack.decompress(raw, MAX_MODEL_BYTES + 1)
        except zlib.error as exc:
            raise _bad_model(path, f"a damaged gzip file: {exc}") from None
        if len(raw) > MAX_MODEL_BYTES:
            raise _bad_model(path, f"it unpacks to more than {MAX_MODEL_BYTES:,} bytes")
    return raw.decode("utf-8", "replace")


def _model_trees(path: Path, fs: Any, text: str) -> dict[str, list[np.ndarray]]:
    """Each tree field of the model file as one array per tree, read from its YAML ``text`` and
    checked against what OpenCV's FileStorage reads (tree counts, tree sizes, end values)."""
    trees: dict[str, list[np.ndarray]] = {}
    for key in _SED_TREES:
        blocks = re.findall(rf"(?ms)^{key}:[ \t]*\n(.*?)(?=^\S|\Z)", text)
        if len(blocks) != 1:
            raise _bad_model(path, f"'{key}' must appear once as a YAML list of trees")
        if _FLOW_LIST.sub("", blocks[0]).strip(" \t\r\n-[],"):
            raise _bad_model(path, f"'{key}' is not a list of [ ... ] trees (the YAML layout)")
        try:
            trees[key] = [
                np.array([float(v) for v in items.split(",") if v.strip()])
                for items in _FLOW_LIST.findall(blocks[0])
            ]
        except ValueError:
            raise _bad_model(path, f"'{key}' holds a value that is not a number") from None
        node = fs.getNode(key)
        seen = [node.at(t) for t in range(node.size())] if node.isSeq() else []
        if [n.size() for n in seen] != [len(a) for a in trees[key]] or any(
            len(a)
            and key != "thresholds"
            and (a[0], a[-1]) != (n.at(0).real(), n.at(n.size() - 1).real())
            for a, n in zip(trees[key], seen, strict=True)
        ):
            raise _bad_model(path, f"'{key}' reads differently in OpenCV (not the YAML layout)")
        if key != "thresholds" and any(
            (a != np.round(a)).any() or (np.abs(a) >= 2**31).any() for a in trees[key]
        ):
            raise _bad_model(path, f"'{key}' must hold integers")
    return trees


def _check_model(path: Path, copy: Path | None = None, raw: bytes | None = None) -> None:
    """Refuse a structured-edge model file OpenCV would crash or loop on (it indexes its trees
    unchecked): readable FileStorage, bounded options, every index within the model's sizes.

    ``copy`` (a private copy of the file's bytes ``raw``) is what is read; messages name
    ``path``."""
    text = _model_text(path, raw)
    try:
        fs = cv2.FileStorage(str(copy or path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:  # the binding wraps a parse error in SystemError
        reason = str(exc.__cause__ or exc.__context__ or exc).replace(str(copy), str(path))
        reason = reason.strip().splitlines()[-1][-120:]
        raise _bad_model(path, f"not a readable OpenCV FileStorage: {reason}") from None
    try:
        if not fs.isOpened():
            raise _bad_model(path, "not a readable OpenCV FileStorage")
        opt = _model_options(fs, path)
        trees = _model_trees(path, fs, text)
    finally:
        fs.release()
    n_trees = opt["numberOfTrees"]
    sizes = [len(a) for a in trees["childs"]]
    if len(sizes) != n_trees or not all(sizes):
        raise _bad_model(path, f"'childs' must hold {n_trees} non-empty trees")
    if len(set(sizes)) != 1:
        raise _bad_model(path, f"the trees of 'childs' differ in size ({sorted(set(sizes))})")
    for key in ("featureIds", "thresholds"):
        if [len(a) for a in trees[key]] != sizes:
            raise _bad_model(path, f"'{key}' does not match the trees of 'childs'")
    n_nodes = sizes[0]
    out = 2 * (opt["numberOfGradientOrientations"] + 1) + 3
    grid = opt["selfsimilarityGridSize"] ** 2
    n_features = (opt["patchSize"] // opt["shrinkNumber"]) ** 2 * out + grid * (grid - 1) // 2 * out
    local = np.arange(n_nodes)
    for childs, ids in zip(trees["childs"], trees["featureIds"], strict=True):
        split = childs != 0  # leaves hold 0; a split's children are childs - 1 and childs
        if ((childs[split] - 1 <= local[split]) | (childs[split] > n_nodes - 1)).any():
            raise _bad_model(
                path, f"'childs' must point forward within each tree of {n_nodes} nodes"
            )
        if ((ids[split] < 0) | (ids[split] >= n_features)).any():
            raise _bad_model(path, f"'featureIds' must lie in [0, {n_features}) at every split")
    bounds = np.concatenate(trees["edgeBoundaries"] or [np.zeros(0)])
    bins = np.concatenate(trees["edgeBins"] or [np.zeros(0)])
    if len(bounds) < n_trees * n_nodes + 1 or ((bounds < 0) | (bounds > len(bins))).any():
        raise _bad_model(
            path, f"'edgeBoundaries' must hold {n_trees * n_nodes + 1} offsets into 'edgeBins'"
        )
    n_bins = opt["patchInnerSize"] ** 2 * out
    if ((bins < 0) | (bins >= n_bins)).any():
        raise _bad_model(path, f"'edgeBins' must lie in [0, {n_bins})")


def _model_cache_key(path: Path) -> tuple[str, bytes]:
    """``(sha256 hex, bytes)`` of a structured-edge model file, read now: the key of the loaded
    detector, so a file overwritten in place is loaded again (never keyed by path or mtime)."""
    raw = path.read_bytes()
    return hashlib.sha256(raw).hexdigest(), raw


def _detector(path: Path) -> Any:
    """The structured-edge detector of the model file's current bytes (cached by their sha256:
    the same identity as :func:`edge_model_id`). It is loaded from a private copy of the bytes
    that were hashed, so a file replaced while it loads cannot give the detector another key."""
    digest, raw = _model_cache_key(path)
    sed = _SED_CACHE.get(digest)
    if sed is None:
        with tempfile.TemporaryDirectory(prefix="vpr-sed-") as tmp:
            copy = Path(tmp) / path.name  # the same name: OpenCV reads .gz by the suffix
            copy.write_bytes(raw)
            _check_model(path, copy, raw)
            try:
                sed = cv2.ximgproc.createStructuredEdgeDetection(str(copy))
            except cv2.error as exc:
                why = str(exc).replace(str(copy), str(path))
                raise _bad_model(path, why.strip().splitlines()[-1][-160:]) from None
        while len(_SED_CACHE) >= _SED_CACHE_SIZE:  # a few models per process at most
            _SED_CACHE.pop(next(iter(_SED_CACHE)))
        _SED_CACHE[digest] = sed
    return sed


def _structured_edges(image: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Structured-edge map and orientation, both ``(H, W)`` float32, NMS-thinned.

    Raises:
        ValueError: the model file cannot be read or is not a structured-edge model (names the
            file and ``VPR_SED_MODEL``).
    """
    sed = _detector(path)
    rgb = image if image.ndim == 3 else np.repeat(image[:, :, None], 3, axis=2)
    edges = sed.detectEdges(np.ascontiguousarray(rgb, dtype=np.float32) / 255.0)
    orient = sed.computeOrientation(edges)
    # keywords: OpenCV 5's Python signature is edgesNms(edge, orient[, dst[, r[, s[, m[, par]]]]])
    edges = sed.edgesNms(edges, orient, r=2, s=0, m=1.0, isParallel=True)
    return edges.astype(np.float32), orient.astype(np.float32)


#: Largest share of pixels Edge Boxes gets as edges (``>= edge_min_mag``). Natural images have
#: 5-15% (Gardens Point, Nordland, synthetic); a denser map (a model painting every patch, noise)
#: makes OpenCV's edge grouping take minutes per image, so only the strongest are kept.
MAX_EDGE_DENSITY = 0.25
_DENSE_NOTICED: set[str] = set()


def _detail(model_path: Path | None) -> str:
    """The edge map's name in messages: the model file, or the gradient map."""
    return f"structured-edge model {model_path}" if model_path else "gradient (Scharr) edge map"


def _bounded_edges(edges: np.ndarray, min_mag: float, detail: str) -> np.ndarray:
    """``edges`` with at most :data:`MAX_EDGE_DENSITY` of its pixels at ``>= min_mag``: the
    strongest kept, ties at the cut drawn with a fixed seed; said once per edge map source."""
    on = np.flatnonzero(edges.ravel() >= min_mag)
    budget = int(MAX_EDGE_DENSITY * edges.size)
    if len(on) <= budget:
        return edges
    flat = edges.ravel()
    cut = np.partition(flat[on], len(on) - budget)[len(on) - budget]
    keep = flat > cut
    ties = np.flatnonzero(flat == cut)
    keep[np.random.default_rng(0).permutation(ties)[: budget - int(keep.sum())]] = True
    if detail not in _DENSE_NOTICED:
        _DENSE_NOTICED.add(detail)
        notice(
            f"edge_boxes: the {detail} marks {len(on) / edges.size:.0%} of an image's pixels "
            f"as edges; Edge Boxes keeps the strongest {MAX_EDGE_DENSITY:.0%} (a work budget: "
            "a denser map takes minutes per image), so its proposals differ from OpenCV's on "
            "the full map. Said once per edge map; a natural image has 5-15%.",
            stacklevel=4,
        )
    return np.where(keep.reshape(edges.shape), edges, 0.0).astype(np.float32)


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
    max_boxes = check_int(max_boxes, "max_boxes")
    check_options(params, EDGE_BOXES_DEFAULTS, "edge_boxes")
    p = {**EDGE_BOXES_DEFAULTS, **params}
    model_path = _resolve_model(model)
    if max_boxes == 0:
        source = "structured" if model_path is not None else "gradient"
        return EdgeBoxes(np.zeros((0, 4)), np.zeros(0), source)

    if model_path is not None:
        edges, orient = _structured_edges(image, model_path)
        source = "structured"
    else:
        edges, orient = gradient_edges(image, float(p["blur_sigma"]), bool(p["edge_nms"]))
        source = "gradient"
    if source not in _LOGGED_SOURCES:
        _LOGGED_SOURCES.add(source)
        logger.info("edge_boxes: using %s", _detail(model_path))
    edges = _bounded_edges(edges, float(p["edge_min_mag"]), _detail(model_path))
    boxes, scores = _proposals(edges, orient, p, max_boxes, image.shape[:2])
    return EdgeBoxes(boxes, scores, source)
