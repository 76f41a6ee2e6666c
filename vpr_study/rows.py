"""The tables the workbench writes: CSV rows read and written, every cell escaped so no
spreadsheet evaluates it (one rule: :func:`csv_safe`)."""

from __future__ import annotations

import csv
import io
import os
import unicodedata
from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["FORMULA_STARTS", "csv_safe", "read_rows", "write_frame_csv", "write_rows"]


def read_rows(path: str | os.PathLike) -> list[dict[str, str]]:
    """Rows of a CSV table with a header line, as dicts (``[]`` if the file does not exist)."""
    path = Path(path)
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


#: First characters that make a spreadsheet evaluate a cell as a formula (the full-width forms
#: too: some spreadsheets read them as the ASCII ones).
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r", "\n", "\uff1d", "\uff0b", "\uff0d", "\uff20")


def _lead_stripped(text: str) -> str:
    """``text`` without its leading whitespace and control or format characters (what a
    spreadsheet may skip before it reads a formula: spaces, tab, CR, LF, NUL, zero-width)."""
    k = 0
    while k < len(text) and (text[k].isspace() or unicodedata.category(text[k])[0] in "CZ"):
        k += 1
    return text[k:]


def csv_safe(value: Any) -> Any:
    """``value`` as a CSV cell no spreadsheet evaluates: text that starts with ``= + - @`` (or
    their full-width forms), tab, CR or LF, or reaches one of ``= + - @`` after leading
    whitespace and control characters (``"\\r=1+1"``, ``"  =1"``), gets a leading single quote;
    numbers, and text that reads as a number (``"-0.5"``), stay as they are. The one escaping
    rule of every CSV the package writes; a cell holding CR or LF is also quoted by the
    writers (:func:`write_rows`, :func:`write_frame_csv`), so it never ends a row."""
    if not isinstance(value, str) or not (
        value.startswith(FORMULA_STARTS) or _lead_stripped(value).startswith(FORMULA_STARTS)
    ):
        return value
    try:
        float(value)
    except ValueError:
        return "'" + value
    return value


def _csv_field(cell: str) -> str:
    """One field as Python's csv writer quotes it (QUOTE_MINIMAL), and quoted as well when it
    holds a CR, which ``lineterminator="\\n"`` alone leaves bare."""
    if any(c in cell for c in ',"\r\n'):
        return '"' + cell.replace('"', '""') + '"'
    return cell


def write_frame_csv(table: Any, path: str | os.PathLike, **to_csv: Any) -> None:
    """``table.to_csv(path, **to_csv)`` (a pandas DataFrame; rows end in ``\\n``) where every cell
    holding a CR or LF is quoted: pandas quotes only the characters of its line terminator, so
    a bare CR in a cell would end the row for a spreadsheet. Tables without a CR are written
    by pandas itself, byte for byte."""
    text = table.to_csv(**to_csv)
    if "\r" in text:
        # every cell with a CR or LF quoted by pandas, parsed back, then each field re-quoted
        crlf = table.to_csv(lineterminator="\r\n", **to_csv)
        rows = list(csv.reader(io.StringIO(crlf, newline="")))
        text = "".join(
            ('""' if row == [""] else ",".join(_csv_field(c) for c in row)) + "\n" for row in rows
        )
    with open(path, "w", encoding="utf-8", newline="") as f:
        f.write(text)


def write_rows(path: str | os.PathLike, rows: list[Mapping[str, Any]]) -> None:
    """Write dict rows as a CSV table; columns are the union of the rows' keys in first-seen
    order (a missing value is empty), text escaped by :func:`csv_safe`, a cell holding CR or LF
    quoted (rows end in CR LF, the csv module's default). Written to a temporary file and
    renamed, so an interrupted write leaves the previous table."""
    path = Path(path)
    fields = list(dict.fromkeys(k for r in rows for k in r))
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=[csv_safe(k) for k in fields])
        w.writeheader()
        w.writerows({csv_safe(k): csv_safe(v) for k, v in r.items()} for r in rows)
    os.replace(tmp, path)
