"""Does the geometry-aware score (not in the paper, ``spatial="consistency"``) help on real data?

dense and classical on Gardens Point mini and Nordland (every 50th place, tolerance 0): AUC, R@1
and the paired difference spatial - plain. Run: ``.venv/bin/python benchmarks/bench_spatial.py``.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from vpr_core import run_method
from vpr_core.datasets import load_dataset
from vpr_core.evaluation import (
    bootstrap_metrics,
    difference_verdict,
    format_interval,
    needs_text,
    paired_bootstrap,
)
from vpr_core.matching import SPATIAL_OPTIONS, Compute, Matching, similarity_matrix

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
METRICS = (("auc", "AUC"), ("r@1", "R@1"))


def _datasets(data: Path) -> dict:
    """The two shared real datasets of the decision."""
    return {
        "gardens_point_mini": lambda: load_dataset("folder", root=data / "gardens_point_mini"),
        "nordland_step50_tol0": lambda: load_dataset(
            "nordland", root=data / "nordland_64x32", step=50, tolerance=0
        ),
    }


def _matrix(res, spatial: str | None) -> np.ndarray:
    """Eq. (1) matrix of a run's landmarks with the run's own matching settings."""
    m = res.config.matching
    d, b = res.descriptors, res.boxes
    return similarity_matrix(
        d["query"],
        b["query"],
        d["reference"],
        b["reference"],
        matching=Matching(soft_nms_iou=m.soft_nms_iou, sigma=m.sigma, spatial=spatial),
        compute=Compute(show_progress=False),
    )


def main() -> None:
    """Run both methods on both datasets and print the comparison."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=DATA, help="folder holding the shared datasets")
    p.add_argument("--spatial", default=SPATIAL_OPTIONS[0], choices=SPATIAL_OPTIONS)
    p.add_argument("--methods", nargs="+", default=["dense", "classical"])
    p.add_argument("--bootstrap", type=int, default=1000)
    args = p.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")
    for name, load in _datasets(args.data).items():
        ds = load()
        gt = ds.ground_truth
        print(f"\n== {name}: {gt.shape[0]} queries x {gt.shape[1]} references")
        for method in args.methods:
            res = run_method(method, ds, keep_descriptors=True, n_bootstrap=0)
            t0 = time.perf_counter()
            plain = _matrix(res, None)
            t1 = time.perf_counter()
            geo = _matrix(res, args.spatial)
            t2 = time.perf_counter()
            same = np.array_equal(plain, res.similarity, equal_nan=True)
            print(
                f"{method}: matching {t1 - t0:.2f} s plain, {t2 - t1:.2f} s spatial; "
                f"spatial=None equals the pipeline's matrix: {same}"
            )
            ci = {
                lab: bootstrap_metrics(s, gt, n=args.bootstrap, ks=(1,))
                for lab, s in (("plain", plain), (args.spatial, geo))
            }
            diff = paired_bootstrap(geo, plain, gt, n=args.bootstrap, ks=(1,))
            for key, label in METRICS:
                d = diff[key]
                print(
                    f"  {label:4s} plain {format_interval(*ci['plain'][key])}  "
                    f"{args.spatial} {format_interval(*ci[args.spatial][key])}  "
                    f"diff {d[0]:+.3f} [{d[1]:+.3f}, {d[2]:+.3f}] p={d[3]:.3f} "
                    f"{difference_verdict(d[1], d[2])} ({needs_text(d.queries_needed)})"
                )


if __name__ == "__main__":
    main()
