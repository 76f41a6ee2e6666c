"""The ``vpr-study`` command line's arguments: the parser, the checks of values argparse cannot
make, and the dataset options they give."""

from __future__ import annotations

import argparse
import inspect
import math
from collections.abc import Callable
from typing import Any

from vpr_core import paper, settings
from vpr_study import outputs
from vpr_study.choices import (
    BACKBONES,
    DATASETS,
    METHODS,
    NORMALISE_OPTIONS,
    PROTOCOLS,
    SPATIAL_OPTIONS,
    WEIGHTING_OPTIONS,
    WHITEN_K,
    weights_found,
)
from vpr_study.usage import COMMANDS, DESCRIPTION, version_text

__all__ = [
    "EVAL_EPILOG",
    "RUN_EPILOG",
    "backbone_help",
    "check_names",
    "command_parser",
    "dataset_options",
    "given_once",
    "parser",
]


def _parse_value(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return {"true": True, "false": False, "none": None}.get(text.lower(), text)


def _number(text: str, kind: type) -> Any:
    """``text`` as a finite ``kind`` (int or float); ValueError otherwise."""
    value = kind(text.strip())
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(text)
    return value


def _typed(item: str, key: str, text: str, default: Any) -> Any:
    """``--opt KEY=VALUE``'s value parsed by the type of the loader's default for ``key``: a
    tuple of numbers from ``a,b`` (``image_size=120,160``), an int, a float, a bool, a string;
    an option without a typed default as :func:`_parse_value` reads it."""
    kind = type(default)
    try:
        finite = math.isfinite(float(text))
    except ValueError:
        finite = True  # no number at all: the type below says what the option takes
    if not finite:
        raise ValueError(
            f"--opt {item!r}: {text!r} is not a finite number (inf, nan or beyond float range); "
            "give a finite value"
        )
    try:
        if isinstance(default, bool):
            parsed = {"true": True, "false": False, "1": True, "0": False}[text.lower()]
            return parsed
        if isinstance(default, int | float):
            return _number(text, kind)
        if isinstance(default, tuple | list) and default:
            parts = [_number(t, type(default[0])) for t in text.replace("x", ",").split(",")]
            if len(parts) != len(default):
                raise ValueError(text)
            return tuple(parts)
    except (ValueError, KeyError):
        what = {bool: "true or false", int: "an integer", float: "a finite number"}.get(kind)
        if what is None:
            what = f"{len(default)} numbers separated by commas"
        example = ",".join(map(str, default)) if isinstance(default, tuple | list) else default
        raise ValueError(
            f"--opt {item!r}: {key} takes {what} (e.g. --opt {key}={example}), got {text!r}"
        ) from None
    if isinstance(default, str):
        return text
    return _parse_value(text)


def _loader_defaults(dataset: str | None) -> dict[str, Any]:
    """The loader of ``dataset``'s keyword defaults (``{}`` for an unknown name: load_dataset
    names the valid ones)."""
    import vpr_core  # a command: the pipeline is loaded now (its face loads names on first use)

    key = str(dataset or "").strip().lower().replace("-", "_")
    if key not in vpr_core.DATASETS:
        return {}
    params = inspect.signature(vpr_core.DATASETS[key]).parameters.values()
    return {p.name: p.default for p in params if p.default is not inspect.Parameter.empty}


def dataset_options(args: argparse.Namespace) -> dict:
    """The loader options of ``--tolerance``, ``--n-places``, ``--step`` and ``--opt KEY=VALUE``.

    Raises:
        ValueError: an ``--opt`` that is not KEY=VALUE, ``--opt root=...`` (``--root`` says
            it), or one option set twice (``--opt tolerance=1 --tolerance 2``,
            ``--opt a=1 --opt a=2``): the message names both.
    """
    opts: dict = {}
    given: dict[str, str] = {}

    def put(key: str, value: object, how: str) -> None:
        same = key.replace("-", "_")
        if same in given:
            raise ValueError(
                f"{given[same]} and {how} both set the loader option {same!r}; give it once"
            )
        given[same] = how
        opts[key] = value

    for key, flag in (("tolerance", "--tolerance"), ("n_places", "--n-places"), ("step", "--step")):
        value = getattr(args, key, None)
        if value is not None:
            put(key, value, f"{flag} {value}")
    items = getattr(args, "opt", None) or []
    defaults = _loader_defaults(getattr(args, "dataset", None)) if items else {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"--opt {item!r} is not KEY=VALUE (e.g. --opt query=winter)")
        if key.strip() == "root":
            raise ValueError(f"--opt {item!r}: the dataset folder is --root, not a loader option")
        name = key.strip().replace("-", "_")
        parsed = _typed(item, name, value.strip(), defaults.get(name))  # by the loader's type
        if isinstance(parsed, float) and not math.isfinite(parsed):
            raise ValueError(
                f"--opt {item!r}: {value.strip()!r} is not a finite number (inf, nan or beyond "
                "float range); give a finite value"
            )
        put(key.strip(), parsed, f"--opt {item}")
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


def _whiten(text: str) -> str | int:
    """``--whiten``: ``none``, ``both`` or the components kept, an integer >= 1."""
    if text in ("none", "both"):
        return text
    try:
        return _int_at_least(1)(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"must be none, both or an integer >= 1 (the components kept), got {text!r}"
        ) from None


def _folder(text: str) -> str:
    """``--root``: a non-empty folder name (``''`` would read the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "--root is empty; give the dataset folder, e.g. --root ~/data/gardens_point"
        )
    return text


def _device(text: str) -> str:
    """``--device``: ``cpu``, ``cuda``, ``cuda:N`` or ``mps``, available on this machine."""

    import torch  # only when --device is given: every --help answers without torch

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


#: Where a parsed namespace records the options given so far (:class:`_Once`); removed by
#: :func:`given_once` after parsing.
_GIVEN = "_given"


class _Once(argparse.Action):
    """``store``, refusing an option given twice (``--tolerance 1 --tolerance 2``): argparse
    would keep the last one silently."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault(_GIVEN, {})
        shown = " ".join(map(str, values)) if isinstance(values, list) else str(values)
        now = f"{option_string} {shown}".strip()
        if self.dest in given:
            raise argparse.ArgumentError(
                self, f"given twice ({given[self.dest]}, {now}); give it once"
            )
        given[self.dest] = now
        setattr(namespace, self.dest, values)


def given_once(args: argparse.Namespace) -> argparse.Namespace:
    """``args`` without the record :class:`_Once` keeps while parsing."""
    vars(args).pop(_GIVEN, None)
    return args


def backbone_help() -> str:
    """``--backbone``'s help: every registered backbone, each that cannot run in this install
    marked with what it needs (a weights file that is absent here)."""
    names = [
        name
        if weights_found(name)
        else f"{name} (needs a weights file, none found here: --weights FILE)"
        for name in BACKBONES
    ]
    return (
        "landmark descriptor: a name, or NAME:OPTION=VALUE,... (e.g. efficientnet_lite0:stage=4,"
        f"input_size=96), of: {', '.join(names)} (default: efficientnet_lite0, ImageNet weights "
        "shipped)"
    )


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Examples kept as written; each option's default named (``(default: X)``) where its help
    does not already say it; ``--backbone`` lists the backbones of this install (read only
    when help is shown)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if action.dest == "backbone":
            return backbone_help().replace("%", "%%")
        default = action.default
        if (
            action.option_strings
            and "default" not in text
            and default not in (None, False, argparse.SUPPRESS)
            and not isinstance(action, argparse._HelpAction)
        ):
            value = " ".join(map(str, default)) if isinstance(default, list) else str(default)
            text += f" (default: {value})".replace("%", "%%")
        return text


#: ``vpr-study eval --help``'s examples and where it writes.
EVAL_EPILOG = """examples:
  vpr-study eval --dataset synthetic --method dense classical
      the paper's two methods on the built-in synthetic set (no download)
  vpr-study eval --dataset synthetic --method dense --weighting both
      without and with the contrast weighting, and the paired difference (--weighting all:
      without and with each of contrast, idf, two_sided)
  vpr-study eval --dataset synthetic --method dense --normalise all
      without and with each normalisation of the matrix (query_batch needs the query batch)
  vpr-study eval --dataset synthetic --method dense --whiten both
      without and with the descriptors whitened on the reference database (256 components)
  vpr-study eval --dataset folder --root ~/photos/route --method dense
      your own images: a folder holding query/ and reference/ image folders
  vpr-study eval --dataset synthetic --method dense --peer MyNet=sim.npy
      your own method's (queries x references) similarity matrix beside ours
  vpr-study eval --study --dataset synthetic --method dense classical
      the study's own call (make study): its committed figures/ and results/

where it writes: user/figures/<label>/ and user/results/<label>/ of the
checkout (git-ignored; outside a checkout, the current folder); --out ROOT:
ROOT/figures/<label>/ and ROOT/results/<label>/; --study: the study's
figures/ and results/. A label holds letters, digits, '_', '-', '.', '+'.
"""

#: ``vpr-study run --help``'s examples.
RUN_EPILOG = """examples:
  vpr-study run --dataset synthetic            # the whole study (make study)
  vpr-study run --dataset synthetic --quick    # the small headless run of the tests
  vpr-study run --dataset synthetic --notebooks 06_comparison --force

the study writes its figures/ and results/ (and runs/<label>/, the executed notebooks).
"""


#: ``vpr-study --help``'s description.


def parser(handlers: dict[str, Callable[[argparse.Namespace], int]]) -> argparse.ArgumentParser:
    """The ``vpr-study`` parser; ``handlers``: the function of each command (``eval``, ``run``,
    ``findings``)."""
    p = argparse.ArgumentParser(
        prog="vpr-study",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=version_text())
    sub = p.add_subparsers(dest="command", required=True)

    def command(name: str, text: str, epilog: str | None = None) -> argparse.ArgumentParser:
        sp = sub.add_parser(name, help=text, epilog=epilog, formatter_class=_HelpFormatter)
        sp.register("action", None, _Once)
        sp.register("action", "store", _Once)
        return sp

    def common(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--dataset", default="synthetic", help=" | ".join(DATASETS))
        sp.add_argument(
            "--root",
            type=_folder,
            default=None,
            help="dataset folder (real datasets; default: none, synthetic needs none)",
        )
        sp.add_argument(
            "--backbone",
            default="efficientnet_lite0",
            help="landmark descriptor (the list is read when help is shown)",
        )
        sp.add_argument(
            "--out",
            default=None,
            help="output root: figures/, results/, runs/ (and .cache/ unless "
            "VPR_CACHE_DIR is set) go under it; default $VPR_OUTPUT_DIR, else the "
            "project checkout holding the current folder (eval: its git-ignored user/), else "
            "the current folder",
        )
        sp.add_argument(
            "--step",
            type=int,
            default=None,
            help="nordland: keep every step-th place (default: all)",
        )
        sp.add_argument(
            "--tolerance",
            type=int,
            default=None,
            help="ground-truth tolerance (frames; default: the dataset's own)",
        )
        sp.add_argument(
            "--opt",
            action="append",
            metavar="KEY=VALUE",
            help="any other loader option, e.g. --opt query=winter (repeatable)",
        )

    e = command("eval", COMMANDS["eval"], EVAL_EPILOG)
    common(e)
    e.add_argument(
        "--study",
        action="store_true",
        help="write the study's committed outputs, figures/<label>/ and results/<label>/ of "
        "the checkout (make study's call), instead of user/",
    )
    e.add_argument(
        "--method",
        nargs="+",
        default=["dense"],
        help=f"one or more of: {', '.join(METHODS)}",
    )
    e.add_argument(
        "--label",
        default=None,
        help="output subfolder and the dataset's name in tables and titles: letters, digits, "
        "'_', '-', '.', '+' (default: the root folder's name for folder datasets, else the "
        "dataset name)",
    )
    e.add_argument(
        "--dim",
        type=int,
        default=paper.PROJECTION_DIM,
        help=f"descriptor dimension after the random projection (default {paper.PROJECTION_DIM})",
    )
    e.add_argument(
        "--seed", type=_int_at_least(0), default=0, help="seed of the random projection (default 0)"
    )
    e.add_argument(
        "--weights",
        default=None,
        help="the backbone's weights file (default: alexnet_conv3: $VPR_ALEXNET_WEIGHTS or the "
        "torch hub cache; EfficientNet-Lite: the shipped ImageNet weights)",
    )
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
        choices=("none", *WEIGHTING_OPTIONS, "both", "all"),
        help="(not in the paper) weight every method's match terms by how much better the "
        "query landmark matches this reference than the others (docs/DEFINITIONS.md); 'both': "
        "every method without and with contrast (two runs each), 'all': without and with each "
        f"weighting ({1 + len(WEIGHTING_OPTIONS)} runs each), and the paired differences; "
        "default none: Eq. (1) as the paper",
    )
    e.add_argument(
        "--normalise",
        default="none",
        choices=("none", *NORMALISE_OPTIONS, "both", "all"),
        help="(not in the paper) normalise every method's similarity matrix after Eq. (1) "
        "(docs/DEFINITIONS.md): query_batch z-scores over references and over the batch of "
        "queries (needs the query batch; also applied to peers), database subtracts each "
        "reference's mean similarity to its 10 nearest references (a single live query); "
        f"'all' (or 'both': both normalisations): every method without and with each "
        f"({1 + len(NORMALISE_OPTIONS)} runs each), and the paired differences",
    )
    e.add_argument(
        "--whiten",
        default="none",
        type=_whiten,
        metavar="K|none|both",
        help="(not in the paper) whiten every method's landmark descriptors on the reference "
        "database before Eq. (1), keeping K components (docs/DEFINITIONS.md; the queries "
        f"never enter the fit); 'both': every method without and with K={WHITEN_K}, and the "
        "paired differences; default none: the descriptors as extracted",
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
    e.add_argument(
        "--n-places",
        type=int,
        default=None,
        help="synthetic: number of places (default: the generator's)",
    )
    e.set_defaults(func=handlers["eval"])

    r = command("run", COMMANDS["run"], RUN_EPILOG)
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
        help="also run notebooks 03-07 on the real datasets beside the project (without "
        "either flag: on for the full synthetic study, off for --quick, --label or another "
        "dataset)",
    )
    r.add_argument(
        "--no-real-data",
        dest="real_data",
        action="store_false",
        default=argparse.SUPPRESS,  # the default is --real-data's (None): said there
        help="only the --dataset study (even for the full synthetic study)",
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

    f = command("findings", COMMANDS["findings"])
    f.add_argument("--labels", nargs="*", help="result folders (default: all but *_quick)")
    f.add_argument("--write", action="store_true", help="also write results/findings.md")
    f.add_argument("--out", default=None, help="output root (default: as for eval and run)")
    f.set_defaults(func=handlers["findings"])
    return p


def command_parser(parser: argparse.ArgumentParser, command: str) -> argparse.ArgumentParser:
    """The parser of subcommand ``command`` (its errors print its own usage)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices[command]
    return parser


def check_names(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Unknown methods and backbones, bad labels and loader options given twice are reported
    before any dataset is generated or read, with the subcommand's usage."""
    parser = command_parser(parser, args.command)
    if args.command == "eval":
        bad = [m for m in args.method if m not in METHODS]
        if bad:
            parser.error(f"unknown method(s) {bad}; valid: {', '.join(METHODS)}")
        twice = sorted({m for m in args.method if args.method.count(m) > 1})
        if twice:
            parser.error(f"--method lists {', '.join(twice)} twice; name each method once")
        if args.protocol == "multi_match" and args.n_bootstrap > 0:
            parser.error(
                "--protocol multi_match ranks all query-reference pairs together, so it has no "
                "bootstrap over queries: add --n-bootstrap 0"
            )
        if args.study and args.out:
            parser.error(
                "--study writes the study's figures/ and results/ of the checkout, --out "
                f"{args.out} another root: give one of them"
            )
        try:
            settings.scheduler_timeout()
        except ValueError as exc:
            parser.error(str(exc))
    if getattr(args, "label", None) is not None:
        try:
            outputs.check_label(args.label)
        except ValueError as exc:
            parser.error(f"--{exc}")
    if args.command in ("eval", "run"):
        try:
            dataset_options(args)
        except ValueError as exc:
            parser.error(str(exc))
    if getattr(args, "backbone", None) is None:
        return
    from vpr_core import Encoder  # a command: the pipeline is loaded now

    try:
        Encoder(args.backbone)  # the backbone spec parsed (its weights are looked up later)
    except (TypeError, ValueError) as exc:
        parser.error(str(exc))
