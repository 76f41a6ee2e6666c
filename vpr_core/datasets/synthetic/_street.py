"""Street furniture in front of the facades: trees, lamps (night glare sources), traffic signs."""

from __future__ import annotations

import cv2
import numpy as np

from ._canvas import World
from ._exact import normal
from ._textures import tex_patch

__all__ = ["draw_lamp", "draw_traffic_sign", "draw_tree"]


def draw_tree(world: World, x: int, ground: int, rng: np.random.Generator) -> None:
    """A trunk and a crown of overlapping discs with a leaf texture, standing at ``x``."""
    u = world.unit
    img = world.img
    th = int(rng.uniform(0.35, 0.55) * u)
    tw = max(2, int(rng.uniform(0.02, 0.035) * u))
    cv2.rectangle(img, (x - tw // 2, ground - th), (x + tw // 2, ground), (70, 50, 35), -1)
    r0 = rng.uniform(0.09, 0.15) * u
    cy = ground - th
    hc, wc = img.shape[:2]
    x0, x1 = max(0, int(x - 2.2 * r0)), min(wc, int(x + 2.2 * r0))
    y0, y1 = max(0, int(cy - 2.2 * r0)), min(hc, int(cy + 1.6 * r0))
    if x1 <= x0 or y1 <= y0:
        return
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    for _ in range(int(rng.integers(4, 8))):
        cx = int(x - x0 + normal(rng, 0, 0.6 * r0))
        cyy = int(cy - y0 + normal(rng, -0.3 * r0, 0.45 * r0))
        cv2.circle(mask, (cx, cyy), int(r0 * rng.uniform(0.55, 0.95)), 1, -1)
    green = np.array([rng.uniform(40, 80), rng.uniform(100, 150), rng.uniform(30, 60)], np.float64)
    t = tex_patch("grass", 0.5 * u / 360.0, y1 - y0, x1 - x0, rng)
    leaves = np.clip(green[None, None, :] * (1.0 + 0.35 * t[..., None]), 0, 255).astype(np.uint8)
    m = mask.astype(bool)
    img[y0:y1, x0:x1][m] = leaves[m]
    world.sky[y0:y1, x0:x1][m] = False


def draw_lamp(world: World, x: int, ground: int, rng: np.random.Generator) -> None:
    """A street lamp (its head becomes a glare source at night)."""
    u = world.unit
    h = int(rng.uniform(0.5, 0.7) * u)
    w = max(2, int(0.012 * u))
    top = ground - h
    cv2.rectangle(world.img, (x - w // 2, top), (x + w // 2, ground), (45, 45, 50), -1)
    arm = int(0.06 * u) * (1 if rng.random() < 0.5 else -1)
    cv2.line(world.img, (x, top), (x + arm, top), (45, 45, 50), w)
    head = (x + arm, top + max(2, int(0.012 * u)))
    cv2.ellipse(
        world.img,
        head,
        (max(2, int(0.03 * u)), max(1, int(0.012 * u))),
        0,
        0,
        360,
        (200, 200, 190),
        -1,
    )
    world.sky[max(0, top - 2) : ground, max(0, x - w) : x + w] = False
    world.lamps.append((head[0], head[1], float(rng.uniform(0.06, 0.11) * u)))


def draw_traffic_sign(world: World, x: int, ground: int, rng: np.random.Generator) -> None:
    """A pole with a prohibition, direction or warning sign."""
    u = world.unit
    h = int(rng.uniform(0.3, 0.42) * u)
    w = max(2, int(0.01 * u))
    cv2.rectangle(world.img, (x - w // 2, ground - h), (x + w // 2, ground), (110, 110, 115), -1)
    r = max(3, int(rng.uniform(0.035, 0.05) * u))
    c = (x, ground - h)
    kind = int(rng.integers(3))
    if kind == 0:
        cv2.circle(world.img, c, r, (200, 20, 20), -1)
        cv2.circle(world.img, c, int(r * 0.7), (245, 245, 245), -1)
    elif kind == 1:
        cv2.circle(world.img, c, r, (20, 60, 180), -1)
        # arrow: shaft + head as integer polygons (no anti-aliasing, no trigonometry)
        t = max(1, r // 10)
        cv2.rectangle(world.img, (c[0] - r // 2, c[1] - t), (c[0], c[1] + t), (250, 250, 250), -1)
        head = np.array(
            [[c[0], c[1] - r // 3], [c[0] + r // 2, c[1]], [c[0], c[1] + r // 3]], np.int32
        )
        cv2.fillPoly(world.img, [head], (250, 250, 250))
    else:
        pts = np.array(
            [[c[0], c[1] - r], [c[0] - r, c[1] + r * 3 // 4], [c[0] + r, c[1] + r * 3 // 4]],
            np.int32,
        )
        cv2.fillPoly(world.img, [pts], (200, 20, 20))
        cv2.fillPoly(world.img, [((pts - c) * 0.65 + c).astype(np.int32)], (245, 240, 230))
