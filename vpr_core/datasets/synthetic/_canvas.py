"""The world canvas of one place and its fill / paste / text primitives: integer-coordinate
OpenCV ``LINE_8`` drawing and elementwise float64 fills (:mod:`._exact`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import cast

import cv2
import numpy as np

from ._exact import resize_area
from ._textures import tex_patch, texture_sources

__all__ = ["World", "fill_textured", "paste_poster", "put_text_fit"]


class World:
    """One place's world canvas (day RGB) plus the light sources used for its night version."""

    def __init__(self, hc: int, wc: int, unit: float) -> None:
        self.img = np.zeros((hc, wc, 3), np.uint8)
        self.sky = np.zeros((hc, wc), bool)
        self.unit = unit  # view height in canvas pixels
        # lit rectangles: (x0, y0, x1, y1, light colour, alpha); at night the rectangle shows
        # colour * ((1 - alpha) + alpha * day pixel): alpha 1 keeps a sign's print readable
        self.lit: list[tuple[int, int, int, int, tuple, float]] = []
        self.lamps: list[tuple[int, int, float]] = []  # glare centres + radius


def fill_textured(
    world: World,
    rect: tuple[int, int, int, int],
    color: Sequence[float],
    texture: tuple[str, float, float],
    rng: np.random.Generator,
) -> None:
    """Fill the canvas rectangle ``rect = (x0, y0, x1, y1)`` with ``color * (1 + gain * t)``,
    ``t`` the texture of ``texture = (name, scale, gain)`` (clipped to the canvas)."""
    (x0, y0, x1, y1), (tex, scale, gain) = rect, texture
    hc, wc = world.img.shape[:2]
    x0, x1, y0, y1 = max(0, x0), min(wc, x1), max(0, y0), min(hc, y1)
    if x1 <= x0 or y1 <= y0:
        return
    t = tex_patch(tex, scale * world.unit / 360.0, y1 - y0, x1 - x0, rng)
    c = np.asarray(color, np.float64)
    region = c[None, None, :] * (1.0 + gain * t[..., None])
    world.img[y0:y1, x0:x1] = np.clip(region, 0, 255).astype(np.uint8)


def paste_poster(world: World, x0: int, y0: int, w: int, h: int, rng: np.random.Generator) -> None:
    """Paste a random crop of a bundled image, framed, into ``(x0, y0, w, h)`` (if it fits)."""
    hc, wc = world.img.shape[:2]
    if w < 6 or h < 6 or x0 < 0 or y0 < 0 or x0 + w > wc or y0 + h > hc:
        return
    posters = cast(list[np.ndarray], texture_sources()["posters"])
    src = posters[int(rng.integers(len(posters)))]
    sh, sw = src.shape[:2]
    aspect = w / h
    ch = int(rng.uniform(0.45, 1.0) * sh)
    cw = min(sw, max(8, int(ch * aspect)))
    ch = min(sh, max(8, int(cw / aspect)))
    oy, ox = int(rng.integers(0, sh - ch + 1)), int(rng.integers(0, sw - cw + 1))
    crop = src[oy : oy + ch, ox : ox + cw]
    if rng.random() < 0.5:
        crop = crop[:, ::-1]
    b = max(1, int(0.008 * world.unit))
    world.img[y0 : y0 + h, x0 : x0 + w] = (30, 30, 30)
    small = resize_area(crop, (h - 2 * b, w - 2 * b))
    world.img[y0 + b : y0 + h - b, x0 + b : x0 + w - b] = np.floor(small + 0.5).astype(np.uint8)


def put_text_fit(
    img: np.ndarray,
    text: str,
    x0: int,
    y0: int,
    x1: int,
    y1: int,
    color: tuple,
    thickness_scale: float = 1.0,
) -> None:
    """Centre ``text`` in a rectangle, scaled to fit (Hershey font, ``LINE_8``: integer-exact)."""
    font = cv2.FONT_HERSHEY_DUPLEX
    w, h = max(1, x1 - x0), max(1, y1 - y0)
    (tw, th), _ = cv2.getTextSize(text, font, 1.0, 1)
    s = min(0.85 * w / tw, 0.7 * h / th)
    if s <= 0.05:
        return
    thick = max(1, round(s * 1.6 * thickness_scale))
    (tw, th), _ = cv2.getTextSize(text, font, s, thick)
    org = (x0 + (w - tw) // 2, y0 + (h + th) // 2)
    cv2.putText(img, text, org, font, s, color, thick, cv2.LINE_8)
