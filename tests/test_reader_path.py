"""The reader's path is measured, not declared (issue 59): docs/ARCHITECTURE.md lists the files
that run for Fig. 13's number and notebook 07's two-sided + query-batch number, as
``benchmarks/reader_path.py`` traces them."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _reader_path():
    spec = importlib.util.spec_from_file_location(
        "reader_path", ROOT / "benchmarks" / "reader_path.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_architecture_lists_the_files_that_run():
    reader_path = _reader_path()
    traced = reader_path.paths()
    assert set(traced) == {"fig13", "steps"}
    assert "vpr_core/evaluation/compare.py" in traced["fig13"]  # the file that prints it
    assert "vpr_core/matching/pairwise.py" not in traced["fig13"]  # the reference: not run
    assert (
        "vpr_core/result.py" in traced["steps"]
        and "vpr_core/matching/normalise.py" in (traced["steps"])
    )
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text(encoding="utf-8")
    assert reader_path.markdown(traced) in text, (
        "docs/ARCHITECTURE.md's reader's path differs from the trace: paste the markdown "
        "`.venv/bin/python benchmarks/reader_path.py` prints under 'The reader's path'"
    )
