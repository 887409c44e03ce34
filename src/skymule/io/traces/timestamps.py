"""The time column of a trace: seconds (digital twin) or ISO-8601 timestamps (AADM).

Timestamps all with a UTC offset are put on UTC; all without are read as one local clock.
A mix is refused: reading the naive ones as UTC would shift them by the offset.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from skymule.io.traces.table import NUMBER_RE, Table, numbers
from skymule.io.traces.trace import TraceError, TraceFormat, quote
from skymule.limits import MAX_DURATION_S

if TYPE_CHECKING:
    from pandas.api.typing import NaTType


def _timestamps(label: str, table: Table, col: int) -> np.ndarray:
    """(R,) seconds since the first row from an ISO-8601 timestamp column."""
    cells = pd.Series(table.cells[:, col], dtype=object).astype(str)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            stamps = pd.to_datetime(cells, format="ISO8601", errors="coerce")
        except (ValueError, TypeError, OverflowError):  # e.g. mixed UTC offsets
            parsed = [_one_timestamp(c) for c in cells]
            _check_offsets(label, table, col, [aware for _, aware in parsed])
            stamps = pd.Series([stamp for stamp, _ in parsed])
    if getattr(stamps.dt, "tz", None) is not None:
        stamps = stamps.dt.tz_convert("UTC").dt.tz_localize(None)
    bad = stamps.isna().to_numpy(dtype=bool)
    if bad.any():
        r = int(np.argmax(bad))
        raw = table.cells[r, col]
        problem = "is empty" if raw == "" else f"{quote(raw)} is not a timestamp"
        raise TraceError(
            f"{label}: row {table.lines[r]}, column {quote(table.header[col])}: {problem} "
            f"(expected e.g. '2025-05-24 16:19:31.186' or seconds)"
        )
    ns = stamps.to_numpy(dtype="datetime64[ns]").astype(np.int64)
    return (ns - ns[0]).astype(float) * 1e-9


def _one_timestamp(text: str) -> tuple[pd.Timestamp | NaTType, bool | None]:
    """(UTC-naive timestamp, whether the text carried a UTC offset); (NaT, None) if unparsable."""
    try:
        parsed: pd.Timestamp | NaTType = pd.Timestamp(text)
    except (ValueError, TypeError, OverflowError):
        return pd.NaT, None
    if not isinstance(parsed, pd.Timestamp):  # "NaT" parses to NaT
        return pd.NaT, None
    stamp = parsed
    if stamp.tzinfo is not None:
        return stamp.tz_convert("UTC").tz_localize(None), True
    return stamp, False


def _check_offsets(label: str, table: Table, col: int, aware: Sequence[bool | None]) -> None:
    """Timestamps with a UTC offset (``+02:00``) and without one cannot be put on one clock.

    Reading the naive ones as UTC would shift them by the offset (a 60-row log became a
    7,260-slot mission), so a mix is an error naming the first row that differs.
    """
    kinds = [a for a in aware if a is not None]
    if not kinds or all(kinds) or not any(kinds):
        return  # all with an offset (converted to UTC) or all without (local clock)
    first = next(r for r, a in enumerate(aware) if a is not None)
    r = next(r for r, a in enumerate(aware) if a is not None and a != aware[first])
    which = "carries a UTC offset" if aware[r] else "has no UTC offset"
    raise TraceError(
        f"{label}: row {table.lines[r]}, column {quote(table.header[col])}: "
        f"{quote(table.cells[r, col])} {which}, unlike row {table.lines[first]}'s "
        f"{quote(table.cells[first, col])}; give every timestamp an offset (e.g. +02:00) or none"
    )


def time_column(label: str, table: Table, col: int, fmt: TraceFormat) -> np.ndarray:
    cells = table.cells[:, col]
    numeric = fmt == "dt" or re.fullmatch(NUMBER_RE, str(cells[0])) is not None
    if numeric:
        t = numbers(label, table, col, missing_ok=False, what="a number (seconds)")
        t = t - t[0]
    else:
        t = _timestamps(label, table, col)
    if not np.isfinite(t[-1]) or t[-1] > MAX_DURATION_S:  # before anything sized by it
        r = len(t) - 1
        raise TraceError(
            f"{label}: row {table.lines[r]}, column {quote(table.header[col])}: "
            f"{quote(cells[r])} is {t[-1]:.3g} s after the first row; a recording may last "
            f"at most {MAX_DURATION_S:g} s (skymule's longest mission)"
        )
    steps = np.diff(t)
    if (steps <= 0).any():
        r = int(np.argmax(steps <= 0)) + 1
        raise TraceError(
            f"{label}: row {table.lines[r]}, column {quote(table.header[col])}: "
            f"{quote(cells[r])} is not after the previous row's {quote(cells[r - 1])} "
            f"(time must be strictly increasing)"
        )
    return t
