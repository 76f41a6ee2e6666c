"""Where the pipeline reads and writes: input paths, the output root (the workbench's outputs go
under it: :mod:`vpr_study.outputs`) and the cache root. Nothing is written inside the installed
package."""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from . import settings

__all__ = [
    "OUT_SETTING",
    "PROJECT_NAME",
    "cache_root",
    "chosen_root",
    "find_input",
    "make_dir",
    "output_root",
    "project_root",
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


def find_input(path: str | os.PathLike) -> Path:
    """An input folder or file as the user means it, from the project root or from ``notebooks/``.

    A relative path that does not exist from the cwd is tried against the project checkout
    holding the cwd (:func:`project_root`), so ``"../shared/data/x"`` reads the same folder from
    the checkout and from a kernel in ``notebooks/``.

    Raises:
        FileNotFoundError: found nowhere; the message names every resolved path tried and the
            working directory.
    """
    given = Path(path).expanduser()
    tried = [given.resolve()]
    if given.exists():
        return given
    checkout = project_root()
    if not given.is_absolute() and checkout is not None and checkout != Path.cwd().resolve():
        candidate = (checkout / given).resolve()
        if candidate.exists():
            return candidate
        tried.append(candidate)
    anchor = f", project root {checkout}" if len(tried) > 1 else ""
    raise FileNotFoundError(
        f"{str(path)!r} does not exist: looked for {' and '.join(map(str, tried))} (working "
        f"directory {Path.cwd()}{anchor}); pass an absolute path or one relative to the "
        "project root"
    )


def chosen_root() -> Path | None:
    """The output root the caller chose: ``--out`` (:func:`using_output_root`), else
    ``$VPR_OUTPUT_DIR``, else None."""
    if _override is not None:
        return _override
    env = settings.output_dir()
    return Path(env).expanduser().resolve() if env else None


def output_root() -> Path:
    """The output root (absolute, not created), the first of: the CLI's ``--out``
    (:func:`using_output_root`), ``$VPR_OUTPUT_DIR``, the project's checkout holding the cwd
    (:func:`project_root`), the cwd. Executed notebooks go to ``<root>/runs/<label>/``, the
    cache to ``<root>/.cache``; the workbench's figures and tables under
    :func:`vpr_study.outputs.figures_root`."""
    return chosen_root() or project_root() or Path.cwd().resolve()


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


#: What chooses the output root, as an error about a folder under it names it (:func:`make_dir`).
OUT_SETTING = "--out / VPR_OUTPUT_DIR (default: the project checkout, else the current folder)"


def cache_root() -> Path:
    """``$VPR_CACHE_DIR`` or ``<output root>/.cache``, created."""
    env = settings.cache_dir()
    root = Path(env).expanduser().resolve() if env else output_root() / ".cache"
    return make_dir(
        root,
        "VPR_CACHE_DIR"
        if env
        else f"{OUT_SETTING}; the cache defaults to <output root>/.cache, or set VPR_CACHE_DIR",
    )
