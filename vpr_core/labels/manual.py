"""Optional interactive helper to label landmark matches by hand (the paper's manual labels).

Needs ``ipywidgets`` (not a dependency: ``pip install ipywidgets``) and a live Jupyter kernel;
headless runs never call :func:`label_widget`. The CSV it writes is the ``file`` format read by
:func:`vpr_core.labels.label_matches` (``method="file", labels=path``):
``query,reference,query_box_index,reference_box_index,correct``.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np

from .file import LABEL_COLUMNS

__all__ = ["append_labels", "label_widget", "pair_label_widget"]


def append_labels(
    path: str | Path, q: int, r: int, matches: np.ndarray, correct: np.ndarray
) -> Path:
    """Append (or create) a labels CSV with one row per match of pair ``(q, r)``.

    Args:
        path: CSV file.
        q: query index.
        r: reference index.
        matches: ``(P, 2)`` landmark index pairs.
        correct: ``(P,)`` bool labels.

    Returns:
        The CSV path.
    """
    matches = np.asarray(matches, dtype=np.int64).reshape(-1, 2)
    correct = np.asarray(correct, dtype=bool).reshape(-1)
    if len(matches) != len(correct):
        raise ValueError(
            f"{len(matches)} matches but {len(correct)} labels: give one label per match."
        )
    path = Path(path)
    new = not path.exists()
    with path.open("a", newline="") as f:
        w = csv.writer(f)
        if new:
            w.writerow(LABEL_COLUMNS)
        for (i, j), c in zip(matches, correct, strict=False):
            w.writerow([q, r, int(i), int(j), int(bool(c))])
    return path


def label_widget(
    dataset: Any,
    q: int,
    r: int,
    boxes_q: np.ndarray,
    boxes_r: np.ndarray,
    matches: np.ndarray,
    out: str | Path = "labels.csv",
) -> Any:
    """Step through the matches of one pair, answer correct / wrong, then save to ``out``.

    Args:
        dataset: a ``PlaceDataset`` (``load_image``).
        q: query index.
        r: reference index.
        boxes_q: ``(Kq, 4)`` query boxes.
        boxes_r: ``(Kr, 4)`` reference boxes.
        matches: ``(P, 2)`` (query box index, reference box index).
        out: the labels CSV (appended by :func:`append_labels` after the last answer).

    Returns:
        The ipywidgets container to display in a notebook.
    """
    try:
        import ipywidgets as widgets
    except ImportError as exc:  # pragma: no cover - optional dependency
        raise ImportError("label_widget needs ipywidgets: pip install ipywidgets") from exc
    import matplotlib.pyplot as plt

    from ..viz import draw_boxes

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

    def answer(value: bool):
        def _cb(_):
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
    """:func:`label_widget` for one pair of a run: its boxes and reciprocal matches are taken
    from the run (nothing to compute by hand).

    Args:
        dataset: the run's dataset.
        result: a :class:`~vpr_core.pipeline.MethodResult` run with ``keep_descriptors=True``.
        query: query index. reference: None for its ground-truth reference.
        out: the labels CSV.
    """
    from . import pair_matches

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
