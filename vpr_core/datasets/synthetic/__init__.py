"""The embedded default dataset: a generated street route (DESIGN.md section 3), one module per
part (difficulty presets, exact arithmetic, textures, canvas, facades, street, world, camera,
night, occluders, render, loader); the loader calls ``render.render_synthetic_place``."""

from __future__ import annotations

from .camera import synthetic_homography
from .difficulty import DIFFICULTIES, SyntheticDifficulty, resolve_difficulty
from .loader import SYNTHETIC_VERSION, load_synthetic
from .render import render_synthetic_place

__all__ = [
    "DIFFICULTIES",
    "SYNTHETIC_VERSION",
    "SyntheticDifficulty",
    "load_synthetic",
    "render_synthetic_place",
    "resolve_difficulty",
    "synthetic_homography",
]
