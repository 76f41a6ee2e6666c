"""The orchestration (vpr_study.runner): the figure registry, the study's datasets, the
parameters the notebooks get, and the summary of the saved comparison tables."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import pandas as pd
import pytest

from vpr_core import paths
from vpr_study import execution, figures, memo, outputs, runner
from vpr_study.figures import NOTEBOOKS


def test_registry_is_one_list():
    stems = [s.stem for s in figures.FIGURES]
    assert len(stems) == len(set(stems)), "a figure stem is registered twice"
    by_nb = figures.expected_figures()
    assert list(by_nb) == sorted(by_nb)
    assert "fig05_selection" in by_nb["03_landmark_selection"]


def test_every_registered_figure_is_saved_by_its_notebook():
    for nb, stems in figures.expected_figures().items():
        folder = runner.notebooks_dir()  # the paired scripts: scripts/ (Lab lists each once)
        script = folder / "scripts" / f"{nb}.py"
        source = (script if script.is_file() else folder / f"{nb}.py").read_text()
        for stem in stems:
            assert f'"{stem}"' in source, f"{nb} does not save {stem}"


def test_study_datasets_reads_vpr_datasets(monkeypatch):
    monkeypatch.setenv("VPR_DATASETS", "gardens_point=/data/gp;oops")
    with pytest.raises(ValueError, match="name=root"):
        runner.study_datasets()
    monkeypatch.setenv("VPR_DATASETS", "gardens_point=/data/gp")
    assert runner.study_datasets()["gardens_point"] == {
        "dataset": "gardens_point",
        "root": "/data/gp",
        "options": {},
        "pooling": "crop",
    }


def test_notebook_parameters_in_quick_mode():
    p = runner.notebook_parameters("synthetic", quick=True)
    assert p["options"] == {"n_places": runner.QUICK_PLACES} and p["limit"] is None
    assert p["label"] == "synthetic_quick"
    p = runner.notebook_parameters("folder", "/x", quick=True, label="gp", pooling="roi")
    assert p["limit"] == runner.QUICK_IMAGES and p["options"] == {}
    assert p["label"] == "gp_quick" and p["pooling"] == "roi" and p["root"] == "/x"
    full = runner.notebook_parameters("nordland", "/n", options={"step": 50})
    assert full["label"] == "nordland" and full["limit"] is None
    assert full["options"] == {"step": 50}


def test_summary_table_reads_the_saved_comparisons(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path))
    folder = tmp_path / "results" / "d"
    folder.mkdir(parents=True)
    pd.DataFrame({"method": ["a", "b"], "run": ["classical", "dense"], "AUC": [0.1, 0.2]}).to_csv(
        folder / "fig05_selection.csv", index=False
    )
    pd.DataFrame({"scale": [1]}).to_csv(folder / "fig06a_scheme1_scales.csv", index=False)
    t = runner.summary_table("d")
    assert list(t["figure"]) == ["fig05_selection"] * 2
    assert list(t["notebook"]) == ["03_landmark_selection"] * 2
    assert runner.summary_table("nothing").empty


def test_runner_imports_no_study_facade():
    import importlib

    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("vpr_core.study")


def test_a_stopped_run_says_what_finished_and_where_the_files_are(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path))
    calls = []

    def fake_execute(notebooks, out_dir, params, kernel, finished, **_):
        calls.extend(nb.stem for nb in notebooks)
        finished[notebooks[0].stem] = (0.0, 0.0)  # the first finished, then Ctrl-C
        raise KeyboardInterrupt

    monkeypatch.setattr(execution, "_execute", fake_execute)
    with pytest.raises(KeyboardInterrupt):
        runner.run_study(
            "synthetic", quick=True, notebooks=["01_pipeline_tour", "02_scale_statistics"]
        )
    out = capsys.readouterr().out
    assert "stopped in 02_scale_statistics (synthetic_quick); finished: 01_pipeline_tour" in out
    assert "cached work is kept" in out and str(tmp_path / "figures") in out


def test_notebook_parameters_of_the_wrong_type_get_one_clear_line():
    runner.check_parameters(
        dataset="synthetic",
        root=None,
        options={},
        limit=None,
        label=None,
        backbone="hog",
        pooling="crop",
    )
    with pytest.raises(
        TypeError,
        match=r"options must be dict such as \{\"tolerance\": 0\}, "
        r"got list \['tolerance', 0\]",
    ):
        runner.check_parameters(options=["tolerance", 0])
    with pytest.raises(TypeError, match="limit must be int or None, got bool"):
        runner.check_parameters(limit=True)


def test_text_progress_bars_for_saved_notebooks(monkeypatch, capsys):
    from vpr_core.utils import progress

    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    monkeypatch.setenv("VPR_PROGRESS", "text")  # what the runner gives its kernels
    assert list(progress(range(3), total=3, desc="features")) == [0, 1, 2]
    out = capsys.readouterr().out
    assert "features: 100%" in out and "3/3" in out  # a final bar on stdout, not a widget
    # issue 61: no work (a cached set), no bar: an empty "0it" bar said nothing
    assert list(progress([], desc="synthetic places", total=0)) == []
    assert list(progress(range(0), desc="features")) == []
    assert capsys.readouterr().out == ""


def test_notebook_logging_is_stdout_and_warnings_are_not_printed_twice(capsys):
    import logging
    import warnings

    from vpr_core.notices import notice
    from vpr_core.utils import configure_logging

    with warnings.catch_warnings():
        configure_logging(stream="stdout", silence_warnings=True)
        notice("a thing that changes a number")
        logging.getLogger("vpr_core").info("a plain line")
    captured = capsys.readouterr()
    assert "[vpr_core WARNING] a thing that changes a number" in captured.out
    assert "[vpr_core INFO] a plain line" in captured.out
    assert "VPRWarning" not in captured.err and captured.err.count("a thing") == 0
    # issue 61: a cell ending with it shows no "<Logger vpr_core (INFO)>"
    assert configure_logging(stream="stdout") is None
    configure_logging()  # back to stderr for the other tests


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"options": ["tolerance", 0]}, "options must be dict"),
        ({"label": 5}, "label must be str or None, got int 5"),
        ({"root": 123}, "root must be str or None, got int 123"),
    ],
)
def test_run_study_refuses_parameters_of_the_wrong_type_before_any_work(
    monkeypatch, kwargs, message
):
    from vpr_core import datasets

    monkeypatch.setattr(datasets, "load_dataset", lambda *a, **k: pytest.fail("loaded"))
    with pytest.raises(TypeError, match=message):
        runner.run_study("synthetic", quick=True, **kwargs)


def test_run_study_refuses_a_label_outside_the_output_root():
    with pytest.raises(ValueError, match="one folder name"):
        runner.run_study("synthetic", quick=True, label="../../x")


def test_kernels_get_their_settings_through_env_not_os_environ(tmp_path, monkeypatch):
    import json
    import os
    import subprocess

    monkeypatch.delenv("VPR_CACHE_DIR", raising=False)
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path / "env"))
    seen = {}

    def fake_run(command, env):
        seen.update(command=command, env=env)
        return subprocess.CompletedProcess(command, 0)

    monkeypatch.setattr(execution.subprocess, "run", fake_run)
    before = dict(os.environ)
    nb = runner.notebook_paths(["01_pipeline_tour"])[0]
    with paths.using_output_root(tmp_path / "cli"):  # what --out does
        execution._execute([nb], tmp_path, {"dataset": "synthetic"}, "python3", {})
    assert dict(os.environ) == before
    assert seen["env"]["VPR_OUTPUT_DIR"] == str(tmp_path / "cli")
    assert seen["env"]["VPR_CACHE_DIR"] == str(tmp_path / "cli" / ".cache")
    assert seen["env"]["VPR_PROGRESS"] == "text"
    assert json.loads(seen["command"][-1])["cwd"] == str(nb.parent)


def test_labels_side_by_side_all_finish_before_the_first_error_is_raised(monkeypatch):
    finished, niceness = [], {}

    def fake_run_label(label, notebooks, params, kernel, force=False, side_by_side=False, nice=0):
        assert side_by_side
        niceness[label] = nice
        if label == "a":
            raise RuntimeError("notebook 03 failed")
        time.sleep(0.2)  # still running when "a" fails
        finished.append(label)
        return [f"{label}/fig.png (absent)"]

    monkeypatch.setattr(execution, "_run_label", fake_run_label)
    with pytest.raises(RuntimeError, match="notebook 03 failed"):
        execution.run_labels([("a", [], {}), ("b", [], {})], "python3", False, jobs=2)
    assert finished == ["b"]
    niceness.clear()
    missing = execution.run_labels([("b", [], {}), ("c", [], {})], "python3", False, jobs=2)
    assert missing == ["b/fig.png (absent)", "c/fig.png (absent)"]
    # the first label keeps its CPU priority, the others fill the cores it leaves idle
    assert niceness == {"b": 0, "c": execution.BACKGROUND_NICE}
    with pytest.raises(ValueError, match=r"jobs \(labels executed at once\) must be a positive"):
        runner.run_study("synthetic", quick=True, jobs=0)


def test_ctrl_c_while_labels_run_side_by_side_starts_no_further_label(monkeypatch):
    started, b_running = [], threading.Event()

    def fake_run_label(label, notebooks, params, kernel, force=False, side_by_side=False, nice=0):
        started.append(label)
        if label == "b":
            b_running.set()
        if label == "a" and b_running.wait(5):
            os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C while the main thread waits
        time.sleep(2.0)  # a and b hold both slots until the main thread has seen Ctrl-C
        return []

    monkeypatch.setattr(execution, "_run_label", fake_run_label)
    chains = [("a", [], {}), ("b", [], {}), ("c", [], {})]
    with pytest.raises(KeyboardInterrupt):
        execution.run_labels(chains, "python3", False, jobs=2)
    assert sorted(started) == ["a", "b"]  # "c" was waiting for a free slot: never started


@pytest.mark.parametrize("jobs", [1, 2])
def test_every_label_runs_when_one_fails_and_the_failures_are_named(monkeypatch, jobs):
    ran = []

    def fake_run_label(label, notebooks, params, kernel, force=False, side_by_side=False, nice=0):
        ran.append(label)
        if label in ("a", "c"):
            raise RuntimeError(f"notebook 0{len(ran)} of {label} failed")
        return [f"{label}/fig.png (absent)"]

    monkeypatch.setattr(execution, "_run_label", fake_run_label)
    chains = [("a", [], {}), ("b", [], {}), ("c", [], {})]
    with pytest.raises(RuntimeError) as err:
        execution.run_labels(chains, "python3", False, jobs=jobs)
    assert sorted(ran) == ["a", "b", "c"]  # the labels after the failed first one ran
    text = str(err.value)
    assert "2 of 3 dataset labels failed" in text
    assert "a: notebook" in text and "of a failed" in text and "of c failed" in text
    assert "These ran to their end: b" in text


def test_vpr_study_run_exits_non_zero_naming_the_failed_labels(tmp_path, monkeypatch, capsys):
    from vpr_study import cli

    def fake_run_label(label, notebooks, params, kernel, force=False, side_by_side=False, nice=0):
        raise RuntimeError(f"notebook 03_landmark_selection.ipynb of {label} failed")

    monkeypatch.setattr(execution, "_run_label", fake_run_label)
    monkeypatch.setattr(
        runner, "study_datasets", lambda: {"other": {"dataset": "synthetic", "root": None}}
    )
    argv = ["run", "--dataset", "synthetic", "--quick", "--real-data", "--jobs", "1"]
    rc = cli.main([*argv, "--out", str(tmp_path)])
    assert rc != 0
    err = capsys.readouterr().err
    assert "2 of 2 dataset labels failed" in err
    assert "synthetic_quick: notebook" in err and "other_quick: notebook" in err


# Issue 54 item 1: the study is a list (the catalogue), not a pattern ------------------------------


def _folder_with_a_duplicate(tmp_path: Path) -> Path:
    """A notebooks/ folder: the catalogue's notebooks and their twins, and a Lab duplicate of
    notebook 01 (``01_pipeline_tour-Copy1.ipynb``) with its twin, as File > Duplicate makes."""
    folder = tmp_path / "notebooks"
    (folder / "scripts").mkdir(parents=True)
    for stem in NOTEBOOKS:
        (folder / f"{stem}.ipynb").write_text(f"{stem}\n")
        (folder / "scripts" / f"{stem}.py").write_text(f"# {stem}\n")
    return folder


def _duplicate(folder: Path) -> None:
    (folder / "01_pipeline_tour-Copy1.ipynb").write_text("a copy\n")
    (folder / "scripts" / "01_pipeline_tour-Copy1.py").write_text("# a copy\n")


def test_a_lab_duplicate_in_notebooks_is_not_a_study_notebook(tmp_path, monkeypatch):
    folder = _folder_with_a_duplicate(tmp_path)
    _duplicate(folder)
    (folder / "08_mine.ipynb").write_text("mine\n")
    monkeypatch.setattr(runner, "notebooks_dir", lambda: folder)
    assert [p.stem for p in runner.notebook_paths()] == list(NOTEBOOKS)
    with pytest.raises(ValueError, match="Unknown notebook.*01_pipeline_tour-Copy1.*user/"):
        runner.notebook_paths(["01_pipeline_tour-Copy1"])
    (folder / "04_overlap.ipynb").unlink()
    with pytest.raises(FileNotFoundError, match="04_overlap.ipynb missing.*git checkout"):
        runner.notebook_paths()


def test_a_users_notebook_beside_the_study_changes_no_memo_key(tmp_path):
    folder = _folder_with_a_duplicate(tmp_path)
    nb = folder / "03_landmark_selection.ipynb"
    before = memo.notebook_key(nb, "inputs")
    _duplicate(folder)
    assert memo.notebook_key(nb, "inputs") == before
    (folder / "helper.csv").write_text("a file a cell may read\n")  # still an input
    assert memo.notebook_key(nb, "inputs") != before


def _checkout(tmp_path: Path) -> Path:
    root = tmp_path / "checkout"
    (root / "notebooks").mkdir(parents=True)
    (root / "pyproject.toml").write_text(f'[project]\nname = "{paths.PROJECT_NAME}"\n')
    return root


@pytest.mark.parametrize(
    ("kw", "label", "where"),
    [
        ({"quick": True}, "synthetic_quick", "user"),
        ({"label": "mine"}, "mine", "user"),
        ({}, "synthetic", ""),
    ],
)
def test_only_the_committed_labels_write_into_figures_and_results(
    tmp_path, monkeypatch, kw, label, where
):
    """``--quick`` and a label the catalogue does not commit write under user/; the kernels get
    that folder as their output root. The study's labels write figures/ and results/."""
    root = _checkout(tmp_path)
    monkeypatch.chdir(root)
    monkeypatch.delenv("VPR_OUTPUT_DIR", raising=False)
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    seen = {}

    def fake_run_labels(chains, kernel, force, jobs):
        seen["labels"] = [c[0] for c in chains]
        seen["env"] = execution.kernel_settings()
        seen["figures"] = outputs.figures_dir(chains[0][0])
        return []

    monkeypatch.setattr(runner, "load_dataset", lambda *a, **k: None)
    monkeypatch.setattr(runner, "run_labels", fake_run_labels)
    monkeypatch.setattr(runner, "study_datasets", lambda: {})
    with outputs.study_outputs():  # as `vpr-study run` calls it
        runner.run_study(notebooks=["03_landmark_selection"], **kw)
    base = root / where if where else root
    assert seen["labels"] == [label]
    assert seen["figures"] == base / "figures" / label
    assert seen["env"]["VPR_OUTPUT_DIR"] == str(base)
    assert seen["env"]["VPR_CACHE_DIR"] == str(tmp_path / "cache")
    assert (root / where / "figures").is_dir() and (where or not (root / "user").exists())


def test_quick_from_the_environment_gives_the_small_set_and_papermill_wins(monkeypatch):
    """Issue 61: ``VPR_QUICK=1 jupyter nbconvert --execute`` runs a study notebook on the small
    set (its parameters cell says ``quick = None``); the runner injects ``quick`` itself."""
    base = {"root": None, "backbone": "efficientnet_lite0", "pooling": "crop", "shortlist": None}
    monkeypatch.setenv("VPR_QUICK", "1")
    got = runner.check_parameters(dataset="synthetic", options={}, limit=None, label=None, **base)
    assert got == ({"n_places": runner.QUICK_PLACES}, None, "synthetic_quick")
    got = runner.check_parameters(dataset="folder", options={}, limit=None, label="gp", **base)
    assert got == ({}, runner.QUICK_IMAGES, "gp_quick")
    # papermill's parameters (the runner's) win over the environment
    full = runner.notebook_parameters("synthetic")
    assert full["quick"] is False
    got = runner.check_parameters(**{k: v for k, v in full.items() if k in runner.PARAMETER_TYPES
                                     or k == "quick"})  # fmt: skip
    assert got == ({}, None, "synthetic")
    small = runner.notebook_parameters("synthetic", quick=True)  # idempotent: applied twice
    assert runner.check_parameters(**small) == (small["options"], None, "synthetic_quick")
    monkeypatch.setenv("VPR_QUICK", "0")
    assert runner.check_parameters(dataset="synthetic", options={"n_places": 5}) == (
        {"n_places": 5}, None, None)  # fmt: skip
    with pytest.raises(TypeError, match="quick must be True, False or None"):
        runner.check_parameters(dataset="synthetic", quick="yes")
