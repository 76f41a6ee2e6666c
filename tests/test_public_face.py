"""Issue 47: the package's face. Every module declares ``__all__`` (names it really defines or
imports), no underscore name crosses a module boundary, each rule is raised from one site, and
docs/ARCHITECTURE.md lists the public names per module as ``benchmarks/code_size.py --names``
prints them."""

from __future__ import annotations

import importlib
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = (ROOT / "vpr_core", ROOT / "vpr_study")


def _code_size():
    spec = importlib.util.spec_from_file_location("code_size", ROOT / "benchmarks" / "code_size.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


code_size = _code_size()


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: p.name)
def test_every_module_declares_all(package):
    assert code_size.face(package)["no_all"] == []


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: p.name)
def test_all_names_exist(package):
    missing = []
    for mod, names in code_size.face(package)["all"].items():
        module = importlib.import_module(mod)
        missing += [f"{mod}.{n}" for n in names if not hasattr(module, n)]
    assert missing == []


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: p.name)
def test_no_underscore_name_crosses_modules(package):
    assert code_size.face(package)["underscore"] == []


def test_each_rule_is_raised_from_one_site():
    sites = code_size.rule_sites(ROOT / "vpr_core")
    assert {m: w for m, w in sites.items() if len(w) > 1} == {}


def test_architecture_lists_the_public_names():
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text(encoding="utf-8")
    assert code_size.names_markdown(ROOT / "vpr_core") in text, (
        "docs/ARCHITECTURE.md's public-name table is stale: paste "
        "`.venv/bin/python benchmarks/code_size.py --names` under 'Public names'"
    )


def test_the_face_measure_counts_what_it_says(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("__all__ = []\n")
    (pkg / "sub" / "__init__.py").write_text("from .a import f\n__all__ = ['f']\n")
    (pkg / "sub" / "a.py").write_text(
        "from ._b import _h\n__all__ = ['f']\ndef f():\n    raise ValueError(f'x {1} bad')\n"
        "def g():\n    raise ValueError(f'x {2} bad')\nclass _P: ...\n"
    )
    (pkg / "sub" / "_b.py").write_text("def _h(): ...\ndef k(): ...\n")
    f = code_size.face(pkg)
    assert f["public"] == [("pkg.sub.a", "f"), ("pkg.sub.a", "g")]
    assert f["no_all"] == ["pkg.sub._b"]
    assert f["underscore"] == [("pkg.sub.a", "_b", "_h")]
    assert code_size.rule_sites(pkg) == {"x {} bad": ["sub/a.py:4", "sub/a.py:6"]}
