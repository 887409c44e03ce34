"""The mission log: what happened in one mission, slot by slot, in SI units.

Engines write it; metrics, run folders and figures read it. It is immutable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skymule.sim.contract import NO_SENSOR

__all__ = ["NO_SENSOR", "MissionLog"]

_ARRAY_FIELDS = (
    "buffers_bit",
    "position_m",
    "end_position_m",
    "snr_db",
    "rate_bps",
    "served",
    "downloaded_bit",
    "remaining_bit",
    "hovering",
    "home_m",
    "hover_points_m",
    "target",
    "affected",
    "chosen",
    "battery_used_j",
)


@dataclass(frozen=True)
class MissionLog:
    """What happened, slot by slot (T' <= T slots; a trace may end the mission early).

    Attributes:
        policy: policy name.
        sensor_names: (N,) names.
        slot_s: slot length [s].
        buffers_bit: (N,) initial buffers [bit].
        position_m: (T', 3) UAV position at the start of each slot [m].
        end_position_m: (3,) UAV position after the last slot [m].
        snr_db: (T', N) SNR observed at the start of each slot [dB] (NaN: no sample).
        rate_bps: (T', N) rate to each sensor [bit/s].
        served: (T',) served sensor index, or NO_SENSOR.
        downloaded_bit: (T',) bits downloaded in each slot.
        remaining_bit: (T', N) buffers after each slot's download [bit].
        hovering: (T',) True where the UAV held its position after the slot by choice.
        home_m: (2,) home point [m] (trajectory.home or the site origin), or None.
        hover_points_m: (N, 2) point inside the geofence each sensor is served from [m]
            (NaN where unknown), or None.
        visit_radius_m: a sensor counts as visited within this distance of its hover point [m].
        target: autonomous: (T',) sensor the policy was heading for in each slot, or
            NO_SENSOR; None on fixed trajectories.
        aadm_window_s: the AADM download window the score counts downloads in [s].
        affected: (T',) True where a per-slot fault touched the slot (``[[faults]]``), or
            None for a fault-free mission.
        chosen: (T',) the sensor the policy chose (``served`` is NO_SENSOR where a fault kept
            it from delivering), or None for a fault-free mission (then equal to ``served``).
        battery_used_j: (T',) propulsion energy the battery has paid after each slot [J]
            (``kind = "battery"``: power at the airspeed, docs/faults.md), or None without a
            battery fault.
    """

    policy: str
    sensor_names: tuple[str, ...]
    slot_s: float
    buffers_bit: np.ndarray
    position_m: np.ndarray
    end_position_m: np.ndarray
    snr_db: np.ndarray
    rate_bps: np.ndarray
    served: np.ndarray
    downloaded_bit: np.ndarray
    remaining_bit: np.ndarray
    hovering: np.ndarray
    home_m: np.ndarray | None = None
    hover_points_m: np.ndarray | None = None
    visit_radius_m: float = 50.0
    target: np.ndarray | None = None
    aadm_window_s: float = 500.0
    affected: np.ndarray | None = None
    chosen: np.ndarray | None = None
    battery_used_j: np.ndarray | None = None

    @property
    def n_slots(self) -> int:
        return int(self.served.shape[0])

    def __post_init__(self) -> None:
        for name in _ARRAY_FIELDS:
            value = getattr(self, name)
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
