"""Place-recognition datasets: :class:`PlaceDataset` (``base``), image files (``images``), ground
truth (``ground_truth``), one module per loader and the synthetic generator (downloads:
:mod:`vpr_study.download`); here the registry :data:`DATASETS` and :func:`load_dataset`."""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable
from typing import Any

from ..checks import check_options
from .base import SIDES, PlaceDataset
from .folder import load_folder
from .freiburg import load_freiburg_across_seasons
from .gardens_point import load_gardens_point
from .ground_truth import ground_truth_references, ground_truth_text
from .images import list_images, read_image
from .mapillary_berlin import load_mapillary_berlin
from .nordland import load_nordland
from .safe_pickle import read_npy
from .synthetic import load_synthetic
from .utm import load_utm
from .vpr_bench import load_vpr_bench

__all__ = [
    "DATASETS",
    "SIDES",
    "PlaceDataset",
    "ground_truth_references",
    "ground_truth_text",
    "list_images",
    "load_dataset",
    "read_image",
    "read_npy",
]

DATASETS: dict[str, Callable[..., PlaceDataset]] = {
    "synthetic": load_synthetic,
    "gardens_point": load_gardens_point,
    "mapillary_berlin": load_mapillary_berlin,
    "freiburg_across_seasons": load_freiburg_across_seasons,
    "folder": load_folder,
    "nordland": load_nordland,
    "vpr_bench": load_vpr_bench,
    "utm": load_utm,
}


def load_dataset(name: str, root: str | os.PathLike | None = None, **options: Any) -> PlaceDataset:
    """Load one of :data:`DATASETS` by name; ``**options`` go to its loader (e.g. ``tolerance``;
    ``synthetic``: ``n_places``, ``seed``, ``image_size``; ``nordland``: ``query``, ``reference``,
    ``step``). A relative ``root`` is read from the cwd, else from the project root
    (:func:`vpr_core.paths.find_input`, by each loader); ``synthetic`` generates its set into
    ``root``.
    Unknown names and options: the error lists valid ones.
    """
    key = str(name).strip().lower().replace("-", "_")
    if key not in DATASETS:
        raise ValueError(
            f"unknown dataset {name!r}; valid names: {', '.join(DATASETS)}. Use 'folder' for any "
            "query/ + reference/ pair of folders."
        )
    loader = DATASETS[key]
    check_options(
        options,
        [p for p in inspect.signature(loader).parameters if p != "root"],
        f"dataset {key!r}",
    )
    return loader(root=root, **options)
