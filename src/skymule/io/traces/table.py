"""The CSV layer shared by both trace formats: cells, line numbers and one-line errors.

Row numbers in messages are file line numbers (the header is row 1), as shown by editors
and spreadsheets.
"""

from __future__ import annotations

import contextlib
import csv
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from skymule.io.traces.trace import TraceError, listing, quote

MAX_TRACE_BYTES = 256 * 2**20
"""Largest trace file [byte] read: its cells take about ten times as much memory."""
MAX_TRACE_ROWS = 1_000_000
"""Most data rows a trace may have (11.6 days at 1 Hz, 28 h at 10 Hz; an AADM flight is about
1,200): checked while reading, so a longer file stops there instead of filling the memory."""

NUMBER_RE = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_NAN_TOKENS = frozenset({"nan", "na", "n/a", "null", "none"})
_UNNAMED_RE = re.compile(r"unnamed: \d+", re.IGNORECASE)


@dataclass(frozen=True)
class Table:
    """Raw CSV content: header names, (R, K) stripped cells and their file line numbers."""

    header: tuple[str, ...]
    cells: np.ndarray
    lines: np.ndarray


@contextlib.contextmanager
def file_errors(label: str, expected: str) -> Iterator[None]:
    """Turn the ways reading a user's file fails into one-line TraceErrors."""
    try:
        yield
    except FileNotFoundError:
        raise TraceError(f"{label}: file not found") from None
    except IsADirectoryError:
        raise TraceError(f"{label}: is a directory, expected {expected}") from None
    except UnicodeDecodeError as exc:
        raise TraceError(
            f"{label}: not a UTF-8 text file (bad byte at offset {exc.start})"
        ) from None
    except csv.Error as exc:
        raise TraceError(f"{label}: malformed CSV ({exc})") from None
    except OSError as exc:
        raise TraceError(f"{label}: cannot read file ({exc.strerror or exc})") from None


def _too_big(label: str, what: str) -> TraceError:
    rows = f"{MAX_TRACE_ROWS:,}"
    return TraceError(
        f"{label}: {what}; a trace may have at most {MAX_TRACE_BYTES // 2**20} MiB and {rows} "
        f"data rows: cut it to the part of the flight you need, e.g. `head -n "
        f"{MAX_TRACE_ROWS + 1} {label} > part.csv` keeps the header and the first {rows} rows"
    )


def _count_lines(path: Path, stop: int) -> int:
    """Line breaks in ``path`` (raw bytes, 1 MiB at a time), up to just past ``stop``."""
    count = 0
    with path.open("rb") as handle:
        while count <= stop and (chunk := handle.read(2**20)):
            count += chunk.count(b"\n")
    return count


def read_table(label: str, path: Path) -> Table:
    """The CSV's header and cells; a file over :data:`MAX_TRACE_BYTES` is refused before it
    is read, one over :data:`MAX_TRACE_ROWS` rows as soon as reading passes them."""
    with file_errors(label, "a CSV file"):
        size = path.stat().st_size
        breaks = _count_lines(path, MAX_TRACE_ROWS + 1) if size <= MAX_TRACE_BYTES else 0
    if size > MAX_TRACE_BYTES:
        raise _too_big(label, f"{size / 2**20:,.0f} MiB")
    if breaks > MAX_TRACE_ROWS + 1:  # the header and the rows: refused before any is parsed
        raise _too_big(label, f"more than {MAX_TRACE_ROWS + 1:,} lines")
    with file_errors(label, "a CSV file"), path.open(newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        header: list[str] | None = None
        rows: list[list[str]] = []
        lines: list[int] = []
        for record in reader:
            stripped = [cell.strip() for cell in record]
            if not any(stripped):
                continue
            if header is None:
                header = stripped
                continue
            if len(stripped) != len(header):
                raise TraceError(
                    f"{label}: row {reader.line_num} has {len(stripped)} fields but the "
                    f"header has {len(header)} (truncated or malformed row)"
                )
            rows.append(stripped)
            lines.append(reader.line_num)
            if len(rows) > MAX_TRACE_ROWS:
                raise _too_big(label, f"more than {MAX_TRACE_ROWS:,} data rows")
    if header is None:
        raise TraceError(f"{label}: empty file (expected a CSV header line)")
    cells = np.array(rows, dtype=object).reshape(len(rows), len(header))
    return Table(tuple(header), cells, np.array(lines, dtype=int))


def _find(header: Sequence[str], name: str) -> list[int]:
    return [i for i, h in enumerate(header) if h.lower() == name.lower()]


def locate(label: str, header: Sequence[str], name: str) -> int:
    hits = _find(header, name)
    if not hits:
        raise TraceError(
            f"{label}: column {quote(name)} is missing (columns present: {listing(header)})"
        )
    if len(hits) > 1:
        names = " and ".join(quote(header[i]) for i in hits)
        raise TraceError(
            f"{label}: columns {names} are the same column (names are case-insensitive)"
        )
    return hits[0]


def is_ignored(name: str) -> bool:
    return name == "" or _UNNAMED_RE.fullmatch(name) is not None


def numbers(
    label: str, table: Table, col: int, *, missing_ok: bool, what: str = "a number"
) -> np.ndarray:
    """(R,) float values of one column; empty/NaN cells -> NaN when ``missing_ok``."""
    cells = pd.Series(table.cells[:, col], dtype=object).astype(str)
    is_number = cells.str.fullmatch(NUMBER_RE).to_numpy(dtype=bool)
    is_missing = (cells.eq("") | cells.str.lower().isin(_NAN_TOKENS)).to_numpy(dtype=bool)
    values = np.full(len(cells), np.nan)
    values[is_number] = cells[is_number].astype(float).to_numpy()
    finite = is_number & np.isfinite(values)
    bad = ~(finite | (is_missing & missing_ok))
    if bad.any():
        r = int(np.argmax(bad))
        raw = table.cells[r, col]
        if raw == "":
            problem = "is empty; a value is required"
        elif is_number[r]:
            problem = f"{quote(raw)} is out of range"
        else:
            problem = f"{quote(raw)} is not {what}"
        raise TraceError(
            f"{label}: row {table.lines[r]}, column {quote(table.header[col])}: {problem}"
        )
    return values


def check_range(
    label: str,
    table: Table,
    col: int,
    values: np.ndarray,
    limit: float,
    unit: str = "degrees",
    *,
    low: float | None = None,
    value_unit: str = "",
) -> None:
    """Every value of a column within [``low``, ``limit``] ``unit`` (``low`` defaults to
    -``limit``); else one line naming the row and the cell (followed by ``value_unit``)."""
    low = -limit if low is None else low
    bad = (values > limit) | (values < low)
    if bad.any():
        r = int(np.argmax(bad))
        cell = quote(table.cells[r, col]) + (f" {value_unit}" if value_unit else "")
        allowed = f"-{limit:g} to {limit:g}" if low == -limit else f"{low:g} to {limit:g}"
        raise TraceError(
            f"{label}: row {table.lines[r]}, column {quote(table.header[col])}: "
            f"{cell} is out of range (allowed: {allowed} {unit})"
        )
