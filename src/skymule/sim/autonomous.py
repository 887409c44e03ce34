"""The slot loop for autonomous missions: the policy steers, the engine keeps the UAV legal.

Every slot t (the slot contract of ``docs/contract.md``, plus motion):

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
   at the end of the mission, r_T = home (the formulation's r_end). Under a wind fault the
   UAV flies each leg of the path at the ground speed the wind allows, and the invariant is
   kept in time instead: ``time_home(r_{t+1}) <= (T-t-1) * dt`` with the way home timed leg
   by leg the same way (``docs/faults.md``, step 5; the autopilot knows the steady wind).

The UAV starts at home. A slot in which the UAV stays put by the policy's choice (not because
the engine overrode it) is logged as ``hovering``. The engine reads only the :class:`Mission`
(home, hover points, navigator, speed cap, return home are built once by ``build_mission``).

:class:`AutonomousFlight` is the engine as a state machine (``observe`` / ``apply``);
:func:`run_autonomous` is the loop that hands each observation to a policy.
"""

from __future__ import annotations

import numpy as np
import shapely

from skymule.errors import ScenarioError, SkymuleError
from skymule.faults.motion import Battery, fly_for, leg_speeds_mps, path_time_s
from skymule.flight.navigation import Navigator, hover_point
from skymule.policies.base import Action, Observation, Policy
from skymule.sim.contract import NO_SENSOR
from skymule.sim.engine import ServingFlight, drive, log_fields
from skymule.sim.faulting import delivered_sensor, fault_fields, slot_faults
from skymule.sim.log import MissionLog
from skymule.world import Mission

#: Slack [m] in the return-home feasibility test (floating-point round-off only).
FEASIBILITY_SLACK_M = 1e-6

XY = tuple[float, float]


def legal_goal(navigator: Navigator, goal: XY) -> XY:
    """``goal`` if it is inside the fence, else the nearest point of the fence."""
    if navigator.covers_goal(goal):
        return goal
    return hover_point(navigator.fence, goal, margin_m=0.0)


def legal_goals(navigator: Navigator, goals: np.ndarray) -> np.ndarray:
    """:func:`legal_goal` of P goals (P, 2), float for float (one vectorised query).

    A goal the fence does not cover (``covers_goals``, one vectorised test) is replaced by the
    nearest point of the fence: ``hover_point(fence, goal, margin_m=0)`` gives shapely's
    ``nearest_points(fence, goal)[0]`` there (the goal is not in the fence, no clearance to
    try), which is the first point of ``shapely.shortest_line`` (one vectorised call here).
    """
    legal = np.array(goals, float).reshape(-1, 2)
    outside = np.flatnonzero(~navigator.covers_goals(legal))
    if outside.size:
        lines = shapely.shortest_line(navigator.fence, shapely.points(legal[outside]))
        legal[outside] = shapely.get_coordinates(shapely.get_point(lines, 0))
    return legal


def next_position(mission: Mission, position: XY, goto_m: XY | None, slot: int) -> tuple[XY, bool]:
    """Where the engine moves the UAV during slot ``slot``, and whether it overrode the goal.

    At most ``max_step_m`` along the in-fence shortest path toward ``goto_m`` (made legal:
    the nearest fence point for a goal outside; staying put for None); with ``return_home``,
    toward home instead whenever the goal would leave too little time to get back.
    """
    nav, step_m = mission.navigator, mission.max_step_m
    assert nav is not None and mission.home_m is not None
    home = (float(mission.home_m[0]), float(mission.home_m[1]))
    goal = position if goto_m is None else legal_goal(nav, goto_m)
    moved = nav.step(position, goal, step_m)
    if mission.return_home:
        budget_m = (mission.n_slots - slot - 1) * step_m + FEASIBILITY_SLACK_M
        # d_home(moved) <= d_home(position) + step: test exactly only when it may bind
        if nav.travel_distance(position, home) + step_m > budget_m and (
            nav.travel_distance(moved, home) > budget_m
        ):
            return nav.step(position, home, step_m), True
    return moved, False


def check_wind(mission: Mission) -> None:
    """Refuse a steady wind at least as fast as the UAV (ScenarioError, one line).

    Against such a wind the UAV makes no headway on some courses, so once it leaves home it
    may never get back (and it could not hold position: drift is not modelled). Scenarios
    refuse it when loaded; this catches a Mission built otherwise and a fleet UAV slower than
    the scenario's speed.
    """
    wind = None if mission.faults is None else mission.faults.wind
    if wind is not None and not wind.reachable_by(mission.max_speed_mps):
        raise ScenarioError(
            f"faults (wind): speed_mps = {wind.speed_mps:g} is not below the UAV's "
            f"max_speed_mps = {mission.max_speed_mps:g}: home would be unreachable against "
            "it; give a slower wind or a faster UAV"
        )


class AutonomousFlight(ServingFlight):
    """One autonomous mission in progress: the policy steers, the engine keeps it legal.

    Call :meth:`observe`, then :meth:`apply` with the action, until :attr:`done`; then
    :meth:`log`. The Mission is only read. ``buffers_bit`` lets several flights share one
    (N,) buffer array (:mod:`skymule.sim.fleet`); each then calls :meth:`record` after the
    fleet's downloads instead of :meth:`apply`.
    """

    def __init__(self, mission: Mission, buffers_bit: np.ndarray | None = None) -> None:
        if mission.source is None or mission.navigator is None or mission.home_m is None:
            raise SkymuleError("autonomous missions need signal.source = 'model' or 'radiomap'")
        self.mission = mission
        home: XY = (float(mission.home_m[0]), float(mission.home_m[1]))
        self._home = home
        check_wind(mission)
        # buffers_bit: a (N,) array shared with other UAVs (sim.fleet), updated in place
        self._remaining = (
            np.array(mission.buffers_bit, float) if buffers_bit is None else buffers_bit
        )
        self.slot = 0
        self.position: XY = home
        self._snr = np.zeros(mission.n_sensors)
        self._rates = np.zeros(mission.n_sensors)
        self._positions: list[XY] = []
        self._snr_log: list[np.ndarray] = []
        self._rate_log: list[np.ndarray] = []
        self._served: list[int] = []
        self._downloaded: list[float] = []
        self._remaining_after: list[np.ndarray] = []
        self._hovering: list[bool] = []
        self._targets: list[int] = []
        # faults (docs/faults.md): None on a fault-free mission, which then never reads them
        self._deliverable = None if mission.faults is None else mission.faults.deliverable()
        self._deliver = self._rates  # what a served sensor yields (true rate, 0 if blocked)
        self._chosen: list[int] = []
        self.used_j = 0.0  # propulsion energy so far (battery fault only)
        self._used_after: list[float] = []  # used_j after each slot (battery fault only)
        self.landed = False  # battery fault: the usable energy is spent

    @property
    def done(self) -> bool:
        """True once every slot has run."""
        return self.slot >= self.mission.n_slots

    def _here(self) -> np.ndarray:
        return np.array([self.position[0], self.position[1], self.mission.altitude_m])

    def observe(self) -> Observation:
        """What the UAV sees at the start of the current slot."""
        mission = self.mission
        assert mission.source is not None
        here = self._here()
        snr = mission.source.snr_db(here[None])[0]
        if mission.fading_db is not None:  # per-slot small-scale fading (radio.fading)
            snr = snr + mission.fading_db[self.slot]
        self._snr = snr
        self._rates = mission.rate_bps(snr)
        self._rates.flags.writeable = False
        self._deliver, seen_snr, seen_rate = self._rates, np.nan_to_num(snr, nan=-np.inf), None
        if mission.faults is not None and self._deliverable is not None:
            now = slot_faults(mission.faults, self._deliverable, self.slot, snr, self._rates)
            self._deliver, seen_snr = now.deliver_bps, now.snr_seen_db
            seen_rate = mission.rate_bps(seen_snr)
            seen_rate.flags.writeable = False
            # the position as reported, even just outside the fence: the Navigator plans
            # from there (first the straight way in), so the policy sees the raw reading
            here = here + now.position_error_m
        return Observation(
            slot=self.slot,
            position_m=here,
            snr_db=seen_snr,
            rate_bps=self._rates if seen_rate is None else seen_rate,
            remaining_bit=self._remaining.copy(),
        )

    def _move(self, goto_m: XY | None) -> tuple[XY, bool]:
        faults = self.mission.faults
        if faults is None or (faults.wind is None and faults.battery is None):
            return next_position(self.mission, self.position, goto_m, self.slot)
        return self._faulted_move(goto_m)

    def _fly(self, goal: XY, speed_mps: float) -> XY:
        """Where one slot of flight toward ``goal`` at ``speed_mps`` ends: along the in-fence
        path, each leg at the ground speed the wind allows (the plain step without wind)."""
        mission = self.mission
        nav, faults = mission.navigator, mission.faults
        assert nav is not None and faults is not None
        if faults.wind is None:
            return nav.step(self.position, goal, speed_mps * mission.slot_s)
        path = np.asarray(nav.shortest_path(self.position, goal), float)
        speeds = leg_speeds_mps(path, faults.wind, speed_mps, mission.max_speed_mps)
        return fly_for(path, mission.slot_s, speeds)

    def _way(self, xy: XY, goal: XY, speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
        """The in-fence path from ``xy`` to ``goal`` and its legs' ground speeds at
        ``speed_mps`` (each at most what the wind allows on its course)."""
        mission = self.mission
        assert mission.navigator is not None and mission.faults is not None
        path = np.asarray(mission.navigator.shortest_path(xy, goal), float)
        speeds = leg_speeds_mps(path, mission.faults.wind, speed_mps, mission.max_speed_mps)
        return path, speeds

    def _way_home(self, xy: XY, speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
        """The in-fence path home from ``xy`` and its legs' ground speeds at ``speed_mps``."""
        return self._way(xy, self._home, speed_mps)

    def _in_time(self, xy: XY) -> bool:
        """True when home is still reachable from ``xy`` (the position after this slot) by the
        mission's end, at the speed cap and the ground speed the wind allows on each leg."""
        mission = self.mission
        budget_s = (mission.n_slots - self.slot - 1) * mission.slot_s
        slack_s = FEASIBILITY_SLACK_M / mission.max_speed_mps
        return path_time_s(*self._way_home(xy, mission.max_speed_mps)) <= budget_s + slack_s

    def _home_speeds(self, battery: Battery) -> tuple[float, ...]:
        """The speeds the engine may fly home at: the return speed (capped) and, with
        ``return_home``, the cap (the in-time rule's)."""
        cap = self.mission.max_speed_mps
        back = min(battery.return_speed_mps, cap)
        return (back, cap) if self.mission.return_home and back != cap else (back,)

    def _home_price_j(self, battery: Battery, xy: XY) -> float:
        """Energy [J] the way home from ``xy`` may take: leg by leg the dearer of flying it at
        each speed the engine may fly home at (:meth:`_home_speeds`), power at the airspeed.

        Taking the dearer per leg makes any slot of the way home, at either speed, cost at
        most what it takes off this price: the battery invariant survives the in-time rule
        sending the UAV home at the cap instead of the return speed."""
        wind = self.mission.faults.wind if self.mission.faults is not None else None
        price: np.ndarray | None = None
        for speed in self._home_speeds(battery):
            path, speeds = self._way_home(xy, speed)
            legs = battery.leg_energy_j(path, speeds, wind)
            price = legs if price is None else np.maximum(price, legs)
        assert price is not None
        return float(np.sum(price))

    def _move_energy_j(
        self, battery: Battery, goal: XY, speed_mps: float, hover_rest: bool = True
    ) -> float:
        """Energy [J] of this slot flying toward ``goal`` at ``speed_mps`` (each leg at the
        ground speed the wind allows, power at the airspeed), hovering for the rest of the
        slot if it gets there first (``hover_rest``; False: it lands there)."""
        mission = self.mission
        assert mission.faults is not None
        path, speeds = self._way(self.position, goal, speed_mps)
        return battery.flight_energy_j(
            path, mission.slot_s, speeds, mission.faults.wind, hover_rest
        )

    def _policy_move(self, goto_m: XY | None) -> tuple[XY, bool, XY]:
        """The policy's move under a wind and/or a battery, kept in time for the return home:
        where it ends, whether the engine overrode the goal, and the goal flown to (at the
        speed cap)."""
        mission, faults = self.mission, self.mission.faults
        assert faults is not None and mission.navigator is not None
        goal = self.position if goto_m is None else legal_goal(mission.navigator, goto_m)
        if faults.wind is None:  # the calm rule, checked in distance
            moved, overridden = next_position(mission, self.position, goto_m, self.slot)
            return moved, overridden, self._home if overridden else goal
        moved = self._fly(goal, mission.max_speed_mps)
        if mission.return_home and not self._in_time(moved):
            return self._fly(self._home, mission.max_speed_mps), True, self._home  # too late
        return moved, False, goal

    def _faulted_move(self, goto_m: XY | None) -> tuple[XY, bool]:
        """The move under wind and/or a battery limit (``docs/faults.md``, steps 5-6).

        The UAV flies along the in-fence path, each leg at the ground speed the wind allows;
        with ``return_home`` the engine sends it home at the cap whenever the move would leave
        too little time to get back at those speeds, so ``time_home(r_{t+1}) <= (T - t - 1)
        dt`` holds after every slot and r_T = home.

        With a battery the move is allowed only if the energy used, plus this slot's, plus the
        (priced) way home from where it ends stays within the usable energy; otherwise the
        UAV heads home at the return speed (at the cap if that would be late) and lands on
        arrival. Each slot home costs at most what it takes off the price of the way home, so
        ``used + price(r_t) <= usable`` holds after every slot (it does at home, at the
        start): the UAV gets home on the usable energy and the reserve is never flown on.
        """
        mission, faults = self.mission, self.mission.faults
        assert faults is not None
        battery = faults.battery
        if self.landed:
            return self.position, True
        moved, overridden, goal = self._policy_move(goto_m)
        if battery is None:
            return moved, overridden
        energy = self._move_energy_j(battery, goal, mission.max_speed_mps)
        if not battery.affords(self.used_j, energy, self._home_price_j(battery, moved)):
            speed = self._home_speeds(battery)[0]
            moved, overridden = self._fly(self._home, speed), True
            if mission.return_home and not self._in_time(moved):
                speed = mission.max_speed_mps  # the return speed would get home too late
                moved = self._fly(self._home, speed)
            energy = self._move_energy_j(battery, self._home, speed, hover_rest=False)
            self.landed = moved == self._home  # home: it lands (the reserve pays for that)
        self.used_j += energy
        self.landed = self.landed or bool(battery.exhausted(self.used_j))
        return moved, overridden

    @property
    def rate_bps(self) -> np.ndarray:
        """(N,) rates [bit/s] a served sensor delivers at in the current slot (the observed
        rates without faults; under faults the true rate, 0 where a fault blocks the link)."""
        return self._deliver

    def record(self, action: Action, sensor: int, bits: float) -> None:
        """Log the slot (``sensor`` served, ``bits`` already taken) and fly toward the goal."""
        moved, overridden = self._move(action.goto_m)
        self._positions.append(self.position)
        self._snr_log.append(self._snr)
        self._rate_log.append(self._rates)
        if self._deliverable is not None:
            self._chosen.append(sensor)
            sensor = delivered_sensor(self._deliverable, self.slot, sensor)
        self._served.append(sensor)
        self._downloaded.append(bits)
        self._remaining_after.append(self._remaining.copy())
        self._hovering.append(moved == self.position and not overridden)
        self._targets.append(NO_SENSOR if action.target is None else int(action.target))
        self._used_after.append(self.used_j)
        self.position = moved
        self.slot += 1

    def log(self, policy: str) -> MissionLog:
        """The mission log of the slots run so far."""
        mission = self.mission
        n_sensors, altitude = mission.n_sensors, mission.altitude_m
        heights = np.full((len(self._positions), 1), altitude)
        assert mission.home_m is not None and mission.hover_points_m is not None
        affected, chosen = fault_fields(mission.faults, self._chosen, len(self._positions))
        return MissionLog(
            **log_fields(mission, policy),
            position_m=np.hstack([np.asarray(self._positions, float).reshape(-1, 2), heights]),
            end_position_m=np.array([self.position[0], self.position[1], altitude]),
            snr_db=np.asarray(self._snr_log, float).reshape(-1, n_sensors),
            rate_bps=np.asarray(self._rate_log, float).reshape(-1, n_sensors),
            served=np.asarray(self._served, int),
            downloaded_bit=np.asarray(self._downloaded, float),
            remaining_bit=np.asarray(self._remaining_after, float).reshape(-1, n_sensors),
            hovering=np.asarray(self._hovering, bool),
            target=np.asarray(self._targets, int),
            affected=affected,
            chosen=chosen,
            battery_used_j=(
                None
                if mission.faults is None or mission.faults.battery is None
                else np.asarray(self._used_after, float)
            ),
        )


def run_autonomous(mission: Mission, policy: Policy) -> MissionLog:
    """Run an autonomous mission under ``policy``; see the module docstring for the rules."""
    return drive(AutonomousFlight(mission), policy)
