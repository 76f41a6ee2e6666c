"""The paper's claims against the saved comparison tables (vpr_study.findings), keyed by
configuration (run key), never by legend text."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from vpr_core import ON_PAR_MARGIN, claim_verdict, cmr_difference
from vpr_core.methods import get_method, run_key
from vpr_study import findings


def _table(folder, figure, rows, baseline_run, baseline_label="base"):
    """A compare() table: the baseline row first, then (run, label, d, lo, hi) rows."""
    folder.mkdir(parents=True, exist_ok=True)
    recs = [{"method": baseline_label, "run": baseline_run, "baseline": None}]
    for run, label, d, lo, hi in rows:
        recs.append(
            {
                "method": label,
                "run": run,
                "baseline": baseline_label,
                "dAUC": d,
                "dAUC lo": lo,
                "dAUC hi": hi,
                "dAUC p": 0.01,
                "dAUC needs": 1234.0,
            }
        )
    pd.DataFrame(recs).to_csv(folder / f"{figure}.csv", index=False)


def test_verdicts_follow_the_interval_and_the_claims_direction(tmp_path):
    res = tmp_path / "results" / "d"
    _table(
        res,
        "fig05_selection",
        [
            ("selection_scheme1", "any legend", 0.2, 0.1, 0.3),
            ("selection_scheme2", "S2", 0.05, -0.02, 0.12),
        ],
        "classical",
    )
    _table(
        res,
        "fig13_comparison",
        [("classical", "c", 0.0, 0.0, 0.0), ("global", "g", -0.1, -0.2, -0.05)],
        "dense",
    )
    _table(
        res,
        "fig07a_overlap_nms",
        [
            ("overlap_scheme1(iou_threshold=0.4)", "renamed", 0.1, 0.05, 0.15),
            ("overlap_scheme1(iou_threshold=0.7)", "x", 0.0, -0.01, 0.02),
        ],
        "classical",
    )
    set1 = run_key(get_method("dense", scales=(0.25,), per_scale=100))
    _table(res, "fig10_scale_levels", [("dense", "Set 5 whatever", -0.2, -0.3, -0.1)], set1)
    t = findings.findings_table(["d"], out=tmp_path)
    v = t["d verdict"]
    assert v["Fig. 5: selection Scheme 1 beats classical"] == "higher (as the paper says)"
    assert (
        v["Fig. 5: selection Scheme 2 lags behind classical"]
        == "inconclusive (needs ~1,200 queries)"
    )
    assert v["Fig. 7a: NMS (Alg. 3) at IoU 0.4 falls below classical"] == "higher (paper: lower)"
    # [-0.01, +0.02] lies inside the +-0.05 margin: the parity claim holds
    assert v["Fig. 7a: NMS at IoU 0.7 is on par with classical"] == "on par (as the paper says)"
    assert (
        v["Table 2: 4 scales x 25 (Set 5) beat one scale x 100 (Set 1)"] == "lower (paper: higher)"
    )
    assert v["Table 2: one large scale (Set 2, 0.49) is worse than Set 1"] == "not run"
    assert v["Fig. 13: classical is clearly worse than dense"] == "not testable (identical results)"
    assert v["Fig. 13: Scheme 1 is slightly worse than dense"] == "not run"
    assert v["(not in the paper) a global descriptor vs dense landmarks"] == "lower"
    assert t.loc["Fig. 5: selection Scheme 1 beats classical", "d"].startswith("+0.200 [+0.100")
    md = findings.findings_markdown(["d"], out=tmp_path)
    lines = md.splitlines()
    assert lines[0] == findings.LEGEND and lines[2] == "| paper's claim | d |"
    assert "**higher** (as the paper says)" in md and "**lower** (paper: higher)" in md
    assert "**inconclusive** (needs ~1,200 queries)" in md
    words = {"holds", "does not hold", "finding"}
    assert not any(w in md.replace("(as the paper says)", "") for w in words), md
    # results/findings.md: the paper's claims (the README's table), then issue 55's steps in a
    # table of their own, with a column for each folder that holds notebook 07's table only
    doc = findings.findings_document(["d"], out=tmp_path)
    assert doc.startswith(md) and "No result folder holds notebook 07's table yet" in doc
    e = [("dense(weighting=contrast)", "c", 0.1, 0.0, 0.2)]  # no step of issue 55 run
    _table(tmp_path / "results" / "e", findings.STEPS_TABLE, e, "dense")
    csv = tmp_path / "results" / "e" / f"{findings.STEPS_TABLE}.csv"
    t = pd.read_csv(csv)
    t.assign(**{c.replace("AUC", "R@1"): t[c] for c in t.columns if c.startswith("dAUC")}).to_csv(
        csv, index=False
    )
    doc = findings.findings_document(["d"], out=tmp_path)
    assert doc.startswith(md) and "| (not in the paper) step | e |" in doc
    rows = [ln for ln in doc[len(md) :].splitlines() if ln.startswith(("| two", "| whit", "| q"))]
    rows += [ln for ln in doc[len(md) :].splitlines() if ln.startswith("| database")]
    steps = [ln for ln in rows if "with vs" in ln]
    assert len(steps) == 36 and len(rows) == len(findings.STEP_CLAIMS) == 36 + 12
    assert all(ln.endswith("**not run** |") for ln in rows)
    assert sum(
        "whitening recipe (needs the query batch): dense against contrast" in ln for ln in rows
    )
    assert sum(ln.startswith("| two-sided contrast: dense with vs without (AUC) |") for ln in steps)
    assert sum(ln.startswith("| two-sided contrast: dense with vs without (R@1) |") for ln in steps)
    assert len({ln.split(" | ")[0] for ln in rows}) == 48  # a row's claim names its metric
    assert not any(c.text in md for c in findings.STEP_CLAIMS)


_PAR = "Fig. 7a: NMS at IoU 0.7 is on par with classical"


@pytest.mark.parametrize(
    ("d", "lo", "hi", "verdict"),
    [
        (0.01, -0.04, 0.049999, "on par (as the paper says)"),  # inside
        # the edge: a bound stored as 0.050000 may have been 0.0500004, beyond the margin
        (0.01, -0.04, 0.05, "inconclusive (on par needs ~130 queries)"),
        (0.03, 0.01, 0.049, "on par (as the paper says)"),  # a difference, but inside the margin
        (0.06, 0.02, 0.1, "higher (paper: on par)"),  # excludes 0, beyond the margin
        (-0.08, -0.12, -0.04, "lower (paper: on par)"),
        # contains 0 but reaches beyond +-0.05: no difference found is not parity;
        # 100 queries * (half-width 0.06 / room 0.03)^2
        (0.02, -0.04, 0.08, "inconclusive (on par needs ~400 queries)"),
        # Gardens Point mini, NMS 0.7: -0.189 [-0.434, +0.000] is no evidence of parity
        (-0.189, -0.434, 0.0, "inconclusive (needs ~1,200 queries)"),
    ],
)
def test_an_on_par_claim_holds_only_inside_the_margin(tmp_path, d, lo, hi, verdict):
    res = tmp_path / "results" / "d"
    _table(
        res,
        "fig07a_overlap_nms",
        [("overlap_scheme1(iou_threshold=0.7)", "x", d, lo, hi)],
        "classical",
    )
    df = pd.read_csv(res / "fig07a_overlap_nms.csv").assign(queries=100)
    df.to_csv(res / "fig07a_overlap_nms.csv", index=False)
    assert findings.findings_table(["d"], out=tmp_path)["d verdict"][_PAR] == verdict
    assert ON_PAR_MARGIN == 0.05


@pytest.mark.parametrize(
    "label", ["a|b", "two\nlines", "cr\rrow", "<img src=x onerror=alert(1)>", "a&b", "back\\|"]
)
def test_the_markdown_table_escapes_every_label_and_cell(tmp_path, label):
    """A label with ``|``, a line break or HTML is escaped as one cell (issue 45); a results folder
    of that name is refused as a label (issue 53: labels read from disk pass check_label)."""
    res = tmp_path / "results" / label.replace("/", "_")
    res.mkdir(parents=True)
    try:
        _table(res, "fig05_selection", [("selection_scheme1", label, 0.2, 0.1, 0.3)], "classical")
    except OSError:
        pytest.skip("this file system refuses the name")
    with pytest.raises(ValueError, match="must be one folder name"):
        findings.findings_markdown([label], out=tmp_path)
    cell = findings.markdown_cell(label)
    assert "<img" not in cell and "\r" not in cell and "\n" not in cell
    assert cell.replace("\\\\", "").replace("\\|", "").count("|") == 0
    assert findings.markdown_cell("<b>&</b>") == "&lt;b&gt;&amp;&lt;/b&gt;"
    assert findings.markdown_cell("a\r\nb\nc|d") == "a<br>b<br>c\\|d"


def test_a_run_against_another_baseline_is_not_the_claim(tmp_path):
    res = tmp_path / "results" / "d"
    # scheme 1 compared against scheme 2, not classical: the claim has no number
    _table(
        res, "fig05_selection", [("selection_scheme1", "s1", 0.2, 0.1, 0.3)], "selection_scheme2"
    )
    v = findings.findings_table(["d"], out=tmp_path)["d verdict"]
    assert v["Fig. 5: selection Scheme 1 beats classical"] == "not run"


def test_a_table_without_run_keys_is_refused(tmp_path):
    res = tmp_path / "results" / "d"
    res.mkdir(parents=True)
    pd.DataFrame({"method": ["a"], "AUC": [0.5]}).to_csv(res / "fig05_selection.csv")
    with pytest.raises(ValueError, match="comparison table"):
        findings.findings_table(["d"], out=tmp_path)


def test_claims_name_configurations():
    keys = {c.text: c.keys for c in findings.CLAIMS}
    assert keys["Fig. 7a: NMS (Alg. 3) at IoU 0.4 falls below classical"] == (
        "overlap_scheme1(iou_threshold=0.4)",
        "classical",
    )
    assert keys["Table 2: 4 scales x 25 (Set 5) beat one scale x 100 (Set 1)"] == (
        "dense",
        "dense(per_scale=100, scales=0.25)",
    )


def test_cmr_difference_bootstraps_over_queries():
    rng = np.random.default_rng(0)
    rows = []
    for q in range(30):
        for scale, p in ((1, 0.2), (2, 0.3), (6, 0.8)):
            for _ in range(10):
                rows.append(
                    {"query": q, "pair": "gt", "scale": scale, "correct": float(rng.random() < p)}
                )
    rows.append({"query": 0, "pair": "irrelevant", "scale": 6, "correct": np.nan})
    d, lo, hi = cmr_difference(pd.DataFrame(rows))
    assert 0.45 < d < 0.6 and lo < d < hi and lo > 0.3
    assert cmr_difference(pd.DataFrame(rows)) == (d, lo, hi)  # seeded
    with pytest.raises(ValueError, match="Scales 1-3"):
        cmr_difference(pd.DataFrame([r for r in rows if r["scale"] != 6]))


def test_result_labels_put_the_study_first_and_skip_quick_and_other_folders(tmp_path):
    for name in ("synthetic", "gardens_point_mini", "nordland_step5", "x_quick", "benchmarks"):
        (tmp_path / "results" / name).mkdir(parents=True)
    for name in ("synthetic", "gardens_point_mini", "nordland_step5", "x_quick"):
        (tmp_path / "results" / name / "fig05_selection.csv").write_text("run\n")
    assert findings.result_labels(["synthetic", "gardens_point_mini", "absent"], out=tmp_path) == [
        "synthetic",
        "gardens_point_mini",
        "nordland_step5",
    ]
    assert findings.result_labels(out=tmp_path / "nothing") == []


def test_identical_results_have_one_verdict_in_compare_and_the_findings(tiny_synthetic):
    """Issue 54 item 5: a run identical to its baseline is "not testable (identical results)"
    in compare's table (not "inconclusive": no number of queries could tell them apart), the
    words of the findings table; the legend states the rules in the order they apply."""
    from vpr_core import run_method
    from vpr_core.evaluation import IDENTICAL, compare

    a = run_method("global", tiny_synthetic, backbone="hog", n_bootstrap=50)
    b = run_method("global", tiny_synthetic, backbone="hog", n_bootstrap=50, label="again")
    table = compare([a, b], n_bootstrap=50)
    assert table.loc["again", "dAUC verdict"] == IDENTICAL == claim_verdict("", 0.0, 0.0, 0.0)
    assert IDENTICAL in str(table)
    order = [
        findings.LEGEND.index(w)
        for w in ("**not testable**", "**on par**", "**higher**", "**inconclusive**")
    ]
    assert order == sorted(order)
