"""The paper's constants and tables as data (vpr_core.paper)."""

from __future__ import annotations

import pytest

from vpr_core import paper


def test_table1_bins():
    t = paper.table1()
    assert list(t.index) == [f"Scale {k}" for k in range(1, 10)]
    assert list(t["lower (incl.)"]) == [0, 0.02, 0.05, 0.09, 0.14, 0.23, 0.34, 0.5, 0.72]
    assert t["normalized scale"].iloc[-1] == "0.72~1"
    assert t["normalized scale"].iloc[0] == "0~0.02"


@pytest.mark.parametrize(
    "table,totals",
    [
        (paper.TABLE2, [100, 100, 98, 98, 100, 96]),
        (paper.TABLE3, [100, 102, 104, 99, 103]),
        (paper.TABLE4, [100, 100, 100, 100]),
    ],
)
def test_dense_tables_are_the_papers(table, totals):
    assert list(paper.dense_settings(table)["total"]) == totals


def test_dense_set_label():
    assert paper.dense_set_label("Set 3", (0.25, 0.49), 49) == "Set 3: 0.25/0.49 x 49"
    assert (
        paper.dense_set_label("Set 4", paper.DENSE_SCALES, (49, 25, 16, 9))
        == "Set 4: 0.16/0.25/0.36/0.49 x 49/25/16/9"
    )
    assert paper.TABLE4["Set 3"][0] == (0.09, 0.20, 0.32, 0.44)
