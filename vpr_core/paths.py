"""Where the workbench writes: the output root (figures, results, runs) and the cache root.

Nothing is ever written inside the installed package.

- Output root: ``$VPR_OUTPUT_DIR`` if set, else the current working directory (so ``make study``
  in a checkout writes ``figures/`` and ``results/`` there). The CLI's ``--out`` sets it.
- Figures: ``<output root>/figures/<label>/``; results: ``<output root>/results/<label>/``;
  executed notebooks: ``<output root>/runs/<label>/``.
- Cache root: ``$VPR_CACHE_DIR`` if set, else ``<output root>/.cache``.
"""

from __future__ import annotations

from pathlib import Path

from . import settings

__all__ = [
    "cache_root",
    "figures_dir",
    "make_dir",
    "output_root",
    "results_dir",
    "runs_dir",
]


def output_root() -> Path:
    """``$VPR_OUTPUT_DIR`` or the current working directory (absolute, not created)."""
    env = settings.output_dir()
    return (Path(env).expanduser() if env else Path.cwd()).resolve()


def make_dir(path: Path, setting: str) -> Path:
    """``path`` created (with parents); an error names the folder, the setting that chose it
    and the fix (``[Errno 30]`` / ``[Errno 17]`` / ``[Errno 20]`` alone say none of that)."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        why = "a file is in the way" if exc.errno in (17, 20) else exc.strerror or str(exc)
        raise type(exc)(
            exc.errno,
            f"cannot create the folder {path} ({why}); it comes from "
            f"{setting}: point it at a writable folder with free space",
        ) from exc
    return path


def _sub(kind: str, label: str | None) -> Path:
    d = output_root() / kind
    if label:
        d = d / label
    return make_dir(d, "--out / VPR_OUTPUT_DIR (default: the current folder)")


def figures_dir(label: str | None = None) -> Path:
    """``<output root>/figures[/<label>]``, created."""
    return _sub("figures", label)


def results_dir(label: str | None = None) -> Path:
    """``<output root>/results[/<label>]``, created."""
    return _sub("results", label)


def runs_dir(label: str | None = None) -> Path:
    """``<output root>/runs[/<label>]`` (executed notebooks), created."""
    return _sub("runs", label)


def cache_root() -> Path:
    """``$VPR_CACHE_DIR`` or ``<output root>/.cache``, created."""
    env = settings.cache_dir()
    root = Path(env).expanduser().resolve() if env else output_root() / ".cache"
    return make_dir(
        root,
        "VPR_CACHE_DIR"
        if env
        else "--out / VPR_OUTPUT_DIR (the cache defaults to <output root>/.cache; or set "
        "VPR_CACHE_DIR)",
    )
