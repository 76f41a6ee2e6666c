"""Label landmark matches by hand in a notebook (optional ``ipywidgets``); the answers are
appended to a CSV that ``label_matches(..., method="file")`` reads."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from vpr_core import append_labels, pair_matches

from .base import draw_boxes

__all__ = ["label_widget", "pair_label_widget"]


def label_widget(
    dataset: Any,
    q: int,
    r: int,
    boxes_q: np.ndarray,
    boxes_r: np.ndarray,
    matches: np.ndarray,
    out: str | Path = "labels.csv",
) -> Any:
    """An ipywidgets box stepping through the ``(P, 2)`` matches of pair (q, r): answer correct /
    wrong; after the last answer the labels are appended to the CSV ``out``."""
    try:
        import ipywidgets as widgets
    except ImportError as exc:  # pragma: no cover - optional dependency
        raise ImportError("label_widget needs ipywidgets: pip install ipywidgets") from exc

    img_q, img_r = dataset.load_image("query", q), dataset.load_image("reference", r)
    matches = np.asarray(matches, dtype=np.int64).reshape(-1, 2)
    labels = np.zeros(len(matches), dtype=bool)
    state = {"k": 0}
    output = widgets.Output()
    status = widgets.Label()
    yes, no = widgets.Button(description="correct"), widgets.Button(description="wrong")

    def show() -> None:
        output.clear_output(wait=True)
        k = state["k"]
        with output:
            if k >= len(matches):
                append_labels(out, q, r, matches, labels)
                status.value = f"saved {len(matches)} labels to {out}"
                yes.disabled = no.disabled = True
                print(status.value)
                return
            i, j = matches[k]
            _fig, axes = plt.subplots(1, 2, figsize=(10, 3))
            for ax, img, box in ((axes[0], img_q, boxes_q[i]), (axes[1], img_r, boxes_r[j])):
                ax.imshow(img)
                draw_boxes(ax, box[None], color="yellow", lw=2)
                ax.axis("off")
            plt.show()
        status.value = f"match {k + 1}/{len(matches)}"

    def answer(value: bool) -> Any:
        def _cb(_: Any) -> None:
            if state["k"] < len(matches):
                labels[state["k"]] = value
                state["k"] += 1
            show()

        return _cb

    yes.on_click(answer(True))
    no.on_click(answer(False))
    show()
    return widgets.VBox([widgets.HBox([yes, no, status]), output])


def pair_label_widget(
    dataset: Any,
    result: Any,
    query: int = 0,
    reference: int | None = None,
    out: str | Path = "labels.csv",
) -> Any:
    """:func:`label_widget` for one pair of a run with ``keep_descriptors=True`` (``reference``
    None: the query's ground-truth reference)."""
    pm = pair_matches(dataset, result, query, reference)
    return label_widget(
        dataset,
        pm.query,
        pm.reference,
        result.boxes["query"][pm.query],
        result.boxes["reference"][pm.reference],
        pm.matches,
        out=out,
    )
