"""Where the workbench reads and writes: input paths, the output root (figures, results, runs),
a user's git-ignored area beside the study's, and the cache root. Nothing is written inside the
installed package; the rules are in :func:`output_root` and :func:`figures_root`."""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from . import settings

__all__ = [
    "LABEL_CHARACTERS",
    "MAX_LABEL_BYTES",
    "MAX_NAME_BYTES",
    "OUT_SETTING",
    "PROJECT_NAME",
    "USER_AREA",
    "cache_root",
    "check_label",
    "check_name",
    "figures_dir",
    "figures_root",
    "find_input",
    "make_dir",
    "output_root",
    "project_root",
    "results_dir",
    "runs_dir",
    "study_outputs",
    "using_output_root",
]

#: ``[project] name`` in this project's ``pyproject.toml`` (how a checkout is recognised).
PROJECT_NAME = "vpr-landmarks"

#: The git-ignored folder of the checkout where a user's own cells save (:func:`figures_root`).
USER_AREA = "user"

_override: Path | None = None
_study = False


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


@contextmanager
def study_outputs(study: bool = True) -> Iterator[None]:
    """Within the block figures and tables go to the study's ``figures/`` and ``results/`` of
    the output root (the CLI's commands and the benchmarks), never to :data:`USER_AREA`;
    ``study=False``: to :data:`USER_AREA` (a label the study does not commit) unless a root
    was chosen."""
    global _study
    saved = _study
    _study = study
    try:
        yield
    finally:
        _study = saved


def _chosen_root() -> Path | None:
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
    cache to ``<root>/.cache``; figures and tables under :func:`figures_root`."""
    return _chosen_root() or project_root() or Path.cwd().resolve()


def figures_root() -> Path:
    """The folder holding ``figures/<label>/`` and ``results/<label>/`` (absolute, not created).

    The study writes its (committed) figures and tables in the output root: the CLI's commands
    (:func:`study_outputs`), and the notebook kernels of the study runner, which it starts with
    ``$VPR_OUTPUT_DIR`` set. So does any caller who chose the output root (``--out``,
    ``$VPR_OUTPUT_DIR``). A user's own cells in the project checkout, with no root chosen, save
    into its git-ignored ``user/`` (:data:`USER_AREA`): they never modify a tracked file.
    """
    chosen = _chosen_root()
    if chosen is not None:
        return chosen
    checkout = project_root()
    if checkout is None:
        return Path.cwd().resolve()
    return checkout if _study else checkout / USER_AREA


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


#: Longest label, in UTF-8 bytes: file names under it add a stem to it (255 bytes at most).
MAX_LABEL_BYTES = 100


#: The characters a label may hold, as :func:`check_label`'s message names them.
LABEL_CHARACTERS = "letters, digits, '_', '-', '.' and '+'"


def _label_character(c: str) -> bool:
    """True for a letter or a decimal digit (any script) or one of ``_ - . +``."""
    return c.isalpha() or c.isdecimal() or c in "_-.+"


def _check_bytes(text: str, what: str, limit: int, why: str) -> str:
    """``text`` if its UTF-8 form is at most ``limit`` bytes (a file-name length rule of
    :func:`check_label` and :func:`check_name`); ``what`` names it, ``why`` gives the limit's
    reason."""
    size = len(text.encode())
    if size > limit:
        raise ValueError(
            f"{what} {text[:20] + '...'!r} is {size} bytes long; give a {what} of at most "
            f"{limit} ({why})"
        )
    return text


def check_label(label: object) -> str:
    """``label`` if it names one output subfolder: only :data:`LABEL_CHARACTERS` (letters,
    digits, ``_ - . +``), not starting with ``.``; one rule for every output label (CLI, runner,
    ``save``), so a label never adds a column or a row, or HTML, to a table that names it.

    Raises:
        ValueError: e.g. ``../../x`` or ``/tmp/x`` (would write outside the output root),
            ``a|b``, a newline or ``<img ...>``; the message names the allowed characters.
        TypeError: not a string (e.g. ``label=5``).
    """
    if not isinstance(label, str):
        raise TypeError(f"label must be a string such as 'gardens_point', got {label!r}")
    bad = sorted({c for c in label if not _label_character(c)})
    if not label or label.startswith(".") or bad:
        found = f"it holds {', '.join(map(repr, bad))}" if bad else "it is empty or starts with '.'"
        raise ValueError(
            f"label {label!r} must be one folder name (no '/', '..' or absolute path) of "
            f"{LABEL_CHARACTERS}, not starting with '.', e.g. 'gardens_point' ({found}); it "
            "names figures/<label>/ and results/<label>/"
        )
    return _check_bytes(
        label,
        "label",
        MAX_LABEL_BYTES,
        "it names folders and the files in them, whose names the file system limits to 255 bytes",
    )


#: Longest file stem given to ``save()``, in UTF-8 bytes: 255 less the longest suffix added
#: (``.timings.csv``) and the temporary file's prefix and suffix (``.``, ``.XXXXXXXX.tmp``).
MAX_NAME_BYTES = 225


def check_name(name: object) -> str:
    """``name`` if it is one file stem inside an output folder (one path component: no ``/``,
    ``\\``, ``.``/``..``, absolute path or control character), as :func:`check_label` confines a
    label; ``save(obj, name, label)`` writes ``<label>/<name>.png`` / ``.csv`` and nowhere else.

    Raises:
        ValueError: e.g. ``../x``, ``/tmp/x`` or ``a/b`` (would write outside the label's
            folder), or a name over :data:`MAX_NAME_BYTES` bytes.
        TypeError: not a string (e.g. ``name=5``).
    """
    if not isinstance(name, str):
        raise TypeError(f"name must be a string such as 'fig13_comparison', got {name!r}")
    if (
        not name.strip()
        or name.strip(".") == ""
        or "/" in name
        or "\\" in name
        or any(ord(c) < 32 or ord(c) == 127 for c in name)
        or Path(name).is_absolute()
    ):
        raise ValueError(
            f"name {name!r} must be one file name without folders (no '/', '\\', '..', "
            "absolute path or control character), e.g. 'fig13_comparison'; it names "
            "<label>/<name>.png or .csv, the label chooses the folder"
        )
    return _check_bytes(
        name, "name", MAX_NAME_BYTES, "the file system limits file names to 255 bytes"
    )


def _sub(kind: str, label: str | None) -> Path:
    d = (output_root() if kind == "runs" else figures_root()) / kind
    if label:
        d = d / check_label(label)
    return make_dir(d, OUT_SETTING)


def figures_dir(label: str | None = None) -> Path:
    """``<figures root>/figures[/<label>]`` (:func:`figures_root`), created."""
    return _sub("figures", label)


def results_dir(label: str | None = None) -> Path:
    """``<figures root>/results[/<label>]`` (:func:`figures_root`), created."""
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
        else f"{OUT_SETTING}; the cache defaults to <output root>/.cache, or set VPR_CACHE_DIR",
    )
