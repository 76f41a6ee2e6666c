"""Only the study in the study's folders (issue 44 item 5): ``figures/`` and ``results/`` hold
exactly what the catalogue (:mod:`vpr_study.catalogue`) says the study writes, and the catalogue
follows the notebooks' save calls and the Makefile's commands."""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from vpr_study import catalogue, runner
from vpr_study.figures import NOTEBOOKS

REPO = Path(__file__).resolve().parents[1]


def _tracked() -> set[str] | None:
    if shutil.which("git") is None or not (REPO / ".git").exists():
        return None
    out = subprocess.run(
        ["git", "ls-files", "--", "figures", "results"], cwd=REPO, capture_output=True, text=True
    )
    return set(out.stdout.split()) if out.returncode == 0 else None


def test_figures_and_results_hold_nothing_the_study_does_not_write():
    stray = catalogue.strays(REPO)
    assert not stray, (
        f"not written by the study (vpr_study.catalogue): {stray}; a test or a user's own run "
        "wrote here (tests write under tmp_path, a user's runs under user/), or a notebook "
        "gained an output the catalogue must name"
    )


def test_every_catalogued_output_is_committed():
    tracked = _tracked()
    if tracked is None:
        pytest.skip("not a git checkout")
    missing = sorted(catalogue.study_outputs() - tracked)
    assert not missing, f"catalogued but not committed (stale catalogue?): {missing}"


def test_strays_names_a_file_the_study_does_not_write(tmp_path):
    labels = {"synthetic": ("03_landmark_selection",)}
    for rel in sorted(catalogue.study_outputs(labels)):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("x")
    (tmp_path / "results/synthetic/fig05_selection.timings.csv").write_text("x")
    assert catalogue.strays(tmp_path, labels) == []
    for rel in (
        "figures/synthetic/eval_synthetic_dense_n-bootstrap-100000000_n-places-4.png",
        "results/synthetic/fig05_selection.csv.tmp",
        "figures/mine/x.png",
        "results/notes.txt",
    ):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("x")
        assert rel in catalogue.strays(tmp_path, labels)


def _script(nb: str) -> Path:
    """A notebook's paired script (``notebooks/scripts/`` or beside the notebook)."""
    for folder in (REPO / "notebooks" / "scripts", REPO / "notebooks"):
        if (folder / f"{nb}.py").is_file():
            return folder / f"{nb}.py"
    pytest.skip(f"no paired script of {nb}")


def _saved_names(source: str) -> set[str]:
    """The string-literal names of ``save(obj, name, ...)`` calls (a loop's names are checked
    by the literals test below and, once written, by the folder test above)."""
    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "save":
            arg = node.args[1] if len(node.args) > 1 else None
            if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                names.add(arg.value)
    return names


@pytest.mark.parametrize("nb", NOTEBOOKS)
def test_each_notebooks_save_calls_are_in_the_catalogue(nb):
    source = _script(nb).read_text(encoding="utf-8")
    known = {
        *catalogue.figure_stems(nb),
        *catalogue.TABLES[nb],
        *catalogue.TIMINGS_ONLY.get(nb, ()),
    }
    names = _saved_names(source)
    assert names <= known, f"{nb} saves {sorted(names - known)}, not in vpr_study.catalogue"
    literals = {
        n.value for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Constant)
    }  # a loop's stems are literals in its tuple
    assert known <= literals, f"catalogued for {nb} but not in it: {sorted(known - literals)}"


def _makefile_commands(verb: str) -> list[str]:
    text = (REPO / "Makefile").read_text(encoding="utf-8").replace("\\\n", " ")
    return [ln for ln in text.splitlines() if f"vpr-study {verb} " in ln]


def test_the_catalogues_labels_follow_the_makefile_and_the_runner():
    assert set(catalogue.TABLES) == set(NOTEBOOKS), "every notebook declares its tables"
    assert catalogue.LABEL_NOTEBOOKS["synthetic"] == NOTEBOOKS
    for label in ("gardens_point_mini", "nordland_step50"):
        assert catalogue.LABEL_NOTEBOOKS[label] == runner.REAL_DATA_NOTEBOOKS, label
    assert set(runner.study_datasets()) <= set(catalogue.LABEL_NOTEBOOKS)
    runs = _makefile_commands("run")
    assert any("--dataset synthetic" in r and "--label" not in r for r in runs), runs
    labelled = {}
    for cmd in runs + list(catalogue.ONE_OFF.values()):
        m = re.search(r"--label (\S+)", cmd)
        if m:
            nbs = re.search(r"--notebooks ((?:\S+ ?)+?)(?:\s+--|\s*$)", cmd)
            labelled[m.group(1)] = tuple(nbs.group(1).split()) if nbs else NOTEBOOKS
    for label, nbs in labelled.items():
        assert catalogue.LABEL_NOTEBOOKS.get(label) == nbs, (label, nbs)
    made = {"synthetic", "gardens_point_mini", "nordland_step50", *labelled}
    assert set(catalogue.LABEL_NOTEBOOKS) == made
    evals = _makefile_commands("eval")
    assert any(
        "--dataset synthetic" in e and re.search(r"--method dense classical(\s|$)", e)
        for e in evals
    ), evals
    assert catalogue.EVAL_OUTPUTS == {"synthetic": ("eval_synthetic_dense+classical",)}


def test_each_benchmark_table_has_its_script():
    sources = "\n".join(p.read_text() for p in (REPO / "benchmarks").glob("*.py"))
    for name in catalogue.RESULTS_FILES:
        if name.startswith("benchmarks/"):
            assert Path(name).name in sources or Path(name).stem in sources, name
