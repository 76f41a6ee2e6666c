"""Night illumination of the canvas and the pedestrian / car occluders."""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from .canvas import _World


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


@lru_cache(maxsize=8)
def _vignette(h: int, w: int) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    return 1.0 - 0.175 * (((xx - w / 2) / (w / 2)) ** 2 + ((yy - h / 2) / (h / 2)) ** 2)
