"""Digital-twin exports: ``Time, <sensor>..., X, Y, Height``.

``Time`` is in seconds, ``X``/``Y`` metres east/north of the scenario origin, ``Height`` in
metres. Every other named column is an SNR column in dB; values ``<= -99`` (the exporter's
missing marker) and empty cells become NaN.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from skymule.io.traces.table import is_ignored
from skymule.io.traces.trace import Trace, TraceError
from skymule.io.traces.writing import write_csv, writer_arrays

DT_MISSING = -99.0
"""Digital-twin missing-sample marker (dB); any SNR value <= this is read as NaN."""

DT_REQUIRED = ("Time", "X", "Y", "Height")
"""Required columns, time first (matched case-insensitively)."""


def snr_columns(label: str, header: Sequence[str]) -> list[int]:
    """Indices of the sensor columns: every named column besides Time, X, Y, Height."""
    reserved = {n.lower() for n in DT_REQUIRED}
    idx = [i for i, h in enumerate(header) if h.lower() not in reserved and not is_ignored(h)]
    if not idx:
        raise TraceError(
            f"{label}: no SNR columns (expected sensor columns besides Time, X, Y, Height)"
        )
    return idx


def build_trace(
    label: str,
    time_s: np.ndarray,
    snr_db: np.ndarray,
    columns: tuple[str, ...],
    pos: Mapping[str, np.ndarray],
) -> Trace:
    """The trace of an export (values at or below the missing marker become NaN)."""
    snr = np.where(snr_db <= DT_MISSING, np.nan, snr_db)
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
    t, snr, keys, pos = writer_arrays(time_s, snr_db, columns, x_m=x_m, y_m=y_m, z_m=z_m)
    reserved = {n.upper() for n in DT_REQUIRED}
    clash = [k for k in keys if k in reserved]
    if clash:
        raise ValueError(f"sensor names {clash} clash with digital-twin columns {DT_REQUIRED}")
    if (snr <= DT_MISSING).any():
        raise ValueError(f"snr_db values <= {DT_MISSING:g} dB would read back as missing")
    data: dict[str, object] = {"Time": t}
    filled = np.where(np.isnan(snr), DT_MISSING, snr)
    data.update({k: filled[:, j] for j, k in enumerate(keys)})
    data.update({"X": pos["x_m"], "Y": pos["y_m"], "Height": pos["z_m"]})
    return write_csv(path, pd.DataFrame(data))
