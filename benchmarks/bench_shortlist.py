"""Exhaustive vs shortlist + re-rank on a Nordland subset: R@1 / AUC with 95% intervals.

One run of :func:`vpr_core.run_method` exhaustive (every query x reference by Eq. (1))
and one per shortlist size k (a whole-image descriptor picks each query's top-k references,
Eq. (1) re-ranks them, NaN elsewhere), on the same features (cached once). Prints one table and
writes ``results/benchmarks/nordland_shortlist.csv`` (under the output root,
see :mod:`vpr_core.paths`).

Columns: ratio-protocol AUC and R@1 with 95% bootstrap intervals over queries, the paired
difference to exhaustive (interval; higher or lower only when it excludes 0), the share of queries
whose correct reference is in the shortlist, and ``run s``: wall seconds of the ``run_method``
call. Run it on an empty cache (``VPR_CACHE_DIR=/tmp/empty``): the exhaustive run then includes
computing the landmark features, the first shortlist run the whole-image descriptors, and the
others are shortlist matching alone; on a warm cache every run reads its cached result.

Usage::

    .venv/bin/python benchmarks/bench_shortlist.py                 # step 12: 298 places
    .venv/bin/python benchmarks/bench_shortlist.py --step 24 --ks 5 10 --n-boot 200
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from vpr_core import run_method
from vpr_core.datasets import load_dataset
from vpr_core.evaluation import bootstrap_metrics, paired_bootstrap
from vpr_study import outputs

DEFAULT_ROOT = Path(__file__).resolve().parents[2] / "shared" / "data" / "nordland_64x32"


def _fmt(v: tuple[float, ...]) -> str:
    return f"{v[0]:.3f} [{v[1]:.3f}, {v[2]:.3f}]"


def _row(
    label: str,
    k: int | None,
    sim: np.ndarray,
    gt: np.ndarray,
    base: np.ndarray | None,
    seconds: float,
    n_boot: int,
) -> dict:
    """One table row: metrics with intervals, paired deltas to ``base``, shortlist recall."""
    m = bootstrap_metrics(sim, gt, n=n_boot, seed=0, ks=(1,))
    row = {
        "setting": label,
        "k": k if k is not None else "",
        "AUC": m["auc"][0],
        "AUC low": m["auc"][1],
        "AUC high": m["auc"][2],
        "R@1": m["r@1"][0],
        "R@1 low": m["r@1"][1],
        "R@1 high": m["r@1"][2],
    }
    has_gt = gt.any(1)
    listed = ~np.isnan(sim)
    row["gt in shortlist"] = float((listed & gt)[has_gt].any(1).mean())
    if base is not None:
        d = paired_bootstrap(sim, base, gt, n=n_boot, seed=0, ks=(1,))
        for key, name in (("auc", "dAUC"), ("r@1", "dR@1")):
            row[name] = d[key][0]
            row[f"{name} low"], row[f"{name} high"], row[f"{name} p"] = d[key][1:4]
    row["run s"] = seconds
    return row


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--root", default=str(DEFAULT_ROOT), help="nordland_64x32 folder")
    p.add_argument("--step", type=int, default=12, help="keep every step-th place")
    p.add_argument("--ks", type=int, nargs="+", default=[5, 10, 25, 50])
    p.add_argument("--method", default="dense")
    p.add_argument("--pooling", default="roi", choices=["roi", "crop"])
    p.add_argument("--n-boot", type=int, default=1000)
    args = p.parse_args(argv)

    ds = load_dataset("nordland", args.root, step=args.step)
    gt = np.asarray(ds.ground_truth, dtype=bool)
    print(
        f"nordland step={args.step}: {len(ds.query_paths)} queries x "
        f"{len(ds.reference_paths)} references, tolerance={ds.tolerance} "
        f"({ds.meta.get('query_traverse')} vs {ds.meta.get('reference_traverse')}), "
        f"method={args.method}, pooling={args.pooling}"
    )
    t0 = time.perf_counter()
    exh = run_method(args.method, ds, pooling=args.pooling)
    rows = [
        _row("exhaustive", None, exh.similarity, gt, None, time.perf_counter() - t0, args.n_boot)
    ]
    for k in args.ks:
        t0 = time.perf_counter()
        res = run_method(args.method, ds, pooling=args.pooling, shortlist=k)
        rows.append(
            _row(
                f"shortlist k={k}",
                k,
                res.similarity,
                gt,
                exh.similarity,
                time.perf_counter() - t0,
                args.n_boot,
            )
        )
    print(
        f"{'setting':<16} {'AUC [95%]':<24} {'R@1 [95%]':<24} {'dR@1 vs exh. [95%]':<26} "
        f"{'gt in list':>10} {'s':>7}"
    )
    for r in rows:
        d = f"{r['dR@1']:+.3f} [{r['dR@1 low']:+.3f}, {r['dR@1 high']:+.3f}]" if "dR@1" in r else ""
        print(
            f"{r['setting']:<16} {_fmt((r['AUC'], r['AUC low'], r['AUC high'])):<24} "
            f"{_fmt((r['R@1'], r['R@1 low'], r['R@1 high'])):<24} {d:<26} "
            f"{r['gt in shortlist']:>10.3f} {r['run s']:>7.1f}"
        )
    import pandas as pd

    with outputs.study_outputs():  # the committed results/benchmarks/, not the user area
        out = outputs.results_dir("benchmarks") / "nordland_shortlist.csv"
    pd.DataFrame(rows).to_csv(out, index=False, float_format="%.6f")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
