"""The reader's path, measured: the ``vpr_core`` files (and their executed lines) that produce a
number, traced line by line (``sys.settrace`` in every thread) on a small generated set, cache
empty, so every stage computes. docs/ARCHITECTURE.md lists the files of two paths and
``tests/test_reader_path.py`` fails when the list and the trace differ (issue 59).

- ``fig13``: notebook 06's Fig. 13 cell to "AUC [95% CI] of dense": ``run_method("dense", ds)``
  then ``compare``.
- ``steps``: notebook 07's two-sided + query-batch number: ``run_method("dense", ds,
  weighting="two_sided", normalise="query_batch")`` then ``compare`` against plain dense.

Usage::

    .venv/bin/python benchmarks/reader_path.py            # both paths: files, lines per file
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "vpr_core"


def trace(run: Callable[[], object], lines: bool = False) -> dict[str, int]:
    """``{file: executed lines}`` of the ``vpr_core`` files whose functions ran in ``run()``
    (module-level code, i.e. imports, and ``__init__`` files left out), relative to the project
    root. ``lines=False``: ``sys.setprofile`` (calls only: fast; every count 0)."""
    seen: dict[str, set[int]] = defaultdict(set)
    prefix = str(PACKAGE) + os.sep

    def local(frame, event, arg):  # type: ignore[no-untyped-def]
        if event == "line":
            seen[frame.f_code.co_filename].add(frame.f_lineno)
        return local

    def tracer(frame, event, arg):  # type: ignore[no-untyped-def]
        code = frame.f_code
        if event == "call" and code.co_filename.startswith(prefix) and code.co_name != "<module>":
            seen[code.co_filename]
            return local if lines else None
        return None

    hook = (sys.settrace, threading.settrace) if lines else (sys.setprofile, threading.setprofile)
    for set_hook in reversed(hook):
        set_hook(tracer)
    try:
        run()
    finally:
        for set_hook in hook:
            set_hook(None)  # type: ignore[arg-type]
    return {
        str(Path(f).relative_to(ROOT)): len(n)
        for f, n in sorted(seen.items())
        if not f.endswith("__init__.py")
    }


def paths(lines: bool = False) -> dict[str, dict[str, int]]:
    """Both traced paths (a new empty cache each), on a 4-place generated set; ``lines``: count
    the executed lines too (:func:`trace`; slow)."""
    from vpr_core import compare, load_dataset, run_method
    from vpr_core.features.stage import get_encoder
    from vpr_core.matching.weighting import clear_reference_cache

    def fresh(run: Callable[[], object]) -> Callable[[], object]:
        """``run`` after the in-memory caches are emptied (encoders, reference statistics)."""

        def go() -> object:
            get_encoder.cache_clear()
            clear_reference_cache()
            return run()

        return go

    ds = load_dataset("synthetic", n_places=4, image_size=(90, 120))
    crop = {"input_size": 32, "n_bootstrap": 20}
    out = {}
    saved = os.environ.get("VPR_CACHE_DIR")
    try:
        with tempfile.TemporaryDirectory() as cache:
            os.environ["VPR_CACHE_DIR"] = cache
            out["fig13"] = trace(fresh(lambda: compare([run_method("dense", ds, **crop)])), lines)
        with tempfile.TemporaryDirectory() as cache:
            os.environ["VPR_CACHE_DIR"] = cache
            plain = run_method("dense", ds, **crop)
        with tempfile.TemporaryDirectory() as cache:  # the stepped run computes every stage
            os.environ["VPR_CACHE_DIR"] = cache
            steps = {"weighting": "two_sided", "normalise": "query_batch"}
            out["steps"] = trace(
                fresh(
                    lambda: compare([plain, run_method("dense", ds, **steps, **crop)], baseline=0)
                ),
                lines,
            )
    finally:
        if saved is None:
            os.environ.pop("VPR_CACHE_DIR", None)
        else:
            os.environ["VPR_CACHE_DIR"] = saved
    return out


#: How :func:`markdown` groups a path's files, in the order a reader meets the stages.
GROUPS = (
    ("the run and its result", ("vpr_core/run.py", "vpr_core/result.py", "vpr_core/methods.py")),
    ("landmarks", ("vpr_core/landmarks/",)),
    ("descriptors", ("vpr_core/features/", "vpr_core/backbones/")),
    ("Eq. (1)-(2) and the steps", ("vpr_core/matching/",)),
    ("metrics, intervals, the table", ("vpr_core/evaluation/",)),
    ("data, cache and checks", ("vpr_core/",)),
)

#: What each traced path is, as docs/ARCHITECTURE.md heads it.
TITLES = {
    "fig13": 'Fig. 13\'s "AUC [95% CI] of dense" (notebook 06: `run_method("dense", ds, ...)`, '
    '`compare(runs, baseline="dense")`)',
    "steps": 'notebook 07\'s two-sided + query-batch number (`run_method("dense", ds, '
    'weighting="two_sided", normalise="query_batch")`, `compare(group, baseline=...)`)',
}


def markdown(traced: dict[str, dict[str, int]]) -> str:
    """The paths as docs/ARCHITECTURE.md lists them: per path, its files by stage."""
    out = []
    for name, files in traced.items():
        out.append(f"- **{TITLES[name]}**: {len(files)} files.")
        left = list(files)
        for group, prefixes in GROUPS:
            mine = [f for f in left if f.startswith(prefixes)]
            left = [f for f in left if f not in mine]
            if mine:
                out.append(f"  - {group}: " + ", ".join(f"`{f}`" for f in mine))
    return "\n".join(out)


def main() -> None:
    traced = paths(lines=True)
    for name, files in traced.items():
        print(f"{name}: {len(files)} files, {sum(files.values())} executed lines")
        for f, n in files.items():
            print(f"  {n:5d}  {f}")
    print(markdown(traced))


if __name__ == "__main__":
    main()
