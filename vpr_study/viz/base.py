"""Saving figures and tables (the deterministic :func:`save_figure`, :func:`save`), the layout
check every saved figure passes, the methods' colours and box drawing."""

from __future__ import annotations

import fcntl
import filecmp
import logging
import os
import re
import sys
import tempfile
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from vpr_core import notice, paths

from .. import outputs, rows
from .styles import METHOD_COLORS

__all__ = [
    "METHOD_COLORS",
    "DEFAULT_LABEL",
    "SAVE_DPI",
    "TIMING_COLUMN",
    "TableFigure",
    "draw_boxes",
    "layout_problems",
    "save",
    "save_all",
    "save_figure",
]

logger = logging.getLogger("vpr_core")

#: The label of a figure or table saved without one (:func:`save`): it goes to
#: ``<output root>/user/figures/scratch/`` or ``.../results/scratch/``, never among the study's.
DEFAULT_LABEL = "scratch"

#: Resolution of every saved study figure (dots per inch).
SAVE_DPI = 110


class TableFigure(Figure):
    """A figure that carries the table of what it shows (``.table``, a DataFrame), for the
    figures whose rows are chosen cases (e.g. :func:`~vpr_study.viz.plot_disagreements`): the
    figure is what ``save(fig, name, label)`` takes, ``save(fig.table, name, label)`` the table."""

    table: pd.DataFrame | None = None


def _png_metadata(suffix: str) -> dict:
    """Metadata that keeps saved files byte-identical: no software/version or date stamp."""
    return {"Software": None} if suffix == ".png" else {"CreationDate": None, "Producer": None}


def save_figure(
    fig: matplotlib.figure.Figure, name: str | Path, dataset: str | None = None, dpi: int = SAVE_DPI
) -> Path:
    """Save ``fig`` as ``figures/<dataset>/<name>.png`` of :func:`vpr_study.outputs.figures_root`,
    byte-identical for identical inputs.

    Args:
        fig: the figure.
        name: file stem, or a file name with ``.png`` / ``.pdf``, or an absolute path (then
            ``dataset`` is ignored).
        dataset: output label (subfolder of :func:`vpr_study.outputs.figures_dir`).
        dpi: resolution.

    Returns:
        The written path.
    """
    path = Path(name)
    if path.suffix not in (".png", ".pdf"):
        path = path.with_suffix(path.suffix + ".png") if path.suffix else path.with_suffix(".png")
    if not path.is_absolute():
        path = outputs.figures_dir(dataset) / path
    paths.make_dir(path.parent, paths.OUT_SETTING)
    _commit([(_staged(path, partial(_draw, fig, suffix=path.suffix, dpi=dpi)), path)], path.parent)
    return path


def _draw(fig: matplotlib.figure.Figure, tmp: Path, suffix: str, dpi: int = SAVE_DPI) -> None:
    fig.savefig(tmp, dpi=dpi, metadata=_png_metadata(suffix), bbox_inches=None, format=suffix[1:])


def _staged(path: Path, write: Callable[[Path], None]) -> Path:
    """``write`` into a fresh temporary file beside ``path`` (unique per call, so concurrent
    writers never share one); a failed write removes it and names ``path``."""
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        write(tmp)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and not exc.filename:
            raise type(exc)(
                exc.errno,
                f"cannot write {path} ({exc.strerror or exc}); free space there or choose "
                "another --out / VPR_OUTPUT_DIR",
            ) from exc
        raise
    return tmp


def _commit(staged: list[tuple[Path, Path]], lock_dir: Path) -> None:
    """Rename every ``(temporary, final)`` pair under one lock of ``lock_dir`` (an exclusive
    ``flock`` on the folder), so concurrent runs never leave a figure beside another run's
    table; says when a file with other content is replaced."""
    fd = os.open(lock_dir, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        for tmp, path in staged:
            if path.is_file() and not filecmp.cmp(tmp, path, shallow=False):
                logger.info("replaced %s (its previous content differed)", path)
            os.chmod(tmp, 0o644)
            tmp.replace(path)
    finally:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
        os.close(fd)  # releases the lock


def _legend_boxes(fig) -> list:
    out = list(fig.legends)
    for ax in fig.axes:
        leg = ax.get_legend()
        if leg is not None:
            out.append(leg)
    return out


def _data_points(ax) -> np.ndarray:
    """Display coordinates of an axes' plotted data: line vertices and bar tops/corners."""
    pts = []
    for line in ax.get_lines():
        xy = np.asarray(line.get_xydata(), dtype=float).reshape(-1, 2)
        xy = xy[np.isfinite(xy).all(axis=1)]
        if len(xy) and line.get_visible() and line.get_linewidth() > 0:
            pts.append(ax.transData.transform(xy))
    for patch in ax.patches:
        if isinstance(patch, Rectangle) and patch.get_visible() and patch.get_height() > 0:
            x, y, w, h = patch.get_x(), patch.get_y(), patch.get_width(), patch.get_height()
            corners = np.array([[x, y + h], [x + w, y + h], [x + w / 2, y + h]])
            pts.append(ax.transData.transform(corners))
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def _texts(fig: matplotlib.figure.Figure) -> list:
    """Every drawn text a reader must see whole: figure texts and super-titles, each axes'
    titles, axis labels and unclipped annotations, legend titles and entries."""
    found: list = list(fig.texts)
    found += [getattr(fig, a, None) for a in ("_suptitle", "_supxlabel", "_supylabel")]
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        found += [ax.title, getattr(ax, "_left_title", None), getattr(ax, "_right_title", None)]
        found += [ax.xaxis.label, ax.yaxis.label]
        found += [t for t in ax.texts if not t.get_clip_on()]
    for leg in _legend_boxes(fig):
        found += [leg.get_title(), *leg.get_texts()]
    return [t for t in found if t is not None and t.get_visible() and t.get_text().strip()]


def _renderer(fig: matplotlib.figure.Figure):
    """The renderer of ``fig``'s canvas, whatever the figure's history: a figure shown by the
    inline backend in an earlier cell, or closed with ``plt.close``, keeps a bare
    ``FigureCanvasBase`` without a renderer; it gets an Agg canvas, the one ``savefig`` uses
    for a PNG anyway (the saved bytes stay the same)."""
    if not hasattr(fig.canvas, "get_renderer"):
        FigureCanvasAgg(fig)  # attaches itself as fig.canvas
    return fig.canvas.get_renderer()  # type: ignore[attr-defined]


def layout_problems(fig: matplotlib.figure.Figure) -> list[str]:
    """What a reader would see as broken in a figure: text cut by the canvas edge (each text's
    extent measured at the saving resolution :data:`SAVE_DPI`), a legend drawn over the
    plotted data (line vertices, bar tops).

    Returns:
        One sentence per problem (empty: the figure passes).
    """
    dpi = fig.get_dpi()
    fig.set_dpi(SAVE_DPI)  # text extents do not scale exactly with the resolution
    try:
        fig.draw_without_rendering()
        renderer = _renderer(fig)
        canvas = fig.bbox.frozen()
        parts = [
            (
                f"axes {ax.get_title()[:50]!r} (its title, tick or axis labels)",
                ax.get_tightbbox(renderer),
            )
            for ax in fig.axes
            if ax.get_visible()
        ]
        parts += [
            (f"text {t.get_text()[:50]!r}", t.get_window_extent(renderer)) for t in _texts(fig)
        ]
        parts += [("a figure legend", leg.get_window_extent(renderer)) for leg in fig.legends]
    finally:
        fig.set_dpi(dpi)
    problems = []
    for what, bb in parts:
        if bb is None:
            continue
        if (
            bb.x0 < canvas.x0 - 1
            or bb.y0 < canvas.y0 - 1
            or bb.x1 > canvas.x1 + 1
            or bb.y1 > canvas.y1 + 1
        ):
            problems.append(f"{what} extends beyond the canvas")
    fig.draw_without_rendering()
    renderer = _renderer(fig)
    for leg in _legend_boxes(fig):
        bb = leg.get_window_extent(renderer)
        for ax in fig.axes:
            pts = _data_points(ax)
            inside = (
                (pts[:, 0] > bb.x0)
                & (pts[:, 0] < bb.x1)
                & (pts[:, 1] > bb.y0)
                & (pts[:, 1] < bb.y1)
            )
            if inside.any():
                problems.append(
                    f"the legend covers {int(inside.sum())} data point(s) of the "
                    f"axes {ax.get_title()[:40]!r}"
                )
    return problems


#: Columns of a table that hold a duration measured on this machine (``s/img``, ``s/pair``,
#: ``(s)``): :func:`save` writes them to ``<stem>.timings.csv`` (git-ignored), not the table.
TIMING_COLUMN = re.compile(r"\bs/(img|pair)\b|\(s\)")


def _split_timings(table: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame | None]:
    """``(table without timing columns, timings or None)``; ``root`` cells become the data
    folder's name, so the committed table is the same on every machine.

    The timings keep the table's index, or its first column when the index is a plain range.
    """
    table = table.copy()
    if "root" in table.columns:
        table["root"] = [Path(v).name if isinstance(v, str) and v else v for v in table["root"]]
    timed = [c for c in table.columns if isinstance(c, str) and TIMING_COLUMN.search(c)]
    if not timed:
        return table, None
    keys = [] if not isinstance(table.index, pd.RangeIndex) else [table.columns[0]]
    keys = [k for k in keys if k not in timed]
    return table.drop(columns=timed), table[keys + timed]


def _write_csv(table: pd.DataFrame, tmp: Path) -> None:
    with_index = not isinstance(table.index, pd.RangeIndex)  # decided before renaming
    table = table.rename(columns=rows.csv_safe, index=rows.csv_safe if with_index else None)
    for i, dtype in enumerate(table.dtypes):
        if not pd.api.types.is_numeric_dtype(dtype):  # text cells; numbers stay numbers
            table.isetitem(i, table.iloc[:, i].map(rows.csv_safe))
    rows.write_frame_csv(table, tmp, float_format="%.6f", index=with_index)


def save_all(
    items: Sequence[tuple[str, matplotlib.figure.Figure | pd.DataFrame]],
    label: str | None = None,
    out: str | Path | None = None,
) -> list[Path]:
    """Write figures and tables of one label as one unit (the one output writer).

    A matplotlib Figure goes to ``figures/<label>/<name>.png`` (byte-identical for identical
    inputs, checked by :func:`layout_problems`, whatever the figure's history: shown inline in
    an earlier cell, closed with ``plt.close``); a pandas DataFrame to
    ``results/<label>/<name>.csv`` (floats with 6 decimals, the index kept; timing columns to
    ``<name>.timings.csv``, :func:`_split_timings`; a table of nothing but timings, such as
    Table 5, goes only there). Everything is written to unique temporary
    files first, then renamed under one lock of the output root: concurrent runs never leave
    one run's figure beside another's table. Replacing a file with other content is logged.

    Args:
        items: ``(file stem, Figure or DataFrame)`` pairs; a figure and its table may share a
            stem, which is one file name (:func:`vpr_study.outputs.check_name`).
        label: the dataset label (one folder name), e.g. ``"gardens_point_mini"``. None: the
            user area ``<output root>/user/`` (:data:`vpr_study.outputs.USER_AREA`) under the label
            :data:`DEFAULT_LABEL`, never the study's folders; the log (``vpr_core``, INFO)
            names the label and every path written.
        out: another output root (default :func:`vpr_study.outputs.figures_root`: the study's
            folders for the study and the CLI, the git-ignored ``user/`` for a user's own
            cells in the checkout).

    Returns:
        The written paths (a table's timings file not included, an all-timings table's
        included), in the order of ``items``.

    Raises:
        TypeError: an item is neither a Figure nor a DataFrame, or ``label`` / a name not a
            string.
        ValueError: ``label`` is not one folder name or a name not one file name (``../x``,
            ``/tmp/x``, ``a/b``), or a figure has no axes; nothing is written then.
    """
    items = list(items)
    for name, _ in items:
        outputs.check_name(name)
    unlabelled = label is None
    if label is None:
        base = paths.output_root() if out is None else Path(out).expanduser().resolve()
        root = base / outputs.USER_AREA
        label = DEFAULT_LABEL
    else:
        outputs.check_label(label)
        root = outputs.figures_root() if out is None else Path(out).expanduser().resolve()
    staged: list[tuple[Path, Path]] = []
    written: list[Path] = []
    try:
        for name, obj in items:
            if isinstance(obj, matplotlib.figure.Figure):
                if not obj.axes:
                    raise ValueError(
                        f"save({name!r}): the figure has no axes, so its PNG would be blank (a "
                        "plt.gcf() in a later cell is a new, empty figure): save the figure the "
                        "plot_* call returned, e.g. fig = plot_pr_curves(runs); save(fig, "
                        f"{name!r}, label)"
                    )
                for problem in layout_problems(obj):
                    notice(f"layout of {name}: {problem}")
                path = paths.make_dir(root / "figures" / label, paths.OUT_SETTING) / f"{name}.png"
                staged.append((_staged(path, partial(_draw, obj, suffix=".png")), path))
            elif isinstance(obj, pd.DataFrame):
                folder = paths.make_dir(root / "results" / label, paths.OUT_SETTING)
                table, timings = _split_timings(obj)
                path = folder / f"{name}.csv"
                if timings is not None and set(table.columns) <= set(timings.columns):
                    # nothing but timings: a measurement of this machine, no committed table
                    path = folder / f"{name}.timings.csv"
                    staged.append((_staged(path, partial(_write_csv, timings)), path))
                    written.append(path)
                    continue
                staged.append((_staged(path, partial(_write_csv, table)), path))
                if timings is not None:
                    extra = folder / f"{name}.timings.csv"
                    staged.append((_staged(extra, partial(_write_csv, timings)), extra))
            elif isinstance(obj, tuple) and any(isinstance(o, Figure) for o in obj):
                raise TypeError(
                    f"save() writes one figure or one table, got a tuple for {name!r} (a "
                    "plot_* that returns (figure, table)): save each, e.g. fig, table = "
                    f"plot_...(...); save(fig, {name!r}, label), save(table, {name!r}, label)"
                )
            else:
                raise TypeError(
                    f"save() writes a matplotlib Figure or a pandas DataFrame, got "
                    f"{type(obj).__name__} for {name!r}"
                )
            written.append(path)
    except BaseException:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
        raise
    _commit(staged, paths.make_dir(root, paths.OUT_SETTING))
    if unlabelled:
        for path in written:
            logger.info(
                "saved without a label: label %r, written to %s (pass a label, e.g. "
                "save(obj, name, 'mine'), to choose the folder)",
                DEFAULT_LABEL,
                path,
            )
    return written


def save(obj, name: str, label: str | None = None, out: str | Path | None = None) -> Path:
    """Write one figure or table of the study under its dataset label (:func:`save_all`).

    Works on a figure whatever its history (shown inline in an earlier cell, closed).

    Args:
        obj: ``matplotlib.figure.Figure`` or ``pandas.DataFrame``.
        name: file stem, one file name, e.g. ``"fig05_selection"`` (``../x``, ``/tmp/x`` or
            ``a/b`` are refused: the label chooses the folder).
        label: the dataset label (one folder name), e.g. ``"synthetic"``. None (left out):
            ``<output root>/user/figures/scratch/`` or ``.../results/scratch/``
            (:data:`DEFAULT_LABEL`), the label and the path written named in the log.
        out: another output root.

    Returns:
        The written path.

    Raises:
        TypeError: ``obj`` is neither a Figure nor a DataFrame.
        ValueError: ``name`` or ``label`` would write outside its folder, or the figure has no
            axes (a blank PNG).
    """
    return save_all([(name, obj)], label, out)[0]


def draw_boxes(ax, boxes: np.ndarray, color="yellow", lw: float = 1.0, alpha: float = 0.9) -> None:
    """Draw ``(K, 4)`` ``(x, y, w, h)`` boxes on an axes."""
    for x, y, w, h in np.asarray(boxes, dtype=float).reshape(-1, 4):
        ax.add_patch(Rectangle((x, y), w, h, fill=False, edgecolor=color, lw=lw, alpha=alpha))


def _show_once(fig: matplotlib.figure.Figure) -> None:
    """IPython's display of a figure (a cell's value, ``display(fig)``, the inline backend's
    end-of-cell flush): the picture in the formats the inline backend is set to (PNG, JPEG...),
    then the figure leaves pyplot, so a ``plot_*`` call as a cell's last expression shows once,
    not twice."""
    from IPython import get_ipython
    from IPython.display import publish_display_data

    ip = get_ipython()
    if ip is None:
        return
    hook = ip.display_formatter.ipython_display_formatter
    hook.enabled = False  # the other formatters render it, not this one again
    try:
        data, metadata = ip.display_formatter.format(fig)
    finally:
        hook.enabled = True
    publish_display_data(data, metadata)
    if "inline" in matplotlib.get_backend():  # "inline" or "module://matplotlib_inline..."
        plt.close(fig)  # shown: the end-of-cell flush would show it again


def _show_figures_once() -> None:
    """In an IPython kernel, display every figure through :func:`_show_once` (outside one,
    IPython is not imported)."""
    ipython = sys.modules.get("IPython")
    if ipython is None:
        return
    ip = ipython.get_ipython()
    if ip is not None and hasattr(ip, "display_formatter"):
        ip.display_formatter.ipython_display_formatter.for_type(Figure, _show_once)


_show_figures_once()
