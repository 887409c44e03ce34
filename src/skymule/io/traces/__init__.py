"""Readers and writers for recorded UAV flight traces (AERPAW testbed / digital twin).

Two CSV formats are recognised from their header (column names are matched
case-insensitively, surrounding whitespace and a UTF-8 BOM are ignored); one module each:

``aadm``  AADM merged log (:mod:`.aadm`)
    ``time, snr_<sensor>..., Longitude, Latitude, Altitude`` plus any other columns
    (attitude, velocity, battery, ...), which are ignored.

``dt``  Digital-twin export (:mod:`.dt`)
    ``Time, <sensor>..., X, Y, Height``; ``-99`` marks a missing sample.

Columns with an empty name (e.g. an index written by ``DataFrame.to_csv``) or named
``Unnamed: <n>`` are ignored in both formats. The shared CSV layer is :mod:`.table`, the
time column :mod:`.timestamps`, AADM volume files :mod:`.volumes`.

Everything that is wrong with a user's file raises :class:`TraceError`, whose message
is one line: ``<file>: <what is wrong> (<what is allowed>)``. Row numbers in messages
are file line numbers (the header is row 1), as shown by editors and spreadsheets.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from skymule.io.traces import aadm, dt
from skymule.io.traces.aadm import AADM_REQUIRED, AADM_TIME_FORMAT, write_aadm_log
from skymule.io.traces.dt import DT_MISSING, DT_REQUIRED, write_dt_export
from skymule.io.traces.table import Table, check_range, locate, numbers, read_table
from skymule.io.traces.timestamps import time_column
from skymule.io.traces.trace import (
    ToLocal,
    Trace,
    TraceError,
    TraceFormat,
    listing,
    normalise_column,
    positions_local,
    quote,
)
from skymule.io.traces.volumes import read_volumes
from skymule.limits import MAX_ALTITUDE_M, MAX_COORDINATE_M, MAX_SNR_DB
from skymule.registry import Registry

__all__ = [
    "AADM_TIME_FORMAT",
    "DT_MISSING",
    "TRACE_FORMATS",
    "ToLocal",
    "Trace",
    "TraceError",
    "TraceFormat",
    "normalise_column",
    "positions_local",
    "read_trace",
    "read_volumes",
    "write_aadm_log",
    "write_dt_export",
]

_UNRECOGNISED = (
    "unrecognised format: expected AADM merged-log columns "
    "(time, snr_<name>..., Longitude, Latitude, Altitude) "
    "or digital-twin columns (Time, <names>..., X, Y, Height)"
)


def _detect(label: str, header: Sequence[str]) -> TraceFormat:
    lower = {h.lower() for h in header}
    has_snr = any(h.startswith("snr_") and len(h) > 4 for h in lower)
    aadm_score = sum(n.lower() in lower for n in AADM_REQUIRED[1:]) + int(has_snr)
    dt_score = sum(n.lower() in lower for n in DT_REQUIRED[1:])
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
    idx = aadm.snr_columns(label, header) if fmt == "aadm" else dt.snr_columns(label, header)
    seen: dict[str, int] = {}
    for i in idx:
        key = normalise_column(header[i])
        if key in seen:
            raise TraceError(
                f"{label}: columns {quote(header[seen[key]])} and {quote(header[i])} "
                f"both name sensor {quote(key)}"
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
                f"{label}: column {quote(shown)} is missing (columns present: {listing(header)})"
            )
        if by_key[key] not in chosen:
            chosen.append(by_key[key])
    return chosen


def _check_snr(
    label: str, table: Table, snr_idx: Sequence[int], snr: np.ndarray, fmt: TraceFormat
) -> None:
    """Every SNR sample within +-MAX_SNR_DB dB (a digital-twin value <= -99 dB is its
    missing-sample marker, so only the top is bounded there); one line naming the cell."""
    low = -np.inf if fmt == "dt" else None
    for j, col in enumerate(snr_idx):
        check_range(label, table, col, snr[:, j], MAX_SNR_DB, "dB", low=low, value_unit="dB")


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
    table = read_table(label, Path(path))
    header = table.header
    fmt = _detect(label, header)
    required: tuple[str, ...] = TRACE_FORMATS.meta(fmt, "required")
    where = {name: locate(label, header, name) for name in required}
    snr_idx = _snr_columns(label, header, fmt)
    if sensors is not None:
        snr_idx = _select_sensors(label, header, snr_idx, sensors, fmt)
    if table.cells.shape[0] == 0:
        raise TraceError(f"{label}: no data rows (the file has only a header)")

    time_s = time_column(label, table, where[required[0]], fmt)
    snr = np.column_stack([numbers(label, table, i, missing_ok=True) for i in snr_idx]).reshape(
        len(time_s), len(snr_idx)
    )
    _check_snr(label, table, snr_idx, snr, fmt)
    pos = {name: numbers(label, table, where[name], missing_ok=False) for name in required[1:]}
    columns = tuple(normalise_column(header[i]) for i in snr_idx)
    if fmt == "aadm":
        return aadm.build_trace(label, table, where, time_s, snr, columns, pos)
    for name, limit in (
        ("X", MAX_COORDINATE_M),
        ("Y", MAX_COORDINATE_M),
        ("Height", MAX_ALTITUDE_M),
    ):
        check_range(label, table, where[name], pos[name], limit, "m")
    return dt.build_trace(label, time_s, snr, columns, pos)


TRACE_FORMATS: Registry[object] = Registry("trace format")
"""Recorded-flight formats: name -> writer; ``required`` (metadata) lists the columns the
reader needs besides the SNR columns. :func:`read_trace` detects the format from the header."""

TRACE_FORMATS.register("aadm", write_aadm_log, required=AADM_REQUIRED, title="AADM merged log")
TRACE_FORMATS.register("dt", write_dt_export, required=DT_REQUIRED, title="digital-twin export")
