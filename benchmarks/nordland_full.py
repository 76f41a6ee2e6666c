"""All 3,576 x 3,576 Nordland places end to end (issue 46.2): dense, roi, shortlist 25, without
and with ``weighting="contrast"``, from an empty cache; writes ``results/benchmarks/
nordland_full.csv`` and ``nordland_full_contrast.csv`` (wall times: docs/MEASUREMENTS.md).

Usage::

    .venv/bin/python benchmarks/nordland_full.py [--root ../shared/data/nordland_64x32]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RUNS = {"nordland_full_contrast": ["--weighting", "contrast"], "nordland_full": []}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=str(REPO.parent / "shared" / "data" / "nordland_64x32"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="vpr-full-") as tmp:
        env = {"VPR_CACHE_DIR": f"{tmp}/cache", "MPLBACKEND": "Agg", "TQDM_DISABLE": "1"}
        for name, extra in RUNS.items():  # contrast first: its wall time is from an empty cache
            out = Path(tmp) / name
            cmd = [sys.executable, "-m", "vpr_study.cli", "eval", "--dataset", "nordland"]
            cmd += ["--root", args.root, "--method", "dense", "--pooling", "roi"]
            cmd += ["--shortlist", "25", "--out", str(out), *extra]
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, env={**os.environ, **env})
            print(f"{name}: {time.perf_counter() - t0:.0f} s wall")
            (table,) = [p for p in (out / "results").rglob("*.csv") if ".timings" not in p.name]
            shutil.copyfile(table, REPO / "results" / "benchmarks" / f"{name}.csv")


if __name__ == "__main__":
    main()
