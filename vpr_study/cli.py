"""Command line: ``vpr-study eval`` (methods on one dataset), ``vpr-study run`` (the study) and
``vpr-study findings`` (the paper's claims against the results); examples: ``vpr-study --help``."""

from __future__ import annotations

import argparse
import errno
import itertools
import os
import shutil
import signal
import sys
import textwrap
import time
from pathlib import Path

from vpr_core import paths, settings
from vpr_core.baselines import find_vprbench_peers, peer_from_descriptors, peer_from_matrix
from vpr_core.datasets import load_dataset
from vpr_core.datasets.ground_truth import ground_truth_text
from vpr_core.evaluation import (
    compact_text,
    compare,
    compare_pairs,
    ground_truth_coverage,
)
from vpr_core.evaluation.spec import check_bootstrap_memory
from vpr_core.matching import SPATIAL_OPTIONS, WEIGHTING_OPTIONS
from vpr_core.pipeline import peer_result, run_method
from vpr_core.utils import configure_logging, short_hash, tune_allocator
from vpr_core.viz import plot_pr_curves
from vpr_core.viz.base import save_all
from vpr_study.arguments import check_names, dataset_options, parser
from vpr_study.findings import findings_markdown, result_labels
from vpr_study.runner import run_study, study_datasets

INTERRUPTED = "interrupted; cached work is kept, rerun to resume"


def say(text: str, width: int) -> None:
    """Print prose wrapped to the terminal's ``width`` (tables are sized by compact_text)."""
    print("\n".join(textwrap.fill(p, width) if p else p for p in text.split("\n")))


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
    dataset = load_dataset(args.dataset, root=args.root, **dataset_options(args))
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
        options=dataset_options(args),
        pooling=args.pooling,
        shortlist=args.shortlist,
        force=args.force,
        jobs=args.jobs or os.cpu_count() or 1,
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
    """The ``vpr-study`` parser, its commands bound to this module's handlers."""
    return parser({"eval": cmd_eval, "run": cmd_run, "findings": cmd_findings})


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
    check_names(parser, args)
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
