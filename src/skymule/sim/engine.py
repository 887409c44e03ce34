"""The reference engine for fixed trajectories: one mission, one policy, one log.

This is the readable reference; the batched engine (:mod:`skymule.sim.batch`) must agree with
it value for value. Every slot t (``docs/contract.md``):

1. the UAV is at r_t (the start of the slot) and observes SNR, rate and buffers there;
2. the policy returns an action: whom to serve, whether to hover;
3. the served sensor i delivers y = min(R_i * dt, Q_i) bits (:func:`contract.served_bits`);
4. the UAV advances one track sample unless it hovers (holding at the end of a planned
   path; a recorded trace ends the mission when it is used up).

:class:`FixedFlight` is the engine as a state machine (``observe`` / ``apply``), for callers
that drive it slot by slot (learning environments, live agents); :func:`run_fixed` is the
loop that hands each observation to a policy.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from skymule.errors import SkymuleError
from skymule.policies.base import Action, Observation, Policy
from skymule.sim import contract
from skymule.sim.context import mission_context
from skymule.sim.contract import NO_SENSOR
from skymule.sim.faulting import delivered_sensor, fault_fields, slot_faults
from skymule.sim.log import MissionLog
from skymule.world import Mission

__all__ = ["NO_SENSOR", "FixedFlight", "MissionLog", "check_serve", "run_fixed"]


def check_serve(serve: int | None, n_sensors: int, who: str) -> int:
    """The served sensor index of an action (NO_SENSOR for None); SkymuleError if invalid."""
    if serve is None:
        return NO_SENSOR
    if isinstance(serve, bool) or not isinstance(serve, int | np.integer):
        raise SkymuleError(
            f"policy {who!r} chose sensor {serve!r}; allowed: 0..{n_sensors - 1} or None"
        )
    if not 0 <= int(serve) < n_sensors:
        raise SkymuleError(
            f"policy {who!r} chose sensor {serve}; allowed: 0..{n_sensors - 1} or None"
        )
    return int(serve)


def _frozen(values: np.ndarray) -> np.ndarray:
    values.flags.writeable = False
    return values


class ServingFlight:
    """What every flight does with an action's ``serve``: check it, close the download window,
    take the bits through the contract, then log the slot (:meth:`record`, per engine).

    A subclass keeps ``mission``, ``slot`` and the buffers ``_remaining`` and gives
    :attr:`rate_bps` and :meth:`record`.
    """

    mission: Mission
    slot: int
    _remaining: np.ndarray

    @property
    def rate_bps(self) -> np.ndarray:
        """(N,) rates [bit/s] a served sensor delivers at in the current slot."""
        raise NotImplementedError

    def record(self, action: Action, sensor: int, bits: float) -> None:
        """Log the slot (``sensor`` served, ``bits`` already taken) and move on."""
        raise NotImplementedError

    def windowed(self, sensor: int) -> int:
        """``sensor``, or NO_SENSOR once the download window has closed."""
        window = self.mission.window_slots
        return NO_SENSOR if window is not None and self.slot >= window else sensor

    def apply(self, action: Action, who: str = "policy") -> float:
        """Apply ``action`` to the slot last observed; returns the bits downloaded."""
        sensor = self.windowed(check_serve(action.serve, self.mission.n_sensors, who))
        rate = float(self.rate_bps[sensor]) if sensor != NO_SENSOR else 0.0
        bits = contract.take_one(self._remaining, sensor, rate, self.mission.slot_s)
        self.record(action, sensor, bits)
        return bits


class FixedFlight(ServingFlight):
    """One fixed-trajectory mission in progress (planned path or recorded trace).

    Call :meth:`observe`, then :meth:`apply` with the action, until :attr:`done`; then
    :meth:`log`. The Mission is only read.
    """

    def __init__(self, mission: Mission, buffers_bit: np.ndarray | None = None) -> None:
        track = mission.track
        if track is None:
            raise SkymuleError("run_fixed needs a fixed trajectory (trajectory.mode = 'fixed')")
        self.mission = mission
        self._track = track
        # SNR and rates for every track sample, computed once
        self._rates = _frozen(mission.rate_bps(track.snr_db))
        self._snr_seen = _frozen(np.nan_to_num(track.snr_db, nan=-np.inf))
        # buffers_bit: a (N,) array shared with other UAVs (sim.fleet), updated in place
        self._remaining = (
            np.array(mission.buffers_bit, float) if buffers_bit is None else buffers_bit
        )
        self.slot = 0
        self._sample = 0
        self._rate_now = self._rates[0]
        self._samples: list[int] = []
        self._served: list[int] = []
        self._downloaded: list[float] = []
        self._remaining_after: list[np.ndarray] = []
        self._hovering: list[bool] = []
        # faults (docs/faults.md): None on a fault-free mission, which then never reads them
        self._faults = mission.faults
        self._deliverable = None if mission.faults is None else mission.faults.deliverable()
        self._chosen: list[int] = []
        self._progress = 0.0  # wind: share of the next track sample reached so far

    @property
    def done(self) -> bool:
        """True once the mission is over (all slots run, or a recorded trace used up)."""
        return self.slot >= self.mission.n_slots or self._sample >= self._track.n_samples

    def observe(self) -> Observation:
        """What the UAV sees at the start of the current slot."""
        sample, fading = self._sample, self.mission.fading_db
        snr_now, self._rate_now = self._snr_seen[sample], self._rates[sample]
        if fading is not None:
            snr_now = _frozen(self._snr_seen[sample] + fading[self.slot])
            self._rate_now = _frozen(self.mission.rate_bps(snr_now))
        position, rate_seen = self._track.position_m[sample], self._rate_now
        if self._faults is not None and self._deliverable is not None:
            # the policy sees the faulty SNR and position; _rate_now (what serving yields)
            # stays the TRUE rate, 0 where a fault blocks the link
            now = slot_faults(self._faults, self._deliverable, self.slot, snr_now, self._rate_now)
            snr_now, self._rate_now = now.snr_seen_db, now.deliver_bps
            rate_seen = _frozen(self.mission.rate_bps(snr_now))
            position = _frozen(position + now.position_error_m)
        return Observation(
            slot=self.slot,
            position_m=position,
            snr_db=snr_now,
            rate_bps=rate_seen,
            remaining_bit=self._remaining.copy(),
        )

    @property
    def rate_bps(self) -> np.ndarray:
        """(N,) rates [bit/s] a served sensor delivers at in the current slot (the observed
        rates without faults; under faults the true rate, 0 where a fault blocks the link)."""
        return self._rate_now

    def record(self, action: Action, sensor: int, bits: float) -> None:
        """Log the slot (``sensor`` served, ``bits`` already taken) and move on the track."""
        self._samples.append(self._sample)
        if self._deliverable is not None:
            self._chosen.append(sensor)
            sensor = delivered_sensor(self._deliverable, self.slot, sensor)
        self._served.append(sensor)
        self._downloaded.append(bits)
        self._remaining_after.append(self._remaining.copy())
        self._hovering.append(bool(action.hover))
        if not action.hover and self._wind_reaches_next_sample():
            last = self._track.n_samples - 1
            self._sample = (
                min(self._sample + 1, last) if self._track.hold_at_end else (self._sample + 1)
            )
        self.slot += 1

    def _wind_reaches_next_sample(self) -> bool:
        """False while a wind keeps the UAV short of the next track sample.

        Progress advances by achieved/commanded of a sample per slot (``docs/faults.md``);
        the UAV holds the current sample until a whole sample is reached.
        """
        wind = None if self._faults is None else self._faults.wind
        nxt = self._sample + 1
        if wind is None or nxt >= self._track.n_samples:
            return True
        commanded = self._track.position_m[nxt, :2] - self._track.position_m[self._sample, :2]
        length = float(np.hypot(*commanded))
        if length == 0.0:
            return True
        slot_s = self.mission.slot_s
        airspeed = max(self.mission.max_speed_mps, length / slot_s)
        achieved = wind.achieved_step_m(commanded, slot_s, airspeed)
        self._progress += float(np.hypot(*achieved)) / length
        if self._progress < 1.0 - 1e-9:
            return False
        self._progress = max(self._progress - 1.0, 0.0)
        return True

    def log(self, policy: str) -> MissionLog:
        """The mission log of the slots run so far."""
        index = np.asarray(self._samples, int)
        affected, chosen = fault_fields(self.mission.faults, self._chosen, index.size)
        return track_log(
            self.mission,
            policy,
            index,
            min(self._sample, self._track.n_samples - 1),
            self._rates,
            served=np.asarray(self._served, int),
            downloaded_bit=np.asarray(self._downloaded, float),
            remaining_bit=np.asarray(self._remaining_after, float).reshape(
                -1, self.mission.n_sensors
            ),
            hovering=np.asarray(self._hovering, bool),
            affected=affected,
            chosen=chosen,
        )


def log_fields(mission: Mission, policy: str) -> dict[str, Any]:
    """The :class:`MissionLog` fields every engine copies from the mission."""
    return {
        "policy": policy,
        "sensor_names": mission.sensor_names,
        "slot_s": mission.slot_s,
        "buffers_bit": mission.buffers_bit.copy(),
        "home_m": mission.home_m,
        "hover_points_m": mission.hover_points_m,
        "visit_radius_m": mission.visit_radius_m,
        "aadm_window_s": mission.score_window_s,
    }


def track_log(
    mission: Mission,
    policy: str,
    index: np.ndarray,
    end_sample: int,
    rates_bps: np.ndarray,
    **slots: Any,
) -> MissionLog:
    """A fixed-trajectory log: position, SNR and rate read off the track at samples ``index``
    (per-slot fading added), the rest (served, downloads, ...) given per slot in ``slots``."""
    track = mission.track
    assert track is not None
    snr_log, rate_log = track.snr_db[index], rates_bps[index]
    if mission.fading_db is not None:
        snr_log = snr_log + mission.fading_db[: index.size]
        rate_log = mission.rate_bps(snr_log)
    return MissionLog(
        **log_fields(mission, policy),
        position_m=track.position_m[index],
        end_position_m=track.position_m[end_sample].copy(),
        snr_db=snr_log,
        rate_bps=rate_log,
        **slots,
    )


class Flight(Protocol):
    """What :func:`drive` needs of an engine in progress (``FixedFlight``, ``AutonomousFlight``)."""

    mission: Mission

    @property
    def done(self) -> bool: ...

    def observe(self) -> Observation: ...

    def apply(self, action: Action, who: str = "policy") -> float: ...

    def log(self, policy: str) -> MissionLog: ...


def drive(flight: Flight, policy: Policy) -> MissionLog:
    """Hand each observation of ``flight`` to ``policy`` until the mission ends; its log."""
    policy.reset(mission_context(flight.mission))
    while not flight.done:
        flight.apply(policy.act(flight.observe()), policy.name)
    return flight.log(policy.name)


def run_fixed(mission: Mission, policy: Policy) -> MissionLog:
    """Run a fixed-trajectory mission (planned path or recorded trace) under ``policy``."""
    return drive(FixedFlight(mission), policy)
