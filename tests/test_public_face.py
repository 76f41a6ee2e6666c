"""Issues 47, 52 and 59: the package's faces. Every module declares ``__all__`` (names it really
defines or imports), nothing outside ``vpr_core`` (``vpr_study``, the notebooks, the starter,
README and docs code) imports past the flat face ``vpr_core`` (nor, outside ``vpr_study``, past
``vpr_study`` and ``vpr_study.viz``), the face holds about 80 names, each rule is raised from one
site, and docs/ARCHITECTURE.md lists the face as ``benchmarks/code_size.py --names`` prints it."""

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


def test_nothing_outside_the_package_reaches_past_a_face():
    assert code_size.reach_past(ROOT / "vpr_core") == []


def test_the_face_is_what_callers_use():
    """One flat face of at most about 80 names (issue 59), and vpr_study needs far fewer of the
    core's names than the 74 it imported before it."""
    import vpr_core

    assert len(vpr_core.__all__) <= 82
    assert len(code_size.core_names_used(ROOT / "vpr_core")) <= 50


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: p.name)
def test_a_lazy_face_lists_what_it_loads(package):
    """The top-level faces load their names on first use (``vpr-study --help`` loads no torch):
    ``__all__`` is the table they load from, and every name loads."""
    module = importlib.import_module(package.name)
    assert set(module.__all__) - {"__version__"} == set(module._FACE)
    for name in module._FACE:
        assert getattr(module, name) is not None


def test_each_rule_is_raised_from_one_site():
    sites = code_size.rule_sites(ROOT / "vpr_core")
    assert {m: w for m, w in sites.items() if len(w) > 1} == {}


def test_architecture_lists_the_faces():
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text(encoding="utf-8")
    assert code_size.names_markdown(ROOT / "vpr_core") in text, (
        "docs/ARCHITECTURE.md's table of faces is stale: paste "
        "`.venv/bin/python benchmarks/code_size.py --names` under 'Faces'"
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
    assert f["faces"] == {"pkg": []} and f["indexes"] == {"pkg.sub": ["f"]}
    assert code_size.rule_sites(pkg) == {"x {} bad": ["sub/a.py:4", "sub/a.py:6"]}
    # the callers: the top-level face passes, anything deeper is listed; benchmarks (and
    # tests) may import modules; outside vpr_study, its faces are vpr_study and vpr_study.viz
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "benchmarks" / "b.py").write_text("from pkg.sub.a import g\n")
    (tmp_path / "README.md").write_text(
        "```python\nfrom pkg import sub\nfrom pkg.sub import f\nfrom vpr_study.viz import save\n"
        "from vpr_study.runner import check_parameters\n```\n"
    )
    (tmp_path / "vpr_study").mkdir()
    (tmp_path / "vpr_study" / "starter.ipynb").write_text('{"cells": []}')
    (tmp_path / "vpr_study" / "x.py").write_text("from pkg import f\nimport pkg.sub._b\n")
    assert code_size.reach_past(pkg) == [
        "vpr_study/x.py: pkg.sub._b",
        "README.md: pkg.sub",
        "README.md: vpr_study.runner",
    ]
