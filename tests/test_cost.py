"""Table 5 measured on the pipeline's own stages (vpr_core.cost)."""

from __future__ import annotations

import os

import pytest

from vpr_core.cost import COST_COLUMNS, cost_table


def test_cost_table_times_fresh_pipeline_stages(tiny_synthetic):
    before = dict(os.environ)
    t = cost_table(tiny_synthetic, n_images=1, methods=("dense", "classical"))
    assert dict(os.environ) == before  # no process-wide change
    assert list(t.columns) == list(COST_COLUMNS)
    assert (t.to_numpy() > 0).all()
    # Edge Boxes over 1,000 candidates (computed afresh) is far slower than the dense grid
    assert (
        t.loc["classical", "extract landmarks (s/img)"]
        > 10 * t.loc["dense", "extract landmarks (s/img)"]
    )
    with pytest.raises(ValueError, match="n_images"):
        cost_table(tiny_synthetic, n_images=0)
