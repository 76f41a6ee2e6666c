"""How the matching cost grows with the number of places (issue 46.3).

Nordland (``nordland_64x32``, winter vs summer, 3,576 places), ``--places N ...``: ``N`` evenly
spaced places, the file indices ``round(linspace(0, 3575, N))``, so each size has exactly ``N``
places (100: about every 36th, 300: every 12th, 1,000: every 3.6th; 3,576: every place).
Dense landmarks with ``roi`` pooling, features cached (computed first if not; content-keyed per
image, so every size reuses those of all 3,576 places): the CPU seconds (this process, every
thread; wall seconds beside them) of the Eq. (1) stage alone (``similarity_matrix`` exhaustive,
``similarity_pairs`` on each query's top-25 shortlist among the ``N`` references; the global
ranking excluded), without and with ``weighting="contrast"``, the median of ``--repeat`` runs in
one process. Sizes run in the order given; the table and figure are rewritten after each (a
stopped run keeps what it measured). Each line's exponent is the slope of a least-squares fit
of log(CPU seconds) on log(places) over its measured sizes. Exhaustive matching above
``--max-exhaustive`` places is not run, and every line not measured at 3,576 places is
extrapolated there from its fit (``measured = False`` in the table; dashed, hollow markers in
the figure). The committed table: ``--places 3576 100 300 1000 --max-exhaustive 1000``
(exhaustive at 3,576 extrapolated, docs/MEASUREMENTS.md); ``--replot`` refits and redraws from
the table. Writes ``results/benchmarks/weighting_scaling.csv`` and
``figures/benchmarks/weighting_scaling.png``.
Run: ``.venv/bin/python benchmarks/bench_scaling.py [--places ...]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np
import pandas as pd

from vpr_core import get_method
from vpr_core.datasets import PlaceDataset, load_dataset
from vpr_core.features import Encoder, extract_features, get_encoder
from vpr_core.landmarks import extract_landmarks
from vpr_core.matching import (
    Compute,
    Matching,
    shortlist_pairs,
    similarity_matrix,
    similarity_pairs,
    split_whole_image,
    with_whole_image_boxes,
)

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


def _places(n: int) -> np.ndarray:
    """The file indices of ``n`` evenly spaced Nordland places (``round(linspace(0, 3575, n))``)."""
    if not 2 <= n <= ALL_PLACES:
        raise ValueError(f"--places {n}: give sizes from 2 to {ALL_PLACES} (every place).")
    return np.linspace(0, ALL_PLACES - 1, n).round().astype(int)


def _dataset(n: int) -> PlaceDataset:
    """Nordland at ``n`` evenly spaced places (:func:`_places`), tolerance 0."""
    full = load_dataset("nordland", DATA, tolerance=0)
    if full.n_query != ALL_PLACES:
        raise ValueError(f"{DATA} holds {full.n_query} places, expected {ALL_PLACES}.")
    if n == ALL_PLACES:
        return full
    idx = _places(n)
    return PlaceDataset(
        name=full.name,
        query_paths=[full.query_paths[i] for i in idx],
        reference_paths=[full.reference_paths[i] for i in idx],
        ground_truth=np.eye(n, dtype=bool),
        tolerance=0,
        root=full.root,
        meta={**full.meta, "places": n},
    )


def _inputs(n: int):
    """Landmarks, descriptors and the top-25 pairs of ``n`` evenly spaced Nordland places."""
    ds = _dataset(n)
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


def measure(sizes: list[int], repeat: int, max_exhaustive: int, save=None) -> pd.DataFrame:
    """One row per measured (places, line): the median seconds of ``repeat`` runs; the sizes in
    the order given, ``save(rows so far)`` after each."""
    rows: list[dict] = []
    for size in sizes:
        n, args, pairs = _inputs(size)
        for mode, w in LINES:
            if mode == "exhaustive" and n > max_exhaustive:
                continue
            times = [_seconds(mode, w, args, pairs) for _ in range(repeat)]
            rows.append(
                {
                    "places": n,
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
        del args, pairs  # before the next size's inputs are read
        if save is not None:
            save(pd.DataFrame(rows))
    return pd.DataFrame(rows)


def fit(df: pd.DataFrame, extrapolate: tuple[int, ...]) -> pd.DataFrame:
    """Each line's exponent, and its fitted seconds at the ``extrapolate`` sizes it did not
    measure (``measured = False``); a line measured at one size only has no exponent (NaN)."""
    df = df[df["measured"].astype(bool)]
    out = []
    for (mode, w), g in df.groupby(["matching", "weighting"], sort=False):
        if g["places"].nunique() < 2:
            out.append(g.assign(measured=True, exponent=np.nan))
            continue
        slope, icpt = _fit(g["places"].to_numpy(float), g["cpu seconds"].to_numpy(float))
        g = g.assign(measured=True, exponent=slope)
        extra = [
            {
                "places": p,
                "matching": mode,
                "weighting": w,
                "cpu seconds": float(np.exp(icpt) * p**slope),
                "wall seconds": np.nan,
                "measured": False,
                "exponent": slope,
            }
            for p in extrapolate
            if p not in set(g["places"])
        ]
        out.append(pd.concat([g, pd.DataFrame(extra)], ignore_index=True) if extra else g)
    res = pd.concat(out, ignore_index=True).sort_values(["matching", "weighting", "places"])
    cols = ["matching", "weighting", "places", "cpu seconds", "wall seconds"]
    return res[[*cols, "measured", "exponent"]]


def plot(df: pd.DataFrame, path: Path) -> None:
    """Log-log lines of CPU seconds against places, each labelled with its fitted exponent; the
    extrapolated points dotted and hollow, with their value written beside them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, NullFormatter

    from vpr_study.viz import METHOD_COLORS
    from vpr_study.viz.styles import WEIGHTING_STYLES

    # every line is dense's (its colour in every figure), the weighting its line style as in
    # every figure, and a marker of its own (the two exhaustive lines nearly coincide)
    color = METHOD_COLORS["dense"]
    marker_of = {
        ("exhaustive", "none"): "o",
        ("exhaustive", "contrast"): "D",
        ("shortlist 25", "none"): "s",
        ("shortlist 25", "contrast"): "^",
    }
    fig, ax = plt.subplots(figsize=(7.5, 4.8), dpi=150)
    for mode, w in marker_of:
        g = df[(df["matching"] == mode) & (df["weighting"] == w)].sort_values("places")
        if g.empty:
            continue
        marker, ls = marker_of[mode, w], WEIGHTING_STYLES["" if w == "none" else w]
        meas = g[g["measured"]]
        name = "contrast" if w == "contrast" else "unweighted"
        e = g["exponent"].iloc[0]
        label = f"{mode}, {name}: " + ("one size" if np.isnan(e) else f"$n^{{{e:.2f}}}$")
        small = 5 if w == "contrast" else 7  # the contrast marker inside the plain one
        ax.plot(
            meas["places"],
            meas["cpu seconds"],
            color=color,
            marker=marker,
            ms=small,
            ls=ls,
            label=label,
        )
        if not g["measured"].all():
            extra = g[~g["measured"]]
            ext = pd.concat([meas.iloc[-1:], extra])
            ax.plot(ext["places"], ext["cpu seconds"], color=color, ls=":", lw=1.0)
            ax.plot(
                extra["places"],
                extra["cpu seconds"],
                ls="",
                color=color,
                marker=marker,
                ms=small,
                mfc="w",
            )
            for _, row in extra.iterrows():
                up = w == "contrast"
                ax.annotate(
                    f"{row['cpu seconds']:,.0f} s, extrapolated",
                    (row["places"], row["cpu seconds"]),
                    xytext=(-8, 6 if up else -12),
                    textcoords="offset points",
                    ha="right",
                    fontsize=7.5,
                    color=color,
                )
    sizes = sorted(set(df["places"]))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xticks(sizes)
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:,.0f}"))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:,.4g}"))
    ax.set_xlim(min(sizes) / 1.25, max(sizes) * 1.25)
    ax.set_xlabel("places (queries = references), Nordland winter vs summer", fontsize=10)
    ax.set_ylabel("Eq. (1) matching, CPU seconds (features cached)", fontsize=10)
    ax.set_title(
        "Eq. (1) matching cost against the number of places (dense, roi)\n"
        "legend: each line's fitted exponent; dotted, hollow: extrapolated from the fit",
        fontsize=10,
    )
    ax.tick_params(labelsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8.5, loc="upper left", frameon=True, handlelength=2.2)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, metadata={"Software": None})
    plt.close(fig)


def main() -> None:
    """Measure, write the table and the figure."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--places",
        nargs="+",
        type=int,
        default=[100, 300, 1000, ALL_PLACES],
        help="sizes: that many evenly spaced Nordland places each",
    )
    p.add_argument("--repeat", type=int, default=1, help="timed runs of each line (median)")
    p.add_argument("--max-exhaustive", type=int, default=1000, help="largest exhaustive run")
    p.add_argument("--out", type=Path, default=OUT)
    p.add_argument("--figure", type=Path, default=FIG)
    p.add_argument(
        "--replot", action="store_true", help="refit and redraw from the measured rows of --out"
    )
    args = p.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")

    def save(measured: pd.DataFrame) -> None:
        df = fit(measured, (ALL_PLACES,))
        args.out.parent.mkdir(parents=True, exist_ok=True)
        df.to_csv(args.out, index=False, float_format="%.4f")
        plot(df, args.figure)
        print(df.to_string(index=False))
        print(f"wrote {args.out} and {args.figure}", flush=True)

    if args.replot:
        save(pd.read_csv(args.out))
        return
    for n in args.places:
        _places(n)  # refuse a bad size before any measuring
    measure(list(dict.fromkeys(args.places)), args.repeat, args.max_exhaustive, save)


if __name__ == "__main__":
    main()
