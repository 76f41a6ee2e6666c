"""Night illumination of the canvas: exposure, gamma, colour cast, lit windows, lamp glare, in
exact arithmetic only (:mod:`._exact`)."""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from ._canvas import World
from ._difficulty import SyntheticDifficulty
from ._exact import gaussian_blur, resize_bilinear, to_grid

__all__ = ["to_night", "vignette"]

_CASTS = ((1.0, 0.78, 0.5), (0.62, 0.75, 1.0), (0.9, 0.85, 1.0), (1.0, 0.9, 0.7))


@lru_cache(maxsize=8)
def _gamma_table(gamma: float) -> np.ndarray:
    """``(k / 255) ** gamma`` for ``k = 0..255``, grid-rounded: ``float64 (256,)``."""
    return np.array([to_grid((k / 255.0) ** gamma) for k in range(256)], np.float64)


def _block_mean4(a: np.ndarray) -> np.ndarray:
    """Mean of 4x4 blocks (fixed order of 16 elementwise adds): ``(H // 4, W // 4, C)``."""
    hq, wq = a.shape[0] // 4, a.shape[1] // 4
    acc = np.zeros((hq, wq) + a.shape[2:], np.float64)
    for dy in range(4):
        for dx in range(4):
            acc = acc + a[dy : 4 * hq : 4, dx : 4 * wq : 4]
    return acc / 16.0


def to_night(world: World, rng: np.random.Generator, diff: SyntheticDifficulty) -> np.ndarray:
    """Night version of the canvas: ``float64 (Hc, Wc, 3)`` in [0, 1] (before noise).

    Args:
        world: The day canvas with its sky mask, lit rectangles and lamps.
        rng: Random stream of the night view.
        diff: Difficulty (ambient exposure, gamma, glare strength).
    """
    cast = np.array(_CASTS[int(rng.integers(len(_CASTS)))], np.float64)
    # ambient level: dark, yet bright enough that the facade outlines stay visible to an edge
    # detector next to the lit windows (v3 had 0.11-0.22, gamma 1.35: its top-100 Edge Boxes were
    # almost all tiny, far from real night images, e.g. Gardens Point night_right)
    amb = float(rng.uniform(*diff.night_ambient))
    lut = _gamma_table(float(diff.night_gamma))[:, None] * (amb * cast)
    night = lut[world.img, np.arange(3)]  # (Hc, Wc, 3) float64, gamma + exposure + cast
    hc = night.shape[0]
    sky_col = np.array([0.02, 0.03, 0.07], np.float64) * rng.uniform(0.6, 1.4)
    grad = np.linspace(1.0, 1.8, hc, dtype=np.float64)[:, None, None]
    np.copyto(night, np.broadcast_to(sky_col * grad, night.shape), where=world.sky[..., None])
    light = np.zeros_like(night)
    for x0, y0, x1, y1, col, alpha in world.lit:
        if rng.random() < 0.85:
            c = np.asarray(col, np.float64) / 255.0 * rng.uniform(0.4, 0.7)
            region = world.img[max(0, y0) : y1, max(0, x0) : x1].astype(np.float64) / 255.0
            lit = c * ((1.0 - alpha) + alpha * region)  # lit from behind: keeps the structure
            night[max(0, y0) : y1, max(0, x0) : x1] = lit
            light[max(0, y0) : y1, max(0, x0) : x1] = c
    for cx, cy, r in world.lamps:
        cv2.circle(light, (int(cx), int(cy)), max(2, int(r * 0.35)), (1.0, 0.9, 0.65), -1)
    # glow: blurred light at a quarter resolution
    small = gaussian_blur(_block_mean4(light), max(1.0, world.unit / 60.0))
    night += diff.glow * resize_bilinear(small, light.shape[:2])
    for cx, cy, r in world.lamps:  # bright lamp cores
        cv2.circle(night, (int(cx), int(cy)), max(2, int(r * 0.15)), (1.0, 1.0, 0.92), -1)
    return night


@lru_cache(maxsize=8)
def vignette(h: int, w: int) -> np.ndarray:
    """Radial fall-off ``1 - 0.175 r^2`` (``r`` = 1 at the edge midpoints): ``float64 (h, w)``."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    dx, dy = (xx - w / 2) / (w / 2), (yy - h / 2) / (h / 2)
    return 1.0 - 0.175 * (dx * dx + dy * dy)
