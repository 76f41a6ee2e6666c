"""A study notebook runs again exactly when what it reads or what it wrote changed."""

from __future__ import annotations

import time

import pytest

from vpr_study import execution, memo, runner
from vpr_study.figures import expected_figures


@pytest.fixture
def fake_study(tmp_path, monkeypatch):
    """Output and cache roots in tmp; papermill replaced by a fake that writes each notebook's
    expected figures (their bytes: the notebook's execution count) and counts executions."""
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path / "out"))
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    executed: list[str] = []

    def fake_execute(notebooks, out_dir, params, kernel, finished, **_):
        for nb in notebooks:
            started = time.time()
            executed.append(nb.stem)
            for stem in expected_figures()[nb.stem]:
                png = runner.outputs.figures_dir(params["label"]) / f"{stem}.png"
                png.write_bytes(f"{nb.stem} run {executed.count(nb.stem)}".encode())
            finished[nb.stem] = (started, time.time())

    monkeypatch.setattr(execution, "_execute", fake_execute)
    return executed


def _run(**kw):
    nb = runner.notebook_paths(["03_landmark_selection"])
    params = runner.notebook_parameters("synthetic", quick=True, **kw)
    return execution._run_label(params["label"], nb, params, "python3")


def test_unchanged_notebook_is_not_executed_again(fake_study, capsys):
    assert _run() == [] and fake_study == ["03_landmark_selection"]
    assert _run() == [] and fake_study == ["03_landmark_selection"]
    assert "not executed again" in capsys.readouterr().out


def test_changed_parameters_or_outputs_execute_it_again(fake_study):
    _run()
    _run(pooling="roi")  # other parameters: another key
    assert len(fake_study) == 2
    _run(pooling="roi")
    assert len(fake_study) == 2
    figure = runner.outputs.figures_dir("synthetic_quick") / "fig05_selection.png"
    figure.write_bytes(b"edited by hand")  # an output changed: executed again, rewritten
    _run(pooling="roi")
    assert len(fake_study) == 3 and figure.read_bytes() != b"edited by hand"
    figure.unlink()  # an output removed: executed again
    _run(pooling="roi")
    assert len(fake_study) == 4 and figure.exists()


def test_force_executes_every_notebook(fake_study):
    nb = runner.notebook_paths(["03_landmark_selection"])
    params = runner.notebook_parameters("synthetic", quick=True)
    execution._run_label(params["label"], nb, params, "python3")
    execution._run_label(params["label"], nb, params, "python3", force=True)
    assert len(fake_study) == 2


def test_inputs_key_follows_data_settings_and_notebook_content(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path / "out"))
    data = tmp_path / "data"
    (data / "query").mkdir(parents=True)
    image = data / "query" / "0.png"
    image.write_bytes(b"first")
    params = {"dataset": "folder", "root": str(data)}
    key = memo.inputs_key(params)
    assert memo.inputs_key(params) == key
    image.write_bytes(b"other")  # same name, new content
    assert memo.inputs_key(params) != key
    key = memo.inputs_key(params)
    model = tmp_path / "model.yml.gz"
    model.write_bytes(b"a")
    monkeypatch.setenv("VPR_SED_MODEL", str(model))
    with_model = memo.inputs_key(params)
    model.write_bytes(b"b")  # the file a setting names, overwritten in place
    assert len({key, with_model, memo.inputs_key(params)}) == 3
    before = memo.inputs_key(params)
    monkeypatch.setenv("VPR_PROGRESS", "text")  # placement settings are not inputs
    assert memo.inputs_key(params) == before
    nb = tmp_path / "01_x.ipynb"
    nb.write_text("{}")
    first = memo.notebook_key(nb, key)
    nb.write_text('{"cells": []}')
    second = memo.notebook_key(nb, key)
    (tmp_path / "my_scheme.py").write_text("K = 8\n")  # a module a cell imports from beside it
    third = memo.notebook_key(nb, key)
    (tmp_path / "my_scheme.py").write_text("K = 6\n")
    assert len({first, second, third, memo.notebook_key(nb, key)}) == 4
