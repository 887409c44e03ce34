"""Readers and writers for recorded UAV flight traces (AERPAW testbed / digital twin).

Two CSV formats are recognised from their header (column names are matched
case-insensitively, surrounding whitespace and a UTF-8 BOM are ignored):

``aadm``  AADM merged log
    ``time, snr_<sensor>..., Longitude, Latitude, Altitude`` plus any other columns
    (attitude, velocity, battery, ...), which are ignored. ``time`` is a timestamp such
    as ``2025-05-24 16:19:31.186`` (ISO 8601; plain numbers are taken as seconds), SNR
    is in dB, ``Altitude`` is metres relative to take-off. Deep drops (about -50 dB)
    are real link losses and are kept as values; empty SNR cells become NaN.

``dt``  Digital-twin export
    ``Time, <sensor>..., X, Y, Height``: ``Time`` in seconds, ``X``/``Y`` metres
    east/north of the scenario origin, ``Height`` in metres. Every other named column
    is an SNR column in dB; values ``<= -99`` (the exporter's missing marker) and empty
    cells become NaN.

Columns with an empty name (e.g. an index written by ``DataFrame.to_csv``) or named
``Unnamed: <n>`` are ignored in both formats.

Everything that is wrong with a user's file raises :class:`TraceError`, whose message
is one line: ``<file>: <what is wrong> (<what is allowed>)``. Row numbers in messages
are file line numbers (the header is row 1), as shown by editors and spreadsheets.
"""

from __future__ import annotations

import contextlib
import csv
import math
import os
import re
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError

if TYPE_CHECKING:
    from pandas.api.typing import NaTType

__all__ = [
    "DT_MISSING",
    "Trace",
    "TraceError",
    "normalise_column",
    "positions_local",
    "read_trace",
    "read_volumes",
    "write_aadm_log",
    "write_dt_export",
]

TraceFormat = Literal["aadm", "dt"]
ToLocal = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]

DT_MISSING = -99.0
"""Digital-twin missing-sample marker (dB); any SNR value <= this is read as NaN."""

AADM_TIME_FORMAT = "%Y-%m-%d %H:%M:%S.%f"
_AADM_REQUIRED = ("time", "Longitude", "Latitude", "Altitude")
_DT_REQUIRED = ("Time", "X", "Y", "Height")
_UNRECOGNISED = (
    "unrecognised format: expected AADM merged-log columns "
    "(time, snr_<name>..., Longitude, Latitude, Altitude) "
    "or digital-twin columns (Time, <names>..., X, Y, Height)"
)
_NUMBER_RE = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_NAN_TOKENS = frozenset({"nan", "na", "n/a", "null", "none"})
_UNNAMED_RE = re.compile(r"unnamed: \d+", re.IGNORECASE)
_MAX_LISTED = 12


class TraceError(SkymuleError):
    """A trace or volume file cannot be used; the message is one user-facing line."""


# ---------------------------------------------------------------------------
# Trace container
# ---------------------------------------------------------------------------


def normalise_column(name: str) -> str:
    """Sensor key of an SNR column name: ``snr_lw1`` -> ``LW1``, ``lw1`` -> ``LW1``."""
    key = name.strip().upper()
    if key.startswith("SNR_") and len(key) > 4:
        key = key[4:]
    return key


def _frozen_array(values: object, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.array(values, dtype=float, copy=True)
    if arr.shape != shape:
        raise ValueError(f"Trace.{name} has shape {arr.shape}, expected {shape}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class Trace:
    """One recorded flight: the file's samples as arrays, not resampled.

    Attributes:
        path: file the trace was read from (as given to :func:`read_trace`).
        format: ``"aadm"`` (merged log, geodetic positions) or ``"dt"`` (digital twin,
            local x/y positions).
        time_s: (S,) seconds since the first sample; strictly increasing, ``time_s[0] == 0``.
        snr_db: (S, C) SNR in dB, NaN for missing samples.
        columns: (C,) upper-case sensor keys of the SNR columns (``snr_lw1`` -> ``LW1``).
        lat_deg, lon_deg: (S,) WGS-84 degrees (AADM) or None.
        x_m, y_m: (S,) metres east/north of the origin (digital twin) or None.
        z_m: (S,) metres (AADM ``Altitude`` above take-off, DT ``Height``).

    Arrays are copied to float and made read-only.
    """

    path: str
    format: TraceFormat
    time_s: np.ndarray
    snr_db: np.ndarray
    columns: tuple[str, ...]
    lat_deg: np.ndarray | None
    lon_deg: np.ndarray | None
    x_m: np.ndarray | None
    y_m: np.ndarray | None
    z_m: np.ndarray

    def __post_init__(self) -> None:
        if self.format not in ("aadm", "dt"):
            raise ValueError(f"Trace.format must be 'aadm' or 'dt', got {self.format!r}")
        columns = tuple(normalise_column(str(c)) for c in self.columns)
        if len(set(columns)) != len(columns):
            raise ValueError(f"Trace.columns has duplicate sensor keys: {columns}")
        time_s = np.array(self.time_s, dtype=float)
        if time_s.ndim != 1:
            raise ValueError(f"Trace.time_s must be 1-D, got shape {time_s.shape}")
        n = time_s.shape[0]
        set_ = object.__setattr__
        set_(self, "columns", columns)
        set_(self, "time_s", _frozen_array(time_s, (n,), "time_s"))
        set_(self, "snr_db", _frozen_array(self.snr_db, (n, len(columns)), "snr_db"))
        set_(self, "z_m", _frozen_array(self.z_m, (n,), "z_m"))
        for name in ("lat_deg", "lon_deg", "x_m", "y_m"):
            value = getattr(self, name)
            if value is not None:
                set_(self, name, _frozen_array(value, (n,), name))
        if (self.lat_deg is None) != (self.lon_deg is None):
            raise ValueError("Trace.lat_deg and Trace.lon_deg must both be set or both None")
        if (self.x_m is None) != (self.y_m is None):
            raise ValueError("Trace.x_m and Trace.y_m must both be set or both None")
        if self.lat_deg is None and self.x_m is None:
            raise ValueError("Trace needs lat_deg/lon_deg or x_m/y_m positions")

    @property
    def n_samples(self) -> int:
        """Number of samples S."""
        return int(self.time_s.shape[0])

    def column_index(self, name: str) -> int:
        """Index into ``snr_db[:, i]`` of a sensor; accepts ``LW1``, ``lw1`` or ``snr_lw1``."""
        key = normalise_column(name)
        try:
            return self.columns.index(key)
        except ValueError:
            raise TraceError(
                f"{self.path}: no SNR column {_q(name)} (available: {_listing(self.columns)})"
            ) from None

    def missing_count(self) -> np.ndarray:
        """(C,) int number of NaN samples in each SNR column."""
        return np.isnan(self.snr_db).sum(axis=0).astype(int)


# ---------------------------------------------------------------------------
# Message helpers
# ---------------------------------------------------------------------------


def _q(text: str, limit: int = 40) -> str:
    """Single-quoted, single-line, length-limited rendering of a user value."""
    flat = text.replace("\r", "\\r").replace("\n", "\\n").replace("\t", "\\t")
    if len(flat) > limit:
        flat = flat[: limit - 3] + "..."
    return f"'{flat}'"


def _listing(names: Sequence[str]) -> str:
    shown = [n.replace("\n", "\\n") for n in names[:_MAX_LISTED]]
    more = len(names) - len(shown)
    return ", ".join(shown) + (f", ... ({more} more)" if more > 0 else "")


# ---------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class _Table:
    """Raw CSV content: header names, (R, K) stripped cells and their file line numbers."""

    header: tuple[str, ...]
    cells: np.ndarray
    lines: np.ndarray


@contextlib.contextmanager
def _file_errors(label: str, expected: str) -> Iterator[None]:
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


def _read_table(label: str, path: Path) -> _Table:
    with _file_errors(label, "a CSV file"), path.open(newline="", encoding="utf-8-sig") as fh:
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
    if header is None:
        raise TraceError(f"{label}: empty file (expected a CSV header line)")
    cells = np.array(rows, dtype=object).reshape(len(rows), len(header))
    return _Table(tuple(header), cells, np.array(lines, dtype=int))


def _find(header: Sequence[str], name: str) -> list[int]:
    return [i for i, h in enumerate(header) if h.lower() == name.lower()]


def _locate(label: str, header: Sequence[str], name: str) -> int:
    hits = _find(header, name)
    if not hits:
        raise TraceError(
            f"{label}: column {_q(name)} is missing (columns present: {_listing(header)})"
        )
    if len(hits) > 1:
        names = " and ".join(_q(header[i]) for i in hits)
        raise TraceError(
            f"{label}: columns {names} are the same column (names are case-insensitive)"
        )
    return hits[0]


def _ignored(name: str) -> bool:
    return name == "" or _UNNAMED_RE.fullmatch(name) is not None


def _detect(label: str, header: Sequence[str]) -> TraceFormat:
    lower = {h.lower() for h in header}
    has_snr = any(h.startswith("snr_") and len(h) > 4 for h in lower)
    aadm_score = sum(n.lower() in lower for n in _AADM_REQUIRED[1:]) + int(has_snr)
    dt_score = sum(n.lower() in lower for n in _DT_REQUIRED[1:])
    if aadm_score == 0 and dt_score == 0:
        hint = ""
        if len(header) == 1 and any(sep in header[0] for sep in ";\t|"):
            hint = "; the header has a single column, is the file comma-separated?"
        raise TraceError(f"{label}: {_UNRECOGNISED}{hint}")
    aadm_complete = aadm_score == 4 and "time" in lower
    dt_complete = dt_score == 3 and "time" in lower
    if aadm_complete or (not dt_complete and aadm_score >= dt_score):
        return "aadm"
    return "dt"


def _snr_columns(label: str, header: Sequence[str], fmt: TraceFormat) -> list[int]:
    if fmt == "aadm":
        idx = [i for i, h in enumerate(header) if h.lower().startswith("snr_") and len(h) > 4]
        if not idx:
            raise TraceError(
                f"{label}: no SNR columns (expected columns named snr_<sensor>; "
                f"columns present: {_listing(header)})"
            )
    else:
        reserved = {n.lower() for n in _DT_REQUIRED}
        idx = [i for i, h in enumerate(header) if h.lower() not in reserved and not _ignored(h)]
        if not idx:
            raise TraceError(
                f"{label}: no SNR columns (expected sensor columns besides Time, X, Y, Height)"
            )
    seen: dict[str, int] = {}
    for i in idx:
        key = normalise_column(header[i])
        if key in seen:
            raise TraceError(
                f"{label}: columns {_q(header[seen[key]])} and {_q(header[i])} "
                f"both name sensor {_q(key)}"
            )
        seen[key] = i
    return idx


def _select_sensors(
    label: str, header: Sequence[str], idx: list[int], sensors: Sequence[str], fmt: TraceFormat
) -> list[int]:
    by_key = {normalise_column(header[i]): i for i in idx}
    chosen: list[int] = []
    for name in sensors:
        key = normalise_column(name)
        if key not in by_key:
            shown = f"snr_{key.lower()}" if fmt == "aadm" else key
            raise TraceError(
                f"{label}: column {_q(shown)} is missing (columns present: {_listing(header)})"
            )
        if by_key[key] not in chosen:
            chosen.append(by_key[key])
    return chosen


def _numbers(
    label: str, table: _Table, col: int, *, missing_ok: bool, what: str = "a number"
) -> np.ndarray:
    """(R,) float values of one column; empty/NaN cells -> NaN when ``missing_ok``."""
    cells = pd.Series(table.cells[:, col], dtype=object).astype(str)
    is_number = cells.str.fullmatch(_NUMBER_RE).to_numpy(dtype=bool)
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
            problem = f"{_q(raw)} is out of range"
        else:
            problem = f"{_q(raw)} is not {what}"
        raise TraceError(
            f"{label}: row {table.lines[r]}, column {_q(table.header[col])}: {problem}"
        )
    return values


def _timestamps(label: str, table: _Table, col: int) -> np.ndarray:
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
        problem = "is empty" if raw == "" else f"{_q(raw)} is not a timestamp"
        raise TraceError(
            f"{label}: row {table.lines[r]}, column {_q(table.header[col])}: {problem} "
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


def _check_offsets(label: str, table: _Table, col: int, aware: Sequence[bool | None]) -> None:
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
        f"{label}: row {table.lines[r]}, column {_q(table.header[col])}: "
        f"{_q(table.cells[r, col])} {which}, unlike row {table.lines[first]}'s "
        f"{_q(table.cells[first, col])}; give every timestamp an offset (e.g. +02:00) or none"
    )


def _time_column(label: str, table: _Table, col: int, fmt: TraceFormat) -> np.ndarray:
    cells = table.cells[:, col]
    numeric = fmt == "dt" or re.fullmatch(_NUMBER_RE, str(cells[0])) is not None
    if numeric:
        t = _numbers(label, table, col, missing_ok=False, what="a number (seconds)")
        t = t - t[0]
    else:
        t = _timestamps(label, table, col)
    steps = np.diff(t)
    if (steps <= 0).any():
        r = int(np.argmax(steps <= 0)) + 1
        raise TraceError(
            f"{label}: row {table.lines[r]}, column {_q(table.header[col])}: "
            f"{_q(cells[r])} is not after the previous row's {_q(cells[r - 1])} "
            f"(time must be strictly increasing)"
        )
    return t


def read_trace(path: str | os.PathLike[str], *, sensors: Sequence[str] | None = None) -> Trace:
    """Read an AADM merged log or a digital-twin export, detected from its header.

    Args:
        path: CSV file.
        sensors: optional sensor names (``LW1``, ``lw1`` or ``snr_lw1``) that must be
            present; when given, only these SNR columns are returned, in this order.

    Returns:
        The :class:`Trace`; ``time_s`` is relative to the first row.

    Raises:
        TraceError: missing/empty/header-only file, unrecognised or incomplete header,
            malformed rows, non-numeric SNR/position/altitude cells, empty position or
            time cells, or a time column that is not strictly increasing.
    """
    label = os.fspath(path)
    table = _read_table(label, Path(path))
    header = table.header
    fmt = _detect(label, header)
    required = _AADM_REQUIRED if fmt == "aadm" else _DT_REQUIRED
    where = {name: _locate(label, header, name) for name in required}
    snr_idx = _snr_columns(label, header, fmt)
    if sensors is not None:
        snr_idx = _select_sensors(label, header, snr_idx, sensors, fmt)
    if table.cells.shape[0] == 0:
        raise TraceError(f"{label}: no data rows (the file has only a header)")

    time_s = _time_column(label, table, where[required[0]], fmt)
    snr = np.column_stack([_numbers(label, table, i, missing_ok=True) for i in snr_idx]).reshape(
        len(time_s), len(snr_idx)
    )
    if fmt == "dt":
        snr[snr <= DT_MISSING] = np.nan
    pos = {name: _numbers(label, table, where[name], missing_ok=False) for name in required[1:]}
    columns = tuple(normalise_column(header[i]) for i in snr_idx)
    if fmt == "aadm":
        _check_range(label, table, where["Latitude"], pos["Latitude"], 90.0)
        _check_range(label, table, where["Longitude"], pos["Longitude"], 180.0)
        return Trace(
            path=label,
            format="aadm",
            time_s=time_s,
            snr_db=snr,
            columns=columns,
            lat_deg=pos["Latitude"],
            lon_deg=pos["Longitude"],
            x_m=None,
            y_m=None,
            z_m=pos["Altitude"],
        )
    return Trace(
        path=label,
        format="dt",
        time_s=time_s,
        snr_db=snr,
        columns=columns,
        lat_deg=None,
        lon_deg=None,
        x_m=pos["X"],
        y_m=pos["Y"],
        z_m=pos["Height"],
    )


def _check_range(label: str, table: _Table, col: int, values: np.ndarray, limit: float) -> None:
    bad = np.abs(values) > limit
    if bad.any():
        r = int(np.argmax(bad))
        raise TraceError(
            f"{label}: row {table.lines[r]}, column {_q(table.header[col])}: "
            f"{_q(table.cells[r, col])} is out of range (allowed: -{limit:g} to {limit:g} degrees)"
        )


def positions_local(trace: Trace, to_local: ToLocal | None = None) -> np.ndarray:
    """(S, 3) positions in metres (x east, y north, z up) in the scenario's local frame.

    Digital-twin traces use their x/y directly. Geodetic (AADM) traces need
    ``to_local(lat_deg, lon_deg) -> (x_m, y_m)``, each argument and result of shape (S,);
    this module does no geodesy itself. z is ``trace.z_m``.
    """
    if trace.x_m is not None and trace.y_m is not None:
        x, y = trace.x_m, trace.y_m
    else:
        if to_local is None:
            raise ValueError(f"{trace.path}: trace has latitude/longitude positions; pass to_local")
        x_raw, y_raw = to_local(np.asarray(trace.lat_deg), np.asarray(trace.lon_deg))
        x = np.asarray(x_raw, dtype=float)
        y = np.asarray(y_raw, dtype=float)
        if x.shape != (trace.n_samples,) or y.shape != (trace.n_samples,):
            raise ValueError(
                f"to_local returned shapes {x.shape} and {y.shape}, "
                f"expected ({trace.n_samples},) each"
            )
    return np.column_stack([x, y, trace.z_m]).astype(float)


def read_volumes(path: str | os.PathLike[str]) -> np.ndarray:
    """(N,) data volumes in Mbit from an AADM volume file: one number a line.

    Blank lines and lines starting with ``#`` are ignored. Values must be finite and
    non-negative.

    Raises:
        TraceError: missing/unreadable file, a bad line (named by its line number), or
            no values at all.
    """
    label = os.fspath(path)
    with _file_errors(label, "a volume file"):
        text = Path(path).read_text(encoding="utf-8-sig")
    values: list[float] = []
    for number, line in enumerate(text.splitlines(), start=1):
        cell = line.strip()
        if not cell or cell.startswith("#"):
            continue
        if re.fullmatch(_NUMBER_RE, cell) is None:
            raise TraceError(
                f"{label}: line {number}: {_q(cell)} is not a number "
                f"(expected one data volume in Mbit per line)"
            )
        value = float(cell)
        if not math.isfinite(value) or value < 0:
            raise TraceError(
                f"{label}: line {number}: {_q(cell)} is not a valid volume "
                f"(expected a finite, non-negative number of Mbit)"
            )
        values.append(value)
    if not values:
        raise TraceError(f"{label}: no volumes (expected one number in Mbit per line)")
    return np.array(values, dtype=float)


# ---------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------


def _writer_arrays(
    time_s: np.ndarray, snr_db: np.ndarray, columns: Sequence[str], **positions: np.ndarray
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...], dict[str, np.ndarray]]:
    t = np.asarray(time_s, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"time_s must be a non-empty 1-D array, got shape {t.shape}")
    if not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        raise ValueError("time_s must be finite and strictly increasing")
    keys = tuple(normalise_column(c) for c in columns)
    if not keys or len(set(keys)) != len(keys) or any(not k for k in keys):
        raise ValueError(f"columns must be non-empty, distinct sensor names, got {columns!r}")
    snr = np.asarray(snr_db, dtype=float)
    if snr.ndim == 1:
        snr = snr.reshape(-1, 1)
    if snr.shape != (t.size, len(keys)):
        raise ValueError(f"snr_db has shape {snr.shape}, expected {(t.size, len(keys))}")
    if np.isinf(snr).any():
        raise ValueError("snr_db must not contain infinities (use NaN for missing samples)")
    out: dict[str, np.ndarray] = {}
    for name, value in positions.items():
        arr = np.asarray(value, dtype=float)
        if arr.shape != t.shape:
            raise ValueError(f"{name} has shape {arr.shape}, expected {t.shape}")
        if not np.isfinite(arr).all():
            raise ValueError(f"{name} must be finite")
        out[name] = arr
    return t, snr, keys, out


def _write_csv(path: str | os.PathLike[str], frame: pd.DataFrame) -> Path:
    target = Path(path)
    frame.to_csv(target, index=False, na_rep="", float_format=None, lineterminator="\n")
    return target


def write_aadm_log(
    path: str | os.PathLike[str],
    time_s: np.ndarray,
    snr_db: np.ndarray,
    columns: Sequence[str],
    lat_deg: np.ndarray,
    lon_deg: np.ndarray,
    alt_m: np.ndarray,
    *,
    start: datetime | str = "2025-05-24 16:19:31.186",
    extra: Mapping[str, np.ndarray] | None = None,
) -> Path:
    """Write an AADM merged log that :func:`read_trace` reads back.

    Args:
        path: output CSV file (overwritten).
        time_s: (S,) seconds since ``start``, strictly increasing; written as
            ``YYYY-mm-dd HH:MM:SS.fff`` (rounded to the millisecond).
        snr_db: (S, C) SNR in dB; NaN is written as an empty cell.
        columns: (C,) sensor names; written as ``snr_<lower-case key>``.
        lat_deg, lon_deg: (S,) WGS-84 degrees.
        alt_m: (S,) metres relative to take-off.
        start: wall-clock time of ``time_s == 0`` (naive, as in the testbed logs).
        extra: additional (S,) columns to write after ``Altitude`` (ignored by the reader).

    Returns:
        The written path.
    """
    t, snr, keys, pos = _writer_arrays(
        time_s, snr_db, columns, lat_deg=lat_deg, lon_deg=lon_deg, alt_m=alt_m
    )
    origin = datetime.fromisoformat(start) if isinstance(start, str) else start
    ms = np.round(t * 1e3).astype(np.int64)
    if (np.diff(ms) <= 0).any():
        raise ValueError("time_s samples closer than 1 ms collapse when written")
    stamps = [(origin + timedelta(milliseconds=int(m))).strftime(AADM_TIME_FORMAT)[:-3] for m in ms]
    data: dict[str, object] = {"time": stamps}
    data.update({f"snr_{k.lower()}": snr[:, j] for j, k in enumerate(keys)})
    data.update({"Longitude": pos["lon_deg"], "Latitude": pos["lat_deg"], "Altitude": pos["alt_m"]})
    for name, values in (extra or {}).items():
        if name.lower() in {c.lower() for c in data}:
            raise ValueError(f"extra column {name!r} clashes with a trace column")
        arr = np.asarray(values)
        if arr.shape != t.shape:
            raise ValueError(f"extra column {name!r} has shape {arr.shape}, expected {t.shape}")
        data[name] = arr
    return _write_csv(path, pd.DataFrame(data))


def write_dt_export(
    path: str | os.PathLike[str],
    time_s: np.ndarray,
    snr_db: np.ndarray,
    columns: Sequence[str],
    x_m: np.ndarray,
    y_m: np.ndarray,
    z_m: np.ndarray,
) -> Path:
    """Write a digital-twin export that :func:`read_trace` reads back.

    Args:
        path: output CSV file (overwritten).
        time_s: (S,) seconds, strictly increasing (written as given, not shifted).
        snr_db: (S, C) SNR in dB; NaN is written as ``-99``. Finite values must be
            above -99 dB, which would otherwise read back as missing.
        columns: (C,) sensor names; written as upper-case keys (``snr_lw1`` -> ``LW1``),
            which must not be ``TIME``, ``X``, ``Y`` or ``HEIGHT``.
        x_m, y_m: (S,) metres east/north of the origin.
        z_m: (S,) metres (``Height``).

    Returns:
        The written path.
    """
    t, snr, keys, pos = _writer_arrays(time_s, snr_db, columns, x_m=x_m, y_m=y_m, z_m=z_m)
    reserved = {n.upper() for n in _DT_REQUIRED}
    clash = [k for k in keys if k in reserved]
    if clash:
        raise ValueError(f"sensor names {clash} clash with digital-twin columns {_DT_REQUIRED}")
    if (snr <= DT_MISSING).any():
        raise ValueError(f"snr_db values <= {DT_MISSING:g} dB would read back as missing")
    data: dict[str, object] = {"Time": t}
    filled = np.where(np.isnan(snr), DT_MISSING, snr)
    data.update({k: filled[:, j] for j, k in enumerate(keys)})
    data.update({"X": pos["x_m"], "Y": pos["y_m"], "Height": pos["z_m"]})
    return _write_csv(path, pd.DataFrame(data))
