"""The embedded default dataset: a generated street route (DESIGN.md section 3)."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from ..utils import cache_dir, logger, progress, short_hash
from .core import PlaceDataset, _check_tolerance, _frame_aligned

# ----------------------------------------------------------------------------------------------
# Synthetic generator (DESIGN.md section 3)
# ----------------------------------------------------------------------------------------------

SYNTHETIC_VERSION = 5
_CANVAS_SCALE = (1.45, 1.8)  # world canvas size in units of the view (H, W)

_SHOP_WORDS = (
    "CAFE", "BAR", "BOOKS", "BAKERY", "HOTEL", "BANK", "MARKET", "PIZZA", "KIOSK", "SALON",
    "DELI", "TAXI", "POST", "OPTIK", "APOTHEKE", "SUSHI", "FLORIST", "GYM", "CINEMA", "LAUNDRY",
    "TOYS", "SHOES", "DINER", "TEA", "MUSIC", "PRINT", "BIKES", "GELATO", "RAMEN", "CAFE",
)
_WALL_TEXTURES = ("brick", "gravel", "plaster", "grass")


@lru_cache(maxsize=1)
def _texture_sources() -> dict[str, np.ndarray]:
    """Bundled scikit-image images: grey textures (float32 in [0, 1]) and RGB posters."""
    import skimage.data as skd

    grey = {
        "brick": skd.brick(),
        "gravel": skd.gravel(),
        "grass": skd.grass(),
    }
    g = skd.gravel().astype(np.float32)
    grey["plaster"] = cv2.GaussianBlur(g, (0, 0), 3.0).astype(np.uint8)
    out: dict[str, np.ndarray] = {}
    for k, v in grey.items():
        v = v.astype(np.float32)
        v = (v - v.mean()) / (v.std() + 1e-6)
        out[k] = v.astype(np.float32)
    posters = [skd.coffee(), skd.astronaut(), skd.chelsea(), skd.rocket(),
               skd.hubble_deep_field(), skd.immunohistochemistry(), skd.colorwheel(),
               np.repeat(skd.text()[..., None], 3, axis=2), np.repeat(skd.coins()[..., None], 3, 2),
               np.repeat(skd.moon()[..., None], 3, axis=2), np.repeat(skd.page()[..., None], 3, 2),
               skd.logo()[..., :3], np.repeat(skd.camera()[..., None], 3, axis=2)]
    out["posters"] = posters  # type: ignore[assignment]
    return out


@lru_cache(maxsize=64)
def _texture(name: str, scale: float) -> np.ndarray:
    src = _texture_sources()[name]
    if abs(scale - 1.0) > 1e-3:
        size = (max(8, round(src.shape[1] * scale)), max(8, round(src.shape[0] * scale)))
        src = cv2.resize(src, size, interpolation=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR)
    return src


def _tex_patch(name: str, scale: float, h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """A ``float32 (h, w)`` zero-mean unit-std texture crop (tiled when needed)."""
    t = _texture(name, round(scale, 2))
    th, tw = t.shape
    oy, ox = int(rng.integers(th)), int(rng.integers(tw))
    reps = (math.ceil((h + oy) / th), math.ceil((w + ox) / tw))
    if reps != (1, 1):
        t = np.tile(t, reps)
    return t[oy:oy + h, ox:ox + w]


def _style_bank(seed: int, n: int = 6) -> list[dict]:
    """Facade styles shared by all places of one seed (the source of perceptual aliasing)."""
    rng = np.random.default_rng([seed, 999_983])
    return [_random_style(rng) for _ in range(n)]


def _random_style(rng: np.random.Generator) -> dict:
    base = rng.choice([
        (200, 170, 140), (180, 90, 70), (225, 215, 190), (150, 150, 155), (210, 190, 120),
        (120, 140, 160), (190, 120, 100), (235, 235, 230), (170, 160, 120), (140, 100, 80),
    ])
    return {
        "color": tuple(int(c) for c in np.clip(base + rng.normal(0, 12, 3), 30, 250)),
        "texture": str(rng.choice(_WALL_TEXTURES, p=[0.4, 0.2, 0.3, 0.1])),
        "tex_scale": float(rng.uniform(0.35, 0.8)),
        "tex_gain": float(rng.uniform(0.08, 0.2)),
        "win_w": float(rng.uniform(0.06, 0.11)),  # units of view height
        "win_h": float(rng.uniform(0.08, 0.15)),
        "gap_x": float(rng.uniform(0.04, 0.09)),
        "gap_y": float(rng.uniform(0.05, 0.09)),
        "glass": tuple(int(c) for c in rng.integers(30, 110, 3)),
        "frame": tuple(int(c) for c in rng.choice([(240, 240, 235), (60, 50, 45), (120, 30, 30),
                                                     (30, 60, 40), (200, 190, 160)])),
        "mullion": bool(rng.random() < 0.6),
        "shutters": bool(rng.random() < 0.3),
        "shutter_color": tuple(int(c) for c in rng.integers(20, 200, 3)),
        "arch": bool(rng.random() < 0.25),
        "roof": str(rng.choice(["flat", "cornice", "gable"], p=[0.3, 0.45, 0.25])),
        "floor_h": float(rng.uniform(0.19, 0.24)),
    }


def _put_text_fit(img: np.ndarray, text: str, x0: int, y0: int, x1: int, y1: int,
                  color: tuple, thickness_scale: float = 1.0) -> None:
    font = cv2.FONT_HERSHEY_DUPLEX
    w, h = max(1, x1 - x0), max(1, y1 - y0)
    (tw, th), _ = cv2.getTextSize(text, font, 1.0, 1)
    s = min(0.85 * w / tw, 0.7 * h / th)
    if s <= 0.05:
        return
    thick = max(1, round(s * 1.6 * thickness_scale))
    (tw, th), _ = cv2.getTextSize(text, font, s, thick)
    org = (x0 + (w - tw) // 2, y0 + (h + th) // 2)
    cv2.putText(img, text, org, font, s, color, thick, cv2.LINE_AA)


class _World:
    """One place's world canvas (day RGB) plus the light sources used for its night version."""

    def __init__(self, hc: int, wc: int, unit: float) -> None:
        self.img = np.zeros((hc, wc, 3), np.uint8)
        self.sky = np.zeros((hc, wc), bool)
        self.unit = unit  # view height in canvas pixels
        # lit rectangles: (x0, y0, x1, y1, light colour, alpha); at night the rectangle shows
        # colour * ((1 - alpha) + alpha * day pixel): alpha 1 keeps a sign's print readable
        self.lit: list[tuple[int, int, int, int, tuple, float]] = []
        self.lamps: list[tuple[int, int, float]] = []  # glare centres + radius


def _fill_textured(world: _World, x0: int, y0: int, x1: int, y1: int, color: Sequence[float],
                   tex: str, scale: float, gain: float, rng: np.random.Generator) -> None:
    hc, wc = world.img.shape[:2]
    x0, x1, y0, y1 = max(0, x0), min(wc, x1), max(0, y0), min(hc, y1)
    if x1 <= x0 or y1 <= y0:
        return
    t = _tex_patch(tex, scale * world.unit / 360.0, y1 - y0, x1 - x0, rng)
    c = np.asarray(color, np.float32)
    region = c[None, None, :] * (1.0 + gain * t[..., None])
    world.img[y0:y1, x0:x1] = np.clip(region, 0, 255).astype(np.uint8)


def _paste_poster(world: _World, x0: int, y0: int, w: int, h: int,
                  rng: np.random.Generator) -> None:
    hc, wc = world.img.shape[:2]
    if w < 6 or h < 6 or x0 < 0 or y0 < 0 or x0 + w > wc or y0 + h > hc:
        return
    posters = _texture_sources()["posters"]
    src = posters[int(rng.integers(len(posters)))]
    sh, sw = src.shape[:2]
    aspect = w / h
    ch = int(rng.uniform(0.45, 1.0) * sh)
    cw = min(sw, max(8, int(ch * aspect)))
    ch = min(sh, max(8, int(cw / aspect)))
    oy, ox = int(rng.integers(0, sh - ch + 1)), int(rng.integers(0, sw - cw + 1))
    crop = src[oy:oy + ch, ox:ox + cw]
    if rng.random() < 0.5:
        crop = crop[:, ::-1]
    b = max(1, int(0.008 * world.unit))
    world.img[y0:y0 + h, x0:x0 + w] = (30, 30, 30)
    world.img[y0 + b:y0 + h - b, x0 + b:x0 + w - b] = cv2.resize(
        np.ascontiguousarray(crop), (w - 2 * b, h - 2 * b), interpolation=cv2.INTER_AREA)


def _draw_building(world: _World, x0: int, x1: int, top: int, base: int, style: dict,
                   rng: np.random.Generator) -> None:
    u = world.unit
    img = world.img
    color = np.clip(np.asarray(style["color"], float) + rng.normal(0, 6, 3), 20, 250)
    _fill_textured(world, x0, top, x1, base, color, style["texture"], style["tex_scale"],
                   style["tex_gain"], rng)
    dark = tuple(int(c * 0.55) for c in color)
    # roof
    if style["roof"] == "cornice":
        ch = max(2, int(0.03 * u))
        cv2.rectangle(img, (x0 - 2, top), (x1 + 2, top + ch), dark, -1)
        cv2.rectangle(img, (x0 - 2, top + ch), (x1 + 2, top + ch + max(1, ch // 3)),
                      tuple(int(c * 0.8) for c in color), -1)
    elif style["roof"] == "gable":
        peak = top - int(rng.uniform(0.1, 0.22) * u)
        pts = np.array([[x0, top], [(x0 + x1) // 2, peak], [x1, top]], np.int32)
        roof_col = tuple(int(c) for c in rng.choice([(120, 50, 40), (70, 70, 80), (90, 60, 40)]))
        cv2.fillPoly(img, [pts], roof_col)
        world.sky[max(0, peak):top, x0:x1] = False
        for k in range(1, 6):  # roof tile rows, inside the gable
            y = top - (top - peak) * k // 6
            half = (x1 - x0) * (1 - k / 6) / 2
            xm = (x0 + x1) / 2
            cv2.line(img, (int(xm - half), y), (int(xm + half), y),
                     tuple(int(c * 0.7) for c in roof_col), 1)
        cv2.fillPoly(world.sky.view(np.uint8), [pts], 0)
    # ground floor
    floor_h = int(style["floor_h"] * u)
    gf_top = base - floor_h
    cv2.line(img, (x0, gf_top), (x1, gf_top), dark, max(1, int(0.012 * u)))
    # window grid (upper floors)
    ww, wh = int(style["win_w"] * u), int(style["win_h"] * u)
    gx, gy = int(style["gap_x"] * u), int(style["gap_y"] * u)
    bw = x1 - x0
    ncol = max(0, (bw - gx) // (ww + gx))
    if ncol > 0 and ww > 2 and wh > 2:
        mx = x0 + (bw - (ncol * ww + (ncol - 1) * gx)) // 2
        y = top + int(0.07 * u)
        frame = style["frame"]
        ft = max(1, int(0.008 * u))
        while y + wh < gf_top - int(0.04 * u):
            for c in range(ncol):
                wx = mx + c * (ww + gx)
                glass = np.clip(np.asarray(style["glass"]) + rng.normal(0, 10, 3), 0, 255)
                if rng.random() < 0.15:  # a curtain / blind: local uniqueness
                    glass = rng.integers(120, 230, 3)
                glass_t = tuple(int(v) for v in glass)
                if style["shutters"]:
                    sw = ww // 3
                    cv2.rectangle(img, (wx - sw, y), (wx, y + wh), style["shutter_color"], -1)
                    cv2.rectangle(img, (wx + ww, y), (wx + ww + sw, y + wh),
                                  style["shutter_color"], -1)
                cv2.rectangle(img, (wx, y), (wx + ww, y + wh), glass_t, -1)
                # sky reflection on the upper part of the glass
                cv2.rectangle(img, (wx, y), (wx + ww, y + wh // 3),
                              tuple(min(255, v + 35) for v in glass_t), -1)
                if style["arch"]:
                    cv2.ellipse(img, (wx + ww // 2, y), (ww // 2, max(1, ww // 3)), 0, 180, 360,
                                glass_t, -1)
                cv2.rectangle(img, (wx, y), (wx + ww, y + wh), frame, ft)
                if style["mullion"]:
                    cv2.line(img, (wx + ww // 2, y), (wx + ww // 2, y + wh), frame, ft)
                    cv2.line(img, (wx, y + wh // 2), (wx + ww, y + wh // 2), frame, ft)
                cv2.rectangle(img, (wx - ft, y + wh), (wx + ww + ft, y + wh + 2 * ft), dark, -1)
                if rng.random() < 0.35:
                    warm = (255, int(rng.uniform(190, 235)), int(rng.uniform(100, 170)))
                    world.lit.append((wx, y, wx + ww, y + wh, warm, 0.45))
            y += wh + gy
    # ground floor: door, shop window, sign, posters
    door_w = int(rng.uniform(0.09, 0.13) * u)
    door_h = int(0.8 * floor_h)
    dx = int(rng.uniform(x0 + 0.05 * bw, max(x0 + 0.05 * bw + 1, x1 - door_w - 0.05 * bw)))
    door_col = tuple(int(c) for c in rng.choice([(80, 40, 30), (30, 50, 90), (40, 40, 40),
                                                  (140, 20, 30), (20, 90, 60)]))
    cv2.rectangle(img, (dx, base - door_h), (dx + door_w, base), door_col, -1)
    cv2.rectangle(img, (dx, base - door_h), (dx + door_w, base), (20, 20, 20),
                  max(1, int(0.008 * u)))
    cv2.circle(img, (dx + int(door_w * 0.8), base - door_h // 2), max(1, int(0.008 * u)),
               (220, 200, 60), -1)
    shop = rng.random() < 0.65
    free = [(x0 + int(0.03 * bw), dx - int(0.03 * bw)), (dx + door_w + int(0.03 * bw),
                                                        x1 - int(0.03 * bw))]
    free = [(a, b) for a, b in free if b - a > 0.12 * u]
    if shop and free:
        a, b = free.pop(int(rng.integers(len(free))))
        sh_top = base - int(0.75 * floor_h)
        cv2.rectangle(img, (a, sh_top), (b, base - int(0.05 * u)), (60, 70, 80), -1)
        cv2.rectangle(img, (a, sh_top), (b, sh_top + (base - sh_top) // 3), (90, 100, 110), -1)
        cv2.rectangle(img, (a, sh_top), (b, base - int(0.05 * u)), (25, 25, 25),
                      max(1, int(0.01 * u)))
        world.lit.append((a, sh_top, b, base - int(0.05 * u), (255, 240, 200), 0.5))
        # the sign above the shop
        sign_col = tuple(int(c) for c in rng.integers(0, 256, 3))
        txt_col = (255, 255, 255) if sum(sign_col) < 380 else (20, 20, 20)
        s_top = gf_top + int(0.01 * u)
        s_bot = sh_top - int(0.01 * u)
        if s_bot - s_top > 4:
            cv2.rectangle(img, (a, s_top), (b, s_bot), sign_col, -1)
            word = str(rng.choice(_SHOP_WORDS))
            if rng.random() < 0.4:
                word += f" {int(rng.integers(1, 99))}"
            _put_text_fit(img, word, a, s_top, b, s_bot, txt_col)
            if rng.random() < 0.6:
                world.lit.append((a, s_top, b, s_bot, (255, 255, 245), 1.0))
    for a, b in free:
        if rng.random() < 0.7:
            pw = int(min(b - a, rng.uniform(0.1, 0.2) * u))
            ph = int(min(0.65 * floor_h, pw * rng.uniform(1.0, 1.5)))
            px = int(rng.uniform(a, max(a + 1, b - pw)))
            _paste_poster(world, px, base - ph - int(0.08 * u), pw, ph, rng)
    # occasional big billboard on the facade (a strong, unique landmark)
    if rng.random() < 0.25 and bw > 0.35 * u and gf_top - top > 0.35 * u:
        bw2 = int(rng.uniform(0.25, 0.4) * u)
        bh2 = int(bw2 * rng.uniform(0.6, 1.0))
        bx = int(rng.uniform(x0 + 0.05 * bw, max(x0 + 0.05 * bw + 1, x1 - bw2 - 0.05 * bw)))
        by = int(rng.uniform(top + 0.06 * u, max(top + 0.06 * u + 1, gf_top - bh2 - 0.05 * u)))
        _paste_poster(world, bx, by, bw2, bh2, rng)


def _draw_tree(world: _World, x: int, ground: int, rng: np.random.Generator) -> None:
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
        cx = int(x - x0 + rng.normal(0, 0.6 * r0))
        cyy = int(cy - y0 + rng.normal(-0.3 * r0, 0.45 * r0))
        cv2.circle(mask, (cx, cyy), int(r0 * rng.uniform(0.55, 0.95)), 1, -1)
    green = np.array([rng.uniform(40, 80), rng.uniform(100, 150), rng.uniform(30, 60)], np.float32)
    t = _tex_patch("grass", 0.5 * u / 360.0, y1 - y0, x1 - x0, rng)
    leaves = np.clip(green[None, None, :] * (1.0 + 0.35 * t[..., None]), 0, 255).astype(np.uint8)
    m = mask.astype(bool)
    img[y0:y1, x0:x1][m] = leaves[m]
    world.sky[y0:y1, x0:x1][m] = False


def _draw_lamp(world: _World, x: int, ground: int, rng: np.random.Generator) -> None:
    u = world.unit
    h = int(rng.uniform(0.5, 0.7) * u)
    w = max(2, int(0.012 * u))
    top = ground - h
    cv2.rectangle(world.img, (x - w // 2, top), (x + w // 2, ground), (45, 45, 50), -1)
    arm = int(0.06 * u) * (1 if rng.random() < 0.5 else -1)
    cv2.line(world.img, (x, top), (x + arm, top), (45, 45, 50), w)
    head = (x + arm, top + max(2, int(0.012 * u)))
    cv2.ellipse(world.img, head, (max(2, int(0.03 * u)), max(1, int(0.012 * u))), 0, 0, 360,
                (200, 200, 190), -1)
    world.sky[max(0, top - 2):ground, max(0, x - w):x + w] = False
    world.lamps.append((head[0], head[1], float(rng.uniform(0.06, 0.11) * u)))


def _draw_traffic_sign(world: _World, x: int, ground: int, rng: np.random.Generator) -> None:
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
        cv2.arrowedLine(world.img, (c[0] - r // 2, c[1]), (c[0] + r // 2, c[1]),
                        (250, 250, 250), max(1, r // 5), tipLength=0.5)
    else:
        pts = np.array([[c[0], c[1] - r], [c[0] - r, c[1] + r * 3 // 4],
                        [c[0] + r, c[1] + r * 3 // 4]], np.int32)
        cv2.fillPoly(world.img, [pts], (200, 20, 20))
        cv2.fillPoly(world.img, [((pts - c) * 0.65 + c).astype(np.int32)], (245, 240, 230))


def _render_world(seed: int, i: int, hc: int, wc: int, unit: float) -> _World:
    rng = np.random.default_rng([seed, i, 2])
    bank = _style_bank(seed)
    world = _World(hc, wc, unit)
    img = world.img
    base = int(0.70 * hc)
    # sky: vertical gradient + a few soft clouds
    top_col = np.array([rng.uniform(90, 140), rng.uniform(140, 180), rng.uniform(200, 240)])
    bot_col = np.array([rng.uniform(190, 225), rng.uniform(205, 230), rng.uniform(225, 245)])
    tgrad = np.linspace(0, 1, base, dtype=np.float32)[:, None, None]
    img[:base] = ((1 - tgrad) * top_col + tgrad * bot_col).astype(np.uint8)
    world.sky[:base] = True
    # buildings along the street
    x = -int(rng.uniform(0, 0.2) * unit)
    while x < wc:
        bw = int(rng.uniform(0.55, 1.1) * unit)
        top = int(rng.uniform(0.06, 0.32) * hc)
        style = bank[int(rng.integers(len(bank)))] if rng.random() < 0.8 else _random_style(rng)
        x1 = min(wc, x + bw)
        world.sky[top:base, max(0, x):x1] = False
        _draw_building(world, x, x1, top, base, style, rng)
        x = x1 + (int(rng.uniform(0.02, 0.12) * unit) if rng.random() < 0.3 else 0)
    # sidewalk and road
    side_h = int(0.1 * hc)
    _fill_textured(world, 0, base, wc, base + side_h, (165, 160, 150), "gravel", 0.5, 0.12, rng)
    for k in range(0, wc, max(8, int(0.18 * unit))):  # paving joints
        cv2.line(img, (k, base), (k - int(0.05 * unit), base + side_h), (135, 130, 125), 1)
    cv2.rectangle(img, (0, base + side_h), (wc, base + side_h + max(2, int(0.015 * unit))),
                  (200, 200, 195), -1)
    _fill_textured(world, 0, base + side_h + max(2, int(0.015 * unit)), wc, hc, (70, 70, 75),
                   "gravel", 0.4, 0.18, rng)
    lane_y = base + side_h + int(0.17 * unit)
    off = int(rng.uniform(0, 0.3 * unit))
    for k in range(-off, wc, int(0.35 * unit)):
        cv2.rectangle(img, (k, lane_y), (k + int(0.18 * unit), lane_y + max(2, int(0.015 * unit))),
                      (225, 225, 215), -1)
    # street furniture in front of the facades
    ground = base + int(0.06 * hc)
    for _ in range(int(rng.integers(0, 3))):
        _draw_tree(world, int(rng.uniform(0.05, 0.95) * wc), ground, rng)
    for _ in range(int(rng.integers(1, 3))):
        _draw_lamp(world, int(rng.uniform(0.05, 0.95) * wc), ground, rng)
    if rng.random() < 0.6:
        _draw_traffic_sign(world, int(rng.uniform(0.1, 0.9) * wc), ground, rng)
    return world


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


def _night(world: _World, rng: np.random.Generator) -> np.ndarray:
    """Night version of the canvas: ``float32 (Hc, Wc, 3)`` in [0, 1] (before noise)."""
    casts = [(1.0, 0.78, 0.5), (0.62, 0.75, 1.0), (0.9, 0.85, 1.0), (1.0, 0.9, 0.7)]
    cast = np.array(casts[int(rng.integers(len(casts)))], np.float32)
    # ambient level: dark, yet bright enough that the facade outlines stay visible to an edge
    # detector next to the lit windows (v3 had 0.11-0.22, gamma 1.35: its top-100 Edge Boxes were
    # almost all tiny, far from real night images, e.g. Gardens Point night_right)
    amb = float(rng.uniform(0.3, 0.5))
    lut = (np.power(np.arange(256, dtype=np.float32) / 255.0, 1.15)[:, None] * (amb * cast))
    night = lut[world.img, np.arange(3)]  # (Hc, Wc, 3) float32, gamma + exposure + cast
    hc = night.shape[0]
    sky_col = np.array([0.02, 0.03, 0.07], np.float32) * rng.uniform(0.6, 1.4)
    grad = np.linspace(1.0, 1.8, hc, dtype=np.float32)[:, None, None]
    np.copyto(night, np.broadcast_to(sky_col * grad, night.shape), where=world.sky[..., None])
    light = np.zeros_like(night)
    for x0, y0, x1, y1, col, alpha in world.lit:
        if rng.random() < 0.85:
            c = np.asarray(col, np.float32) / 255.0 * rng.uniform(0.4, 0.7)
            region = world.img[max(0, y0):y1, max(0, x0):x1].astype(np.float32) / 255.0
            lit = c * ((1.0 - alpha) + alpha * region)  # lit from behind: keeps the structure
            night[max(0, y0):y1, max(0, x0):x1] = lit
            light[max(0, y0):y1, max(0, x0):x1] = c
    for cx, cy, r in world.lamps:
        cv2.circle(light, (int(cx), int(cy)), max(2, int(r * 0.35)), (1.0, 0.9, 0.65), -1)
    # glow: blurred light at a quarter resolution
    small = cv2.resize(light, (light.shape[1] // 4, light.shape[0] // 4),
                       interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), max(1.0, world.unit / 60.0))
    glow = cv2.resize(small, (light.shape[1], light.shape[0]), interpolation=cv2.INTER_LINEAR)
    night += 0.4 * glow
    for cx, cy, r in world.lamps:  # bright lamp cores
        cv2.circle(night, (int(cx), int(cy)), max(2, int(r * 0.15)), (1.0, 1.0, 0.92), -1)
    return night


def _draw_occluders(img: np.ndarray, rng: np.random.Generator, night: bool) -> None:
    """Pedestrian / car silhouettes in image coordinates (in place, ``float32`` in [0, 1])."""
    h, w = img.shape[:2]
    u = float(h)
    n = int(rng.integers(1, 3)) if night else int(rng.random() < 0.35)
    for _ in range(n):
        if rng.random() < 0.55:  # pedestrian
            ph = rng.uniform(0.35, 0.65) * u
            fx, fy = rng.uniform(0.05, 0.95) * w, rng.uniform(0.9, 1.05) * u
            col = tuple(float(c) for c in rng.uniform(0.0, 0.08 if night else 0.45, 3))
            bw = 0.22 * ph
            body = np.array([[fx - bw / 2, fy - 0.8 * ph], [fx + bw / 2, fy - 0.8 * ph],
                             [fx + bw * 0.35, fy - 0.42 * ph], [fx - bw * 0.35, fy - 0.42 * ph]])
            cv2.fillPoly(img, [body.astype(np.int32)], col)
            cv2.circle(img, (int(fx), int(fy - 0.88 * ph)), max(2, int(0.075 * ph)), col, -1)
            lw = max(2, int(0.07 * ph))
            cv2.line(img, (int(fx - bw * 0.2), int(fy - 0.45 * ph)), (int(fx - bw * 0.35), int(fy)),
                     col, lw)
            cv2.line(img, (int(fx + bw * 0.2), int(fy - 0.45 * ph)), (int(fx + bw * 0.3), int(fy)),
                     col, lw)
        else:  # car
            cw = rng.uniform(0.35, 0.6) * w
            ch = cw * 0.32
            x0 = rng.uniform(-0.2, 0.9) * w
            y1 = rng.uniform(0.95, 1.1) * u
            body_col = tuple(float(c) for c in (rng.uniform(0, 0.12, 3) if night
                                                 else rng.uniform(0.1, 0.8, 3)))
            cv2.rectangle(img, (int(x0), int(y1 - 0.6 * ch)), (int(x0 + cw), int(y1 - 0.15 * ch)),
                          body_col, -1)
            cabin = np.array([[x0 + 0.2 * cw, y1 - 0.6 * ch], [x0 + 0.3 * cw, y1 - ch],
                              [x0 + 0.72 * cw, y1 - ch], [x0 + 0.82 * cw, y1 - 0.6 * ch]])
            cv2.fillPoly(img, [cabin.astype(np.int32)], body_col)
            for wx in (x0 + 0.2 * cw, x0 + 0.8 * cw):
                cv2.circle(img, (int(wx), int(y1 - 0.15 * ch)), max(2, int(0.16 * ch)),
                           (0.02, 0.02, 0.02), -1)
            if night:  # head / tail lights with glare
                for lx, col in ((x0 + 0.03 * cw, (1.0, 0.95, 0.8)), (x0 + 0.97 * cw, (1.0, 0.15, 0.1))):
                    cv2.circle(img, (int(lx), int(y1 - 0.45 * ch)), max(3, int(0.22 * ch)),
                               tuple(0.5 * c for c in col), -1)
                    cv2.circle(img, (int(lx), int(y1 - 0.45 * ch)), max(2, int(0.08 * ch)),
                               col, -1)


def _to_uint8(a: np.ndarray) -> np.ndarray:
    return (np.clip(a, 0, 1) * 255.0 + 0.5).astype(np.uint8)


@lru_cache(maxsize=8)
def _vignette(h: int, w: int) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    return 1.0 - 0.175 * (((xx - w / 2) / (w / 2)) ** 2 + ((yy - h / 2) / (h / 2)) ** 2)


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


def _write_png(path: Path, rgb: np.ndarray) -> None:
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR),
                           [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:  # pragma: no cover - encoding a uint8 RGB array does not fail
        raise RuntimeError(f"could not encode {path}")
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(buf.tobytes())
    os.replace(tmp, path)


def load_synthetic(
    root: str | os.PathLike | None = None,
    n_places: int = 60,
    seed: int = 0,
    image_size: tuple[int, int] = (360, 640),
    tolerance: int = 0,
) -> PlaceDataset:
    """The embedded default: a generated street route (DESIGN.md section 3).

    Place ``i`` is drawn from ``(seed, i)`` only: a wide world canvas of building facades
    (window grids from a style bank shared by all places -- perceptual aliasing --, doors, shop
    signs, posters from scikit-image's bundled images, trees, lamps, traffic signs, sidewalk and
    road). The reference is a day view from one side of the path; the query is a night view
    (dark, colour cast, lit windows, lamp glare, noise, blur, vignetting) from the other side
    (horizontal shift, zoom 0.85-1.15, rotation +-5 deg, keystone perspective) with pedestrian /
    car occluders. Query ``i`` shows the place of reference ``i``; ``homographies[i]`` maps
    query-``i`` pixels to reference-``i`` pixels exactly (occluders aside).

    Files: ``<dir>/query/0000.png``, ``<dir>/reference/0000.png`` and ``<dir>/manifest.json``
    where ``<dir>`` is ``root`` if given, else ``cache_dir("datasets", "synthetic-<hash>")``
    (the hash covers seed, image size and generator version, not ``n_places``, so a larger
    route reuses the places of a smaller one). Missing files are (re)generated.

    Args:
        root: Output folder (default: the cache).
        n_places: Number of places (``>= 1``).
        seed: Route seed (``>= 0``); same seed -> identical pixels.
        image_size: ``(H, W)`` of the views (each ``>= 32``).
        tolerance: ``|q - r| <= tolerance`` ground truth.
    """
    tolerance = _check_tolerance(tolerance)
    if isinstance(n_places, bool) or not isinstance(n_places, (int, np.integer)) or n_places < 1:
        raise ValueError(f"synthetic: n_places must be an int >= 1, got {n_places!r}.")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"synthetic: seed must be an int >= 0, got {seed!r}.")
    try:
        size = tuple(int(v) for v in image_size)
    except (TypeError, ValueError):
        size = ()
    if len(size) != 2 or min(size) < 32:
        raise ValueError(
            f"synthetic: image_size must be (H, W) with H, W >= 32, got {image_size!r}; "
            "e.g. image_size=(360, 640)."
        )
    n_places, seed = int(n_places), int(seed)
    params = {"generator": "synthetic", "version": SYNTHETIC_VERSION, "seed": seed,
              "image_size": list(size)}
    out = Path(root).expanduser() if root is not None else \
        cache_dir("datasets", f"synthetic-{short_hash(params)}")
    (out / "query").mkdir(parents=True, exist_ok=True)
    (out / "reference").mkdir(parents=True, exist_ok=True)
    qp = [out / "query" / f"{i:04d}.png" for i in range(n_places)]
    rp = [out / "reference" / f"{i:04d}.png" for i in range(n_places)]
    missing = [i for i in range(n_places) if not (qp[i].is_file() and rp[i].is_file())]
    homs = np.zeros((n_places, 3, 3), np.float64)
    if missing:
        logger.info("synthetic: generating %d of %d places (seed=%d, %dx%d) into %s",
                    len(missing), n_places, seed, size[0], size[1], out)
    for i in progress(missing, desc="synthetic places", total=len(missing)):
        ref, qry, _ = render_synthetic_place(seed, i, size)
        _write_png(rp[i], ref)
        _write_png(qp[i], qry)
    for i in range(n_places):
        homs[i] = synthetic_homography(seed, i, size)
    if missing:
        manifest_path = out / "manifest.json"
        have = sorted(int(p.stem) for p in (out / "query").glob("[0-9][0-9][0-9][0-9].png"))
        manifest = dict(params, places=len(have), files="query/NNNN.png, reference/NNNN.png",
                        note="homographies map query pixels to reference pixels; "
                             "recomputed from (seed, i) by synthetic_homography",
                        homographies={str(i): synthetic_homography(seed, i, size).round(10).tolist()
                                      for i in have})
        tmp = manifest_path.with_name(f".manifest.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(manifest, indent=1))
        os.replace(tmp, manifest_path)
    gt = _frame_aligned(n_places, n_places, tolerance)
    meta = dict(params, n_places=n_places, ground_truth_rule=f"frame-aligned |q-r|<={tolerance}",
                exact_geometry=True)
    return PlaceDataset("synthetic", qp, rp, gt, tolerance, root=out, homographies=homs, meta=meta)
