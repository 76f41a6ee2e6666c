"""One place's world canvas: sky, a row of buildings, sidewalk, road and street furniture."""

from __future__ import annotations

import cv2
import numpy as np

from ._canvas import World, fill_textured
from ._difficulty import SyntheticDifficulty
from ._facade import draw_building, random_style, style_bank
from ._street import draw_lamp, draw_traffic_sign, draw_tree

__all__ = ["render_world"]

#: Stream key of the route-wide shared buildings (perceptual aliasing between places).
_POOL_KEY = 7_919


def render_world(
    seed: int, i: int, hc: int, wc: int, unit: float, diff: SyntheticDifficulty
) -> World:
    """The day canvas of place ``i``: sky, buildings, sidewalk, road, trees, lamps, signs.

    Args:
        seed, i: Route seed and place index (the canvas depends on nothing else).
        hc, wc: Canvas size in pixels.
        unit: View height in canvas pixels (sizes are given in this unit).
        diff: Difficulty (style sharing, repeated buildings, lit windows).

    Returns:
        The :class:`World` with its ``uint8 (hc, wc, 3)`` image, sky mask and light sources.
    """
    rng = np.random.default_rng([seed, i, 2])
    bank = style_bank(seed)
    world = World(hc, wc, unit)
    img = world.img
    base = int(0.70 * hc)
    # sky: vertical gradient + a few soft clouds
    top_col = np.array([rng.uniform(90, 140), rng.uniform(140, 180), rng.uniform(200, 240)])
    bot_col = np.array([rng.uniform(190, 225), rng.uniform(205, 230), rng.uniform(225, 245)])
    tgrad = np.linspace(0, 1, base, dtype=np.float64)[:, None, None]
    img[:base] = ((1 - tgrad) * top_col + tgrad * bot_col).astype(np.uint8)
    world.sky[:base] = True
    # buildings along the street
    x = -int(rng.uniform(0, 0.2) * unit)
    while x < wc:
        b_rng = rng
        if rng.random() < diff.repeat_facades:  # a copy of one of the route's shared buildings
            b_rng = np.random.default_rng([seed, _POOL_KEY, int(rng.integers(diff.facade_pool))])
        bw = int(b_rng.uniform(0.55, 1.1) * unit)
        top = int(b_rng.uniform(0.06, 0.32) * hc)
        if b_rng.random() < diff.style_share:
            style = bank[int(b_rng.integers(len(bank)))]
        else:
            style = random_style(b_rng)
        x1 = min(wc, x + bw)
        world.sky[top:base, max(0, x) : x1] = False
        draw_building(world, x, x1, top, base, style, b_rng, diff.lit_windows)
        x = x1 + (int(rng.uniform(0.02, 0.12) * unit) if rng.random() < 0.3 else 0)
    # sidewalk and road
    side_h = int(0.1 * hc)
    fill_textured(world, (0, base, wc, base + side_h), (165, 160, 150), ("gravel", 0.5, 0.12), rng)
    for k in range(0, wc, max(8, int(0.18 * unit))):  # paving joints
        cv2.line(img, (k, base), (k - int(0.05 * unit), base + side_h), (135, 130, 125), 1)
    cv2.rectangle(
        img,
        (0, base + side_h),
        (wc, base + side_h + max(2, int(0.015 * unit))),
        (200, 200, 195),
        -1,
    )
    fill_textured(
        world,
        (0, base + side_h + max(2, int(0.015 * unit)), wc, hc),
        (70, 70, 75),
        ("gravel", 0.4, 0.18),
        rng,
    )
    lane_y = base + side_h + int(0.17 * unit)
    off = int(rng.uniform(0, 0.3 * unit))
    for k in range(-off, wc, int(0.35 * unit)):
        cv2.rectangle(
            img,
            (k, lane_y),
            (k + int(0.18 * unit), lane_y + max(2, int(0.015 * unit))),
            (225, 225, 215),
            -1,
        )
    # street furniture in front of the facades
    ground = base + int(0.06 * hc)
    for _ in range(int(rng.integers(0, 3))):
        draw_tree(world, int(rng.uniform(0.05, 0.95) * wc), ground, rng)
    for _ in range(int(rng.integers(1, 3))):
        draw_lamp(world, int(rng.uniform(0.05, 0.95) * wc), ground, rng)
    if rng.random() < 0.6:
        draw_traffic_sign(world, int(rng.uniform(0.1, 0.9) * wc), ground, rng)
    return world
