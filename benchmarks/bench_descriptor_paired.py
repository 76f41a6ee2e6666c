"""Is one descriptor better than another? Paired bootstrap on a larger Nordland subset.

``bench_descriptors.py`` compares every option on 10 and 72 queries, where no two are
distinguishable. This benchmark takes two backbone specs and asks the question with more
queries and a paired test: both run on the same Nordland places (winter vs summer), and the
difference ``a - b`` of ratio-protocol AUC, R@1 and R@5 gets a 95% interval and a p-value from
the same 1,000 query resamples (:func:`vpr_core.evaluation.paired_bootstrap`, seed 0). A
difference is higher or lower only when its interval excludes 0, else inconclusive.

Run (each row appends to / replaces its row in ``results/benchmarks/descriptor_paired.csv``)::

    # crop, every 12th place (298), tolerance 1, dense and classical
    .venv/bin/python benchmarks/bench_descriptor_paired.py \\
        efficientnet_lite0:input_size=96 efficientnet_lite0 --step 12
    # roi + shortlist 25 on all 3,576 places (the at-scale path)
    .venv/bin/python benchmarks/bench_descriptor_paired.py \\
        efficientnet_lite0:input_size=96 efficientnet_lite0 --step 1 --pooling roi \\
        --shortlist 25 --methods dense
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "nordland_64x32"
METRICS = (("auc", "AUC"), ("r@1", "R@1"), ("r@5", "R@5"))
KEY = ("a", "b", "method", "dataset", "pooling", "shortlist")


def _fmt(v) -> str:
    return f"{v[0]:+.3f} [{v[1]:+.3f}, {v[2]:+.3f}]"


def _merge(path: Path, row: dict) -> None:
    """Write ``row`` into the table, replacing an earlier row of the same comparison."""
    from vpr_core import utils

    same = tuple(str(row[k]) for k in KEY)
    utils.write_rows(
        path, [r for r in utils.read_rows(path) if tuple(r[k] for k in KEY) != same] + [row]
    )


def main() -> None:
    """Run both descriptors, print and store the paired differences."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("a", help="backbone spec a (the difference is a - b)")
    p.add_argument("b", help="backbone spec b")
    p.add_argument("--root", type=Path, default=SHARED, help="Nordland root (season folders)")
    p.add_argument("--step", type=int, default=12, help="keep every step-th place")
    p.add_argument("--tolerance", type=int, default=1, help="in kept places")
    p.add_argument("--pooling", default="crop", choices=("crop", "roi"))
    p.add_argument("--shortlist", type=int, default=None)
    p.add_argument("--methods", nargs="+", default=["dense", "classical"])
    p.add_argument("--bootstrap", type=int, default=1000)
    args = p.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")

    from vpr_core import run_method
    from vpr_core.datasets import load_dataset
    from vpr_core.evaluation import difference_verdict, paired_bootstrap
    from vpr_study import outputs

    if not args.root.is_dir():
        raise SystemExit(
            f"no Nordland data at {args.root}: pass --root <folder with summer/ and winter/>"
        )
    ds = load_dataset("nordland", args.root, step=args.step, tolerance=args.tolerance)
    name = f"nordland_step{args.step}_tol{args.tolerance}"
    with outputs.study_outputs():  # the committed results/benchmarks/, not the user area
        out = outputs.results_dir("benchmarks") / "descriptor_paired.csv"
    print(
        f"{name}: {len(ds.query_paths)} queries x {len(ds.reference_paths)} references, "
        f"pooling {args.pooling}, shortlist {args.shortlist}"
    )
    for method in args.methods:
        res = {
            spec: run_method(
                method,
                ds,
                backbone=spec,
                pooling=args.pooling,
                shortlist=args.shortlist,
                n_bootstrap=args.bootstrap,
            )
            for spec in (args.a, args.b)
        }
        d = paired_bootstrap(
            res[args.a].similarity,
            res[args.b].similarity,
            ds.ground_truth,
            n=args.bootstrap,
            seed=0,
        )
        row = {
            "a": args.a,
            "b": args.b,
            "method": method,
            "dataset": name,
            "pooling": args.pooling,
            "shortlist": args.shortlist or "",
            "queries": res[args.a].queries_with_gt[0],
        }
        for key, label in METRICS:
            for spec, tag in ((args.a, "a"), (args.b, "b")):
                v = res[spec].intervals[key]
                row[f"{label} {tag}"] = f"{v[0]:.3f} [{v[1]:.3f}, {v[2]:.3f}]"
            delta, lo, hi, pval = d[key]
            row[f"d{label}"] = round(delta, 4)
            row[f"d{label} 95%"] = f"[{lo:+.3f}, {hi:+.3f}]"
            row[f"d{label} p"] = round(pval, 4)
            row[f"d{label} verdict"] = difference_verdict(lo, hi)
        _merge(out, row)
        print(
            f"  {method:<10} "
            + "  ".join(
                f"d{label} {_fmt(d[key])} {difference_verdict(d[key][1], d[key][2])}"
                for key, label in METRICS
            ),
            flush=True,
        )
    print(f"written {out}")


if __name__ == "__main__":
    main()
