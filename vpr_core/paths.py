"""Where the workbench writes: the output root (figures, results, runs) and the cache root.

Nothing is ever written inside the installed package; the rules are in :func:`output_root`.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from . import settings

__all__ = [
    "PROJECT_NAME",
    "cache_root",
    "check_label",
    "figures_dir",
    "make_dir",
    "output_root",
    "project_root",
    "results_dir",
    "runs_dir",
    "using_output_root",
]

#: ``[project] name`` in this project's ``pyproject.toml`` (how a checkout is recognised).
PROJECT_NAME = "vpr-landmarks"

_override: Path | None = None


def project_root(start: Path | None = None) -> Path | None:
    """The checkout of this project holding ``start`` (default: the cwd), or None.

    Walks up from ``start`` to the first folder holding ``notebooks/`` and a ``pyproject.toml``
    whose ``[project] name`` is :data:`PROJECT_NAME`, so a kernel started in ``notebooks/``
    finds the same root as ``make study`` run at the top.
    """
    here = (start or Path.cwd()).resolve()
    for folder in (here, *here.parents):
        toml = folder / "pyproject.toml"
        if toml.is_file() and (folder / "notebooks").is_dir():
            try:
                text = toml.read_text(errors="replace")
            except OSError:
                continue
            if re.search(rf'^name\s*=\s*"{PROJECT_NAME}"', text, re.MULTILINE):
                return folder
    return None


@contextmanager
def using_output_root(root: str | Path | None) -> Iterator[None]:
    """Within the block, :func:`output_root` is ``root`` (the CLI's ``--out``); ``None``
    changes nothing. The previous root is restored afterwards."""
    global _override
    saved = _override
    if root is not None:
        _override = Path(root).expanduser().resolve()
    try:
        yield
    finally:
        _override = saved


def output_root() -> Path:
    """The output root (absolute, not created), the first of: the CLI's ``--out``
    (:func:`using_output_root`), ``$VPR_OUTPUT_DIR``, the project's checkout holding the cwd
    (:func:`project_root`), the cwd. Figures go to ``<root>/figures/<label>/``, tables to
    ``<root>/results/<label>/``, executed notebooks to ``<root>/runs/<label>/``."""
    if _override is not None:
        return _override
    env = settings.output_dir()
    if env:
        return Path(env).expanduser().resolve()
    return project_root() or Path.cwd().resolve()


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


_OUT_SETTING = "--out / VPR_OUTPUT_DIR (default: the project checkout, else the current folder)"


def check_label(label: object) -> str:
    """``label`` if it names one output subfolder (one path component, not ``.``/``..``).

    Raises:
        ValueError: e.g. ``../../x`` or ``/tmp/x`` (would write outside the output root).
        TypeError: not a string (e.g. ``label=5``).
    """
    if not isinstance(label, str):
        raise TypeError(f"label must be a string such as 'gardens_point', got {label!r}")
    if (
        not label.strip()
        or label in (".", "..")
        or "/" in label
        or "\\" in label
        or "\0" in label
        or Path(label).is_absolute()
    ):
        raise ValueError(
            f"label {label!r} must be one folder name (no '/', '..' or absolute path), "
            "e.g. 'gardens_point'; it names figures/<label>/ and results/<label>/"
        )
    return label


def _sub(kind: str, label: str | None) -> Path:
    d = output_root() / kind
    if label:
        d = d / check_label(label)
    return make_dir(d, _OUT_SETTING)


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
        else f"{_OUT_SETTING}; the cache defaults to <output root>/.cache, or set VPR_CACHE_DIR",
    )
