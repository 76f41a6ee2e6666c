"""Command line: ``vpr-study eval`` (one method on one dataset) and ``vpr-study run`` (the study).

Examples::

    vpr-study eval --dataset synthetic --method dense
    vpr-study eval --dataset gardens_point --root ~/data/gardens_point --method classical
    vpr-study run --dataset synthetic            # all notebooks, figures/ and results/
    vpr-study run --dataset synthetic --quick    # the small headless run used by the tests
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .utils import REPO_DIR


def _dataset_options(args: argparse.Namespace) -> dict:
    opts: dict = {}
    if args.tolerance is not None:
        opts["tolerance"] = args.tolerance
    if getattr(args, "n_places", None) is not None:
        opts["n_places"] = args.n_places
    return opts


def format_table(rows: list[dict], columns: list[str] | None = None, floatfmt: str = ".3f") -> str:
    """Plain-text table (no extra dependency) of a list of dict rows."""
    if not rows:
        return "(no rows)"
    columns = columns or list(rows[0])
    cells = [[(f"{r[c]:{floatfmt}}" if isinstance(r.get(c), float) else str(r.get(c, "")))
              for c in columns] for r in rows]
    widths = [max(len(c), *(len(row[k]) for row in cells)) for k, c in enumerate(columns)]
    line = "  ".join(c.ljust(w) for c, w in zip(columns, widths))
    sep = "  ".join("-" * w for w in widths)
    body = ["  ".join(v.rjust(w) if k else v.ljust(w) for k, (v, w) in enumerate(zip(row, widths)))
            for row in cells]
    return "\n".join([line, sep, *body])


def cmd_eval(args: argparse.Namespace) -> int:
    from .datasets import load_dataset
    from .pipeline import run_method
    from .viz import plot_pr_curves, save_figure

    dataset = load_dataset(args.dataset, root=args.root, **_dataset_options(args))
    print(f"dataset: {dataset.name}  queries={len(dataset.query_paths)} "
          f"references={len(dataset.reference_paths)} tolerance={dataset.tolerance}")
    results = [run_method(m, dataset, backbone=args.backbone, dim=args.dim, seed=args.seed,
                          weights=args.weights) for m in args.method]
    rows = [r.row() for r in results]
    table = format_table(rows, floatfmt=".4f")
    print(f"backbone: {results[0].encoder.get('backbone')} "
          f"(weights: {results[0].encoder.get('weights')})")
    print(table)
    out = Path(args.out) if args.out else REPO_DIR / "results" / dataset.name
    out.mkdir(parents=True, exist_ok=True)
    stem = "eval_" + "+".join(args.method) + f"_{args.backbone}"
    (out / f"{stem}.txt").write_text(table + "\n")
    import pandas as pd

    pd.DataFrame(rows).to_csv(out / f"{stem}.csv", index=False, float_format="%.6f")
    fig = plot_pr_curves({r.label: r.curve() for r in results},
                         title=f"{dataset.name} (tolerance {dataset.tolerance})")
    png = save_figure(fig, out / f"{stem}.png")
    print(f"wrote {out / (stem + '.csv')} and {png}")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from .runner import run_study

    run_study(dataset=args.dataset, root=args.root, backbone=args.backbone, quick=args.quick,
              notebooks=args.notebooks or None)
    return 0


def build_parser() -> argparse.ArgumentParser:
    from .methods import available_methods

    p = argparse.ArgumentParser(prog="vpr-study", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)

    def common(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--dataset", default="synthetic",
                        help="synthetic | gardens_point | mapillary_berlin | "
                             "freiburg_across_seasons | folder")
        sp.add_argument("--root", default=None, help="dataset folder (real datasets)")
        sp.add_argument("--backbone", default="efficientnet_lite0")

    e = sub.add_parser("eval", help="evaluate one or more methods on a dataset")
    common(e)
    e.add_argument("--method", nargs="+", default=["dense"],
                   help=f"one or more of: {', '.join(available_methods())}")
    e.add_argument("--dim", type=int, default=1024)
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--weights", default=None, help="AlexNet weights file (alexnet_conv3)")
    e.add_argument("--tolerance", type=int, default=None, help="ground-truth tolerance (frames)")
    e.add_argument("--n-places", type=int, default=None, help="synthetic: number of places")
    e.add_argument("--out", default=None, help="output folder (default results/<dataset>)")
    e.set_defaults(func=cmd_eval)

    r = sub.add_parser("run", help="execute the study notebooks and regenerate figures/")
    common(r)
    r.add_argument("--quick", action="store_true", help="small synthetic set (used by tests)")
    r.add_argument("--notebooks", nargs="*", help="subset of notebooks (file stems)")
    r.set_defaults(func=cmd_run)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command == "eval":
        from .methods import available_methods

        bad = [m for m in args.method if m not in available_methods()]
        if bad:
            parser.error(f"unknown method(s) {bad}; valid: {', '.join(available_methods())}")
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError, IndexError, RuntimeError) as exc:
        print(f"vpr-study: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
