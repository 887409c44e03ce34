"""Mission metrics: pure functions of a :class:`~skymule.sim.engine.MissionLog`."""

from __future__ import annotations

from typing import Any

import numpy as np

from skymule.energy import propulsion_power_w
from skymule.sim.engine import NO_SENSOR, MissionLog

BITS_PER_MBIT = 1e6

HEADLINE_METRICS = (
    "total_downloaded_mbit",
    "completion",
    "handovers",
    "hover_time_s",
    "distance_m",
    "energy_kj",
    "aadm_score",
)
"""The summary fields shown in tables and aggregated over sweeps."""

#: AADM challenge scoring (AERPAW AADM rules): mission reference time [s], landing
#: tolerance [m] and penalty per metre beyond it.
AADM_REFERENCE_S = 600.0
AADM_LANDING_TOLERANCE_M = 3.0
AADM_PENALTY_PER_M = 20.0


def step_lengths_m(log: MissionLog) -> np.ndarray:
    """(T',) distance flown during each slot [m] (from r_t to r_{t+1})."""
    after = np.vstack([log.position_m[1:], log.end_position_m[None, :]])
    return np.linalg.norm(after - log.position_m, axis=1)


def handovers(served: np.ndarray) -> int:
    """Times the served sensor changed, over the slots in which some sensor was served."""
    active = served[served != NO_SENSOR]
    return int(np.count_nonzero(active[1:] != active[:-1]))


def per_sensor_downloaded_bit(log: MissionLog) -> np.ndarray:
    """(N,) bits downloaded from each sensor."""
    return log.buffers_bit - (log.remaining_bit[-1] if log.n_slots else log.buffers_bit)


def speed_mps(log: MissionLog) -> np.ndarray:
    """(T',) horizontal-plus-vertical speed flown during each slot [m/s]."""
    return step_lengths_m(log) / log.slot_s


def power_w(log: MissionLog) -> np.ndarray:
    """(T',) rotary-wing propulsion power in each slot [W] (Zeng, Xu & Zhang 2019, eq. 12)."""
    return np.asarray(propulsion_power_w(speed_mps(log)), float).reshape(-1)


def energy_j(log: MissionLog) -> float:
    """Propulsion energy of the mission [J]: sum over slots of P(V_t) * slot_s."""
    return float(power_w(log).sum() * log.slot_s)


def distance_to_home_m(log: MissionLog) -> float:
    """Horizontal distance from the UAV's end position to home [m] (NaN without a home)."""
    if log.home_m is None:
        return float("nan")
    return float(np.hypot(*(log.end_position_m[:2] - log.home_m)))


def visit_order(log: MissionLog) -> list[str]:
    """Sensor names in the order they were first visited.

    Autonomous runs (the log has the policy's ``target``): sensor i is visited at the first
    slot the UAV was heading for it and ended within ``visit_radius_m`` of its hover point
    (the paper's "navigation order", Table II). Fixed runs: a run in which the UAV hovered
    while serving (HGAD) counts a sensor at the first slot it hovered serving it; otherwise
    (Greedy) at the first slot the UAV was within ``visit_radius_m`` of its hover point.
    """
    n_sensors = len(log.sensor_names)
    hovered = log.hovering & (log.served != NO_SENSOR)
    if log.target is not None and log.hover_points_m is not None and log.n_slots:
        after = np.vstack([log.position_m[1:, :2], log.end_position_m[None, :2]])
        offset = after[:, None, :] - log.hover_points_m[None, :, :]
        near = np.hypot(offset[..., 0], offset[..., 1]) <= log.visit_radius_m
        hits = near & (log.target[:, None] == np.arange(n_sensors)[None, :])
    elif hovered.any():
        hits = hovered[:, None] & (log.served[:, None] == np.arange(n_sensors)[None, :])
    elif log.hover_points_m is not None and log.n_slots:
        offset = log.position_m[:, None, :2] - log.hover_points_m[None, :, :]
        hits = np.hypot(offset[..., 0], offset[..., 1]) <= log.visit_radius_m  # NaN -> False
    else:
        return []
    first = np.where(hits.any(axis=0), hits.argmax(axis=0), log.n_slots)
    order = [int(i) for i in np.argsort(first, kind="stable") if first[i] < log.n_slots]
    return [log.sensor_names[i] for i in order]


def completion_time_s(log: MissionLog) -> float | None:
    """End of the slot in which the last buffered bit was downloaded [s]; None if never."""
    if not log.n_slots:
        return 0.0 if not log.buffers_bit.any() else None
    empty = np.flatnonzero(log.remaining_bit.sum(axis=1) <= 0)
    if not log.buffers_bit.any():
        return 0.0
    return float((empty[0] + 1) * log.slot_s) if empty.size else None


def aadm_score(log: MissionLog) -> float:
    """The AADM challenge score.

    100 * downloaded / total, plus max(0, 600 - t) when every buffer was emptied by time t,
    minus 20 per metre the UAV ends more than 3 m from home (no penalty without a home).
    The completion bonus is clipped at 0 so that finishing late never scores below not
    finishing.
    """
    total = float(log.buffers_bit.sum())
    score = 100.0 * float(log.downloaded_bit.sum()) / total if total > 0 else 100.0
    done = completion_time_s(log)
    if done is not None:
        score += max(0.0, AADM_REFERENCE_S - done)
    distance = distance_to_home_m(log)
    if np.isfinite(distance):
        score -= AADM_PENALTY_PER_M * max(0.0, distance - AADM_LANDING_TOLERANCE_M)
    return float(score)


def summarize(log: MissionLog, scenario_name: str) -> dict[str, Any]:
    """The run summary written to ``summary.json`` (Mbit at this edge)."""
    per_sensor = per_sensor_downloaded_bit(log)
    total_buffer = float(log.buffers_bit.sum())
    total = float(log.downloaded_bit.sum())
    names = log.sensor_names
    return {
        "scenario": scenario_name,
        "policy": log.policy,
        "mission_time_s": log.n_slots * log.slot_s,
        "slots": log.n_slots,
        "slot_s": log.slot_s,
        "total_downloaded_mbit": total / BITS_PER_MBIT,
        "total_buffer_mbit": total_buffer / BITS_PER_MBIT,
        "per_sensor_downloaded_mbit": {
            n: float(v) / BITS_PER_MBIT for n, v in zip(names, per_sensor, strict=True)
        },
        "per_sensor_buffer_mbit": {
            n: float(v) / BITS_PER_MBIT for n, v in zip(names, log.buffers_bit, strict=True)
        },
        "completion": total / total_buffer if total_buffer > 0 else 1.0,
        "handovers": handovers(log.served),
        "hover_time_s": float(np.count_nonzero(log.hovering) * log.slot_s),
        "distance_m": float(step_lengths_m(log).sum()),
        "energy_kj": energy_j(log) / 1e3,
        "visit_order": visit_order(log),
        "landed_at_home": bool(distance_to_home_m(log) <= AADM_LANDING_TOLERANCE_M),
        "distance_to_home_m": distance_to_home_m(log),
        "aadm_score": aadm_score(log),
    }
