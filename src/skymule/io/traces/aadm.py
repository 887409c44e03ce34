"""AADM merged logs: ``time, snr_<sensor>..., Longitude, Latitude, Altitude`` (+ ignored columns).

``time`` is an ISO-8601 timestamp such as ``2025-05-24 16:19:31.186`` (plain numbers are
taken as seconds), SNR is in dB, ``Altitude`` is metres relative to take-off. Deep drops
(about -50 dB) are real link losses and are kept as values; empty SNR cells become NaN.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd

from skymule.io.traces.table import Table, check_range
from skymule.io.traces.trace import Trace, TraceError, listing
from skymule.io.traces.writing import write_csv, writer_arrays
from skymule.limits import MAX_ALTITUDE_M

AADM_TIME_FORMAT = "%Y-%m-%d %H:%M:%S.%f"
AADM_REQUIRED = ("time", "Longitude", "Latitude", "Altitude")
"""Required columns, time first (matched case-insensitively)."""


def snr_columns(label: str, header: Sequence[str]) -> list[int]:
    """Indices of the ``snr_<sensor>`` columns."""
    idx = [i for i, h in enumerate(header) if h.lower().startswith("snr_") and len(h) > 4]
    if not idx:
        raise TraceError(
            f"{label}: no SNR columns (expected columns named snr_<sensor>; "
            f"columns present: {listing(header)})"
        )
    return idx


def build_trace(
    label: str,
    table: Table,
    where: Mapping[str, int],
    time_s: np.ndarray,
    snr_db: np.ndarray,
    columns: tuple[str, ...],
    pos: Mapping[str, np.ndarray],
) -> Trace:
    """The trace of a merged log (latitude/longitude checked against their ranges)."""
    check_range(label, table, where["Latitude"], pos["Latitude"], 90.0)
    check_range(label, table, where["Longitude"], pos["Longitude"], 180.0)
    check_range(label, table, where["Altitude"], pos["Altitude"], MAX_ALTITUDE_M, "m")
    return Trace(
        path=label,
        format="aadm",
        time_s=time_s,
        snr_db=snr_db,
        columns=columns,
        lat_deg=pos["Latitude"],
        lon_deg=pos["Longitude"],
        x_m=None,
        y_m=None,
        z_m=pos["Altitude"],
    )


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
    t, snr, keys, pos = writer_arrays(
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
    return write_csv(path, pd.DataFrame(data))
