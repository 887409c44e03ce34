"""The slot loop for autonomous missions: the policy steers, the engine keeps the UAV legal.

Every slot t (the slot contract of DESIGN.md, plus motion):

1. the UAV is at r_t (start of the slot, at ``trajectory.altitude_m``); the engine evaluates
   ``mission.source.snr_db(r_t)`` and the rates there;
2. the policy returns an action: whom to serve and a point ``goto_m`` to fly toward (or None
   to stay);
3. the served sensor i delivers y = min(R_i dt, Q_i) bits;
4. the engine moves the UAV at most ``max_speed_mps * slot_s`` metres toward the goal along
   the shortest path inside the geofence (:class:`~skymule.flight.navigation.Navigator`);
   a goal outside the fence is replaced by the nearest point of the fence;
5. with ``return_home`` the engine overrides the goal with home whenever flying to it would
   leave too little time to get back: the invariant ``d_home(r_{t+1}) <= (T-t-1) * step``
   (``d_home`` the in-fence travel distance) holds after every slot, so the UAV is at home
   at the end of the mission, r_T = home (the formulation's r_end).

The UAV starts at home. A slot in which the UAV stays put by the policy's choice (not because
the engine overrode it) is logged as ``hovering``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TypedDict

import numpy as np
from shapely.geometry import Point, Polygon, box

from skymule.errors import ScenarioError, SkymuleError
from skymule.flight.navigation import Navigator, hover_point
from skymule.geo import LocalFrame
from skymule.policies.base import MissionContext, Observation, Policy
from skymule.scenario import Scenario
from skymule.sim.engine import NO_SENSOR, MissionLog, check_serve, mission_context
from skymule.world import Mission

#: Half-width [m] of the square that stands in for a geofence when a scenario gives none.
UNFENCED_HALF_WIDTH_M = 1.0e6

#: Clearance [m] of hover points from the fence boundary (see ``hover_point``).
HOVER_MARGIN_M = 1.0

#: Slack [m] in the return-home feasibility test (floating-point round-off only).
FEASIBILITY_SLACK_M = 1e-6


@dataclass(frozen=True)
class Geometry:
    """Where the UAV may fly and where it serves each sensor from (local metres).

    Attributes:
        navigator: in-fence shortest paths (a very large square when there is no fence).
        home_m: (2,) home point [m].
        hover_points_m: (N, 2) point inside the fence closest to each sensor [m]
            (NaN where the sensor has no position).
        altitude_m: flight altitude [m].
        max_step_m: longest move in one slot, max_speed_mps * slot_s [m].
        fenced: whether the scenario gave a geofence.
    """

    navigator: Navigator
    home_m: np.ndarray
    hover_points_m: np.ndarray
    altitude_m: float
    max_step_m: float
    fenced: bool


def home_xy(scenario: Scenario, frame: LocalFrame) -> np.ndarray:
    """(2,) home point [m]: ``trajectory.home`` (lat/lon or [x, y]) or the site origin."""
    home = scenario.trajectory.home
    if home is None:
        return np.zeros(2)
    if isinstance(home, list):
        if len(home) != 2:
            raise ScenarioError(
                f"trajectory.home = {home!r}: give [x_m, y_m] (2 numbers) or {{ lat, lon }}"
            )
        return np.asarray(home, float)
    x_m, y_m = frame.to_local(home.lat, home.lon)
    return np.array([float(x_m), float(y_m)])


def _fence_or_box(fence: Polygon | None) -> Polygon:
    if fence is not None:
        return fence
    half = UNFENCED_HALF_WIDTH_M
    return box(-half, -half, half, half)


def build_geometry(mission: Mission) -> Geometry:
    """Navigator, home and hover points of a mission; raises ScenarioError on bad geometry."""
    spec = mission.scenario.trajectory
    fence = _fence_or_box(mission.fence)
    home = home_xy(mission.scenario, mission.frame)
    if not fence.buffer(1e-6).covers(Point(home)):
        raise ScenarioError(
            f"trajectory.home = ({home[0]:.1f}, {home[1]:.1f}) m lies outside the geofence; "
            "the home point must be inside it"
        )
    hover = np.full((mission.n_sensors, 2), np.nan)
    for index, sensor in enumerate(mission.sensor_m):
        if np.all(np.isfinite(sensor[:2])):
            hover[index] = hover_point(fence, (sensor[0], sensor[1]), HOVER_MARGIN_M)
    return Geometry(
        navigator=Navigator(fence),
        home_m=home,
        hover_points_m=hover,
        altitude_m=spec.altitude_m,
        max_step_m=spec.max_speed_mps * mission.slot_s,
        fenced=mission.fence is not None,
    )


def check_duration(mission: Mission, geometry: Geometry) -> None:
    """Reject a mission too short to fly out to the nearest hover point and back home.

    Raises ScenarioError naming mission.duration_s, the time needed and why.
    """
    spec = mission.scenario.trajectory
    reachable = np.all(np.isfinite(geometry.hover_points_m), axis=1)
    if not reachable.any():
        return
    distances = [
        geometry.navigator.travel_distance(tuple(geometry.home_m), tuple(point))
        for point in geometry.hover_points_m[reachable]
    ]
    nearest = int(np.argmin(distances))
    name = np.asarray(mission.sensor_names)[reachable][nearest]
    needed_slots = 2 * math.ceil(distances[nearest] / geometry.max_step_m - 1e-9)
    if mission.n_slots < max(needed_slots, 1):
        raise ScenarioError(
            f"mission.duration_s = {mission.n_slots * mission.slot_s:g}: too short to fly from "
            f"home to the nearest hover point ({name}, {distances[nearest]:.0f} m) and back at "
            f"max_speed_mps = {spec.max_speed_mps:g}; needs >= "
            f"{needed_slots * mission.slot_s:g} s"
        )


def autonomous_context(mission: Mission, geometry: Geometry) -> MissionContext:
    """The mission context with the autonomous fields filled in.

    ``peak_rate_bps`` is R*_i, the rate at sensor i's hover point (paper Alg. 2).
    """
    assert mission.source is not None
    points = np.nan_to_num(geometry.hover_points_m, nan=0.0)
    at_hover = np.column_stack([points, np.full(len(points), geometry.altitude_m)])
    snr = mission.source.snr_db(at_hover)  # (N sensors at their own hover point, N)
    peak = np.diag(mission.rate_bps(snr)).copy() if len(points) else np.zeros(0)
    peak[~np.all(np.isfinite(geometry.hover_points_m), axis=1)] = 0.0
    return replace(
        mission_context(mission),
        peak_rate_bps=peak,
        hover_points_m=geometry.hover_points_m.copy(),
        home_m=geometry.home_m.copy(),
        max_step_m=geometry.max_step_m,
        visit_radius_m=mission.scenario.trajectory.visit_radius_m,
        navigator=geometry.navigator,
        predict_snr_db=mission.source.snr_db,
        return_home=mission.scenario.trajectory.return_home,
        rate_of_snr_bps=mission.rate_bps,
    )


def _legal_goal(geometry: Geometry, goal: tuple[float, float]) -> tuple[float, float]:
    """``goal`` if it is inside the fence, else the nearest point of the fence."""
    fence = geometry.navigator.fence
    if fence.buffer(1e-6).covers(Point(goal)):
        return goal
    return hover_point(fence, goal, margin_m=0.0)


def run_autonomous(mission: Mission, policy: Policy) -> MissionLog:
    """Run an autonomous mission under ``policy``; see the module docstring for the rules."""
    if mission.source is None:
        raise SkymuleError("autonomous missions need signal.source = 'model'")
    geometry = build_geometry(mission)
    check_duration(mission, geometry)
    policy.reset(autonomous_context(mission, geometry))

    nav = geometry.navigator
    step_m = geometry.max_step_m
    home = (float(geometry.home_m[0]), float(geometry.home_m[1]))
    return_home = mission.scenario.trajectory.return_home
    dt = mission.slot_s
    n_slots = mission.n_slots
    remaining = mission.buffers_bit.astype(float).copy()

    position = home
    positions: list[tuple[float, float]] = []
    snr_log: list[np.ndarray] = []
    rate_log: list[np.ndarray] = []
    served: list[int] = []
    downloaded: list[float] = []
    remaining_after: list[np.ndarray] = []
    hovering: list[bool] = []
    targets: list[int] = []
    for slot in range(n_slots):
        here = np.array([position[0], position[1], geometry.altitude_m])
        snr = mission.source.snr_db(here[None])[0]
        if mission.fading_db is not None:  # per-slot small-scale fading (radio.fading)
            snr = snr + mission.fading_db[slot]
        rates = mission.rate_bps(snr)
        action = policy.act(
            Observation(
                slot=slot,
                position_m=here,
                snr_db=np.nan_to_num(snr, nan=-np.inf),
                rate_bps=rates,
                remaining_bit=remaining.copy(),
            )
        )
        sensor = check_serve(action.serve, mission.n_sensors, policy)
        bits = 0.0
        if sensor != NO_SENSOR:
            bits = float(min(rates[sensor] * dt, remaining[sensor]))
            remaining[sensor] -= bits

        goal = position if action.goto_m is None else _legal_goal(geometry, action.goto_m)
        moved = nav.step(position, goal, step_m)
        overridden = False
        if return_home:
            budget_m = (n_slots - slot - 1) * step_m + FEASIBILITY_SLACK_M
            # d_home(moved) <= d_home(position) + step: test exactly only when it may bind
            if nav.travel_distance(position, home) + step_m > budget_m and (
                nav.travel_distance(moved, home) > budget_m
            ):
                moved = nav.step(position, home, step_m)
                overridden = True

        positions.append(position)
        snr_log.append(snr)
        rate_log.append(rates)
        served.append(sensor)
        downloaded.append(bits)
        remaining_after.append(remaining.copy())
        hovering.append(moved == position and not overridden)
        targets.append(NO_SENSOR if action.target is None else int(action.target))
        position = moved

    altitude = np.full((n_slots, 1), geometry.altitude_m)
    return MissionLog(
        policy=policy.name,
        sensor_names=mission.sensor_names,
        slot_s=dt,
        buffers_bit=mission.buffers_bit.copy(),
        position_m=np.hstack([np.asarray(positions, float).reshape(-1, 2), altitude]),
        end_position_m=np.array([position[0], position[1], geometry.altitude_m]),
        snr_db=np.asarray(snr_log, float).reshape(-1, mission.n_sensors),
        rate_bps=np.asarray(rate_log, float).reshape(-1, mission.n_sensors),
        served=np.asarray(served, int),
        downloaded_bit=np.asarray(downloaded, float),
        remaining_bit=np.asarray(remaining_after, float).reshape(-1, mission.n_sensors),
        hovering=np.asarray(hovering, bool),
        home_m=geometry.home_m.copy(),
        hover_points_m=geometry.hover_points_m.copy(),
        visit_radius_m=mission.scenario.trajectory.visit_radius_m,
        target=np.asarray(targets, int),
    )


class FixedGeometry(TypedDict):
    """The :class:`~skymule.sim.engine.MissionLog` fields ``fixed_geometry_fields`` fills in."""

    home_m: np.ndarray
    hover_points_m: np.ndarray
    visit_radius_m: float


def fixed_geometry_fields(mission: Mission) -> FixedGeometry:
    """Home, hover points and visit radius for a fixed-trajectory log (metrics need them).

    Home is ``trajectory.home`` or the site origin (the AADM launch point in the presets).
    """
    fence = mission.fence
    hover = np.full((mission.n_sensors, 2), np.nan)
    for index, sensor in enumerate(mission.sensor_m):
        if np.all(np.isfinite(sensor[:2])):
            xy = (float(sensor[0]), float(sensor[1]))
            hover[index] = xy if fence is None else hover_point(fence, xy, HOVER_MARGIN_M)
    return {
        "home_m": home_xy(mission.scenario, mission.frame),
        "hover_points_m": hover,
        "visit_radius_m": mission.scenario.trajectory.visit_radius_m,
    }
