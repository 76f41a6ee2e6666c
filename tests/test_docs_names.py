"""Every dotted name and file path the README and docs name resolves (issue 59): a reader who
follows `vpr_core.x.y` or `vpr_core/x/y.py` finds it."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: Folders a relative file name in the docs is read from (the project, then the packages').
BASES = (ROOT, ROOT / "vpr_core", ROOT / "vpr_study")
#: The files the docs name that a user or the package makes, never in the repository: a
#: dataset's ground truth, the generator's manifest, the starter ``make lab`` copies.
USER_FILES = {
    "ground_truth.npy",
    "ground_truth_new.npy",
    "manifest.json",
    "user/notebooks/00_start_here.ipynb",
}
_SKIP = {".venv", ".cache", ".git", "runs", "user"}


def _tracked(name: str) -> bool:
    """A bare file name (no folder) found anywhere in the project, outside caches and runs."""
    return any(not _SKIP.intersection(p.relative_to(ROOT).parts) for p in ROOT.rglob(name))


_TICKED = re.compile(r"`([^`\n]+)`")
_DOTTED = re.compile(r"^(vpr_core|vpr_study)(\.[A-Za-z_]\w*)+$")
_FILE = re.compile(r"^[\w./-]+\.(py|md|csv|png|ipynb|toml|json|npy|txt)$")


def _resolves(dotted: str) -> bool:
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def _names() -> list[tuple[str, str]]:
    found = []
    for md in DOCS:
        for token in _TICKED.findall(md.read_text(encoding="utf-8")):
            token = token.strip().rstrip("(),:;").split("(")[0]
            if _DOTTED.match(token) or (
                _FILE.match(token) and "<" not in token and "*" not in token
            ):
                found.append((md.name, token))
    return sorted(set(found))


NAMES = _names()


def test_the_docs_name_things():
    assert len(NAMES) > 100


@pytest.mark.parametrize("where,name", NAMES, ids=[f"{w}:{n}" for w, n in NAMES])
def test_a_named_thing_exists(where, name):
    if _DOTTED.match(name):
        assert _resolves(name), f"{where} names {name}, which does not resolve"
    elif name not in USER_FILES:
        if name.startswith("../shared/") and not (ROOT.parent / "shared").is_dir():
            pytest.skip("../shared is not beside this checkout (CI puts it there)")
        found = any((base / name).exists() for base in BASES) or (
            "/" not in name and _tracked(name)
        )
        assert found, f"{where} names {name}: no such file"
