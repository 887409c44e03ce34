"""Shared checks of the trace writers (:mod:`.aadm`, :mod:`.dt`)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from skymule.io import atomic
from skymule.io.traces.trace import normalise_column


def writer_arrays(
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


def write_csv(path: str | os.PathLike[str], frame: pd.DataFrame) -> Path:
    return atomic.write_with(
        Path(path),
        lambda tmp: frame.to_csv(tmp, index=False, na_rep="", lineterminator="\n"),
    )
