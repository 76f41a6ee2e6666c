"""The paper's claims against the study's numbers: one row per claim, one column per dataset.

Every claim is a signed difference between two runs of one figure (``dAUC`` of the ratio
protocol, from the paired bootstrap that :meth:`~vpr_core.study.Study.compare` writes to
``results/<label>/<notebook>_<figure>_paired.csv``), or, for the first observation, the
difference of correct-match rates between large (Table-1 Scales 5-7) and small (Scales 1-3)
landmarks, bootstrapped over query images from the labelled matches of notebook 02.

Verdicts (95% intervals, 1,000 resamples, seed 0):

* claim "a > b": **holds** when the interval of ``a - b`` lies above 0, **does not hold** when
  it lies below 0, **inconclusive** when it contains 0;
* claim "a ~ b" (on par): **holds** when the interval contains 0 (no difference found; this
  is absence of evidence, said so in the text), **does not hold** otherwise;
* no claim (``"?"``, rows the paper does not make): **finding: higher / lower** or
  **inconclusive**;
* **not testable (identical results)**: both runs gave the same ranking for every query (e.g.
  on 64x32 Nordland frames Edge Boxes yields ~13 proposals, all at Scale >= 6, so the
  selection schemes keep the same boxes as classical);
* **not run**: the dataset has no such result (e.g. notebook 02 runs on ``synthetic`` only).

:func:`findings_table` reads the CSVs; ``vpr-study findings`` prints it as Markdown and the
runner writes ``results/findings.md`` after ``make study``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .. import paths

__all__ = ["CLAIMS", "Claim", "cmr_difference", "findings_markdown", "findings_table"]

_NB2, _NB3, _NB4 = "02_scale_statistics", "03_landmark_selection", "04_overlap"
_NB5, _NB6 = "05_dense_sampling_parameters", "06_comparison"


@dataclass(frozen=True)
class Claim:
    """One claim of the paper as a signed difference ``method - baseline`` of ``metric``.

    Attributes:
        text: the claim, as the paper makes it.
        notebook, figure: where the two runs are compared.
        method, baseline: run labels (a dense ``Set N`` is matched by its ``"Set N:"`` prefix).
        expect: ``">"`` (method better), ``"<"`` (method worse), ``"~"`` (on par) or ``"?"``
            (no claim: the verdict only says whether there is a finding and its sign).
        metric: ``"dAUC"`` or ``"dR@1"`` (columns of the paired CSV).
    """

    text: str
    notebook: str
    figure: str
    method: str
    baseline: str
    expect: str
    metric: str = "dAUC"


#: The paper's claims, in paper order (observation 1 is handled by :func:`cmr_difference`).
CLAIMS: tuple[Claim, ...] = (
    Claim("Fig. 5: selection Scheme 1 beats classical", _NB3, "fig05_selection",
          "selection_scheme1", "classical", ">"),
    Claim("Fig. 5: selection Scheme 2 lags behind classical", _NB3, "fig05_selection",
          "selection_scheme2", "classical", "<"),
    Claim("Fig. 7a: NMS (Alg. 3) at IoU 0.4 falls below classical", _NB4, "fig07a_overlap_nms",
          "overlap_scheme1 (IoU 0.4)", "classical", "<"),
    Claim("Fig. 7a: NMS at IoU 0.7 is on par with classical", _NB4, "fig07a_overlap_nms",
          "overlap_scheme1 (IoU 0.7)", "classical", "~"),
    Claim("Fig. 7b: soft-NMS (Alg. 4) at IoU 0.3 falls below classical", _NB4,
          "fig07b_overlap_soft_nms", "overlap_scheme2 (IoU 0.3)", "classical", "<"),
    Claim("Fig. 7b: soft-NMS at IoU 0.7 is on par with classical", _NB4,
          "fig07b_overlap_soft_nms", "overlap_scheme2 (IoU 0.7)", "classical", "~"),
    Claim("Table 2: 4 scales x 25 (Set 5) beat one scale x 100 (Set 1)", _NB5,
          "fig10_scale_levels", "Set 5", "Set 1", ">"),
    Claim("Table 2: one large scale (Set 2, 0.49) is worse than Set 1", _NB5,
          "fig10_scale_levels", "Set 2", "Set 1", "<"),
    Claim("Table 2: six scales x 16 (Set 6) are worse even than one scale (Set 1)", _NB5,
          "fig10_scale_levels", "Set 6", "Set 1", "<"),
    Claim("Table 3: the most uneven split (Set 4) is worse than uniform 25 each (Set 1)", _NB5,
          "fig11_landmarks_per_scale", "Set 4", "Set 1", "<"),
    Claim("Table 4: similar scales (Set 2) are on par with Set 1", _NB5,
          "fig12_normalized_scales", "Set 2", "Set 1", "~"),
    Claim("Table 4: small scales (Set 3) are worse than Set 1", _NB5,
          "fig12_normalized_scales", "Set 3", "Set 1", "<"),
    Claim("Table 4: oversize scales (Set 4) are worse than Set 1", _NB5,
          "fig12_normalized_scales", "Set 4", "Set 1", "<"),
    Claim("Fig. 13: classical is clearly worse than dense", _NB6, "fig13_comparison",
          "classical", "dense", "<"),
    Claim("Fig. 13: Scheme 1 is slightly worse than dense", _NB6, "fig13_comparison",
          "selection_scheme1", "dense", "<"),
    Claim("(not in the paper) a global descriptor vs dense landmarks", _NB6, "fig13_comparison",
          "global", "dense", "?"),
)

#: Observation 1 (Fig. 4): large landmarks (Scales 5-7) match correctly more often than small
#: ones (Scales 1-3).
OBSERVATION_1 = ("Obs. 1 / Fig. 4: large landmarks (Scales 5-7) match correctly more often "
                 "than small ones (Scales 1-3), CMR difference")


def _verdict(expect: str, lo: float, hi: float, delta: float | None = None) -> str:
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return "not run"
    if delta == 0 and lo == 0 and hi == 0:
        return "not testable (identical results)"
    if expect == "?":
        return "finding: higher" if lo > 0 else ("finding: lower" if hi < 0 else "inconclusive")
    if expect == "~":
        return "holds (no difference found)" if lo <= 0 <= hi else "does not hold"
    above, below = lo > 0, hi < 0
    if not (above or below):
        return "inconclusive"
    return "holds" if (above if expect == ">" else below) else "does not hold"


def _find(labels: Sequence[str], wanted: str) -> str | None:
    if wanted in labels:
        return wanted
    hits = [lab for lab in labels if lab.startswith(wanted + ":")]
    return hits[0] if len(hits) == 1 else None


def _claim_cell(folder: Path, claim: Claim) -> tuple[str, str]:
    csv = folder / f"{claim.notebook}_{claim.figure}_paired.csv"
    if not csv.is_file():
        return "-", "not run"
    df = pd.read_csv(csv)
    base = _find(list(df["baseline"].unique()), claim.baseline)
    row = df[df["baseline"] == base] if base else df.iloc[0:0]
    method = _find(list(row["method"]), claim.method)
    if method is None:
        return "-", "not run"
    r = row[row["method"] == method].iloc[0]
    d, lo, hi = (float(r[claim.metric]), float(r[f"{claim.metric} lo"]),
                 float(r[f"{claim.metric} hi"]))
    p = float(r[f"{claim.metric} p"])
    return f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}] p={p:.3f}", _verdict(claim.expect, lo, hi, d)


def cmr_difference(matches: pd.DataFrame, n: int = 1000, seed: int = 0
                   ) -> tuple[float, float, float]:
    """CMR(Scales 5-7) - CMR(Scales 1-3) of labelled ground-truth matches, bootstrapped over
    query images (all matches of a drawn query count).

    Args:
        matches: notebook 02's ``*_matches.csv`` (columns ``query``, ``pair``, ``scale``,
            ``correct``); only ``pair == "gt"`` rows are used.
        n: resamples. seed: their seed.

    Returns:
        ``(difference, low, high)``: 95% percentile interval.

    Raises:
        ValueError: no labelled ground-truth match at Scales 1-3 or 5-7.
    """
    m = matches[(matches["pair"] == "gt") & matches["correct"].notna()]
    groups = {"small": m["scale"].between(1, 3), "large": m["scale"].between(5, 7)}
    if not all(g.any() for g in groups.values()):
        raise ValueError("cmr_difference needs labelled ground-truth matches at Scales 1-3 "
                         "and 5-7")
    queries = np.unique(m["query"].to_numpy())
    qi = np.searchsorted(queries, m["query"].to_numpy())
    sums = {}
    for name, mask in groups.items():
        mask = mask.to_numpy()
        sums[name] = (np.bincount(qi[mask], weights=m["correct"].to_numpy()[mask],
                                  minlength=len(queries)),
                      np.bincount(qi[mask], minlength=len(queries)).astype(float))

    def diff(w: np.ndarray) -> np.ndarray:
        rates = {k: (w @ c) / np.maximum(w @ t, 1e-12) for k, (c, t) in sums.items()}
        return rates["large"] - rates["small"]

    point = float(diff(np.ones((1, len(queries))))[0])
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, len(queries), size=(n, len(queries)))
    w = np.zeros((n, len(queries)))
    np.add.at(w, (np.repeat(np.arange(n), len(queries)), draws.ravel()), 1.0)
    lo, hi = np.percentile(diff(w), [2.5, 97.5])
    return point, float(lo), float(hi)


def _observation_1(folder: Path) -> tuple[str, str]:
    csvs = sorted(folder.glob(f"{_NB2}_*_matches.csv"))
    if not csvs:
        return "-", "not run"
    d, lo, hi = cmr_difference(pd.read_csv(csvs[0]))
    return f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}]", _verdict(">", lo, hi)


def findings_table(labels: Sequence[str]) -> pd.DataFrame:
    """One row per claim, two columns per dataset label (``<label>`` value and verdict).

    Args:
        labels: result folders under ``<output root>/results/`` (e.g. ``["synthetic",
            "gardens_point_mini", "nordland_step50"]``).

    Returns:
        DataFrame indexed by claim text.
    """
    rows = []
    for claim in (None, *CLAIMS):
        row = {"claim": OBSERVATION_1 if claim is None else claim.text}
        for label in labels:
            folder = paths.output_root() / "results" / label
            value, verdict = _observation_1(folder) if claim is None else _claim_cell(folder,
                                                                                      claim)
            row[label], row[f"{label} verdict"] = value, verdict
        rows.append(row)
    return pd.DataFrame(rows).set_index("claim")


def findings_markdown(labels: Sequence[str]) -> str:
    """:func:`findings_table` as a Markdown table (value and verdict in one cell)."""
    table = findings_table(labels)
    head = "| paper's claim | " + " | ".join(labels) + " |"
    sep = "|---" * (len(labels) + 1) + "|"
    lines = [head, sep]
    for claim, r in table.iterrows():
        cells = [f"{r[lab]} **{r[lab + ' verdict']}**" if r[lab] != "-" else
                 f"**{r[lab + ' verdict']}**" for lab in labels]
        lines.append(f"| {claim} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
