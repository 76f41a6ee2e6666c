"""Render one place: the day reference and the night query with their homography; every step is
exact (:mod:`._exact`, docs/SYNTHETIC.md), down to the ``floor(255 x + 0.5)`` quantisation."""

from __future__ import annotations

import numpy as np

from ._camera import canvas_size, place_geometry
from ._difficulty import SyntheticDifficulty, resolve_difficulty
from ._exact import gaussian_blur, normal, normalise_h, to_uint8, warp_perspective
from ._night import to_night, vignette
from ._occluders import draw_occluders
from ._world import render_world

__all__ = ["render_place", "render_synthetic_place"]


def render_synthetic_place(
    seed: int,
    i: int,
    image_size: tuple[int, int] = (360, 640),
    difficulty: str | SyntheticDifficulty = "default",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Render place ``i`` of the synthetic route (independent of how many places are asked for).

    Args:
        seed: Route seed (``>= 0``).
        i: Place index (``>= 0``).
        image_size: ``(H, W)`` of both views.
        difficulty: A name of ``DIFFICULTIES`` (``easy``, ``default``, ``hard``) or a
            :class:`SyntheticDifficulty`.

    Returns:
        ``(reference, query, H)``: ``uint8 (H, W, 3)`` RGB day reference, ``uint8 (H, W, 3)``
        RGB night query, and ``float64 (3, 3)`` query -> reference pixel homography.
    """
    _, diff = resolve_difficulty(difficulty)
    return render_place(int(seed), int(i), (int(image_size[0]), int(image_size[1])), diff)


def render_place(
    seed: int, i: int, image_size: tuple[int, int], diff: SyntheticDifficulty
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`render_synthetic_place` on parsed input (ints, a :class:`SyntheticDifficulty`)."""
    h, w = image_size
    hc, wc = canvas_size((h, w))
    world = render_world(seed, i, hc, wc, float(h), diff)
    canvas_from_ref, canvas_from_qry, qry_to_ref = place_geometry(seed, i, (h, w), diff)
    fx = np.random.default_rng([seed, i, 3])
    # day reference: mild exposure jitter + light sensor noise, occasionally a passer-by
    ref = warp_perspective(world.img, canvas_from_ref, (h, w)) / 255.0
    ref = np.clip(ref * fx.uniform(0.9, 1.1) + fx.uniform(-0.03, 0.03), 0, 1)
    draw_occluders(ref, fx, night=False, diff=diff)
    ref = ref + normal(fx, 0.0, 0.008, ref.shape)
    # night query
    night = to_night(world, fx, diff)
    qry = warp_perspective(night, canvas_from_qry, (h, w))
    draw_occluders(qry, fx, night=True, diff=diff)
    qry = gaussian_blur(qry, fx.uniform(*diff.blur) * h / 360.0)
    qry = qry + normal(fx, 0.0, float(fx.uniform(*diff.noise)), qry.shape)
    qry = qry * vignette(h, w)[..., None]
    return to_uint8(ref), to_uint8(qry), normalise_h(qry_to_ref)
