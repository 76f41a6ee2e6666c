"""``load_synthetic``: the embedded default dataset, generated into the cache on demand."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from pathlib import Path

import cv2
import numpy as np

from ...checks import check_int, is_number
from ...utils import cache_dir, file_sha256, logger, progress, short_hash
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


def _png(rgb: np.ndarray) -> bytes:
    """``uint8 (H, W, 3)`` RGB as the generator's PNG bytes (the same bytes on every run)."""
    ok, buf = cv2.imencode(
        ".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 1]
    )
    assert ok, "could not encode a view"  # encoding a uint8 RGB array does not fail
    return buf.tobytes()


def _write_png(path: Path, rgb: np.ndarray) -> str:
    """Write ``uint8 (H, W, 3)`` RGB as a PNG atomically (temporary file + rename); returns
    the hex sha256 of the bytes written (the manifest's digest of the file)."""
    data = _png(rgb)
    _write_atomic(path, data)
    return hashlib.sha256(data).hexdigest()


def _views(i: int) -> tuple[str, str]:
    """The two views of place ``i``, as the manifest names them (``query/0000.png``, ...)."""
    return f"query/{i:04d}.png", f"reference/{i:04d}.png"


def _files(n_places: int) -> list[str]:
    """The views of places ``0..n_places-1``, as the manifest names them."""
    return [f for i in range(n_places) for f in _views(i)]


def _manifest(root: Path) -> dict | None:
    """``root/manifest.json`` as a dict; None when absent, unreadable or not an object."""
    try:
        path = root / "manifest.json"
        manifest = json.loads(path.read_text()) if path.is_file() else None
    except (OSError, ValueError):
        return None
    return manifest if isinstance(manifest, dict) else None


def _digests(manifest: dict | None) -> dict[str, str]:
    """The manifest's sha256 of each file (``{"query/0000.png": hex}``); {} when it holds none
    (made before digests were recorded, or not by the generator)."""
    found = (manifest or {}).get("sha256")
    if not isinstance(found, dict):
        return {}
    return {k: v for k, v in found.items() if isinstance(k, str) and isinstance(v, str)}


def _matches(root: Path, name: str, digests: dict[str, str]) -> bool:
    """Whether ``root/name`` is a regular file whose sha256 is the manifest's."""
    path = root / name
    return name in digests and path.is_file() and file_sha256(path) == digests[name]


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


def _generated_folder(root: Path, params: dict, n_places: int, diff) -> Path:
    """``root`` if the generator made it with ``params`` and it holds ``n_places`` places, each
    file with the sha256 its manifest records, and a seeded place drawn again gives that
    digest (a manifest copied beside other images is not the generator's); the loader only
    reads such a folder (DESIGN.md: generated data lives in the cache)."""
    manifest = _manifest(root)
    made = manifest is not None and all(manifest.get(k) == v for k, v in params.items())
    complete = made and all((root / f).is_file() for f in _files(n_places))
    fix = (
        "the synthetic set is generated into the cache (VPR_CACHE_DIR), never into a folder "
        "you name: drop root= (--root), or name a folder the generator made with the same "
        "settings"
    )
    if not complete:
        why = "holds fewer places than asked" if made else "was not made by the generator"
        raise ValueError(f"synthetic: root={str(root)!r} {why} with these settings; {fix}")
    digests = _digests(manifest)
    if not digests:
        raise ValueError(
            f"synthetic: root={str(root)!r}: its manifest.json records no file digests (made "
            f"by an older generator, or not by the generator), so its images are unverified; {fix}"
        )
    bad = next((f for f in _files(n_places) if not _matches(root, f, digests)), None)
    if bad is None:  # the digests themselves: one seeded place drawn again must give them
        i = int(np.random.default_rng(n_places).integers(n_places))
        ref, qry, _ = render_place(params["seed"], i, tuple(params["image_size"]), diff)
        for side, rgb in (("reference", ref), ("query", qry)):
            if hashlib.sha256(_png(rgb)).hexdigest() != digests[f"{side}/{i:04d}.png"]:
                bad = f"{side}/{i:04d}.png"
    if bad is not None:
        raise ValueError(
            f"synthetic: root={str(root)!r}: {bad} is not the image the generator made (its "
            "sha256 differs from the digest manifest.json records, or the recorded digest from "
            f"the place drawn again): a changed, swapped or replaced image is not the generated "
            f"set and has no exact geometry; {fix}"
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
    places of a smaller one). The manifest records each file's sha256: a missing file, or one
    that differs from its digest, is (re)generated there, never in ``root``.

    Args:
        root: A folder the generator made (a copy of a cache folder), read only; refused if
            its manifest differs from these settings, a place is missing, a file's sha256
            differs from its manifest's digest, or a seeded place drawn again differs from
            its digest. Default: the cache.
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
        out = _generated_folder(Path(root).expanduser(), params, n_places, diff)
    else:
        out = cache_dir("datasets", f"synthetic-{short_hash(params)}")
    for side in ("query", "reference"):
        try:
            (out / side).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise _write_error(out / side, exc) from exc
    qp = [out / "query" / f"{i:04d}.png" for i in range(n_places)]
    rp = [out / "reference" / f"{i:04d}.png" for i in range(n_places)]
    digests = _digests(_manifest(out))
    # a cached place is kept only with the digests its manifest records (a folder written
    # before digests were recorded is drawn again once: the same bytes); a root is checked
    missing = [
        i
        for i in range(n_places)
        if root is None and not all(_matches(out, f, digests) for f in _views(i))
    ]
    changed = [i for i in missing if _views(i)[0] in digests and qp[i].is_file()]
    if changed:
        logger.warning(
            "synthetic: %d place(s) in %s differ from their manifest's digests (changed after "
            "they were generated): drawn again (%s)",
            len(changed),
            out,
            ", ".join(map(str, changed[:10])),
        )
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
        digests[f"reference/{i:04d}.png"] = _write_png(rp[i], ref)
        digests[f"query/{i:04d}.png"] = _write_png(qp[i], qry)
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
            sha256={k: digests[k] for k in sorted(digests)},  # checked on every load
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
