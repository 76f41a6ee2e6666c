"""The one comparison table (:func:`compare`): metrics with 95% intervals and chance levels,
paired differences with verdicts; :func:`compact` is how a person reads it (notebooks, terminal).
Definitions: docs/DEFINITIONS.md ("Uncertainty", "Chance level")."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from importlib.metadata import PackageNotFoundError, version
from typing import Any

import numpy as np
import pandas as pd

from ..checks import check_bootstrap_memory, check_int, check_results, is_result
from ..matching.normalise import needs_query_batch
from .bootstrap import (
    IDENTICAL,
    N_BOOTSTRAP,
    bootstrap_columns,
    difference_verdict,
    format_interval,
    paired_bootstrap,
)
from .chance import chance, saturation_notice

__all__ = [
    "DIFFERENCES",
    "IDENTICAL",
    "METRICS",
    "ComparisonTable",
    "CompactView",
    "check_same_dataset",
    "compact",
    "compact_text",
    "compare",
    "compare_pairs",
    "identical_to",
    "normalise_of",
]

#: The metric columns of :func:`compare` (column name -> metric key).
METRICS = {"AUC": "auc", "R@100P": "r@100p", "R@1": "r@1", "R@5": "r@5"}

#: The paired differences of :func:`compare` (column prefix -> metric key).
DIFFERENCES = {"dAUC": "auc", "dR@100P": "r@100p", "dR@1": "r@1"}

#: Terminal width of :func:`compact_text` when none is given (``print(table)``, notebooks).
TERMINAL_WIDTH = 100

#: The row label of the chance level in :func:`compact`.
CHANCE_ROW = "chance (random)"


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=True))


def _same_result(a: Any, b: Any) -> bool:
    """Same similarity matrix, or the same PR curve, metrics and per-query ranking decision
    (then nothing a table or figure shows can tell the two apart)."""
    if _same(np.asarray(a.similarity), np.asarray(b.similarity)):
        return True
    if getattr(a, "metrics", None) != getattr(b, "metrics", None):
        return False
    ca, cb = a.curve(), b.curve()
    return _same(np.asarray(ca.recall), np.asarray(cb.recall)) and _same(
        np.asarray(ca.precision), np.asarray(cb.precision)
    )


def identical_to(results: Sequence[Any]) -> list[str | None]:
    """Per result, the label of the first earlier result with the same similarity matrix, or
    the same metrics and PR curve (then the figure draws one curve and the table says so),
    else None."""
    out: list[str | None] = []
    for i, r in enumerate(results):
        out.append(next((p.label for p in results[:i] if _same_result(p, r)), None))
    return out


def _version() -> str:
    try:
        return version("vpr-landmarks")
    except PackageNotFoundError:  # pragma: no cover - running from a bare source tree
        return "unknown"


def _context(r: Any) -> dict:
    enc = getattr(r, "encoder", {}) or {}
    return {
        "dataset": r.dataset,
        "root": getattr(r, "root", None),
        "tolerance": getattr(r, "tolerance", None),
        "protocol": getattr(r, "protocol", "ratio"),
        "backbone": enc.get("backbone"),
        "pooling": enc.get("pooling"),
        "version": _version(),
    }


def check_same_dataset(results: Sequence[Any], base: Any, caller: str) -> np.ndarray:
    """The baseline's ground truth; refuses results (checked by :func:`check_results`) of
    another dataset (their fingerprints where both are recorded, and the ground truth), naming
    both, and both tolerances where they differ (one dataset loaded at two tolerances: its
    fingerprints differ too). ``caller``: the function the message names."""
    fp = getattr(base, "dataset_fingerprint", None)
    gt = np.asarray(base.ground_truth, dtype=bool)
    for r in results:
        other = getattr(r, "dataset_fingerprint", None)
        tol, base_tol = getattr(r, "tolerance", None), getattr(base, "tolerance", None)
        other_data = bool(fp and other and other != fp)  # unset ("" or None): the truth decides
        other_truth = not _same(np.asarray(r.ground_truth, dtype=bool), gt)
        if tol != base_tol and (other_truth or (other_data and r.dataset == base.dataset)):
            raise ValueError(
                f"{caller}(): {r.label!r} was scored at tolerance {tol} and {base.label!r} at "
                f"tolerance {base_tol} (another ground truth); load the dataset at one "
                "tolerance and run both on it (the Eq. (1) matrices are reused from the cache)"
            )
        if other_data:
            raise ValueError(
                f"{caller}(): {r.label!r} ran on dataset {r.dataset!r} (fingerprint {other}) and "
                f"{base.label!r} on {base.dataset!r} (fingerprint {fp}): query i of one is not "
                "query i of the other; compare runs of one dataset only"
            )
        if other_truth:
            raise ValueError(
                f"{caller}(): {r.label!r} was evaluated on another ground truth than "
                f"{base.label!r}; compare runs of one dataset only"
            )
    return gt


def _with_chance(row: dict, level: dict[str, float]) -> dict:
    """``row`` with ``"<metric> chance"`` right after each metric's ``hi`` column."""
    out: dict = {}
    for col, value in row.items():
        out[col] = value
        name = col[: -len(" hi")] if col.endswith(" hi") else None
        if name in METRICS:
            out[f"{name} chance"] = level[METRICS[name]]
    return out


def normalise_of(r: Any) -> str | None:
    """The normalisation of a result's matrix (not in the paper): its ``Matching``'s, or a
    peer's recorded one; None when it has none."""
    cfg = getattr(r, "config", None)
    if isinstance(cfg, dict):
        return cfg.get("normalise")
    return getattr(getattr(cfg, "matching", None), "normalise", None)


def compare(
    results: Sequence[Any],
    baseline: str | int | None = None,
    n_bootstrap: int = N_BOOTSTRAP,
    seed: int = 0,
) -> pd.DataFrame:
    """Metrics with intervals for every result, and paired differences against a baseline.

    Args:
        results: :class:`~vpr_core.MethodResult` objects (or peers from
            :func:`~vpr_core.peer_result`) on the same dataset.
        baseline: the label (or position) of the result the others are compared with;
            default: the first.
        n_bootstrap: resamples of the paired bootstrap (0: differences without intervals,
            verdict ``not computed``).
        seed: seed of the resampling.

    Returns:
        A :class:`ComparisonTable` (a DataFrame; printed and shown by :func:`compact`) indexed by
        label: ``run``, ``AUC``/``AUC lo``/``AUC hi``/``AUC chance`` ... ``R@5 chance`` (chance:
        :func:`~vpr_core.evaluation.chance`, the same on every row), ``queries``, the cost
        columns, ``identical to``, ``baseline`` and for each of :data:`DIFFERENCES` the delta,
        ``lo``, ``hi``, ``p``, ``verdict`` (``higher`` / ``lower`` when the interval lies
        above / below 0, else ``inconclusive``; ``not computed`` without resamples) and
        ``needs`` (queries at which an inconclusive interval would exclude 0, where known),
        then the context columns and ``warnings``; where any run's matrix was normalised over
        the batch of queries (not in the paper), ``query batch``: ``needed`` or ``not needed``.
        A notice is raised when chance lies inside every run's interval
        (:func:`~vpr_core.evaluation.saturation_notice`).

    Raises:
        TypeError: ``results`` is one result (pass a list) or holds something else than
            results; ``baseline`` is neither a label nor an index (``True`` included).
        ValueError: no results, duplicate labels, an unknown baseline, ``seed`` or
            ``n_bootstrap`` not an integer >= 0, or results on different datasets (fingerprints
            or ground truths differ; both are named).
    """
    check_bootstrap_memory(check_int(n_bootstrap, "n_bootstrap (resamples; 0: no intervals)"))
    if is_result(baseline):
        raise TypeError(
            "compare(): the second argument is the baseline, and a result was given: pass the "
            "results as one list, compare([a, b, ...]), and baseline=<label> if not the first"
        )
    results = check_results(results, "compare", unique_labels=True)
    seed = check_int(seed, "compare(): seed (of the resampling)")
    labels = [r.label for r in results]
    if baseline is None:
        base = results[0]
    elif isinstance(baseline, bool) or not isinstance(baseline, (str, int, np.integer)):
        raise TypeError(
            f"compare(): baseline={baseline!r} is neither a label nor a position: pass one of the "
            f"labels ({', '.join(labels)}), an index 0 to {len(results) - 1}, or None (the first)"
        )
    elif isinstance(baseline, (int, np.integer)):
        if not -len(results) <= baseline < len(results):
            raise ValueError(
                f"compare(): baseline={baseline} is not one of the {len(results)} results: give "
                f"an index 0 to {len(results) - 1} or a label ({', '.join(labels)})"
            )
        base = results[baseline]
    elif baseline in labels:
        base = results[labels.index(baseline)]
    else:
        raise ValueError(f"baseline {baseline!r} is not one of the results: {', '.join(labels)}")
    gt = check_same_dataset(results, base, "compare")
    protocols = sorted({getattr(r, "protocol", "ratio") for r in results})
    if len(protocols) > 1:
        raise ValueError(
            f"compare(): the results use different protocols ({', '.join(protocols)});"
            " run them all with the same protocol=..."
        )
    protocol = protocols[0]
    soft = getattr(base, "soft_only", None)  # soft-only pairs: neither right nor wrong
    level = chance(gt, protocol, ks=(1, 5), soft=soft)
    tolerances = {getattr(r, "tolerance", None) for r in results}
    saturation_notice(
        gt,
        [r.intervals or {} for r in results],  # a run without intervals: not "every run"
        protocol,
        soft,
        labels=[r.label for r in results],
        tolerance=tolerances.pop() if len(tolerances) == 1 else None,
    )
    twins = identical_to(results)
    # (not in the paper) a normalisation over the query batch is not a single-query result: a
    # table holding one says so per row (a table without one is the paper's, column for column)
    batch = [needs_query_batch(normalise_of(r)) for r in results]
    rows = []
    for r, twin, needs in zip(results, twins, batch, strict=True):
        row = {**_with_chance(r.row(), level), "identical to": twin, "baseline": None}
        if any(batch):
            row["query batch"] = "needed" if needs else "not needed"
        if r is not base:
            row["baseline"] = base.label
            queries = int(gt.any(axis=1).sum())
            diff = paired_bootstrap(
                r.similarity, base.similarity, gt, n_bootstrap, seed, protocol, ks=(1,)
            )
            cols = bootstrap_columns({k: diff[k] for k in DIFFERENCES.values()}, prefix="d")
            same = _same_result(r, base)  # no query could ever tell them apart
            for name, key in DIFFERENCES.items():
                lo, hi = cols[f"{name} lo"], cols[f"{name} hi"]
                row.update(
                    {
                        name: cols[name],
                        f"{name} lo": lo,
                        f"{name} hi": hi,
                        f"{name} p": cols[f"{name} p"],
                        f"{name} verdict": IDENTICAL
                        if same
                        else difference_verdict(lo, hi, queries),
                        f"{name} needs": getattr(diff[key], "queries_needed", np.nan),
                    }
                )
        row.update(_context(r))
        row["warnings"] = " | ".join(getattr(r, "warnings", []) or [])
        rows.append(row)
    return ComparisonTable(pd.DataFrame(rows).set_index("method"))


def _difference_text(row: pd.Series, name: str) -> str:
    """``"+0.050 [-0.252, +0.420] inconclusive"`` (empty for the baseline)."""
    verdict = row.get(f"{name} verdict")
    if not isinstance(verdict, str):
        return ""
    lo, hi = row[f"{name} lo"], row[f"{name} hi"]
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return f"{row[name]:+.3f} {verdict}"
    return f"{row[name]:+.3f} [{lo:+.3f}, {hi:+.3f}] {verdict}"


def compact(table: pd.DataFrame) -> CompactView:
    """The comparison table as a person reads it: one text column per metric, one per paired
    difference with its verdict, and a last row with each metric's chance level.

    Args:
        table: :func:`compare`'s table (the full numeric one stays the CSV).

    Returns:
        A DataFrame of strings (:class:`CompactView`: in a notebook, each label on one line)
        indexed by label: ``queries``; ``AUC(<protocol>)``, ``R@100P``,
        ``R@1``, ``R@5`` as ``0.892 [0.838, 0.946]``; ``dAUC``, ``dR@100P``, ``dR@1`` (vs the
        baseline) as ``+0.050 [-0.252, +0.420] inconclusive``; ``note`` (``= <label>`` for a
        run identical to another); then the row :data:`CHANCE_ROW`.
    """
    protocol = table["protocol"].iloc[0] if "protocol" in table.columns else "ratio"
    heads = {name: f"AUC({protocol})" if name == "AUC" else name for name in METRICS}
    diffs = [name for name in DIFFERENCES if f"{name} verdict" in table.columns]
    bases = list(dict.fromkeys(b for b in table.get("baseline", []) if isinstance(b, str)))
    base = bases[0] if len(bases) == 1 else "each row's baseline"  # rows of several compares
    rows: dict[str, dict[str, str]] = {}
    for label, r in table.iterrows():
        row = {"queries": str(int(r["queries"]))}
        row.update({heads[n]: format_interval(r[n], r[f"{n} lo"], r[f"{n} hi"]) for n in METRICS})
        for name in diffs:
            row[f"{name} vs {base}"] = _difference_text(r, name)
        twin = r.get("identical to")
        row["note"] = f"= {twin}" if isinstance(twin, str) else ""
        row["query batch"] = "needed" if r.get("query batch") == "needed" else ""
        rows[str(label)] = row
    if f"{next(iter(METRICS))} chance" in table.columns:
        first = table.iloc[0]
        rows[CHANCE_ROW] = {heads[n]: f"{first[f'{n} chance']:.3f}" for n in METRICS}
    out = pd.DataFrame.from_dict(rows, orient="index").fillna("")
    for col in ("note", "query batch"):
        if col in out and not out[col].str.len().any():
            out = out.drop(columns=col)
    out.index.name = "method"
    return CompactView(out)


class CompactView(pd.DataFrame):
    """:func:`compact`'s table; in a notebook each run's label stays on one line (a long label,
    ``dense (weighting: two_sided, normalised: query_batch, ...)``, wrapped to five lines in
    JupyterLab's narrow index column), the other cells wrap. A derived frame is a plain one."""

    def _repr_html_(self) -> str | None:
        html = pd.DataFrame(self)._repr_html_()
        if html is None or "<tbody>" not in html:
            return html
        head, _, rest = html.partition("<tbody>")
        body, _, tail = rest.partition("</tbody>")
        body = body.replace("<th>", '<th style="white-space: nowrap">')
        return f"{head}<tbody>{body}</tbody>{tail}"


def _by_priority(columns: Sequence[str]) -> list[str]:
    """The columns in the order a narrow terminal keeps them: AUC and its difference, R@1 and
    its difference, R@100P and its difference, R@5, then the rest."""
    ranks = ("AUC", "dAUC", "R@1", "dR@1", "R@100P", "dR@100P", "R@5")

    def rank(col: str) -> int:
        name = col.split()[0].split("(")[0]  # "AUC(ratio)", "dAUC vs dense"
        return ranks.index(name) if name in ranks else len(ranks)

    return sorted(columns, key=rank)


def compact_text(table: pd.DataFrame, width: int = TERMINAL_WIDTH, wide: bool = False) -> str:
    """:func:`compact` as text for a terminal of ``width`` columns: one row per run with as many
    columns as fit, in the order AUC, its paired difference, R@1, its difference, ... (no cell
    is cut), and a last line naming the columns left out. ``wide=True``: every column, however
    long the rows. The CSV of the full table keeps everything."""
    view = compact(table)
    label_w = max([len(str(view.index.name or ""))] + [len(str(i)) for i in view.index])
    used, shown, left = label_w, [], list[str]()
    for col in _by_priority(list(view.columns)):
        w = max(len(col), *(len(v) for v in view[col])) + 2
        if wide or (not left and used + w <= width):
            shown.append(col)
            used += w
        else:
            left.append(col)
    text = view[[c for c in view.columns if c in shown]].to_string()
    if not left:
        return text
    note = f"not shown at {width} columns: {', '.join(left)} (--wide or wide=True: all; the CSV)"
    return text + "\n" + textwrap.fill(note, width)


def compare_pairs(
    pairs: Sequence[Sequence[Any]], n_bootstrap: int = N_BOOTSTRAP, seed: int = 0
) -> ComparisonTable:
    """Each pair's second result against its first (paired), one row per pair: e.g. every
    method with the geometry score against the same method without it.

    Args:
        pairs: ``[(baseline, result), ...]`` on one dataset.
        n_bootstrap, seed: as :func:`compare`.

    Returns:
        The rows of :func:`compare` for each pair's second result (its ``baseline`` column
        names its own first).
    """
    rows = [compare(p, n_bootstrap=n_bootstrap, seed=seed).iloc[1:] for p in pairs]
    table = pd.concat(rows)
    if "query batch" in table.columns:  # pairs without a query-batch normalisation need none
        table["query batch"] = table["query batch"].fillna("not needed")
    return ComparisonTable(table)


class ComparisonTable(pd.DataFrame):
    """:func:`compare`'s full numeric table (columns, CSV, ``pd.DataFrame`` behaviour), shown
    compactly: ``print(table)`` / ``repr`` give :func:`compact_text`, a notebook
    :func:`compact`'s HTML. ``pd.DataFrame(table)`` is the plain view; a derived frame is a
    plain DataFrame."""

    def __repr__(self) -> str:
        try:
            return compact_text(self)
        except (KeyError, ValueError, TypeError):  # columns dropped: the plain view
            return pd.DataFrame(self).__repr__()

    def _repr_html_(self) -> str | None:
        try:
            return compact(self)._repr_html_()
        except (KeyError, ValueError, TypeError):
            return pd.DataFrame(self)._repr_html_()
