"""Agreement of the ``geometric`` match labeller with the ``exact`` one on ``synthetic`` pairs.

On ``synthetic`` the generator's homography gives exact labels. ``geometric`` (SIFT + ratio test
+ RANSAC, :func:`vpr_core.labels.estimate_pair_geometry`) is what real datasets use; this
script measures how often it agrees with ``exact`` on the reciprocal landmark matches of the
ground-truth pairs (irrelevant pairs are all-incorrect under both and are left out).

Reported for three rules: ``auto`` (homography rule when one homography explains the pair, else
the point rule — the default), ``points`` (point rule forced, what fundamental-matrix pairs get)
and ``homography`` (homography rule forced). ``exact`` is the reference: precision / recall are
of "correct" as the positive class.

``--tune`` grid-searches the point-rule parameters (``min_points``, ``point_iou``) on a *tuning*
seed and reports them on the validation seed.

The SIFT settings and model-acceptance thresholds were chosen on seeds 1, 3, 7 (and the point
rule on seed 7); the default validation seed 11 was not used for tuning. Measured (seed 11, 20
pairs, efficientnet_lite0): dense landmarks, 728 matches (85% correct): auto 1.000 accuracy
(precision 1.000, recall 1.000), points forced 0.964 (0.982 / 0.976); edge_boxes landmarks, 169
matches (12% correct): auto 1.000, points forced 0.953 (0.842 / 0.762). Every synthetic pair is
exactly planar, so ``auto`` runs the homography rule on all of them; the point rule is what
non-planar real pairs get.

Usage::

    .venv/bin/python benchmarks/bench_labelling.py                 # 20 pairs, seed 11, dense
    .venv/bin/python benchmarks/bench_labelling.py --landmarks edge_boxes
    .venv/bin/python benchmarks/bench_labelling.py --pairs 40 --tune --tune-seed 7
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vpr_core import paper, utils
from vpr_core.datasets import load_dataset
from vpr_core.features import LandmarkEncoder
from vpr_core.labels import (
    LabelRule,
    LabelUnavailableError,
    estimate_pair_geometry,
    label_matches,
    label_matches_geometric,
)
from vpr_core.landmarks import dense_sampling, edge_boxes
from vpr_core.matching import match_landmarks


def landmark_boxes(image: np.ndarray, landmarks: str) -> np.ndarray:
    """``(K, 4)`` boxes: ``dense`` (4 scales x 25, the paper's dense set) or ``edge_boxes``
    (100 Edge Boxes, the classical method: many small landmarks)."""
    if landmarks == "dense":
        return dense_sampling(image.shape[:2])
    if landmarks == "edge_boxes":
        return np.asarray(edge_boxes(image, max_boxes=paper.N_LANDMARKS), dtype=np.float64)
    raise ValueError(f"landmarks must be 'dense' or 'edge_boxes', got {landmarks!r}")


def collect_pairs(
    n_pairs: int,
    seed: int,
    backbone: str = "efficientnet_lite0",
    n_places: int | None = None,
    landmarks: str = "dense",
) -> list[dict]:
    """Matches, exact labels and estimated geometry of the first ``n_pairs`` (i, i) pairs.

    Args:
        n_pairs: ground-truth pairs used (queries 0..n_pairs-1).
        seed: ``synthetic`` seed.
        backbone: landmark descriptor backbone.
        n_places: dataset size (default ``max(n_pairs, 2)``).
        landmarks: ``dense`` or ``edge_boxes``.

    Returns:
        one dict per pair: ``q``, ``boxes_q``, ``boxes_r``, ``matches`` ``(P, 2)``, ``exact``
        ``(P,)`` bool, ``geometry`` (``PairGeometry``).
    """
    ds = load_dataset("synthetic", n_places=n_places or max(n_pairs, 2), seed=seed)
    enc = LandmarkEncoder(backbone=backbone, dim=1024, seed=0)
    out = []
    for q in utils.progress(range(min(n_pairs, len(ds))), desc=f"pairs seed {seed}"):
        if not ds.ground_truth[q, q]:
            continue
        img_q, img_r = ds.load_image("query", q), ds.load_image("reference", q)
        bq, br = landmark_boxes(img_q, landmarks), landmark_boxes(img_r, landmarks)
        res = match_landmarks(enc.encode(img_q, bq), bq, enc.encode(img_r, br), br)
        m = np.asarray(res.matches, dtype=np.int64).reshape(-1, 2)
        exact = label_matches(ds, q, q, bq, br, m, method="exact")
        geo = estimate_pair_geometry(img_q, img_r)
        out.append(
            {"q": q, "boxes_q": bq, "boxes_r": br, "matches": m, "exact": exact, "geometry": geo}
        )
    return out


def agreement(pairs: list[dict], **rule) -> dict:
    """Confusion counts and accuracy / precision / recall of ``geometric`` vs ``exact``.

    Pairs whose geometry is unusable (``LabelUnavailableError``) are counted in
    ``unlabelled_pairs`` and left out of the scores.
    """
    tp = fp = fn = tn = 0
    unl = 0
    for p in pairs:
        try:
            g = label_matches_geometric(
                p["boxes_q"], p["boxes_r"], p["matches"], p["geometry"], LabelRule(**rule)
            )
        except LabelUnavailableError:
            unl += 1
            continue
        e = p["exact"]
        tp += int((g & e).sum())
        fp += int((g & ~e).sum())
        fn += int((~g & e).sum())
        tn += int((~g & ~e).sum())
    n = tp + fp + fn + tn
    return {
        "tp": tp,
        "fp": fp,
        "fn": fn,
        "tn": tn,
        "n": n,
        "unlabelled_pairs": unl,
        "accuracy": (tp + tn) / n if n else float("nan"),
        "precision": tp / (tp + fp) if tp + fp else float("nan"),
        "recall": tp / (tp + fn) if tp + fn else float("nan"),
    }


def _row(name: str, a: dict) -> str:
    return (
        f"{name:<34} acc {a['accuracy']:.3f}  prec {a['precision']:.3f}  "
        f"rec {a['recall']:.3f}  TP {a['tp']:4d} FP {a['fp']:4d} FN {a['fn']:4d} "
        f"TN {a['tn']:4d}  (n={a['n']}, unlabelled pairs {a['unlabelled_pairs']})"
    )


def tune_point_rule(pairs: list[dict]) -> dict:
    """Grid search of the point rule on tuning pairs (best accuracy, ties: first in grid)."""
    best = None
    for mp in (1, 2, 3, 4, 5, 6, 8):
        for piou in (0.1, 0.2, 0.25, 0.3, 0.35, 0.4, 0.5, 0.6):
            a = agreement(pairs, model="points", min_points=mp, point_iou=piou)
            if best is None or a["accuracy"] > best[0]:
                best = (a["accuracy"], {"min_points": mp, "point_iou": piou})
    return best[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=20, help="ground-truth pairs (default 20)")
    ap.add_argument(
        "--seed",
        type=int,
        default=11,
        help="validation synthetic seed (default 11; the labeller was tuned on 1, 3, 7)",
    )
    ap.add_argument("--backbone", default="efficientnet_lite0")
    ap.add_argument("--landmarks", default="dense", choices=("dense", "edge_boxes"))
    ap.add_argument("--tune", action="store_true", help="tune the point rule on --tune-seed")
    ap.add_argument("--tune-seed", type=int, default=7)
    args = ap.parse_args(argv)
    os.environ.setdefault("TQDM_DISABLE", "1")

    t0 = time.perf_counter()
    pairs = collect_pairs(args.pairs, args.seed, args.backbone, landmarks=args.landmarks)
    kinds = [p["geometry"].kind for p in pairs]
    n_all = sum(len(p["matches"]) for p in pairs)
    n_ok = int(sum(p["exact"].sum() for p in pairs))
    print(
        f"synthetic seed {args.seed}: {len(pairs)} ground-truth pairs, {args.landmarks} "
        f"landmarks, {args.backbone}; {n_all} reciprocal matches, {n_ok} correct by exact "
        f"labels (majority-class baseline accuracy {max(n_ok, n_all - n_ok) / max(n_all, 1):.3f})"
    )
    print(
        "estimated geometry per pair: "
        + ", ".join(f"{k}={kinds.count(k)}" for k in ("homography", "fundamental", "none"))
    )
    rules = {
        "geometric auto (default)": {},
        "geometric points (forced)": {"model": "points"},
        "geometric homography (forced)": {"model": "homography"},
    }
    if args.tune:
        tpairs = collect_pairs(args.pairs, args.tune_seed, args.backbone, landmarks=args.landmarks)
        best = tune_point_rule(tpairs)
        print(
            f"point rule tuned on seed {args.tune_seed}: {best} "
            f"(tuning accuracy {agreement(tpairs, model='points', **best)['accuracy']:.3f})"
        )
        rules["geometric points (tuned)"] = {"model": "points", **best}
    for name, rule in rules.items():
        print(_row(name, agreement(pairs, **rule)))
    print(f"time {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
