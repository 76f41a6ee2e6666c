"""The paper's constants and tables as data (vpr_core.paper)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

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


def _paper_map_functions() -> list[tuple[str, str]]:
    """(paper item, dotted function) of every row of PAPER_MAP's one-function table."""
    text = (Path(__file__).parents[1] / "docs" / "PAPER_MAP.md").read_text()
    table = text.split("## One function per paper item", 1)[1].split("\n\n", 2)[1]
    rows = []
    for line in table.splitlines()[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        names = re.findall(r"`(vpr_(?:core|study)\.[\w.]+)`", cells[1])
        assert len(names) == 1, f"PAPER_MAP row {cells[0]!r} names {names}, not one function"
        rows.append((cells[0], names[0]))
    return rows


def test_paper_map_names_one_existing_function_per_row():
    rows = _paper_map_functions()
    assert len(rows) >= 15
    for item, dotted in rows:
        module, _, name = dotted.rpartition(".")
        owner, attr = module, None
        if module.rpartition(".")[2][:1].isupper():  # a method: module.Class.method
            owner, _, attr = module.rpartition(".")
        obj = importlib.import_module(owner)
        obj = getattr(obj, attr, None) if attr else obj
        obj = getattr(obj, name, None)
        assert callable(obj), f"PAPER_MAP row {item!r}: {dotted} does not exist"
    # one home per item, and no function named as the home of two items
    homes = [d for _, d in rows]
    assert len(set(homes)) == len(homes)
