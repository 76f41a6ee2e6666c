"""The UTM-named layout of VPR-datasets-downloader / VPR-methods-evaluation (``database/`` +
``queries/``, coordinates in the file names): :func:`load_utm` documents it."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..checks import check_file, is_number
from ._layout import check_root, data_name, listed_paths, traverse_dir
from .base import PlaceDataset
from .ground_truth import check_coverage
from .images import IMAGE_EXTENSIONS

__all__ = ["UTM_LAYOUT", "load_utm"]

UTM_LAYOUT = (
    "<root>/database/**/@<utm_easting>@<utm_northing>@...@.jpg, <root>/queries/**/@...@.jpg, "
    "optional <root>/database_images_paths.txt and <root>/queries_images_paths.txt"
)
_PATTERN = "@<utm_easting>@<utm_northing>@...@.jpg (e.g. @0543256.96@4178906.93@10@S@@.jpg)"


def _paths(folder: Path, what: str) -> list[Path]:
    listing = folder.parent / f"{folder.name}_images_paths.txt"
    if check_file(listing, "utm: paths list"):
        paths = listed_paths(listing, folder, "utm")
        missing = [p for p in paths if not p.is_file()]
        if missing:
            raise FileNotFoundError(
                f"utm: {listing} lists {len(missing)} file(s) that do not exist under {folder} "
                f"(first: {missing[0]}); paths in it are relative to {folder}. Fix or delete the "
                "list (without it the images are found by searching the folder)."
            )
    else:
        paths = sorted(
            (
                p
                for p in folder.rglob("*")
                if p.is_file()
                and p.suffix.lower() in IMAGE_EXTENSIONS
                and not p.name.startswith(".")
            ),
            key=str,
        )
    if not paths:
        raise ValueError(
            f"utm: {what} folder {folder} contains no images. Expected layout: {UTM_LAYOUT}"
        )
    return paths


def _utm_coordinates(paths: list[Path]) -> np.ndarray:
    """``float64 (N, 2)`` UTM (easting, northing) of each file, from fields 1 and 2 of its name.

    Raises:
        ValueError: a name without two numeric coordinates (the message names the file).
    """
    out = np.empty((len(paths), 2))
    for i, p in enumerate(paths):
        fields = p.name.split("@")
        try:
            out[i] = float(fields[1]), float(fields[2])
        except (IndexError, ValueError):
            raise ValueError(
                f"utm: {p} has no UTM coordinates in its name; names must be {_PATTERN} "
                "(fields split by '@': 1 = easting, 2 = northing, in metres)."
            ) from None
        if not np.isfinite(out[i]).all():
            raise ValueError(f"utm: {p}: the coordinates in its name are not finite numbers.")
    return out


_BANDS = "CDEFGHJKLMNPQRSTUVWX"  # latitude bands; C..M south of the equator, N..X north


def _utm_zones(paths: list[Path]) -> list[str | None]:
    """The UTM zone of each file from fields 3 and 4 of its name (``@e@n@32@T@...`` -> ``"32N"``:
    zone number and hemisphere, since bands of one hemisphere share the zone's coordinates), or
    None where the name carries no zone.

    Raises:
        ValueError: a zone field that is not a zone (1..60 and a band letter C..X).
    """
    out: list[str | None] = []
    for p in paths:
        fields = p.name.split("@")
        zone, band = (fields[3].strip(), fields[4].strip().upper()) if len(fields) > 5 else ("", "")
        if not zone and not band:
            out.append(None)
            continue
        if not (zone.isdigit() and 1 <= int(zone) <= 60 and len(band) == 1 and band in _BANDS):
            raise ValueError(
                f"utm: {p}: fields 3 and 4 of its name ({zone!r}, {band!r}) are not a UTM zone "
                "(a number 1..60 and a latitude band C..X, e.g. @32@T@); fix the name."
            )
        out.append(f"{int(zone)}{'N' if band >= 'N' else 'S'}")
    return out


def _one_zone(query: list[Path], database: list[Path]) -> str | None:
    """The zone every file shares (None: no name carries one); mixed zones are refused."""
    zones = {"query": _utm_zones(query), "database": _utm_zones(database)}
    seen: dict[str | None, Path] = {}
    for side, paths in (("query", query), ("database", database)):
        for zone, p in zip(zones[side], paths, strict=True):
            seen.setdefault(zone, p)
    if len(seen) > 1:
        listed = ", ".join(
            f"{'no zone' if z is None else 'zone ' + z[:-1] + ('' if z[-1] == 'N' else ' south')}"
            f" ({p.name})"
            for z, p in seen.items()
        )
        raise ValueError(
            f"utm: the images lie in different UTM zones or hemispheres ({listed}); eastings and "
            "northings of different zones are not comparable (the same digits can be hundreds of "
            "km apart). Convert all coordinates to one zone, or split the dataset by zone."
        )
    return next(iter(seen))


def _threshold(value: Any, what: str) -> float:
    if not is_number(value) or value < 0:
        raise ValueError(f"utm: {what} must be a number of metres >= 0, got {value!r}.")
    return float(value)


def load_utm(
    root: str | os.PathLike | None = None,
    positive_dist_threshold: float = 25,
    soft_dist_threshold: float | None = None,
    database: str = "database",
    queries: str = "queries",
) -> PlaceDataset:
    """A dataset in the UTM-named layout of VPR-datasets-downloader / VPR-methods-evaluation.

    Layout (Pitts30k, MSLS, Tokyo 24/7, St Lucia, SF-XL, Nordland, ...)::

        <root>/database/**/@<utm_easting>@<utm_northing>@<zone>@<band>@...@.jpg
        <root>/queries/**/@<utm_easting>@<utm_northing>@<zone>@<band>@...@.jpg
        <root>/database_images_paths.txt     # optional: one path per line, relative to database/
        <root>/queries_images_paths.txt      # optional, likewise

    Fields 1 and 2 of a name are the UTM easting and northing in metres; fields 3 and 4, when
    present, the zone number and latitude band: all images must lie in one zone and hemisphere
    (mixed zones are refused, never merged). Without a paths list the images are found
    recursively and sorted by their path strings (as ``sorted(glob(...))`` does); with one, its
    order is kept, and every listed path must stay inside its folder. Either way the order is
    VPR-methods-evaluation's, so its ``--save_descriptors`` files line up as a peer. Ground
    truth: reference ``r`` is a positive of query ``q`` when their Euclidean UTM distance is
    ``<= positive_dist_threshold`` metres (GThard); with ``soft_dist_threshold`` (VPR_Tutorial's
    GTsoft) the pairs within it but beyond the hard threshold are stored in
    :attr:`PlaceDataset.ground_truth_soft`: they count neither right nor wrong.

    Args:
        root: The folder holding ``database/`` and ``queries/``.
        positive_dist_threshold: Metres; positives are within it (VPR-methods-evaluation's
            default 25).
        soft_dist_threshold: Metres (>= the hard threshold) or None: pairs within it but beyond
            the hard threshold are soft positives, ignored by the evaluation.
        database: Reference folder name.
        queries: Query folder name.

    Returns:
        PlaceDataset named after the root folder with ``tolerance`` ``"<threshold> m"``,
        ``meta["utm_query"]`` / ``meta["utm_reference"]`` the coordinates,
        ``meta["utm_zone"]`` (e.g. ``"32N"``, None when the names carry none), and
        ``ground_truth_soft`` when asked.

    Raises:
        ValueError: bad thresholds, names without coordinates, mixed UTM zones or hemispheres,
            no positive pair, a listed path outside its folder.
        FileNotFoundError: missing root or folders, a paths list naming missing files.
    """
    hard = _threshold(positive_dist_threshold, "positive_dist_threshold")
    soft = (
        None
        if soft_dist_threshold is None
        else _threshold(soft_dist_threshold, "soft_dist_threshold")
    )
    if soft is not None and soft < hard:
        raise ValueError(
            f"utm: soft_dist_threshold ({soft:g} m) must be >= "
            f"positive_dist_threshold ({hard:g} m)."
        )
    root = check_root(root, "utm", UTM_LAYOUT)
    qp = _paths(traverse_dir(root, queries, "utm", UTM_LAYOUT), "query")
    rp = _paths(traverse_dir(root, database, "utm", UTM_LAYOUT), "database")
    uq, ur = _utm_coordinates(qp), _utm_coordinates(rp)
    zone = _one_zone(qp, rp)
    dist = np.hypot(uq[:, None, 0] - ur[None, :, 0], uq[:, None, 1] - ur[None, :, 1])
    gt = dist <= hard
    rule = f"UTM distance <= {hard:g} m"
    check_coverage(gt, f"utm file names ({rule})")
    meta = {
        "layout": UTM_LAYOUT,
        "loader": "utm",
        "query_traverse": queries,
        "reference_traverse": database,
        "ground_truth_rule": rule + (f" (soft <= {soft:g} m)" if soft is not None else ""),
        "utm_zone": zone,
        "utm_query": uq,
        "utm_reference": ur,
    }
    return PlaceDataset(
        data_name(root),
        qp,
        rp,
        gt,
        f"{hard:g} m",
        root=root,
        meta=meta,
        ground_truth_soft=None if soft is None else dist <= soft,
    )
