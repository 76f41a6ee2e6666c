"""Does a database weighting of the Eq. (1) terms help (issue 34, not in the paper)?

dense and classical x weighting {None, contrast, idf} on Gardens Point mini, Nordland every 50th
place (72, the study's set), Nordland every 5th place (716, roi, shortlist 25 as
``make study-nordland``) and the repetitive synthetic route (60 places, ``repetition=0.9``, roi):
metrics with 95% intervals, each weighting's paired difference against the same method without
it, and the matching time. Writes ``results/benchmarks/weighting.csv`` (rows of the sets run
replace their old rows). Run: ``.venv/bin/python benchmarks/bench_weighting.py [--sets ...]``.

``--statistics STEP ...`` (issue 46.1) measures instead the shortlist ``contrast`` statistics on
Nordland every STEP-th place (5: 716 places, 1: all 3,576; dense, roi, top-25): the Eq. (1)
seconds of ``similarity_pairs`` (features and pairs given; wall, and CPU seconds of this
process over every thread) without a weighting and with the statistics over samples of 8, 12
(the default, ``CONTRAST_SAMPLE``), 16, 32, 64 and 256 references (256: the references of the
statistics before issue 46), each one's ratio to the unweighted matching, its AUC and R@1 and
the paired difference against the 256-reference statistics; and, up to 1,000 places, the
precision of the default statistics against those over every reference (on 64 queries).
Runs are interleaved, ``--repeat`` rounds (medians), except the 256-reference statistics, the
comparison's reference, run in the first round only. Writes
``results/benchmarks/weighting_statistics.csv`` (rows of the sizes run replace their old rows).
Committed: ``--statistics 5 --sizes 8 12 16 24 256 --repeat 1`` (716 places, wall seconds only)
and ``--statistics 1 --sizes 16 256 --repeat 1`` (3,576 places).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from vpr_core import get_method, run_method
from vpr_core.datasets import load_dataset
from vpr_core.evaluation import compare_pairs, evaluate, paired_bootstrap
from vpr_core.features import Encoder, extract_features, get_encoder
from vpr_core.landmarks import extract_landmarks
from vpr_core.matching import (
    CONTRAST_SAMPLE,
    WEIGHTING_SAMPLE,
    Compute,
    Matching,
    Problem,
    sample_matches,
    shortlist_pairs,
    similarity_matrix,
    similarity_pairs,
    split_whole_image,
    weighting_sample,
    with_whole_image_boxes,
)
from vpr_core.matching import (
    WEIGHTINGS as WEIGHTING_TABLE,
)

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
OUT = ROOT / "results" / "benchmarks" / "weighting.csv"
METHODS = ("dense", "classical")
WEIGHTINGS = (None, *WEIGHTING_TABLE)

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


STAT_OUT = ROOT / "results" / "benchmarks" / "weighting_statistics.csv"
#: References of the shortlist contrast statistics compared (256: before issue 46).
SAMPLE_SIZES = (8, CONTRAST_SAMPLE, 16, 32, 64, WEIGHTING_SAMPLE)


def _shortlist_inputs(step: int):
    """Nordland every ``step``-th place: dense roi landmarks, descriptors, top-25 pairs, gt."""
    ds = load_dataset("nordland", DATA / "nordland_64x32", step=step, tolerance=0)
    boxes = extract_landmarks(get_method("dense").landmarks, ds)
    enc = get_encoder(Encoder(pooling="roi"))
    feats, glob = split_whole_image(extract_features(with_whole_image_boxes(boxes, ds), ds, enc))
    pairs, _ = shortlist_pairs(glob["query"], glob["reference"], 25)
    args = (feats["query"], boxes["query"], feats["reference"], boxes["reference"])
    return args, pairs, np.asarray(ds.ground_truth, dtype=bool)


def _precision(args, n_queries: int = 64) -> dict[str, float]:
    """Errors of the default (``CONTRAST_SAMPLE``) statistics against those over every reference.

    On ``n_queries`` evenly spaced queries, over their landmarks: the median and 90th percentile
    of ``|mu_s - mu_all| / sigma_all`` and of ``|sigma_s / sigma_all - 1|`` (``s``: the sample).
    """
    prob = Problem.build(*args, Matching(weighting="contrast"), Compute(show_progress=False))
    nr = prob.r.n
    qs = np.linspace(0, prob.q.n - 1, n_queries).round().astype(int)
    has = prob.r.count > 0
    err_mu, err_sd = [], []
    for qi in qs:
        sel = slice(int(qi), int(qi) + 1)
        valid = prob.q.mask[qi]
        full = sample_matches(prob, sel, torch.arange(nr), 64).best[0][has]  # (N, Kq)
        part_ids = torch.from_numpy(weighting_sample(nr, "contrast"))
        part = sample_matches(prob, sel, part_ids, 64).best[0][has[part_ids]]
        full, part = full.clamp(-1, 1)[:, valid], part.clamp(-1, 1)[:, valid]
        mu, sd = full.mean(0), full.std(0, correction=0)
        mu_s, sd_s = part.mean(0), part.std(0, correction=0)
        ok = sd > 1e-6
        err_mu.append(((mu_s - mu).abs() / sd)[ok])
        err_sd.append((sd_s / sd - 1).abs()[ok])
    em, es = torch.cat(err_mu).numpy(), torch.cat(err_sd).numpy()
    return {
        "mu err median": float(np.median(em)),
        "mu err p90": float(np.percentile(em, 90)),
        "sigma err median": float(np.median(es)),
        "sigma err p90": float(np.percentile(es, 90)),
    }


def _statistics_rows(step: int, repeat: int, sizes: tuple[int, ...]) -> list[dict]:
    """The shortlist contrast statistics' cost and metrics for each sample size (module doc)."""
    args, pairs, gt = _shortlist_inputs(step)
    nq, nr = len(args[0]), len(args[2])
    compute = Compute(show_progress=False)
    plain, contrast = Matching(), Matching(weighting="contrast")
    rng_ids = {n: weighting_sample(nr, "contrast" if n == CONTRAST_SAMPLE else None) for n in sizes}
    for n in sizes:
        if n not in (CONTRAST_SAMPLE, WEIGHTING_SAMPLE) and n < nr:
            pick = np.random.default_rng(0).choice(nr, n, replace=False)
            rng_ids[n] = np.sort(pick).astype(np.int64)
    times: dict = {None: [], **{n: [] for n in sizes}}
    cpu: dict = {key: [] for key in times}
    sims: dict = {}
    for rnd in range(repeat):  # interleaved; the 256-reference reference in the first round only
        for key in times:
            if rnd and key == WEIGHTING_SAMPLE:
                continue
            t0, c0 = time.perf_counter(), time.process_time()
            if key is None:
                v = similarity_pairs(*args, pairs, plain, compute)
            else:
                v = similarity_pairs(*args, pairs, contrast, compute, sample=rng_ids[key])
            times[key].append(time.perf_counter() - t0)
            cpu[key].append(time.process_time() - c0)
            sim = np.full((nq, nr), np.nan)
            sim[pairs[:, 0], pairs[:, 1]] = v
            sims[key] = sim
    base = statistics.median(times[None])
    cpu_base = statistics.median(cpu[None])
    ref = sims.get(WEIGHTING_SAMPLE)
    rows = []
    for key, ts in times.items():
        m = evaluate(sims[key], gt)
        row = {
            "places": nq,
            "weighting": "none" if key is None else "contrast",
            "sample": key,
            "default": key == CONTRAST_SAMPLE,
            "matching s": statistics.median(ts),
            "x none": statistics.median(ts) / base,
            "cpu s": statistics.median(cpu[key]),
            "cpu x none": statistics.median(cpu[key]) / cpu_base,
            "AUC": m["auc"],
            "R@1": m["r@1"],
        }
        if key is not None and ref is not None and key != WEIGHTING_SAMPLE:
            d = paired_bootstrap(sims[key], ref, gt)
            for k, col in (("auc", "dAUC"), ("r@1", "dR@1")):
                v, lo, hi, _ = d[k]
                verdict = "higher" if lo > 0 else "lower" if hi < 0 else "inconclusive"
                row.update({col: v, f"{col} lo": lo, f"{col} hi": hi, f"{col} verdict": verdict})
        rows.append(row)
        print(
            f"{nq} places, {row['weighting']:8s} sample {str(key):4s}: "
            f"{row['matching s']:7.2f} s = x{row['x none']:.2f} unweighted "
            f"({row['cpu s']:.2f} CPU s = x{row['cpu x none']:.2f}); "
            f"AUC {row['AUC']:.4f} R@1 {row['R@1']:.4f}"
            + (
                f"; vs 256-reference statistics dAUC {row['dAUC']:+.4f} "
                f"[{row['dAUC lo']:+.4f}, {row['dAUC hi']:+.4f}] ({row['dAUC verdict']}), "
                f"dR@1 {row['dR@1']:+.4f} [{row['dR@1 lo']:+.4f}, {row['dR@1 hi']:+.4f}] "
                f"({row['dR@1 verdict']})"
                if "dAUC" in row
                else ""
            ),
            flush=True,
        )
    if nq <= 1000:
        prec = _precision(args)
        print(
            f"{nq} places: the {CONTRAST_SAMPLE}-reference statistics against every reference's: "
            + ", ".join(f"{k} {v:.3f}" for k, v in prec.items()),
            flush=True,
        )
        for row in rows:
            if row["default"]:
                row.update(prec)
    return rows


def main() -> None:
    """Run the chosen sets and merge their rows into ``weighting.csv``."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    p.add_argument("--repeat", type=int, default=5, help="timed runs (median)")
    p.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    p.add_argument("--out", type=Path, default=OUT)
    p.add_argument(
        "--statistics",
        nargs="+",
        type=int,
        metavar="STEP",
        help="measure the shortlist contrast statistics on Nordland every STEP-th place instead",
    )
    p.add_argument(
        "--sizes", nargs="+", type=int, default=list(SAMPLE_SIZES), help="with --statistics"
    )
    args = p.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")
    if args.statistics:
        rows = [
            row
            for step in args.statistics
            for row in _statistics_rows(step, args.repeat, tuple(args.sizes))
        ]
        out = STAT_OUT if args.out == OUT else args.out
        new = pd.DataFrame(rows)
        if out.is_file():
            old = pd.read_csv(out)
            new = pd.concat([old[~old["places"].isin(new["places"])], new], ignore_index=True)
        out.parent.mkdir(parents=True, exist_ok=True)
        new["sample"] = new["sample"].astype("Int64")
        first = ["places", "weighting", "sample", "default", "matching s", "x none"]
        first += ["cpu s", "cpu x none"]
        new = new[[c for c in first if c in new] + [c for c in new if c not in first]]
        new.sort_values(["places"], kind="stable").to_csv(out, index=False, float_format="%.4f")
        print(f"wrote {out}")
        return
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
