"""Notebooks sharing one kernel (vpr_study.session) start each as a fresh kernel would."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import nbformat
import pytest

from vpr_study import execution, runner

FIRST = """\
from matplotlib_inline.backend_inline import set_matplotlib_formats
import matplotlib.pyplot as plt
set_matplotlib_formats("jpeg")
left_behind = 1
plt.figure()
plt.plot([0, 1])
"""

SECOND = """\
import matplotlib.pyplot as plt
assert "left_behind" not in globals(), "the previous notebook's names leaked"
assert plt.get_fignums() == [], "the previous notebook's figures leaked"
plt.figure()
plt.plot([0, 1])
"""


def _notebook(path, *sources):
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(s) for s in sources]
    nb.metadata["kernelspec"] = {
        "name": "python3",
        "display_name": "Python 3",
        "language": "python",
    }
    nbformat.write(nb, path)
    return path


def test_notebooks_in_one_kernel_start_clean(tmp_path):
    first = _notebook(tmp_path / "a.ipynb", FIRST)
    niceness = min(os.nice(0) + 3, 19)
    check_nice = f"import os\nassert os.nice(0) == {niceness}, os.nice(0)"
    second = _notebook(tmp_path / "b.ipynb", "pass", SECOND, check_nice)
    status = tmp_path / "status.jsonl"
    request = {
        "notebooks": [
            {"input_path": str(p), "output_path": str(tmp_path / f"out_{p.name}"), "parameters": {}}
            for p in (first, second)
        ],
        "cwd": str(tmp_path),
        "kernel": "python3",
        "progress_bar": False,
        "status": str(status),
        "nice": 3,  # the session and its kernel: lower CPU priority (labels side by side)
    }
    env = {"MPLBACKEND": "module://matplotlib_inline.backend_inline"}
    done = subprocess.run(
        [sys.executable, "-m", "vpr_study.session", json.dumps(request)],
        env={**runner.settings.child_environment(env)},
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    out = nbformat.read(tmp_path / "out_b.ipynb", as_version=4)
    assert [c.execution_count for c in out.cells] == [1, 2, 3]  # counted as in a fresh kernel
    shown = [o for o in out.cells[1].outputs if o.output_type == "display_data"]
    assert shown and "image/png" in shown[0].data  # not the first notebook's JPEG
    a = nbformat.read(tmp_path / "out_a.ipynb", as_version=4)
    assert "image/jpeg" in a.cells[0].outputs[-1].data
    lines = [json.loads(x) for x in status.read_text().splitlines()]
    assert [x.get("done") for x in lines if "done" in x] == ["a", "b"]


def test_a_failing_notebook_names_itself_and_what_finished(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path / "out"))
    ok = _notebook(tmp_path / "01_ok.ipynb", "x = 1")
    bad = _notebook(tmp_path / "02_bad.ipynb", "raise ValueError('boom')")
    with pytest.raises(RuntimeError, match=r"notebook 02_bad.ipynb failed"):
        execution._run_label("t", [ok, bad], {}, "python3")
    assert "stopped in 02_bad (t); finished: 01_ok" in capsys.readouterr().out
