"""Several UAVs in one mission: one Mission per UAV over one shared set of buffers.

A fleet is K Missions (each UAV with its own home, altitude, speed, path, fading and fault
draws) that the engine runs as K columns sharing one set of buffers (``fleet=`` of
:func:`skymule.sim.run.run_missions`). Every slot (``docs/fleet.md``):

1. every UAV observes at the start of the slot (same buffers for all);
2. every UAV's policy chooses (one column of the batched action);
3. :func:`contract.fleet_served` settles conflicts -- each sensor serves at most one UAV, the
   higher rate wins, ties to the lower UAV index; a loser serves nothing this slot and the
   record marks it (``lost``);
4. :func:`contract.serve_slot` takes the winners' downloads from the shared buffers (the one
   place a download happens, for one UAV or many);
5. every UAV moves as its engine moves any column.

A fleet of one UAV is exactly the single-UAV engine (same numbers, value for value).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from skymule.errors import ScenarioError
from skymule.faults.draws import FaultDraws, draw_uav_faults
from skymule.radio.channel import FADING_STREAM
from skymule.radio.fading import draw_fading_db
from skymule.scenario import PolicySpec, Scenario
from skymule.sim.faulted_motion import check_wind
from skymule.world import Mission, build_mission, check_home_inside, home_xy


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
    if trajectory.flight is not None:
        raise ScenarioError(
            f"uavs[{index}] ({uav.name}): trajectory.flight flies one recorded flight; give each "
            "UAV of a fleet its own waypoints instead"
        )
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
