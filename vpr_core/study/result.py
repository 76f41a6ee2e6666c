"""What every study figure method returns: :class:`FigureResult`."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..viz.base import SAVE_DPI, png_metadata

__all__ = ["FigureResult"]


@dataclass(frozen=True)
class FigureResult:
    """One study figure: the matplotlib figure, where it was saved, and its table.

    A notebook cell that ends with a ``FigureResult`` shows the figure inline, then the table
    (IPython display hooks), so no notebook re-reads a PNG from disk.

    Attributes:
        figure: the ``matplotlib.figure.Figure`` (closed in pyplot; it still renders).
        path: the saved file, ``<output root>/figures/<label>/<stem>.png``.
        table: the numbers behind the figure (metrics per method, counts per scale, ...) as a
            ``pandas.DataFrame``, or None when the figure has none.
        panels: further files of the same figure saved separately (Fig. 4a-c), in order.
        dpi: the resolution the figure was saved with (used for the inline picture too).
    """

    figure: Any
    path: Path
    table: Any = None
    panels: tuple[Path, ...] = ()
    dpi: int = SAVE_DPI

    @property
    def stem(self) -> str:
        """The figure's file stem, e.g. ``"fig05_selection"``."""
        return self.path.stem

    def png(self) -> bytes:
        """The figure rendered as PNG bytes (same settings as the saved file)."""
        buf = io.BytesIO()
        self.figure.savefig(buf, format="png", dpi=self.dpi, metadata=png_metadata(".png"),
                            bbox_inches=None)
        return buf.getvalue()

    def _repr_png_(self) -> bytes:
        return self.png()

    def _ipython_display_(self) -> None:
        from IPython.display import Image, display

        display(Image(data=self.png(), format="png"))
        if self.table is not None:
            display(self.table)

    def __repr__(self) -> str:
        rows = "no table" if self.table is None else f"table {getattr(self.table, 'shape', '?')}"
        return f"FigureResult({self.path}, {rows})"
