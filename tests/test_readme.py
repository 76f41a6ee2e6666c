"""The README's numbers are the committed files' numbers (issue 26 item 9, issue 44 item 3).

Every number in the README is accounted for: the findings table is ``vpr-study findings`` on the
committed results; each other measured number is formatted here from the committed file it comes
from (``quoted()``: quoted text -> file, row and column); every remaining number is in a small
allow-list of numbers that are not measurements (paper references, settings, definitions). A
regenerated table that changes a quoted number, or a new prose number with no source, fails
here. The tables of docs/MEASUREMENTS.md are checked against their CSVs the same way. Wall times
of whole commands are in no CSV: their record is the timed-runs table of docs/MEASUREMENTS.md.
"""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

from vpr_study.findings import findings_markdown

REPO = Path(__file__).resolve().parents[1]
README = (REPO / "README.md").read_text(encoding="utf-8")
MEASUREMENTS = (REPO / "docs" / "MEASUREMENTS.md").read_text(encoding="utf-8")
RESULTS = REPO / "results"
MAX_LINES = 200  # every line counts, the findings table's too

#: Numbers that are not measurements: paper references, method settings, definitions, names.
#: Each entry masks only its own text, so the same digits elsewhere still need a source.
ALLOWED_PATTERNS = [
    # the paper's numbered items: Table 1, Tables 2-4, Fig. 13, Alg. 3-4, Eq. (1), Scheme 2 ...
    r"\b(?:Tables?|Figs?\.|Alg\.|Algorithms?|Eq\.|Observation|Scheme) \(?\d+\)?(?:-\d+)?",
    r"\bR@\d+\b",  # metric names
    r"\bnotebooks? \d\d(?:-\d\d)?\b",  # notebook numbers
    r"--[a-z][a-z-]* \d+\b",  # command-line settings in the examples (--step 50, --shortlist 25)
]
ALLOWED_TEXT = [
    "4 scales x 25",  # the paper's dense default (Sec. 4)
    "4 x 25",
    "six scales x 16",  # Table 2 settings
    "one scale x 100",
    "top 100 Edge Box",  # the paper's landmarks per image
    "top 25 references",  # the shortlist setting of nordland_step5
    "roi, shortlist 25",
    "tolerance 0",
    "tolerance 1",  # the frame tolerance of the all-of-Nordland benchmarks
    "IoU 0.3",  # Fig. 7 thresholds
    "IoU 0.4",
    "IoU 0.7",
    "at 0.4",
    "128 px",  # descriptor settings
    "1,024-d",
    "112-channel",
    "95%",  # definitions: interval level, verdict rule, equivalence margin
    "excludes 0",
    "exclude 0",
    "contains 0",
    "±0.05 AUC",
    "2-core",  # the machine, named in results/benchmarks/study_profile.csv
    "5-minute target of issue 35",
    "Tokyo 24/7",  # a dataset's name
    "VPR_QUICK=1",  # a setting: the headless small set
    "$1",  # a shell argument
    "8 generated places",  # the small set's places (vpr_study.runner.QUICK_PLACES)
]

NUMBER = re.compile(r"\d+(?:[.,]\d+)*")


def _unwrapped(text: str) -> str:
    """Markdown paragraphs with their line breaks (and list indentation) as single spaces."""
    return re.sub(r"\s*\n\s*", " ", text)


def _iv(value: float, lo: float, hi: float, signed: bool = True) -> str:
    f = "{:+.3f}" if signed else "{:.3f}"
    return f"{f.format(value)} [{f.format(lo)}, {f.format(hi)}]"


def _csv(path: str) -> pd.DataFrame:
    return pd.read_csv(RESULTS / path, comment="#")


def _run(path: str, run: str) -> pd.Series:
    """The row of a study table whose run key is ``run``."""
    return _csv(path).set_index("run").loc[run]


def _queries(label: str) -> int:
    return int(_csv(f"{label}/fig13_comparison.csv")["queries"].iloc[0])


def _timed(key: str) -> str:
    """The wall time of row ``key`` of docs/MEASUREMENTS.md's timed-runs table."""
    for line in MEASUREMENTS.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells[0] == key:
            return cells[4]
    raise KeyError(f"docs/MEASUREMENTS.md has no timed run {key!r}")


def _findings_lines() -> list[str]:
    """The README's findings table: from its header row to the last row of the block."""
    lines = README.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("| paper's claim |"))
    end = start
    while end < len(lines) and lines[end].startswith("|"):
        end += 1
    return lines[start:end]


def quoted() -> list[tuple[str, str]]:
    """Each measured number the README quotes: (the text as the README must say it, its source)."""
    step5 = "nordland_step5"
    d, c = (
        _run(f"{step5}/fig13_comparison.csv", "dense"),
        _run(f"{step5}/fig13_comparison.csv", "classical"),
    )
    wd = _run(f"{step5}/weighting_dense.csv", "dense(weighting=contrast)")
    wc = _run(f"{step5}/weighting_classical.csv", "classical(weighting=contrast)")
    ws = _run("synthetic/weighting_dense.csv", "dense(weighting=contrast)")
    paired = _csv("benchmarks/descriptor_paired.csv")
    full = paired[(paired["dataset"] == "nordland_step1_tol1") & (paired["method"] == "dense")]
    full = full.iloc[0]
    prof = _csv("benchmarks/study_profile.csv").set_index(["label", "notebook", "category"])
    crop = prof.loc[("ALL", "ALL", "crop features"), "cold_s"]
    total = prof.loc[("ALL", "ALL", "TOTAL"), "cold_s"]
    n = {label: _queries(label) for label in ("synthetic", "gardens_point_mini", step5)}
    n50, nk25 = _queries("nordland_step50"), _queries("nordland_step50_k25")
    fig13 = f"results/{step5}/fig13_comparison.csv: dense, classical"
    stats = _csv("benchmarks/weighting_statistics.csv")
    contrast = stats[stats["weighting"] == "contrast"]
    kept = contrast[contrast["default"]].iloc[0]
    kept_all = contrast[contrast["default"]].sort_values("places").iloc[-1]  # the most places
    former = contrast.loc[contrast["sample"].idxmax()]
    scaling = _csv("benchmarks/weighting_scaling.csv")
    fc = _csv("benchmarks/nordland_full_contrast.csv").iloc[0]

    def exponent(matching: str) -> str:
        rows = scaling[(scaling["matching"] == matching) & (scaling["weighting"] == "none")]
        return f"{rows['exponent'].iloc[0]:.2f}"

    return [
        (f"generated, {n['synthetic']} places", "results/synthetic/*.csv: queries"),
        (f"the embedded set, {n['synthetic']} places", "results/synthetic/*.csv: queries"),
        (f"{n['gardens_point_mini']} real Gardens Point", "results/gardens_point_mini: queries"),
        (f"{n50} Nordland places, every 50th", "results/nordland_step50/*.csv: queries"),
        (f"{n[step5]} places, every 5th", f"results/{step5}/*.csv: queries"),
        (f"the {nk25} places with that shortlist", "results/nordland_step50_k25: queries"),
        (f"{n[step5]} Nordland places", f"results/{step5}/*.csv: queries"),
        (
            f"dense AUC {_iv(d['AUC'], d['AUC lo'], d['AUC hi'], False)} against "
            f"{_iv(c['AUC'], c['AUC lo'], c['AUC hi'], False)} for classical",
            fig13,
        ),
        (
            f"dense AUC {d['AUC']:.3f} -> {wd['AUC']:.3f}, "
            f"{_iv(wd['dAUC'], wd['dAUC lo'], wd['dAUC hi'])}",
            f"results/{step5}/weighting_dense.csv",
        ),
        (
            f"classical {c['AUC']:.3f} -> {wc['AUC']:.3f}, "
            f"{_iv(wc['dAUC'], wc['dAUC lo'], wc['dAUC hi'])}",
            f"results/{step5}/weighting_classical.csv",
        ),
        (
            f"generated set dense {_iv(ws['dAUC'], ws['dAUC lo'], ws['dAUC hi'])}",
            "results/synthetic/weighting_dense.csv",
        ),
        (
            f"{full['queries']:,} x {full['queries']:,} places",
            "results/benchmarks/descriptor_paired.csv: nordland_step1_tol1 queries",
        ),
        (
            f"dense AUC {full['AUC b']}",
            "results/benchmarks/descriptor_paired.csv: nordland_step1_tol1, AUC b",
        ),
        (
            f"in {_timed('nordland-full')} from an empty cache",
            "docs/MEASUREMENTS.md: nordland-full",
        ),
        (
            f"{_timed('study-cold')} from an empty cache, {_timed('study-unchanged')} when "
            "nothing changed",
            "docs/MEASUREMENTS.md: study-cold, study-unchanged",
        ),
        (f"AMD EPYC: {_timed('study-cold-epyc')} cold", "docs/MEASUREMENTS.md: study-cold-epyc"),
        (
            f"with contrast AUC {_iv(fc['AUC'], fc['AUC lo'], fc['AUC hi'], False)} in "
            f"{_timed('nordland-full-contrast')}",
            "results/benchmarks/nordland_full_contrast.csv, docs/MEASUREMENTS.md",
        ),
        (
            f"Crop features are {crop:.0f} s of the {total:.0f} s of a cold profile",
            "results/benchmarks/study_profile.csv: ALL crop features, TOTAL (cold_s)",
        ),
        (
            f"statistics now come from {int(kept['sample'])} sampled references, "
            f"{kept['x none']:.2f}x the unweighted matching time on {int(kept['places'])} places",
            "results/benchmarks/weighting_statistics.csv: default contrast sample",
        ),
        (
            f"and {kept_all['x none']:.2f}x ({kept_all['cpu x none']:.2f}x in CPU time) on "
            f"{int(kept_all['places']):,}",
            "results/benchmarks/weighting_statistics.csv: default contrast sample, most places",
        ),
        (
            f"former {int(former['sample'])}-reference shortlist statistics",
            "results/benchmarks/weighting_statistics.csv: the largest contrast sample",
        ),
        (
            f"as n^{exponent('exhaustive')} exhaustive and n^{exponent('shortlist 25')} with a "
            "shortlist of 25",
            "results/benchmarks/weighting_scaling.csv: exponent, unweighted",
        ),
    ]


def test_the_findings_table_is_the_one_the_committed_tables_give():
    labels = [c.strip() for c in _findings_lines()[0].strip("|").split("|")[1:]]
    expected = findings_markdown(labels, out=REPO)
    assert expected in README, (
        "README's findings table differs from `vpr-study findings` on the committed results; "
        "paste this table:\n" + expected
    )
    assert expected in (RESULTS / "findings.md").read_text(encoding="utf-8")


@pytest.mark.parametrize(("text", "source"), quoted(), ids=lambda v: v[:40])
def test_each_quoted_number_is_its_committed_source(text, source):
    assert text in _unwrapped(README), f"README should say {text!r} (from {source})"


def _findings_block() -> str:
    """The findings block as ``vpr-study findings`` writes it when the README holds it (its text
    too), else the README's findings table."""
    labels = [c.strip() for c in _findings_lines()[0].strip("|").split("|")[1:]]
    expected = findings_markdown(labels, out=REPO)
    return expected if expected in README else "\n".join(_findings_lines())


def test_every_number_in_the_readme_has_a_source_or_is_allowed():
    """Digits run: a number; digits inside a name (fig13, nordland_64x32, 00_start_here) are not.
    The findings block is checked whole by the test above."""
    body = README.replace(_findings_block(), "")
    body = re.sub(r"(?m)^\d+\. ", "#. ", body)  # numbered list items
    text = _unwrapped(body)
    for quote, _ in quoted():
        text = text.replace(quote, "#" * len(quote))
    for allowed in ALLOWED_TEXT:
        text = text.replace(allowed, "#" * len(allowed))
    for pattern in ALLOWED_PATTERNS:
        text = re.sub(pattern, lambda m: "#" * len(m.group()), text)
    stray = []
    for m in NUMBER.finditer(text):
        before = text[m.start() - 1] if m.start() else " "
        after = text[m.end()] if m.end() < len(text) else " "
        if re.match(r"[A-Za-z_]", before) or re.match(r"[A-Za-z_]", after):
            continue
        stray.append(text[max(0, m.start() - 30) : m.end() + 20])
    assert not stray, (
        "numbers in the README with no committed source: add each to quoted() with its file, "
        "or, when it is not a measurement, to ALLOWED_TEXT:\n" + "\n".join(stray)
    )


def test_readme_is_short():
    n = len(README.splitlines())
    assert n <= MAX_LINES, f"README has {n} lines; at most {MAX_LINES} (move detail to docs/)"


def test_readme_links_point_to_files():
    targets = re.findall(r"\]\(([^)#\s]+)[^)]*\)", README)
    assert targets
    missing = [t for t in targets if "://" not in t and not (REPO / t).exists()]
    assert not missing, missing
    for doc in ("ARCHITECTURE", "DEFINITIONS", "PAPER_MAP", "MEASUREMENTS"):
        assert f"](docs/{doc}.md)" in README, doc


def test_the_shortlist_moves_no_verdict():
    """README: the 72 places with a shortlist of 25 give every verdict of the exhaustive run."""
    rows = [line for line in _findings_lines()[2:]]
    head = [c.strip() for c in _findings_lines()[0].strip("|").split("|")]
    a, b = head.index("nordland_step50"), head.index("nordland_step50_k25")
    compared = 0
    for line in rows:
        cells = [c.strip() for c in line.strip("|").split("|")]
        va, vb = (re.sub(r" \(.*", "", c.split("**")[1]) for c in (cells[a], cells[b]))
        if "not run" in (va, vb):
            continue
        compared += 1
        assert va == vb, (cells[0], va, vb)
    assert compared >= 10


def test_timed_runs_have_date_machine_and_commit():
    """docs/MEASUREMENTS.md: each wall time names its machine, date and recording commit."""
    rows = [
        line
        for line in MEASUREMENTS.splitlines()
        if re.match(r"^\| (study|nordland)[a-z0-9-]* \|", line)
    ]
    assert len(rows) >= 5
    for line in rows:
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert re.search(r"20\d\d-\d\d-\d\d \([0-9a-f]{7}\)", cells[3]), line
        assert re.fullmatch(r"(\d+ min )?\d+ s", cells[4]), line


# docs/MEASUREMENTS.md: the tables moved there from the README, against their committed CSVs.


def _paste(rows: list[str]) -> str:
    return "docs/MEASUREMENTS.md should hold these rows:\n" + "\n".join(rows)


def test_profile_table_is_the_study_profile():
    prof = _csv("benchmarks/study_profile.csv")
    rows = [
        f"| {r['category']} | {r['cold_s']:.0f} | {r['warm_s']:.0f} |"
        for _, r in prof[prof["label"] == "ALL"].iterrows()
    ]
    assert all(row in MEASUREMENTS for row in rows), _paste(rows)


def test_descriptor_table_is_the_benchmark_table():
    table = _csv("benchmarks/descriptor_choice.csv")
    cols = [
        "gardens_point_mini classical AUC",
        "gardens_point_mini dense AUC",
        "nordland_step50 classical AUC",
        "nordland_step50 dense AUC",
        "nordland_step50 dense R@1",
    ]
    rows = [
        f"| {r['option']} | {r['raw_dim']} | {r['s/img']:.3f} | "
        + " | ".join(f"{r[c]:.3f} {r[c + ' 95%']}" for c in cols)
        + " |"
        for _, r in table.iterrows()
    ]
    shown = [line for line in MEASUREMENTS.splitlines() if line.startswith(("| lite", "| hog"))]
    assert shown == rows, _paste(rows)


def test_paired_descriptor_rows_are_the_benchmark_table():
    paired = _csv("benchmarks/descriptor_paired.csv")
    rows = []
    for _, r in paired.iterrows():
        where = f"{r['queries']} places, {r['pooling']}"
        if r["shortlist"] == r["shortlist"]:  # not NaN
            where += f", shortlist {int(r['shortlist'])}"
        cells = " | ".join(f"{r[d]:+.3f} {r[d + ' 95%']}" for d in ("dAUC", "dR@1"))
        rows.append(f"| {r['a']} - {r['b']} ({where}) | {r['method']} | {cells} |")
    assert all(row in MEASUREMENTS for row in rows), _paste(rows)


def test_descriptor_prose_is_the_benchmark_tables():
    paired = _csv("benchmarks/descriptor_paired.csv")
    text = _unwrapped(MEASUREMENTS)
    lite2 = paired[paired["a"] == "efficientnet_lite2:input_size=260"].set_index("method")
    for method, prefix in (("dense", "dense AUC "), ("classical", "classical ")):
        r = lite2.loc[method]
        a, b = r["AUC a"].split()[0], r["AUC b"].split()[0]
        assert f"{prefix}{a} against {b}" in text, method
    choice = _csv("benchmarks/descriptor_choice.csv").set_index("option")
    s = choice["s/img"]
    assert (
        f"costs {s['lite2 s5 260']:.2f} s per image against {s['lite0 s5 128 (default)']:.2f} s"
    ) in text
    full = paired[paired["dataset"] == "nordland_step1_tol1"].iloc[0]
    assert f"AUC {full['AUC a']} against the default's {full['AUC b']}" in text


def test_weighting_table_is_the_benchmark_table():
    """(Not in the paper) each row of results/benchmarks/weighting.csv, as MEASUREMENTS shows it."""
    table = _csv("benchmarks/weighting.csv")
    rows = []
    for _, r in table.iterrows():
        where = f"{r['set']} ({r['queries']}, {r['pooling']}"
        where += ", shortlist 25)" if r["shortlist"] == 25 else ")"
        metrics = [_iv(r[m], r[f"{m} lo"], r[f"{m} hi"], False) for m in ("AUC", "R@1")]
        diffs = (
            ["", ""]
            if r["weighting"] == "none"
            else [_iv(r[m], r[f"{m} lo"], r[f"{m} hi"]) for m in ("dAUC", "dR@1")]
        )
        cells = [where, r["method"], r["weighting"], *metrics, *diffs]
        rows.append("| " + " | ".join(cells) + f" | {r['matching x none']:.2f}x |")
    assert all(row in MEASUREMENTS for row in rows), _paste(rows)


def test_geometry_rows_are_the_study_tables():
    rows = []
    for label in (
        "synthetic",
        "gardens_point_mini",
        "nordland_step50",
        "nordland_step5",
        "nordland_step50_k25",
    ):
        cells = []
        for method in ("dense", "classical"):
            r = _csv(f"{label}/geometry_{method}.csv").iloc[1]
            cells.append(_iv(r["dAUC"], r["dAUC lo"], r["dAUC hi"]))
        rows.append(f"| {label} | {cells[0]} | {cells[1]} |")
    assert all(row in MEASUREMENTS for row in rows), _paste(rows)


def test_observation_1_rates_are_fig04():
    cmr = _csv("synthetic/fig04_scale_statistics.csv")["cmr"]
    text = (
        f"{cmr[0]:.2f} at Scale 1, {cmr[1]:.2f} at Scale 2 and "
        f"{cmr[2:7].min():.2f}-{cmr[2:7].max():.2f} at Scales 3-7"
    )
    assert text in _unwrapped(MEASUREMENTS)


def test_calibration_table_is_the_synthetic_study():
    """docs/SYNTHETIC.md's calibrated column is the committed synthetic study."""
    synthetic = (
        pd.concat(_csv(f"synthetic/{f}") for f in ("fig05_selection.csv", "fig13_comparison.csv"))
        .drop_duplicates("run")
        .set_index("run")
    )
    doc = (REPO / "docs" / "SYNTHETIC.md").read_text(encoding="utf-8")
    for run, name in [
        ("classical", "classical"),
        ("selection_scheme1", "selection Scheme 1"),
        ("selection_scheme2", "selection Scheme 2"),
        ("dense", "dense 4 x 25"),
    ]:
        r = synthetic.loc[run]
        cell = _iv(r["AUC"], r["AUC lo"], r["AUC hi"], signed=False)
        assert re.search(rf"^\| {name} \| [0-9.]+ \| {re.escape(cell)} \|$", doc, re.M), name


def test_makefile_study_nordland_comment_is_measured():
    """The comment above `study-nordland` says the places and the time that were measured."""
    makefile = (REPO / "Makefile").read_text(encoding="utf-8")
    comment = _unwrapped(makefile[: makefile.index("\nstudy-nordland:")].rsplit("\n\n", 1)[-1])
    assert f"{_queries('nordland_step5')} Nordland places" in comment
    assert f"{_timed('study-nordland')} from an empty cache" in comment


def test_the_readme_says_what_make_clean_removes_and_names_the_insight_calls():
    """Issue 54 items 3 and 6: every path `make clean` removes is named beside it; the three
    calls that look closer are named; the documented small run of a study notebook parses."""
    import re
    import shlex

    makefile = (REPO / "Makefile").read_text(encoding="utf-8")
    (recipe,) = re.findall(r"^\trm -rf (.+)$", makefile[makefile.index("\nclean:") :], re.M)
    said_by_make = makefile[makefile.index("\nclean:") :]
    # issue 61: make clean says what it removed, what stays, and that Lab must be stopped first
    for words in ("removed .venv", "kept: user/", "figures/ and results/", "stop it first"):
        assert words in said_by_make, words
    text = _unwrapped(README)
    said = text[text.index("`make clean` removes") :][:300]
    for path in recipe.replace("$(VENV)", ".venv").split():
        assert f"`{path}" in said, f"README: `make clean` removes {path}, say so"
    for call in ("per_query(", "plot_disagreements(", "ds.with_tolerance("):
        assert call in text, call
    (command,) = re.findall(r"`(vpr-study run --quick --notebooks \w+)`", text)
    from vpr_study import cli

    args = cli.build_parser().parse_args(shlex.split(command)[1:])
    assert args.quick and args.notebooks == ["03_landmark_selection"]


def _step_rows(label: str) -> list[str]:
    """(Not in the paper; issue 55) the rows of MEASUREMENTS' table of notebook 07's steps at
    scale: each dense and classical run of ``places_alike_steps`` with its difference against
    the plain method and, for the two-sided runs, against the method with ``contrast``."""
    steps = _csv(f"{label}/places_alike_steps.csv")
    versus = _csv(f"{label}/places_alike_vs_contrast.csv").set_index("run")
    rows = []
    issue_55 = steps["method"].str.match(r"(dense|classical)\b") & ~steps["method"].str.contains(
        "whitened"
    )  # issue 62's whitening rows have a table of their own
    for _, r in steps[issue_55].iterrows():
        cells = [label, str(r["method"])]
        cells += [_iv(r[m], r[f"{m} lo"], r[f"{m} hi"], False) for m in ("AUC", "R@1")]
        plain = pd.isna(r["baseline"])
        cells += ["" if plain else _iv(r[m], r[f"{m} lo"], r[f"{m} hi"]) for m in ("dAUC", "dR@1")]
        v = versus.loc[r["run"]] if r["run"] in versus.index else None
        vs = v is not None and not pd.isna(v["baseline"])
        cells += [_iv(v[m], v[f"{m} lo"], v[f"{m} hi"]) if vs else "" for m in ("dAUC", "dR@1")]
        rows.append("| " + " | ".join(cells) + " |")
    return rows


def test_step_tables_at_scale_are_notebook_07s():
    rows = _step_rows("nordland_step5") + _step_rows("nordland_step1")
    assert len(rows) == 28
    assert all(row in MEASUREMENTS for row in rows), _paste(rows)


def test_whitening_tables_are_notebook_07s():
    """(Not in the paper; issue 62) every row of MEASUREMENTS' two whitening tables (each method
    without and with it; the recipe against two-sided + query batch and contrast) equals notebook
    07's committed tables to the 3 decimals it shows."""
    section = MEASUREMENTS[
        MEASUREMENTS.index("## Whitening on the reference database") : MEASUREMENTS.index(
            "**Cost** (`benchmarks/bench_whiten.py"
        )
    ]
    labels = {
        "synthetic": "synthetic",
        "gardens_point_mini": "gardens_point_mini",
        "Nordland 72": "nordland_step50",
        "Nordland 716": "nordland_step5",
        "Nordland 3,576": "nordland_step1",
    }
    recipe = (
        "{} (whitened: 256, weighting: contrast, normalised: query_batch, needs the query batch)"
    )
    best = "{} (weighting: two_sided, normalised: query_batch, needs the query batch)"

    def num(text: str) -> float:
        return float(text.split()[0])

    checked = 0
    for line in section.splitlines():
        c = [x.strip() for x in line.strip().strip("|").split("|")]
        if c[0] not in labels or len(c) not in (6, 9):
            continue
        label, m = labels[c[0]], c[1]
        steps = _csv(f"{label}/places_alike_steps.csv").set_index("method")
        if len(c) == 6:  # without and with whitening
            row, plain = steps.loc[f"{m} (whitened: 256)"], steps.loc[m]
            got = [plain["AUC"], row["AUC"], row["dAUC"], plain["R@1"], row["R@1"], row["dR@1"]]
            want = [*c[2].split(" -> "), c[3], *c[4].split(" -> "), c[5]]
        else:  # the recipe against today's best
            vb = _csv(f"{label}/places_alike_vs_best.csv").set_index("method")
            vc = _csv(f"{label}/places_alike_vs_contrast.csv").set_index("method")
            r, b = recipe.format(m), best.format(m)
            got = [vb.loc[r, "AUC"], vb.loc[r, "R@1"], vb.loc[b, "AUC"], vb.loc[b, "R@1"]]
            got += [vb.loc[r, "dAUC"], vb.loc[r, "dR@1"], vc.loc[r, "dAUC"], vc.loc[r, "dR@1"]]
            want = [*c[2].split(" / "), *c[3].split(" / "), c[4], c[5], c[7], c[8]]
        assert [f"{g:.3f}" for g in got] == [f"{num(w):.3f}" for w in want], line
        checked += 1
    assert checked == 28


def test_whitening_cost_tables_are_the_benchmark_tables():
    rows = []
    for places in (716, 3576):
        for _, r in _csv(f"benchmarks/whiten_cost_{places}.csv").iterrows():
            mb = "" if pd.isna(r["peak MB"]) else f"{r['peak MB']:.0f} MB"
            cells = [f"{places:,}", r["step"], f"{r['seconds']:.1f} s", f"{r['ratio']:.2f}x", mb]
            rows.append("| " + " | ".join(cells) + " |")
    assert len(rows) == 14 and all(row in MEASUREMENTS for row in rows), _paste(rows)


def test_two_sided_cost_tables_are_the_benchmark_tables():
    rows = []
    for places in (716, 3576):
        for _, r in _csv(f"benchmarks/two_sided_cost_{places}.csv").iterrows():
            cells = [f"{places:,}", r["path"], r["step"], f"{r['seconds']:.1f} s"]
            rows.append("| " + " | ".join(cells) + f" | {r['ratio']:.2f}x |")
    assert all(row in MEASUREMENTS for row in rows), _paste(rows)


def test_the_readme_runs_each_study_notebook_headless_on_the_small_set():
    """Issue 61: one headless command per study notebook on the small set, plain nbconvert."""
    from vpr_study.figures import NOTEBOOKS

    assert "VPR_QUICK=1 .venv/bin/jupyter nbconvert --to notebook --execute" in README
    for stem in NOTEBOOKS:
        assert f"nb {stem}" in README, stem
    block = README[README.index("## Two commands") : README.index("## Five minutes")]
    assert "make lab" not in block.split("```")[1]  # two commands; make lab its own step
