"""Calibrate a difficulty of the ``synthetic`` generator against the targets of issue 9 item 3.

Evaluates one difficulty on the default study's methods through the public API and says PASS or
FAIL per target:

1. saturation: no method of Fig. 5 (classical, selection_scheme1, selection_scheme2), Fig. 7
   (overlap_scheme1 at every ``paper.FIG7_NMS_THRESHOLDS``, overlap_scheme2 at every
   ``paper.FIG7_SOFT_NMS_THRESHOLDS``) or Fig. 13 (classical, dense, global when the method
   exists) exceeds AUC 0.95 (ratio protocol);
2. spread: the best and the worst of {classical, selection_scheme1, selection_scheme2, dense}
   differ by >= 0.15 AUC, and their 95% bootstrap intervals (1,000 query resamples, seed 0) do
   not overlap;
3. scale realism: the share of night-query Edge Boxes (the first 100 per image, the classical
   method) at Table-1 scale >= 4 is within 10 points of the same share on the real Gardens Point
   night frames (``gardens_point_mini/reference``: see its SOURCE.md).

Usage (use a private cache; features of one method on 60 places take a minute or two)::

    VPR_CACHE_DIR=/tmp/calib_cache TQDM_DISABLE=1 python benchmarks/calibrate_synthetic.py \\
        --difficulty default [--n-places 60] [--json out.json]

Exit status 0 when every target passes, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from vpr_core import available_methods, paper, run_method
from vpr_core.datasets import list_images, load_dataset, read_image
from vpr_core.evaluation import auc_pr, bootstrap_metrics, pr_curve
from vpr_core.landmarks import edge_boxes, scale_index

MAX_AUC = 0.95
MIN_SPREAD = 0.15
MAX_SHARE_GAP = 0.10
MIN_SCALE = 4
SPREAD_METHODS = ("classical", "selection_scheme1", "selection_scheme2", "dense")
GARDENS_POINT_NIGHT = (
    Path(__file__).resolve().parents[2] / "shared" / "data" / "gardens_point_mini" / "reference"
)


def study_runs() -> list[tuple[str, str, dict]]:
    """``(label, method, overrides)`` of every run of Fig. 5, Fig. 7 and Fig. 13."""
    runs = [
        ("classical", "classical", {}),
        ("selection_scheme1", "selection_scheme1", {}),
        ("selection_scheme2", "selection_scheme2", {}),
        ("dense", "dense", {}),
    ]
    runs += [
        (f"overlap_scheme1 t={t}", "overlap_scheme1", {"iou_threshold": t})
        for t in paper.FIG7_NMS_THRESHOLDS
    ]
    runs += [
        (f"overlap_scheme2 soft={t}", "overlap_scheme2", {"soft_nms_iou": t})
        for t in paper.FIG7_SOFT_NMS_THRESHOLDS
    ]
    if "global" in available_methods():
        runs.append(("global", "global", {}))
    return runs


def high_scale_share(images) -> float:
    """Share of the first ``paper.N_LANDMARKS`` Edge Boxes per image with Table-1 scale >= 4."""
    total = high = 0
    for img in images:
        boxes = np.asarray(edge_boxes(img, max_boxes=paper.N_LANDMARKS).boxes)
        idx = np.asarray(scale_index(boxes, img.shape[:2]))
        total += idx.size
        high += int((idx >= MIN_SCALE).sum())
    if total == 0:
        raise RuntimeError("Edge Boxes returned no box on any image: cannot measure the share")
    return high / total


def evaluate(difficulty: str, n_places: int, seed: int, only: list[str] | None = None) -> dict:
    """All numbers of the calibration for one difficulty (see the module docstring).

    ``only`` restricts the runs to these labels (a quicker, partial check while iterating).
    """
    ds = load_dataset("synthetic", n_places=n_places, seed=seed, difficulty=difficulty)
    runs = study_runs()
    if only:
        unknown = sorted(set(only) - {r[0] for r in runs})
        if unknown:
            raise SystemExit(f"unknown run label(s) {unknown}; valid: {[r[0] for r in runs]}")
        runs = [r for r in runs if r[0] in only]
    rows = []
    for label, method, overrides in runs:
        res = run_method(method, ds, **overrides)
        auc = auc_pr(pr_curve(res.similarity, res.ground_truth))
        _, low, high = bootstrap_metrics(res.similarity, res.ground_truth, n=1000, seed=0)["auc"]
        rows.append({"label": label, "method": method, "auc": auc, "low": low, "high": high})
        print(f"  {label:28s} AUC {auc:.3f} [{low:.3f}, {high:.3f}]", flush=True)
    synth_share = high_scale_share(ds.load_image("query", i) for i in range(len(ds)))
    real = sorted(list_images(GARDENS_POINT_NIGHT)) if GARDENS_POINT_NIGHT.is_dir() else []
    real_share = high_scale_share(read_image(p) for p in real) if real else None
    return {
        "difficulty": difficulty,
        "n_places": n_places,
        "seed": seed,
        "runs": rows,
        "partial": bool(only),
        "night_share_synthetic": synth_share,
        "night_share_gardens_point": real_share,
    }


def verdicts(report: dict) -> list[tuple[str, bool | None, str]]:
    """``(target, passed, detail)``; ``passed`` is None when it cannot be measured here."""
    rows = report["runs"]
    top = max(rows, key=lambda r: r["auc"])
    out = [("no AUC > 0.95", top["auc"] <= MAX_AUC, f"max {top['auc']:.3f} ({top['label']})")]
    spread = [r for r in rows if r["label"] in SPREAD_METHODS]
    if not spread:
        return out
    best, worst = max(spread, key=lambda r: r["auc"]), min(spread, key=lambda r: r["auc"])
    gap = best["auc"] - worst["auc"]
    separate = best["low"] > worst["high"]
    detail = (
        f"{best['label']} {best['auc']:.3f} [{best['low']:.3f}, {best['high']:.3f}] - "
        f"{worst['label']} {worst['auc']:.3f} [{worst['low']:.3f}, {worst['high']:.3f}] "
        f"= {gap:.3f}"
    )
    out.append(("spread >= 0.15, intervals apart", gap >= MIN_SPREAD and separate, detail))
    s, g = report["night_share_synthetic"], report["night_share_gardens_point"]
    if g is None:
        out.append(
            (
                "night scale-share within 10 points",
                None,
                f"synthetic {s:.3f}; Gardens Point mini not found at {GARDENS_POINT_NIGHT}",
            )
        )
    else:
        out.append(
            (
                "night scale-share within 10 points",
                abs(s - g) <= MAX_SHARE_GAP,
                f"synthetic {s:.3f} vs Gardens Point night {g:.3f}",
            )
        )
    return out


def main(argv: list[str] | None = None) -> int:
    """Command line entry point (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--difficulty", default="default")
    ap.add_argument("--n-places", type=int, default=60)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    ap.add_argument("--only", default="", help="comma-separated run labels (partial check)")
    args = ap.parse_args(argv)
    only = [o.strip() for o in args.only.split(",") if o.strip()]
    print(
        f"synthetic difficulty={args.difficulty} n_places={args.n_places} seed={args.seed} "
        "(AUC, ratio protocol, 95% bootstrap over queries, 1,000 resamples, seed 0)"
    )
    report = evaluate(args.difficulty, args.n_places, args.seed, only)
    if only:
        print("PARTIAL: only " + ", ".join(only) + " (the saturation target needs every run)")
    ok = True
    for target, passed, detail in verdicts(report):
        tag = "n/a " if passed is None else ("PASS" if passed else "FAIL")
        ok = ok and passed is not False
        print(f"{tag}  {target}: {detail}")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
