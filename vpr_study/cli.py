"""Command line: ``vpr-study eval`` (methods on one dataset), ``vpr-study run`` (the study) and
``vpr-study findings`` (the paper's claims against the results); examples: ``vpr-study --help``."""

from __future__ import annotations

import argparse
import errno
import itertools
import logging
import os
import pickle
import shutil
import signal
import sys
import textwrap
import threading
import time
import warnings
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path

import pandas as pd

from vpr_core import (
    NORMALISATIONS,
    SPATIAL_OPTIONS,
    WEIGHTINGS,
    VPRWarning,
    checks,
    compact,
    compare,
    compare_pairs,
    load_dataset,
    normalise_result,
    paths,
    run_method,
    settings,
    utils,
)
from vpr_study.arguments import check_names, command_parser, dataset_options, given_once, parser
from vpr_study.choices import WHITEN_K
from vpr_study.cluster import DaskExecutor
from vpr_study.findings import findings_document, result_labels
from vpr_study.peers import (
    find_vprbench_peers,
    peer_from_descriptors,
    peer_from_matrix,
    peer_result,
)
from vpr_study.runner import run_study, study_datasets
from vpr_study.viz import plot_pr_curves
from vpr_study.viz.base import save_all

from . import outputs

__all__ = [
    "HEADLINE",
    "INTERRUPTED",
    "PIPED_WIDTH",
    "PROGRESS_INTERVAL_S",
    "build_parser",
    "changed_settings",
    "cmd_eval",
    "cmd_findings",
    "cmd_run",
    "default_label",
    "eval_settings",
    "eval_stem",
    "fit_text",
    "format_table",
    "main",
    "output_width",
    "say",
    "StageLines",
]

INTERRUPTED = "interrupted; cached work is kept, rerun to resume"


def say(text: str, width: int) -> None:
    """Print prose wrapped to the terminal's ``width`` (tables: :func:`fit_text`); a word
    longer than the width (a path) stands whole on its own line."""
    wrap = textwrap.TextWrapper(width, break_long_words=False, break_on_hyphens=False)
    print("\n".join(wrap.fill(p) if p else p for p in text.split("\n")))


#: The columns a narrow terminal shows first, as :func:`fit_text` orders them: AUC and R@1
#: with their paired differences (always shown, in further blocks when the width needs them),
#: then R@100P, its difference and R@5 where they fit; a ``note`` (a run identical to
#: another) is always shown.
HEADLINE = ("AUC", "dAUC", "R@1", "dR@1", "note")
_PRIORITY = (*HEADLINE, "R@100P", "dR@100P", "R@5")


def _metric(column: str) -> str:
    return column.split()[0].split("(")[0] if column.strip() else column  # "AUC(ratio)"


def _block(view: pd.DataFrame, columns: list[str], width: int) -> list[str]:
    """The rows of ``view`` with ``columns`` side by side (labels left, values right), or, for
    one column too wide beside the labels, one wrapped ``label  value`` line per row."""
    labels = [str(i) for i in view.index]
    label_w = max(len(str(view.index.name or "")), *map(len, labels))
    widths = {c: max(len(c), *(len(v) for v in view[c])) for c in columns}
    if len(columns) == 1 and label_w + 2 + widths[columns[0]] > width:
        col = columns[0]
        lines = [col]
        for label, value in zip(labels, view[col], strict=True):
            if value:
                lines += textwrap.wrap(
                    f"{label}  {value}", width, initial_indent="  ", subsequent_indent="    "
                )
        return lines
    head = str(view.index.name or "").ljust(label_w) + "".join(
        "  " + c.rjust(widths[c]) for c in columns
    )
    rows = [
        label.ljust(label_w) + "".join("  " + view.at[i, c].rjust(widths[c]) for c in columns)
        for label, i in zip(labels, view.index, strict=True)
        if any(view.at[i, c] for c in columns)  # a block of differences: not the baseline's
    ]
    return [line.rstrip() for line in (head, *rows)]


def fit_text(
    view: pd.DataFrame, width: int, keep: tuple[str, ...] | None = None, wide: bool = False
) -> str:
    """``view`` (strings; the index names the rows) as text with no line over ``width``.

    Columns go side by side while they fit; a column of ``keep`` (metric names such as
    ``"R@1"``, ``"dAUC"``; None: every column) that does not fit starts a further block of the
    same rows; the other columns are shown only where they fit, the ones left out named in a
    last line. ``wide``: every column in one block, however long the lines.
    """
    columns = sorted(
        view.columns,
        key=lambda c: _PRIORITY.index(_metric(c)) if _metric(c) in _PRIORITY else len(_PRIORITY),
    )
    if wide:
        return "\n".join(_block(view, list(columns), sys.maxsize))
    labels = [str(view.index.name or ""), *map(str, view.index)]
    label_w = max(map(len, labels))
    blocks: list[list[str]] = [[]]
    left: list[str] = []
    used = label_w
    for col in columns:
        w = 2 + max(len(col), *(len(v) for v in view[col]))
        kept = keep is None or _metric(col) in keep
        if not left and used + w <= width:
            blocks[-1].append(col)
            used += w
        elif kept:
            blocks.append([col])
            used = label_w + w
        else:
            left.append(col)
    lines: list[str] = []
    for cols in filter(None, blocks):
        lines += ([""] if lines else []) + _block(view, cols, width)
    if left:
        note = f"not shown at {width} columns: {', '.join(left)} (--wide: all; the CSV)"
        lines += textwrap.wrap(note, width)
    return "\n".join(lines)


def format_table(rows: list[dict], width: int = sys.maxsize) -> str:
    """Plain-text table of dict rows (their first key names the rows) within ``width``."""
    if not rows:
        return "(no rows)"
    view = pd.DataFrame(rows).fillna("").astype(str)
    view = view.set_index(view.columns[0])
    return fit_text(view, width)


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


def _cost_rows(
    table, results: list, computed: dict[str, bool], wall: dict[str, float]
) -> tuple[list[dict], list[dict]]:
    """``(ours, peers)``: each run's landmark count and costs (not in the committed CSV).

    Ours are the seconds recorded when each stage was computed (a stage read from the cache
    keeps the seconds of the run that computed it), ``wall s`` this call's seconds for the
    run; ``measured`` says ``this run`` when this
    call computed the run's similarity matrix (``computed``), ``earlier run`` when it read it
    from the cache. Peers: VPR-Bench's stored encode and match times, from its machine.
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
        source = "this run" if computed.get(r.label, True) else "earlier run"
        ours.append(
            {"method": r.label, **cells, "wall s": f"{wall[r.label]:.1f}", "measured": source}
        )
    return ours, peers


def _matrix_entries() -> dict[str, tuple[int, int, int]]:
    """``{file: (inode, mtime ns, size)}`` of the cached similarity matrices (``results/`` of
    the cache): a run that wrote or rewrote one computed its matrix in this call."""
    folder = paths.cache_root() / "results"
    found = {}
    for path in folder.rglob("*.npz") if folder.is_dir() else []:
        try:
            st = path.stat()
        except OSError:  # removed meanwhile (another run healing it)
            continue
        found[str(path)] = (st.st_ino, st.st_mtime_ns, st.st_size)
    return found


#: Columns of ``eval``'s text when stdout is piped or redirected and ``$COLUMNS`` is unset: a
#: log keeps each table's rows whole instead of wrapping them at a terminal's default 80.
PIPED_WIDTH = 160


def output_width() -> int:
    """The columns ``eval`` fits its text to: ``$COLUMNS``, else the terminal's, else (stdout
    piped or redirected) :data:`PIPED_WIDTH`."""
    if os.environ.get("COLUMNS", "").strip().isdigit() or sys.stdout.isatty():
        return shutil.get_terminal_size().columns
    return PIPED_WIDTH


#: Outside a terminal: a line when each stage of ``eval`` starts, and one every this many
#: seconds while it runs (:class:`StageLines`).
PROGRESS_INTERVAL_S = 10.0


class StageLines:
    """Progress without a terminal: one ``[vpr-study] <stage>`` line on stderr when a stage
    starts and a ``still running`` line every :data:`PROGRESS_INTERVAL_S` seconds while it
    runs, the only progress lines then (the stage's own progress lines are off: piped output
    does not mix the two); nothing on a terminal (its progress bars show live)."""

    def __init__(self) -> None:
        self.enabled = not getattr(sys.stderr, "isatty", lambda: False)()

    def _say(self, text: str) -> None:
        print(f"[vpr-study] {text}", file=sys.stderr, flush=True)

    @contextmanager
    def stage(self, what: str, detail: str = "") -> Iterator[None]:
        """Within the block, stage ``what`` runs (its line, with ``detail``, printed first)."""
        if not self.enabled:
            yield
            return
        t0 = time.perf_counter()
        self._say(what + detail)
        stop = threading.Event()

        def beat() -> None:
            while not stop.wait(PROGRESS_INTERVAL_S):
                self._say(f"{what}: still running, {time.perf_counter() - t0:.0f} s")

        thread = threading.Thread(target=beat, name="vpr-study-progress", daemon=True)
        thread.start()
        saved = os.environ.get("TQDM_DISABLE")
        os.environ["TQDM_DISABLE"] = "1"  # vpr_core.utils.progress: these lines say it
        try:
            yield
        finally:
            if saved is None:
                os.environ.pop("TQDM_DISABLE", None)
            else:
                os.environ["TQDM_DISABLE"] = saved
            stop.set()
            thread.join()


#: ``eval`` arguments that do not change a number (where and how the run is done).
_NOT_SETTINGS = ("command", "func", "out", "label", "scheduler", "wide", "study")


def eval_settings(args: argparse.Namespace) -> dict:
    """Every ``eval`` argument that can change a number (methods, peers, protocol, shortlist,
    pooling, backbone, loader options, ...), unset ones left out; file arguments (root, peers,
    weights) as absolute paths. Hashed into the output file names."""
    found = {}
    for key, value in sorted(vars(args).items()):
        if key in _NOT_SETTINGS or key.startswith("_") or value is None or value is False:
            continue
        if value == []:
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


#: Settings the dataset line of a PR figure already names (:func:`vpr_study.viz.dataset_line`).
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
        parts.append(utils.short_hash(files, 8))
    stem = "_".join([f"eval_{label}", "+".join(args.method), *parts])
    return "".join(c if c.isalnum() or c in "-_.+=" else "_" for c in stem)


def default_label(name: str) -> str:
    """A dataset's name as an output label (:func:`vpr_study.outputs.check_label`): each other
    character becomes ``_`` (a folder dataset is named by its folder, e.g. ``my photos``)."""
    label = "".join(c if c.isalpha() or c.isdecimal() or c in "_-.+" else "_" for c in name)
    return label.lstrip(".")[: outputs.MAX_LABEL_BYTES // 4] or "dataset"


def cmd_eval(args: argparse.Namespace) -> int:
    checks.check_bootstrap_memory(args.n_bootstrap, "--n-bootstrap")
    utils.tune_allocator()  # process-wide, here at the boundary: crop features ~1.7x faster
    lines = StageLines()
    with lines.stage(f"loading {args.dataset}"):
        dataset = load_dataset(args.dataset, root=args.root, **dataset_options(args))
    label = outputs.check_label(args.label or default_label(dataset.name))
    n_gt, n_q = dataset.queries_with_gt
    truth = dataset.truth_text
    loader = "" if dataset.name == args.dataset else f" (loader {args.dataset})"
    width = output_width()
    say(
        f"dataset: {label}{loader}  queries={len(dataset.query_paths)} "
        f"references={len(dataset.reference_paths)}  {truth}",
        width,
    )
    print(f"queries with ground truth: {n_gt} of {n_q}")
    mode = "exhaustive" if args.shortlist is None else f"shortlist k={args.shortlist}"
    scheduler = args.scheduler or settings.dask_scheduler()
    spatial = [None, *SPATIAL_OPTIONS] if args.spatial == "both" else [args.spatial]
    choices: dict[str, list[str | None]] = {
        "none": [None],
        "both": [None, "contrast"],  # without and with the workbench's weighting
        "all": [None, *WEIGHTINGS],
    }
    weighting = choices.get(args.weighting, [args.weighting])
    every = [None, *NORMALISATIONS]  # both normalisations, and without
    norms: dict[str, list[str | None]] = {"none": [None], "both": every, "all": every}
    normalise = norms.get(args.normalise, [args.normalise])
    whitening: list[int | None] = [None, WHITEN_K] if args.whiten == "both" else [None]
    if args.whiten not in ("none", "both"):
        whitening = [int(args.whiten)]
    results, computed, wall, run_of = [], {}, {}, {}
    todo = list(itertools.product(args.method, spatial, weighting, normalise, whitening))
    with ExitStack() as stack:  # a Dask executor is closed however the runs end
        executor = stack.enter_context(DaskExecutor(scheduler)) if scheduler else None
        for n, (m, s, w, z, h) in enumerate(todo, 1):
            named = (("whiten", h), ("spatial", s), ("weighting", w), ("normalise", z))
            options = ", ".join(f"{k} {v}" for k, v in named if v)
            before, t0 = _matrix_entries(), time.perf_counter()
            with lines.stage(
                f"{m}{f' ({options})' if options else ''} on {label}",
                f" ({n} of {len(todo)}): landmarks, features, Eq. (1) matrix, metrics",
            ):
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
                    executor=executor,
                    n_bootstrap=args.n_bootstrap,
                    protocol=args.protocol,
                    spatial=s,
                    weighting=w,
                    normalise=z,
                    whiten=h,
                )
            results.append(r)
            run_of[m, s, w, z, h] = r
            computed[r.label] = _matrix_entries() != before
            wall[r.label] = time.perf_counter() - t0
    if args.peers or args.peer_dataset or args.peer:
        with lines.stage("peers"):
            peers = _peer_results(args, dataset) + _user_peers(args, dataset)
            if "query_batch" in normalise:  # a peer's matrix normalised the same way
                peers += [normalise_result(p, "query_batch") for p in peers]
            results += peers
        labels = [r.label for r in results]
        twice = sorted({x for x in labels if labels.count(x) > 1})
        if twice:  # compare() would advise label=..., which a command line cannot pass
            raise ValueError(
                f"--peer: {', '.join(map(repr, twice))} names both a peer and a method (or "
                f"another peer) of this run; give the peer a name of its own, e.g. --peer "
                f"{twice[0]}-peer=PATH"
            )
    say(
        f"backbone: {results[0].encoder.get('backbone')} "
        f"(weights: {results[0].encoder.get('weights')}, pooling: {args.pooling}, {mode}; "
        f"95% bootstrap intervals over queries, {args.n_bootstrap} resamples)",
        width,
    )
    if len(results) > 1:
        say(
            f"paired bootstrap (same resampled queries): dAUC and dR@1 = method - "
            f"{results[0].label}; higher or lower only where the interval excludes 0, else "
            "inconclusive",
            width,
        )
    with lines.stage(f"comparing {len(results)} runs ({args.n_bootstrap} bootstrap resamples)"):
        table = compare(results, n_bootstrap=args.n_bootstrap)
    print(fit_text(compact(table), width, HEADLINE, wide=args.wide))
    ours, peers = _cost_rows(table, results, computed, wall)
    say(
        "cost (lm: landmarks, feat: features), seconds recorded when each stage was computed "
        "(wall s: this call's); measured: 'this run' where this call computed the run, "
        "'earlier run' where it read it from the cache:",
        width,
    )
    print(format_table(ours, width))
    if peers:
        say("peers' costs as stored with them (VPR-Bench: its machine; not comparable):", width)
        print(format_table(peers, width))
    stem = eval_stem(args, label)
    readable, _ = changed_settings(args)
    shown = [f"{k.replace('_', ' ')} {v}" for k, v in readable.items() if k not in _IN_DATASET_LINE]
    title = f"vpr-study eval on {label}" + (f" ({', '.join(shown)})" if shown else "")
    with lines.stage("plotting"):
        fig = plot_pr_curves(results, title=title)
    items: list = [(stem, table), (stem, fig)]

    def paired(suffix: str, heading: str, pairs: list) -> None:
        """Each pair's paired differences, shown under ``heading`` and saved as ``suffix``."""
        table = compare_pairs(pairs, n_bootstrap=args.n_bootstrap)
        say(f"\n(not in the paper) {heading}:", width)
        print(fit_text(compact(table), width, HEADLINE, wide=args.wide))
        items.append((f"{stem}_{suffix}", table))

    product = itertools.product
    if args.spatial == "both":
        paired(
            "geometry",
            "geometry-aware score, each method with minus without",
            [
                (run_of[m, None, w, z, h], run_of[m, s, w, z, h])
                for m, w, z, h in product(args.method, weighting, normalise, whitening)
                for s in SPATIAL_OPTIONS
            ],
        )
    if args.weighting in ("both", "all"):
        paired(
            "weighting",
            "database weighting, each method with minus without",
            [
                (run_of[m, s, None, z, h], run_of[m, s, w, z, h])
                for m, s, z, h in product(args.method, spatial, normalise, whitening)
                for w in weighting[1:]
            ],
        )
    if args.normalise in ("both", "all"):
        paired(
            "normalise",
            "normalisation, each method with minus without (query_batch needs the query batch)",
            [
                (run_of[m, s, w, None, h], run_of[m, s, w, z, h])
                for m, s, w, h in product(args.method, spatial, weighting, whitening)
                for z in NORMALISATIONS
            ],
        )
    if args.whiten == "both":
        paired(
            "whiten",
            "whitening on the reference database, each method with minus without",
            [
                (run_of[m, s, w, z, None], run_of[m, s, w, z, WHITEN_K])
                for m, s, w, z in product(args.method, spatial, weighting, normalise)
            ],
        )
    with lines.stage("writing the figure and tables"):
        written = save_all(items, label, out=args.out)
    root = outputs.figures_root() if args.out is None else Path(args.out).expanduser().resolve()
    say(f"wrote under {root}:", width)
    for folder in dict.fromkeys(p.parent for p in written):
        print(f"{folder.relative_to(root)}/")
        print("\n".join(f"  {p.name}" for p in written if p.parent == folder))
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
        options=dataset_options(args),
        pooling=args.pooling,
        shortlist=args.shortlist,
        force=args.force,
        jobs=args.jobs or os.cpu_count() or 1,
    )
    return 0


def cmd_findings(args: argparse.Namespace) -> int:
    labels = args.labels or result_labels(["synthetic", *study_datasets()])
    text = findings_document(labels)
    print(text)
    if args.write:
        out = outputs.results_dir() / "findings.md"
        out.write_text(text + "\n")
        print(f"wrote {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``vpr-study`` parser, its commands bound to this module's handlers."""
    return parser({"eval": cmd_eval, "run": cmd_run, "findings": cmd_findings})


class _Terminated(Exception):
    """SIGTERM, turned into an exception so that it unwinds like Ctrl-C."""


def _terminated(signum, frame):
    raise _Terminated()


class _EachOnce(logging.Filter):
    """Pass each distinct warning record once (a notice raised by a run and again by the
    comparison of its runs prints one line)."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno < logging.WARNING:
            return True
        text = record.getMessage()
        if text in self.seen:
            return False
        self.seen.add(text)
        return True


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning that is not a logged notice, as one line without its source line."""
    print(f"vpr-study: {category.__name__}: {message}", file=sys.stderr)


@contextmanager
def _notices_once() -> Iterator[None]:
    """Within the block each notice prints once: a :class:`~vpr_core.notices.VPRWarning` is
    already logged by ``notice()`` (so Python does not print it again, with its source line),
    a repeated log warning is dropped, and any other warning prints as one line."""
    logger = logging.getLogger("vpr_core")
    once = _EachOnce()
    logger.addFilter(once)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", VPRWarning)
            warnings.showwarning = _show_warning
            yield
    finally:
        logger.removeFilter(once)


def _writes_to(args: argparse.Namespace):
    """Where a command's figures and tables go: ``eval`` under the checkout's ``user/`` unless
    ``--study`` (the study's ``figures/`` and ``results/``) or ``--out``; ``run`` and
    ``findings``: the study's folders."""
    if args.command == "eval" and not args.study:
        return paths.using_output_root(None)  # outputs.figures_root: user/ of the checkout
    return outputs.study_outputs()


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``vpr-study``; returns the exit code (2 on a user error, 130 on Ctrl-C)."""
    parser = build_parser()
    args = given_once(parser.parse_args(argv))
    prog = command_parser(parser, args.command).prog  # "vpr-study eval"
    previous = signal.getsignal(signal.SIGTERM)
    signal.signal(signal.SIGTERM, _terminated)
    check_names(parser, args)
    utils.configure_logging()
    try:
        # --out applies to this command only; the runner hands it to its kernels
        with paths.using_output_root(args.out or None), _writes_to(args), _notices_once():
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
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2
    except (
        ValueError,
        TypeError,
        LookupError,
        RuntimeError,
        ImportError,
        ArithmeticError,
        AttributeError,
        EOFError,
        MemoryError,
        pickle.UnpicklingError,
    ) as exc:
        # a data file can raise any of these; ours name the file, a library's is named by type
        ours = isinstance(exc, (ValueError, TypeError, RuntimeError, ImportError, IndexError))
        text = str(exc) if ours else f"{type(exc).__name__}: {exc}"
        text = text if len(text) <= 2000 else text[:2000] + " ... (message cut at 2,000 characters)"
        print(f"{prog}: error: {text}", file=sys.stderr)
        return 2
    finally:
        signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
