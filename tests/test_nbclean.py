"""vpr_study.nbclean and tools/nbstrip (issue 60 item 5): the git filter fails closed. A study
notebook it cannot strip stops the ``git add`` with a sentence (the filter is ``required``); a
lone surrogate is stripped by keeping its JSON escape; outputs never reach git through an error.
Each case is a real ``git add`` in a temporary repository."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest
from test_lab import REPO, TOUR, _clone, _executed, _git, _tour

from vpr_study import nbclean

needs_make = pytest.mark.skipif(
    shutil.which("make") is None or shutil.which("git") is None, reason="make and git are needed"
)


def _deep(depth: int = 3000) -> str:
    """The tour, run, with a cell output nested ``depth`` lists deep (Python's JSON parser
    gives up at about 1,000)."""
    nb = _executed(_tour())
    text = json.dumps(nb, indent=1)
    return text.replace('"ran\\n"', "[" * depth + "1" + "]" * depth, 1)


def _surrogate() -> str:
    """The tour, run, with a lone surrogate escape in an output and in a code cell."""
    nb = _executed(_tour())
    code = next(c for c in nb["cells"] if c["cell_type"] == "code")
    code["source"] = ["x = '\\ud800'  # a lone surrogate\n"]
    return json.dumps(nb, indent=1).replace('"ran\\n"', '"\\udc80 ran\\n"', 1)  # an escape


def _broken() -> str:
    return json.dumps(_executed(_tour()), indent=1)[:-40]  # a save cut short


@pytest.mark.parametrize(
    ("data", "why"),
    [
        (lambda: _deep().encode(), "RecursionError"),
        (lambda: _broken().encode(), "not JSON"),
        (lambda: b"\xff\xfe{}", "UnicodeDecodeError"),
        (lambda: b'{"nbformat": 3, "worksheets": []}', "its nbformat is 3"),
    ],
    ids=["nested 3,000 deep", "cut short", "not UTF-8", "nbformat 3"],
)
def test_a_study_notebook_the_filter_cannot_strip_is_refused_in_a_sentence(data, why):
    done = subprocess.run(
        [sys.executable, "vpr_study/nbclean.py", "--clean", TOUR],
        cwd=REPO,
        input=data(),
        capture_output=True,
    )
    err = done.stderr.decode()
    assert done.returncode == 1 and done.stdout == b"", err
    assert err.count("\n") == 1 and "Traceback" not in err and why in err
    assert err.startswith(f"tools/nbstrip: {TOUR}: not added, its outputs would reach git")


def test_a_lone_surrogate_is_stripped_keeping_its_escape():
    out, why = nbclean._stripped(_surrogate().encode(), TOUR)
    assert why is None
    text = out.decode("utf-8")  # encodes, unlike the parsed text
    nb = json.loads(text)
    assert "\\ud800" in text and '"output_type"' not in text
    assert all(c.get("outputs", []) == [] for c in nb["cells"])


@needs_make
@pytest.mark.parametrize(
    ("make", "added"),
    [(_deep, False), (_broken, False), (_surrogate, True)],
    ids=["nested 3,000 deep", "cut short", "lone surrogate"],
)
def test_git_add_never_stages_a_study_notebooks_outputs(tmp_path, make, added):
    clone = _clone(tmp_path)
    subprocess.run(["make", "-s", "git-filter"], cwd=clone, check=True, timeout=120)
    assert _git(clone, "config", "--local", "filter.nbstripout.required").stdout.strip() == "true"
    (clone / TOUR).write_text(make(), encoding="utf-8")
    done = _git(clone, "add", TOUR, check=False)
    staged = _git(clone, "show", f":{TOUR}").stdout
    assert '"output_type"' not in staged  # outputs never staged
    if added:
        assert done.returncode == 0, done.stderr
        assert json.loads(staged)["cells"] and "\\ud800" in staged
    else:
        assert done.returncode != 0
        assert f"tools/nbstrip: {TOUR}: not added, its outputs would reach git" in done.stderr
        assert _git(clone, "diff", "--cached", "--name-only").stdout == ""


@needs_make
def test_git_add_without_a_python_stops_for_a_study_notebook(tmp_path):
    clone = _clone(tmp_path)
    subprocess.run(["make", "-s", "git-filter"], cwd=clone, check=True, timeout=120)
    bare = tmp_path / "bin"
    bare.mkdir()
    for tool in ("cat", "echo", "sh", "git"):
        (bare / tool).symlink_to(shutil.which(tool))
    (clone / TOUR).write_text(json.dumps(_executed(_tour())), encoding="utf-8")
    done = subprocess.run(
        ["git", "add", TOUR], cwd=clone, capture_output=True, text=True, env={"PATH": str(bare)}
    )
    assert done.returncode != 0 and "no Python 3" in done.stderr
    assert _git(clone, "diff", "--cached", "--name-only").stdout == ""
    assert sys.executable  # the tests' Python is not on that PATH
