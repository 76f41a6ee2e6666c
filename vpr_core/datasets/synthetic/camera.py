"""View geometry: the day reference and night query cameras of a place, and their homography."""

from __future__ import annotations

import math

import cv2
import numpy as np

_CANVAS_SCALE = (1.45, 1.8)  # world canvas size in units of the view (H, W)

def _view_corners(center: tuple[float, float], w: float, h: float, zoom: float, angle_deg: float,
                  keystone: float) -> np.ndarray:
    """Canvas corners (TL, TR, BR, BL) of a view: ``float32 (4, 2)``."""
    hw, hh = 0.5 * w / zoom, 0.5 * h / zoom
    # keystone: the left edge is taller than the right one (a facade seen at an angle)
    pts = np.array([[-hw, -hh * (1 + keystone)], [hw, -hh * (1 - keystone)],
                    [hw, hh * (1 - keystone)], [-hw, hh * (1 + keystone)]], np.float64)
    a = math.radians(angle_deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return (pts @ rot.T + np.asarray(center)).astype(np.float32)


def _place_geometry(seed: int, i: int, image_size: tuple[int, int]) -> tuple[np.ndarray,
                                                                              np.ndarray]:
    """Canvas->reference and canvas->query homographies of place ``i`` (``float64 (3, 3)`` each)."""
    h, w = image_size
    hc, wc = round(_CANVAS_SCALE[0] * h), round(_CANVAS_SCALE[1] * w)
    rng = np.random.default_rng([seed, i, 1])
    side = 1.0 if rng.random() < 0.5 else -1.0
    shift = rng.uniform(0.1, 0.22) * w * side  # the query walks on the other side of the path
    cy = 0.5 * hc + rng.uniform(-0.03, 0.03) * h
    c_ref = (0.5 * wc - 0.5 * shift, cy)
    c_q = (0.5 * wc + 0.5 * shift, cy + rng.uniform(-0.05, 0.05) * h)
    ref = _view_corners(c_ref, w, h, 1.0, rng.uniform(-1.0, 1.0), -side * rng.uniform(0.0, 0.04))
    qry = _view_corners(c_q, w, h, rng.uniform(0.85, 1.15), rng.uniform(-5.0, 5.0),
                        side * rng.uniform(0.02, 0.07))
    dst = np.array([[0, 0], [w, 0], [w, h], [0, h]], np.float32)
    h_ref = cv2.getPerspectiveTransform(ref, dst).astype(np.float64)
    h_q = cv2.getPerspectiveTransform(qry, dst).astype(np.float64)
    return h_ref, h_q


def synthetic_homography(seed: int, i: int, image_size: tuple[int, int] = (360, 640)) -> np.ndarray:
    """Query-``i`` -> reference-``i`` pixel mapping of the synthetic place ``i``.

    Returns:
        ``float64 (3, 3)`` ``H`` with ``[x_r, y_r, 1] ~ H @ [x_q, y_q, 1]``, normalised so that
        ``H[2, 2] == 1``.
    """
    h_ref, h_q = _place_geometry(int(seed), int(i), tuple(image_size))
    hm = h_ref @ np.linalg.inv(h_q)
    return hm / hm[2, 2]
