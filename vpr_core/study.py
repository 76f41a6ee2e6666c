"""The study, section by section: one function per notebook cell.

Notebooks stay thin: they open a :class:`Study` with their parameters and call its methods,
each of which computes (through the cached :mod:`vpr_core.pipeline`), prints/returns a table,
draws the figure and writes it to ``figures/<dataset>/figNN_<name>.png`` and the metrics to
``results/<dataset>/<notebook>.csv``.

The paper's experimental settings live here as data: :data:`TABLE2`, :data:`TABLE3`,
:data:`TABLE4` (dense sampling sweeps), :data:`OVERLAP_NMS_THRESHOLDS` and
:data:`OVERLAP_SOFT_NMS_THRESHOLDS` (Fig. 7).
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from . import landmarks as lm
from .pipeline import MethodResult, get_encoder, run_method
from .utils import REPO_DIR, logger, make_deterministic

# ---- the paper's settings (data) ----------------------------------------------------------
#: Table 2: scale levels (setting -> (scales, per_scale)).
TABLE2: dict[str, tuple[tuple[float, ...], int]] = {
    "Set 1": ((0.25,), 100),
    "Set 2": ((0.49,), 100),
    "Set 3": ((0.25, 0.49), 49),
    "Set 4": ((0.16, 0.36), 49),
    "Set 5": ((0.16, 0.25, 0.36, 0.49), 25),
    "Set 6": ((0.09, 0.18, 0.25, 0.33, 0.41, 0.49), 16),
}
#: Table 3: landmarks per scale at scales (0.16, 0.25, 0.36, 0.49).
TABLE3: dict[str, tuple[tuple[float, ...], tuple[int, ...]]] = {
    "Set 1": ((0.16, 0.25, 0.36, 0.49), (25, 25, 25, 25)),
    "Set 2": ((0.16, 0.25, 0.36, 0.49), (36, 25, 25, 16)),
    "Set 3": ((0.16, 0.25, 0.36, 0.49), (36, 36, 16, 16)),
    "Set 4": ((0.16, 0.25, 0.36, 0.49), (49, 25, 16, 9)),
    "Set 5": ((0.16, 0.25, 0.36, 0.49), (49, 36, 9, 9)),
}
#: Table 4: normalised scales with 25 landmarks per scale.
TABLE4: dict[str, tuple[tuple[float, ...], int]] = {
    "Set 1": ((0.16, 0.25, 0.36, 0.49), 25),
    "Set 2": ((0.18, 0.27, 0.38, 0.51), 25),
    "Set 3": ((0.09, 0.20, 0.32, 0.44), 25),
    "Set 4": ((0.20, 0.32, 0.44, 0.54), 25),
}
DENSE_TABLES = {"table2": TABLE2, "table3": TABLE3, "table4": TABLE4}
OVERLAP_NMS_THRESHOLDS = (0.4, 0.5, 0.6, 0.7)
OVERLAP_SOFT_NMS_THRESHOLDS = (0.3, 0.4, 0.5, 0.6, 0.7)
QUICK_PLACES = 8

RESULT_COLUMNS = ["figure", "method", "AUC(ratio)", "R@100P", "R@1", "R@5", "landmarks/img",
                  "landmarks s/img", "features s/img", "matching s/pair"]


def table1() -> pd.DataFrame:
    """Table 1 of the paper: the nine landmark scales and their normalised-scale ranges."""
    edges = (0.0, *lm.SCALE_EDGES, 1.0)
    return pd.DataFrame({
        "scale index": [f"Scale {k}" for k in range(1, 10)],
        "normalized scale": [f"{edges[k]:g}~{edges[k + 1]:g}" for k in range(9)],
        "lower (incl.)": edges[:9], "upper": edges[1:],
    }).set_index("scale index")


def results_dir(label: str) -> Path:
    """``results/<label>`` (or ``$VPR_RESULTS_DIR/<label>``), created."""
    root = Path(os.environ.get("VPR_RESULTS_DIR", REPO_DIR / "results"))
    d = root / label
    d.mkdir(parents=True, exist_ok=True)
    return d


def _subset(dataset, n: int):
    """First ``n`` queries and references of a real dataset (quick runs)."""
    nq, nr = min(n, len(dataset.query_paths)), min(n, len(dataset.reference_paths))
    return dataclasses.replace(
        dataset, query_paths=list(dataset.query_paths[:nq]),
        reference_paths=list(dataset.reference_paths[:nr]),
        ground_truth=np.asarray(dataset.ground_truth)[:nq, :nr].copy())


@dataclass
class Study:
    """One notebook's view of the study: a dataset, a backbone and where outputs go.

    Attributes:
        dataset: the :class:`~vpr_core.datasets.PlaceDataset`.
        label: output subfolder name (the dataset name; ``<name>_quick`` in quick mode).
        notebook: the notebook's stem; metrics go to ``results/<label>/<notebook>.csv``.
        backbone: landmark encoder backbone.
    """

    dataset: Any
    label: str
    notebook: str
    backbone: str = "efficientnet_lite0"
    quick: bool = False
    seed: int = 0
    _rows: list = field(default_factory=list, repr=False)
    _cache: dict = field(default_factory=dict, repr=False)

    # ---- infrastructure --------------------------------------------------------------------
    @property
    def figures_dir(self) -> Path:
        from .viz import figures_dir

        return figures_dir(self.label)

    @property
    def results_dir(self) -> Path:
        return results_dir(self.label)

    def save(self, fig, name: str) -> Path:
        """Write a figure as ``figures/<label>/<name>.png`` (byte-deterministic) and close it."""
        import matplotlib.pyplot as plt

        from .viz import save_figure

        path = save_figure(fig, name, dataset=self.label)
        plt.close(fig)
        return path

    def run(self, method: str, label: str | None = None, keep_descriptors: bool = False,
            **overrides: Any) -> MethodResult:
        """Run (cached in this study) one method on the study's dataset."""
        key = (method, label, keep_descriptors, tuple(sorted(overrides.items())))
        if key not in self._cache:
            self._cache[key] = run_method(method, self.dataset, backbone=self.backbone,
                                          seed=self.seed, label=label,
                                          keep_descriptors=keep_descriptors, **overrides)
        return self._cache[key]

    def record(self, figure: str, results: Sequence[MethodResult]) -> pd.DataFrame:
        """Append metrics rows for a figure and rewrite ``results/<label>/<notebook>.csv``."""
        rows = [{"figure": figure, **r.row()} for r in results]
        self._rows = [r for r in self._rows if r["figure"] != figure] + rows
        table = pd.DataFrame(self._rows, columns=RESULT_COLUMNS)
        table.to_csv(self.results_dir / f"{self.notebook}.csv", index=False, float_format="%.6f")
        return pd.DataFrame(rows, columns=RESULT_COLUMNS).set_index("method").drop(
            columns="figure")

    def describe(self) -> str:
        """One paragraph: dataset, sizes, tolerance, backbone and its weights."""
        enc = get_encoder(self.backbone, 1024, self.seed)
        d = self.dataset
        return (f"dataset {d.name!r} ({self.label}): {len(d.query_paths)} queries, "
                f"{len(d.reference_paths)} references, tolerance {d.tolerance}; "
                f"backbone {self.backbone} (weights: {enc.config.get('weights')})")

    # ---- PR comparisons (Fig. 5, 7, 10-13) ---------------------------------------------------
    def compare(self, runs: Sequence[str | tuple[str, dict]], figure: str,
                title: str | None = None) -> pd.DataFrame:
        """Run several methods, plot their PR curves (ratio protocol) and record the metrics.

        Args:
            runs: method names, or ``(name, overrides)`` / ``(name, overrides, label)`` tuples.
            figure: figure file stem, e.g. ``"fig05_selection"``.
            title: plot title (default: the figure stem and dataset).

        Returns:
            The metrics table (one row per method).
        """
        from .viz import plot_pr_curves

        results = []
        for item in runs:
            if isinstance(item, str):
                results.append(self.run(item))
            else:
                name, overrides, *rest = item
                results.append(self.run(name, label=rest[0] if rest else None, **overrides))
        ttl = title or figure
        fig = plot_pr_curves({r.label: r.curve() for r in results},
                             title=f"{ttl}\n{self.label} ({len(self.dataset.query_paths)} queries, "
                                   f"tolerance {self.dataset.tolerance})")
        self.save(fig, figure)
        return self.record(figure, results)

    def dense_sweep(self, table: str, figure: str) -> pd.DataFrame:
        """Dense-sampling settings of the paper's Table 2, 3 or 4 (Fig. 10, 11, 12)."""
        if table not in DENSE_TABLES:
            raise ValueError(f"Unknown table {table!r}; valid: {', '.join(DENSE_TABLES)}.")
        runs = []
        for set_name, (scales, per_scale) in DENSE_TABLES[table].items():
            ps = "/".join(map(str, per_scale)) if isinstance(per_scale, tuple) else per_scale
            lab = f"{set_name}: {'/'.join(f'{s:g}' for s in scales)} x {ps}"
            runs.append(("dense", {"scales": scales, "per_scale": per_scale}, lab))
        return self.compare(runs, figure, title=f"{figure} ({table.replace('table', 'Table ')})")

    @staticmethod
    def dense_settings(table: str) -> pd.DataFrame:
        """The paper's Table 2/3/4 as a DataFrame (setting, scales, per scale, total)."""
        rows = []
        for set_name, (scales, per_scale) in DENSE_TABLES[table].items():
            counts = per_scale if isinstance(per_scale, tuple) else (per_scale,) * len(scales)
            rows.append({"setting": set_name, "normalized scales": scales,
                         "landmarks per scale": counts, "total": int(sum(counts))})
        return pd.DataFrame(rows).set_index("setting")

    # ---- Section 3.1: scale statistics -------------------------------------------------------
    def scale_statistics(self, method: str = "classical", n_irrelevant: int = 5, **overrides):
        """CMR / CLS / ASL per Table-1 scale for a method's landmarks (Fig. 4).

        Labels: ``exact`` on ``synthetic`` (generator geometry), ``geometric`` (SIFT + RANSAC)
        on real datasets.
        """
        from .statistics import scale_statistics

        res = self.run(method, keep_descriptors=True, **overrides)
        stats = scale_statistics(self.dataset, res.boxes["query"], res.boxes["reference"],
                                 res.descriptors["query"], res.descriptors["reference"],
                                 n_irrelevant=n_irrelevant, seed=self.seed)
        frame = stats.to_frame()
        frame.to_csv(self.results_dir / f"{self.notebook}_scale_statistics_{method}.csv",
                     float_format="%.6f")
        # every match with its scale, score and label: the statistics can be recomputed from it
        stats.matches_frame().to_csv(
            self.results_dir / f"{self.notebook}_scale_statistics_{method}_matches.csv",
            index=False, float_format="%.8f")
        return stats

    def plot_scale_statistics(self, stats, prefix: str = "fig04") -> list[Path]:
        """Fig. 4 (a) CMR, (b) CLS, (c) ASL as three files plus one combined figure."""
        import matplotlib.pyplot as plt

        from .viz import plot_asl, plot_cls, plot_cmr, plot_scale_statistics

        paths = []
        for suffix, fn in (("a_cmr", plot_cmr), ("b_cls", plot_cls), ("c_asl", plot_asl)):
            fig, ax = plt.subplots(figsize=(5.5, 3.6))
            fn(stats, ax=ax)
            fig.tight_layout()
            paths.append(self.save(fig, f"{prefix}{suffix}"))
        paths.append(self.save(plot_scale_statistics(stats), f"{prefix}_scale_statistics"))
        return paths

    def labelled_matches(self, pair: int = 0, method: str = "classical",
                         reference: int | None = None, figure: str = "fig01_labelled_matches"):
        """Matched landmarks of one image pair coloured correct/incorrect (Fig. 1-2).

        ``reference=None`` uses the query's ground-truth reference (Fig. 1); another index
        shows a query-irrelevant pair, where every match is wrong (Fig. 2).
        """
        from .matching import match_landmarks
        from .statistics import LabelUnavailableError, label_matches
        from .viz import plot_labelled_matches

        res = self.run(method, keep_descriptors=True)
        q = int(pair)
        gt = np.asarray(self.dataset.ground_truth, dtype=bool)
        if reference is None:
            r = q if q < gt.shape[1] and gt[q, q] else int(np.flatnonzero(gt[q])[0])
        else:
            r = int(reference)
        m = match_landmarks(res.descriptors["query"][q], res.boxes["query"][q],
                            res.descriptors["reference"][r], res.boxes["reference"][r])
        note = ""
        if bool(gt[q, r]):
            try:
                labels = label_matches(self.dataset, q, r, res.boxes["query"][q],
                                       res.boxes["reference"][r], m.matches)
            except LabelUnavailableError as exc:
                labels, note = None, f" (labels unavailable: {exc})"
                logger.warning("pair (%d, %d) cannot be labelled: %s", q, r, exc)
        else:
            labels = np.zeros(len(m.matches), dtype=bool)
        fig = plot_labelled_matches(self.dataset.load_image("query", q),
                                    self.dataset.load_image("reference", r),
                                    res.boxes["query"][q], res.boxes["reference"][r],
                                    m.matches, labels)
        counts = (f"{int(labels.sum())}/{len(labels)} matches correct" if labels is not None
                  else f"{len(m.matches)} matches, unlabelled{note[:80]}")
        fig.suptitle(f"{res.label}: query {q} vs reference {r} "
                     f"({'ground truth' if gt[q, r] else 'irrelevant'}); {counts}; "
                     f"S = {m.similarity:.3f}", fontsize=9)
        self.save(fig, figure)
        return fig

    # ---- Section 3.1: scale distributions (Fig. 6) -----------------------------------------
    def scale_distribution(self, method: str, figure: str) -> pd.DataFrame:
        """Landmark counts per Table-1 scale for query and reference images (Fig. 6)."""
        from .viz import plot_scale_distribution

        res = self.run(method)
        hists = {}
        for side in ("query", "reference"):
            h = np.zeros(10, dtype=np.int64)
            for i, b in enumerate(res.boxes[side]):
                h += lm.scale_histogram(b, self.dataset.image_size(side, i))
            hists[side] = h
        fig = plot_scale_distribution(hists, title=f"{res.label}: landmarks per scale "
                                                    f"({self.dataset.name})")
        self.save(fig, figure)
        frame = pd.DataFrame({k: v[1:] for k, v in hists.items()},
                             index=[f"Scale {k}" for k in range(1, 10)])
        frame.to_csv(self.results_dir / f"{self.notebook}_{figure}.csv")
        return frame

    # ---- Section 4 / 5.2: pipeline pictures ------------------------------------------------
    def examples(self, figure: str = "examples", indices: Sequence[int] = (0, 1, 2)) -> Path:
        """Reference/query pairs with their dense landmarks drawn."""
        from .viz import plot_examples

        idx = [i for i in indices if i < len(self.dataset.query_paths)]
        fig = plot_examples(self.dataset, indices=idx,
                            boxes=lambda side, i, size: lm.dense_sampling(size, scales=(0.16,)),
                            title=f"{self.dataset.name}: reference (left) / query (right); dense "
                                  "landmarks of scale 0.16 drawn (Fig. 9 shows all four scales)")
        return self.save(fig, figure)

    def pipeline_figure(self, method: str, pair: int = 0, figure: str = "fig03_pipeline"):
        """One query/reference pair with the method's landmarks and its reciprocal matches."""
        return self.labelled_matches(pair=pair, method=method, figure=figure)

    def dense_scales(self, figure: str = "fig09_dense_scales", index: int = 0) -> Path:
        """The four dense sampling scales of Fig. 9 drawn on a reference image."""
        from .viz import plot_dense_scales

        fig = plot_dense_scales(self.dataset.load_image("reference", index))
        return self.save(fig, figure)

    def coverage(self, figure: str = "fig14_coverage", index: int = 0,
                 side: str = "reference") -> pd.DataFrame:
        """Landmark coverage heatmaps: top-100 Edge Boxes vs dense sampling (Fig. 14).

        Returns the share of the image covered by at least one landmark, per method, for this
        image and averaged over the dataset's images of that side.
        """
        import matplotlib.pyplot as plt

        from .viz import plot_coverage

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
                cov = lm.landmark_coverage(b, self.dataset.image_size(side, i))
                shares.append(float((cov > 0).mean()))
            rows.append({"method": method, "covered share (this image)": shares[index],
                         "covered share (mean)": float(np.mean(shares))})
        fig.tight_layout()
        self.save(fig, figure)
        return pd.DataFrame(rows).set_index("method")

    # ---- Section 5.3: cost (Table 5) --------------------------------------------------------
    def cost_table(self, n_images: int = 4, repeats: int = 1) -> pd.DataFrame:
        """Table 5 measured here: seconds per image for landmark extraction and CNN features,
        and per image pair for the remaining steps (matching + Eq. (1)), computed fresh (no
        cache) on ``n_images`` images."""
        from .matching import similarity_matrix

        make_deterministic(self.seed)
        enc = get_encoder(self.backbone, 1024, self.seed)
        n = min(n_images, len(self.dataset.query_paths))
        imgs = [self.dataset.load_image("query", i) for i in range(n)]
        rows = []
        for method in ("classical", "dense"):
            t_lm, t_ft, boxes, descs = 0.0, 0.0, [], []
            for _ in range(repeats):
                boxes, descs = [], []
                for img in imgs:
                    t0 = time.perf_counter()
                    if method == "classical":
                        b = lm.edge_boxes(img, max_boxes=100).boxes
                    else:
                        b = lm.dense_sampling(img.shape[:2])
                    t1 = time.perf_counter()
                    d = enc.encode(img, np.asarray(b))
                    t2 = time.perf_counter()
                    t_lm += t1 - t0
                    t_ft += t2 - t1
                    boxes.append(np.asarray(b))
                    descs.append(d)
            t0 = time.perf_counter()
            for _ in range(repeats):
                similarity_matrix(descs, boxes, descs, boxes)
            t_match = (time.perf_counter() - t0) / (repeats * n * n)
            rows.append({"method": method,
                         "extract landmarks (s/img)": t_lm / (repeats * n),
                         "computing CNN features (s/img)": t_ft / (repeats * n),
                         "remaining steps (s/pair)": t_match,
                         "matching two images (s)": 2 * (t_lm + t_ft) / (repeats * n) + t_match})
        frame = pd.DataFrame(rows).set_index("method")
        frame.to_csv(self.results_dir / f"{self.notebook}_table5_cost.csv", float_format="%.6f")
        return frame


def open_study(dataset: str = "synthetic", root: str | None = None,
               backbone: str = "efficientnet_lite0", quick: bool = False,
               notebook: str = "study", label: str | None = None, seed: int = 0,
               **options: Any) -> Study:
    """Open the study for a notebook.

    Args:
        dataset: dataset name (see :func:`vpr_core.datasets.load_dataset`).
        root: dataset folder for real datasets.
        backbone: landmark encoder backbone.
        quick: small run (``synthetic`` with 8 places; first 20 images of real datasets);
            outputs go to ``figures/<name>_quick`` and ``results/<name>_quick``.
        notebook: the calling notebook's stem (names the metrics CSV).
        label: output subfolder (default: dataset name, ``_quick`` appended in quick mode).
        **options: passed to the loader (e.g. ``tolerance``).
    """
    from .datasets import load_dataset

    make_deterministic(seed)
    if dataset == "synthetic" and quick:
        options.setdefault("n_places", QUICK_PLACES)
    ds = load_dataset(dataset, root=root, **options)
    if quick and dataset != "synthetic":
        ds = _subset(ds, 20)
    label = label or (ds.name if not quick else f"{ds.name}_quick")
    logger.info("study %s: %s", notebook, label)
    return Study(dataset=ds, label=label, notebook=notebook, backbone=backbone, quick=quick,
                 seed=seed)


def extra_datasets() -> dict[str, dict]:
    """Real datasets found beside the project, for the comparison notebook.

    ``../shared/data/gardens_point_mini`` (10 Gardens Point day/night pairs) when present, and
    any ``VPR_DATASETS`` entries (``name=root`` separated by ``;``).
    """
    found: dict[str, dict] = {}
    mini = REPO_DIR.parent / "shared" / "data" / "gardens_point_mini"
    if mini.is_dir():
        found["gardens_point_mini"] = {"dataset": "folder", "root": str(mini)}
    for item in filter(None, os.environ.get("VPR_DATASETS", "").split(";")):
        name, _, root = item.partition("=")
        found[name.strip()] = {"dataset": name.strip(), "root": root.strip()}
    return found
