"""Fixed paths and tracks.

A fixed path is a list of waypoints flown at a nominal speed. The engine does not fly the
waypoints directly: it walks a :class:`Track`, the path sampled every ``slot_s`` of nominal
flight time (or a recorded flight, one trace sample per slot). In a slot in which the UAV
does not hover it advances one sample; hovering repeats the current one.
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skymule.errors import ScenarioError
from skymule.rules.contract import slots_to_cover


@dataclass(frozen=True)
class Track:
    """Samples the UAV walks through on a fixed trajectory.

    Attributes:
        position_m: (K, 3) sample positions, local metres (x east, y north, z up).
        snr_db: (K, N) SNR to each sensor at each sample [dB]; NaN = no sample.
        hold_at_end: True for a planned path (the UAV holds at the end point once it gets
            there); False for a recorded trace (the mission ends when the UAV moves past
            the last sample).
    """

    position_m: np.ndarray
    snr_db: np.ndarray
    hold_at_end: bool

    @property
    def n_samples(self) -> int:
        return int(self.position_m.shape[0])


def path_length_m(waypoints_m: np.ndarray) -> float:
    """Length [m] of the polyline through the waypoints (W, 3)."""
    return float(np.sum(np.linalg.norm(np.diff(waypoints_m, axis=0), axis=1)))


def sample_path(waypoints_m: np.ndarray, speed_mps: float, slot_s: float) -> np.ndarray:
    """Positions (K, 3) after k slots of nominal flight, k = 0..K-1, ending at the last waypoint.

    Sample k lies at arc length min(k * speed * slot_s, L) along the polyline of length L;
    K = ceil(L / (speed * slot_s)) + 1, so the last sample is the end point.
    """
    waypoints = np.asarray(waypoints_m, float)
    segment = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
    cumulative = np.concatenate([[0.0], np.cumsum(segment)])
    length = cumulative[-1]
    step = speed_mps * slot_s
    n_samples = int(slots_to_cover(length, step)) + 1 if length > 0 else 1
    arc = np.minimum(np.arange(n_samples) * step, length)
    return np.column_stack([np.interp(arc, cumulative, waypoints[:, axis]) for axis in range(3)])


def read_waypoints_csv(
    path: Path, to_local: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
) -> np.ndarray:
    """Waypoints from CSV with header ``x_m,y_m,z_m`` (local metres) or ``lat,lon,alt``."""
    try:
        with path.open(newline="") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        raise ScenarioError(f"trajectory.waypoints: cannot read {path} ({exc.strerror})") from None
    if not rows:
        raise ScenarioError(f"{path}: empty waypoint file")
    header = [h.strip().lower() for h in rows[0]]
    body = [r for r in rows[1:] if any(cell.strip() for cell in r)]
    try:
        values = np.array([[float(c) for c in r[:3]] for r in body], float)
    except ValueError:
        raise ScenarioError(f"{path}: waypoint rows must hold three numbers") from None
    if header[:3] == ["x_m", "y_m", "z_m"]:
        return values.reshape(-1, 3)
    if header[:3] == ["lat", "lon", "alt"]:
        x_m, y_m = to_local(values[:, 0], values[:, 1])
        return np.column_stack([x_m, y_m, values[:, 2]])
    raise ScenarioError(
        f"{path}: waypoint CSV header {','.join(rows[0])!r}; "
        "allowed: 'x_m,y_m,z_m' or 'lat,lon,alt'"
    )
