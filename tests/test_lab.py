"""JupyterLab and git with the study notebooks (issue 33 item 3; issue 44 items 2, 7 and 8;
issue 45 item 2): the save hook strips exactly the committed study notebooks, a malformed one is
saved untouched, the git filter works in any clone and without .venv, a user's starter notebook
in user/notebooks/ runs end to end, and Lab lists each notebook once."""

from __future__ import annotations

import copy
import json
import logging
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from vpr_study import lab

REPO = Path(__file__).resolve().parents[1]
NB_DIR = REPO / "notebooks"
TOUR = "notebooks/01_pipeline_tour.ipynb"

needs_git = pytest.mark.skipif(shutil.which("git") is None, reason="git is needed")
needs_make = pytest.mark.skipif(
    shutil.which("make") is None or shutil.which("git") is None, reason="make and git are needed"
)


def _git(cwd: Path, *args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        check=check,
    )


def _executed(nb: dict) -> dict:
    """``nb`` as JupyterLab saves it after running every cell: outputs, execution counts, the
    kernel's language_info, widget state and cell timing metadata."""
    nb = copy.deepcopy(nb)
    nb["metadata"]["language_info"] = {"name": "python", "version": "3.11.9"}
    nb["metadata"]["widgets"] = {"application/vnd.jupyter.widget-state+json": {"state": {}}}
    for i, cell in enumerate(nb["cells"]):
        if cell["cell_type"] == "code":
            cell["execution_count"] = i + 1
            cell["outputs"] = [{"output_type": "stream", "name": "stdout", "text": ["ran\n"]}]
            cell["metadata"]["execution"] = {"iopub.status.idle": "2026-01-01T00:00:00Z"}
    return nb


def _tour() -> dict:
    return json.loads((REPO / TOUR).read_text(encoding="utf-8"))


# 1. The save hook: exactly the committed study notebooks, by path ------------------------------


def test_the_study_notebooks_of_the_hook_are_the_committed_ones():
    if shutil.which("git") and (REPO / ".git").exists():
        listed = _git(REPO, "ls-files", "notebooks/*.ipynb").stdout.split()
    else:  # a copy without git: the folder
        listed = [f"notebooks/{p.name}" for p in NB_DIR.glob("*.ipynb")]
    assert set(listed) == lab.STUDY_NOTEBOOKS


class _Server:
    """What the hook reads of jupyter_server's contents manager: its root and its log."""

    def __init__(self, root: Path) -> None:
        self.root_dir = str(root)
        self.log = logging.getLogger("test_lab.server")


@pytest.mark.parametrize(
    ("path", "root", "strips"),
    [
        (TOUR, None, True),
        ("/notebooks/06_comparison.ipynb", None, True),
        (TOUR, REPO, True),
        ("01_pipeline_tour.ipynb", NB_DIR, True),  # a server started in notebooks/
        ("notebooks/01_pipeline_tour-Copy1.ipynb", None, False),  # Lab's "Duplicate"
        ("notebooks/08_mine.ipynb", None, False),
        ("notebooks/my_scheme.ipynb", None, False),
        ("user/notebooks/x.ipynb", None, False),
        ("user/notebooks/00_start_here.ipynb", REPO, False),
        ("01_pipeline_tour-Copy1.ipynb", NB_DIR, False),
        ("elsewhere/notebooks/01_pipeline_tour.ipynb", REPO, False),
    ],
)
def test_the_save_hook_strips_exactly_the_study_notebooks(path, root, strips):
    model = {"type": "notebook", "content": _executed(_tour())}
    lab.strip_outputs(model, path, _Server(root) if root else None)
    cells = [c for c in model["content"]["cells"] if c["cell_type"] == "code"]
    if strips:
        assert all(c["outputs"] == [] and c["execution_count"] is None for c in cells)
        assert "language_info" not in model["content"]["metadata"]
        assert json.loads(json.dumps(model["content"])) == _tour()  # as git keeps it
    else:
        assert model["content"] == _executed(_tour())  # a user's outputs: kept, untouched


def test_the_save_hook_drops_labs_view_state_from_a_study_notebook_and_its_twin():
    """Issue 54 item 2: a click on a cell's collapser saves ``jupyter.source_hidden``; the
    study notebook and its jupytext twin are saved without it, a user's notebook with it."""
    nb = _tour()
    nb["cells"][1]["metadata"]["jupyter"] = {"source_hidden": True}
    nb["cells"][2]["metadata"]["collapsed"] = False
    for path, kept in ((TOUR, False), ("notebooks/01_pipeline_tour-Copy1.ipynb", True)):
        model = {"type": "notebook", "content": copy.deepcopy(nb)}
        lab.strip_outputs(model, path, None)
        assert (model["content"] == nb) is kept
        assert (model["content"] == _tour()) is not kept
    twin = (REPO / TWIN).read_text(encoding="utf-8")
    marked = twin.replace("# %%\n", '# %% jupyter={"source_hidden": true}\n', 1)
    assert marked != twin
    model = {"type": "file", "format": "text", "content": marked}
    lab.strip_outputs(model, TWIN, None)
    assert model["content"] == twin
    mine = {"type": "file", "format": "text", "content": marked}
    lab.strip_outputs(mine, "notebooks/scripts/08_mine.py", None)
    assert mine["content"] == marked


def test_the_save_hook_leaves_files_and_folders_alone():
    model = {"type": "file", "content": "x", "format": "text"}
    lab.strip_outputs(model, TOUR)
    assert model == {"type": "file", "content": "x", "format": "text"}


MALFORMED = {
    "no cells": ({"nbformat": 4, "nbformat_minor": 5, "metadata": {}}, "no list of 'cells'"),
    "nbformat 3": (
        {"nbformat": 3, "nbformat_minor": 0, "metadata": {}, "worksheets": [{"cells": []}]},
        "nbformat is 3, not 4",
    ),
    "a list": ([{"cells": []}], "JSON list, not an object"),
    "a string": ("not a notebook", "JSON str, not an object"),
    "None": (None, "JSON NoneType"),
    "a cell not an object": (
        {"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": ["print(1)"]},
        "cell 0 is not a JSON object",
    ),
    "cells not a list": (
        {"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": {"a": 1}},
        "no list of 'cells'",
    ),
    "outputs not a list": (
        {
            "nbformat": 4,
            "nbformat_minor": 5,
            "metadata": {},
            "cells": [{"cell_type": "code", "source": "1", "metadata": {}, "outputs": 3}],
        },
        "cell 0's 'outputs' is not a list",
    ),
}


@pytest.mark.parametrize("case", list(MALFORMED))
@pytest.mark.parametrize("server", [False, True], ids=["module log", "server log"])
def test_a_malformed_study_notebook_is_saved_untouched_with_a_logged_reason(case, server, caplog):
    content, why = MALFORMED[case]
    model = {"type": "notebook", "content": copy.deepcopy(content)}
    with caplog.at_level(logging.WARNING):
        lab.strip_outputs(model, TOUR, _Server(REPO) if server else None)  # never raises
    assert model["content"] == content
    (record,) = [r for r in caplog.records if "untouched" in r.getMessage()]
    assert record.name == ("test_lab.server" if server else "vpr_study.lab")
    assert TOUR in record.getMessage() and why in record.getMessage()


def test_the_filter_command_refuses_a_malformed_notebook_with_its_reason():
    """Issue 60 item 5: the filter fails closed (status 1, nothing on stdout, the reason)."""
    for text in ('{"nbformat": 3, "worksheets": []}', "not json", "[1, 2]"):
        done = subprocess.run(
            [sys.executable, "-m", "vpr_study.lab"], input=text, capture_output=True, text=True
        )
        assert done.returncode == 1 and done.stdout == ""
        assert "not added, its outputs would reach git" in done.stderr
    # a study notebook with outputs: stripped, byte-identical to the committed file
    executed = json.dumps(_executed(_tour()), indent=1, ensure_ascii=False)
    done = subprocess.run(
        [sys.executable, "-m", "vpr_study.lab"], input=executed.encode(), capture_output=True
    )
    assert done.returncode == 0 and done.stdout == (REPO / TOUR).read_bytes()


# 2. The git filter: a relative command, working without .venv ---------------------------------


def _strip_command() -> str:
    """The filter command that ``make git-filter`` writes (the Makefile's STRIP)."""
    (value,) = re.findall(r"^STRIP\s*:=\s*(.+)$", (REPO / "Makefile").read_text(), re.M)
    return value.strip()


def test_the_makefile_writes_a_relative_filter_command():
    command = _strip_command()
    assert command == "sh tools/nbstrip"
    makefile = (REPO / "Makefile").read_text()
    assert "filter.nbstripout.clean '$(STRIP) --clean %f'" in makefile  # git gives the path
    assert "abspath" not in command and "$(PY)" not in command and "/.venv" not in command
    assert not any(Path(word).is_absolute() for word in command.split())
    script = (REPO / "tools" / "nbstrip").read_text()
    assert script.startswith("#!/bin/sh\n") and "vpr_study/nbclean.py" in script
    git_filter = re.search(r"^git-filter:(.*?)\n\n", makefile, re.M | re.S)
    assert git_filter and "$(STAMP)" not in git_filter.group(0).split("\n")[0]  # needs no .venv
    assert "$(abspath" not in git_filter.group(0)
    assert re.search(r"^install: \$\(STAMP\) git-filter$", makefile, re.M)


def test_the_filter_module_needs_only_the_standard_library():
    """vpr_study/nbclean.py run as git runs it, by a Python that has no third-party package
    and does not see this project (``-I -S``): it reads the catalogue and strips."""
    executed = json.dumps(_executed(_tour()), indent=1, ensure_ascii=False)
    done = subprocess.run(
        [sys.executable, "-I", "-S", "vpr_study/nbclean.py", "--clean", TOUR],
        cwd=REPO,
        input=executed.encode(),
        capture_output=True,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout == (REPO / TOUR).read_bytes()
    source = (REPO / "vpr_study" / "nbclean.py").read_text()
    imported = set(re.findall(r"^\s*(?:from|import) ([\w.]+)", source, re.M))
    assert imported <= {
        "__future__",
        "importlib.util",
        "json",
        "re",
        "sys",
        "pathlib",
        "typing",
        "vpr_study.figures",
    }, imported


def _clone(tmp_path: Path, name: str = "clone") -> Path:
    """A git clone of this repository, its filter files as in the working tree (what is tested),
    without .venv."""
    clone = tmp_path / name
    _git(tmp_path, "clone", "-q", "--shared", str(REPO), str(clone))
    for f in (
        "Makefile",
        ".gitattributes",
        "tools/nbstrip",
        "vpr_study/lab.py",
        "vpr_study/nbclean.py",
        "vpr_study/figures.py",
        TOUR,
        TWIN,
    ):
        (clone / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / f, clone / f)
    _git(clone, "add", "-A")
    _git(clone, "commit", "-qm", "the working tree's filter", check=False)
    assert not (clone / ".venv").exists()
    return clone


def _fake_venv(clone: Path) -> None:
    """``.venv/bin/python`` of ``clone``: this interpreter (a wrapper script, so that the
    interpreter finds its own environment)."""
    py = clone / ".venv" / "bin" / "python"
    py.parent.mkdir(parents=True)
    py.write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    py.chmod(0o755)


TWIN = "notebooks/scripts/01_pipeline_tour.py"


def _lab_views(clone: Path) -> dict[str, str]:
    """What a Lab session leaves in ``clone``: the study notebook run with a collapsed cell and
    its twin with the collapsed cell's marker; a Lab duplicate and a user's own notebook with
    outputs. ``{path: text written}``."""
    nb = _executed(_tour())
    nb["cells"][1]["metadata"]["jupyter"] = {"source_hidden": True}
    nb["cells"][2]["metadata"]["collapsed"] = True
    text = json.dumps(nb, indent=1, ensure_ascii=False) + "\n"
    twin = (REPO / TWIN).read_text(encoding="utf-8")
    first = next(line for line in twin.splitlines() if line.startswith("# %%"))
    twin = twin.replace(first + "\n", first + ' jupyter={"source_hidden": true}\n', 1)
    written = {
        TOUR: text,
        TWIN: twin,
        "notebooks/01_pipeline_tour-Copy1.ipynb": text,
        "notebooks/08_mine.ipynb": text,
    }
    for path, content in written.items():
        (clone / path).write_text(content, encoding="utf-8")
    return written


def _staged_as_the_readme_says(clone: Path, written: dict[str, str]) -> None:
    """``git add`` of each kind: the study notebook and its twin as committed (status clean),
    the duplicate and the user's notebook with their outputs, as written."""
    added = _git(clone, "add", "-A")
    assert added.stderr == "", added.stderr
    for path in (TOUR, TWIN):
        assert _git(clone, "show", f":{path}").stdout == (REPO / path).read_text(encoding="utf-8")
    for path in ("notebooks/01_pipeline_tour-Copy1.ipynb", "notebooks/08_mine.ipynb"):
        assert _git(clone, "show", f":{path}").stdout == written[path]
    assert sorted(_git(clone, "status", "--porcelain").stdout.split()) == sorted(
        ["A", "notebooks/01_pipeline_tour-Copy1.ipynb", "A", "notebooks/08_mine.ipynb"]
    )
    shown = _git(clone / "notebooks", "diff", "--cached").stdout  # textconv, from a subfolder
    assert "ran" in shown and "01_pipeline_tour.ipynb" not in shown
    assert _git(clone, "diff", "HEAD", "--", TOUR, TWIN).stdout == ""


@needs_make
def test_git_keeps_each_kind_of_notebook_as_the_readme_says_with_or_without_venv(tmp_path):
    """Issue 54 item 2: in a clone without .venv (a fresh clone, or after ``make clean``) and
    after ``make install``, ``git add`` strips the study's notebook and its twin (outputs and
    Lab's view state) and keeps a Lab duplicate and a user's own notebook as they are."""
    clone = _clone(tmp_path)
    subprocess.run(["make", "-s", "git-filter"], cwd=clone, check=True, timeout=120)
    assert _git(clone, "config", "--local", "filter.nbstripout.clean").stdout.strip() == (
        "sh tools/nbstrip --clean %f"
    )
    assert _git(clone, "config", "--local", "diff.ipynb.textconv").stdout.strip() == (
        "sh tools/nbstrip"
    )
    _staged_as_the_readme_says(clone, _lab_views(clone))  # no .venv
    _git(clone, "reset", "-q", "--hard")
    _git(clone, "clean", "-qfd")
    # after `make install` (its stamps fresh: it installs nothing, it sets the filter)
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / ".installed").touch()
    _git(clone, "config", "--local", "--unset", "filter.nbstripout.clean")
    subprocess.run(["make", "-s", "install", f"VENV={venv}"], cwd=clone, check=True, timeout=120)
    _fake_venv(clone)
    _staged_as_the_readme_says(clone, _lab_views(clone))
    # the clone moved: the same relative command works there
    _git(clone, "reset", "-q", "--hard")
    moved = clone.rename(tmp_path / "moved")
    (moved / TOUR).write_text(_lab_views(moved)[TOUR], encoding="utf-8")
    assert _git(moved, "status", "--porcelain", "--", TOUR).stdout == ""


@needs_git
def test_without_a_python_the_filter_fails_closed_on_study_notebooks_and_says_so(tmp_path):
    """Issue 60 item 5: without a Python 3 a notebook under notebooks/ is refused (git stops
    the add); another file passes unchanged; each time, it says why."""
    clone = _clone(tmp_path)
    text = json.dumps(_executed(_tour()))
    bare = tmp_path / "bin"
    bare.mkdir()
    for tool in ("cat", "echo", "sh"):
        found = shutil.which(tool)
        if found:
            (bare / tool).symlink_to(found)
    for path, status in ((TOUR, 1), (TOUR, 1), ("user/notebooks/mine.ipynb", 0)):
        done = subprocess.run(
            ["sh", "tools/nbstrip", "--clean", path],
            cwd=clone,
            input=text,
            capture_output=True,
            text=True,
            env={"PATH": str(bare)},
        )
        assert done.returncode == status and done.stdout == ("" if status else text)
        assert "no Python 3" in done.stderr


# 3. A clean tree after a Lab session (issue 33 item 3) ------------------------------------------


def _lab_save(nb_path: Path, hook: bool = False) -> None:
    """What JupyterLab's autosave writes after running every cell (:func:`_executed`);
    jupytext rewrites the twin in notebooks/scripts/. ``hook``: through ``make lab``'s save
    hook, written as jupyter_server's file manager does."""
    import jupytext
    import nbformat

    nb = _executed(json.loads(nb_path.read_text()))
    if hook:
        model = {"type": "notebook", "content": nb}
        lab.strip_outputs(model, f"notebooks/{nb_path.name}", None)
        nbformat.write(nbformat.from_dict(model["content"]), nb_path, version=nbformat.NO_CONVERT)
    else:
        nb_path.write_text(json.dumps(nb, indent=1))
    twin = nb_path.parent / "scripts" / f"{nb_path.stem}.py"
    jupytext.write(jupytext.read(nb_path), twin, fmt="py:percent")


def _lab_clone(tmp_path: Path, name: str) -> tuple[Path, Path]:
    """A git repository holding the Makefile, .gitattributes, the filter script and notebook 01
    with its twin, a .venv whose Python is this one, and a stand-in install folder whose stamps
    are fresh (``make VENV=...`` installs nothing)."""
    clone = tmp_path / name
    (clone / "notebooks" / "scripts").mkdir(parents=True)
    for f in (
        "Makefile",
        "pyproject.toml",
        ".gitattributes",
        "tools/nbstrip",
        "vpr_study/nbclean.py",
        "vpr_study/figures.py",
        TOUR,
    ):
        (clone / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / f, clone / f)
    shutil.copy2(REPO / TWIN, clone / TWIN)
    (clone / ".gitignore").write_text(".venv/\n")
    venv = tmp_path / f"{name}-venv"
    (venv / "bin").mkdir(parents=True)
    (venv / ".installed").touch()
    (venv / ".lab-installed").touch()
    _git(clone, "init", "-q")
    _git(clone, "add", ".")
    _git(clone, "commit", "-qm", "clone")
    _fake_venv(clone)
    return clone, venv


@needs_make
def test_make_lab_installs_the_output_filter_so_a_lab_session_leaves_git_status_clean(tmp_path):
    attrs = (REPO / ".gitattributes").read_text().splitlines()
    assert "*.ipynb filter=nbstripout" in attrs and "*.ipynb diff=ipynb" in attrs
    # without the filter a Lab session changes the notebook (what issue 33 saw)
    bare, _ = _lab_clone(tmp_path, "bare")
    _lab_save(bare / TOUR)
    assert "language_info" in _git(bare, "diff").stdout and "outputs" in _git(bare, "diff").stdout
    _git(bare, "add", "-u")
    assert _git(bare, "status", "--porcelain").stdout.split() == ["M", TOUR]
    # make lab's filter target, then the same session: no change, nothing to commit
    clone, venv = _lab_clone(tmp_path, "clone")
    subprocess.run(["make", "-s", "git-filter", f"VENV={venv}"], cwd=clone, check=True)
    _lab_save(clone / TOUR)
    assert _git(clone, "diff").stdout == ""  # the .py twin rewritten by jupytext: unchanged too
    _git(clone, "add", "-u")  # git status lists a resized file until its stat is refreshed
    assert _git(clone, "status", "--porcelain").stdout == ""
    # with make lab's save hook too: the saved file is the committed one, git status clean as is
    hooked, venv = _lab_clone(tmp_path, "hooked")
    subprocess.run(["make", "-s", "git-filter", f"VENV={venv}"], cwd=hooked, check=True)
    _lab_save(hooked / TOUR, hook=True)
    assert _git(hooked, "status", "--porcelain").stdout == ""
    assert (hooked / TOUR).read_bytes() == (REPO / TOUR).read_bytes()


@needs_make
def test_make_lab_installs_the_lab_extra_once_and_opens_the_starter(tmp_path):
    clone, venv = _lab_clone(tmp_path, "clone")
    dry = subprocess.run(
        ["make", "-n", "lab", f"VENV={venv}"], cwd=clone, capture_output=True, text=True, check=True
    ).stdout
    assert "pip install" not in dry and "jupyter lab" in dry
    assert "git config --local filter.nbstripout.clean 'sh tools/nbstrip --clean %f'" in dry
    assert "--ContentsManager.pre_save_hook=vpr_study.lab.strip_outputs" in dry
    assert f'--ServerApp.root_dir="{clone}"' in dry  # notebooks/ and user/notebooks/ visible
    starter = f"{lab.USER_NOTEBOOKS}/{lab.STARTER_NAME}"
    assert f"--LabApp.default_url=/lab/tree/{starter}" in dry
    assert dry.index("-m vpr_study.lab init") < dry.index("jupyter lab")  # created, then opened
    (venv / ".lab-installed").unlink()  # a fresh clone: installed once
    dry = subprocess.run(
        ["make", "-n", "lab", f"VENV={venv}"], cwd=clone, capture_output=True, text=True, check=True
    ).stdout
    assert "pip install -q -e '.[dev,lab]'" in dry and "touch" in dry


# 4. A user's own notebooks: user/notebooks/ and the starter -------------------------------------


def _checkout(tmp_path: Path) -> Path:
    """A minimal checkout of this project (what vpr_core.paths.project_root recognises)."""
    from vpr_core import paths

    root = tmp_path / "checkout"
    (root / "notebooks").mkdir(parents=True)
    (root / "pyproject.toml").write_text(f'[project]\nname = "{paths.PROJECT_NAME}"\n')
    return root


def test_init_writes_the_starter_when_absent_and_never_replaces_a_users_file(
    tmp_path, capsys, monkeypatch
):
    root = _checkout(tmp_path)
    path = lab.init(root)
    assert path == root / "user" / "notebooks" / "00_start_here.ipynb"
    assert path.read_bytes() == lab.starter_source()
    assert "the starter notebook" in capsys.readouterr().out
    path.write_text("my own work")
    assert lab.init(root) == path and path.read_text() == "my own work"
    assert "kept" in capsys.readouterr().out
    # the command make lab runs, from the checkout (and a clear error outside one)
    path.unlink()
    done = subprocess.run(
        [sys.executable, "-m", "vpr_study.lab", "init"], cwd=root, capture_output=True, text=True
    )
    assert done.returncode == 0 and path.read_bytes() == lab.starter_source()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    with pytest.raises(FileNotFoundError, match="not inside a checkout.*--root"):
        lab.init()
    assert not (elsewhere / "user").exists()


@needs_git
def test_the_starter_ships_in_the_package_and_a_users_notebooks_are_ignored():
    import nbformat

    nb = nbformat.reads(lab.starter_source().decode(), as_version=4)
    nbformat.validate(nb)
    assert lab.malformed(json.loads(lab.starter_source())) is None
    assert not (NB_DIR / lab.STARTER_NAME).exists()  # not among the study notebooks
    ignored = _git(
        REPO, "check-ignore", "-q", f"{lab.USER_NOTEBOOKS}/{lab.STARTER_NAME}", check=False
    )
    assert ignored.returncode == 0
    source = "\n".join(c.source for c in nb.cells if c.cell_type == "code")
    for shown in (
        "load_dataset(",
        "def boxes(self, image",
        "nn.Module",
        'weighting="contrast"',
        "compare(",
        "plot_pr_curves(",
        "save(",
    ):
        assert shown in source, shown
    assert all(not c.get("outputs") for c in nb.cells if c.cell_type == "code")


def _suggested_code(nb) -> list[str]:
    """The code the starter's Markdown suggests: each fenced ``python`` block. A call in
    inline code of a name the notebook imports (``load_dataset(...)``) must be one of them or
    a code cell's: what the starter shows, it runs."""
    import ast

    markdown = "\n".join(c.source for c in nb.cells if c.cell_type == "markdown")
    blocks = re.findall(r"```python\n(.*?)```", markdown, re.S)
    code = "\n".join([*(c.source for c in nb.cells if c.cell_type == "code"), *blocks])
    imported = {
        a.asname or a.name
        for node in ast.walk(ast.parse(code))
        if isinstance(node, ast.ImportFrom)
        for a in node.names
    }
    for span in re.findall(r"`([^`\n]+)`", re.sub(r"```.*?```", "", markdown, flags=re.S)):
        try:
            tree = ast.parse(span, mode="eval").body
        except SyntaxError:
            continue
        if isinstance(tree, ast.Call) and getattr(tree.func, "id", None) in imported:
            assert "..." in span or span in code, f"the Markdown shows {span} but runs it nowhere"
    return blocks


def test_the_starter_notebook_runs_end_to_end_with_the_inline_backend(
    tmp_path, monkeypatch, gardens_point_mini_root
):
    """As a user runs it in Lab: a kernel in user/notebooks/, figures inline, every code cell
    and every line its Markdown suggests (issue 54: the real-data line failed); everything it
    writes lands in the chosen output and cache roots (tmp_path), nothing in the repository."""
    import nbformat
    from nbclient import NotebookClient

    out, cache = tmp_path / "out", tmp_path / "cache"
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(out))
    monkeypatch.setenv("VPR_CACHE_DIR", str(cache))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    monkeypatch.setenv("TQDM_DISABLE", "1")
    checkout = _checkout(tmp_path)
    data = tmp_path / "shared" / "data"  # ../shared/data beside the checkout, as here
    data.mkdir(parents=True)
    (data / "gardens_point_mini").symlink_to(gardens_point_mini_root)
    path = lab.init(checkout)
    nb = nbformat.read(path, as_version=4)
    suggested = _suggested_code(nb)
    assert any(
        'load_dataset("folder", root="../shared/data/gardens_point_mini")' in c for c in suggested
    )
    nb.cells += [nbformat.v4.new_code_cell(code) for code in suggested]  # as a user tries them
    NotebookClient(
        nb, kernel_name="python3", timeout=600, resources={"metadata": {"path": str(path.parent)}}
    ).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    (real,) = [c for c in nb.cells if c.cell_type == "code" and "real = load_dataset" in c.source]
    shown = "".join(str(o.get("data", {}).get("text/plain", "")) for o in real.outputs)
    assert "gardens_point_mini" in shown and "n_query=10" in shown
    code = [c for c in nb.cells if c.cell_type == "code"]
    (closer,) = [c for c in code if "plot_disagreements(ds, a" in c.source]
    shown = "".join(str(o.get("data", {}).get("text/html", "")) for o in closer.outputs)
    assert "first correct rank" in shown  # its table, after its figure
    assert any("image/png" in o.get("data", {}) for o in outputs)  # the PR curves, inline
    png = out / "figures" / "mine" / "my_comparison.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import pandas as pd

    table = pd.read_csv(out / "results" / "mine" / "my_comparison.csv")
    assert list(table["method"]) == [
        "dense",
        "CentreGrid",
        "dense (backbone: TinyNet)",
        "dense (weighting: contrast)",
    ]
    assert (table["AUC"].between(0, 1)).all() and table["dAUC verdict"].notna().sum() == 3


# 5. Lab lists each notebook once ----------------------------------------------------------------


def test_lab_lists_each_notebook_once_the_paired_scripts_in_a_subfolder():
    from jupytext.paired_paths import paired_paths

    assert not list(NB_DIR.glob("*.py"))  # beside the notebooks: only notebooks
    for path in sorted(NB_DIR.glob("[0-9][0-9]_*.ipynb")):
        formats = json.loads(path.read_text())["metadata"]["jupytext"]["formats"]
        paired = [Path(p) for p, _ in paired_paths(str(path), "ipynb", formats)]
        assert paired == [path, NB_DIR / "scripts" / f"{path.stem}.py"]
        assert paired[1].is_file()


# Issue 61: opening a study notebook in Lab leaves it unmodified; a duplicate is the user's -----


def _study_checkout(tmp_path: Path) -> Path:
    root = tmp_path / "repo"
    (root / "notebooks" / "scripts").mkdir(parents=True)
    (root / "user" / "notebooks").mkdir(parents=True)
    shutil.copy(REPO / "pyproject.toml", root / "pyproject.toml")
    shutil.copy(REPO / TOUR, root / TOUR)
    twin = "notebooks/scripts/01_pipeline_tour.py"
    shutil.copy(REPO / twin, root / twin)
    return root


def test_lab_serves_a_study_notebook_as_its_kernel_will_see_it_and_copies_go_to_user(tmp_path):
    """Lab sets the kernel's language_info when the kernel starts; equal to what the server
    served, the notebook stays unmodified (no 'unsaved' mark, no autosave rewriting both
    files). A Duplicate of a study notebook lands in user/notebooks/, not beside the study's."""
    import asyncio

    pytest.importorskip("jupyter_server")
    pytest.importorskip("ipykernel")
    from vpr_study.lab import StudyContentsManager, kernel_language_info

    root = _study_checkout(tmp_path)
    before = {p: (root / p).read_bytes() for p in (TOUR, "notebooks/scripts/01_pipeline_tour.py")}
    cm = StudyContentsManager(root_dir=str(root))
    cm.pre_save_hook = lab.strip_outputs  # as make lab configures it

    async def session():
        model = await cm.get(TOUR)
        info = model["content"]["metadata"]["language_info"]
        assert info == kernel_language_info()  # what JupyterLab will set: no change, not dirty
        assert info["name"] == "python" and info["version"] == sys.version.split()[0]
        # a save of what Lab holds writes the same bytes (the hook strips language_info)
        await cm.save({"type": "notebook", "format": "json", "content": model["content"]}, TOUR)
        for path, data in before.items():
            assert (root / path).read_bytes() == data, path
        # a user's notebook is served as it is
        (root / "user" / "notebooks" / "mine.ipynb").write_bytes(before[TOUR])
        mine = await cm.get("user/notebooks/mine.ipynb")
        assert "language_info" not in mine["content"]["metadata"]
        # Lab's Duplicate: copy into the notebook's own folder
        copied = await cm.copy(TOUR, "notebooks")
        assert copied["path"] == "user/notebooks/01_pipeline_tour-Copy1.ipynb"
        assert not list((root / "notebooks").glob("*Copy*"))
        # a copy to elsewhere, asked for: where asked
        other = await cm.copy(TOUR, "user")
        assert other["path"] == "user/01_pipeline_tour.ipynb"

    asyncio.run(session())
