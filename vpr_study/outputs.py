"""Where the workbench writes: the study's ``figures/``, ``results/`` and ``runs/`` under the output
root (:func:`vpr_core.paths.output_root`), a user's git-ignored area beside them, and the rules
for a label and a file name; nothing is written inside the installed package."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from vpr_core import paths

__all__ = [
    "LABEL_CHARACTERS",
    "MAX_LABEL_BYTES",
    "MAX_NAME_BYTES",
    "USER_AREA",
    "check_label",
    "check_name",
    "figures_dir",
    "figures_root",
    "results_dir",
    "runs_dir",
    "study_outputs",
]

#: The git-ignored folder of the checkout where a user's own cells save (:func:`figures_root`).
USER_AREA = "user"

_study = False


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


def figures_root() -> Path:
    """The folder holding ``figures/<label>/`` and ``results/<label>/`` (absolute, not created).

    The study writes its (committed) figures and tables in the output root: the CLI's commands
    (:func:`study_outputs`), and the notebook kernels of the study runner, which it starts with
    ``$VPR_OUTPUT_DIR`` set. So does any caller who chose the output root (``--out``,
    ``$VPR_OUTPUT_DIR``). A user's own cells in the project checkout, with no root chosen, save
    into its git-ignored ``user/`` (:data:`USER_AREA`): they never modify a tracked file.
    """
    chosen = paths.chosen_root()
    if chosen is not None:
        return chosen
    checkout = paths.project_root()
    if checkout is None:
        return Path.cwd().resolve()
    return checkout if _study else checkout / USER_AREA


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
    d = (paths.output_root() if kind == "runs" else figures_root()) / kind
    if label:
        d = d / check_label(label)
    return paths.make_dir(d, paths.OUT_SETTING)


def figures_dir(label: str | None = None) -> Path:
    """``<figures root>/figures[/<label>]`` (:func:`figures_root`), created."""
    return _sub("figures", label)


def results_dir(label: str | None = None) -> Path:
    """``<figures root>/results[/<label>]`` (:func:`figures_root`), created."""
    return _sub("results", label)


def runs_dir(label: str | None = None) -> Path:
    """``<output root>/runs[/<label>]`` (executed notebooks), created."""
    return _sub("runs", label)
