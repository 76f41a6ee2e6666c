"""A study notebook is executed again only when something it reads changed (as ``make`` does,
but keyed by content): its folder's files, its parameters and every file or folder they name, the
package code, the installed packages and the ``VPR_*`` settings; while its outputs are intact."""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import os
import time
from collections.abc import Iterable, Iterator
from pathlib import Path

from vpr_core import paths, utils
from vpr_study.figures import NOTEBOOKS

__all__ = ["inputs_key", "notebook_key", "record", "up_to_date", "written_since"]

#: Settings that only say where things go or how progress looks (the key leaves them out).
_PLACEMENT = {"VPR_OUTPUT_DIR", "VPR_CACHE_DIR", "VPR_PROGRESS", "VPR_DASK_SCHEDULER"}


#: Folders a walk never enters: editor and interpreter litter, not what a notebook reads.
_LITTER = {".ipynb_checkpoints", "__pycache__", ".git"}


def _files(top: Path) -> list[Path]:
    """Every file under folder ``top``, symlinked folders followed (each real folder walked
    once, in name order: a link loop ends) and :data:`_LITTER` left out."""
    found: list[Path] = []
    seen: set[tuple[int, int]] = set()
    for folder, dirs, names in os.walk(top, followlinks=True):
        st = os.stat(folder)
        if (st.st_dev, st.st_ino) in seen:
            dirs.clear()
            continue
        seen.add((st.st_dev, st.st_ino))
        dirs[:] = sorted(d for d in dirs if d not in _LITTER)
        found += [p for p in (Path(folder, n) for n in names) if p.is_file()]
    return found


def _tree_digest(files: Iterable[Path], base: Path) -> str:
    digest = hashlib.sha256()
    for f in sorted(files):
        digest.update(f"{f.relative_to(base)}|{utils.file_sha256(f)}|".encode())
    return digest.hexdigest()


def _path_digest(path: Path) -> str:
    """A file by its content, a folder by every file under it (:func:`_files`)."""
    if path.is_file():
        return utils.file_sha256(path)
    return _tree_digest(_files(path), path)


def _code_digest() -> str:
    """Every source file of the two packages and pyproject.toml, by content."""
    checkout = Path(__file__).resolve().parents[1]
    files = [p for pkg in ("vpr_core", "vpr_study") for p in (checkout / pkg).rglob("*.py")]
    if (checkout / "pyproject.toml").is_file():
        files.append(checkout / "pyproject.toml")
    return _tree_digest(files, checkout)


def _packages() -> list[str]:
    return sorted(
        f"{d.metadata['Name']}=={d.version}"
        for d in importlib.metadata.distributions()
        if d.metadata["Name"]
    )


def _settings() -> dict[str, str]:
    """``VPR_*`` variables that can change a result; a file they name by its sha256 too."""
    out = {}
    for name, value in sorted(os.environ.items()):
        if name.startswith("VPR_") and name not in _PLACEMENT:
            is_file = Path(value).expanduser().is_file()
            out[name] = f"{value}|{utils.file_sha256(value) if is_file else ''}"
    return out


def _strings(value: object) -> Iterator[str]:
    """Every string in a parameter value (nested dicts, lists and tuples walked)."""
    if isinstance(value, str):
        yield value
    elif isinstance(value, dict):
        for item in value.values():
            yield from _strings(item)
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _strings(item)


def _named_path(text: str) -> Path | None:
    """The existing file or folder a parameter string names as a notebook resolves it
    (:func:`vpr_core.paths.find_input`), else None. A folder holding the cache or the output
    root is no input (the run itself writes in it)."""
    if not text.strip() or text.strip() == "." or "\n" in text or len(text) > 4096:
        return None
    try:
        found = paths.find_input(text).resolve()
    except (OSError, ValueError):  # not there, or not a path at all (a NUL, too long)
        return None
    if found.is_dir() and any(
        w.resolve().is_relative_to(found) for w in (paths.cache_root(), paths.output_root())
    ):
        return None
    return found


def _paths_digest(params: dict) -> dict[str, str]:
    """Every file or folder a parameter names (``root``, ``--opt ground_truth=...``), by
    content; ``label`` names outputs, not an input."""
    named = {
        text: _named_path(text)
        for key, value in params.items()
        if key != "label"
        for text in _strings(value)
    }
    return {text: _path_digest(path) for text, path in sorted(named.items()) if path is not None}


def inputs_key(params: dict) -> str:
    """The content key of what a study notebook reads besides its own folder, with ``params``:
    every file or folder a parameter names is hashed by content (symlinks followed)."""
    parts = {
        "parameters": params,
        "code": _code_digest(),
        "paths": _paths_digest(params),
        "packages": _packages(),
        "settings": _settings(),
        "output root": str(paths.output_root()),
    }
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()


def _users(path: Path, folder: Path) -> bool:
    """Whether ``path`` in the notebooks' ``folder`` is a user's notebook or its jupytext twin
    (a notebook outside the catalogue, :data:`vpr_study.figures.NOTEBOOKS`)."""
    rel = path.relative_to(folder)
    if path.suffix == ".ipynb":
        return path.stem not in NOTEBOOKS
    return rel.parts[:1] == ("scripts",) and path.suffix == ".py" and path.stem not in NOTEBOOKS


def notebook_key(notebook: Path, inputs: str) -> str:
    """The content key of one execution: every file of the notebook's folder tree (the
    notebook, a module or CSV a cell reads beside it or in a subfolder, symlinked folders
    followed) but a user's notebooks there (:func:`_users`: a Lab duplicate changes no key),
    and :func:`inputs_key`."""
    folder = notebook.parent
    files = [p for p in _files(folder) if p.stem == notebook.stem or not _users(p, folder)]
    return hashlib.sha256(f"{_tree_digest(files, folder)}|{inputs}".encode()).hexdigest()


def _record_path(label: str, stem: str) -> Path:
    return paths.cache_root() / "study" / label / f"{stem}.json"


def up_to_date(label: str, stem: str, key: str) -> dict | None:
    """The record of an earlier execution with this key whose outputs are all there unchanged,
    else None."""
    path = _record_path(label, stem)
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if record.get("key") != key or not record.get("outputs"):
        return None
    for name, digest in record["outputs"].items():
        if not Path(name).is_file() or utils.file_sha256(name) != digest:
            return None
    return record


def written_since(folders: Iterable[Path], since: float) -> list[Path]:
    """The files under ``folders`` modified at or after ``since`` (2 s of timestamp slack)."""
    return [
        p
        for folder in folders
        if folder.is_dir()
        for p in folder.iterdir()
        if p.is_file() and p.stat().st_mtime >= since - 2.0
    ]


def record(label: str, stem: str, key: str, outputs: Iterable[Path], seconds: float) -> None:
    """Remember that ``stem`` ran for ``label`` with ``key`` and wrote ``outputs``."""
    path = _record_path(label, stem)
    path.parent.mkdir(parents=True, exist_ok=True)
    entry = {
        "key": key,
        "outputs": {str(p): utils.file_sha256(p) for p in sorted(outputs)},
        "seconds": round(seconds, 1),
        "when": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(entry, indent=1))
    os.replace(tmp, path)
