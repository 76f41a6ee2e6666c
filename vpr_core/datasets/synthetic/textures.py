"""Wall and poster textures from scikit-image's bundled images (no downloads)."""

from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np

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
