"""Which landmark descriptor? Speed and accuracy of the backbone options on real data.

Run: ``VPR_CACHE_DIR=/tmp/desc_cache .venv/bin/python benchmarks/bench_descriptors.py
[--nordland-step 50] [--nordland-tolerance 0] [--options NAME ...] [--bootstrap 1000]``.

For each option (a backbone spec, see :mod:`vpr_core.backbones`, and a pooling mode):

* ``s/img``: median wall seconds (and process CPU seconds) to encode one 640x360 image with 100
  dense landmarks (Sec. 4 default grid), measured here after a warm-up;
* pooling ``roi@N`` is ``roi`` at working size N (plain ``roi``: the default, 4 crop sides);
* R@1 and AUC (ratio protocol) with 95% bootstrap intervals over queries
  (``vpr_core.evaluation.bootstrap_metrics``, 1,000 resamples, seed 0) for the ``classical`` and
  ``dense`` methods on ``gardens_point_mini`` (10 Gardens Point day/night pairs, exact ground
  truth) and a Nordland subset (winter vs summer, every ``step``-th place, tolerance 0 by
  default: with step 50 neighbouring kept places are 500 original frames apart).

``crop`` and ``roi`` options run through ``vpr_core.run_method(method, dataset,
backbone=spec, pooling=...)``; ``roi@N`` (another working size, not a ``run_method`` argument)
through the same landmark and feature stages with a ``LandmarkEncoder(pooling="roi",
working_size=N)``. The table is printed and written to
``results/benchmarks/descriptor_choice.csv`` (``vpr_core.paths``) after each option,
so an interrupted run keeps what it measured.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np
import torch

#: (label, backbone spec, pooling[, spatial]). Lite0 stages 4/5/6 at 96-224 px, Lite1, Lite2 at
#: its natural 260 px with and without the geometry-aware score (``spatial="consistency"``, not
#: in the paper), HOG, roi. ``roi`` runs at the default working size (4 crop sides: 384 px at
#: 96, 512 px at 128, 1040 px at 260).
OPTIONS: tuple[tuple[str, ...], ...] = (
    ("lite0 s5 128 (default)", "efficientnet_lite0", "crop"),
    ("lite0 s5 128 roi", "efficientnet_lite0", "roi"),
    ("lite0 s5 96", "efficientnet_lite0:input_size=96", "crop"),
    ("lite0 s5 96 roi", "efficientnet_lite0:input_size=96", "roi"),
    ("lite0 s5 96 roi@512", "efficientnet_lite0:input_size=96", "roi@512"),
    ("lite0 s5 160", "efficientnet_lite0:input_size=160", "crop"),
    ("lite0 s4 160", "efficientnet_lite0:stage=4,input_size=160", "crop"),
    ("lite0 s6 224", "efficientnet_lite0:stage=6,input_size=224", "crop"),
    ("lite1 s5 128", "efficientnet_lite1", "crop"),
    ("lite2 s5 260", "efficientnet_lite2:input_size=260", "crop"),
    ("lite2 s5 260 +geometry", "efficientnet_lite2:input_size=260", "crop", "consistency"),
    ("lite2 s5 260 roi", "efficientnet_lite2:input_size=260", "roi"),
    ("lite2 s5 260 roi +geometry", "efficientnet_lite2:input_size=260", "roi", "consistency"),
    ("hog 64", "hog", "crop"),
)
METHODS = ("classical", "dense")
SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def datasets(step: int, tolerance: int = 0) -> dict:
    """``{label: PlaceDataset}`` for the real data found beside the checkout."""
    from vpr_core.datasets import load_dataset

    out = {}
    if (SHARED / "gardens_point_mini").is_dir():
        out["gardens_point_mini"] = load_dataset("folder", SHARED / "gardens_point_mini")
    if (SHARED / "nordland_64x32").is_dir():
        out[f"nordland_step{step}"] = load_dataset(
            "nordland", SHARED / "nordland_64x32", step=step, tolerance=tolerance
        )
    if not out:
        raise SystemExit(f"no real data under {SHARED}: nothing to measure")
    return out


def encoder_for(spec: str, pooling: str):
    """The encoder of one option (``run_method``'s shared one for crop)."""
    from vpr_core.features import LandmarkEncoder, get_encoder

    if pooling == "crop":
        return get_encoder(spec)
    mode, _, size = pooling.partition("@")  # "roi@384": roi at working size 384
    return LandmarkEncoder(spec, pooling=mode, **({"working_size": int(size)} if size else {}))


def seconds_per_image(encoder, repeats: int = 3) -> tuple[float, float]:
    """Median wall and CPU seconds to encode a 640x360 image with 100 dense landmarks."""
    from vpr_core.landmarks import dense_sampling

    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, (360, 640, 3), dtype=np.uint8)
    boxes = np.asarray(dense_sampling(image.shape[:2]))
    encoder.encode(image, boxes)  # warm-up
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        encoder.encode(image, boxes)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu)


def similarity(
    method: str, dataset, spec: str, pooling: str, encoder, spatial: str | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``(similarity (Nq, Nr), ground_truth (Nq, Nr))`` of one method with one option."""
    from vpr_core import run_method
    from vpr_core.features import extract_features
    from vpr_core.landmarks import extract_landmarks

    if pooling in ("crop", "roi"):
        r = run_method(
            method, dataset, backbone=spec, pooling=pooling, spatial=spatial, n_bootstrap=0
        )
        return r.similarity, r.ground_truth
    from vpr_core import get_method
    from vpr_core.matching import Matching, similarity_matrix

    conf = get_method(method)
    boxes = extract_landmarks(conf.landmarks, dataset)
    feats = extract_features(boxes, dataset, encoder)
    sim = similarity_matrix(
        feats["query"],
        boxes["query"],
        feats["reference"],
        boxes["reference"],
        matching=Matching(
            soft_nms_iou=conf.matching.soft_nms_iou, sigma=conf.matching.sigma, spatial=spatial
        ),
    )
    return np.asarray(sim, dtype=np.float64), np.asarray(dataset.ground_truth, dtype=bool)


def fmt(v: tuple[float, float, float]) -> str:
    """``value [low, high]``."""
    return f"{v[0]:.3f} [{v[1]:.2f}, {v[2]:.2f}]"


def _kept_rows(path: Path, rerun: set[str]) -> list[dict]:
    """Rows of an earlier table whose option is still in :data:`OPTIONS` and not re-run now
    (``--options`` measures some options again and keeps the others' measurements)."""
    from vpr_core import utils

    old = utils.read_rows(path)
    known = {o[0]: o for o in OPTIONS}
    return [
        {"option": r["option"], "backbone": r["backbone"], "pooling": r["pooling"], "geometry": ""}
        | r
        for r in old
        if r["option"] in known
        and r["option"] not in rerun
        and (r["backbone"], r["pooling"], r.get("geometry", "")) == _settings(known[r["option"]])
    ]


def _settings(option: tuple[str, ...]) -> tuple[str, str, str]:
    """``(backbone, pooling, geometry)`` of an option ("" when Eq. (1) is used as the paper)."""
    return option[1], option[2], option[3] if len(option) > 3 else ""


def _in_option_order(rows: list[dict]) -> list[dict]:
    order = {o[0]: i for i, o in enumerate(OPTIONS)}
    return sorted(rows, key=lambda r: order[r["option"]])


def main() -> None:
    """Measure every option and write the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--nordland-step", type=int, default=50)
    p.add_argument(
        "--nordland-tolerance",
        type=int,
        default=0,
        help="in kept places (step 50: places 500 frames apart, so 0)",
    )
    p.add_argument(
        "--options",
        nargs="*",
        default=None,
        help="labels from OPTIONS (default all); the table keeps the other options' earlier rows",
    )
    p.add_argument("--bootstrap", type=int, default=1000)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")
    from vpr_core import utils
    from vpr_core.evaluation import bootstrap_metrics
    from vpr_study import outputs

    data = datasets(args.nordland_step, args.nordland_tolerance)
    options = [o for o in OPTIONS if args.options is None or o[0] in args.options]
    with outputs.study_outputs():  # the committed results/benchmarks/, not the user area
        out = outputs.results_dir("benchmarks") / "descriptor_choice.csv"
    print(
        f"torch threads {torch.get_num_threads()}, load average {os.getloadavg()}; datasets: "
        + ", ".join(
            f"{k} ({len(v.query_paths)}q x {len(v.reference_paths)}r, tolerance {v.tolerance})"
            for k, v in data.items()
        )
    )
    rows = []
    kept = _kept_rows(out, {o[0] for o in options}) if args.options else []
    for option in options:
        label, spec, pooling, geometry = (*option[:1], *_settings(option))
        t_opt = time.perf_counter()
        enc = encoder_for(spec, pooling)
        wall, cpu = seconds_per_image(enc, args.repeats)
        row = {
            "option": label,
            "backbone": spec,
            "pooling": pooling,
            "geometry": geometry,
            "raw_dim": enc.raw_dim,
            "s/img": round(wall, 4),
            "cpu s/img": round(cpu, 4),
        }
        for dname, ds in data.items():
            for method in METHODS:
                sim, gt = similarity(method, ds, spec, pooling, enc, geometry or None)
                bm = bootstrap_metrics(sim, gt, n=args.bootstrap, seed=0)
                for key, name in (("r@1", "R@1"), ("auc", "AUC")):
                    v = bm[key]
                    row[f"{dname} {method} {name}"] = round(v[0], 4)
                    row[f"{dname} {method} {name} 95%"] = f"[{v[1]:.3f}, {v[2]:.3f}]"
                print(
                    f"  {label:<24} {dname:<22} {method:<10} R@1 {fmt(bm['r@1'])}  "
                    f"AUC {fmt(bm['auc'])}",
                    flush=True,
                )
        print(
            f"{label:<24} {wall:.3f} s/img wall, {cpu:.3f} s/img cpu "
            f"({time.perf_counter() - t_opt:.0f} s for this option)",
            flush=True,
        )
        rows.append(row)
        utils.write_rows(out, _in_option_order(kept + rows))
    print(f"\nwritten {out}")
    keys = [k for k in rows[0] if k.endswith(("R@1", "AUC"))]
    print(
        f"{'option':<24}{'s/img':>7}  "
        + "  ".join(k.replace("gardens_point_mini", "gp") for k in keys)
    )
    for r in rows:
        print(
            f"{r['option']:<24}{r['s/img']:>7.3f}  "
            + "  ".join(f"{r[k]:.3f} {r[k + ' 95%']}" for k in keys)
        )


if __name__ == "__main__":
    main()
