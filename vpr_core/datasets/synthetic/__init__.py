"""The embedded default dataset: a generated street route (DESIGN.md section 3).

This face is the public interface. The generator's parts are package-private modules (``_x.py``,
names public only inside this package, code map in docs/SYNTHETIC.md): difficulty presets,
exact arithmetic, textures, canvas, facades, street, world, camera, night, occluders, render,
loader; the loader calls ``_render.render_synthetic_place``."""

from __future__ import annotations

from ._camera import synthetic_homography
from ._difficulty import DIFFICULTIES, SyntheticDifficulty, resolve_difficulty
from ._loader import SYNTHETIC_VERSION, load_synthetic
from ._render import render_synthetic_place

__all__ = [
    "DIFFICULTIES",
    "SYNTHETIC_VERSION",
    "SyntheticDifficulty",
    "load_synthetic",
    "render_synthetic_place",
    "resolve_difficulty",
    "synthetic_homography",
]
