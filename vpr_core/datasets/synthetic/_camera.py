"""View geometry: the day reference and night query cameras of a place, and their homography, in
scalar Python floats (grid-rounded rotations, :func:`._exact.solve_homography`; no LAPACK, no
OpenCV), so the matrices are identical on every CPU."""

from __future__ import annotations

import math

import numpy as np

from ._difficulty import SyntheticDifficulty, resolve_difficulty
from ._exact import Matrix3, mat3_mul, normalise_h, solve_homography, to_grid

__all__ = ["canvas_size", "place_geometry", "place_homography", "synthetic_homography"]

_CANVAS_SCALE = (1.45, 1.8)  # world canvas size in units of the view (H, W)


def canvas_size(image_size: tuple[int, int]) -> tuple[int, int]:
    """``(Hc, Wc)`` of the world canvas for views of ``image_size = (H, W)``."""
    h, w = image_size
    return round(_CANVAS_SCALE[0] * h), round(_CANVAS_SCALE[1] * w)


def _view_corners(
    center: tuple[float, float], w: float, h: float, zoom: float, angle_deg: float, keystone: float
) -> list[tuple[float, float]]:
    """Canvas corners (TL, TR, BR, BL) of a view as 4 ``(x, y)`` Python floats."""
    hw, hh = 0.5 * w / zoom, 0.5 * h / zoom
    # keystone: the left edge is taller than the right one (a facade seen at an angle)
    pts = [
        (-hw, -hh * (1 + keystone)),
        (hw, -hh * (1 - keystone)),
        (hw, hh * (1 - keystone)),
        (-hw, hh * (1 + keystone)),
    ]
    a = math.radians(angle_deg)
    c, s = to_grid(math.cos(a)), to_grid(math.sin(a))
    return [(c * x - s * y + center[0], s * x + c * y + center[1]) for x, y in pts]


def _place_views(
    seed: int, i: int, image_size: tuple[int, int], diff: SyntheticDifficulty
) -> tuple[list, list]:
    """Canvas corners of the reference and the query view of place ``i``."""
    h, w = image_size
    hc, wc = canvas_size(image_size)
    rng = np.random.default_rng([seed, i, 1])
    side = 1.0 if rng.random() < 0.5 else -1.0
    shift = rng.uniform(*diff.shift) * w * side  # the query walks on the other side of the path
    cy = 0.5 * hc + rng.uniform(-0.03, 0.03) * h
    c_ref = (0.5 * wc - 0.5 * shift, cy)
    c_q = (0.5 * wc + 0.5 * shift, cy + rng.uniform(-diff.vertical, diff.vertical) * h)
    ref = _view_corners(c_ref, w, h, 1.0, rng.uniform(-1.0, 1.0), -side * rng.uniform(0.0, 0.04))
    qry = _view_corners(
        c_q,
        w,
        h,
        rng.uniform(*diff.zoom),
        rng.uniform(-diff.rotation_deg, diff.rotation_deg),
        side * rng.uniform(*diff.keystone),
    )
    return ref, qry


def place_geometry(
    seed: int, i: int, image_size: tuple[int, int], diff: SyntheticDifficulty
) -> tuple[Matrix3, Matrix3, Matrix3]:
    """View->canvas maps of the reference and the query, and the query->reference map."""
    h, w = image_size
    ref, qry = _place_views(seed, i, image_size, diff)
    img = [(0.0, 0.0), (float(w), 0.0), (float(w), float(h)), (0.0, float(h))]
    canvas_from_ref = solve_homography(img, ref)
    canvas_from_qry = solve_homography(img, qry)
    ref_from_canvas = solve_homography(ref, img)
    return canvas_from_ref, canvas_from_qry, mat3_mul(ref_from_canvas, canvas_from_qry)


def synthetic_homography(
    seed: int,
    i: int,
    image_size: tuple[int, int] = (360, 640),
    difficulty: str | SyntheticDifficulty = "default",
) -> np.ndarray:
    """Query-``i`` -> reference-``i`` pixel mapping of the synthetic place ``i``.

    Args:
        seed: Route seed.
        i: Place index.
        image_size: ``(H, W)`` of the views.
        difficulty: A name of :data:`DIFFICULTIES` or a :class:`SyntheticDifficulty`.

    Returns:
        ``float64 (3, 3)`` ``H`` with ``[x_r, y_r, 1] ~ H @ [x_q, y_q, 1]``, normalised so that
        ``H[2, 2] == 1``.
    """
    _, diff = resolve_difficulty(difficulty)
    size = (int(image_size[0]), int(image_size[1]))
    return place_homography(int(seed), int(i), size, diff)


def place_homography(
    seed: int, i: int, image_size: tuple[int, int], diff: SyntheticDifficulty
) -> np.ndarray:
    """:func:`synthetic_homography` on parsed input (ints, a :class:`SyntheticDifficulty`)."""
    return normalise_h(place_geometry(seed, i, image_size, diff)[2])
