"""The paper's claims against paired differences (vpr_core.study.findings)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from vpr_core.study import findings


def _paired(folder, notebook, figure, baseline, rows):
    folder.mkdir(parents=True, exist_ok=True)
    recs = [{"figure": figure, "method": m, "baseline": baseline, "dAUC": d, "dAUC lo": lo,
             "dAUC hi": hi, "dAUC p": 0.01} for m, d, lo, hi in rows]
    pd.DataFrame(recs).to_csv(folder / f"{notebook}_{figure}_paired.csv", index=False)


def test_verdicts_follow_the_interval_and_the_claims_direction(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path))
    res = tmp_path / "results" / "d"
    _paired(res, "03_landmark_selection", "fig05_selection", "classical",
            [("selection_scheme1", 0.2, 0.1, 0.3), ("selection_scheme2", 0.05, -0.02, 0.12)])
    _paired(res, "06_comparison", "fig13_comparison", "dense",
            [("classical", 0.0, 0.0, 0.0), ("global", -0.1, -0.2, -0.05)])
    _paired(res, "04_overlap", "fig07a_overlap_nms", "classical",
            [("overlap_scheme1 (IoU 0.4)", 0.1, 0.05, 0.15),
             ("overlap_scheme1 (IoU 0.7)", 0.0, -0.01, 0.02)])
    _paired(res, "05_dense_sampling_parameters", "fig10_scale_levels", "Set 1: 0.25 x 100",
            [("Set 5: 0.16/0.25/0.36/0.49 x 25", -0.2, -0.3, -0.1)])
    t = findings.findings_table(["d"])
    v = t["d verdict"]
    assert v["Fig. 5: selection Scheme 1 beats classical"] == "holds"
    assert v["Fig. 5: selection Scheme 2 lags behind classical"] == "inconclusive"
    assert v["Fig. 7a: NMS (Alg. 3) at IoU 0.4 falls below classical"] == "does not hold"
    assert v["Fig. 7a: NMS at IoU 0.7 is on par with classical"].startswith("holds")
    assert v["Table 2: 4 scales x 25 (Set 5) beat one scale x 100 (Set 1)"] == "does not hold"
    assert v["Fig. 13: classical is clearly worse than dense"] == "not testable (identical results)"
    assert v["Fig. 13: Scheme 1 is slightly worse than dense"] == "not run"
    assert v["(not in the paper) a global descriptor vs dense landmarks"] == "finding: lower"
    assert t.loc["Fig. 5: selection Scheme 1 beats classical", "d"].startswith("+0.200 [+0.100")
    md = findings.findings_markdown(["d"])
    assert md.splitlines()[0] == "| paper's claim | d |" and "**holds**" in md


def test_cmr_difference_bootstraps_over_queries():
    rng = np.random.default_rng(0)
    rows = []
    for q in range(30):
        for scale, p in ((1, 0.2), (2, 0.3), (6, 0.8)):
            for _ in range(10):
                rows.append({"query": q, "pair": "gt", "scale": scale,
                             "correct": float(rng.random() < p)})
    rows.append({"query": 0, "pair": "irrelevant", "scale": 6, "correct": np.nan})
    d, lo, hi = findings.cmr_difference(pd.DataFrame(rows))
    assert 0.45 < d < 0.6 and lo < d < hi and lo > 0.3
    assert findings.cmr_difference(pd.DataFrame(rows)) == (d, lo, hi)  # seeded
    with pytest.raises(ValueError, match="Scales 1-3"):
        findings.cmr_difference(pd.DataFrame([r for r in rows if r["scale"] != 6]))
