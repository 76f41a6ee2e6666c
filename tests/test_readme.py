"""The README's numbers are the committed files' numbers (issue 26 item 9).

Each quoted number is formatted here from the committed table it comes from and looked up in the
README; a regenerated table that changes a quoted number fails this test until the README says
the new number. Regenerate the findings table with ``vpr-study findings`` and paste it.
"""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

from vpr_study.findings import findings_markdown

REPO = Path(__file__).resolve().parents[1]
README = (REPO / "README.md").read_text(encoding="utf-8")
RESULTS = REPO / "results"


def _section(heading: str) -> str:
    """The README text from ``heading`` to the next heading of the same or a higher level."""
    start = README.index(heading)
    level = heading.split(" ")[0]
    rest = README[start + len(heading) :]
    nxt = re.search(rf"^#{{1,{len(level)}}} ", rest, flags=re.M)
    return rest[: nxt.start()] if nxt else rest


def _unwrapped(text: str) -> str:
    """Markdown paragraphs with their line breaks (and list indentation) as single spaces."""
    return re.sub(r"\s*\n\s*", " ", text)


def _iv(value: float, lo: float, hi: float, signed: bool = True) -> str:
    f = "{:+.3f}" if signed else "{:.3f}"
    return f"{f.format(value)} [{f.format(lo)}, {f.format(hi)}]"


def test_the_findings_table_is_the_one_the_committed_tables_give():
    head = next(line for line in README.splitlines() if line.startswith("| paper's claim |"))
    labels = [c.strip() for c in head.strip("|").split("|")[1:]]
    expected = findings_markdown(labels, out=REPO)
    assert expected in README, (
        "README's findings table differs from `vpr-study findings` on the committed results; "
        "paste this table:\n" + expected
    )
    assert expected in (RESULTS / "findings.md").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    "label", ["synthetic", "gardens_point_mini", "nordland_step50", "nordland_step5"]
)
@pytest.mark.parametrize("method", ["dense", "classical"])
def test_geometry_numbers_are_the_study_tables(label, method):
    row = pd.read_csv(RESULTS / label / f"geometry_{method}.csv").iloc[1]
    quoted = _iv(row["dAUC"], row["dAUC lo"], row["dAUC hi"])
    assert quoted in _unwrapped(_section("## Why a method wins")), (label, method, quoted)


def test_calibration_table_is_the_synthetic_study():
    synthetic = pd.concat(
        pd.read_csv(RESULTS / "synthetic" / f)
        for f in ("fig05_selection.csv", "fig13_comparison.csv")
    ).drop_duplicates("run")
    for run, name in [
        ("classical", "classical"),
        ("selection_scheme1", "selection Scheme 1"),
        ("selection_scheme2", "selection Scheme 2"),
        ("dense", "dense 4 x 25"),
    ]:
        r = synthetic.set_index("run").loc[run]
        cell = _iv(r["AUC"], r["AUC lo"], r["AUC hi"], signed=False)
        assert re.search(rf"^\| {name} \| [0-9.]+ \| {re.escape(cell)} \|$", README, re.M), name


def test_observation_1_rates_are_fig04():
    cmr = pd.read_csv(RESULTS / "synthetic" / "fig04_scale_statistics.csv")["cmr"]
    text = (
        f"correct-match rate {cmr[0]:.2f} at Scale 1, {cmr[1]:.2f} at Scale 2, "
        f"{cmr[2:7].min():.2f}-{cmr[2:7].max():.2f} at Scales 3-7"
    )
    assert text in _unwrapped(README)


def test_descriptor_at_scale_numbers_are_the_paired_benchmark():
    paired = pd.read_csv(RESULTS / "benchmarks" / "descriptor_paired.csv")
    r = paired[(paired["dataset"] == "nordland_step1_tol1") & (paired["method"] == "dense")].iloc[0]
    text = _unwrapped(README)
    assert f"AUC {r['AUC a']}, R@1 {r['R@1 a']}" in text  # the 96 px run
    assert f"dense AUC {r['AUC b']}, R@1 {r['R@1 b']}" in text  # the default
    d_auc = f"dAUC {r['dAUC']:.3f} {r['dAUC 95%'].replace('+', '')}"
    d_r1 = f"dR@1 {r['dR@1']:.3f} {r['dR@1 95%'].replace('+', '')}"
    assert d_auc in text and d_r1 in text


def descriptor_rows() -> list[str]:
    """The README's "Which descriptor?" table rows, from ``descriptor_choice.csv``."""
    table = pd.read_csv(RESULTS / "benchmarks" / "descriptor_choice.csv")
    cols = [
        "gardens_point_mini classical AUC",
        "gardens_point_mini dense AUC",
        "nordland_step50 classical AUC",
        "nordland_step50 dense AUC",
        "nordland_step50 dense R@1",
    ]
    return [
        f"| {r['option']} | {r['raw_dim']} | {r['s/img']:.3f} | "
        + " | ".join(f"{r[c]:.3f} {r[c + ' 95%']}" for c in cols)
        + " |"
        for _, r in table.iterrows()
    ]


def test_descriptor_table_is_the_benchmark_table():
    rows = descriptor_rows()
    shown = [line for line in README.splitlines() if line.startswith(("| lite", "| hog"))]
    assert shown == rows, "paste these rows:\n" + "\n".join(rows)


def test_paired_descriptor_rows_are_the_benchmark_table():
    paired = pd.read_csv(RESULTS / "benchmarks" / "descriptor_paired.csv")
    rows = [line for line in README.splitlines() if re.match(r"^\| .* - default \(", line)]
    assert len(rows) == len(paired)
    for _, r in paired.iterrows():
        cells = [f"{r[d]:+.3f} {r[d + ' 95%']} {r[d + ' verdict']}" for d in ("dAUC", "dR@1")]
        want = f"| {r['method']} | {cells[0]} | {cells[1]} |"
        assert any(line.endswith(want) for line in rows), want


def test_backbone_choice_prose_is_the_lite2_benchmark():
    paired = pd.read_csv(RESULTS / "benchmarks" / "descriptor_paired.csv")
    lite2 = paired[paired["a"] == "efficientnet_lite2:input_size=260"].set_index("method")
    text = _unwrapped(README)
    for method in ("dense", "classical"):
        r = lite2.loc[method]
        a, b = r["AUC a"].split()[0], r["AUC b"].split()[0]
        assert f"{method} AUC {a} against {b}" in text or f"{method} {a} against {b}" in text
        assert f"{r['dAUC']:+.3f} {r['dAUC 95%']}" in text, method
    choice = pd.read_csv(RESULTS / "benchmarks" / "descriptor_choice.csv").set_index("option")
    assert f"costs {choice.loc['lite2 s5 260', 's/img']:.2f} s per" in text


def test_weighting_numbers_are_the_benchmark_table():
    """(Not in the paper) every row of results/benchmarks/weighting.csv is quoted in the README's
    weighting section: AUC and R@1 with intervals, and each weighting's paired differences."""
    table = pd.read_csv(RESULTS / "benchmarks" / "weighting.csv")
    text = _unwrapped(_section("### Does a database weighting help?"))
    for _, r in table.iterrows():
        for col in ("AUC", "R@1"):
            quoted = _iv(r[col], r[f"{col} lo"], r[f"{col} hi"], signed=False)
            assert quoted in text, (r["set"], r["method"], r["weighting"], col, quoted)
        if r["weighting"] != "none":
            for col in ("dAUC", "dR@1"):
                quoted = f"{_iv(r[col], r[f'{col} lo'], r[f'{col} hi'])} {r[f'{col} verdict']}"
                assert quoted in text, (r["set"], r["method"], r["weighting"], col, quoted)
