"""Table 5: the cost of each stage, measured here on the code path that produced the results.

For each method the landmark stage is the pipeline's own
(:func:`vpr_core.pipeline.landmarks_for_image`: Edge Boxes' 1,000 candidates then the method's
selection, or the dense grid), the features are :meth:`LandmarkEncoder.encode` of the study's
encoder, and the remaining steps are :func:`vpr_core.matching.similarity_matrix` with the
method's matching settings. Everything is computed fresh: the pipeline's caches point at an
empty temporary folder while timing.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

import numpy as np
import pandas as pd

from ..paths import CACHE_ENV
from ..utils import make_deterministic

__all__ = ["COST_COLUMNS", "CostTable", "fresh_cache"]

#: Columns of Table 5 as measured here.
COST_COLUMNS = ("extract landmarks (s/img)", "computing CNN features (s/img)",
                "remaining steps (s/pair)", "matching two images (s)")


@contextmanager
def fresh_cache() -> Iterator[str]:
    """Point ``$VPR_CACHE_DIR`` at a new empty folder for the duration (restored after)."""
    before = os.environ.get(CACHE_ENV)
    with tempfile.TemporaryDirectory(prefix="vpr-cost-") as tmp:
        os.environ[CACHE_ENV] = tmp
        try:
            yield tmp
        finally:
            if before is None:
                os.environ.pop(CACHE_ENV, None)
            else:
                os.environ[CACHE_ENV] = before


class CostTable:
    """Study method for Table 5 (mixed into :class:`~vpr_core.study.Study`)."""

    def _time_method(self, method: str, n: int, repeats: int) -> dict[str, float]:
        """Seconds per image (landmarks, features) and per pair (matching) of one method."""
        from ..matching import similarity_matrix
        from ..methods import get_method
        from ..pipeline import landmarks_for_image

        conf = get_method(method)
        t_lm = t_ft = t_match = 0.0
        for _ in range(repeats):
            boxes, descs = [], []
            with fresh_cache():  # the landmark stage computes, not reads, its candidates
                for i in range(n):
                    # seconds measured by the stage itself, around the computation only
                    b, seconds = landmarks_for_image(conf, self.dataset, "query", i)
                    image = self.dataset.load_image("query", i)
                    t0 = time.perf_counter()
                    d = self.encoder.encode(image, np.asarray(b))
                    t_ft += time.perf_counter() - t0
                    t_lm += seconds
                    boxes.append(np.asarray(b))
                    descs.append(d)
            t0 = time.perf_counter()
            similarity_matrix(descs, boxes, descs, boxes,
                              soft_nms_iou=conf["matching"]["soft_nms_iou"],
                              sigma=conf["matching"]["sigma"])
            t_match += time.perf_counter() - t0
        per_img_lm, per_img_ft = t_lm / (repeats * n), t_ft / (repeats * n)
        per_pair = t_match / (repeats * n * n)
        return dict(zip(COST_COLUMNS, (per_img_lm, per_img_ft, per_pair,
                                       2 * (per_img_lm + per_img_ft) + per_pair)))

    def cost_table(self, n_images: int = 4, repeats: int = 1,
                   methods: Sequence[str] = ("classical", "dense")) -> pd.DataFrame:
        """Table 5 measured here, computed fresh on the first ``n_images`` query images.

        Args:
            n_images: images timed (all ``n * n`` pairs for the matching step).
            repeats: repetitions averaged.
            methods: method presets, one row each.

        Returns:
            DataFrame indexed by method with :data:`COST_COLUMNS`: seconds per image for
            landmark extraction and CNN features, seconds per image pair for the remaining
            steps (reciprocal matching + Eq. (1)) and the total for matching two new images.
            Also written to ``results/<label>/<notebook>_table5_cost.csv``.
        """
        if n_images < 1 or repeats < 1:
            raise ValueError(f"cost_table needs n_images >= 1 and repeats >= 1, got "
                             f"{n_images} and {repeats}.")
        make_deterministic(self.seed)
        n = min(n_images, len(self.dataset.query_paths))
        rows = [{"method": m, **self._time_method(m, n, repeats)} for m in methods]
        frame = pd.DataFrame(rows).set_index("method")
        frame.to_csv(self.results_dir / f"{self.notebook}_table5_cost.csv", float_format="%.6f")
        return frame
