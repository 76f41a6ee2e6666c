"""What does whitening the landmark descriptors on the reference database cost (issue 62, not in
the paper)?

On Nordland every STEP-th place (dense, roi; features from the cache), in one process: the fit
(once per database, its cache emptied first: the content key, the mean, covariance and
eigendecomposition; then the fit kept for the database: key and lookup), the whitening of both
sides with the fit kept (``whiten_landmarks``: key, lookup, transform), and the shortlist
top-``--k`` Eq. (1) matching (``similarity_pairs``) on the whitened ``--whiten``-d descriptors
beside the same matching on the 1,024-d descriptors (interleaved, the least of ``--repeat``
calls each); every time as a ratio to the 1,024-d matching of the same run, and the peak memory
the fit and the whitening of both sides allocate (``tracemalloc``, numpy's arrays included; the
descriptors themselves are not counted). Writes ``--out`` (default
``results/benchmarks/whiten_cost_<places>.csv``: ``whiten_cost_716.csv`` and
``whiten_cost_3576.csv``). Run: ``.venv/bin/python benchmarks/bench_whiten.py --step 5`` (716
places; ``--step 1``: all 3,576, 357,600 reference landmarks).
"""

from __future__ import annotations

import argparse
import time
import tracemalloc
from pathlib import Path

import pandas as pd

from vpr_core import get_method
from vpr_core.datasets import load_dataset
from vpr_core.features import Encoder, extract_features, get_encoder
from vpr_core.landmarks import extract_landmarks
from vpr_core.matching import (
    Compute,
    clear_whitening_cache,
    fit_whitening,
    shortlist_pairs,
    similarity_pairs,
    split_whole_image,
    whiten_landmarks,
    with_whole_image_boxes,
)

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
QUIET = Compute(show_progress=False)


def _features(step: int):
    ds = load_dataset("nordland", root=DATA / "nordland_64x32", step=step, tolerance=0)
    boxes = extract_landmarks(get_method("dense").landmarks, ds)
    enc = get_encoder(Encoder(pooling="roi"))
    feats, glob = split_whole_image(extract_features(with_whole_image_boxes(boxes, ds), ds, enc))
    return boxes, feats, glob


def _timed(fn, setup=None, repeat: int = 1):
    """``(fn()'s output, the least seconds of ``repeat`` calls)``; ``setup()`` untimed before
    each."""
    best, out = float("inf"), None
    for _ in range(repeat):
        if setup is not None:
            setup()
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def _peak_mb(fn) -> float:
    """The most memory ``fn()`` allocated at once above what was allocated before (MB)."""
    tracemalloc.start()
    tracemalloc.reset_peak()
    before = tracemalloc.get_traced_memory()[0]
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return (peak - before) / 1e6


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--step", type=int, default=5, help="every STEP-th Nordland place (5: 716)")
    p.add_argument("--k", type=int, default=25, help="shortlist size")
    p.add_argument("--whiten", type=int, default=256, help="components kept")
    p.add_argument("--out", type=Path, help="default results/benchmarks/whiten_cost_<N>.csv")
    p.add_argument("--repeat", type=int, default=2, help="calls per time (the least counts)")
    a = p.parse_args()
    boxes, feats, glob = _features(a.step)
    nr, n_lm = len(feats["reference"]), sum(len(d) for d in feats["reference"])
    pairs, _ = shortlist_pairs(glob["query"], glob["reference"], a.k)
    ref = feats["reference"]
    fit, t_fit = _timed(
        lambda: fit_whitening(ref, a.whiten), setup=clear_whitening_cache, repeat=a.repeat
    )
    _, t_kept = _timed(lambda: fit_whitening(ref, a.whiten), repeat=a.repeat)

    def transform():  # the fit is kept: its content key, the lookup, both sides transformed
        return whiten_landmarks(feats["query"], ref, a.whiten)

    (wq, wr, _), t_tr = _timed(transform, repeat=a.repeat)
    plain = (feats["query"], boxes["query"], feats["reference"], boxes["reference"])
    white = (wq, boxes["query"], wr, boxes["reference"])
    t_plain = t_white = float("inf")
    for _ in range(max(1, a.repeat)):  # interleaved: load from other processes hits both alike
        t_plain = min(t_plain, _timed(lambda: similarity_pairs(*plain, pairs, compute=QUIET))[1])
        t_white = min(t_white, _timed(lambda: similarity_pairs(*white, pairs, compute=QUIET))[1])
    fit_mb = _peak_mb(lambda: (clear_whitening_cache(), fit_whitening(ref, a.whiten)))
    tr_mb = _peak_mb(transform)
    dim = ref[0].shape[1]
    rows = [
        (f"matching at {dim} dimensions, shortlist k={a.k}", t_plain, float("nan")),
        (f"matching at {fit.kept} dimensions (whitened), shortlist k={a.k}", t_white, float("nan")),
        (f"fit, once per database ({n_lm:,} reference landmarks; key included)", t_fit, fit_mb),
        ("fit kept for this database (its content key and the lookup)", t_kept, float("nan")),
        ("whitening of both sides, fit kept (key, lookup, transform)", t_tr, tr_mb),
        ("whitening + whitened matching, fit kept", t_tr + t_white, float("nan")),
        (
            "whitening + whitened matching, fit computed",
            t_fit - t_kept + t_tr + t_white,
            float("nan"),
        ),
    ]
    table = pd.DataFrame(
        [
            {"step": s, "seconds": t, "ratio": t / t_plain, "peak MB": mb, "places": nr}
            for s, t, mb in rows
        ]
    )
    out = a.out or ROOT / "results" / "benchmarks" / f"whiten_cost_{nr}.csv"
    out.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(out, index=False)
    print(table.to_string(index=False, float_format=lambda x: f"{x:.3f}"))


if __name__ == "__main__":
    main()
