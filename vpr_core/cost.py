"""Table 5: the cost of each stage, measured fresh on the code path that produced the results
(the pipeline's landmark stage, the run's encoder without its cache, then
:func:`vpr_core.matching.similarity_matrix` with the method's matching settings)."""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
import pandas as pd

from . import checks, paper
from .features.stage import get_encoder
from .landmarks.stage import landmarks_for_image
from .matching.similarity import similarity_matrix
from .methods import get_method

__all__ = ["COST_COLUMNS", "cost_table"]

#: Columns of Table 5 as measured here.
COST_COLUMNS = (
    "extract landmarks (s/img)",
    "computing CNN features (s/img)",
    "remaining steps (s/pair)",
    "matching two images (s)",
)


def _time_method(method: str, dataset, encoder, n: int, repeats: int) -> dict[str, float]:
    """Seconds per image (landmarks, features) and per pair (matching) of one method."""
    conf = get_method(method)
    t_lm = t_ft = t_match = 0.0
    for _ in range(repeats):
        boxes, descs = [], []
        for i in range(n):
            b, seconds = landmarks_for_image(conf.landmarks, dataset, "query", i, fresh=True)
            image = dataset.load_image("query", i)
            t0 = time.perf_counter()
            descs.append(encoder.encode(image, np.asarray(b)))
            t_ft += time.perf_counter() - t0
            t_lm += seconds
            boxes.append(np.asarray(b))
        t0 = time.perf_counter()
        similarity_matrix(descs, boxes, descs, boxes, matching=conf.matching)
        t_match += time.perf_counter() - t0
    per_img_lm, per_img_ft = t_lm / (repeats * n), t_ft / (repeats * n)
    per_pair = t_match / (repeats * n * n)
    return dict(
        zip(
            COST_COLUMNS,
            (per_img_lm, per_img_ft, per_pair, 2 * (per_img_lm + per_img_ft) + per_pair),
            strict=False,
        )
    )


def cost_table(
    dataset,
    methods: Sequence[str] = ("classical", "dense"),
    n_images: int = 4,
    repeats: int = 1,
    backbone: str = "efficientnet_lite0",
    pooling: str = "crop",
    seed: int = 0,
) -> pd.DataFrame:
    """Table 5 measured here, computed fresh on the first ``n_images`` query images.

    Args:
        dataset: a :class:`~vpr_core.datasets.PlaceDataset`.
        methods: method presets, one row each.
        n_images: images timed (all ``n * n`` pairs for the matching step).
        repeats: repetitions averaged.
        backbone, pooling, seed: the landmark encoder (as :func:`~vpr_core.run_method`).

    Returns:
        DataFrame indexed by method with :data:`COST_COLUMNS`: seconds per image for landmark
        extraction and CNN features, seconds per image pair for the remaining steps
        (reciprocal matching + Eq. (1)) and the total for matching two new images.

    Raises:
        ValueError: ``n_images`` or ``repeats`` below 1.
    """
    n_images, repeats = (
        checks.check_int(n_images, "n_images", 1),
        checks.check_int(repeats, "repeats", 1),
    )
    encoder = get_encoder(backbone, dim=paper.PROJECTION_DIM, seed=seed, pooling=pooling)
    n = min(n_images, len(dataset.query_paths))
    rows = [{"method": m, **_time_method(m, dataset, encoder, n, repeats)} for m in methods]
    return pd.DataFrame(rows).set_index("method")
