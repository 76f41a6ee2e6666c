"""Render one place: the day reference and the night query with their homography."""

from __future__ import annotations

import cv2
import numpy as np

from .camera import _CANVAS_SCALE, _place_geometry
from .night import _draw_occluders, _night, _vignette
from .world import _render_world


def _to_uint8(a: np.ndarray) -> np.ndarray:
    return (np.clip(a, 0, 1) * 255.0 + 0.5).astype(np.uint8)


def render_synthetic_place(
    seed: int, i: int, image_size: tuple[int, int] = (360, 640)
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Render place ``i`` of the synthetic route (independent of how many places are asked for).

    Args:
        seed: Route seed (``>= 0``).
        i: Place index (``>= 0``).
        image_size: ``(H, W)`` of both views.

    Returns:
        ``(reference, query, H)``: ``uint8 (H, W, 3)`` RGB day reference, ``uint8 (H, W, 3)``
        RGB night query, and ``float64 (3, 3)`` query -> reference pixel homography.
    """
    seed, i = int(seed), int(i)
    h, w = (int(v) for v in image_size)
    hc, wc = round(_CANVAS_SCALE[0] * h), round(_CANVAS_SCALE[1] * w)
    world = _render_world(seed, i, hc, wc, float(h))
    h_ref, h_q = _place_geometry(seed, i, (h, w))
    fx = np.random.default_rng([seed, i, 3])
    # day reference: mild exposure jitter + light sensor noise, occasionally a passer-by
    ref = cv2.warpPerspective(world.img, h_ref, (w, h), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REFLECT101).astype(np.float32) / 255.0
    ref = np.clip(ref * fx.uniform(0.9, 1.1) + fx.uniform(-0.03, 0.03), 0, 1)
    _draw_occluders(ref, fx, night=False)
    ref += 0.008 * fx.standard_normal(ref.shape, dtype=np.float32)
    # night query
    night = _night(world, fx)
    qry = cv2.warpPerspective(night, h_q, (w, h), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REFLECT101)
    _draw_occluders(qry, fx, night=True)
    qry = cv2.GaussianBlur(qry, (0, 0), fx.uniform(0.5, 1.0) * h / 360.0)
    qry += float(fx.uniform(0.02, 0.04)) * fx.standard_normal(qry.shape, dtype=np.float32)
    qry *= _vignette(h, w)[..., None]
    hm = h_ref @ np.linalg.inv(h_q)
    return _to_uint8(ref), _to_uint8(qry), hm / hm[2, 2]
