"""The ``vpr-study`` command line's arguments: the parser, the checks of values argparse cannot
make, and the dataset options they give."""

from __future__ import annotations

import argparse
from collections.abc import Callable

import torch

from vpr_core import paths, settings
from vpr_core.backbones import parse_backbone
from vpr_core.datasets import DATASETS
from vpr_core.evaluation import PROTOCOLS
from vpr_core.matching import SPATIAL_OPTIONS, WEIGHTING_OPTIONS
from vpr_core.methods import available_methods
from vpr_core.paper import PROJECTION_DIM


def _parse_value(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return {"true": True, "false": False, "none": None}.get(text.lower(), text)


def dataset_options(args: argparse.Namespace) -> dict:
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


def _int_at_least(low: int) -> Callable[[str], int]:
    """An argparse ``type=``: an integer >= ``low`` (argparse names the option in the error)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = low - 1
        if value < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {text!r}")
        return value

    return parse


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


#: ``vpr-study --help``'s description.
DESCRIPTION = """vpr-study eval: methods on a dataset; run: the study; findings: claims vs results.

Examples::

    vpr-study eval --dataset synthetic --method dense
    vpr-study eval --dataset gardens_point --root ~/data/gardens_point --method classical
    vpr-study eval --dataset nordland --root ../shared/data/nordland_64x32 --method dense \\
        --pooling roi --shortlist 25             # all 3,576 x 3,576 places
    vpr-study run --dataset synthetic            # all notebooks, figures/ and results/
    vpr-study run --dataset synthetic --quick    # the small headless run used by the tests
"""


def parser(handlers: dict[str, Callable[[argparse.Namespace], int]]) -> argparse.ArgumentParser:
    """The ``vpr-study`` parser; ``handlers``: the function of each command (``eval``, ``run``,
    ``findings``)."""
    p = argparse.ArgumentParser(
        prog="vpr-study",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
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
        "--seed", type=_int_at_least(0), default=0, help="seed of the random projection (default 0)"
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
    e.set_defaults(func=handlers["eval"])

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
        "--jobs",
        type=_int_at_least(1),
        default=None,
        help="dataset labels executed at once, each in its own kernel (default: one per CPU "
        "core); the outputs are the same for any count",
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
    r.set_defaults(func=handlers["run"])

    f = sub.add_parser("findings", help="the paper's claims vs results/<dataset>/ (Markdown)")
    f.add_argument("--labels", nargs="*", help="result folders (default: all but *_quick)")
    f.add_argument("--write", action="store_true", help="also write results/findings.md")
    f.add_argument("--out", default=None, help="output root (default: as for eval and run)")
    f.set_defaults(func=handlers["findings"])
    return p


def check_names(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
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
