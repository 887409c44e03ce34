"""Several UAVs in one mission: per-UAV flights over one shared set of buffers.

A fleet is K ordinary flights (:class:`~skymule.sim.engine.FixedFlight` or
:class:`~skymule.sim.autonomous.AutonomousFlight`, each with its own home, altitude, speed,
path, geofence and return-home rule) that share one (N,) buffer array. Every slot
(``docs/fleet.md``):

1. every UAV observes at the start of the slot (same buffers for all);
2. every UAV's policy chooses (one :class:`~skymule.policies.base.Action` per UAV);
3. :func:`contract.fleet_served` settles conflicts -- each sensor serves at most one UAV, the
   higher rate wins, ties to the lower UAV index; a loser serves nothing this slot and the log
   marks it (``lost``);
4. :func:`contract.take_bits` takes the winners' downloads from the shared buffers (the one
   place a download happens, for one UAV or many);
5. every flight records the slot and moves as its own engine does.

A fleet of one UAV is exactly the single-UAV engine (same numbers, value for value).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from skymule.errors import ScenarioError
from skymule.faults.draws import FaultDraws, draw_uav_faults
from skymule.policies.base import Action, Observation
from skymule.radio.channel import FADING_STREAM
from skymule.radio.fading import draw_fading_db
from skymule.scenario import PolicySpec, Scenario
from skymule.sim import contract
from skymule.sim.autonomous import AutonomousFlight, check_wind
from skymule.sim.contract import NO_SENSOR
from skymule.sim.engine import FixedFlight, check_serve
from skymule.sim.log import MissionLog
from skymule.world import Mission, build_mission, check_home_inside, home_xy

Flight = FixedFlight | AutonomousFlight


@dataclass(frozen=True)
class Fleet:
    """K UAVs on one mission: one :class:`Mission` per UAV (same sensors, signal, clock).

    Attributes:
        scenario: the scenario (with its ``[[uavs]]``, or one UAV from ``[trajectory]``).
        names: (K,) UAV names.
        missions: (K,) each UAV's Mission (its home, altitude, speed, path, fading).
        policies: (K,) each UAV's ``[policy]``.
    """

    scenario: Scenario
    names: tuple[str, ...]
    missions: tuple[Mission, ...]
    policies: tuple[PolicySpec, ...]

    @property
    def size(self) -> int:
        return len(self.names)

    @property
    def mode(self) -> str:
        return self.missions[0].mode


def uav_scenario(scenario: Scenario, index: int) -> Scenario:
    """The single-UAV scenario of UAV ``index``: its fields over ``[trajectory]``/``[policy]``."""
    assert scenario.uavs is not None
    uav = scenario.uavs[index]
    trajectory = scenario.trajectory
    update: dict[str, object] = {}
    if uav.home is not None:
        update["home"] = uav.home
    if uav.altitude_m is not None:
        update["altitude_m"] = uav.altitude_m
    if uav.max_speed_mps is not None:
        update["max_speed_mps"] = uav.max_speed_mps
        update["speed_mps"] = uav.max_speed_mps
    if uav.waypoints is not None:
        update["waypoints"] = uav.waypoints
    elif trajectory.mode == "fixed":
        raise ScenarioError(
            f"uavs[{index}] ({uav.name}): waypoints is required with trajectory.mode = 'fixed' "
            "(each UAV flies its own path)"
        )
    return scenario.model_copy(
        update={
            "trajectory": trajectory.model_copy(update=update),
            "policy": uav.policy or scenario.policy,
            "uavs": None,
        }
    )


def uav_fading_db(scenario: Scenario, mission: Mission, index: int) -> np.ndarray | None:
    """UAV ``index``'s small-scale fading: UAV 0 keeps the mission's, others draw their own."""
    if index == 0 or mission.fading_db is None:
        return mission.fading_db
    seed = np.random.SeedSequence(scenario.seed, spawn_key=(FADING_STREAM, index))
    return draw_fading_db(
        scenario.radio, np.random.default_rng(seed), mission.n_slots, mission.n_sensors
    )


def uav_faults(scenario: Scenario, mission: Mission, index: int) -> FaultDraws | None:
    """UAV ``index``'s fault draws: UAV 0 keeps the mission's; the others share the towers'
    (outages, Gilbert-Elliott link states) and draw their own SNR errors, missed polls and GPS
    errors from their own generator (``docs/faults.md``, "Several UAVs")."""
    if index == 0 or not scenario.faults:
        return mission.faults
    draws = draw_uav_faults(
        scenario.faults,
        mission.n_slots,
        mission.sensor_names,
        mission.slot_s,
        scenario.seed,
        index,
    )
    return None if draws.is_empty else draws


def build_fleet(scenario: Scenario) -> Fleet:
    """Resolve a scenario into a :class:`Fleet` (one UAV when it has no ``[[uavs]]``)."""
    if not scenario.uavs:
        mission = build_mission(scenario)
        return Fleet(scenario, ("uav",), (mission,), (scenario.policy,))
    if scenario.signal.source == "trace":
        raise ScenarioError(
            "[[uavs]] needs signal.source = 'model' or 'radiomap': a recorded trace is one "
            "UAV's flight"
        )
    missions = []
    for index, uav in enumerate(scenario.uavs):
        single = uav_scenario(scenario, index)
        try:
            mission = build_mission(single)
            if uav.home is not None:
                check_home_inside(mission.fence, home_xy(single, mission.frame))
            if mission.mode == "autonomous":
                check_wind(mission)  # this UAV may be slower than the scenario's speed
        except ScenarioError as exc:
            raise ScenarioError(f"uavs[{index}] ({uav.name}): {exc}") from None
        fading = uav_fading_db(scenario, mission, index)
        faults = uav_faults(scenario, mission, index)
        missions.append(replace(mission, fading_db=fading, faults=faults))
    names = tuple(u.name for u in scenario.uavs)
    specs = tuple(u.policy or scenario.policy for u in scenario.uavs)
    return Fleet(scenario, names, tuple(missions), specs)


@dataclass(frozen=True)
class FleetLog:
    """What happened to every UAV, slot by slot.

    Attributes:
        names: (K,) UAV names.
        logs: (K,) each UAV's :class:`MissionLog` (``remaining_bit``: the shared buffers after
            the slot; ``served``: what it actually served).
        chosen: (T, K) sensor each UAV's policy chose, or NO_SENSOR.
        lost: (T, K) True where a UAV chose a sensor another UAV won (it served nothing).
    """

    names: tuple[str, ...]
    logs: tuple[MissionLog, ...]
    chosen: np.ndarray
    lost: np.ndarray

    def __post_init__(self) -> None:
        self.chosen.flags.writeable = False
        self.lost.flags.writeable = False

    @property
    def downloaded_bit(self) -> float:
        """Bits the whole fleet downloaded."""
        return float(sum(log.downloaded_bit.sum() for log in self.logs))


def _flight(mission: Mission, buffers_bit: np.ndarray) -> Flight:
    if mission.mode == "autonomous":
        return AutonomousFlight(mission, buffers_bit)
    return FixedFlight(mission, buffers_bit)


class FleetFlight:
    """A fleet mission in progress: :meth:`observe` every UAV, :meth:`apply` their actions."""

    def __init__(self, fleet: Fleet) -> None:
        self.fleet = fleet
        self.buffers_bit = np.array(fleet.missions[0].buffers_bit, float)
        self.flights = tuple(_flight(m, self.buffers_bit) for m in fleet.missions)
        self._chosen: list[np.ndarray] = []
        self._lost: list[np.ndarray] = []

    @property
    def slot(self) -> int:
        return self.flights[0].slot

    @property
    def done(self) -> bool:
        """True once every slot has run."""
        return all(flight.done for flight in self.flights)

    @property
    def last_lost(self) -> np.ndarray:
        """(K,) True where a UAV lost its chosen sensor to another in the last slot run."""
        return self._lost[-1] if self._lost else np.zeros(len(self.flights), bool)

    def observe(self) -> tuple[Observation, ...]:
        """What every UAV sees at the start of the current slot."""
        return tuple(flight.observe() for flight in self.flights)

    def apply(self, actions: Sequence[Action], who: Sequence[str]) -> np.ndarray:
        """Apply one action per UAV to the slot last observed; (K,) bits each downloaded."""
        n_sensors = self.fleet.missions[0].n_sensors
        chosen = np.array(
            [
                flight.windowed(check_serve(a.serve, n_sensors, w))
                for flight, a, w in zip(self.flights, actions, who, strict=True)
            ],
            np.int64,
        )
        rates = np.stack([flight.rate_bps for flight in self.flights])
        chosen_rate = rates[np.arange(len(chosen)), np.maximum(chosen, 0)]
        served = contract.fleet_served(chosen[:, None], chosen_rate[:, None])[:, 0]
        slot_s = self.fleet.missions[0].slot_s
        bits = contract.take_bits(self.buffers_bit, served, rates, slot_s)
        for flight, action, sensor, got in zip(self.flights, actions, served, bits, strict=True):
            flight.record(action, int(sensor), float(got))
        self._chosen.append(chosen)
        self._lost.append((chosen != NO_SENSOR) & (served == NO_SENSOR))
        return bits

    def log(self, policies: Sequence[str]) -> FleetLog:
        """The fleet log of the slots run so far."""
        k = len(self.flights)
        return FleetLog(
            names=self.fleet.names,
            logs=tuple(f.log(p) for f, p in zip(self.flights, policies, strict=True)),
            chosen=np.asarray(self._chosen, np.int64).reshape(-1, k),
            lost=np.asarray(self._lost, bool).reshape(-1, k),
        )
