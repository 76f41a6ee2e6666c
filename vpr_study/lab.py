"""JupyterLab and git for the study notebooks (``make lab``): the save hook and the git filter
keep the committed study notebooks (the catalogue's, by path) as git keeps them (no outputs,
execution counts, run metadata or Lab's view state: :mod:`vpr_study.nbclean`), and ``init`` gives
a user a starter notebook of their own under ``user/notebooks/``.

Command line (``python -m vpr_study.lab``): ``init [--root DIR]`` copies the starter notebook;
otherwise it strips a study notebook given on stdin or as a path to stdout (git's filter,
``tools/nbstrip``, runs :mod:`vpr_study.nbclean` itself, with the system Python)."""

from __future__ import annotations

import logging
import sys
from importlib import resources
from pathlib import Path, PurePosixPath
from typing import Any

from vpr_core import checks, paths
from vpr_study.nbclean import (
    RUN_METADATA,
    STUDY_NOTEBOOKS,
    STUDY_TWINS,
    clean_text,
    malformed,
    strip_notebook,
    strip_twin,
)
from vpr_study.nbclean import main as nbclean_main

from . import outputs

__all__ = [
    "RUN_METADATA",
    "STARTER_NAME",
    "STUDY_NOTEBOOKS",
    "STUDY_TWINS",
    "USER_NOTEBOOKS",
    "init",
    "kernel_language_info",
    "main",
    "malformed",
    "project_path",
    "starter_source",
    "strip_outputs",
    "strip_text",
    "stripped",
]

logger = logging.getLogger(__name__)

#: A user's own notebooks: the git-ignored ``user/notebooks/`` of the checkout.
USER_NOTEBOOKS = PurePosixPath(outputs.USER_AREA, "notebooks")

#: The starter notebook ``init`` writes into :data:`USER_NOTEBOOKS` (``make lab`` opens it).
STARTER_NAME = "00_start_here.ipynb"


def stripped(nb: Any) -> Any:
    """``nb`` (a notebook as a dict or NotebookNode, changed in place) without outputs,
    execution counts and :data:`RUN_METADATA` (:func:`vpr_study.nbclean.strip_notebook`)."""
    return strip_notebook(nb)


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
    byte-identical to the committed one unless its cells changed, and its jupytext twin
    (:data:`STUDY_TWINS`) without Lab's view state; every other notebook keeps what it showed.
    A study notebook that is not a v4 notebook (:func:`malformed`) is saved untouched and the
    reason logged (the server's log when given): a save never fails here."""
    where = project_path(path, getattr(contents_manager, "root_dir", None))
    if model.get("type") == "file" and where in STUDY_TWINS:
        if isinstance(model.get("content"), str):
            model["content"] = strip_twin(model["content"])
        return
    if model.get("type") != "notebook" or where not in STUDY_NOTEBOOKS:
        return
    log = getattr(contents_manager, "log", None) or logger
    content = model.get("content")
    why = malformed(content)
    if why is None and isinstance(content, dict):
        try:
            strip_notebook(content)
            return
        except Exception as exc:  # a save hook that raises fails the user's save
            why = f"stripping failed: {type(exc).__name__}: {exc}"
    log.warning("%s saved with its outputs, untouched: %s", path, why)


def kernel_language_info() -> dict:
    """The ``language_info`` the project's kernel (ipykernel, on this Python) reports, which
    JupyterLab writes into a notebook's metadata when its kernel starts."""
    from ipykernel.ipkernel import IPythonKernel

    return dict(IPythonKernel.language_info)


def _study_contents_manager() -> type:
    """``make lab``'s contents manager: jupytext's (the pairing with ``notebooks/scripts/``),
    and, for the committed study notebooks, the two things Lab would otherwise change on open:

    - a study notebook is served with its kernel's ``language_info`` (git keeps it without
      it): Lab sets that metadata when the kernel starts and, finding it equal, leaves the
      notebook unmodified (it marked it unsaved, and its autosave rewrote both files with
      the same bytes);
    - a copy of a study notebook into ``notebooks/`` (Lab's "Duplicate") lands in the user's
      ``user/notebooks/`` instead (a copy is the user's: there it keeps its outputs, beside the
      starter), and the server's log says so.
    """
    from jupyter_core.utils import ensure_async
    from jupytext.async_contentsmanager import AsyncTextFileContentsManager

    class StudyContentsManager(AsyncTextFileContentsManager):  # type: ignore[misc,valid-type]
        async def get(self, path, content=True, type=None, format=None, **kwargs):
            model = await super().get(path, content=content, type=type, format=format, **kwargs)
            where = project_path(path, self.root_dir)
            if content and model.get("type") == "notebook" and where in STUDY_NOTEBOOKS:
                meta = model["content"].setdefault("metadata", {})
                meta.setdefault("language_info", kernel_language_info())
            return model

        async def copy(self, from_path, to_path=None):
            target = (to_path if to_path is not None else from_path.rsplit("/", 1)[0]).strip("/")
            served_at_root = project_path(from_path, self.root_dir) == from_path.strip("/")
            if (
                served_at_root
                and from_path.strip("/") in STUDY_NOTEBOOKS
                and target == "notebooks"
                and await ensure_async(self.dir_exists(str(USER_NOTEBOOKS)))
            ):
                self.log.info(
                    "%s copied to %s/: a copy of a study notebook is yours (it keeps its "
                    "outputs there; notebooks/ holds the study's)",
                    from_path,
                    USER_NOTEBOOKS,
                )
                stem, n = PurePosixPath(from_path).stem, 1
                name = f"{USER_NOTEBOOKS}/{stem}-Copy{{}}.ipynb"
                while await ensure_async(self.file_exists(name.format(n))):
                    n += 1
                to_path = name.format(n)  # named as Lab names a copy
            return await super().copy(from_path, to_path)

    return StudyContentsManager


def __getattr__(name: str) -> Any:
    """``StudyContentsManager`` (:func:`_study_contents_manager`), built on first use: only
    ``make lab`` has the server libraries it derives from."""
    if name == "StudyContentsManager":
        cls = _study_contents_manager()
        globals()[name] = cls
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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
    """A study notebook file's text as git keeps it, and None; or the text unchanged and the
    reason when it is not a notebook this module strips (:func:`vpr_study.nbclean.clean_text`)."""
    return clean_text(text)


def main(argv: list[str]) -> int:
    """``init [--root DIR]``, or a study notebook on stdin or at a path stripped to stdout
    (:func:`vpr_study.nbclean.main`: one that cannot be stripped is refused, status 1)."""
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
        return 0
    return nbclean_main(argv)


if __name__ == "__main__":  # pragma: no cover - git and make run it
    sys.exit(main(sys.argv[1:]))
