"""JupyterLab and git for the study notebooks (``make lab``): the save hook and the git filter
keep the committed study notebooks as git keeps them (no outputs, execution counts or run
metadata), and ``init`` gives a user a starter notebook of their own under ``user/notebooks/``.

Command line (``python -m vpr_study.lab``): ``init [--root DIR]`` copies the starter notebook;
otherwise it is git's clean filter (a notebook on stdin) or textconv (a notebook path),
writing the stripped notebook to stdout (``tools/nbstrip`` runs it)."""

from __future__ import annotations

import json
import logging
import sys
from importlib import resources
from pathlib import Path, PurePosixPath
from typing import Any

from vpr_core import checks, paths
from vpr_study.figures import NOTEBOOKS

__all__ = [
    "RUN_METADATA",
    "STARTER_NAME",
    "STUDY_NOTEBOOKS",
    "USER_NOTEBOOKS",
    "init",
    "main",
    "malformed",
    "project_path",
    "starter_source",
    "strip_outputs",
    "strip_text",
    "stripped",
]

logger = logging.getLogger(__name__)

#: The committed study notebooks, as paths from the project root (JupyterLab's API paths with
#: ``make lab``'s root): the only files the save hook strips. A copy (Lab's "Duplicate",
#: ``01_pipeline_tour-Copy1.ipynb``) or a user's ``notebooks/08_mine.ipynb`` keeps its outputs.
STUDY_NOTEBOOKS = frozenset(f"notebooks/{stem}.ipynb" for stem in NOTEBOOKS)

#: A user's own notebooks: the git-ignored ``user/notebooks/`` of the checkout.
USER_NOTEBOOKS = PurePosixPath(paths.USER_AREA, "notebooks")

#: The starter notebook ``init`` writes into :data:`USER_NOTEBOOKS` (``make lab`` opens it).
STARTER_NAME = "00_start_here.ipynb"

#: What JupyterLab and the kernel add that is not the notebook (nbstripout's defaults, the
#: kernel's language_info and Lab's collapsed-heading flag).
RUN_METADATA = [
    "metadata.signature",
    "metadata.widgets",
    "metadata.language_info",
    "cell.metadata.collapsed",
    "cell.metadata.ExecuteTime",
    "cell.metadata.execution",
    "cell.metadata.heading_collapsed",
    "cell.metadata.hidden",
    "cell.metadata.scrolled",
    "cell.metadata.jp-MarkdownHeadingCollapsed",
]


def malformed(content: Any) -> str | None:
    """Why ``content`` (a notebook as parsed JSON) is not a notebook this module strips: not an
    object, not nbformat 4, no list of cells, a cell that is not an object; None when it is."""
    if not isinstance(content, dict):
        return f"it is a JSON {type(content).__name__}, not an object"
    version = content.get("nbformat")
    if version != 4:
        return f"its nbformat is {version!r}, not 4 (open and save it in JupyterLab to upgrade)"
    cells = content.get("cells")
    if not isinstance(cells, list):
        return "it has no list of 'cells'"
    bad = [i for i, cell in enumerate(cells) if not isinstance(cell, dict)]
    if bad:
        return f"cell {bad[0]} is not a JSON object"
    if not isinstance(content.get("metadata", {}), dict):
        return "its 'metadata' is not a JSON object"
    return None


def stripped(nb: Any) -> Any:
    """``nb`` (a NotebookNode) without outputs, execution counts and :data:`RUN_METADATA`."""
    from nbstripout import strip_output

    return strip_output(
        nb, keep_output=False, keep_count=False, keep_id=True, extra_keys=RUN_METADATA
    )


def project_path(path: str, root: str | Path | None = None) -> str:
    """``path`` (a JupyterLab API path under the server's ``root``) as a POSIX path from the
    checkout holding it: ``make lab`` serves the checkout, so its API paths are that already;
    a server started elsewhere (``root``) is mapped through :func:`vpr_core.paths.project_root`."""
    rel = PurePosixPath(path.strip("/"))
    if root is None:
        return str(rel)
    full = (Path(root) / rel).resolve()
    checkout = paths.project_root(full.parent)
    if checkout is None:
        return str(rel)
    return full.relative_to(checkout).as_posix()


def strip_outputs(model: dict, path: str, contents_manager: Any = None, **kwargs: Any) -> None:
    """``ContentsManager.pre_save_hook`` of ``make lab``: a committed study notebook
    (:data:`STUDY_NOTEBOOKS`, by path) is saved as git keeps it, so its file stays
    byte-identical to the committed one unless its cells changed; every other notebook keeps
    what it showed. A study notebook that is not a v4 notebook (:func:`malformed`) is saved
    untouched and the reason logged (the server's log when given): a save never fails here."""
    root = getattr(contents_manager, "root_dir", None)
    if model.get("type") != "notebook" or project_path(path, root) not in STUDY_NOTEBOOKS:
        return
    log = getattr(contents_manager, "log", None) or logger
    content = model.get("content")
    why = malformed(content)
    if why is None:
        import nbformat

        try:
            model["content"] = stripped(nbformat.from_dict(content))
            return
        except Exception as exc:  # a save hook that raises fails the user's save
            why = f"stripping failed: {type(exc).__name__}: {exc}"
    log.warning("%s saved with its outputs, untouched: %s", path, why)


def starter_source() -> bytes:
    """The starter notebook shipped in the package (``vpr_study/starter.ipynb``)."""
    return resources.files("vpr_study").joinpath("starter.ipynb").read_bytes()


def init(root: str | Path | None = None) -> Path:
    """Write the starter notebook to ``<root>/user/notebooks/00_start_here.ipynb`` unless a
    file of that name exists (a user's edited copy is never replaced); return its path.
    ``root``: the project checkout (default: the one holding the cwd)."""
    base = Path(root) if root is not None else paths.project_root()
    if base is None:
        raise FileNotFoundError(
            f"{Path.cwd()} is not inside a checkout of {paths.PROJECT_NAME}; run `make lab` "
            "(or `python -m vpr_study.lab init`) from the project, or pass --root DIR"
        )
    folder = paths.make_dir(base / USER_NOTEBOOKS, "--root (default: the project checkout)")
    target = folder / STARTER_NAME
    checks.check_file(
        target, "the starter notebook"
    )  # a folder or a dangling link there: not "kept"
    try:
        with open(target, "xb") as f:  # exclusive: never overwrites
            f.write(starter_source())
    except FileExistsError:
        print(f"{target.relative_to(base)}: kept (yours; delete it to get the starter again)")
    else:
        print(f"{target.relative_to(base)}: the starter notebook, yours to edit (git-ignored)")
    return target


def strip_text(text: str) -> tuple[str, str | None]:
    """A notebook file's text as git keeps it, and None; or the text unchanged and the reason
    when it is not a notebook this module strips (the git filter never fails on a file)."""
    try:
        content = json.loads(text)
    except ValueError as exc:
        return text, f"not JSON ({exc})"
    why = malformed(content)
    if why is not None:
        return text, why
    import io

    import nbformat

    out = io.StringIO()
    nbformat.write(stripped(nbformat.from_dict(content)), out, version=nbformat.NO_CONVERT)
    return out.getvalue(), None


def main(argv: list[str]) -> None:
    """``init [--root DIR]``, or git's clean filter (stdin) / textconv (a path): stripped to
    stdout; a malformed notebook passes through unchanged, the reason on stderr."""
    if argv[:1] == ["init"]:
        import argparse

        parser = argparse.ArgumentParser(
            prog="python -m vpr_study.lab init",
            description=f"Copy the starter notebook to {USER_NOTEBOOKS}/{STARTER_NAME} "
            "when absent.",
        )
        parser.add_argument("--root", help="the project checkout (default: the cwd's)")
        try:
            init(parser.parse_args(argv[1:]).root)
        except (OSError, ValueError) as exc:
            parser.exit(2, f"{parser.prog}: error: {exc}\n")
        return
    source = argv[0] if argv else "stdin"
    data = Path(argv[0]).read_bytes() if argv else sys.stdin.buffer.read()
    try:
        out, why = strip_text(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        out, why = "", f"not UTF-8 text ({exc})"
    if why is not None:
        print(f"vpr_study.lab: {source} passed through unchanged: {why}", file=sys.stderr)
    sys.stdout.buffer.write(data if why is not None else out.encode("utf-8"))


if __name__ == "__main__":  # pragma: no cover - git and make run it
    main(sys.argv[1:])
