"""Greedy's and HGAD's autonomous tours as array state machines over B missions at once.

The rules are those of :class:`skymule.policies.autonomous.GreedyTour` and
:class:`~skymule.policies.autonomous.HGADTour` (paper Alg. 1 and Alg. 2, with the slot contract
of ``docs/contract.md``), restated step for step over columns: each mission's tour state (its
target, visited or hovered sensors, planned waypoints, hover budget) is one column of an array,
and every slot the tours of all active missions decide at once. The batched autonomous engine
(:mod:`skymule.sim.batch_autonomous`) drives them, and its tests compare every slot of every
mission with the reference tours.

Arrays are sensor-major, (N, B) for N sensors and B missions, like :mod:`skymule.sim.contract`.
Active missions are the first A columns (the engine orders missions by length, longest first).
Each tour's :meth:`act` returns three (A,) arrays: the sensor served, the goal (a sensor whose
hover point the UAV flies toward, :data:`STAY` to hold its position, or ``N`` for home) and the
logged target (NO_SENSOR: none).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skymule.sim import contract
from skymule.sim.batch_paths import Paths
from skymule.sim.contract import NO_SENSOR

STAY = -1
"""Goal code: hold the current position (``Action.goto_m = None``)."""

Sight = tuple[np.ndarray, np.ndarray]
"""(visible mask, distances [m]) from points to the navigator's graph vertices
(:meth:`Navigator.sights`), (..., k) each."""


@dataclass(frozen=True)
class TourGeometry:
    """Where B missions' tours go, on one shared navigator (one geofence).

    Attributes:
        navigator: the geofence's path queries (shared by every mission of the batch): its
            :class:`~skymule.flight.navigation.Navigator` or
            :class:`~skymule.sim.batch_paths.CompiledPaths`.
        hover_m: (N, B, 2) hover points [m] (NaN where unknown).
        known: (N, B) True where the hover point is known.
        home_m: (B, 2) home points [m].
        hover_sight: sights of the hover points, (N, B, k) each (unknown points: home's).
    """

    navigator: Paths
    hover_m: np.ndarray
    known: np.ndarray
    home_m: np.ndarray
    hover_sight: Sight


class GreedyTours:
    """Nearest-first tours of the hover points, serving argmax SNR (Alg. 1), B missions."""

    def __init__(self, geometry: TourGeometry, visit_radius_m: np.ndarray) -> None:
        self._geo = geometry
        self._radius_m = visit_radius_m
        self._visited = ~geometry.known
        self._target = np.full(geometry.known.shape[1], NO_SENSOR, np.int64)

    def _nearest(self, cols: np.ndarray, position: np.ndarray, pending: np.ndarray) -> np.ndarray:
        """(C,) the pending sensor with the shortest in-fence travel from ``position``."""
        geo = self._geo
        sensor, which = np.nonzero(pending)  # pairs (sensor, mission among cols)
        mission = cols[which]
        vis, dist = geo.hover_sight
        distance = np.full(pending.shape, np.inf)
        distance[sensor, which] = geo.navigator.travel_distances(
            position[which],
            geo.hover_m[sensor, mission],
            (vis[sensor, mission], dist[sensor, mission]),
        )
        return np.argmin(distance, axis=0)  # ties: the lowest index, as the reference

    def act(
        self, position: np.ndarray, snr_db: np.ndarray, rate_bps: np.ndarray, remaining: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(served sensor, goal, target), each (A,), for the first A missions this slot.

        ``position`` (A, 2) [m]; ``snr_db`` (seen), ``rate_bps``, ``remaining`` (N, A).
        """
        n_sensors, active = remaining.shape
        geo = self._geo
        serve = contract.greedy_choice(snr_db, contract.servable(rate_bps, remaining))
        known = geo.known[:, :active]
        off_x = np.where(known, geo.hover_m[:, :active, 0] - position[:, 0], np.inf)
        off_y = np.where(known, geo.hover_m[:, :active, 1] - position[:, 1], np.inf)
        visited = self._visited[:, :active]
        visited |= np.hypot(off_x, off_y) <= self._radius_m[:active]
        pending = ~visited & (remaining > 0)
        touring = pending.any(axis=0)
        target = self._target[:active]
        target[~touring] = NO_SENSOR
        cols = np.arange(active)
        lost = ~pending[np.maximum(target, 0), cols]
        retarget = np.flatnonzero(touring & ((target < 0) | lost))
        if retarget.size:
            target[retarget] = self._nearest(retarget, position[retarget], pending[:, retarget])
        goal = np.where(touring, target, n_sensors)
        return serve, goal, target.copy()


class HGADTours:
    """Buffer-priority tours with hovering at each target's hover point (Alg. 2), B missions.

    Args:
        geometry: hover points and navigator.
        peak_rate_bps: (N, B) R*_i, the rate at sensor i's own hover point [bit/s].
        buffers_bit: (N, B) initial buffers [bit] (the plan's priority).
        slot_s: (B,) slot length [s].
        max_hover_s: (B,) longest hover [s].
        planned: (B,) True for ``priority="initial"`` (a planned tour), False for
            ``"remaining"``.
    """

    def __init__(
        self,
        geometry: TourGeometry,
        peak_rate_bps: np.ndarray,
        buffers_bit: np.ndarray,
        slot_s: np.ndarray,
        max_hover_s: np.ndarray,
        planned: np.ndarray,
    ) -> None:
        self._geo = geometry
        self._peak = peak_rate_bps
        self._slot_s = slot_s
        self._max_hover_s = max_hover_s
        n_sensors, n_missions = buffers_bit.shape
        # the plan: sensors by initial buffer, largest first (stable: ties to the lower index),
        # those with a hover point and data; compacted to the top of each column
        order = np.argsort(-buffers_bit, axis=0, kind="stable")
        keep = np.take_along_axis(geometry.known & (buffers_bit > 0), order, axis=0)
        self._plan = np.take_along_axis(order, np.argsort(~keep, axis=0, kind="stable"), axis=0)
        self._plan_len = keep.sum(axis=0)
        self._plan_pos = np.zeros(n_missions, np.int64)
        self._planned = planned.copy()
        self._hovered = np.zeros((n_sensors, n_missions), bool)
        self._target = np.full(n_missions, NO_SENSOR, np.int64)
        self._hovering = np.zeros(n_missions, bool)
        self._budget_s = np.zeros(n_missions)

    def _next_target(self, cols: np.ndarray, remaining: np.ndarray) -> None:
        """New targets for missions ``cols``: the next planned waypoint, else this round's
        largest remaining buffer not yet hovered over (a new round when none is left)."""
        pop = self._planned[cols] & (self._plan_pos[cols] < self._plan_len[cols])
        popped = cols[pop]
        self._target[popped] = self._plan[self._plan_pos[popped], popped]
        self._plan_pos[popped] += 1
        rest = cols[~pop]
        if not rest.size:
            return
        self._planned[rest] = False
        left = remaining[:, rest]
        # a hover point where the rate is 0 has nothing to give: never a target of a round
        worth = self._geo.known[:, rest] & (left > 0) & (self._peak[:, rest] > 0)
        candidates = worth & ~self._hovered[:, rest]
        new_round = ~candidates.any(axis=0)
        self._hovered[:, rest[new_round]] = False
        candidates[:, new_round] = worth[:, new_round]
        best = np.argmax(np.where(candidates, left, -np.inf), axis=0)
        self._target[rest] = np.where(candidates.any(axis=0), best, NO_SENSOR)

    def _hover_slot(
        self, cols: np.ndarray, rate_bps: np.ndarray, remaining: np.ndarray
    ) -> np.ndarray:
        """Missions ``cols`` serve their target without moving; (C,) the sensor served.

        A hover ends when its budget or the buffer runs out.
        """
        sensor = self._target[cols]
        self._budget_s[cols] -= self._slot_s[cols]
        now = remaining[sensor, cols]
        left = now - contract.served_bits(rate_bps[sensor, cols], now, self._slot_s[cols])
        ends = (self._budget_s[cols] <= contract.HOVER_EPS_S) | (left <= 0)
        self._hovering[cols[ends]] = False
        self._target[cols[ends]] = NO_SENSOR
        return sensor

    def act(
        self, position: np.ndarray, snr_db: np.ndarray, rate_bps: np.ndarray, remaining: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(served sensor, goal, target), each (A,), for the first A missions this slot.

        ``position`` (A, 2) [m]; ``snr_db`` (seen), ``rate_bps``, ``remaining`` (N, A).
        """
        n_sensors, active = remaining.shape
        hover = self._geo.hover_m
        en_route = contract.hgad_choice(rate_bps, snr_db, contract.servable(rate_bps, remaining))
        serve = np.full(active, NO_SENSOR, np.int64)
        goal = np.full(active, n_sensors, np.int64)  # home
        shown = np.full(active, NO_SENSOR, np.int64)
        has_data = (remaining > 0).any(axis=0)
        in_hover = has_data & self._hovering[:active] & (self._target[:active] >= 0)
        todo = np.flatnonzero(has_data & ~in_hover)
        hovering = np.flatnonzero(in_hover)
        sensor = self._hover_slot(hovering, rate_bps, remaining)
        serve[hovering], goal[hovering], shown[hovering] = sensor, STAY, sensor
        # the reference's bound on passes (never reached: each pass returns or retires a target)
        passes = self._plan_len[todo] - self._plan_pos[todo] + 2 * n_sensors + 2
        while todo.size:
            spent = passes <= 0
            serve[todo[spent]] = en_route[todo[spent]]
            todo, passes = todo[~spent], passes[~spent] - 1
            target = self._target[todo]
            retired = (target < 0) | (
                ~self._planned[todo] & (remaining[np.maximum(target, 0), todo] <= 0)
            )
            self._next_target(todo[retired], remaining)
            target = self._target[todo]
            home = target < 0
            serve[todo[home]] = en_route[todo[home]]
            todo, target, passes = todo[~home], target[~home], passes[~home]
            point = hover[target, todo]
            away = (position[todo, 0] != point[:, 0]) | (position[todo, 1] != point[:, 1])
            going = todo[away]
            serve[going], goal[going], shown[going] = en_route[going], target[away], target[away]
            todo, target, passes = todo[~away], target[~away], passes[~away]
            # arrived: hover if there is something to gain, else on to the next waypoint
            self._hovered[target, todo] = True
            left = remaining[target, todo]
            gain = (left > 0) & (self._peak[target, todo] > 0)
            start = todo[gain]
            self._hovering[start] = True
            self._budget_s[start] = np.minimum(
                left[gain] / self._peak[target[gain], start], self._max_hover_s[start]
            )
            sensor = self._hover_slot(start, rate_bps, remaining)
            serve[start], goal[start], shown[start] = sensor, STAY, sensor
            self._target[todo[~gain]] = NO_SENSOR
            todo, passes = todo[~gain], passes[~gain]
        return serve, goal, shown
