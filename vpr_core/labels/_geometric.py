"""Geometric-verification match labels for real images (SIFT + ratio test + RANSAC).
The rules and thresholds are in docs/DEFINITIONS.md ("Match labels")."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from ..boxes import paired_iou_parsed
from ..checks import check_boxes, check_choice
from ._exact import (
    LabelRule,
    LabelUnavailableError,
    check_matches,
    is_ground_truth,
    map_boxes,
    value_or_fields,
)

__all__ = [
    "GEOMETRIC_OPTIONS",
    "PairGeometry",
    "Verification",
    "estimate_pair_geometry",
    "label_matches_geometric",
    "label_pair_geometric",
]


@dataclass
class PairGeometry:
    """Two-view geometry of one image pair from SIFT + ratio test + RANSAC: ``kind`` is
    ``"homography"`` (``(3, 3)`` query -> reference pixel map), ``"fundamental"`` (point rule) or
    ``"none"`` (unlabelled); ``points_q`` / ``points_r`` ``(N, 2)`` the chosen model's inliers;
    ``n_putative`` the correspondences that passed the ratio test."""

    kind: str
    homography: np.ndarray | None
    fundamental: np.ndarray | None
    points_q: np.ndarray
    points_r: np.ndarray
    n_putative: int
    n_inliers_h: int
    n_inliers_f: int
    image_size_q: tuple[int, int]
    image_size_r: tuple[int, int]


def _gray(img: np.ndarray, equalize: bool, denoise: float = 0.0) -> np.ndarray:
    a = np.asarray(img)
    if a.ndim == 3:
        a = cv2.cvtColor(a[..., :3].astype(np.uint8), cv2.COLOR_RGB2GRAY)
    a = a.astype(np.uint8)
    if denoise > 0:  # night images: sensor noise makes spurious keypoints
        a = cv2.GaussianBlur(a, (0, 0), float(denoise))
    if equalize:  # night images: local contrast equalisation helps SIFT find keypoints
        a = cv2.createCLAHE(clipLimit=2.0, tileGridSize=(8, 8)).apply(a)
    return a


def _homography_is_sane(H: np.ndarray, size_q: tuple[int, int]) -> bool:
    """False for a degenerate homography: area ratio outside [1/16, 16], non-convex or flipped."""
    if H is None or not np.isfinite(H).all():
        return False
    h, w = size_q
    corners = np.array([[0, 0, 1], [w, 0, 1], [w, h, 1], [0, h, 1]], dtype=np.float64) @ H.T
    if (corners[:, 2] <= 1e-12).any():
        return False
    c = corners[:, :2] / corners[:, 2:]
    # signed area (shoelace) and convexity: all cross products of consecutive edges same sign
    edges = np.roll(c, -1, axis=0) - c
    cross = (
        edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1]
        - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
    )
    if not ((cross > 0).all() or (cross < 0).all()):
        return False
    area = 0.5 * abs(np.sum(c[:, 0] * np.roll(c[:, 1], -1) - np.roll(c[:, 0], -1) * c[:, 1]))
    ratio = area / float(w * h)
    return 1.0 / 16 <= ratio <= 16.0 and bool(cross[0] > 0)


@dataclass(frozen=True)
class Verification:
    """How :func:`estimate_pair_geometry` verifies a pair (defaults set from the chance level;
    docs/DEFINITIONS.md): SIFT (``max_features``, ``contrast_threshold``) after CLAHE
    (``equalize``), a Gaussian ``denoise`` sigma and an ``upscale`` factor; Lowe's ``ratio``;
    RANSAC or MAGSAC (``robust``, seeded by ``seed``) homography and fundamental matrix with
    pixel thresholds ``h_threshold`` / ``f_threshold``; a model is kept with at least
    ``min_inliers*`` inliers and ``min_inlier_ratio*`` of the ratio-test matches, the homography
    only with ``h_share`` of the fundamental matrix's inliers."""

    ratio: float = 0.8
    max_features: int = 4000
    equalize: bool = True
    h_threshold: float = 4.0
    f_threshold: float = 2.0
    min_inliers: int = 15
    min_inlier_ratio: float = 0.3
    min_inliers_f: int = 20
    min_inlier_ratio_f: float = 0.45
    h_share: float = 0.7
    contrast_threshold: float = 0.01
    denoise: float = 0.0
    upscale: float = 1.0
    robust: str = "ransac"
    seed: int = 0

    def __post_init__(self) -> None:
        check_choice(self.robust, "robust estimator", ("ransac", "magsac"))


#: The options of ``method="geometric"`` (:func:`label_pair_geometric`): where the geometry comes
#: from, and the :class:`Verification` as a value or as its fields.
GEOMETRIC_OPTIONS = (
    "images",
    "geometry",
    "geometry_cache",
    "verification",
    *(f.name for f in dataclasses.fields(Verification)),
)


def _as_verification(options: dict[str, Any]) -> Verification:
    """A :class:`Verification` from ``verification=`` or its fields as keywords (not both); the
    option names were checked against :data:`GEOMETRIC_OPTIONS`."""
    return value_or_fields(Verification, "verification", options.pop("verification", None), options)


def _ratio_test_points(
    img_q: np.ndarray, img_r: np.ndarray, v: Verification
) -> tuple[np.ndarray, np.ndarray] | None:
    """``(points_q (N, 2), points_r (N, 2))``: SIFT correspondences that pass Lowe's ratio test,
    in original pixels; None when an image has fewer than two keypoints."""
    sift = cv2.SIFT_create(  # type: ignore[attr-defined]
        nfeatures=int(v.max_features), contrastThreshold=float(v.contrast_threshold)
    )
    ratio, upscale = v.ratio, v.upscale
    gq, gr = _gray(img_q, v.equalize, v.denoise), _gray(img_r, v.equalize, v.denoise)
    if upscale != 1.0:
        gq = cv2.resize(gq, None, fx=upscale, fy=upscale, interpolation=cv2.INTER_LINEAR)
        gr = cv2.resize(gr, None, fx=upscale, fy=upscale, interpolation=cv2.INTER_LINEAR)
    kq, dq = sift.detectAndCompute(gq, None)
    kr, dr = sift.detectAndCompute(gr, None)
    if dq is None or dr is None or len(kq) < 2 or len(kr) < 2:
        return None
    knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(dq, dr, k=2)
    good = [p[0] for p in knn if len(p) == 2 and p[0].distance < ratio * p[1].distance]
    pq = np.array([kq[g.queryIdx].pt for g in good], dtype=np.float64).reshape(-1, 2) / upscale
    pr = np.array([kr[g.trainIdx].pt for g in good], dtype=np.float64).reshape(-1, 2) / upscale
    return pq, pr


def _fit_models(
    pq: np.ndarray, pr: np.ndarray, v: Verification
) -> tuple[Any, np.ndarray, Any, np.ndarray]:
    """``(H or None, inliers_h (N,), F or None, inliers_f (N,))``: RANSAC (or MAGSAC)
    homography and fundamental matrix of ``(N, 2)`` correspondences."""
    n_put = len(pq)
    h_method = cv2.RANSAC if v.robust == "ransac" else cv2.USAC_MAGSAC
    f_method = cv2.FM_RANSAC if v.robust == "ransac" else cv2.USAC_MAGSAC
    cv2.setRNGSeed(int(v.seed))
    H, mask_h = cv2.findHomography(
        pq, pr, h_method, float(v.h_threshold), maxIters=5000, confidence=0.999
    )
    inl_h = mask_h.ravel().astype(bool) if mask_h is not None else np.zeros(n_put, bool)
    cv2.setRNGSeed(int(v.seed))
    F, mask_f = cv2.findFundamentalMat(pq, pr, f_method, float(v.f_threshold), 0.999, 5000)
    if F is not None and F.shape != (3, 3):  # several solutions stacked: keep the first
        F = F[:3]
    inl_f = mask_f.ravel().astype(bool) if mask_f is not None else np.zeros(n_put, bool)
    return H, inl_h, F, inl_f


def estimate_pair_geometry(
    img_q: np.ndarray, img_r: np.ndarray, verification: Verification = Verification()
) -> PairGeometry:
    """SIFT, Lowe ratio test, RANSAC homography and fundamental matrix for one pair; the
    settings and the model choice: :class:`Verification`, docs/DEFINITIONS.md."""
    v = verification
    size_q = (int(img_q.shape[0]), int(img_q.shape[1]))
    size_r = (int(img_r.shape[0]), int(img_r.shape[1]))
    empty = np.zeros((0, 2), dtype=np.float64)
    cv2.setRNGSeed(int(v.seed))
    points = _ratio_test_points(img_q, img_r, v)
    if points is None:
        return PairGeometry("none", None, None, empty, empty, 0, 0, 0, size_q, size_r)
    pq, pr = points
    n_put = len(pq)
    if n_put < max(min(v.min_inliers, v.min_inliers_f), 8):
        return PairGeometry("none", None, None, empty, empty, n_put, 0, 0, size_q, size_r)
    H, inl_h, F, inl_f = _fit_models(pq, pr, v)
    n_h, n_f = int(inl_h.sum()), int(inl_f.sum())
    if (
        H is not None
        and n_h >= v.min_inliers
        and n_h >= v.min_inlier_ratio * n_put
        and _homography_is_sane(H, size_q)
        and n_h >= v.h_share * max(n_f, 1)
    ):
        return PairGeometry(
            "homography", H, F, pq[inl_h], pr[inl_h], n_put, n_h, n_f, size_q, size_r
        )
    if F is not None and n_f >= v.min_inliers_f and n_f >= v.min_inlier_ratio_f * n_put:
        return PairGeometry(
            "fundamental", None, F, pq[inl_f], pr[inl_f], n_put, n_h, n_f, size_q, size_r
        )
    return PairGeometry("none", None, None, empty, empty, n_put, n_h, n_f, size_q, size_r)


def _inside(points: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """``(K, N)`` bool: point n inside box k (closed box)."""
    if len(points) == 0 or len(boxes) == 0:
        return np.zeros((len(boxes), len(points)), dtype=bool)
    x, y = points[:, 0][None], points[:, 1][None]
    bx, by, bw, bh = (boxes[:, i][:, None] for i in range(4))
    return (x >= bx) & (x <= bx + bw) & (y >= by) & (y <= by + bh)


def label_matches_geometric(
    boxes_q: np.ndarray,
    boxes_r: np.ndarray,
    matches: np.ndarray,
    geometry: PairGeometry,
    rule: LabelRule = LabelRule(),
) -> np.ndarray:
    """``(P,)`` geometric-verification labels of ``(P, 2)`` matches from a :class:`PairGeometry`
    (docs/DEFINITIONS.md) by a :class:`LabelRule` (its ``model`` forces the ``"homography"`` or
    the ``"points"`` rule)."""
    bq, br = check_boxes(boxes_q, "boxes_q"), check_boxes(boxes_r, "boxes_r")
    m = check_matches(matches, len(bq), len(br))
    return _geometric_labels(bq, br, m, geometry, rule)


def _geometric_labels(
    bq: np.ndarray, br: np.ndarray, m: np.ndarray, geometry: PairGeometry, rule: LabelRule
) -> np.ndarray:
    """:func:`label_matches_geometric` of parsed boxes and matches (no checks)."""
    if geometry.kind == "none":
        raise LabelUnavailableError(
            f"no two-view geometry for this pair ({geometry.n_putative} ratio-test matches, "
            f"{geometry.n_inliers_h} homography / {geometry.n_inliers_f} fundamental inliers)"
        )
    if len(m) == 0:
        return np.zeros(0, dtype=bool)
    use_h = rule.model == "homography" or (rule.model == "auto" and geometry.kind == "homography")
    if use_h:
        if geometry.homography is None:
            raise LabelUnavailableError("homography rule requested but the pair has no homography")
        mapped = map_boxes(bq[m[:, 0]], geometry.homography, geometry.image_size_r)
        return paired_iou_parsed(mapped, br[m[:, 1]]) >= rule.iou_threshold
    in_q = _inside(geometry.points_q, bq[m[:, 0]])  # (P, N)
    in_r = _inside(geometry.points_r, br[m[:, 1]])
    n_q = in_q.sum(1)
    n_r = in_r.sum(1)
    n_qr = (in_q & in_r).sum(1)
    union = n_q + n_r - n_qr
    piou = np.where(union > 0, n_qr / np.maximum(union, 1), 0.0)
    return (n_qr >= rule.min_points) & (piou >= rule.point_iou)


def label_pair_geometric(
    dataset: Any,
    q: int,
    r: int,
    bq: np.ndarray,
    br: np.ndarray,
    m: np.ndarray,
    rule: LabelRule,
    **options: Any,
) -> np.ndarray:
    """``method="geometric"`` of :func:`vpr_core.labels.label_matches` on boxes, matches, a rule
    and options (:data:`GEOMETRIC_OPTIONS`) a caller already parsed (no checks).

    The geometry comes from ``geometry=``, else ``geometry_cache[(q, r)]``, else is estimated
    from ``images=(img_q, img_r)`` or the dataset's images (and cached); the other options are
    the :class:`Verification` of :func:`estimate_pair_geometry`.
    """
    images = options.pop("images", None)
    geometry = options.pop("geometry", None)
    cache = options.pop("geometry_cache", None)
    verification = _as_verification(options)
    if not is_ground_truth(dataset, q, r):
        return np.zeros(len(m), dtype=bool)
    if geometry is None and cache is not None:
        geometry = cache.get((q, r))
    if geometry is None:
        if images is None:
            images = (dataset.load_image("query", q), dataset.load_image("reference", r))
        geometry = estimate_pair_geometry(images[0], images[1], verification)
        if cache is not None:
            cache[(q, r)] = geometry
    return _geometric_labels(bq, br, m, geometry, rule)
