"""The notebooks of each dataset label executed in one kernel (:mod:`vpr_study.session`),
labels side by side; each execution's outputs recorded (:mod:`vpr_study.memo`) so unchanged
notebooks are not executed again."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor, wait
from pathlib import Path

from vpr_core import paths, settings
from vpr_study import memo
from vpr_study.figures import expected_figures

from . import outputs

__all__ = ["BACKGROUND_NICE", "kernel_settings", "run_labels"]

logger = logging.getLogger("vpr_core")


def kernel_settings(shared: bool = False) -> dict[str, str]:
    """The ``env=`` settings of the notebook kernels: the absolute figures and cache roots (a
    kernel in ``notebooks/`` writes where the caller does: a label the study does not commit
    under ``user/``, :func:`vpr_study.outputs.figures_root`), inline figures even under
    ``MPLBACKEND=Agg``, and text progress bars the saved notebooks can show. ``shared``: kernels
    run side by side, so torch's OpenMP threads sleep when idle instead of spinning (two
    spinning kernels on 2 cores run crop features 1.8x slower; same bits either way)."""
    env = {
        settings.OUTPUT_ENV: str(outputs.figures_root()),
        settings.CACHE_ENV: str(paths.cache_root()),
        "MPLBACKEND": "module://matplotlib_inline.backend_inline",
        settings.PROGRESS_ENV: "text",
    }
    return {**env, "OMP_WAIT_POLICY": "PASSIVE"} if shared else env


def _unwritten(folder: Path, stems: Sequence[str], since: float) -> list[str]:
    """The expected ``<stem>.png`` in ``folder`` that are absent or older than ``since``."""
    out = []
    for stem in stems:
        png = folder / f"{stem}.png"
        if not png.exists():
            out.append(f"{png} (absent)")
        elif png.stat().st_mtime < since - 2.0:  # 2 s: coarse file-system timestamps
            out.append(f"{png} (not rewritten by this run)")
    return out


def _relay(stream, prefix: str) -> None:
    """Print each line of a child's output with ``prefix`` (kernels running side by side)."""
    for line in stream:
        sys.stdout.write(prefix + line)
        sys.stdout.flush()


def _execute(
    notebooks: Sequence[Path],
    out_dir: Path,
    params: dict,
    kernel: str,
    finished: dict,
    prefix: str | None = None,
    nice: int = 0,
) -> None:
    """Run papermill on ``notebooks`` in order, all in one kernel (:mod:`vpr_study.session`),
    in a child process whose environment holds :func:`kernel_settings`; the kernel's output
    streams here live, each line led by ``prefix`` when given (kernels side by side). ``nice``:
    the child's and its kernel's CPU niceness (higher: lower priority).
    ``finished`` gets ``{notebook stem: (unix time it started, ended)}`` of each notebook that
    finished, also when the run stops.

    Raises:
        RuntimeError: a notebook failed (the message names the first unfinished one).
    """
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="vpr_session_") as tmp:
        status = Path(tmp) / "status.jsonl"
        request = {
            "notebooks": [
                {"input_path": str(nb), "output_path": str(out_dir / nb.name), "parameters": params}
                for nb in notebooks
            ],
            "cwd": str(notebooks[0].parent),
            "kernel": kernel,
            "progress_bar": prefix is None
            and sys.stderr.isatty()
            and not settings.progress_disabled(),
            "status": str(status),
            "nice": nice,
        }
        logger.info("executing %s -> %s", ", ".join(nb.name for nb in notebooks), out_dir)
        command = [sys.executable, "-m", "vpr_study.session", json.dumps(request)]
        env = settings.child_environment(kernel_settings(shared=prefix is not None))
        try:
            if prefix is None:
                done = subprocess.run(command, env=env)
            else:
                with subprocess.Popen(
                    command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
                ) as child:
                    assert child.stdout is not None  # piped above
                    _relay(child.stdout, prefix)
                done = subprocess.CompletedProcess(command, child.wait())
        finally:
            lines = (
                [json.loads(x) for x in status.read_text().splitlines()] if status.exists() else []
            )
            started = {x["notebook"]: x["started"] for x in lines if "started" in x}
            finished.update(
                {x["done"]: (started[x["done"]], x["ended"]) for x in lines if "done" in x}
            )
    if done.returncode != 0:
        failed = next(nb for nb in notebooks if nb.stem not in finished)
        raise RuntimeError(
            f"notebook {failed.name} failed (the error is printed above); open "
            f"{out_dir / failed.name} to see the failing cell"
        )
    logger.info(
        "%d notebook(s) done in %.1f s -> %s", len(notebooks), time.perf_counter() - t0, out_dir
    )


def _run_label(
    label: str,
    selected: Sequence[Path],
    params: dict,
    kernel: str,
    force: bool = False,
    side_by_side: bool = False,
    nice: int = 0,
) -> list[str]:
    """Execute ``selected`` notebooks for one output label (one kernel), skipping those whose
    inputs and recorded outputs are unchanged (:mod:`vpr_study.memo`) unless ``force``; the
    expected figures not written. ``side_by_side``: other labels run meanwhile (output lines
    get a ``[label]`` prefix); ``nice``: the kernel's CPU niceness."""
    inputs = memo.inputs_key(params)
    keys = {nb.stem: memo.notebook_key(nb, inputs) for nb in selected}
    todo = [
        nb for nb in selected if force or memo.up_to_date(label, nb.stem, keys[nb.stem]) is None
    ]
    for nb in selected:
        if nb not in todo:
            print(
                f"{nb.stem} ({label}): inputs and outputs unchanged since its last execution, "
                "not executed again (vpr-study run --force executes it)"
            )
    if not todo:
        return []
    expected = expected_figures()
    finished: dict[str, tuple[float, float]] = {}
    try:
        prefix = f"[{label}] " if side_by_side else None
        _execute(todo, outputs.runs_dir(label), params, kernel, finished, prefix=prefix, nice=nice)
    except BaseException:
        stopped = next((nb.stem for nb in todo if nb.stem not in finished), "?")
        print(
            f"\nstopped in {stopped} ({label}); finished: {', '.join(finished) or 'none'}. "
            f"Figures so far in {outputs.figures_dir(label)}, tables in "
            f"{outputs.results_dir(label)}; cached work is kept, rerun to resume."
        )
        raise
    missing: list[str] = []
    folders = [outputs.figures_dir(label), outputs.results_dir(label), outputs.runs_dir(label)]
    for nb in todo:
        started, ended = finished[nb.stem]
        lost = _unwritten(outputs.figures_dir(label), expected.get(nb.stem, []), started)
        missing += lost
        if not lost:
            written = [
                p for p in memo.written_since(folders, started) if p.stat().st_mtime <= ended + 2.0
            ]
            memo.record(label, nb.stem, keys[nb.stem], written, ended - started)
    return missing


#: CPU niceness of the labels after the first when labels run side by side: the first (the
#: ``--dataset`` study, in ``make study`` the longest chain) keeps the cores it can use, the
#: others fill those it leaves idle (its single-threaded plotting, Edge Boxes and I/O).
BACKGROUND_NICE = 10


def _failed(chains: Sequence[tuple[str, Sequence[Path], dict]], errors: list) -> None:
    """Raise one RuntimeError naming every label whose chain failed and the ones that ran
    (nothing when none failed)."""
    failed = [(label, e) for (label, _, _), e in zip(chains, errors, strict=True) if e is not None]
    if not failed:
        return
    ran = [label for (label, _, _), e in zip(chains, errors, strict=True) if e is None]
    raise RuntimeError(
        f"{len(failed)} of {len(chains)} dataset labels failed: "
        + "; ".join(f"{label}: {e}" for label, e in failed)
        + (f". These ran to their end: {', '.join(ran)}" if ran else "")
    ) from failed[0][1]


def run_labels(
    chains: Sequence[tuple[str, Sequence[Path], dict]], kernel: str, force: bool, jobs: int
) -> list[str]:
    """:func:`_run_label` of each ``(label, notebooks, parameters)``, ``jobs`` labels at once
    (the first, longest chain starts first). Every label runs, also after another failed;
    then one RuntimeError names each label that failed (its error) and those that ran. A
    Ctrl-C starts no further label. Returns the expected figures not written."""
    if jobs <= 1 or len(chains) <= 1:
        missing: list[str] = []
        errors: list[Exception | None] = []
        for label, nbs, params in chains:
            try:
                missing += _run_label(label, nbs, params, kernel, force)
            except Exception as exc:  # the next labels still run; Ctrl-C stops them all
                errors.append(exc)
            else:
                errors.append(None)
        _failed(chains, errors)
        return missing
    with ThreadPoolExecutor(min(jobs, len(chains)), thread_name_prefix="label") as pool:
        futures = [
            pool.submit(
                _run_label, label, nbs, params, kernel, force, True, BACKGROUND_NICE * (n > 0)
            )
            for n, (label, nbs, params) in enumerate(chains)
        ]
        try:
            pending = set(futures)
            while pending:  # timed waits: a Ctrl-C that reached a label's thread is seen here
                pending = wait(pending, timeout=0.2)[1]
            done = [f.exception() for f in futures]
        except BaseException:  # Ctrl-C: the running kernels got it too; start no other label
            pool.shutdown(cancel_futures=True)
            raise
    for error in done:
        if error is not None and not isinstance(error, Exception):
            raise error  # KeyboardInterrupt or SystemExit in a label's thread
    _failed(chains, [e if isinstance(e, Exception) else None for e in done])
    return [m for f in futures for m in f.result()]
