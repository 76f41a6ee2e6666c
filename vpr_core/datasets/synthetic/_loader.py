"""``load_synthetic``: the embedded default dataset, generated into the cache on demand."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import cv2
import numpy as np

from ...checks import check_int, is_number
from ...utils import cache_dir, logger, progress, short_hash
from ..base import PlaceDataset
from ..ground_truth import check_tolerance, frame_aligned
from ._camera import place_homography
from ._difficulty import SyntheticDifficulty, resolve_difficulty
from ._render import render_place

__all__ = ["REPETITION_POOL", "SYNTHETIC_VERSION", "load_synthetic"]

#: Generator version: part of every cache key. 6: exact arithmetic (same pixels on every CPU)
#: and difficulty settings.
SYNTHETIC_VERSION = 6
#: Most places a route may have: its ``(n, n)`` ground truth and similarity matrices take
#: 9 bytes x n^2 (3.6 GB at 20,000), and each place takes about a second to draw.
MAX_PLACES = 20_000
#: (Not in the paper.) Shared buildings of a route with ``repetition > 0``: few, so that every
#: place shows the same facades in another arrangement.
REPETITION_POOL = 3


def _write_png(path: Path, rgb: np.ndarray) -> None:
    """Write ``uint8 (H, W, 3)`` RGB as a PNG atomically (temporary file + rename)."""
    ok, buf = cv2.imencode(
        ".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 1]
    )
    assert ok, f"could not encode {path}"  # encoding a uint8 RGB array does not fail
    _write_atomic(path, buf.tobytes())


def _write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` via a temporary file and a rename; a failed write (a full
    disk, a read-only folder) removes the temporary file and raises an OSError of the same
    errno that names ``path`` and the fix."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise _write_error(path, exc) from exc


def _write_error(path: Path, exc: OSError) -> OSError:
    """The error of a write that failed under the synthetic dataset's folder: the file, the
    cause and the fix."""
    return OSError(
        exc.errno,
        f"synthetic: cannot write {path} ({exc.strerror or exc}); free space on that disk, or "
        "set VPR_CACHE_DIR to a writable folder with room for the "
        "dataset; nothing partial was kept",
    )


def _generated_folder(root: Path, params: dict, n_places: int) -> Path:
    """``root`` if the generator made it with ``params`` and it holds ``n_places`` places; the
    loader only reads such a folder (DESIGN.md: generated data lives in the cache)."""
    try:
        path = root / "manifest.json"
        manifest = json.loads(path.read_text()) if path.is_file() else None
    except (OSError, ValueError):
        manifest = None
    made = isinstance(manifest, dict) and all(manifest.get(k) == v for k, v in params.items())
    complete = made and all(
        (root / side / f"{i:04d}.png").is_file()
        for side in ("query", "reference")
        for i in range(n_places)
    )
    if not complete:
        why = "holds fewer places than asked" if made else "was not made by the generator"
        raise ValueError(
            f"synthetic: root={str(root)!r} {why} with these settings; the synthetic set is "
            "generated into the cache (VPR_CACHE_DIR), never into a folder you name: drop "
            "root= (--root), or name a folder the generator made with the same settings"
        )
    return root


def load_synthetic(
    root: str | os.PathLike | None = None,
    n_places: int = 60,
    seed: int = 0,
    image_size: tuple[int, int] = (360, 640),
    tolerance: int = 0,
    difficulty: str | SyntheticDifficulty = "default",
    repetition: float = 0.0,
) -> PlaceDataset:
    """The embedded default: a generated street route (DESIGN.md section 3).

    Place ``i`` is drawn from ``(seed, i)`` only: a wide world canvas of building facades
    (window grids from a style bank shared by all places -- perceptual aliasing --, doors, shop
    signs, posters from scikit-image's bundled images, trees, lamps, traffic signs, sidewalk and
    road). The reference is a day view from one side of the path; the query is a night view
    (dark, colour cast, lit windows, lamp glare, noise, blur, vignetting) from the other side
    (horizontal shift, zoom, rotation, keystone perspective) with pedestrian / car occluders;
    ``difficulty`` sets how strong each of these is and how many buildings are exact copies
    of buildings elsewhere on the route (docs/SYNTHETIC.md). Query ``i`` shows the place of
    reference ``i``; ``homographies[i]`` maps query-``i`` pixels to reference-``i`` pixels
    exactly (occluders aside).

    Files: ``<dir>/query/0000.png``, ``<dir>/reference/0000.png`` and ``<dir>/manifest.json``
    where ``<dir>`` is ``cache_dir("datasets", "synthetic-<hash>")`` (the hash covers seed,
    image size, difficulty and generator version, not ``n_places``, so a larger route reuses the
    places of a smaller one). Missing files are (re)generated there, never in ``root``.

    Args:
        root: A folder the generator made (a copy of a cache folder), read only; refused if
            its manifest differs from these settings or a place is missing. Default: the cache.
        n_places: Number of places (1 to :data:`MAX_PLACES`).
        seed: Route seed (``>= 0``); same seed -> identical pixels.
        image_size: ``(H, W)`` of the views (each ``>= 32``).
        tolerance: ``|q - r| <= tolerance`` ground truth.
        difficulty: A name of ``DIFFICULTIES`` (``easy``, ``default``, ``hard``) or a
            :class:`SyntheticDifficulty`.
        repetition: (Not in the paper.) Probability in ``[0, 1]`` that a building is an exact
            copy of one of :data:`REPETITION_POOL` buildings shared by the whole route, which then
            repeats itself: places differ in the arrangement of the same facades and a few rare
            elements (unique buildings, trees, lamps, signs). 0 (default): the difficulty's own
            setting, the same pixels and cache folder as without it.

    Raises:
        ValueError: bad ``n_places``, ``seed``, ``image_size``, ``tolerance`` or an unknown
            difficulty name (the message lists the valid ones), or a ``root`` the generator
            did not make.
    """
    tolerance = check_tolerance(tolerance)
    diff_name, diff = resolve_difficulty(difficulty)
    n_places = check_int(n_places, "synthetic: n_places", minimum=1)
    if n_places > MAX_PLACES:
        raise ValueError(
            f"synthetic: n_places={n_places:,} is more than {MAX_PLACES:,}, the most a route may "
            "have (its (n, n) matrices take 9 bytes x n^2); give a smaller n_places"
        )
    seed = check_int(seed, "synthetic: seed")
    try:
        size = tuple(int(v) for v in image_size)
    except (TypeError, ValueError):
        size = ()
    if len(size) != 2 or min(size) < 32:
        raise ValueError(
            f"synthetic: image_size must be (H, W) with H, W >= 32, got {image_size!r}; "
            "e.g. image_size=(360, 640)."
        )
    if not is_number(repetition) or not 0 <= repetition <= 1:
        raise ValueError(f"synthetic: repetition must be a number in [0, 1], got {repetition!r}.")
    if repetition > 0:
        diff = dataclasses.replace(
            diff, repeat_facades=float(repetition), facade_pool=REPETITION_POOL, style_share=1.0
        )
    params = {
        "generator": "synthetic",
        "version": SYNTHETIC_VERSION,
        "seed": seed,
        "image_size": list(size),
        "difficulty": diff_name,
        "difficulty_settings": diff.as_dict(),
    }
    if repetition > 0:  # absent at 0: the default route keeps its cache key
        params["repetition"] = float(repetition)
    if root is not None:
        out = _generated_folder(Path(root).expanduser(), params, n_places)
    else:
        out = cache_dir("datasets", f"synthetic-{short_hash(params)}")
    for side in ("query", "reference"):
        try:
            (out / side).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise _write_error(out / side, exc) from exc
    qp = [out / "query" / f"{i:04d}.png" for i in range(n_places)]
    rp = [out / "reference" / f"{i:04d}.png" for i in range(n_places)]
    missing = [i for i in range(n_places) if not (qp[i].is_file() and rp[i].is_file())]
    homs = np.zeros((n_places, 3, 3), np.float64)
    if missing:
        logger.info(
            "synthetic: generating %d of %d places (seed=%d, %dx%d) into %s",
            len(missing),
            n_places,
            seed,
            size[0],
            size[1],
            out,
        )
    for i in progress(missing, desc="synthetic places", total=len(missing)):
        ref, qry, _ = render_place(seed, i, size, diff)
        _write_png(rp[i], ref)
        _write_png(qp[i], qry)
    for i in range(n_places):
        homs[i] = place_homography(seed, i, size, diff)
    if missing:
        manifest_path = out / "manifest.json"
        have = sorted(int(p.stem) for p in (out / "query").glob("[0-9][0-9][0-9][0-9].png"))
        manifest = dict(
            params,
            places=len(have),
            files="query/NNNN.png, reference/NNNN.png",
            note="homographies map query pixels to reference pixels; "
            "recomputed from (seed, i) by synthetic_homography",
            homographies={
                str(i): place_homography(seed, i, size, diff).round(10).tolist() for i in have
            },
        )
        _write_atomic(manifest_path, json.dumps(manifest, indent=1).encode())
    gt = frame_aligned(n_places, n_places, tolerance)
    meta = dict(
        params,
        n_places=n_places,
        ground_truth_rule=f"frame-aligned |q-r|<={tolerance}",
        frame_aligned=True,
        exact_geometry=True,
    )
    return PlaceDataset("synthetic", qp, rp, gt, tolerance, root=out, homographies=homs, meta=meta)
