"""vpr_study.tables: one schema per table read back, applied wherever it is read (findings, the
plots, the runner's summary): p-values in [0, 1], query counts non-negative integers, "needs"
non-negative, intervals ordered, ranks >= 1, numbers finite; a table file that is no regular
file is refused by name, never reported as "not run" (issue 60 item 6)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vpr_study import findings
from vpr_study.tables import CHANGES, COMPARISON, check_table

_RUN = "overlap_scheme1(iou_threshold=0.7)"  # Fig. 7a's claim of parity, against classical


def _comparison(**changes: object) -> pd.DataFrame:
    """A compare() table: the classical baseline row and the claim's row, ``changes`` set on
    the claim's row (``"base:<column>"``: on the baseline row)."""
    base = {"method": "classical", "run": "classical", "baseline": None, "queries": 60}
    base |= {"AUC": 0.5, "AUC lo": 0.4, "AUC hi": 0.6}
    row = {"method": "nms", "run": _RUN, "baseline": "classical", "queries": 60}
    row |= {"AUC": 0.52, "AUC lo": 0.41, "AUC hi": 0.62, "dAUC": 0.01, "dAUC lo": -0.02}
    row |= {"dAUC hi": 0.03, "dAUC p": 0.5, "dAUC verdict": "inconclusive", "dAUC needs": 900.0}
    for key, value in changes.items():
        (base if key.startswith("base:") else row)[key.removeprefix("base:")] = value
    return pd.DataFrame([base, row])


def _saved(tmp_path: Path, table: pd.DataFrame, name: str = "fig07a_overlap_nms") -> Path:
    folder = tmp_path / "results" / "d"
    folder.mkdir(parents=True, exist_ok=True)
    table.to_csv(folder / f"{name}.csv", index=False)
    return folder / f"{name}.csv"


_FINITE = "not a finite number in"
BAD_COMPARISONS = {
    "p above 1": ({"dAUC p": 7.0}, rf"column 'dAUC p' holds 7.0, {_FINITE} \[0, 1\]"),
    "p below 0": ({"dAUC p": -0.5}, rf"column 'dAUC p' holds -0.5, {_FINITE}"),
    "negative queries": ({"queries": -3}, r"column 'queries' holds -3, not an integer >= 0"),
    "inf queries": ({"queries": np.inf}, r"column 'queries' holds inf, not an integer >= 0"),
    "fractional queries": ({"queries": 2.5}, r"column 'queries' holds 2.5, not an integer"),
    "negative needs": ({"dAUC needs": -40.0}, r"column 'dAUC needs' holds -40.0, not a number"),
    "an AUC above 1": ({"AUC": 1.5}, rf"column 'AUC' holds 1.5, {_FINITE}"),
    "an inf bound": ({"AUC hi": np.inf}, rf"column 'AUC hi' holds inf, {_FINITE}"),
    "reversed baseline interval": ({"base:AUC lo": 0.7}, r"the interval of AUC is reversed"),
    "reversed difference": ({"dAUC lo": 0.05, "dAUC hi": -0.02}, r"the interval of dAUC is"),
}


@pytest.mark.parametrize("case", list(BAD_COMPARISONS))
def test_findings_refuse_a_comparison_table_outside_its_schema(tmp_path, case):
    changes, words = BAD_COMPARISONS[case]
    csv = _saved(tmp_path, _comparison(**changes))
    line = 2 if case.startswith("reversed baseline") else 3
    with pytest.raises(ValueError, match=rf"^{csv} line {line} {words}.*rerun the notebook"):
        findings.findings_table(["d"], out=tmp_path)


def test_a_table_within_its_schema_gives_its_verdict(tmp_path):
    _saved(tmp_path, _comparison())
    table = findings.findings_table(["d"], out=tmp_path)
    assert (
        table.loc["Fig. 7a: NMS at IoU 0.7 is on par with classical", "d verdict"]
        == "on par (as the paper says)"
    )


@pytest.mark.parametrize(
    ("column", "value", "words"),
    [
        ("scale", 0, r"column 'scale' holds 0, not an integer in \[1, 9\]"),
        ("scale", 12, r"column 'scale' holds 12, not an integer in \[1, 9\]"),
        ("query", -1, r"column 'query' holds -1, not an integer >= 0"),
        ("correct", 0.5, r"column 'correct' holds 0.5, not True or False"),
    ],
)
def test_findings_refuse_a_matches_table_outside_its_schema(tmp_path, column, value, words):
    rows = {"query": [0, 1], "reference": [0, 1], "pair": ["gt", "gt"], "scale": [2, 6]}
    rows |= {"score": [0.1, 0.2], "correct": [1.0, 0.0]}
    rows[column] = [rows[column][0], value]
    csv = _saved(tmp_path, pd.DataFrame(rows), "fig04_matches")
    with pytest.raises(ValueError, match=rf"^{csv} line 3 {words}"):
        findings.findings_table(["d"], out=tmp_path)


def _special(path: Path, kind: str) -> None:
    if kind == "FIFO":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    elif kind == "dangling link":
        path.symlink_to(path.parent / "nowhere.csv")
    else:
        path.symlink_to("/dev/null")


@pytest.mark.parametrize("kind", ["FIFO", "folder", "dangling link", "/dev/null"])
@pytest.mark.parametrize("name", ["fig07a_overlap_nms", "fig04_matches"])
def test_a_table_that_is_no_regular_file_is_refused_by_name_not_not_run(tmp_path, kind, name):
    csv = _saved(tmp_path, _comparison(), "fig13_comparison")  # the label's folder holds one
    target = csv.with_name(f"{name}.csv")
    _special(target, kind)
    with pytest.raises(ValueError, match=rf"{target} is .*, not a regular file"):
        findings.findings_table(["d"], out=tmp_path)


def test_the_runners_summary_reads_with_the_schema(tmp_path, monkeypatch):
    from vpr_study import runner

    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path))
    csv = _saved(tmp_path, _comparison(**{"dAUC p": 7.0}))
    with pytest.raises(ValueError, match=rf"^{csv} line 3 column 'dAUC p' holds 7.0"):
        runner.summary_table("d")
    os.unlink(csv)
    _special(csv, "FIFO")
    with pytest.raises(ValueError, match=rf"{csv} is a FIFO"):
        runner.summary_table("d")


def test_plot_paired_differences_refuses_a_reversed_interval():
    from vpr_study.viz import plot_paired_differences

    table = _comparison(**{"dAUC lo": 0.05, "dAUC hi": -0.02, "dR@1": 0.0, "dR@1 lo": -0.1})
    table = table.assign(**{"dR@1 hi": 0.1, "dR@1 verdict": "inconclusive"})
    with pytest.raises(ValueError, match=r"comparison table: row 1 the interval of dAUC is rev"):
        plot_paired_differences(table)


def test_plot_step_changes_refuses_rank_zero():
    from vpr_study.viz import plot_step_changes

    rows = {"query": [0, 0], "case": ["fixed"] * 2, "reference": [0, 1], "correct": [True, False]}
    rows |= {"rank before": [3, 1], "rank after": [1, 0], "score before": [0.1, 0.2]}
    with pytest.raises(ValueError, match=r"row 1 column 'rank after' holds 0, not an integer >= 1"):
        plot_step_changes(pd.DataFrame(rows | {"score after": [0.3, 0.1]}))


def test_the_committed_tables_hold_their_schemas():
    root = Path(__file__).resolve().parents[1] / "results"
    checked = 0
    for csv in sorted(root.glob("*/*.csv")):
        table = pd.read_csv(csv)
        schema = (
            COMPARISON
            if {"run", "AUC"} <= set(table.columns)
            else CHANGES
            if csv.stem.endswith("_changes")
            else None
        )
        if schema is not None:
            check_table(table, schema, csv)
            checked += 1
    assert checked > 10
