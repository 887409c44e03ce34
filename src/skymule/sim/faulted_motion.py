"""Autonomous motion under a wind or a battery limit, for one mission's UAV (``docs/faults.md``,
steps 5-6).

The autonomous engine (:mod:`skymule.sim.autonomous`) moves calm missions all at once;
a UAV under a wind flies each leg of its in-fence path at the ground speed the wind allows and
keeps its return home in time instead of distance, and a battery allows a move only if the way
home still fits the usable energy. Those rules are per mission and path by path, so they are
stated here once, for one UAV, and the engine applies them to the rows that have them:

* :func:`wind_move` -- the policy's move under a wind: along the in-fence path, each leg at
  the ground speed the wind allows; with ``return_home`` the engine sends the UAV home at the
  cap whenever the move would leave too little time to get back at those speeds, so
  ``time_home(r_{t+1}) <= (T - t - 1) dt`` holds after every slot and r_T = home;
* :func:`battery_move` -- the move allowed only if the energy used, plus this slot's, plus the
  (priced) way home from where it ends stays within the usable energy; otherwise the UAV
  heads home at the return speed (at the cap if that would be late) and lands on arrival. Each
  slot home costs at most what it takes off the price of the way home, so
  ``used + price(r_t) <= usable`` holds after every slot (it does at home, at the start): the
  UAV gets home on the usable energy and the reserve is never flown on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skymule.errors import ScenarioError
from skymule.faults.motion import Battery, fly_for, leg_speeds_mps, path_time_s
from skymule.rules.home import FEASIBILITY_SLACK_M, home_budget
from skymule.world import Mission

XY = tuple[float, float]


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


@dataclass(frozen=True)
class FaultedUav:
    """One mission's UAV for the wind and battery rules (``mission.faults`` has one)."""

    mission: Mission

    @property
    def home(self) -> XY:
        assert self.mission.home_m is not None
        return float(self.mission.home_m[0]), float(self.mission.home_m[1])

    def fly(self, position: XY, goal: XY, speed_mps: float) -> XY:
        """Where one slot of flight toward ``goal`` at ``speed_mps`` ends: along the in-fence
        path, each leg at the ground speed the wind allows (the plain step without wind)."""
        mission = self.mission
        nav, faults = mission.navigator, mission.faults
        assert nav is not None and faults is not None
        if faults.wind is None:
            return nav.step(position, goal, speed_mps * mission.slot_s)
        path, speeds = self.way(position, goal, speed_mps)
        return fly_for(path, mission.slot_s, speeds)

    def way(self, xy: XY, goal: XY, speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
        """The in-fence path from ``xy`` to ``goal`` and its legs' ground speeds at
        ``speed_mps`` (each at most what the wind allows on its course)."""
        mission = self.mission
        assert mission.navigator is not None and mission.faults is not None
        path = np.asarray(mission.navigator.shortest_path(xy, goal), float)
        speeds = leg_speeds_mps(path, mission.faults.wind, speed_mps, mission.max_speed_mps)
        return path, speeds

    def in_time(self, xy: XY, slot: int) -> bool:
        """True when home is still reachable from ``xy`` (the position after slot ``slot``) by
        the mission's end, at the speed cap and the ground speed the wind allows on each leg."""
        mission = self.mission
        slack_s = FEASIBILITY_SLACK_M / mission.max_speed_mps
        budget_s = home_budget(mission.n_slots, slot, mission.slot_s, slack_s)
        return path_time_s(*self.way(xy, self.home, mission.max_speed_mps)) <= budget_s

    def home_speeds(self, battery: Battery) -> tuple[float, ...]:
        """The speeds the engine may fly home at: the return speed (capped) and, with
        ``return_home``, the cap (the in-time rule's)."""
        cap = self.mission.max_speed_mps
        back = min(battery.return_speed_mps, cap)
        return (back, cap) if self.mission.return_home and back != cap else (back,)

    def home_price_j(self, battery: Battery, xy: XY) -> float:
        """Energy [J] the way home from ``xy`` may take: leg by leg the dearer of flying it at
        each speed the engine may fly home at (:meth:`home_speeds`), power at the airspeed.

        Taking the dearer per leg makes any slot of the way home, at either speed, cost at
        most what it takes off this price: the battery invariant survives the in-time rule
        sending the UAV home at the cap instead of the return speed."""
        wind = self.mission.faults.wind if self.mission.faults is not None else None
        price: np.ndarray | None = None
        for speed in self.home_speeds(battery):
            path, speeds = self.way(xy, self.home, speed)
            legs = battery.leg_energy_j(path, speeds, wind)
            price = legs if price is None else np.maximum(price, legs)
        assert price is not None
        return float(np.sum(price))

    def move_energy_j(
        self, battery: Battery, position: XY, goal: XY, speed_mps: float, hover_rest: bool = True
    ) -> float:
        """Energy [J] of a slot flying from ``position`` toward ``goal`` at ``speed_mps`` (each
        leg at the ground speed the wind allows, power at the airspeed), hovering for the rest
        of the slot if it gets there first (``hover_rest``; False: it lands there)."""
        mission = self.mission
        assert mission.faults is not None
        path, speeds = self.way(position, goal, speed_mps)
        return battery.flight_energy_j(
            path, mission.slot_s, speeds, mission.faults.wind, hover_rest
        )

    def wind_move(self, position: XY, goal: XY, slot: int) -> tuple[XY, bool, XY]:
        """The policy's move toward the legal ``goal`` under a wind, kept in time for the
        return home: where it ends, whether the engine overrode the goal, the goal flown to."""
        mission = self.mission
        moved = self.fly(position, goal, mission.max_speed_mps)
        if mission.return_home and not self.in_time(moved, slot):
            return self.fly(position, self.home, mission.max_speed_mps), True, self.home
        return moved, False, goal

    def battery_move(
        self, position: XY, moved: XY, overridden: bool, goal: XY, used_j: float, slot: int
    ) -> tuple[XY, bool, float, bool]:
        """The move ``position`` -> ``moved`` (toward ``goal``) under the battery limit: where
        the UAV ends, whether the engine overrode the policy, the energy used after the slot
        and whether the UAV has landed (module docstring)."""
        mission = self.mission
        assert mission.faults is not None and mission.faults.battery is not None
        battery = mission.faults.battery
        landed = False
        energy = self.move_energy_j(battery, position, goal, mission.max_speed_mps)
        if not battery.affords(used_j, energy, self.home_price_j(battery, moved)):
            speed = self.home_speeds(battery)[0]
            moved, overridden = self.fly(position, self.home, speed), True
            if mission.return_home and not self.in_time(moved, slot):
                speed = mission.max_speed_mps  # the return speed would get home too late
                moved = self.fly(position, self.home, speed)
            energy = self.move_energy_j(battery, position, self.home, speed, hover_rest=False)
            landed = moved == self.home  # home: it lands (the reserve pays for that)
        used_j += energy
        return moved, overridden, used_j, landed or bool(battery.exhausted(used_j))
