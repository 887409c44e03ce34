"""Mission metrics: pure functions of a :class:`~skymule.engine.MissionLog`."""

from __future__ import annotations

from typing import Any

import numpy as np

from skymule.engine import NO_SENSOR, MissionLog

BITS_PER_MBIT = 1e6


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
    }
