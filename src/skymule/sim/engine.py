"""The slot loop: one mission, one policy, one log.

This is the readable reference engine. Every slot t:

1. the UAV is at r_t (the start of the slot) and observes SNR, rate and buffers there;
2. the policy returns an action: whom to serve, whether to hover;
3. the served sensor i delivers y = min(R_i * dt, Q_i) bits; nothing else changes buffers;
4. on a fixed trajectory the UAV advances one track sample unless it hovers (holding at the
   end of a planned path; a recorded trace ends the mission when it is used up).

Faster engines (batched over missions) must agree with this one value for value.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from skymule.errors import SkymuleError
from skymule.policies.base import MissionContext, Observation, Policy
from skymule.world import Mission

NO_SENSOR = -1
"""``served`` value for a slot in which no sensor was served."""


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

    @property
    def n_slots(self) -> int:
        return int(self.served.shape[0])


def mission_context(mission: Mission) -> MissionContext:
    track = mission.track
    peak = mission.peak_rate_bps() if track is not None else np.zeros(mission.n_sensors)
    return MissionContext(
        sensor_names=mission.sensor_names,
        slot_s=mission.slot_s,
        n_slots=mission.n_slots,
        buffers_bit=mission.buffers_bit.copy(),
        peak_rate_bps=peak,
        mode=mission.scenario.trajectory.mode,
        sensor_m=mission.sensor_m.copy(),
        track_rate_bps=None if track is None else mission.rate_bps(track.snr_db),
        track_hold_at_end=True if track is None else track.hold_at_end,
    )


def check_serve(serve: int | None, n_sensors: int, policy: Policy) -> int:
    if serve is None:
        return NO_SENSOR
    if not 0 <= int(serve) < n_sensors:
        raise SkymuleError(
            f"policy {policy.name!r} chose sensor {serve}; allowed: 0..{n_sensors - 1} or None"
        )
    return int(serve)


def run_fixed(mission: Mission, policy: Policy) -> MissionLog:
    """Run a fixed-trajectory mission (planned path or recorded trace) under ``policy``."""
    track = mission.track
    if track is None:
        raise SkymuleError("run_fixed needs a fixed trajectory (trajectory.mode = 'fixed')")
    dt = mission.slot_s
    n_sensors = mission.n_sensors
    # SNR and rates for every track sample, computed once before the loop
    rates = mission.rate_bps(track.snr_db)
    snr_seen = np.nan_to_num(track.snr_db, nan=-np.inf)
    fading = mission.fading_db  # (T, N) per-slot fading [dB] on top of the track, or None
    remaining = mission.buffers_bit.astype(float).copy()
    policy.reset(mission_context(mission))

    sample_of_slot: list[int] = []
    served: list[int] = []
    downloaded: list[float] = []
    remaining_after: list[np.ndarray] = []
    hovering: list[bool] = []
    sample = 0
    for slot in range(mission.n_slots):
        if sample >= track.n_samples:
            break  # a recorded trace is used up
        snr_now, rate_now = snr_seen[sample], rates[sample]
        if fading is not None:
            snr_now = snr_seen[sample] + fading[slot]
            rate_now = mission.rate_bps(snr_now)
        observation = Observation(
            slot=slot,
            position_m=track.position_m[sample],
            snr_db=snr_now,
            rate_bps=rate_now,
            remaining_bit=remaining.copy(),
        )
        action = policy.act(observation)
        sensor = check_serve(action.serve, n_sensors, policy)
        bits = 0.0
        if sensor != NO_SENSOR:
            bits = float(min(rate_now[sensor] * dt, remaining[sensor]))
            remaining[sensor] -= bits
        sample_of_slot.append(sample)
        served.append(sensor)
        downloaded.append(bits)
        remaining_after.append(remaining.copy())
        hovering.append(bool(action.hover))
        if not action.hover:
            sample = min(sample + 1, track.n_samples - 1) if track.hold_at_end else sample + 1

    index = np.asarray(sample_of_slot, int)
    end_sample = min(sample, track.n_samples - 1)
    snr_log, rate_log = track.snr_db[index], rates[index]
    if fading is not None:
        snr_log = snr_log + fading[: index.size]
        rate_log = mission.rate_bps(snr_log)
    return MissionLog(
        policy=policy.name,
        sensor_names=mission.sensor_names,
        slot_s=dt,
        buffers_bit=mission.buffers_bit.copy(),
        position_m=track.position_m[index],
        end_position_m=track.position_m[end_sample].copy(),
        snr_db=snr_log,
        rate_bps=rate_log,
        served=np.asarray(served, int),
        downloaded_bit=np.asarray(downloaded, float),
        remaining_bit=np.asarray(remaining_after, float).reshape(-1, n_sensors),
        hovering=np.asarray(hovering, bool),
    )


def run_mission(mission: Mission, policy: Policy) -> MissionLog:
    """Run one mission under ``policy`` (fixed or autonomous trajectory)."""
    # imported here: engine_autonomous builds on this module
    from skymule.sim.autonomous import fixed_geometry_fields, run_autonomous

    if mission.scenario.trajectory.mode == "fixed":
        return replace(run_fixed(mission, policy), **fixed_geometry_fields(mission))
    if mission.scenario.trajectory.mode == "autonomous":
        return run_autonomous(mission, policy)
    raise SkymuleError(
        f"trajectory.mode = {mission.scenario.trajectory.mode!r} is not supported yet; "
        "allowed: fixed"
    )
