"""The embedded default dataset: a generated street route (DESIGN.md section 3).

Where things live:

* :mod:`.textures`: wall and poster textures from scikit-image's bundled images;
* :mod:`.canvas`: the world canvas of a place and its fill / paste / text primitives;
* :mod:`.facade`: the facade style bank (perceptual aliasing) and one building's drawing;
* :mod:`.street`: trees, lamps and traffic signs;
* :mod:`.world`: one place's world canvas (:func:`~.world._render_world`);
* :mod:`.camera`: the reference / query views and :func:`synthetic_homography`;
* :mod:`.night`: night illumination and occluders;
* :mod:`.render`: :func:`render_synthetic_place`;
* :mod:`.loader`: :func:`load_synthetic` and :data:`SYNTHETIC_VERSION`.

:func:`load_synthetic` renders through this package's attribute ``render_synthetic_place``, so
replacing that attribute (e.g. ``monkeypatch.setattr``) changes what the loader calls.
"""

from __future__ import annotations

from .camera import synthetic_homography
from .loader import SYNTHETIC_VERSION, load_synthetic
from .render import render_synthetic_place

__all__ = ["SYNTHETIC_VERSION", "load_synthetic", "render_synthetic_place", "synthetic_homography"]
