"""One offline AADM flight: the emulated controller, the agent and the kinematic vehicle.

:func:`fly_loopback` serves the controller on two loopback ports (any free ones), flies the
scenario's policy as the agent with a :class:`~skymule.aadm.vehicle.KinematicVehicle` over
the challenge's TCP bytes (telemetry, then the poll: the same code path as ``skymule aadm
agent`` against ``skymule aadm controller`` in two processes), then runs the same scenario
and policy through the engine (``skymule run``) and scores both by the rule in force.

The flight climbs to the mission altitude before its first poll (telemetry only), so the
volumes are shared (t1 = 0, slot 0 of the policy) at home at the engine's altitude, as the
engine's slot 0. Everything else (one poll = one 1-s slot, the slot contract, the fence and
return-home rules) is the same, so the two give the same Mbit poll by poll;
:func:`first_difference` names the first poll where they do not.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from skymule.aadm.agent import AadmAgent, fly_tcp
from skymule.aadm.controller import ControllerCore, serve_controller
from skymule.aadm.score import aadm_score_one, scenario_prediction
from skymule.aadm.vehicle import TAKEOFF_ALTITUDE_M, KinematicVehicle
from skymule.flight.navigation import Navigator
from skymule.policies import make_policy
from skymule.rules.contract import window_slots
from skymule.scenario import Scenario
from skymule.units import BITS_PER_MBIT
from skymule.world import Mission, build_mission, fence_or_box


@dataclass(frozen=True)
class LoopbackResult:
    """The flight and the engine's run of the same scenario, side by side.

    ``engine_mbit`` counts the engine's downloads inside the controller's window (what the
    controller would have credited); ``engine_mission_mbit`` is its whole mission's total.
    """

    policy: str
    flight_mbit: np.ndarray
    flight_score: dict[str, Any]
    flight_per_poll_bit: list[float]
    engine_mbit: np.ndarray
    engine_mission_mbit: float
    engine_score: dict[str, Any]
    flight_prediction: dict[str, Any]
    engine_prediction: dict[str, Any]
    engine_per_slot_bit: list[float]
    polls: int
    climb_slots: int
    share_poll: int
    landed_distance_m: float
    sensor_names: tuple[str, ...]


def kinematic_vehicle(agent: AadmAgent) -> KinematicVehicle:
    """A kinematic vehicle at the agent's launch point, inside the mission's fence."""
    mission = agent.mission
    navigator = mission.navigator or Navigator(fence_or_box(mission.fence))
    return KinematicVehicle(navigator, agent.home_xy())


def takeoff_altitude_m(scenario: Scenario, mission: Mission) -> float:
    """The altitude the agent takes off to: the scenario's flight altitude (autonomous), the
    path's own altitude if above 25 m (fixed path), else the challenge's 25 m.

    One rule for ``aadm fly`` and ``aadm agent`` (an agent that climbed to 25 m while
    ``aadm fly`` flew at the scenario's 30 m saw other SNRs: the planner split at poll 19).
    """
    if scenario.trajectory.mode == "autonomous":
        return float(scenario.trajectory.altitude_m)
    if mission.track is not None:
        return max(TAKEOFF_ALTITUDE_M, float(mission.track.position_m[0, 2]))
    return TAKEOFF_ALTITUDE_M


def fly_loopback(
    scenario: Scenario,
    policy: str | None = None,
    *,
    poll_s: float = 0.0,
    log_path: Path | None = None,
) -> LoopbackResult:
    """Fly ``scenario`` on loopback (pacing ``poll_s`` of wall time a poll) and run the engine."""
    from skymule.tasks.simulate import simulate

    if policy is not None:
        scenario = scenario.with_policy(policy)
    mission = build_mission(scenario)
    agent = AadmAgent(mission, make_policy(scenario.policy))
    vehicle = kinematic_vehicle(agent)
    core = ControllerCore(mission, log_path=log_path)
    with serve_controller(core) as server:
        record = fly_tcp(
            agent,
            vehicle,
            server.host,
            server.port,
            server.telemetry_port,
            pace_s=poll_s,
            altitude_m=takeoff_altitude_m(scenario, mission),
        )
    engine = simulate(scenario, mission=mission)
    total = float(mission.buffers_bit.sum())
    in_window = min(engine.log.n_slots, int(window_slots(core.window_s, mission.slot_s)))
    left = engine.log.remaining_bit[in_window - 1] if in_window else mission.buffers_bit
    return LoopbackResult(
        policy=scenario.policy.name,
        flight_mbit=core.received_mbit(),
        flight_score=core.score(),
        flight_per_poll_bit=list(core.per_poll_bit),
        engine_mbit=(mission.buffers_bit - left) / BITS_PER_MBIT,
        engine_mission_mbit=float(engine.log.downloaded_bit.sum()) / BITS_PER_MBIT,
        engine_score=aadm_score_one(engine.log.downloaded_bit, total, mission.slot_s),
        flight_prediction=scenario_prediction(scenario, np.array(core.per_poll_bit), total),
        engine_prediction=scenario_prediction(scenario, engine.log.downloaded_bit, total),
        engine_per_slot_bit=[float(b) for b in engine.log.downloaded_bit],
        polls=record.polls,
        climb_slots=record.climb_slots,
        share_poll=record.share_poll if record.share_poll is not None else -1,
        landed_distance_m=record.end_distance_to(agent.home_xy()),
        sensor_names=mission.sensor_names,
    )


def first_difference(result: LoopbackResult, tolerance_bit: float = 1.0) -> str | None:
    """Where the flight and the engine part, in one line (None: poll by poll the same, up to
    the shorter of the two)."""
    flight = np.asarray(result.flight_per_poll_bit, float)
    engine = np.asarray(result.engine_per_slot_bit, float)
    n = min(flight.size, engine.size)
    apart = np.flatnonzero(np.abs(flight[:n] - engine[:n]) > tolerance_bit)
    if apart.size == 0:
        return None
    k = int(apart[0])
    return (
        f"the flight and skymule run part at poll {k} after sharing: "
        f"{flight[k] / BITS_PER_MBIT:.3f} Mbit credited in the flight, "
        f"{engine[k] / BITS_PER_MBIT:.3f} in skymule run (the UAV was elsewhere, or the policy "
        "chose another tower)"
    )
