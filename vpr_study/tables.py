"""One schema per table the workbench reads back (a ``compare`` table, ``step_changes``, the
labelled matches), checked wherever it is read (findings, the plots, the runner's summary): its
columns' kinds and bounds and its intervals, each refusal naming the table, line and fix."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from vpr_core import checks

__all__ = [
    "CHANGES",
    "COMPARISON",
    "MATCHES",
    "Rule",
    "Schema",
    "check_table",
    "table_exists",
]


@dataclass(frozen=True)
class Rule:
    """What the columns whose names full-match ``pattern`` hold: ``kind`` ``number``,
    ``integer`` or ``bool`` (``True``/``False`` or 0/1), in ``[low, high]``; ``missing``: an
    empty cell (NaN) allowed; ``infinite``: ``inf`` allowed where the bounds hold it."""

    pattern: str
    kind: str = "number"
    low: float = -np.inf
    high: float = np.inf
    missing: bool = True
    infinite: bool = False

    def expected(self) -> str:
        """The rule in words (the refusal's end)."""
        what = {"integer": "an integer", "bool": "True or False"}.get(self.kind, "a number")
        if self.kind != "bool" and (np.isfinite(self.low) or np.isfinite(self.high)):
            what += (
                f" in [{self.low:g}, {self.high:g}]"
                if np.isfinite(self.low) and np.isfinite(self.high)
                else f" >= {self.low:g}"
                if np.isfinite(self.low)
                else f" <= {self.high:g}"
            )
        if not self.infinite and self.kind == "number":
            what = "a finite " + what.removeprefix("a ")
        return what


@dataclass(frozen=True)
class Schema:
    """A table's schema: its ``required`` columns, the :class:`Rule` of every column a rule
    covers (others are free text), the value columns ``v`` whose ``v lo`` and ``v hi`` form an
    interval (``intervals``: a pattern), and how it is written (``writer``, in the fix)."""

    name: str
    writer: str
    required: tuple[str, ...]
    rules: tuple[Rule, ...]
    intervals: str = ""


_METRIC = r"(AUC|R@\d+P?)"
#: ``compare`` tables (``vpr_core.evaluation.compare``), as returned or saved.
COMPARISON = Schema(
    "comparison table",
    "write it with save(compare(runs), figure, label)",
    ("method",),
    (
        Rule("queries", "integer", 0, missing=False),
        Rule(rf"{_METRIC}( lo| hi| chance)?", low=0, high=1),
        Rule(rf"d{_METRIC}( lo| hi)?", low=-1, high=1),
        Rule(rf"d{_METRIC} p", low=0, high=1),
        Rule(rf"d{_METRIC} needs", low=0, infinite=True),  # inf: a difference of exactly 0
        Rule("landmarks/img|pairs scored", low=0),
        Rule("tolerance", "integer", 0),
        Rule("shortlist", "integer", 1),
    ),
    rf"d?{_METRIC}",
)
#: :func:`vpr_core.step_changes` tables (one or several, with a ``step`` column).
CHANGES = Schema(
    "step_changes table",
    "pass step_changes(plain, stepped) (several concatenated with a 'step' column)",
    ("query", "case", "reference", "correct", "rank before", "rank after"),
    (
        Rule("query|reference", "integer", 0, missing=False),
        Rule("rank before|rank after", "integer", 1, missing=False),
        Rule("correct", "bool", missing=False),
        Rule("score before|score after"),
    ),
)
#: The labelled matches of notebook 02 (``ScaleStats.matches_frame``).
MATCHES = Schema(
    "table of labelled matches",
    "write it with save(stats.matches_frame(), ...) as notebook 02 does",
    ("pair", "correct", "scale", "query"),
    (
        Rule("query|reference|query_box_index|reference_box_index", "integer", 0, missing=False),
        Rule("scale", "integer", 1, 9, missing=False),
        Rule("correct", "bool"),
        Rule("score"),
    ),
)


def table_exists(path: str | Path, what: str = "the table") -> bool:
    """Whether the table file ``path`` is there: True for a regular file, False when nothing is
    (a table not written: "not run"); anything else (a folder, a FIFO, a device, a dangling
    link) is refused by name, never read and never reported as "not run"."""
    return checks.check_file(path, what)


def _values(column: pd.Series, rule: Rule) -> pd.Series:
    """``column`` as floats (text that is no number: NaN), ``True``/``False`` as 1/0."""
    if rule.kind == "bool":
        column = column.replace({"True": 1, "False": 0, True: 1, False: 0})
    return pd.to_numeric(column, errors="coerce").astype(float)


def _fault(cell: object, value: float, rule: Rule) -> bool:
    """Whether one cell breaks ``rule`` (``value``: the cell as a float)."""
    if pd.isna(cell):
        return not rule.missing
    if np.isnan(value):  # text that is no number
        return True
    if np.isinf(value):
        return not rule.infinite or not rule.low <= value <= rule.high
    if rule.kind == "bool":
        return value not in (0.0, 1.0)
    return (rule.kind == "integer" and value != round(value)) or not (
        rule.low <= value <= rule.high
    )


def check_table(table: pd.DataFrame, schema: Schema, source: str | Path | None = None) -> None:
    """Refuse ``table`` unless it holds ``schema``'s required columns, every cell of a column a
    rule covers is what the rule says, and every interval is ordered (``lo <= hi``).

    Args:
        table: the table (read from a file: its rows are the file's lines 2, 3, ...).
        schema: :data:`COMPARISON`, :data:`CHANGES` or :data:`MATCHES`.
        source: the file it was read from (refusals name its line), or None (an in-memory
            table: they name the row).

    Raises:
        ValueError: naming the table, the line (or row), the column, the value and the fix.
    """
    where = f"{source} " if source is not None else f"the {schema.name}: "
    fix = (
        f"this is not a {schema.name} the package wrote: rerun the notebook or command that "
        "writes it"
        if source is not None
        else schema.writer
    )

    def row(i: int) -> str:
        return f"line {i + 2}" if source is not None else f"row {table.index[i]!r}"

    missing = [c for c in schema.required if c not in table.columns]
    if missing:
        raise ValueError(
            f"{where}lacks the column(s) {', '.join(missing)}: it is not a {schema.name}; {fix}"
        )
    for col in table.columns:
        rule = next((r for r in schema.rules if re.fullmatch(r.pattern, str(col))), None)
        if rule is None:
            continue
        cells = table[col].reset_index(drop=True)
        values = _values(cells, rule).to_numpy()
        bad = next((i for i, c in enumerate(cells) if _fault(c, values[i], rule)), None)
        if bad is not None:
            cell = cells[bad]
            if pd.isna(cell):
                what = f"an empty cell, not {rule.expected()}"
            elif np.isnan(values[bad]):
                what = f"{str(cell)[:40]!r}, not a number"
            else:
                shown = repr(cell) if isinstance(cell, str) else str(cell)  # 7.0, not np.float64
                what = f"{shown}, not {rule.expected()}"
            raise ValueError(f"{where}{row(bad)} column {col!r} holds {what}; {fix}.")
    for col in table.columns:
        lo_hi = (f"{col} lo", f"{col} hi")
        if not schema.intervals or not re.fullmatch(schema.intervals, str(col)):
            continue
        if not all(c in table.columns for c in lo_hi):
            continue
        lo, hi = (pd.to_numeric(table[c], errors="coerce").to_numpy(float) for c in lo_hi)
        reversed_ = np.flatnonzero(lo > hi)  # NaN compares False: no interval, not reversed
        if reversed_.size:
            i = int(reversed_[0])
            raise ValueError(
                f"{where}{row(i)} the interval of {col} is reversed ({lo[i]} > {hi[i]}); {fix}."
            )
