"""Occluders in front of the facades: pedestrians and cars (with their lights at night)."""

from __future__ import annotations

import cv2
import numpy as np

from ._difficulty import SyntheticDifficulty

__all__ = ["draw_occluders"]


def draw_occluders(
    img: np.ndarray, rng: np.random.Generator, night: bool, diff: SyntheticDifficulty
) -> None:
    """Pedestrian / car silhouettes in image coordinates.

    Args:
        img: ``float64 (H, W, 3)`` view in [0, 1], drawn on in place (integer coordinates,
            ``LINE_8`` primitives: integer rasterisation).
        rng: Random stream of the view.
        night: Night query (dark silhouettes, car lights) or day reference.
        diff: Difficulty (how many occluders).
    """
    h, w = img.shape[:2]
    u = float(h)
    lo, hi = diff.occluders
    n = int(rng.integers(lo, hi + 1)) if night else int(rng.random() < diff.day_occluder)
    for _ in range(n):
        if rng.random() < 0.55:  # pedestrian
            ph = rng.uniform(0.35, 0.65) * u
            fx, fy = rng.uniform(0.05, 0.95) * w, rng.uniform(0.9, 1.05) * u
            col = tuple(float(c) for c in rng.uniform(0.0, 0.08 if night else 0.45, 3))
            bw = 0.22 * ph
            body = np.array(
                [
                    [fx - bw / 2, fy - 0.8 * ph],
                    [fx + bw / 2, fy - 0.8 * ph],
                    [fx + bw * 0.35, fy - 0.42 * ph],
                    [fx - bw * 0.35, fy - 0.42 * ph],
                ]
            )
            cv2.fillPoly(img, [body.astype(np.int32)], col)
            cv2.circle(img, (int(fx), int(fy - 0.88 * ph)), max(2, int(0.075 * ph)), col, -1)
            lw = max(2, int(0.07 * ph))
            cv2.line(
                img,
                (int(fx - bw * 0.2), int(fy - 0.45 * ph)),
                (int(fx - bw * 0.35), int(fy)),
                col,
                lw,
            )
            cv2.line(
                img,
                (int(fx + bw * 0.2), int(fy - 0.45 * ph)),
                (int(fx + bw * 0.3), int(fy)),
                col,
                lw,
            )
        else:  # car
            cw = rng.uniform(0.35, 0.6) * w
            ch = cw * 0.32
            x0 = rng.uniform(-0.2, 0.9) * w
            y1 = rng.uniform(0.95, 1.1) * u
            body_col = tuple(
                float(c) for c in (rng.uniform(0, 0.12, 3) if night else rng.uniform(0.1, 0.8, 3))
            )
            cv2.rectangle(
                img,
                (int(x0), int(y1 - 0.6 * ch)),
                (int(x0 + cw), int(y1 - 0.15 * ch)),
                body_col,
                -1,
            )
            cabin = np.array(
                [
                    [x0 + 0.2 * cw, y1 - 0.6 * ch],
                    [x0 + 0.3 * cw, y1 - ch],
                    [x0 + 0.72 * cw, y1 - ch],
                    [x0 + 0.82 * cw, y1 - 0.6 * ch],
                ]
            )
            cv2.fillPoly(img, [cabin.astype(np.int32)], body_col)
            for wx in (x0 + 0.2 * cw, x0 + 0.8 * cw):
                cv2.circle(
                    img,
                    (int(wx), int(y1 - 0.15 * ch)),
                    max(2, int(0.16 * ch)),
                    (0.02, 0.02, 0.02),
                    -1,
                )
            if night:  # head / tail lights with glare
                for lx, col in (
                    (x0 + 0.03 * cw, (1.0, 0.95, 0.8)),
                    (x0 + 0.97 * cw, (1.0, 0.15, 0.1)),
                ):
                    cv2.circle(
                        img,
                        (int(lx), int(y1 - 0.45 * ch)),
                        max(3, int(0.22 * ch)),
                        tuple(0.5 * c for c in col),
                        -1,
                    )
                    cv2.circle(img, (int(lx), int(y1 - 0.45 * ch)), max(2, int(0.08 * ch)), col, -1)
