"""Command line: ``vpr-study eval`` (one method on one dataset) and ``vpr-study run`` (the study).

Examples::

    vpr-study eval --dataset synthetic --method dense
    vpr-study eval --dataset gardens_point --root ~/data/gardens_point --method classical
    vpr-study eval --dataset nordland --root ../shared/data/nordland_64x32 --method dense \\
        --pooling roi --shortlist 25             # all 3,576 x 3,576 places
    vpr-study run --dataset synthetic            # all notebooks, figures/ and results/
    vpr-study run --dataset synthetic --quick    # the small headless run used by the tests
"""

from __future__ import annotations

import argparse
import errno
import itertools
import shutil
import signal
import sys
import textwrap
import time
from pathlib import Path

import torch

from vpr_core import paths, settings
from vpr_core.backbones import parse_backbone
from vpr_core.baselines import find_vprbench_peers, peer_from_descriptors, peer_from_matrix
from vpr_core.datasets import DATASETS, load_dataset
from vpr_core.datasets.ground_truth import ground_truth_text
from vpr_core.evaluation import (
    PROTOCOLS,
    compact_text,
    compare,
    compare_pairs,
    ground_truth_coverage,
)
from vpr_core.evaluation.spec import check_bootstrap_memory
from vpr_core.matching import SPATIAL_OPTIONS, WEIGHTING_OPTIONS
from vpr_core.methods import available_methods
from vpr_core.paper import PROJECTION_DIM
from vpr_core.pipeline import peer_result, run_method
from vpr_core.utils import configure_logging, short_hash, tune_allocator
from vpr_core.viz import plot_pr_curves
from vpr_core.viz.base import save_all
from vpr_study.findings import findings_markdown, result_labels
from vpr_study.runner import run_study, study_datasets

INTERRUPTED = "interrupted; cached work is kept, rerun to resume"


def say(text: str, width: int) -> None:
    """Print prose wrapped to the terminal's ``width`` (tables are sized by compact_text)."""
    print("\n".join(textwrap.fill(p, width) if p else p for p in text.split("\n")))


def _parse_value(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return {"true": True, "false": False, "none": None}.get(text.lower(), text)


def _dataset_options(args: argparse.Namespace) -> dict:
    opts: dict = {}
    if args.tolerance is not None:
        opts["tolerance"] = args.tolerance
    if getattr(args, "n_places", None) is not None:
        opts["n_places"] = args.n_places
    if getattr(args, "step", None) is not None:
        opts["step"] = args.step
    for item in getattr(args, "opt", None) or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"--opt {item!r} is not KEY=VALUE (e.g. --opt query=winter)")
        opts[key.strip()] = _parse_value(value.strip())
    return opts


def _non_negative(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"--seed must be an integer >= 0, got {text!r}")
    return value


def _folder(text: str) -> str:
    """``--root``: a non-empty folder name (``''`` would read the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "--root is empty; give the dataset folder, e.g. --root ~/data/gardens_point"
        )
    return text


def _device(text: str) -> str:
    """``--device``: ``cpu``, ``cuda``, ``cuda:N`` or ``mps``, available on this machine."""

    try:
        kind = torch.device(text).type
    except (RuntimeError, ValueError):
        kind = ""
    if kind not in ("cpu", "cuda", "mps"):
        raise argparse.ArgumentTypeError(f"--device must be cpu, cuda, cuda:N or mps, got {text!r}")
    if kind == "cuda" and not torch.cuda.is_available():
        raise argparse.ArgumentTypeError(
            f"--device {text}: no CUDA device is available here; use --device cpu"
        )
    if kind == "mps" and not torch.backends.mps.is_available():
        raise argparse.ArgumentTypeError(
            f"--device {text}: no MPS device is available here; use --device cpu"
        )
    return text


def format_table(rows: list[dict], columns: list[str] | None = None, floatfmt: str = ".3f") -> str:
    """Plain-text table (no extra dependency) of a list of dict rows."""
    if not rows:
        return "(no rows)"
    columns = columns or list(rows[0])
    cells = [
        [
            (f"{r[c]:{floatfmt}}" if isinstance(r.get(c), float) else str(r.get(c, "")))
            for c in columns
        ]
        for r in rows
    ]
    widths = [max(len(c), *(len(row[k]) for row in cells)) for k, c in enumerate(columns)]
    line = "  ".join(c.ljust(w) for c, w in zip(columns, widths, strict=False))
    sep = "  ".join("-" * w for w in widths)
    body = [
        "  ".join(
            v.rjust(w) if k else v.ljust(w)
            for k, (v, w) in enumerate(zip(row, widths, strict=False))
        )
        for row in cells
    ]
    return "\n".join([line, sep, *body])


def _peer_results(args: argparse.Namespace, dataset) -> list:
    """VPR-Bench peers (``--peers ROOT --peer-dataset NAME``) as results beside ours."""
    if not args.peers and not args.peer_dataset:
        return []

    if not args.peer_dataset:
        raise ValueError(
            "--peers needs --peer-dataset NAME (the folder under "
            "precomputed_matches/, e.g. GardensPoint)"
        )
    return [
        peer_result(p, dataset, n_bootstrap=args.n_bootstrap, protocol=args.protocol)
        for p in find_vprbench_peers(args.peers, args.peer_dataset)
    ]


def _user_peers(args: argparse.Namespace, dataset) -> list:
    """``--peer NAME=PATH``: a user's method from a similarity (or, with ``--peer-distance``,
    distance) matrix ``.npy``, or from a folder with ``queries_descriptors.npy`` and
    ``database_descriptors.npy``."""

    out = []
    for item in args.peer or []:
        name, sep, path = item.partition("=")
        if not sep or not name.strip() or not path.strip():
            raise ValueError(
                f"--peer {item!r} is not NAME=PATH (e.g. --peer MyNet=sim.npy or "
                "--peer MyNet=descriptors_folder/)"
            )
        p = Path(path.strip()).expanduser()
        if p.is_dir():
            peer = peer_from_descriptors(
                p / "queries_descriptors.npy",
                p / "database_descriptors.npy",
                name.strip(),
                metric=args.peer_metric,
            )
        else:
            peer = peer_from_matrix(p, name.strip(), distance=args.peer_distance)
        out.append(
            peer_result(
                peer,
                dataset,
                n_bootstrap=args.n_bootstrap,
                label=name.strip(),
                protocol=args.protocol,
            )
        )
    return out


def _cost_rows(table, results: list, wall: dict[str, float]) -> tuple[list[dict], list[dict]]:
    """``(ours, peers)``: each run's landmark count and costs (not in the committed CSV).

    Ours are the seconds recorded when the stages computed; ``measured`` says whether that was
    in this run, or ``from cache`` when they exceed the run's wall time here (an earlier run
    measured them). Peers: VPR-Bench's stored encode and match times, from its machine.
    """
    cols = {
        "landmarks/img": "lm/img",
        "landmarks s/img": "lm s/img",
        "features s/img": "feat s/img",
        "matching s/pair": "match s/pair",
    }
    ours, peers = [], []
    for r in results:
        row = table.loc[r.label]
        cells = {
            short: f"{row[c]:.3g}" for c, short in cols.items() if c in table and row[c] == row[c]
        }
        if r.method.startswith("peer:"):
            peers.append({"peer": r.label, **cells})
            continue
        n_img = sum(r.similarity.shape)
        t = r.timings
        spent = (t["landmarks_s_per_image"] + t["features_s_per_image"]) * n_img + t[
            "matching_s_per_pair"
        ] * t.get("pairs", 0)
        here = wall[r.label]
        source = "this run" if spent <= here else "earlier run"
        ours.append({"method": r.label, **cells, "wall s": f"{here:.1f}", "measured": source})
    return ours, peers


#: ``eval`` arguments that do not change a number (where and how the run is done).
_NOT_SETTINGS = ("command", "func", "out", "label", "scheduler", "wide")


def eval_settings(args: argparse.Namespace) -> dict:
    """Every ``eval`` argument that can change a number (methods, peers, protocol, shortlist,
    pooling, backbone, loader options, ...), unset ones left out; file arguments (root, peers,
    weights) as absolute paths. Hashed into the output file names."""
    found = {}
    for key, value in sorted(vars(args).items()):
        if key in _NOT_SETTINGS or value is None or value is False or value == []:
            continue
        if key in ("root", "peers", "weights"):
            value = str(Path(value).expanduser().resolve())
        elif key == "peer":
            value = [
                f"{n}={Path(p).expanduser().resolve()}"
                for n, _, p in (item.partition("=") for item in value)
            ]
        found[key] = value
    return found


#: Settings the dataset line of a PR figure already names (:func:`vpr_core.viz.dataset_line`).
_IN_DATASET_LINE = ("backbone", "pooling", "shortlist", "protocol")


def changed_settings(args: argparse.Namespace) -> tuple[dict[str, str], dict[str, object]]:
    """``({setting: readable value}, {setting: full value})``: the :func:`eval_settings` that
    differ from ``eval``'s defaults (dataset, root and methods left out: the label and the
    method list name them); a file argument reads as its name, its full path in the second."""
    defaults = vars(build_parser().parse_args(["eval"]))
    readable: dict[str, str] = {}
    files: dict[str, object] = {}
    for key, value in eval_settings(args).items():
        if key in ("dataset", "root", "method") or value == defaults.get(key):
            continue
        if key in ("peers", "weights"):
            readable[key], files[key] = Path(str(value)).name, value
        elif key == "peer":
            readable[key] = "+".join(str(v).partition("=")[0] for v in value)
            files[key] = value
        else:
            readable[key] = "+".join(map(str, value)) if isinstance(value, list) else str(value)
    return readable, files


def eval_stem(args: argparse.Namespace, label: str) -> str:
    """``eval_<label>_<methods>[_<setting>-<value>...][_<hash>]``: named by the settings that
    differ from the defaults (:func:`changed_settings`, e.g. ``_pooling-roi_shortlist-25``); a
    short hash only of file arguments' full paths, so two files of one name never share one."""
    readable, files = changed_settings(args)
    parts = [f"{k.replace('_', '-')}-{v}" for k, v in readable.items()]
    if files:
        parts.append(short_hash(files, 8))
    stem = "_".join([f"eval_{label}", "+".join(args.method), *parts])
    return "".join(c if c.isalnum() or c in "-_.+=" else "_" for c in stem)


def cmd_eval(args: argparse.Namespace) -> int:
    check_bootstrap_memory(args.n_bootstrap, "--n-bootstrap")
    tune_allocator()  # process-wide, here at the boundary: crop features ~1.7x faster
    dataset = load_dataset(args.dataset, root=args.root, **_dataset_options(args))
    label = paths.check_label(args.label or dataset.name)
    n_gt, n_q = ground_truth_coverage(dataset.ground_truth)
    truth = ground_truth_text(
        dataset.ground_truth, dataset.tolerance, bool(dataset.meta.get("ground_truth_file"))
    )
    loader = "" if dataset.name == args.dataset else f" (loader {args.dataset})"
    width = shutil.get_terminal_size().columns  # $COLUMNS, the terminal, else 80
    say(
        f"dataset: {label}{loader}  queries={len(dataset.query_paths)} "
        f"references={len(dataset.reference_paths)}  {truth}",
        width,
    )
    print(f"queries with ground truth: {n_gt} of {n_q}")
    mode = "exhaustive" if args.shortlist is None else f"shortlist k={args.shortlist}"
    scheduler = args.scheduler or settings.dask_scheduler()
    spatial = [None, *SPATIAL_OPTIONS] if args.spatial == "both" else [args.spatial]
    choices: dict[str, list[str | None]] = {"none": [None], "both": [None, *WEIGHTING_OPTIONS]}
    weighting = choices.get(args.weighting, [args.weighting])
    results, wall, run_of = [], {}, {}
    for m, s, w in itertools.product(args.method, spatial, weighting):
        t0 = time.perf_counter()
        r = run_method(
            m,
            dataset,
            backbone=args.backbone,
            dim=args.dim,
            seed=args.seed,
            weights=args.weights,
            pooling=args.pooling,
            device=args.device,
            shortlist=args.shortlist,
            scheduler=scheduler,
            n_bootstrap=args.n_bootstrap,
            protocol=args.protocol,
            spatial=s,
            weighting=w,
        )
        results.append(r)
        run_of[m, s, w] = r
        wall[r.label] = time.perf_counter() - t0
    results += _peer_results(args, dataset) + _user_peers(args, dataset)
    say(
        f"backbone: {results[0].encoder.get('backbone')} "
        f"(weights: {results[0].encoder.get('weights')}, pooling: {args.pooling}, {mode}; "
        f"95% bootstrap intervals over queries, {args.n_bootstrap} resamples)",
        width,
    )
    if len(results) > 1:
        say(
            f"paired bootstrap (same resampled queries): dAUC and dR@1 = method - "
            f"{results[0].label}; a finding only where the interval excludes 0",
            width,
        )
    table = compare(results, n_bootstrap=args.n_bootstrap)
    print(compact_text(table, width, wide=args.wide))
    ours, peers = _cost_rows(table, results, wall)
    say(
        "cost (lm: landmarks, feat: features): seconds recorded when computed, in 'this run' or "
        "an 'earlier run' (read from the cache: more seconds than this run's wall time):",
        width,
    )
    print(format_table(ours))
    if peers:
        say("peers' costs as stored with them (VPR-Bench: its machine; not comparable):", width)
        print(format_table(peers))
    stem = eval_stem(args, label)
    readable, _ = changed_settings(args)
    shown = [f"{k.replace('_', ' ')} {v}" for k, v in readable.items() if k not in _IN_DATASET_LINE]
    title = f"vpr-study eval on {label}" + (f" ({', '.join(shown)})" if shown else "")
    fig = plot_pr_curves(results, title=title)
    items: list = [(stem, table), (stem, fig)]
    if args.spatial == "both":
        pairs = [
            (run_of[m, None, w], run_of[m, s, w])
            for m, w in itertools.product(args.method, weighting)
            for s in SPATIAL_OPTIONS
        ]
        geometry = compare_pairs(pairs, n_bootstrap=args.n_bootstrap)
        say("\n(not in the paper) geometry-aware score, each method with minus without:", width)
        print(compact_text(geometry, width, wide=args.wide))
        items.append((f"{stem}_geometry", geometry))
    if args.weighting == "both":
        pairs = [
            (run_of[m, s, None], run_of[m, s, w])
            for m, s in itertools.product(args.method, spatial)
            for w in WEIGHTING_OPTIONS
        ]
        weighted = compare_pairs(pairs, n_bootstrap=args.n_bootstrap)
        say("\n(not in the paper) database weighting, each method with minus without:", width)
        print(compact_text(weighted, width, wide=args.wide))
        items.append((f"{stem}_weighting", weighted))
    written = save_all(items, label, out=args.out)
    root = paths.figures_root() if args.out is None else Path(args.out).expanduser().resolve()
    say(f"wrote under {root}:", width)
    print("\n".join(f"  {p.relative_to(root)}" for p in written))
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    run_study(
        dataset=args.dataset,
        root=args.root,
        backbone=args.backbone,
        quick=args.quick,
        notebooks=args.notebooks or None,
        real_data=args.real_data,
        label=args.label,
        options=_dataset_options(args),
        pooling=args.pooling,
        shortlist=args.shortlist,
        force=args.force,
    )
    return 0


def cmd_findings(args: argparse.Namespace) -> int:
    labels = args.labels or result_labels(["synthetic", *study_datasets()])
    text = findings_markdown(labels)
    print(text)
    if args.write:
        out = paths.results_dir() / "findings.md"
        out.write_text(text + "\n")
        print(f"wrote {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="vpr-study", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = p.add_subparsers(dest="command", required=True)

    def common(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--dataset", default="synthetic", help=" | ".join(DATASETS))
        sp.add_argument("--root", type=_folder, default=None, help="dataset folder (real datasets)")
        sp.add_argument(
            "--backbone",
            default="efficientnet_lite0",
            help="landmark descriptor: efficientnet_lite0 (default, ImageNet "
            "weights shipped), efficientnet_lite1/2, alexnet_conv3 (the "
            "paper's; needs a weights file), hog, sift",
        )
        sp.add_argument(
            "--out",
            default=None,
            help="output root: figures/, results/, runs/ (and .cache/ unless "
            "VPR_CACHE_DIR is set) go under it; default $VPR_OUTPUT_DIR, else the "
            "project checkout holding the current folder, else the current folder",
        )
        sp.add_argument("--step", type=int, default=None, help="nordland: keep every step-th place")
        sp.add_argument(
            "--tolerance", type=int, default=None, help="ground-truth tolerance (frames)"
        )
        sp.add_argument(
            "--opt",
            action="append",
            metavar="KEY=VALUE",
            help="any other loader option, e.g. --opt query=winter (repeatable)",
        )

    e = sub.add_parser("eval", help="evaluate one or more methods on a dataset")
    common(e)
    e.add_argument(
        "--method",
        nargs="+",
        default=["dense"],
        help=f"one or more of: {', '.join(available_methods())}",
    )
    e.add_argument(
        "--label",
        default=None,
        help="output subfolder and the dataset's name in tables and titles "
        "(default: the root folder's name for folder datasets, else the "
        "dataset name)",
    )
    e.add_argument(
        "--dim",
        type=int,
        default=PROJECTION_DIM,
        help=f"descriptor dimension after the random projection (default {PROJECTION_DIM})",
    )
    e.add_argument(
        "--seed", type=_non_negative, default=0, help="seed of the random projection (default 0)"
    )
    e.add_argument("--weights", default=None, help="AlexNet weights file (alexnet_conv3)")
    e.add_argument(
        "--pooling",
        default="crop",
        choices=("crop", "roi"),
        help="crop: the paper's per-landmark crops (default); roi: one backbone "
        "pass per image, regions pooled from the feature map",
    )
    e.add_argument(
        "--shortlist",
        type=int,
        default=None,
        metavar="K",
        help="re-rank only each query's top-K references by a whole-image "
        "descriptor (default: exhaustive, the paper's)",
    )
    e.add_argument(
        "--spatial",
        default=None,
        choices=(*SPATIAL_OPTIONS, "both"),
        help="(not in the paper) re-score every method's reciprocal matches by the agreement "
        "of their box displacements (docs/DEFINITIONS.md); 'both': every method without and "
        "with it, and each method's paired difference; default off: Eq. (1) as the paper",
    )
    e.add_argument(
        "--weighting",
        default="none",
        choices=("none", *WEIGHTING_OPTIONS, "both"),
        help="(not in the paper) weight every method's match terms by how much better the "
        "query landmark matches this reference than the others (docs/DEFINITIONS.md); 'both': "
        "every method without and with each weighting, and the paired differences; default "
        "none: Eq. (1) as the paper",
    )
    e.add_argument(
        "--wide",
        action="store_true",
        help="print every column of the table (default: the columns that fit the terminal; "
        "the CSV keeps them all)",
    )
    e.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="Dask scheduler (tcp://host:8786; default $VPR_DASK_SCHEDULER): run "
        "features and matching on that cluster; unset: in-process",
    )
    e.add_argument(
        "--protocol",
        default="ratio",
        choices=PROTOCOLS,
        help="PR protocol of AUC and R@100P: ratio (the paper's, default), vpr_bench "
        "(VPR-Bench's AUC-PR), best_match (VPR_Tutorial's), multi_match; see "
        "docs/DEFINITIONS.md",
    )
    e.add_argument(
        "--device", type=_device, default="cpu", help="torch device: cpu (default), cuda[:N], mps"
    )
    e.add_argument(
        "--n-bootstrap",
        type=int,
        default=1000,
        help="bootstrap resamples of the 95%% intervals (default 1000)",
    )
    e.add_argument(
        "--peers",
        default=None,
        metavar="VPR_BENCH",
        help="VPR-Bench checkout (or $VPR_BENCH_ROOT): add its precomputed "
        "techniques for --peer-dataset as peers in the table and the figure",
    )
    e.add_argument(
        "--peer-dataset",
        default=None,
        metavar="NAME",
        help="VPR-Bench dataset folder under precomputed_matches/ (e.g. GardensPoint)",
    )
    e.add_argument(
        "--peer",
        action="append",
        metavar="NAME=PATH",
        help="your own method as a peer: a (Nq, Nr) similarity matrix .npy, or a "
        "folder with queries_descriptors.npy + database_descriptors.npy "
        "(repeatable)",
    )
    e.add_argument(
        "--peer-distance",
        action="store_true",
        help="--peer matrices are distances (lower = more similar)",
    )
    e.add_argument(
        "--peer-metric",
        default="cosine",
        choices=("cosine", "l2"),
        help="metric of --peer descriptor folders (default cosine)",
    )
    e.add_argument("--n-places", type=int, default=None, help="synthetic: number of places")
    e.set_defaults(func=cmd_eval)

    r = sub.add_parser("run", help="execute the study notebooks and regenerate figures/")
    common(r)
    r.add_argument("--quick", action="store_true", help="small synthetic set (used by tests)")
    r.add_argument("--notebooks", nargs="*", help="subset of notebooks (file stems)")
    r.add_argument(
        "--force",
        action="store_true",
        help="execute every notebook, also those whose inputs and outputs are unchanged since "
        "their last execution (skipped by default)",
    )
    r.add_argument(
        "--real-data",
        dest="real_data",
        action="store_true",
        default=None,
        help="also run notebooks 03-06 on the real datasets beside the project "
        "(default for the full synthetic study)",
    )
    r.add_argument(
        "--no-real-data", dest="real_data", action="store_false", help="only the --dataset study"
    )
    r.add_argument(
        "--label",
        default=None,
        help="subfolder of figures/ and results/ (default: the dataset's name)",
    )
    r.add_argument(
        "--pooling",
        default="crop",
        choices=("crop", "roi"),
        help="landmark pooling of every run (default crop, the paper's)",
    )
    r.add_argument(
        "--shortlist",
        type=int,
        default=None,
        metavar="K",
        help="re-rank each query's top-K references (global cosine) by Eq. (1)",
    )
    r.set_defaults(func=cmd_run)

    f = sub.add_parser("findings", help="the paper's claims vs results/<dataset>/ (Markdown)")
    f.add_argument("--labels", nargs="*", help="result folders (default: all but *_quick)")
    f.add_argument("--write", action="store_true", help="also write results/findings.md")
    f.add_argument("--out", default=None, help="output root (default: as for eval and run)")
    f.set_defaults(func=cmd_findings)
    return p


def _check_names(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Unknown methods and backbones are reported before any dataset is generated or read."""

    if args.command == "eval":
        bad = [m for m in args.method if m not in available_methods()]
        if bad:
            parser.error(f"unknown method(s) {bad}; valid: {', '.join(available_methods())}")
        twice = sorted({m for m in args.method if args.method.count(m) > 1})
        if twice:
            parser.error(f"--method lists {', '.join(twice)} twice; name each method once")
        if args.protocol == "multi_match" and args.n_bootstrap > 0:
            parser.error(
                "--protocol multi_match ranks all query-reference pairs together, so it has no "
                "bootstrap over queries: add --n-bootstrap 0"
            )
        try:
            settings.scheduler_timeout()
        except ValueError as exc:
            parser.error(str(exc))
    if getattr(args, "label", None) is not None:
        try:
            paths.check_label(args.label)
        except ValueError as exc:
            parser.error(f"--{exc}")
    if getattr(args, "backbone", None) is None:
        return
    try:
        parse_backbone(args.backbone)
    except (TypeError, ValueError) as exc:
        parser.error(str(exc))


class _Terminated(Exception):
    """SIGTERM, turned into an exception so that it unwinds like Ctrl-C."""


def _terminated(signum, frame):
    raise _Terminated()


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``vpr-study``; returns the exit code (2 on a user error, 130 on Ctrl-C)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    previous = signal.getsignal(signal.SIGTERM)
    signal.signal(signal.SIGTERM, _terminated)
    _check_names(parser, args)
    configure_logging()
    try:
        # --out applies to this command only; the runner hands it to its kernels. The CLI
        # writes the study's figures/ and results/, never the user's area (paths.figures_root)
        with paths.using_output_root(args.out or None), paths.study_outputs():
            return args.func(args)
    except KeyboardInterrupt:
        print(INTERRUPTED, file=sys.stderr)
        return 130
    except _Terminated:
        print(INTERRUPTED.replace("interrupted", "terminated"), file=sys.stderr)
        return 143
    except OSError as exc:
        if exc.errno == errno.ENOSPC and not exc.filename:
            where = Path(args.out).expanduser().resolve() if args.out else paths.output_root()
            exc = OSError(exc.errno, f"{exc.strerror} while writing under {where} or its cache")
        print(f"vpr-study: error: {exc}", file=sys.stderr)
        return 2
    except (
        ValueError,
        TypeError,
        IndexError,
        RuntimeError,
        ImportError,
    ) as exc:
        print(f"vpr-study: error: {exc}", file=sys.stderr)
        return 2
    finally:
        signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
