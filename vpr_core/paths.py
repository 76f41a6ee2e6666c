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
    "output_root",
    "results_dir",
    "runs_dir",
]

def output_root() -> Path:
    """``$VPR_OUTPUT_DIR`` or the current working directory (absolute, not created)."""
    env = settings.output_dir()
    return (Path(env).expanduser() if env else Path.cwd()).resolve()


def _sub(kind: str, label: str | None) -> Path:
    d = output_root() / kind
    if label:
        d = d / label
    d.mkdir(parents=True, exist_ok=True)
    return d


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
    root.mkdir(parents=True, exist_ok=True)
    return root
