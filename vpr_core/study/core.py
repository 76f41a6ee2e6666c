"""The Study core: one notebook's dataset, backbone and output label, cached runs, saving and
recording; :func:`open_study`, :func:`table1` and :func:`extra_datasets`.

The figure methods live in the section modules (:mod:`.matches`, :mod:`.scales`,
:mod:`.landmarks`, :mod:`.comparisons`, :mod:`.tour`, :mod:`.cost`) and are mixed into
:class:`Study` here, so a notebook calls ``study.fig05_selection()`` and gets a
:class:`~vpr_core.study.result.FigureResult`.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import paths
from ..paper import PROJECTION_DIM, SCALE_LABELS, SCALE_RANGE_LABELS, SCALE_RANGES
from ..pipeline import MethodResult, get_encoder, run_method
from ..utils import configure_logging, make_deterministic
from ..viz.base import SAVE_DPI
from .comparisons import ComparisonFigures
from .cost import CostTable
from .landmarks import LandmarkFigures
from .matches import MatchFigures
from .result import FigureResult
from .scales import ScaleFigures
from .tour import TourSteps

__all__ = ["QUICK_PLACES", "RESULT_COLUMNS", "Study", "extra_datasets", "open_study", "table1"]

logger = logging.getLogger("vpr_core")

#: Places of the ``synthetic`` dataset in quick mode (the headless notebook tests).
QUICK_PLACES = 8
#: Images per side kept from a real dataset in quick mode.
QUICK_IMAGES = 20

#: Columns of ``results/<label>/<notebook>.csv``.
#: ``lo`` / ``hi``: 95% bootstrap interval over queries (1,000 resamples, seed 0); ``queries``:
#: queries with ground truth.
RESULT_COLUMNS = ["figure", "method", "run", "AUC", "AUC lo", "AUC hi", "R@100P", "R@100P lo",
                  "R@100P hi", "R@1", "R@1 lo", "R@1 hi", "R@5", "R@5 lo", "R@5 hi", "queries",
                  "landmarks/img", "landmarks s/img", "features s/img", "matching s/pair"]


def table1() -> pd.DataFrame:
    """Table 1 of the paper: the nine landmark scales and their normalised-scale ranges.

    Returns:
        ``(9, 3)`` DataFrame indexed ``Scale 1`` .. ``Scale 9`` with the range label and the
        lower (inclusive) and upper edges.
    """
    return pd.DataFrame({
        "scale index": list(SCALE_LABELS),
        "normalized scale": list(SCALE_RANGE_LABELS),
        "lower (incl.)": [lo for lo, _ in SCALE_RANGES],
        "upper": [hi for _, hi in SCALE_RANGES],
    }).set_index("scale index")


def _subset(dataset, n: int):
    """First ``n`` queries and references of a real dataset (quick runs)."""
    nq, nr = min(n, len(dataset.query_paths)), min(n, len(dataset.reference_paths))
    return dataclasses.replace(
        dataset, query_paths=list(dataset.query_paths[:nq]),
        reference_paths=list(dataset.reference_paths[:nr]),
        ground_truth=np.asarray(dataset.ground_truth)[:nq, :nr].copy())


@dataclass
class Study(MatchFigures, ScaleFigures, LandmarkFigures, ComparisonFigures, TourSteps,
            CostTable):
    """One notebook's view of the study: a dataset, a backbone and where outputs go.

    Every figure method (``fig01_labelled_matches`` ... ``fig14_coverage``, ``examples``,
    ``compare``, ``dense_sweep``, the tour steps) returns a :class:`FigureResult`; table
    methods (:func:`table1`, :meth:`dense_settings`, :meth:`cost_table`) return DataFrames.

    Attributes:
        dataset: the :class:`~vpr_core.datasets.PlaceDataset`.
        label: output subfolder name (the dataset name; ``<name>_quick`` in quick mode).
        notebook: the notebook's stem; metrics go to ``results/<label>/<notebook>.csv``.
        backbone: landmark encoder backbone.
        seed: seed of the encoder's random projection and of sampling.
        pooling: ``"crop"`` (the paper's per-landmark crops) or ``"roi"`` (one backbone pass).
    """

    dataset: Any
    label: str
    notebook: str
    backbone: str = "efficientnet_lite0"
    seed: int = 0
    pooling: str = "crop"
    _rows: list = field(default_factory=list, repr=False)
    _cache: dict = field(default_factory=dict, repr=False)
    _figure_results: dict = field(default_factory=dict, repr=False)

    # ---- infrastructure --------------------------------------------------------------------
    @property
    def figures_dir(self) -> Path:
        """``<output root>/figures/<label>`` (created)."""
        return paths.figures_dir(self.label)

    @property
    def results_dir(self) -> Path:
        """``<output root>/results/<label>`` (created)."""
        return paths.results_dir(self.label)

    @property
    def encoder(self):
        """The shared :class:`~vpr_core.features.LandmarkEncoder` of this study's backbone."""
        return get_encoder(self.backbone, PROJECTION_DIM, self.seed, pooling=self.pooling)

    def save(self, fig, stem: str, table: pd.DataFrame | None = None,
             panels: Sequence[Path] = ()) -> FigureResult:
        """Write ``fig`` as ``figures/<label>/<stem>.png`` (byte-deterministic), close it in
        pyplot and wrap it with its table."""
        import matplotlib.pyplot as plt

        from ..viz import save_figure

        path = save_figure(fig, stem, dataset=self.label, dpi=SAVE_DPI)
        plt.close(fig)
        return FigureResult(figure=fig, path=path, table=table, panels=tuple(panels),
                            dpi=SAVE_DPI)

    def run(self, method: str, label: str | None = None, keep_descriptors: bool = False,
            **overrides: Any) -> MethodResult:
        """Run (cached in this study) one method on the study's dataset.

        Args:
            method: a preset name (:func:`vpr_core.methods.available_methods`).
            label: display label (legend, table row); default from the config.
            keep_descriptors: keep the descriptors (the scale statistics need them).
            **overrides: flat config overrides, e.g. ``iou_threshold=0.4``.
        """
        key = (method, label, keep_descriptors, tuple(sorted(overrides.items())))
        if key not in self._cache:
            self._cache[key] = run_method(method, self.dataset, backbone=self.backbone,
                                          seed=self.seed, label=label, pooling=self.pooling,
                                          keep_descriptors=keep_descriptors, **overrides)
        return self._cache[key]

    def record(self, figure: str, results: Sequence[Any]) -> pd.DataFrame:
        """Append metrics rows for a figure and rewrite ``results/<label>/<notebook>.csv``.

        Args:
            figure: the figure stem the rows belong to (rows of an earlier call with the same
                stem are replaced).
            results: objects with ``.row()`` (a :class:`~vpr_core.pipeline.MethodResult`).

        Returns:
            This figure's rows, indexed by method label.
        """
        rows = [{"figure": figure, **r.row()} for r in results]
        self._rows = [r for r in self._rows if r["figure"] != figure] + rows
        table = pd.DataFrame(self._rows, columns=RESULT_COLUMNS)
        table.to_csv(self.results_dir / f"{self.notebook}.csv", index=False, float_format="%.6f")
        return pd.DataFrame(rows, columns=RESULT_COLUMNS).set_index("method").drop(
            columns="figure")

    def describe(self) -> str:
        """One paragraph: dataset, sizes, tolerance, backbone and its weights."""
        d = self.dataset
        return (f"dataset {d.name!r} ({self.label}): {len(d.query_paths)} queries, "
                f"{len(d.reference_paths)} references, tolerance {d.tolerance}; "
                f"backbone {self.backbone} (weights: {self.encoder.config.get('weights')}, "
                f"pooling {self.pooling}); metrics with 95% bootstrap intervals over queries")


def open_study(dataset: str = "synthetic", root: str | None = None,
               backbone: str = "efficientnet_lite0", quick: bool = False,
               notebook: str = "study", label: str | None = None, seed: int = 0,
               pooling: str = "crop", **options: Any) -> Study:
    """Open the study for a notebook (and set up the ``vpr_core`` log output).

    Args:
        dataset: dataset name (see :func:`vpr_core.datasets.load_dataset`).
        root: dataset folder for real datasets.
        backbone: landmark encoder backbone.
        quick: small run (``synthetic`` with :data:`QUICK_PLACES` places; the first
            :data:`QUICK_IMAGES` images of real datasets); outputs go to ``<name>_quick``.
        notebook: the calling notebook's stem (names the metrics CSV).
        label: output subfolder (default: dataset name, ``_quick`` appended in quick mode).
        seed: seed of the encoder projection and of sampling.
        pooling: landmark pooling, ``"crop"`` (default, the paper's) or ``"roi"``.
        **options: passed to the loader (e.g. ``tolerance``, ``step``).

    Returns:
        A :class:`Study` writing under :func:`vpr_core.paths.output_root`.
    """
    from ..datasets import load_dataset

    configure_logging()
    make_deterministic(seed)
    if dataset == "synthetic" and quick:
        options.setdefault("n_places", QUICK_PLACES)
    ds = load_dataset(dataset, root=root, **options)
    if quick and dataset != "synthetic":
        ds = _subset(ds, QUICK_IMAGES)
    label = label or ds.name
    if quick and not label.endswith("_quick"):
        label += "_quick"
    logger.info("study %s: %s (outputs under %s)", notebook, label, paths.output_root())
    return Study(dataset=ds, label=label, notebook=notebook, backbone=backbone, seed=seed,
                 pooling=pooling)


#: The Nordland subset of ``make study``: every 50th of the 3,576 places of
#: ``../shared/data/nordland_64x32`` (72 places, 500 original frames apart, so tolerance 0),
#: winter queries against summer references, ``roi`` pooling (one backbone pass per image: the
#: 64x32 frames make per-landmark crops as slow as full-size images for no extra detail).
NORDLAND_STUDY = {"dataset": "nordland", "options": {"step": 50, "tolerance": 0},
                  "pooling": "roi"}


def extra_datasets() -> dict[str, dict]:
    """Real datasets found beside the project, for the comparison notebooks (03-06).

    ``../shared/data/gardens_point_mini`` next to the source checkout (10 Gardens Point
    day/night pairs, crop pooling), ``../shared/data/nordland_64x32`` (the
    :data:`NORDLAND_STUDY` subset) when present, and any ``VPR_DATASETS`` entries
    (``name=root`` separated by ``;``; ``name`` is a :func:`~vpr_core.datasets.load_dataset`
    name; loader defaults, crop pooling).

    Returns:
        ``{label: {"dataset": loader name, "root": folder, "options": {...}, "pooling": ...}}``.
    """
    from ..runner import source_checkout

    found: dict[str, dict] = {}
    checkout = source_checkout()
    if checkout is not None:
        data = checkout.parent / "shared" / "data"
        if (data / "gardens_point_mini").is_dir():
            found["gardens_point_mini"] = {"dataset": "folder",
                                           "root": str(data / "gardens_point_mini"),
                                           "options": {}, "pooling": "crop"}
        if (data / "nordland_64x32").is_dir():
            found["nordland_step50"] = {**NORDLAND_STUDY, "root": str(data / "nordland_64x32")}
    for item in filter(None, os.environ.get("VPR_DATASETS", "").split(";")):
        name, sep, root = item.partition("=")
        if not sep or not name.strip() or not root.strip():
            raise ValueError(f"VPR_DATASETS entry {item!r} is not 'name=root'; write entries as "
                             "'gardens_point=/data/gp;folder=/data/x'.")
        found[name.strip()] = {"dataset": name.strip(), "root": root.strip(), "options": {},
                               "pooling": "crop"}
    return found
