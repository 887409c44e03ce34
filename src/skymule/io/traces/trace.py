"""The :class:`Trace` container (one recorded flight as arrays) and its error type."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from skymule.errors import SkymuleError

TraceFormat = Literal["aadm", "dt"]
ToLocal = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]

_MAX_LISTED = 12


class TraceError(SkymuleError):
    """A trace or volume file cannot be used; the message is one user-facing line."""


def normalise_column(name: str) -> str:
    """Sensor key of an SNR column name: ``snr_lw1`` -> ``LW1``, ``lw1`` -> ``LW1``."""
    key = name.strip().upper()
    if key.startswith("SNR_") and len(key) > 4:
        key = key[4:]
    return key


def quote(text: str, limit: int = 40) -> str:
    """Single-quoted, single-line, length-limited rendering of a user value."""
    flat = text.replace("\r", "\\r").replace("\n", "\\n").replace("\t", "\\t")
    if len(flat) > limit:
        flat = flat[: limit - 3] + "..."
    return f"'{flat}'"


def listing(names: Sequence[str]) -> str:
    shown = [n.replace("\n", "\\n") for n in names[:_MAX_LISTED]]
    more = len(names) - len(shown)
    return ", ".join(shown) + (f", ... ({more} more)" if more > 0 else "")


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
                f"{self.path}: no SNR column {quote(name)} (available: {listing(self.columns)})"
            ) from None

    def missing_count(self) -> np.ndarray:
        """(C,) int number of NaN samples in each SNR column."""
        return np.isnan(self.snr_db).sum(axis=0).astype(int)


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
