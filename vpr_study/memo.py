"""A study notebook is executed again only when something it reads changed (as ``make`` does,
but keyed by content): its text, parameters, the package code, the data, the installed
packages and the ``VPR_*`` settings; and only while its recorded outputs are intact."""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import os
import time
from collections.abc import Iterable
from pathlib import Path

from vpr_core import paths
from vpr_core.utils import file_sha256

#: Settings that only say where things go or how progress looks (the key leaves them out).
_PLACEMENT = {"VPR_OUTPUT_DIR", "VPR_CACHE_DIR", "VPR_PROGRESS", "VPR_DASK_SCHEDULER"}


def _tree_digest(files: Iterable[Path], base: Path) -> str:
    digest = hashlib.sha256()
    for f in sorted(files):
        digest.update(f"{f.relative_to(base)}|{file_sha256(f)}|".encode())
    return digest.hexdigest()


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
            out[name] = f"{value}|{file_sha256(value) if is_file else ''}"
    return out


def _data_digest(root: str | None) -> str:
    """A dataset root by the content of every file under it (None: the generated set, made by
    the package code, which the key holds already)."""
    if root is None:
        return ""
    base = Path(root).expanduser()
    files = [base] if base.is_file() else [p for p in base.rglob("*") if p.is_file()]
    return _tree_digest(files, base.parent if base.is_file() else base)


def inputs_key(params: dict) -> str:
    """The content key of what a study notebook reads besides its own text, with ``params``."""
    parts = {
        "parameters": params,
        "code": _code_digest(),
        "data": _data_digest(params.get("root")),
        "packages": _packages(),
        "settings": _settings(),
        "output root": str(paths.output_root()),
    }
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()


def notebook_key(notebook: Path, inputs: str) -> str:
    """The content key of one execution: the notebook's text, the Python files beside it (a
    module a cell imports from its folder) and :func:`inputs_key`."""
    helpers = _tree_digest(notebook.parent.glob("*.py"), notebook.parent)
    return hashlib.sha256(f"{file_sha256(notebook)}|{helpers}|{inputs}".encode()).hexdigest()


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
        if not Path(name).is_file() or file_sha256(name) != digest:
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
        "outputs": {str(p): file_sha256(p) for p in sorted(outputs)},
        "seconds": round(seconds, 1),
        "when": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(entry, indent=1))
    os.replace(tmp, path)
