"""The embedded default dataset: a generated street route (DESIGN.md section 3).

Where things live:

* :mod:`.difficulty`: :class:`SyntheticDifficulty` and the named presets :data:`DIFFICULTIES`;
* :mod:`.exact`: CPU-independent image arithmetic (warps, blur, resampling, homographies);
* :mod:`.textures`: wall and poster textures from scikit-image's bundled images;
* :mod:`.canvas`: the world canvas of a place and its fill / paste / text primitives;
* :mod:`.facade`: the facade style bank (perceptual aliasing) and one building's drawing;
* :mod:`.street`: trees, lamps and traffic signs;
* :mod:`.world`: one place's world canvas (:func:`~.world._render_world`);
* :mod:`.camera`: the reference / query views and :func:`synthetic_homography`;
* :mod:`.night`: night illumination; :mod:`.occluders`: pedestrians and cars;
* :mod:`.render`: :func:`render_synthetic_place`;
* :mod:`.loader`: :func:`load_synthetic` and :data:`SYNTHETIC_VERSION`.

:func:`load_synthetic` renders through ``render.render_synthetic_place``, so replacing that
module attribute (e.g. ``monkeypatch.setattr``) changes what the loader calls.
"""

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
