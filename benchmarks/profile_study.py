"""Where the seconds of ``make study`` go: per dataset label, notebook and category, cold and warm.

Runs the study as ``make study`` does (the runner's notebooks on ``synthetic``, notebooks 03-07 on
every real dataset of :func:`vpr_study.runner.study_datasets`, then the closing ``vpr-study eval``)
into a temporary output root and an empty temporary cache, twice: cold, then warm (same cache).

Each notebook runs as the runner runs it (papermill in a child process, the runner's parameters
and kernel environment) from a copy with one cell added first (starts ``cProfile`` without
built-ins) and one last (dumps the profile). Each profiled second goes to the innermost
categorised function on its call path (:func:`categorise`: by module, e.g. ``vpr_core/labels/``
is labelling, matplotlib is plotting); the parts are scaled to the seconds measured inside the
kernel (cProfile's overhead shared out pro rata). ``kernel start`` is the child's wall time less
the time inside the kernel (process, papermill, kernel start, saving the notebook); ``imports``
the notebook's imports; ``other`` what no category claims (pipeline glue, pandas, I/O). The
``TOTAL`` rows are wall times.

Usage::

    .venv/bin/python benchmarks/profile_study.py                     # the full study, cold + warm
    .venv/bin/python benchmarks/profile_study.py --quick --datasets synthetic \\
        --notebooks 03_landmark_selection --no-eval --csv /tmp/p.csv --note "loaded machine"

Writes ``results/benchmarks/study_profile.csv`` (``--csv``): one row per (label, notebook,
category) with ``cold_s`` and ``warm_s``, a ``TOTAL`` category row per notebook (its wall
time) and per label, and the study's total; ``--note`` goes into the comment line at the top.
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import json
import os
import platform
import pstats
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: Categories, first match wins: (name, path fragments of the function's file).
CATEGORIES: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("synthetic generation", ("vpr_core/datasets/synthetic/",)),
    ("Edge Boxes", ("vpr_core/landmarks/edge_boxes.py",)),
    ("landmark selection", ("vpr_core/landmarks/",)),
    ("crop features", ("vpr_core/features/", "vpr_core/backbones/")),
    ("labelling", ("vpr_core/labels/",)),
    ("matching", ("vpr_core/matching/", "vpr_core/engine/")),
    ("bootstrap", ("vpr_core/evaluation/bootstrap.py",)),
    ("plotting", ("vpr_core/viz/", "matplotlib/", "matplotlib_inline/", "PIL/")),
    ("cache I/O", ("vpr_core/pipeline/cache.py",)),
    ("image reading", ("vpr_core/datasets/images.py",)),
    ("imports", ("<frozen importlib._bootstrap",)),
)
NAMES = [c[0] for c in CATEGORIES]
ORDER = ["kernel start", *NAMES, "other", "TOTAL"]


def category(key: tuple[str, int, str]) -> str | None:
    """The category of a pstats function key ``(file, line, name)``, or None."""
    file = key[0].replace(os.sep, "/")
    for name, fragments in CATEGORIES:
        if any(f in file for f in fragments):
            return name
    return None


def categorise(stats: pstats.Stats, rounds: int = 100) -> dict[str, float]:
    """Profiled seconds per category, each second to the innermost categorised caller.

    A categorised function's own time is its category's; an uncategorised function (numpy,
    torch, pandas, a module's top level) inherits its callers' categories in proportion to the
    cumulative time each caller spent in it (gprof's rule), iterated over the call graph. So a
    nested category is not counted twice and the parts add up to the profiled time; what has
    no categorised caller is ``other``.
    """
    raw = stats.stats  # type: ignore[attr-defined]
    keys = sorted(raw, key=lambda k: -raw[k][3])  # callers first: few rounds converge
    cat = {k: category(k) for k in keys}
    share: dict = {k: ({cat[k]: 1.0} if cat[k] else {None: 1.0}) for k in keys}
    for _ in range(rounds):
        changed = 0.0
        for k in keys:
            if cat[k] is not None:
                continue
            callers = raw[k][4]
            total = sum(edge[3] for g, edge in callers.items() if g in share and g != k)
            if total <= 0:
                continue
            new: dict = defaultdict(float)
            for g, edge in callers.items():
                if g == k or g not in share:
                    continue
                for c, f in share[g].items():
                    new[c] += f * edge[3] / total
            changed += sum(abs(new[c] - share[k].get(c, 0.0)) for c in set(new) | set(share[k]))
            share[k] = dict(new)
        if changed < 1e-9:
            break
    out: dict[str, float] = defaultdict(float)
    for k in keys:
        for c, f in share[k].items():
            out[c or "other"] += raw[k][2] * f
    return dict(out)


FIRST_CELL = """\
import cProfile as _vpr_cprofile, time as _vpr_time
_vpr_t0 = _vpr_time.perf_counter()
_vpr_profile = _vpr_cprofile.Profile(builtins=False)
_vpr_profile.enable()
"""

LAST_CELL = """\
_vpr_profile.disable()
_vpr_profile.dump_stats({prof!r})
import json as _vpr_json, sys as _vpr_sys
with open({info!r}, "w") as _vpr_f:
    _vpr_json.dump({{"kernel_s": _vpr_time.perf_counter() - _vpr_t0,
                    "modules": {{m: getattr(_vpr_sys.modules.get(m), "__file__", None)
                                for m in ("vpr_core", "vpr_study")}}}}, _vpr_f)
"""


def instrumented(nb: Path, work: Path, prof: Path, info: Path) -> Path:
    """A copy of notebook ``nb`` under ``work`` with the profiling cells first and last."""
    import nbformat

    book = nbformat.read(nb, as_version=4)
    first = nbformat.v4.new_code_cell(FIRST_CELL)
    last = nbformat.v4.new_code_cell(LAST_CELL.format(prof=str(prof), info=str(info)))
    for cell in (first, last):
        cell.metadata["tags"] = ["profile_study"]
    book.cells = [first, *book.cells, last]
    out = work / nb.name
    nbformat.write(book, out)
    return out


#: The runner's child process before notebooks shared a kernel: papermill on one notebook.
PAPERMILL = (
    "import json, sys; import papermill as pm; "
    "pm.execute_notebook(**json.loads(sys.argv[1]), stdout_file=sys.stdout, stderr_file=sys.stderr)"
)


def _child(command: list[str], env: dict, what: str) -> None:
    done = subprocess.run(
        command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    if done.returncode != 0:
        raise RuntimeError(f"{what} failed:\n{done.stderr[-3000:]}")


def run_label(
    notebooks: list[Path], params: dict, runs: Path, work: Path, env: dict, shared: bool
) -> dict[str, dict[str, float]]:
    """Execute one label's instrumented notebooks as the runner does: all in one kernel
    (``shared``, :mod:`vpr_study.session`; the kernel's start and stop are the first
    notebook's) or one papermill child per notebook; ``{notebook: {category: seconds}}``."""
    copies = [
        instrumented(nb, work, work / f"{nb.stem}.prof", work / f"{nb.stem}.json")
        for nb in notebooks
    ]
    jobs = [
        {"input_path": str(c), "output_path": str(runs / c.name), "parameters": params}
        for c in copies
    ]
    walls: dict[str, float] = {}
    if shared:
        status = work / "status.jsonl"
        request = {
            "notebooks": jobs,
            "cwd": str(notebooks[0].parent),
            "kernel": "python3",
            "progress_bar": False,
            "status": str(status),
        }
        t0 = time.time()
        _child([sys.executable, "-m", "vpr_study.session", json.dumps(request)], env, str(runs))
        t1 = time.time()
        lines = [json.loads(x) for x in status.read_text().splitlines()]
        started = {x["notebook"]: x["started"] for x in lines if "started" in x}
        ended = {x["done"]: x["ended"] for x in lines if "done" in x}
        walls = {nb.stem: ended[nb.stem] - started[nb.stem] for nb in notebooks}
        walls[notebooks[0].stem] += t1 - t0 - sum(walls.values())
    else:
        for nb, job in zip(notebooks, jobs, strict=True):
            request = {**job, "cwd": str(nb.parent), "kernel_name": "python3"}
            t0 = time.perf_counter()
            request["progress_bar"] = False
            _child([sys.executable, "-c", PAPERMILL, json.dumps(request)], env, nb.name)
            walls[nb.stem] = time.perf_counter() - t0
    out = {}
    for nb in notebooks:
        info = work / f"{nb.stem}.json"
        found = json.loads(info.read_text())
        check_modules(found["modules"], nb.name)
        info.write_text(json.dumps({**found, "wall_s": walls[nb.stem]}))  # re-analysable
        out[nb.stem] = split(
            pstats.Stats(str(work / f"{nb.stem}.prof")), walls[nb.stem], found["kernel_s"]
        )
    return out


def split(stats: pstats.Stats, wall: float, inside: float) -> dict[str, float]:
    """Categories + ``kernel start`` (wall - inside) + ``other`` + ``TOTAL`` (wall)."""
    out = categorise(stats)
    # the profile's own overhead: the kernel's measured seconds share out pro rata
    scale = inside / max(sum(out.values()), 1e-9)
    out = {c: v * scale for c, v in out.items()}
    out["kernel start"] = max(wall - inside, 0.0)
    out["TOTAL"] = wall
    return out


def check_modules(modules: dict[str, str | None], where: str) -> None:
    """Refuse a run whose packages do not come from this checkout (``PYTHONPATH``)."""
    for name, file in modules.items():
        if file is not None and not Path(file).resolve().is_relative_to(ROOT):
            raise RuntimeError(
                f"{where}: {name} imported from {file}, not from {ROOT}; run with PYTHONPATH={ROOT}"
            )


EVAL_CODE = """\
import cProfile, json, sys, time
t0 = time.perf_counter()
p = cProfile.Profile(builtins=False)
p.enable()
import vpr_study, vpr_core
from vpr_study.cli import main
rc = main(sys.argv[3:])
p.disable()
p.dump_stats(sys.argv[1])
json.dump({"kernel_s": time.perf_counter() - t0, "rc": rc,
           "modules": {"vpr_core": vpr_core.__file__, "vpr_study": vpr_study.__file__}},
          open(sys.argv[2], "w"))
sys.exit(rc)
"""


def run_eval(args: list[str], work: Path, env: dict) -> dict[str, float]:
    """``vpr-study eval ARGS`` in a child process, profiled like a notebook."""
    prof, info = work / "eval.prof", work / "eval.json"
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", EVAL_CODE, str(prof), str(info), *args],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"vpr-study eval {' '.join(args)} failed:\n{done.stderr[-3000:]}")
    found = json.loads(info.read_text())
    check_modules(found["modules"], "eval")
    info.write_text(json.dumps({**found, "wall_s": wall}))
    return split(pstats.Stats(str(prof)), wall, found["kernel_s"])


def study_plan(args: argparse.Namespace) -> list[tuple[str, list[Path], dict]]:
    """``[(label, notebooks, parameters)]`` as ``run_study`` would execute them."""
    from vpr_study import runner

    options = {"n_places": args.n_places} if args.n_places else {}
    plan = [
        (
            runner.output_label("synthetic", args.quick),
            runner.notebook_paths(args.notebooks),
            runner.notebook_parameters("synthetic", quick=args.quick, options=options),
        )
    ]
    for name, spec in runner.study_datasets().items():
        selected = [
            nb
            for nb in runner.notebook_paths(args.notebooks)
            if nb.stem in runner.REAL_DATA_NOTEBOOKS
        ]
        params = runner.notebook_parameters(
            spec["dataset"],
            spec["root"],
            quick=args.quick,
            label=name,
            options=spec.get("options", {}),
            pooling=spec.get("pooling", "crop"),
        )
        plan.append((params["label"], selected, params))
    if args.datasets:
        known = [label for label, _, _ in plan]
        bad = [d for d in args.datasets if d not in known]
        if bad:
            raise SystemExit(f"--datasets {bad} unknown; this run has: {', '.join(known)}")
        plan = [p for p in plan if p[0] in args.datasets]
    return [p for p in plan if p[1]]


def one_pass(plan, args, out_root: Path, cache: Path, work: Path, tag: str) -> dict:
    """Run the plan once; ``{(label, notebook): {category: seconds}}``."""
    from vpr_core import settings
    from vpr_study.execution import kernel_settings

    os.environ[settings.OUTPUT_ENV] = str(out_root)
    os.environ[settings.CACHE_ENV] = str(cache)
    env = settings.child_environment(kernel_settings())
    env.setdefault("PYTHONPATH", str(ROOT))
    results: dict = {}
    for label, notebooks, params in plan:
        runs = out_root / "runs" / label
        runs.mkdir(parents=True, exist_ok=True)
        where = work / tag / label
        where.mkdir(parents=True, exist_ok=True)
        rows = run_label(notebooks, params, runs, where, env, args.kernels == "shared")
        for stem, row in rows.items():
            results[(label, stem)] = row
            print(f"{tag:4s} {label:22s} {stem:30s} {row['TOTAL']:7.1f} s", flush=True)
    if not args.no_eval:
        cli = ["eval", "--dataset", "synthetic", "--method", "dense", "classical"]
        if args.quick or args.n_places:
            cli += ["--n-places", str(args.n_places or 8)]
        where = work / tag / "eval"
        where.mkdir(parents=True, exist_ok=True)
        results[("synthetic", "vpr-study eval")] = row = run_eval(cli, where, env)
        print(
            f"{tag:4s} {'synthetic':22s} {'vpr-study eval':30s} {row['TOTAL']:7.1f} s", flush=True
        )
    return results


def write_csv(path: Path, cold: dict, warm: dict, note: str) -> None:
    """The table: per (label, notebook, category) cold and warm seconds, then totals."""
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = []
    per_label: dict = defaultdict(lambda: [0.0, 0.0])
    per_category: dict = defaultdict(lambda: [0.0, 0.0])
    for key in cold:
        label, notebook = key
        for c in ORDER:
            a, b = cold[key].get(c, 0.0), warm.get(key, {}).get(c, 0.0)
            if a == 0 and b == 0 and c != "TOTAL":
                continue
            rows.append([label, notebook, c, f"{a:.2f}", f"{b:.2f}"])
            if c == "TOTAL":
                per_label[label][0] += a
                per_label[label][1] += b
            else:
                per_category[c][0] += a
                per_category[c][1] += b
    for label, (a, b) in per_label.items():
        rows.append([label, "ALL", "TOTAL", f"{a:.2f}", f"{b:.2f}"])
    for c in ORDER[:-1]:
        if c in per_category:
            a, b = per_category[c]
            rows.append(["ALL", "ALL", c, f"{a:.2f}", f"{b:.2f}"])
    a, b = (sum(v[i] for v in per_label.values()) for i in (0, 1))
    rows.append(["ALL", "ALL", "TOTAL", f"{a:.2f}", f"{b:.2f}"])
    with path.open("w", newline="") as f:
        f.write(f"# {note}\n")
        writer = csv.writer(f)
        writer.writerow(["label", "notebook", "category", "cold_s", "warm_s"])
        writer.writerows(rows)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--notebooks", nargs="*", help="notebook stems (default: all)")
    p.add_argument("--datasets", nargs="*", help="labels (synthetic, gardens_point_mini, ...)")
    p.add_argument("--quick", action="store_true", help="the runner's quick mode (tests' size)")
    p.add_argument("--n-places", type=int, default=None, help="synthetic places (default: study's)")
    p.add_argument("--no-eval", action="store_true", help="leave out the closing vpr-study eval")
    p.add_argument("--no-warm", action="store_true", help="cold pass only")
    p.add_argument(
        "--kernels",
        choices=("shared", "per-notebook"),
        default="shared" if importlib.util.find_spec("vpr_study.session") else "per-notebook",
        help="one kernel per dataset label, as the runner (default when vpr_study.session "
        "exists), or one per notebook, as the runner did before",
    )
    p.add_argument("--csv", type=Path, default=ROOT / "results/benchmarks/study_profile.csv")
    p.add_argument("--keep", type=Path, default=None, help="work folder to keep (default: temp)")
    p.add_argument(
        "--note",
        default="idle machine",
        help="machine state for the CSV's comment line (e.g. 'loaded machine')",
    )
    args = p.parse_args(argv)
    os.environ.setdefault("TQDM_DISABLE", "1")
    os.environ.setdefault("MPLBACKEND", "Agg")
    import vpr_core
    import vpr_study

    check_modules({"vpr_core": vpr_core.__file__, "vpr_study": vpr_study.__file__}, "this script")
    with tempfile.TemporaryDirectory(prefix="profile_study_") as tmp:
        work = args.keep or Path(tmp)
        out_root, cache = work / "out", work / "cache"
        cache.mkdir(parents=True, exist_ok=True)
        if any(cache.iterdir()):
            raise SystemExit(f"cache {cache} is not empty; give an empty --keep folder")
        plan = study_plan(args)
        t0 = time.perf_counter()
        cold = one_pass(plan, args, out_root, cache, work, "cold")
        t_cold = time.perf_counter() - t0
        warm = {} if args.no_warm else one_pass(plan, args, out_root, cache, work, "warm")
        t_warm = time.perf_counter() - t0 - t_cold
    note = (
        f"{args.note}; kernels {args.kernels}; {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, {time.strftime('%Y-%m-%d')}; "
        f"cold {t_cold:.0f} s, warm {t_warm:.0f} s; "
        f"benchmarks/profile_study.py {' '.join(argv if argv is not None else sys.argv[1:])}"
    )
    write_csv(args.csv, cold, warm, note)
    print(f"cold {t_cold:.1f} s, warm {t_warm:.1f} s; wrote {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
