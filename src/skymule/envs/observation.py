"""The learning environments' observation and action encodings (pure numpy, no gymnasium).

One layout is shared by the single environment (:mod:`skymule.envs.datamule`), the vectorised
one (:mod:`skymule.envs.vector`) and the ``rl:`` policy that runs a trained model inside the
engine (:mod:`skymule.policies.rl`), so that what an agent was trained on is exactly what it
sees when it flies a mission.

Observation, float32, shape ``(3 + 5 N,)`` for N sensors, in this order:

=================  =====  ==========================================================
field              shape  unit / meaning
=================  =====  ==========================================================
position           2      UAV x (east), y (north) [m] in the scenario's local frame
time left          1      (T - t) * dt [s] at the start of slot t
SNR                N      SNR to each sensor [dB], clipped to [SNR_FLOOR_DB,
                          SNR_CEIL_DB]; -inf / NaN (no link) -> SNR_FLOOR_DB
rate               N      rate to each sensor [Mbit/s]
remaining          N      data left in each buffer [Mbit]
hover offset       2 N    (dx, dy) from the UAV to each sensor's hover point [m]
                          (autonomous; fixed paths: to the sensor; 0 when unknown)
=================  =====  ==========================================================

The hover offsets are beyond the minimum (position, time, SNR, rate, data): with them an
agent knows where the sensors are, which it otherwise could only infer from SNR gradients.

Action (``move="headings"``, the default): two integers ``(serve, heading)``. ``serve`` = 0
serves no sensor, k in 1..N serves sensor k-1. ``heading`` = 0 stays, h in 1..8 flies toward
the point ``max_step_m`` away at angle (h-1) * 45 deg counter-clockwise from east (1 = east,
3 = north, 5 = west, 7 = south). ``move="velocity"``: a dict ``{"serve": int, "velocity":
(vx, vy)}`` with the velocity a fraction of the speed cap (norm clipped to 1; (0, 0) stays).
On fixed trajectories a move only decides whether the UAV advances along the path (any
heading but 0, any non-zero velocity) or hovers (heading 0, zero velocity).
"""

from __future__ import annotations

import numpy as np

from skymule.rules.contract import NO_SENSOR
from skymule.units import BITS_PER_MBIT

#: SNR values are clipped to this range [dB]; no link (-inf, NaN) maps to the floor.
SNR_FLOOR_DB = -30.0
SNR_CEIL_DB = 80.0

#: Finite upper bounds of the time [s], rate [Mbit/s] and data [Mbit] fields.
TIME_LIMIT_S = 1.0e9
RATE_LIMIT_MBPS = 1.0e6
DATA_LIMIT_MBIT = 1.0e12

#: Number of heading actions: stay + 8 compass directions.
N_HEADINGS = 9

#: Bound on the position and offset fields [m] (the unfenced square is 1e6 m half-width).
POSITION_LIMIT_M = 4.0e6


MOVES = ("headings", "velocity")

_ANGLES = np.deg2rad(45.0 * np.arange(N_HEADINGS - 1))
#: (9, 2) unit vectors of the headings; row 0 (stay) is zero.
HEADING_UNIT = np.vstack([np.zeros(2), np.column_stack([np.cos(_ANGLES), np.sin(_ANGLES)])])


def observation_bounds(n_sensors: int) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) float32 bounds of the observation vector (see the module docstring)."""
    n = n_sensors
    low = np.concatenate(
        [
            np.full(2, -POSITION_LIMIT_M),
            [0.0],
            np.full(n, SNR_FLOOR_DB),
            np.zeros(n),
            np.zeros(n),
            np.full(2 * n, -POSITION_LIMIT_M),
        ]
    )
    high = np.concatenate(
        [
            np.full(2, POSITION_LIMIT_M),
            [TIME_LIMIT_S],
            np.full(n, SNR_CEIL_DB),
            np.full(n, RATE_LIMIT_MBPS),
            np.full(n, DATA_LIMIT_MBIT),
            np.full(2 * n, POSITION_LIMIT_M),
        ]
    )
    return low.astype(np.float32), high.astype(np.float32)


def encode(
    position_m: np.ndarray,
    time_left_s: np.ndarray,
    snr_db: np.ndarray,
    rate_bps: np.ndarray,
    remaining_bit: np.ndarray,
    anchors_m: np.ndarray,
) -> np.ndarray:
    """(B, 3 + 5N) float32 observations of B missions.

    Args:
        position_m: (B, 2) UAV positions [m].
        time_left_s: (B,) time left [s].
        snr_db: (B, N) SNR [dB] (-inf / NaN: no link).
        rate_bps: (B, N) rates [bit/s].
        remaining_bit: (B, N) buffers [bit].
        anchors_m: (B, N, 2) hover points (or sensor positions) [m]; NaN where unknown.
    """
    snr = np.clip(np.nan_to_num(snr_db, nan=SNR_FLOOR_DB, neginf=SNR_FLOOR_DB), SNR_FLOOR_DB,
                  SNR_CEIL_DB)  # fmt: skip
    offset = np.nan_to_num(anchors_m - position_m[:, None, :], nan=0.0)
    offset = np.clip(offset, -POSITION_LIMIT_M, POSITION_LIMIT_M)
    batch = position_m.shape[0]
    return np.concatenate(
        [
            np.clip(position_m, -POSITION_LIMIT_M, POSITION_LIMIT_M),
            np.asarray(time_left_s, float).reshape(batch, 1),
            snr,
            rate_bps / BITS_PER_MBIT,
            remaining_bit / BITS_PER_MBIT,
            offset.reshape(batch, -1),
        ],
        axis=1,
    ).astype(np.float32)


#: Divisors of the scaled observation (``scaled=True``): position and offsets per km, time per
#: 10 min, SNR per 50 dB, rate per 10 Mbit/s, data per Gbit, so every field is of order 1 (what
#: neural-network policies learn well from; the ``rl:`` policy applies the same scale).
SCALE = {"position": 1000.0, "time": 600.0, "snr": 50.0, "rate": 10.0, "data": 1000.0}


def scale_vector(n_sensors: int) -> np.ndarray:
    """(3 + 5N,) float32 divisors that turn an observation into the scaled one."""
    n = n_sensors
    parts = [
        np.full(2, SCALE["position"]),
        np.full(1, SCALE["time"]),
        np.full(n, SCALE["snr"]),
        np.full(n, SCALE["rate"]),
        np.full(n, SCALE["data"]),
        np.full(2 * n, SCALE["position"]),
    ]
    return np.concatenate(parts).astype(np.float32)


def serve_index(serve: int) -> int:
    """Engine sensor index of the action's ``serve`` field (0 -> NO_SENSOR, k -> k - 1)."""
    return NO_SENSOR if serve == 0 else serve - 1


def heading_step_m(heading: np.ndarray, max_step_m: float | np.ndarray) -> np.ndarray:
    """(B, 2) displacement [m] the headings ask for: ``max_step_m`` along each heading."""
    return HEADING_UNIT[heading] * np.asarray(max_step_m, float).reshape(-1, 1)


def velocity_step_m(velocity: np.ndarray, max_step_m: float) -> np.ndarray:
    """(2,) displacement [m] of a velocity given as a fraction of the speed cap (norm <= 1)."""
    v = np.asarray(velocity, float).reshape(2)
    norm = float(np.hypot(v[0], v[1]))
    if norm > 1.0:
        v = v / norm
    return v * max_step_m
