"""Building facades: the shared style bank (perceptual aliasing) and one building's drawing."""

from __future__ import annotations

import cv2
import numpy as np

from ._canvas import World, fill_textured, paste_poster, put_text_fit
from ._exact import normal
from ._textures import WALL_TEXTURES

__all__ = ["draw_building", "random_style", "style_bank"]

_SHOP_WORDS = (
    "CAFE",
    "BAR",
    "BOOKS",
    "BAKERY",
    "HOTEL",
    "BANK",
    "MARKET",
    "PIZZA",
    "KIOSK",
    "SALON",
    "DELI",
    "TAXI",
    "POST",
    "OPTIK",
    "APOTHEKE",
    "SUSHI",
    "FLORIST",
    "GYM",
    "CINEMA",
    "LAUNDRY",
    "TOYS",
    "SHOES",
    "DINER",
    "TEA",
    "MUSIC",
    "PRINT",
    "BIKES",
    "GELATO",
    "RAMEN",
    "CAFE",
)


def style_bank(seed: int, n: int = 6) -> list[dict]:
    """Facade styles shared by all places of one seed (the source of perceptual aliasing)."""
    rng = np.random.default_rng([seed, 999_983])
    return [random_style(rng) for _ in range(n)]


def random_style(rng: np.random.Generator) -> dict:
    """One facade style: colour, wall texture, window grid, frames, shutters, roof."""
    base = rng.choice(
        [
            (200, 170, 140),
            (180, 90, 70),
            (225, 215, 190),
            (150, 150, 155),
            (210, 190, 120),
            (120, 140, 160),
            (190, 120, 100),
            (235, 235, 230),
            (170, 160, 120),
            (140, 100, 80),
        ]
    )
    return {
        "color": tuple(int(c) for c in np.clip(base + normal(rng, 0, 12, 3), 30, 250)),
        "texture": str(rng.choice(WALL_TEXTURES, p=[0.4, 0.2, 0.3, 0.1])),
        "tex_scale": float(rng.uniform(0.35, 0.8)),
        "tex_gain": float(rng.uniform(0.08, 0.2)),
        "win_w": float(rng.uniform(0.06, 0.11)),  # units of view height
        "win_h": float(rng.uniform(0.08, 0.15)),
        "gap_x": float(rng.uniform(0.04, 0.09)),
        "gap_y": float(rng.uniform(0.05, 0.09)),
        "glass": tuple(int(c) for c in rng.integers(30, 110, 3)),
        "frame": tuple(
            int(c)
            for c in rng.choice(
                [(240, 240, 235), (60, 50, 45), (120, 30, 30), (30, 60, 40), (200, 190, 160)]
            )
        ),
        "mullion": bool(rng.random() < 0.6),
        "shutters": bool(rng.random() < 0.3),
        "shutter_color": tuple(int(c) for c in rng.integers(20, 200, 3)),
        "arch": bool(rng.random() < 0.25),
        "roof": str(rng.choice(["flat", "cornice", "gable"], p=[0.3, 0.45, 0.25])),
        "floor_h": float(rng.uniform(0.19, 0.24)),
    }


def draw_building(
    world: World,
    x0: int,
    x1: int,
    top: int,
    base: int,
    style: dict,
    rng: np.random.Generator,
    lit_windows: float = 0.35,
) -> None:
    """Draw one building (wall, roof, window grid, ground floor) between ``x0`` and ``x1``.

    Args:
        world: Canvas to draw on (its ``lit`` list receives the night light sources).
        x0, x1: Horizontal extent (canvas pixels).
        top, base: Roof line and ground line (canvas pixels).
        style: A :func:`random_style` dict.
        rng: Random stream of this building.
        lit_windows: Probability that a window is lit at night.
    """
    u = world.unit
    color = np.clip(np.asarray(style["color"], float) + normal(rng, 0, 6, 3), 20, 250)
    fill_textured(
        world,
        (x0, top, x1, base),
        color,
        (style["texture"], style["tex_scale"], style["tex_gain"]),
        rng,
    )
    dark = tuple(int(c * 0.55) for c in color)
    _draw_roof(world, x0, x1, top, style, color, dark, rng)
    floor_h = int(style["floor_h"] * u)
    gf_top = base - floor_h
    cv2.line(world.img, (x0, gf_top), (x1, gf_top), dark, max(1, int(0.012 * u)))
    _draw_windows(world, (x0, x1, top, gf_top), style, dark, rng, lit_windows)
    _draw_ground_floor(world, x0, x1, base, gf_top, floor_h, rng)
    # occasional big billboard on the facade (a strong, unique landmark)
    bw = x1 - x0
    if rng.random() < 0.25 and bw > 0.35 * u and gf_top - top > 0.35 * u:
        bw2 = int(rng.uniform(0.25, 0.4) * u)
        bh2 = int(bw2 * rng.uniform(0.6, 1.0))
        bx = int(rng.uniform(x0 + 0.05 * bw, max(x0 + 0.05 * bw + 1, x1 - bw2 - 0.05 * bw)))
        by = int(rng.uniform(top + 0.06 * u, max(top + 0.06 * u + 1, gf_top - bh2 - 0.05 * u)))
        paste_poster(world, bx, by, bw2, bh2, rng)


def _draw_roof(
    world: World,
    x0: int,
    x1: int,
    top: int,
    style: dict,
    color: np.ndarray,
    dark: tuple,
    rng: np.random.Generator,
) -> None:
    """Cornice or gable (with tile rows) above the roof line; flat roofs draw nothing."""
    u, img = world.unit, world.img
    if style["roof"] == "cornice":
        ch = max(2, int(0.03 * u))
        cv2.rectangle(img, (x0 - 2, top), (x1 + 2, top + ch), dark, -1)
        cv2.rectangle(
            img,
            (x0 - 2, top + ch),
            (x1 + 2, top + ch + max(1, ch // 3)),
            tuple(int(c * 0.8) for c in color),
            -1,
        )
    elif style["roof"] == "gable":
        peak = top - int(rng.uniform(0.1, 0.22) * u)
        pts = np.array([[x0, top], [(x0 + x1) // 2, peak], [x1, top]], np.int32)
        roof_col = tuple(int(c) for c in rng.choice([(120, 50, 40), (70, 70, 80), (90, 60, 40)]))
        cv2.fillPoly(img, [pts], roof_col)
        world.sky[max(0, peak) : top, x0:x1] = False
        for k in range(1, 6):  # roof tile rows, inside the gable
            y = top - (top - peak) * k // 6
            half = (x1 - x0) * (1 - k / 6) / 2
            xm = (x0 + x1) / 2
            cv2.line(
                img,
                (int(xm - half), y),
                (int(xm + half), y),
                tuple(int(c * 0.7) for c in roof_col),
                1,
            )
        cv2.fillPoly(world.sky.view(np.uint8), [pts], 0)


def _draw_windows(
    world: World,
    upper: tuple[int, int, int, int],
    style: dict,
    dark: tuple,
    rng: np.random.Generator,
    lit_windows: float,
) -> None:
    """The window grid of the upper floors ``upper = (x0, x1, top, gf_top)`` (facade columns,
    roof line, top of the ground floor); some windows are registered as lit at night."""
    x0, x1, top, gf_top = upper
    u, img = world.unit, world.img
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
                glass = np.clip(np.asarray(style["glass"]) + normal(rng, 0, 10, 3), 0, 255)
                if rng.random() < 0.15:  # a curtain / blind: local uniqueness
                    glass = rng.integers(120, 230, 3)
                glass_t = tuple(int(v) for v in glass)
                if style["shutters"]:
                    sw = ww // 3
                    cv2.rectangle(img, (wx - sw, y), (wx, y + wh), style["shutter_color"], -1)
                    cv2.rectangle(
                        img, (wx + ww, y), (wx + ww + sw, y + wh), style["shutter_color"], -1
                    )
                cv2.rectangle(img, (wx, y), (wx + ww, y + wh), glass_t, -1)
                # sky reflection on the upper part of the glass
                cv2.rectangle(
                    img,
                    (wx, y),
                    (wx + ww, y + wh // 3),
                    tuple(min(255, v + 35) for v in glass_t),
                    -1,
                )
                if style["arch"]:
                    cv2.ellipse(
                        img, (wx + ww // 2, y), (ww // 2, max(1, ww // 3)), 0, 180, 360, glass_t, -1
                    )
                cv2.rectangle(img, (wx, y), (wx + ww, y + wh), frame, ft)
                if style["mullion"]:
                    cv2.line(img, (wx + ww // 2, y), (wx + ww // 2, y + wh), frame, ft)
                    cv2.line(img, (wx, y + wh // 2), (wx + ww, y + wh // 2), frame, ft)
                cv2.rectangle(img, (wx - ft, y + wh), (wx + ww + ft, y + wh + 2 * ft), dark, -1)
                if rng.random() < lit_windows:
                    warm = (255, int(rng.uniform(190, 235)), int(rng.uniform(100, 170)))
                    world.lit.append((wx, y, wx + ww, y + wh, warm, 0.45))
            y += wh + gy


def _draw_ground_floor(
    world: World, x0: int, x1: int, base: int, gf_top: int, floor_h: int, rng: np.random.Generator
) -> None:
    """Door, shop window with its (often lit) sign, and posters on the free wall."""
    u, img = world.unit, world.img
    bw = x1 - x0
    # ground floor: door, shop window, sign, posters
    door_w = int(rng.uniform(0.09, 0.13) * u)
    door_h = int(0.8 * floor_h)
    dx = int(rng.uniform(x0 + 0.05 * bw, max(x0 + 0.05 * bw + 1, x1 - door_w - 0.05 * bw)))
    door_col = tuple(
        int(c)
        for c in rng.choice([(80, 40, 30), (30, 50, 90), (40, 40, 40), (140, 20, 30), (20, 90, 60)])
    )
    cv2.rectangle(img, (dx, base - door_h), (dx + door_w, base), door_col, -1)
    cv2.rectangle(
        img, (dx, base - door_h), (dx + door_w, base), (20, 20, 20), max(1, int(0.008 * u))
    )
    cv2.circle(
        img,
        (dx + int(door_w * 0.8), base - door_h // 2),
        max(1, int(0.008 * u)),
        (220, 200, 60),
        -1,
    )
    shop = rng.random() < 0.65
    free = [
        (x0 + int(0.03 * bw), dx - int(0.03 * bw)),
        (dx + door_w + int(0.03 * bw), x1 - int(0.03 * bw)),
    ]
    free = [(a, b) for a, b in free if b - a > 0.12 * u]
    if shop and free:
        a, b = free.pop(int(rng.integers(len(free))))
        sh_top = base - int(0.75 * floor_h)
        cv2.rectangle(img, (a, sh_top), (b, base - int(0.05 * u)), (60, 70, 80), -1)
        cv2.rectangle(img, (a, sh_top), (b, sh_top + (base - sh_top) // 3), (90, 100, 110), -1)
        cv2.rectangle(
            img, (a, sh_top), (b, base - int(0.05 * u)), (25, 25, 25), max(1, int(0.01 * u))
        )
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
            put_text_fit(img, word, a, s_top, b, s_bot, txt_col)
            if rng.random() < 0.6:
                world.lit.append((a, s_top, b, s_bot, (255, 255, 245), 1.0))
    for a, b in free:
        if rng.random() < 0.7:
            pw = int(min(b - a, rng.uniform(0.1, 0.2) * u))
            ph = int(min(0.65 * floor_h, pw * rng.uniform(1.0, 1.5)))
            px = int(rng.uniform(a, max(a + 1, b - pw)))
            paste_poster(world, px, base - ph - int(0.08 * u), pw, ph, rng)
