"""How the matching cost grows with the number of places (issue 46.3).

Nordland (``nordland_64x32``, winter vs summer, every ``step``-th place; the default steps 50,
35, 25, 10, 5, 1 give 72, 103, 144, 358, 716 and all 3,576 places), dense landmarks with ``roi``
pooling, features cached (computed first if not): the CPU seconds (this process, every thread;
wall seconds beside them) of the Eq. (1) stage alone (``similarity_matrix`` exhaustive,
``similarity_pairs`` on each query's top-25 shortlist; the global ranking excluded), without and
with ``weighting="contrast"``, the median of ``--repeat`` runs in one process. Each line's
exponent is the slope of a least-squares fit of log(CPU seconds) on log(places). Exhaustive
matching above ``--max-exhaustive`` places is not run, and every line not measured at 3,576
places is extrapolated there from its fit (``measured = False``, dashed in the figure). The
committed table: ``--steps 50 35 25 10 5 --max-exhaustive 400`` (the features of those steps are
the study's); ``--replot`` refits and redraws from the table. Writes
``results/benchmarks/weighting_scaling.csv`` and ``figures/benchmarks/weighting_scaling.png``.
Run: ``.venv/bin/python benchmarks/bench_scaling.py [--steps ...]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np
import pandas as pd

from vpr_core.datasets import load_dataset
from vpr_core.engine.shortlist import shortlist_pairs, split_whole_image, with_whole_image_boxes
from vpr_core.features import Encoder
from vpr_core.matching import Compute, Matching, similarity_matrix, similarity_pairs
from vpr_core.methods import get_method
from vpr_core.pipeline.feature_stage import extract_features, get_encoder
from vpr_core.pipeline.landmark_stage import extract_landmarks

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "nordland_64x32"
OUT = ROOT / "results" / "benchmarks" / "weighting_scaling.csv"
FIG = ROOT / "figures" / "benchmarks" / "weighting_scaling.png"
K = 25
#: Every place of nordland_64x32: each line not measured there is extrapolated to it.
ALL_PLACES = 3576
LINES = (
    ("exhaustive", None),
    ("exhaustive", "contrast"),
    ("shortlist 25", None),
    ("shortlist 25", "contrast"),
)


def _inputs(step: int):
    """Landmarks, descriptors and the top-25 pairs of Nordland every ``step``-th place."""
    ds = load_dataset("nordland", DATA, step=step, tolerance=0)
    boxes = extract_landmarks(get_method("dense").landmarks, ds)
    enc = get_encoder(Encoder(pooling="roi"))
    feats, glob = split_whole_image(extract_features(with_whole_image_boxes(boxes, ds), ds, enc))
    pairs, _ = shortlist_pairs(glob["query"], glob["reference"], K)
    args = (feats["query"], boxes["query"], feats["reference"], boxes["reference"])
    return len(feats["query"]), args, pairs


def _seconds(mode: str, weighting: str | None, args, pairs) -> tuple[float, float]:
    """``(wall, CPU)`` seconds of one matching (CPU: this process, every thread)."""
    compute = Compute(show_progress=False)
    matching = Matching(weighting=weighting)
    t0, c0 = time.perf_counter(), time.process_time()
    if mode == "exhaustive":
        similarity_matrix(*args, matching=matching, compute=compute)
    else:
        similarity_pairs(*args, pairs, matching, compute)
    return time.perf_counter() - t0, time.process_time() - c0


def _fit(n: np.ndarray, s: np.ndarray) -> tuple[float, float]:
    """``(exponent, log intercept)`` of the least-squares line of log s on log n."""
    slope, icpt = np.polyfit(np.log(n), np.log(s), 1)
    return float(slope), float(icpt)


def measure(steps: list[int], repeat: int, max_exhaustive: int) -> pd.DataFrame:
    """One row per measured (places, line): the median seconds of ``repeat`` runs."""
    rows = []
    for step in steps:
        n, args, pairs = _inputs(step)
        for mode, w in LINES:
            if mode == "exhaustive" and n > max_exhaustive:
                continue
            times = [_seconds(mode, w, args, pairs) for _ in range(repeat)]
            rows.append(
                {
                    "places": n,
                    "step": step,
                    "matching": mode,
                    "weighting": w or "none",
                    "cpu seconds": statistics.median(t[1] for t in times),
                    "wall seconds": statistics.median(t[0] for t in times),
                    "measured": True,
                }
            )
            print(
                f"{n:5d} places {mode:12s} {w or 'none':8s} "
                f"{rows[-1]['cpu seconds']:8.2f} CPU s, {rows[-1]['wall seconds']:8.2f} s wall",
                flush=True,
            )
    return pd.DataFrame(rows)


def fit(df: pd.DataFrame, extrapolate: dict[int, int]) -> pd.DataFrame:
    """Each line's exponent, and its fitted seconds at the ``{places: step}`` it did not measure
    (``measured = False``)."""
    df = df[df["measured"].astype(bool)]
    out = []
    for (mode, w), g in df.groupby(["matching", "weighting"], sort=False):
        slope, icpt = _fit(g["places"].to_numpy(float), g["cpu seconds"].to_numpy(float))
        g = g.assign(measured=True, exponent=slope)
        extra = [
            {
                "places": p,
                "step": step,
                "matching": mode,
                "weighting": w,
                "cpu seconds": float(np.exp(icpt) * p**slope),
                "wall seconds": np.nan,
                "measured": False,
                "exponent": slope,
            }
            for p, step in extrapolate.items()
            if p not in set(g["places"])
        ]
        out.append(pd.concat([g, pd.DataFrame(extra)], ignore_index=True) if extra else g)
    res = pd.concat(out, ignore_index=True).sort_values(["matching", "weighting", "places"])
    cols = ["matching", "weighting", "places", "step", "cpu seconds", "wall seconds"]
    return res[[*cols, "measured", "exponent"]]


def plot(df: pd.DataFrame, path: Path) -> None:
    """Log-log lines of seconds against places; the fitted exponent in the legend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    style = {
        ("exhaustive", "none"): ("tab:blue", "o"),
        ("exhaustive", "contrast"): ("tab:orange", "s"),
        ("shortlist 25", "none"): ("tab:green", "^"),
        ("shortlist 25", "contrast"): ("tab:red", "D"),
    }
    fig, ax = plt.subplots(figsize=(7.5, 4.6), dpi=150)
    for (mode, w), g in df.groupby(["matching", "weighting"], sort=False):
        color, marker = style[(mode, w)]
        g = g.sort_values("places")
        meas = g[g["measured"]]
        name = "contrast" if w == "contrast" else "unweighted"
        label = f"{mode}\n{name}, n^{g['exponent'].iloc[0]:.2f}"
        ax.plot(meas["places"], meas["cpu seconds"], color=color, marker=marker, label=label)
        if not g["measured"].all():
            last = meas.iloc[-1:]
            ext = pd.concat([last, g[~g["measured"]]])
            ax.plot(
                ext["places"], ext["cpu seconds"], color=color, ls="--", marker=marker, mfc="none"
            )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("places (queries = references), Nordland winter vs summer", fontsize=10)
    ax.set_ylabel("Eq. (1) matching, CPU seconds (features cached)", fontsize=10)
    ax.set_title(
        "Eq. (1) matching cost against the number of places (dense, roi)\n"
        "legend: each line's fitted exponent; dashed, hollow: extrapolated from the fit",
        fontsize=10,
    )
    ax.tick_params(labelsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", frameon=True, handlelength=1.6, labelspacing=0.6)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, metadata={"Software": None})
    plt.close(fig)


def main() -> None:
    """Measure, write the table and the figure."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", nargs="+", type=int, default=[50, 35, 25, 10, 5, 1])
    p.add_argument("--repeat", type=int, default=1, help="timed runs of each line (median)")
    p.add_argument("--max-exhaustive", type=int, default=1000, help="largest exhaustive run")
    p.add_argument("--out", type=Path, default=OUT)
    p.add_argument("--figure", type=Path, default=FIG)
    p.add_argument(
        "--replot", action="store_true", help="refit and redraw from the measured rows of --out"
    )
    args = p.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")
    if args.replot:
        measured = pd.read_csv(args.out)
    else:
        measured = measure(sorted(args.steps, reverse=True), args.repeat, args.max_exhaustive)
    df = fit(measured, {ALL_PLACES: 1})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(args.out, index=False, float_format="%.4f")
    print(df.to_string(index=False))
    plot(df, args.figure)
    print(f"wrote {args.out} and {args.figure}")


if __name__ == "__main__":
    main()
