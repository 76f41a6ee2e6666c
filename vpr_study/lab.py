"""The study notebooks as git keeps them: no outputs, execution counts or run metadata. One
home for the git filter of ``make lab`` (``python -m vpr_study.lab``) and its save hook."""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

#: The tracked study notebooks, as paths from the project root (JupyterLab's API paths).
STUDY_NOTEBOOK = re.compile(r"notebooks/\d\d_[^/]+\.ipynb")


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


def stripped(nb: Any) -> Any:
    """``nb`` (a NotebookNode) without outputs, execution counts and :data:`RUN_METADATA`."""
    from nbstripout import strip_output

    return strip_output(
        nb, keep_output=False, keep_count=False, keep_id=True, extra_keys=RUN_METADATA
    )


def strip_outputs(model: dict, path: str, contents_manager: Any = None, **kwargs: Any) -> None:
    """``ContentsManager.pre_save_hook`` of ``make lab``: a study notebook is saved as git
    keeps it, so its file stays byte-identical to the committed one unless its cells changed
    and a Lab session leaves ``git status`` clean (executed copies: ``runs/<label>/``)."""
    if model.get("type") != "notebook" or not STUDY_NOTEBOOK.fullmatch(path.lstrip("/")):
        return
    import nbformat

    model["content"] = stripped(nbformat.from_dict(model["content"]))


def main(argv: list[str]) -> None:
    """Git's clean filter (notebook on stdin) or textconv (notebook path): stripped to stdout."""
    import nbformat

    text = Path(argv[0]).read_text(encoding="utf-8") if argv else sys.stdin.read()
    nb = nbformat.reads(text, as_version=nbformat.NO_CONVERT)
    nbformat.write(stripped(nb), sys.stdout, version=nbformat.NO_CONVERT)


if __name__ == "__main__":  # pragma: no cover - git runs it
    main(sys.argv[1:])
