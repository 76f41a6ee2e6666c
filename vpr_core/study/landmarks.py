"""Landmark pictures: dataset examples, the dense scales (Fig. 9) and coverage (Fig. 14)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from ..paper import DENSE_SCALES
from .result import FigureResult

__all__ = ["LandmarkFigures"]


class LandmarkFigures:
    """Study methods for the examples, Fig. 9 and Fig. 14 (mixed into ``Study``)."""

    def examples(self, figure: str = "examples", indices: Sequence[int] = (0, 1, 2)
                 ) -> FigureResult:
        """Reference/query pairs with the dense landmarks of the smallest dense scale drawn."""
        from ..landmarks import dense_sampling
        from ..viz import plot_examples

        idx = [i for i in indices if i < len(self.dataset.query_paths)]
        smallest = DENSE_SCALES[0]
        fig = plot_examples(self.dataset, indices=idx,
                            boxes=lambda side, i, size: dense_sampling(size, scales=(smallest,)),
                            title=f"{self.dataset.name}: reference (left) / query (right); dense "
                                  f"landmarks of scale {smallest:g} drawn (Fig. 9 shows all four "
                                  "scales)")
        return self.save(fig, figure)

    def fig09_dense_scales(self, index: int = 0) -> FigureResult:
        """Fig. 9: the four dense sampling scales (25 landmarks each) on a reference image."""
        from ..viz import plot_dense_scales

        fig = plot_dense_scales(self.dataset.load_image("reference", index))
        return self.save(fig, "fig09_dense_scales")

    def fig14_coverage(self, figure: str = "fig14_coverage", index: int = 0,
                       side: str = "reference") -> FigureResult:
        """Fig. 14: landmark coverage heatmaps, top-100 Edge Boxes vs dense sampling.

        Args:
            figure: file stem (notebook 01 writes ``fig14_coverage``, notebook 06
                ``fig14_coverage_comparison``).
            index: the image shown.
            side: ``"query"`` or ``"reference"``.

        Returns:
            The figure and, per method, the share of the image covered by at least one
            landmark for this image and averaged over the dataset's images of that side.
        """
        import matplotlib.pyplot as plt

        from ..landmarks import landmark_coverage
        from ..viz import plot_coverage

        image = self.dataset.load_image(side, index)
        fig, axes = plt.subplots(1, 2, figsize=(11, 3.4))
        rows = []
        for ax, method in zip(axes, ("classical", "dense")):
            res = self.run(method)
            plot_coverage(image, res.boxes[side][index], ax=ax)
            ax.set_title(f"({'ab'[method == 'dense']}) {method}: {len(res.boxes[side][index])} "
                         "landmarks")
            shares = []
            for i, b in enumerate(res.boxes[side]):
                cov = landmark_coverage(b, self.dataset.image_size(side, i))
                shares.append(float((cov > 0).mean()))
            rows.append({"method": method, "covered share (this image)": shares[index],
                         "covered share (mean)": float(np.mean(shares))})
        fig.tight_layout()
        return self.save(fig, figure, table=pd.DataFrame(rows).set_index("method"))
