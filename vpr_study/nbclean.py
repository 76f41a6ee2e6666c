"""The study notebooks as git keeps them: without outputs, execution counts, run metadata and
Lab's view state (a collapsed cell). Only the notebooks of the catalogue
(:data:`vpr_study.figures.NOTEBOOKS`, by path: :data:`STUDY_NOTEBOOKS`) and their jupytext twins
are stripped; any other notebook (a Lab duplicate, ``notebooks/08_mine.ipynb``) is the user's and
passes unchanged.

Standard library only: git's filter (``tools/nbstrip``) runs this file with the system Python,
so it works in a fresh clone and after ``make clean`` as with ``.venv``.

Command line (``python3 vpr_study/nbclean.py``): ``--clean PATH`` is git's clean filter (the
file's text on stdin, ``PATH`` its path from the top of the work tree); ``FILE`` is git's diff
textconv. Either writes the text git keeps to stdout."""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path, PurePosixPath
from typing import Any

if __package__:
    from vpr_study.figures import NOTEBOOKS
else:  # run as a file by git's filter: the catalogue's file alone, no package imported
    _spec = importlib.util.spec_from_file_location(
        "vpr_study_catalogue_figures", Path(__file__).with_name("figures.py")
    )
    assert _spec is not None and _spec.loader is not None
    _figures = importlib.util.module_from_spec(_spec)
    sys.modules[_spec.name] = _figures
    _spec.loader.exec_module(_figures)
    NOTEBOOKS = _figures.NOTEBOOKS

__all__ = [
    "RUN_METADATA",
    "STUDY_NOTEBOOKS",
    "STUDY_TWINS",
    "clean_text",
    "is_study",
    "main",
    "malformed",
    "notebook_text",
    "strip_notebook",
    "strip_twin",
]

#: The committed study notebooks, as paths from the project root: the catalogue
#: (:data:`vpr_study.figures.NOTEBOOKS`) by path. Only these are stripped.
STUDY_NOTEBOOKS = frozenset(f"notebooks/{stem}.ipynb" for stem in NOTEBOOKS)

#: Their jupytext twins (``notebooks/scripts/<stem>.py``).
STUDY_TWINS = frozenset(f"notebooks/scripts/{stem}.py" for stem in NOTEBOOKS)

#: What JupyterLab and the kernel add that is not the notebook: nbstripout's defaults, the
#: kernel's language_info, and Lab's view state (a collapsed cell, collapsed heading, hidden
#: source or outputs).
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
    "cell.metadata.jupyter.source_hidden",
    "cell.metadata.jupyter.outputs_hidden",
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
    for i, cell in enumerate(cells):
        if not isinstance(cell.get("metadata", {}), dict):
            return f"cell {i}'s 'metadata' is not a JSON object"
        if not isinstance(cell.get("outputs", []), list):
            return f"cell {i}'s 'outputs' is not a list"
    return None


def _pop(d: Any, dotted: str) -> None:
    """Remove the nested key ``a.b.c`` of ``d``; a parent left empty by it goes too."""
    head, _, tail = dotted.partition(".")
    if not isinstance(d, dict) or head not in d:
        return
    if not tail:
        del d[head]
        return
    _pop(d[head], tail)
    if d[head] == {}:
        del d[head]


def strip_notebook(content: dict) -> dict:
    """``content`` (a v4 notebook as parsed JSON, :func:`malformed` None), changed in place:
    no outputs, no execution counts, no :data:`RUN_METADATA`; cell ids kept."""
    for key in RUN_METADATA:
        where, _, dotted = key.partition(".")
        if where == "metadata":
            _pop(content.get("metadata", {}), dotted)
    content.get("metadata", {}).pop("orig_nbformat", None)
    for cell in content["cells"]:
        if cell.get("cell_type") == "code":
            cell["outputs"] = []
            cell["execution_count"] = None
        meta = cell.setdefault("metadata", {})
        for key in RUN_METADATA:
            if key.startswith("cell.metadata."):
                _pop(meta, key.removeprefix("cell.metadata."))
        meta.pop("trusted", None)
    return content


#: A lone surrogate (``"\\ud800"`` in a notebook's JSON): no UTF-8 encoding of it exists.
_SURROGATE = re.compile("[\ud800-\udfff]")


def notebook_text(content: dict) -> str:
    """``content`` as nbformat writes a notebook file (sorted keys, indent 1, sources split
    into lines, a final newline); a lone surrogate stays the JSON escape it was read from (it
    can only stand inside a JSON string), so the text always encodes to UTF-8."""
    for cell in content.get("cells", []):
        if isinstance(cell.get("source"), str):
            cell["source"] = cell["source"].splitlines(True)
    text = json.dumps(content, indent=1, sort_keys=True, separators=(",", ": "), ensure_ascii=False)
    text = _SURROGATE.sub(lambda m: f"\\u{ord(m.group()):04x}", text)
    return text if text.endswith("\n") else text + "\n"


#: A py:percent cell marker's view-state metadata, as jupytext writes it.
_VIEW = re.compile(
    r' (?:jupyter=\{"(?:source|outputs)_hidden": true(?:, "(?:source|outputs)'
    r'_hidden": true)?\}|collapsed=(?:true|false))(?= |$)'
)


def strip_twin(text: str) -> str:
    """A jupytext py:percent twin without Lab's view state on its ``# %%`` lines."""
    lines = text.splitlines(True)
    return "".join(_VIEW.sub("", x) if x.startswith("# %%") else x for x in lines)


def is_study(path: str | None) -> bool:
    """Whether ``path`` (a POSIX path from the top of the work tree) is a study notebook or its
    twin; None (an older filter that gives no path) counts as one."""
    if path is None:
        return True
    rel = str(PurePosixPath(path.replace("\\", "/")))
    return rel in STUDY_NOTEBOOKS or rel in STUDY_TWINS


def clean_text(text: str, path: str | None = None) -> tuple[str, str | None]:
    """The text git keeps of the file at ``path``, and None; or the text unchanged and the
    reason when it is a study notebook this module cannot strip. A file outside the catalogue
    (the user's) is returned unchanged with no reason: it keeps its outputs."""
    if not is_study(path):
        return text, None
    if path is not None and path.endswith(".py"):
        return strip_twin(text), None
    try:
        content = json.loads(text)
    except ValueError as exc:
        return text, f"not JSON ({exc})"
    why = malformed(content)
    if why is not None:
        return text, why
    return notebook_text(strip_notebook(content)), None


def _textconv_path(arg: str) -> str:
    """The work-tree path of git's textconv argument: the file itself when it lies in the work
    tree, else a temporary copy git names ``XXXXXX_<file name>`` (its folder is then taken to
    be ``notebooks/`` or ``notebooks/scripts/``, where the catalogue's files are)."""
    file = Path(arg)
    try:
        return file.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        name = re.sub(r"^[^_]{6}_", "", file.name)
        return f"notebooks/scripts/{name}" if name.endswith(".py") else f"notebooks/{name}"


def _stripped(data: bytes, path: str | None) -> tuple[bytes, str | None]:
    """:func:`clean_text` of a file's bytes: ``(bytes git keeps, None)``, or ``(data, why)``
    when a study notebook cannot be stripped, whatever the reason (not UTF-8, not JSON, nested
    too deep for the parser, malformed, any error while stripping)."""
    try:
        out, why = clean_text(data.decode("utf-8"), path)
        return (data, why) if why is not None else (out.encode("utf-8"), None)
    except Exception as exc:  # the filter fails closed, whatever went wrong
        text = str(exc).splitlines()[0][:120] if str(exc) else ""
        return data, f"{type(exc).__name__}{': ' + text if text else ''}"


def main(argv: list[str]) -> int:
    """``--clean PATH`` (stdin; git's clean filter) or ``FILE`` (textconv), stripped as
    :func:`clean_text`; returns the exit status. The filter fails closed: a study notebook
    that cannot be stripped is refused (status 1, a sentence on stderr: git, whose filter is
    ``required``, then stops the ``git add``), so its outputs never reach git through an error;
    the textconv (what ``git diff`` shows) shows it unchanged, the reason on stderr."""
    clean = argv[:1] == ["--clean"] or not argv  # no argument: an older filter, on stdin
    if argv[:1] == ["--clean"]:
        path = argv[1] if len(argv) > 1 else None
        data = sys.stdin.buffer.read()
    elif argv:
        path = _textconv_path(argv[0])
        data = Path(argv[0]).read_bytes()
    else:
        path = None
        data = sys.stdin.buffer.read()
    out, why = _stripped(data, path)
    if why is not None and clean:
        print(
            f"tools/nbstrip: {path or 'the study notebook on stdin'}: not added, its outputs "
            f"would reach git: the filter cannot strip it ({why}); open it in JupyterLab "
            "(make lab), clear its outputs and save it as a notebook, then add it again",
            file=sys.stderr,
        )
        return 1
    if why is not None:
        print(f"vpr_study.lab: {path or 'stdin'} shown unchanged: {why}", file=sys.stderr)
    sys.stdout.buffer.write(out)
    return 0


if __name__ == "__main__":  # pragma: no cover - git runs it
    sys.exit(main(sys.argv[1:]))
