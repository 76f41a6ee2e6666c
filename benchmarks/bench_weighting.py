"""Does a database weighting of the Eq. (1) terms help (issue 34, not in the paper)?

dense and classical x weighting {None, contrast, idf} on Gardens Point mini, Nordland every 50th
place (72, the study's set), Nordland every 5th place (716, roi, shortlist 25 as
``make study-nordland``) and the repetitive synthetic route (60 places, ``repetition=0.9``, roi):
metrics with 95% intervals, each weighting's paired difference against the same method without
it, and the matching time. Writes ``results/benchmarks/weighting.csv`` (rows of the sets run
replace their old rows). Run: ``.venv/bin/python benchmarks/bench_weighting.py [--sets ...]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import pandas as pd

from vpr_core.datasets import load_dataset
from vpr_core.evaluation import compare_pairs
from vpr_core.matching import WEIGHTING_OPTIONS, Compute, Matching, similarity_matrix
from vpr_core.pipeline import run_method

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
OUT = ROOT / "results" / "benchmarks" / "weighting.csv"
METHODS = ("dense", "classical")
WEIGHTINGS = (None, *WEIGHTING_OPTIONS)

#: name -> (loader, loader options, run options)
SETS: dict[str, tuple[str, dict, dict]] = {
    "gardens_point_mini": ("folder", {"root": DATA / "gardens_point_mini"}, {"pooling": "crop"}),
    "nordland_step50": (
        "nordland",
        {"root": DATA / "nordland_64x32", "step": 50, "tolerance": 0},
        {"pooling": "roi"},
    ),
    "synthetic_repetitive": (
        "synthetic",
        {"n_places": 60, "repetition": 0.9},
        {"pooling": "roi"},
    ),
    "nordland_step5": (
        "nordland",
        {"root": DATA / "nordland_64x32", "step": 5, "tolerance": 0},
        {"pooling": "roi", "shortlist": 25},
    ),
}


def _study_cost(runs: dict, repeat: int) -> dict:
    """Median matching seconds of each weighting relative to None, interleaved (one process)."""
    times: dict = {w: [] for w in WEIGHTINGS}
    for _ in range(repeat):
        for w in WEIGHTINGS:
            d, b = runs[w].descriptors, runs[w].boxes
            t0 = time.perf_counter()
            similarity_matrix(
                d["query"],
                b["query"],
                d["reference"],
                b["reference"],
                matching=Matching(weighting=w),
                compute=Compute(show_progress=False),
            )
            times[w].append(time.perf_counter() - t0)
    base = statistics.median(times[None])
    return {w: statistics.median(t) / base for w, t in times.items()}


def _rows(name: str, repeat: int, methods: tuple[str, ...] = METHODS) -> list[dict]:
    loader, options, run_options = SETS[name]
    ds = load_dataset(loader, **options)
    rows = []
    for method in methods:
        runs = {
            w: run_method(method, ds, weighting=w, keep_descriptors=True, **run_options)
            for w in WEIGHTINGS
        }
        table = compare_pairs([(runs[None], runs[w]) for w in WEIGHTINGS[1:]])
        cost = _study_cost(runs, repeat) if "shortlist" not in run_options else {}
        plain_s = runs[None].timings["matching_s_per_pair"]
        for w, r in runs.items():
            row = {
                "set": name,
                "method": method,
                "weighting": w or "none",
                "run": r.run,
                "queries": r.queries_with_gt[0],
                "tolerance": r.tolerance,
                "pooling": run_options["pooling"],
                "shortlist": run_options.get("shortlist"),
            }
            for key, col in (("auc", "AUC"), ("r@1", "R@1")):
                v, lo, hi = r.intervals[key]
                row.update({col: v, f"{col} lo": lo, f"{col} hi": hi})
            if w is not None:
                t = table.loc[r.label]
                for col in ("dAUC", "dR@1"):
                    row.update({c: t[c] for c in (col, f"{col} lo", f"{col} hi", f"{col} verdict")})
            s = r.timings["matching_s_per_pair"]
            row["matching s/pair"] = s
            row["matching x none"] = cost.get(w, s / plain_s)
            rows.append(row)
            print(
                f"{name} {method:9s} {row['weighting']:8s} AUC {row['AUC']:.3f} "
                f"[{row['AUC lo']:.3f}, {row['AUC hi']:.3f}] R@1 {row['R@1']:.3f} "
                + (
                    f"dAUC {row['dAUC']:+.3f} [{row['dAUC lo']:+.3f}, {row['dAUC hi']:+.3f}] "
                    f"({row['dAUC verdict']}) dR@1 {row['dR@1']:+.3f} "
                    f"[{row['dR@1 lo']:+.3f}, {row['dR@1 hi']:+.3f}] "
                    if w is not None
                    else ""
                )
                + f"matching x{row['matching x none']:.2f}",
                flush=True,
            )
    return rows


def main() -> None:
    """Run the chosen sets and merge their rows into ``weighting.csv``."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    p.add_argument("--repeat", type=int, default=5, help="timed runs of the exhaustive matching")
    p.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    p.add_argument("--out", type=Path, default=OUT)
    args = p.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")
    methods = tuple(args.methods)
    new = pd.DataFrame([row for name in args.sets for row in _rows(name, args.repeat, methods)])
    if args.out.is_file():
        old = pd.read_csv(args.out)
        mine = old["set"].isin(args.sets) & old["method"].isin(methods)
        new = pd.concat([old[~mine], new], ignore_index=True)
    order = {name: i for i, name in enumerate(SETS)}
    new = new.sort_values("set", key=lambda s: s.map(order), kind="stable")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    new.to_csv(args.out, index=False, float_format="%.4f")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
