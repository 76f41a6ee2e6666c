"""Wall and poster textures from scikit-image's bundled images (no downloads), kept as ``uint8``,
normalised with integer statistics and resampled with the exact primitives of :mod:`._exact`."""

from __future__ import annotations

import math
from functools import lru_cache
from typing import cast

import numpy as np
import skimage.data as skd

from ._exact import gaussian_blur, resize_area, resize_bilinear

__all__ = ["WALL_TEXTURES", "tex_patch", "texture_sources"]

WALL_TEXTURES = ("brick", "gravel", "plaster", "grass")


def _int_stats(v: np.ndarray) -> tuple[float, float]:
    """Mean and standard deviation of an integer image from exact integer sums."""
    a = v.astype(np.int64)
    n, s, sq = a.size, int(a.sum()), int((a * a).sum())
    return s / n, math.sqrt((n * sq - s * s) / (n * n))


@lru_cache(maxsize=1)
def texture_sources() -> dict[str, object]:
    """Bundled scikit-image images: ``uint8`` grey textures with ``(mean, std)``, RGB posters."""
    grey = {"brick": skd.brick(), "gravel": skd.gravel(), "grass": skd.grass()}
    grey["plaster"] = np.floor(gaussian_blur(skd.gravel(), 3.0)).astype(np.uint8)
    out: dict[str, object] = {k: (v, _int_stats(v)) for k, v in grey.items()}
    out["posters"] = [
        skd.coffee(),
        skd.astronaut(),
        skd.chelsea(),
        skd.rocket(),
        skd.hubble_deep_field(),
        skd.immunohistochemistry(),
        skd.colorwheel(),
        np.repeat(skd.text()[..., None], 3, axis=2),
        np.repeat(skd.coins()[..., None], 3, 2),
        np.repeat(skd.moon()[..., None], 3, axis=2),
        np.repeat(skd.page()[..., None], 3, 2),
        skd.logo()[..., :3],
        np.repeat(skd.camera()[..., None], 3, axis=2),
    ]
    return out


@lru_cache(maxsize=64)
def _texture(name: str, scale: float) -> np.ndarray:
    """Texture ``name`` resampled by ``scale``: ``float64 (h, w)``, zero mean, unit std."""
    entry = cast(tuple[np.ndarray, tuple[float, float]], texture_sources()[name])
    src, (mean, std) = entry
    if abs(scale - 1.0) > 1e-3:
        size = (max(8, round(src.shape[0] * scale)), max(8, round(src.shape[1] * scale)))
        res = resize_area(src, size) if scale < 1 else resize_bilinear(src, size)
    else:
        res = src.astype(np.float64)
    return (res - mean) / (std + 1e-6)


def tex_patch(name: str, scale: float, h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """A ``float64 (h, w)`` zero-mean unit-std texture crop (tiled when needed)."""
    t = _texture(name, round(scale, 2))
    th, tw = t.shape
    oy, ox = int(rng.integers(th)), int(rng.integers(tw))
    reps = (math.ceil((h + oy) / th), math.ceil((w + ox) / tw))
    if reps != (1, 1):
        t = np.tile(t, reps)
    return t[oy : oy + h, ox : ox + w]
