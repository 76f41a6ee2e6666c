"""The study, section by section: one call per notebook cell.

Notebooks stay thin: they open a :class:`Study` with their parameters and call its methods.
Every figure method returns a :class:`FigureResult` (figure, saved path, table), which a
notebook shows inline. Outputs go to ``<output root>/figures/<label>/<stem>.png`` and
``<output root>/results/<label>/<notebook>.csv`` (:mod:`vpr_core.paths`).

- :mod:`.core`: :class:`Study` (runs, saving, recording), :func:`open_study`,
  :func:`table1`, :func:`extra_datasets`.
- :mod:`.registry`: :data:`FIGURES`, the expected figures (stem -> notebook, paper item).
- :mod:`.matches` (Fig. 1-3, 8), :mod:`.scales` (Fig. 4, 6), :mod:`.landmarks` (Fig. 9, 14),
  :mod:`.comparisons` (Fig. 5, 7, 10-13), :mod:`.tour` (notebook 01's pipeline steps),
  :mod:`.cost` (Table 5).

The paper's settings (Tables 2-4, Fig. 7 thresholds) come from :mod:`vpr_core.paper` and are
re-exported here for notebooks.
"""

from __future__ import annotations

from ..paper import (
    DENSE_TABLES,
    FIG7_NMS_THRESHOLDS,
    FIG7_SOFT_NMS_THRESHOLDS,
    TABLE2,
    TABLE3,
    TABLE4,
)
from .core import QUICK_PLACES, RESULT_COLUMNS, Study, extra_datasets, open_study, table1
from .cost import COST_COLUMNS
from .registry import FIGURES, FigureSpec, expected_figures, figure_spec
from .result import FigureResult

__all__ = [
    "COST_COLUMNS",
    "DENSE_TABLES",
    "FIG7_NMS_THRESHOLDS",
    "FIG7_SOFT_NMS_THRESHOLDS",
    "FIGURES",
    "QUICK_PLACES",
    "RESULT_COLUMNS",
    "TABLE2",
    "TABLE3",
    "TABLE4",
    "FigureResult",
    "FigureSpec",
    "Study",
    "expected_figures",
    "extra_datasets",
    "figure_spec",
    "open_study",
    "table1",
]
