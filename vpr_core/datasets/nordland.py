"""Nordland (NRK 2012-13, CC BY 3.0): one railway route filmed in four seasons, frame-synchronised.
Any copy whose season folders hold the same file names loads (the 64x32 SeqSLAM-style subset,
the full-size partitioned release)."""

from __future__ import annotations

import logging
import os

from ..checks import check_choice, check_int
from ._layout import check_root, data_name
from .base import PlaceDataset
from .ground_truth import check_tolerance, frame_aligned
from .images import list_images

__all__ = ["NORDLAND_LAYOUT", "load_nordland"]

log = logging.getLogger("vpr_core")

NORDLAND_LAYOUT = (
    "<root>/<season>/<frame>.png for each season (e.g. summer/, winter/), the same file names in "
    "every season folder: a file name is a place"
)
_MISSING = ("error", "intersect")


def _season_files(root: os.PathLike, season: str, seasons: list[str]) -> dict:
    if season not in seasons:
        raise FileNotFoundError(
            f"nordland: season folder {season!r} not found in {root}; seasons found: "
            f"{', '.join(seasons) or 'none'}. Pass query=/reference= one of those. Expected "
            f"layout: {NORDLAND_LAYOUT}"
        )
    paths = list_images(os.path.join(root, season), f"nordland {season} folder")
    return {p.name: p for p in paths}


def _common_names(q: dict, r: dict, query: str, reference: str, missing: str) -> list[str]:
    only_q = sorted(set(q) - set(r))
    only_r = sorted(set(r) - set(q))
    if not only_q and not only_r:
        return list(q)
    detail = (
        f"{len(only_q)} file(s) only in {query} (e.g. {only_q[:3]}), {len(only_r)} only in "
        f"{reference} (e.g. {only_r[:3]})"
    )
    if missing == "error":
        raise ValueError(
            f"nordland: the season folders do not hold the same file names: {detail}. The "
            "seasons are matched by file name; remove or restore those files, or pass "
            "missing='intersect' to keep only the names present in both."
        )
    keep = [n for n in q if n in r]
    log.warning(
        "nordland: %s; keeping the %d file names present in both (missing='intersect')",
        detail,
        len(keep),
    )
    return keep


def load_nordland(
    root: str | os.PathLike | None = None,
    query: str = "winter",
    reference: str = "summer",
    tolerance: int = 1,
    step: int = 1,
    missing: str = "error",
) -> PlaceDataset:
    """Nordland, one season against another, matched by file name.

    Layout::

        <root>/summer/images-00010.png ...   # one folder per season
        <root>/winter/images-00010.png ...   # the same file names: a file name is a place

    Places are the file names, naturally sorted; ``step`` keeps every ``step``-th of them (first
    kept: the first). Query ``i`` and reference ``i`` are the same file name, and the ground truth
    is ``|i - j| <= tolerance`` over the kept places (so the tolerance is in kept places: on the
    64x32 subset, which holds every 10th original frame, ``step=10, tolerance=1`` is +-100
    original frames). ``missing``: a file name present in one season only is an ``"error"`` (an
    incomplete copy) or, with ``"intersect"``, dropped with a warning giving the counts.
    """
    tolerance = check_tolerance(tolerance)
    step = check_int(step, "nordland: step", minimum=1)
    check_choice(missing, "nordland missing", _MISSING)
    root = check_root(root, "nordland", NORDLAND_LAYOUT)
    seasons = sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    q_files = _season_files(root, query, seasons)
    r_files = _season_files(root, reference, seasons)
    names = _common_names(q_files, r_files, query, reference, missing)[::step]
    qp = [q_files[n] for n in names]
    rp = [r_files[n] for n in names]
    gt = frame_aligned(len(qp), len(rp), tolerance)
    meta = {
        "query_traverse": query,
        "reference_traverse": reference,
        "step": step,
        "seasons_found": seasons,
        "layout": NORDLAND_LAYOUT,
        "ground_truth_rule": f"same file name, |i-j|<={tolerance} kept places",
        "frame_aligned": True,
    }
    meta["loader"] = "nordland"
    return PlaceDataset(data_name(root), qp, rp, gt, tolerance, root=root, meta=meta)
