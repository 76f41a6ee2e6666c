"""Place-recognition datasets: one loader per dataset, a registry, and the synthetic generator.

See :mod:`vpr_core.datasets.core` for the dataset model, ground-truth files and the real-data
loaders, and :mod:`vpr_core.datasets.synthetic` for the embedded default.
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable
from typing import Any

from .core import (
    DOWNLOADS,
    IMAGE_EXTENSIONS,
    PlaceDataset,
    download_dataset,
    list_images,
    load_folder,
    load_freiburg_across_seasons,
    load_gardens_point,
    load_mapillary_berlin,
    read_ground_truth,
    read_image,
)
from .synthetic import load_synthetic, render_synthetic_place, synthetic_homography

__all__ = [
    "DATASETS",
    "DOWNLOADS",
    "IMAGE_EXTENSIONS",
    "PlaceDataset",
    "download_dataset",
    "list_images",
    "load_dataset",
    "load_folder",
    "load_freiburg_across_seasons",
    "load_gardens_point",
    "load_mapillary_berlin",
    "load_synthetic",
    "read_ground_truth",
    "read_image",
    "render_synthetic_place",
    "synthetic_homography",
]

# ----------------------------------------------------------------------------------------------
# Registry and entry point
# ----------------------------------------------------------------------------------------------

DATASETS: dict[str, Callable[..., PlaceDataset]] = {
    "synthetic": load_synthetic,
    "gardens_point": load_gardens_point,
    "mapillary_berlin": load_mapillary_berlin,
    "freiburg_across_seasons": load_freiburg_across_seasons,
    "folder": load_folder,
}


def load_dataset(name: str, root: str | os.PathLike | None = None, **options: Any) -> PlaceDataset:
    """Load a dataset by name.

    Args:
        name: One of :data:`DATASETS` (``synthetic``, ``gardens_point``, ``mapillary_berlin``,
            ``freiburg_across_seasons``, ``folder``).
        root: Dataset folder (not needed for ``synthetic``).
        **options: Loader options, e.g. ``tolerance``; ``synthetic`` takes ``n_places``,
            ``seed``, ``image_size``.

    Returns:
        A :class:`PlaceDataset`.

    Raises:
        ValueError: unknown name (the message lists the valid ones) or a bad option value.
        TypeError: an option the loader does not take (the message lists those it takes).
        FileNotFoundError: missing root or traverse folders.
    """
    key = str(name).strip().lower().replace("-", "_")
    if key not in DATASETS:
        raise ValueError(
            f"unknown dataset {name!r}; valid names: {', '.join(DATASETS)}. Use 'folder' for any "
            "query/ + reference/ pair of folders."
        )
    loader = DATASETS[key]
    valid = [p for p in inspect.signature(loader).parameters if p != "root"]
    bad = sorted(set(options) - set(valid))
    if bad:
        raise TypeError(
            f"dataset {key!r} does not take option(s) {', '.join(bad)}; valid options: "
            f"{', '.join(valid)}."
        )
    return loader(root=root, **options)
