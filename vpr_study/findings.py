"""The paper's claims against the study's numbers: one row per claim, one column per dataset,
each claim a signed difference between two runs named by configuration (``run_key``), with
its verdict (docs/DEFINITIONS.md, "Verdicts"); ``vpr-study findings`` prints the table."""

from __future__ import annotations

import dataclasses
import io
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from vpr_core import (
    ON_PAR_MARGIN,
    VERDICT_WORDS,
    claim_verdict,
    cmr_difference,
    get_method,
    paper,
    paths,
    step_between,
)

from . import outputs
from .tables import COMPARISON, MATCHES, check_table, table_exists

__all__ = [
    "CELL_WORDS",
    "CLAIMS",
    "STEPS",
    "STEPS_TABLE",
    "STEP_CLAIMS",
    "VS_BEST",
    "LEGEND",
    "MATCHES_TABLE",
    "OBSERVATION_1",
    "Claim",
    "findings_document",
    "findings_markdown",
    "findings_table",
    "markdown_cell",
    "read_table",
    "result_labels",
    "step_labels",
]


@dataclass(frozen=True)
class Claim:
    """One claim of the paper as a signed difference ``method - baseline`` of ``metric``.

    Attributes:
        text: the claim, as the paper makes it.
        figure: the figure (and saved table ``results/<label>/<figure>.csv``) comparing the runs.
        method, baseline: ``(preset name, {options})`` of the two runs.
        expect: ``">"`` (method better), ``"<"`` (method worse), ``"~"`` (on par, judged with
            :data:`ON_PAR_MARGIN`) or ``"?"`` (no claim: the verdict is higher, lower or
            inconclusive).
        metric: ``"dAUC"`` or ``"dR@1"`` (columns of the comparison table).
    """

    text: str
    figure: str
    method: tuple[str, dict] = field(hash=False)
    baseline: tuple[str, dict] = field(hash=False)
    expect: str
    metric: str = "dAUC"

    @property
    def keys(self) -> tuple[str, str]:
        """The run keys of method and baseline (the ``run`` column of the tables)."""
        (m_name, m_opts), (b_name, b_opts) = self.method, self.baseline
        return get_method(m_name, **m_opts).key, get_method(b_name, **b_opts).key


def _dense(table: dict, name: str) -> tuple[str, dict]:
    scales, per_scale = table[name]
    return "dense", {"scales": scales, "per_scale": per_scale}


_C: tuple[str, dict] = ("classical", {})
_D: tuple[str, dict] = ("dense", {})
_S1: tuple[str, dict] = ("selection_scheme1", {})
_F5, _F7A, _F7B = "fig05_selection", "fig07a_overlap_nms", "fig07b_overlap_soft_nms"
_T2, _T3, _T4 = "fig10_scale_levels", "fig11_landmarks_per_scale", "fig12_normalized_scales"
_O1, _O2 = "overlap_scheme1", "overlap_scheme2"
_F13 = "fig13_comparison"

#: (Not in the paper.) Notebook 07's table of each method without and with each step.
STEPS_TABLE = "places_alike_steps"

#: (Not in the paper.) The steps of issues 55 and 62 judged in notebook 07's :data:`STEPS_TABLE`.
STEPS: dict[str, dict] = {
    "two-sided contrast": {"weighting": "two_sided"},
    "query-batch normalisation (needs the query batch)": {"normalise": "query_batch"},
    "database normalisation": {"normalise": "database"},
    "two-sided + query-batch (needs the query batch)": {
        "weighting": "two_sided",
        "normalise": "query_batch",
    },
    "whitening": {"whiten": 256},
    "whitening + contrast + query-batch, the recipe (needs the query batch)": {
        "whiten": 256,
        "weighting": "contrast",
        "normalise": "query_batch",
    },
}

#: (Not in the paper; issue 62.) Today's best steps the whitening recipe is judged against: the
#: notebook 07 table that pairs them, and the step's options.
VS_BEST: dict[str, tuple[str, dict]] = {
    "two-sided + query-batch": (
        "places_alike_vs_best",
        {"weighting": "two_sided", "normalise": "query_batch"},
    ),
    "contrast": ("places_alike_vs_contrast", {"weighting": "contrast"}),
}

#: The paper's claims, in paper order (observation 1 is handled by :func:`cmr_difference`).
# fmt: off
CLAIMS: tuple[Claim, ...] = (
    Claim("Fig. 5: selection Scheme 1 beats classical", _F5, _S1, _C, ">"),
    Claim("Fig. 5: selection Scheme 2 lags behind classical",
          _F5, ("selection_scheme2", {}), _C, "<"),
    Claim("Fig. 7a: NMS (Alg. 3) at IoU 0.4 falls below classical",
          _F7A, (_O1, {"iou_threshold": 0.4}), _C, "<"),
    Claim("Fig. 7a: NMS at IoU 0.7 is on par with classical",
          _F7A, (_O1, {"iou_threshold": 0.7}), _C, "~"),
    Claim("Fig. 7b: soft-NMS (Alg. 4) at IoU 0.3 falls below classical",
          _F7B, (_O2, {"soft_nms_iou": 0.3}), _C, "<"),
    Claim("Fig. 7b: soft-NMS at IoU 0.7 is on par with classical",
          _F7B, (_O2, {"soft_nms_iou": 0.7}), _C, "~"),
    Claim("Table 2: 4 scales x 25 (Set 5) beat one scale x 100 (Set 1)",
          _T2, _dense(paper.TABLE2, "Set 5"), _dense(paper.TABLE2, "Set 1"), ">"),
    Claim("Table 2: one large scale (Set 2, 0.49) is worse than Set 1",
          _T2, _dense(paper.TABLE2, "Set 2"), _dense(paper.TABLE2, "Set 1"), "<"),
    Claim("Table 2: six scales x 16 (Set 6) are worse even than one scale (Set 1)",
          _T2, _dense(paper.TABLE2, "Set 6"), _dense(paper.TABLE2, "Set 1"), "<"),
    Claim("Table 3: the most uneven split (Set 4) is worse than uniform 25 each (Set 1)",
          _T3, _dense(paper.TABLE3, "Set 4"), _dense(paper.TABLE3, "Set 1"), "<"),
    Claim("Table 4: similar scales (Set 2) are on par with Set 1",
          _T4, _dense(paper.TABLE4, "Set 2"), _dense(paper.TABLE4, "Set 1"), "~"),
    Claim("Table 4: small scales (Set 3) are worse than Set 1",
          _T4, _dense(paper.TABLE4, "Set 3"), _dense(paper.TABLE4, "Set 1"), "<"),
    Claim("Table 4: oversize scales (Set 4) are worse than Set 1",
          _T4, _dense(paper.TABLE4, "Set 4"), _dense(paper.TABLE4, "Set 1"), "<"),
    Claim("Fig. 13: classical is clearly worse than dense", _F13, _C, _D, "<"),
    Claim("Fig. 13: Scheme 1 is slightly worse than dense", _F13, _S1, _D, "<"),
    Claim("(not in the paper) a global descriptor vs dense landmarks",
          _F13, ("global", {}), _D, "?"),
    Claim("(not in the paper) geometry-aware score: dense with vs without",
          "geometry_dense", ("dense", {"spatial": "consistency"}), _D, "?"),
    Claim("(not in the paper) geometry-aware score: classical with vs without",
          "geometry_classical", ("classical", {"spatial": "consistency"}), _C, "?"),
    *(
        Claim(f"(not in the paper) weighting {w}: {m} with vs without", f"weighting_{m}",
              (m, {"weighting": w}), base, "?")
        for m, base in (("dense", _D), ("classical", _C)) for w in ("contrast", "idf")
    ),
)

#: (Not in the paper; issues 55 and 62.) Each method without and with each step of notebook 07
#: (settings fixed in DEFINITIONS.md), then the whitening recipe against :data:`VS_BEST`, AUC and
#: R@1: a table of its own in ``results/findings.md``, beside the paper's claims (which the README
#: shows).
STEP_CLAIMS: tuple[Claim, ...] = tuple(
    Claim(
        f"{text}: {m} with vs without ({metric[1:]})",
        STEPS_TABLE,
        (m, opts),
        (m, {}),
        "?",
        metric,
    )
    for m in ("dense", "classical", "selection_scheme1")
    for text, opts in STEPS.items()
    for metric in ("dAUC", "dR@1")
) + tuple(
    Claim(
        f"whitening recipe (needs the query batch): {m} against {best} ({metric[1:]})",
        figure,
        (m, STEPS["whitening + contrast + query-batch, the recipe (needs the query batch)"]),
        (m, opts),
        "?",
        metric,
    )
    for m in ("dense", "classical", "selection_scheme1")
    for best, (figure, opts) in VS_BEST.items()
    for metric in ("dAUC", "dR@1")
)
# fmt: on

#: Observation 1 (Fig. 4): large landmarks (Scales 5-7) match correctly more often than small
#: ones (Scales 1-3).
OBSERVATION_1 = (
    "Obs. 1 / Fig. 4: large landmarks (Scales 5-7) match correctly more often "
    "than small ones (Scales 1-3), CMR difference"
)

#: The file of labelled matches that observation 1 reads (``results/<label>/<name>.csv``).
MATCHES_TABLE = "fig04_matches"


#: The leading words a findings cell's verdict can have (bold in the Markdown table).
CELL_WORDS = (*VERDICT_WORDS, "not run")


def _claim_cell(folder: Path, claim: Claim) -> tuple[str, str]:
    csv = folder / f"{claim.figure}.csv"
    if not table_exists(csv):  # a FIFO, folder or dangling link there: refused by name
        return "-", "not run"
    df = read_table(csv)
    if "run" not in df.columns or "baseline" not in df.columns:
        raise ValueError(
            f"{csv} is not a comparison table (no 'run' / 'baseline' column); "
            "write it with save(compare(runs), figure, label)"
        )
    m = claim.metric
    missing = [c for c in (m, f"{m} lo", f"{m} hi", f"{m} p") if c not in df.columns]
    if missing:
        raise ValueError(
            f"{csv} lacks the column(s) {', '.join(missing)} of a paired comparison; write it "
            "with save(compare(runs), figure, label) from runs of one dataset"
        )
    check_table(df, COMPARISON, csv)  # every cell, not only the claim's: one schema per table
    method_key, base_key = claim.keys
    base = df[df["run"] == base_key]
    rows = df[(df["run"] == method_key) & df["baseline"].isin(base["method"])]
    if base.empty or rows.empty:
        return "-", "not run"
    d, lo, hi, p, needs, queries = _claim_numbers(csv, df, base, rows, m)
    if claim.figure == STEPS_TABLE:  # credited to the step only if the rows differ by it alone
        step_between(_row_parts(base, claim.baseline), _row_parts(rows, claim.method), str(csv))
    verdict = claim_verdict(claim.expect, lo, hi, d, needs, queries)
    return f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}] p={p:.3f}", verdict


#: The columns of a ``compare`` table that say what a row's numbers come from besides its method.
_CONTEXT = ("dataset", "root", "tolerance", "protocol", "backbone", "pooling", "shortlist")


def _row_parts(rows: pd.DataFrame, method: tuple[str, dict]) -> dict:
    """What the first of ``rows`` (a ``compare`` table's) comes from, as
    :func:`vpr_core.step_between` compares it: the claim's method and the row's context."""
    row, conf = rows.iloc[0], get_method(method[0], **method[1])
    parts = {"label": str(row["method"]), "method": conf.name, "landmarks": conf.landmarks}
    parts |= dataclasses.asdict(conf.matching)
    return parts | {c: None if pd.isna(row[c]) else row[c] for c in _CONTEXT if c in row.index}


def _claim_numbers(
    csv: Path, df: pd.DataFrame, base: pd.DataFrame, rows: pd.DataFrame, m: str
) -> tuple[float, ...]:
    """``(d, lo, hi, p, needs, queries)`` of a claim's row, refused naming the file and line (the
    header is line 1) when a run has two rows, a cell is not a number, the interval is NaN or
    reversed, or the difference lies outside it."""
    cols = [m, f"{m} lo", f"{m} hi", f"{m} p", f"{m} needs", "queries"]
    twice = base if len(base) > 1 else rows
    line = int(twice.index[0]) + 2
    values = [np.nan] * len(cols)
    why = f"holds a second row of run {twice['run'].iloc[0]!r}" if len(twice) > 1 else ""
    for k, col in enumerate(cols):
        cell = twice.iloc[0].get(col, np.nan) if not why and col in df.columns else np.nan
        value = pd.to_numeric(pd.Series([cell]), errors="coerce").iloc[0]
        if not why and pd.isna(value) and not pd.isna(cell):
            why = f"column {col!r} holds {str(cell)[:40]!r}, not a number"
        values[k] = float(value)
    d, lo, hi = values[:3]
    if not why and not np.isfinite([d, lo, hi]).all():
        why = f"{m} {d} [{lo}, {hi}] is not finite (NaN interval: run with n_bootstrap >= 1)"
    elif not why and lo > hi:
        why = f"the interval of {m} is reversed ({lo} > {hi})"
    elif not why and not lo <= d <= hi:
        why = f"{m} {d} lies outside its own interval [{lo}, {hi}]"
    if why:
        raise ValueError(
            f"{csv} line {line} {why}; this is not a table compare() wrote: rerun the notebook "
            "or command that writes it."
        )
    return tuple(values)


def read_table(csv: Path) -> pd.DataFrame:
    """A saved results table, refused naming the file when it is no regular file (a FIFO, a
    folder, a device: never read), empty, not a CSV table or truncated (its last line cut off)."""
    if not table_exists(csv):
        raise FileNotFoundError(f"{csv} does not exist; run the notebook or command that writes it")
    raw = csv.read_bytes()
    if not raw.strip():
        raise ValueError(f"{csv} is empty; rerun the notebook or command that writes it")
    try:
        df = pd.read_csv(io.BytesIO(raw))
    except (ValueError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        why = str(exc).strip().splitlines()[0][:80] if str(exc).strip() else type(exc).__name__
        raise ValueError(
            f"{csv} is not a readable CSV table ({why}); rerun the notebook or command that "
            "writes it"
        ) from None
    if not raw.endswith(b"\n") or df.empty:
        raise ValueError(
            f"{csv} is truncated (its last line is cut off, or it holds no row); rerun the "
            "notebook or command that writes it"
        )
    return df


def _observation_1(folder: Path) -> tuple[str, str]:
    csv = folder / f"{MATCHES_TABLE}.csv"
    if not table_exists(csv):
        return "-", "not run"
    table = read_table(csv)
    missing = sorted({"pair", "correct", "scale", "query"} - set(table.columns))
    why = f"lacks the column(s) {', '.join(missing)}" if missing else ""
    for col in () if missing else ("scale", "query", "correct"):
        text = pd.to_numeric(table[col].replace({"True": 1, "False": 0}), errors="coerce")
        bad = np.flatnonzero(text.isna() & table[col].notna())
        why = why or (
            f"line {bad[0] + 2} holds {str(table[col][bad[0]])[:40]!r} in column "
            f"{col!r}, not a number"
            if bad.size
            else ""
        )
    if why:
        raise ValueError(
            f"{csv} {why}: it is not a table of labelled matches; write it with "
            "save(stats.matches_frame(), ...) as notebook 02 does."
        )
    check_table(table, MATCHES, csv)
    d, lo, hi = cmr_difference(table)
    return f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}]", claim_verdict(">", lo, hi)


def result_labels(first: Sequence[str] = (), out: str | Path | None = None) -> list[str]:
    """The result folders that hold comparison tables (``results/<label>/fig*.csv``), not quick
    runs: ``first`` (those present, in that order), then the others sorted."""
    return _labels_holding("fig*.csv", first, out)


def _labels_holding(pattern: str, first: Sequence[str], out: str | Path | None) -> list[str]:
    """The folders under ``<output root>/results/`` (quick runs left out) holding a file that
    matches ``pattern``: those of ``first`` in that order, then the others sorted."""
    root = (paths.output_root() if out is None else Path(out)) / "results"
    found = (
        sorted(
            p.name
            for p in root.iterdir()
            if p.is_dir() and not p.name.endswith("_quick") and any(p.glob(pattern))
        )
        if root.is_dir()
        else []
    )
    head = [lab for lab in first if lab in found]
    return head + [lab for lab in found if lab not in head]


def findings_table(
    labels: Sequence[str], out: str | Path | None = None, claims: tuple[Claim, ...] = CLAIMS
) -> pd.DataFrame:
    """One row per claim (the index; observation 1 first with the paper's :data:`CLAIMS`), two
    columns per result folder label under ``<output root>/results/`` (value and verdict)."""
    root = paths.output_root() if out is None else Path(out)
    for label in labels:
        outputs.check_label(label)  # a folder name on disk is a label too: no markup, no column
        if not (root / "results" / label).is_dir():
            found = result_labels(out=root)
            raise ValueError(
                f"no results for label {label!r} under {root / 'results'}; labels with "
                f"results: {', '.join(found) or 'none'}"
            )
    rows = []
    for claim in (None, *claims) if claims is CLAIMS else claims:
        row = {"claim": OBSERVATION_1 if claim is None else claim.text}
        for label in labels:
            folder = root / "results" / label
            value, verdict = _observation_1(folder) if claim is None else _claim_cell(folder, claim)
            row[label], row[f"{label} verdict"] = value, verdict
        rows.append(row)
    return pd.DataFrame(rows).set_index("claim")


#: The line above the Markdown findings table: how to read a cell.
LEGEND = (
    "Each cell: the difference `method - baseline` (AUC; Obs. 1: CMR) [95% interval] p, then "
    "the verdict, by the first of these rules that applies: **not testable** when the two runs "
    "give identical results; for a claim of parity, **on par** when the whole interval lies "
    f"inside ±{ON_PAR_MARGIN} AUC; **higher** or **lower** when the interval lies above or below "
    '0; else **inconclusive** (with the queries a verdict would need). "(as the paper says)" '
    'or "(paper: lower)" sets the verdict beside the paper\'s claim (docs/DEFINITIONS.md, '
    '"Verdicts").'
)


def step_labels(labels: Sequence[str], out: str | Path | None = None) -> list[str]:
    """The result folders holding notebook 07's :data:`STEPS_TABLE`: those of ``labels`` in
    that order, then the others under ``results/`` sorted (quick runs left out)."""
    return _labels_holding(f"{STEPS_TABLE}.csv", labels, out)


def findings_document(labels: Sequence[str], out: str | Path | None = None) -> str:
    """``results/findings.md``: the paper's claims (:func:`findings_markdown` of ``labels``, the
    README's table), then the steps of notebook 07 (:data:`STEP_CLAIMS`, not in the paper) for
    every folder that holds its table (:func:`step_labels`)."""
    found = step_labels(labels, out=out)
    steps = (
        findings_markdown(found, out=out, claims=STEP_CLAIMS).split("\n", 2)[2]
        if found
        else "No result folder holds notebook 07's table yet: run notebook 07."
    )
    return (
        findings_markdown(labels, out=out)
        + "\n\n## Not in the paper: two-sided contrast, normalisation and whitening (notebook "
        + "07)\n\n"
        + "Each method with minus without each step, AUC and R@1, then the whitening recipe "
        + "against today's best steps; `query_batch` needs the batch of queries "
        + "(docs/DEFINITIONS.md). Cells read as above; a column for every result folder that "
        + "holds notebook 07's table.\n\n"
        + steps
    )


def markdown_cell(text: object) -> str:
    """``text`` as one Markdown table cell: HTML (``&``, ``<``, ``>``), ``|``, ``\\`` and the
    link / image syntax ``](`` ``][`` escaped, each line break (CR, LF, CRLF) a ``<br>``: a label
    or claim cannot add a column, inject a row, a link or an image, or carry markup."""
    out = str(text).replace("\\", "\\\\").replace("&", "&amp;")
    out = out.replace("<", "&lt;").replace(">", "&gt;").replace("|", "\\|")
    out = out.replace("](", "]\\(").replace("][", "]\\[")
    return "<br>".join(out.replace("\r\n", "\n").replace("\r", "\n").split("\n"))


def _bold_verdict(verdict: str) -> str:
    """``**higher** (paper: lower)``: the verdict's word bold, its note after it."""
    word = next((w for w in CELL_WORDS if verdict.startswith(w)), verdict)
    rest = verdict[len(word) :]
    return f"**{markdown_cell(word)}**{markdown_cell(rest)}"


def findings_markdown(
    labels: Sequence[str], out: str | Path | None = None, claims: tuple[Claim, ...] = CLAIMS
) -> str:
    """:func:`findings_table` as Markdown: :data:`LEGEND`, then the table (value and verdict in
    one cell; every header and cell escaped by :func:`markdown_cell`)."""
    table = findings_table(labels, out=out, claims=claims)
    first = "paper's claim" if claims is CLAIMS else "(not in the paper) step"
    head = f"| {first} | " + " | ".join(markdown_cell(lab) for lab in labels) + " |"
    sep = "|---" * (len(labels) + 1) + "|"
    lines = [LEGEND, "", head, sep]
    for claim, r in table.iterrows():
        cells = [
            (f"{markdown_cell(r[lab])} " if r[lab] != "-" else "")
            + _bold_verdict(r[lab + " verdict"])
            for lab in labels
        ]
        lines.append(f"| {markdown_cell(claim)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
