"""Greedy's and HGAD's autonomous tours (paper Alg. 1 and Alg. 2) over B missions at once.

Both steer by naming a goal; the engine moves the UAV at most ``max_speed_mps * slot_s`` per
slot along the in-fence shortest path and enforces the geofence and the return-home deadline,
so these tours only decide *where to go next* and whom to serve. Each mission's tour state
(its target, visited or hovered sensors, planned waypoints, hover budget) is one column of an
array, and every slot the tours of all missions decide at once.

Greedy (Alg. 1; Hossen et al.'s framework): tour the sensors nearest-first (smallest in-fence
travel distance from where the UAV is to a hover point), a sensor counting as visited once
the UAV is within ``visit_radius_m`` of its hover point; never hover; every slot serve the
highest-SNR sensor with data; after the tour, or once every buffer is empty, fly home.

HGAD (Alg. 2): fly at full speed to the hover point of the target sensor, serving the
highest-rate sensor with data on the way (opportunistic download); at the hover point hover
and serve the target for T_hover = min(Q_i / R*_i, max_hover_s) (R*_i the rate at that hover
point, eq. (3) of the paper), then go to the next target; once every buffer is empty, fly
home.

The tour (``priority="initial"``, the default) is planned once, by *priority by buffer*: the
hover points ordered by initial buffer, largest first (paper Table II, column "Priority by
buffer"; Alg. 2: "a sensor i has higher data buffer" and "UAV moves towards the next
waypoint"). The UAV flies to every planned waypoint in turn, also when opportunistic
downloads emptied that sensor on the way (it then does not hover there) -- this is what
reproduces the paper's Table II navigation orders: at Lake Wheeler LW1 stands 14 m from the
launch point and is emptied en route in every Table II case. Ranking by the data *left* and
skipping emptied sensors (``priority="remaining"``, the literal reading of "next-largest
buffer") lets those en-route downloads reorder and shorten the tour and reproduces none of
the four orders (see ``tests/test_autonomous.py``). After the planned round, while data is
left, further rounds go to the largest remaining buffer not yet hovered over this round.

``hgad-robust`` adds two rules (``fail_slots``, ``arrive_m``): a hover is abandoned after
``fail_slots`` consecutive hover slots in which the target's buffer did not shrink (a silent
tower: it waits for the next round), and a reported position within ``arrive_m`` of a hover
point counts as arrived (GPS error: the reported position never equals it), the hover then
still flying to the point.

Arrays are sensor-major, (N, B) for N sensors and B missions, like :mod:`skymule.rules.contract`.
Each tour's :meth:`act` returns three (B,) arrays: the sensor served, the goal (a sensor whose
hover point the UAV flies toward, :data:`STAY` to hold its position, or ``N`` for home) and the
logged target (NO_SENSOR: none).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from skymule.policies.base import MissionContext
from skymule.rules import contract
from skymule.rules.contract import NO_SENSOR

if TYPE_CHECKING:  # the geometry is imported when a tour starts, not with the registry
    from skymule.flight.navigation import Navigator
    from skymule.sim.batch_paths import Paths, Sight

STAY = -1
"""Goal code: hold the current position (``goto_m`` NaN)."""


@dataclass(frozen=True)
class TourGeometry:
    """Where B missions' tours go, on one shared geofence.

    Attributes:
        navigator: the geofence's :class:`Navigator` (numpy path queries; any start).
        paths: its batched path queries, compiled when numba is installed (starts inside the
            fence).
        hover_m: (N, B, 2) hover points [m] (NaN where unknown).
        known: (N, B) True where the hover point is known.
        home_m: (B, 2) home points [m].
        hover_sight: sights of the hover points, (N, B, k) each (unknown points: home's).
    """

    navigator: Navigator
    paths: Paths
    hover_m: np.ndarray
    known: np.ndarray
    home_m: np.ndarray
    hover_sight: Sight

    @classmethod
    def of(cls, contexts: Sequence[MissionContext]) -> TourGeometry:
        """The geometry of B missions' contexts (one fence, one sensor count)."""
        from skymule.sim.batch_paths import path_queries

        navigator = contexts[0].navigator
        if navigator is None or any(c.hover_points_m is None or c.home_m is None for c in contexts):
            raise ValueError("autonomous tours need hover points, home and a navigator")
        paths = path_queries(navigator, "auto")
        home = np.array([c.home_m for c in contexts], float).reshape(-1, 2)
        hover = np.stack([np.asarray(c.hover_points_m, float) for c in contexts], axis=1)
        known = np.all(np.isfinite(hover), axis=2)
        places = np.where(known[..., None], hover, home[None])
        vis, dist = paths.sights(places.reshape(-1, 2))
        sight = (vis.reshape(*places.shape[:2], -1), dist.reshape(*places.shape[:2], -1))
        return cls(navigator, paths, hover, known, home, sight)

    def travel_m(
        self, position_m: np.ndarray, sensor: np.ndarray, mission: np.ndarray
    ) -> np.ndarray:
        """(P,) in-fence travel distance [m] from positions (P, 2) to the hover points of
        (sensor, mission) pairs. A reported position outside the fence (GPS error) counts the
        straight way in (:meth:`Navigator.travel_distances`)."""
        vis, dist = self.hover_sight
        goal = self.hover_m[sensor, mission]
        sight = (vis[sensor, mission], dist[sensor, mission])
        inside = self.navigator.in_cover(position_m)
        if inside.all():
            return self.paths.travel_distances(position_m, goal, sight)
        out = np.empty(len(position_m))
        rows = np.flatnonzero(inside)
        if rows.size:
            out[rows] = self.paths.travel_distances(
                position_m[rows], goal[rows], (sight[0][rows], sight[1][rows])
            )
        rows = np.flatnonzero(~inside)
        out[rows] = self.navigator.travel_distances(position_m[rows], goal[rows])
        return out

    def goals_m(self, goal: np.ndarray) -> np.ndarray:
        """(B, 2) the points of goal codes (B,): a hover point, home (N) or NaN (STAY)."""
        n_missions = self.known.shape[1]
        places = np.concatenate([self.hover_m, self.home_m[None]], axis=0)
        out = places[np.maximum(goal, 0), np.arange(n_missions)]
        out[goal == STAY] = np.nan
        return out


class GreedyTours:
    """Nearest-first tours of the hover points, serving argmax SNR (Alg. 1), B missions."""

    def __init__(self, geometry: TourGeometry, visit_radius_m: np.ndarray) -> None:
        self._geo = geometry
        self._radius_m = visit_radius_m
        self._visited = ~geometry.known
        self._target = np.full(geometry.known.shape[1], NO_SENSOR, np.int64)

    def _nearest(self, cols: np.ndarray, position: np.ndarray, pending: np.ndarray) -> np.ndarray:
        """(C,) the pending sensor with the shortest in-fence travel from ``position``."""
        sensor, which = np.nonzero(pending)  # pairs (sensor, mission among cols)
        distance = np.full(pending.shape, np.inf)
        distance[sensor, which] = self._geo.travel_m(position[which], sensor, cols[which])
        return np.argmin(distance, axis=0)  # ties: the lowest index

    def act(
        self,
        position: np.ndarray,
        snr_db: np.ndarray,
        rate_bps: np.ndarray,
        remaining: np.ndarray,
        active: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(served sensor, goal, target), each (B,), this slot.

        ``position`` (B, 2) [m]; ``snr_db`` (seen), ``rate_bps``, ``remaining`` (N, B).
        """
        n_sensors, n_missions = remaining.shape
        geo = self._geo
        serve = contract.greedy_choice(snr_db, contract.servable(rate_bps, remaining))
        off_x = np.where(geo.known, geo.hover_m[..., 0] - position[:, 0], np.inf)
        off_y = np.where(geo.known, geo.hover_m[..., 1] - position[:, 1], np.inf)
        self._visited |= np.hypot(off_x, off_y) <= self._radius_m
        pending = ~self._visited & (remaining > 0)
        touring = pending.any(axis=0)
        target = self._target
        target[~touring] = NO_SENSOR
        lost = ~pending[np.maximum(target, 0), np.arange(n_missions)]
        retarget = np.flatnonzero(active & touring & ((target < 0) | lost))
        if retarget.size:
            target[retarget] = self._nearest(retarget, position[retarget], pending[:, retarget])
        goal = np.where(touring, target, n_sensors)
        return serve, goal, target.copy()


class HGADTours:
    """Buffer-priority tours with hovering at each target's hover point (Alg. 2), B missions.

    Args:
        geometry: hover points and paths.
        peak_rate_bps: (N, B) R*_i, the rate at sensor i's own hover point [bit/s].
        buffers_bit: (N, B) initial buffers [bit] (the plan's priority).
        slot_s: (B,) slot length [s].
        max_hover_s: (B,) longest hover [s].
        planned: (B,) True for ``priority="initial"`` (a planned tour), False for
            ``"remaining"``.
        fail_slots: (B,) robust: abandon a hover after this many slots without data (0: never).
        arrive_m: (B,) robust: a reported position this close to a hover point is there [m].
    """

    def __init__(
        self,
        geometry: TourGeometry,
        peak_rate_bps: np.ndarray,
        buffers_bit: np.ndarray,
        slot_s: np.ndarray,
        max_hover_s: np.ndarray,
        planned: np.ndarray,
        fail_slots: np.ndarray,
        arrive_m: np.ndarray,
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
        self._fail_slots = fail_slots
        self._arrive_m = arrive_m
        self._robust = bool((fail_slots > 0).any() or (arrive_m > 0).any())
        self._fails = np.zeros(n_missions, np.int64)
        self._before_bit = np.full(n_missions, -1.0)  # hovered buffer before the last hover slot

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
    ) -> tuple[np.ndarray, np.ndarray]:
        """Missions ``cols`` serve their target without moving: (C,) the sensor served
        (NO_SENSOR where a silent tower is left) and (C,) the goal (STAY, or the hover point
        itself with ``arrive_m``). A hover ends when its budget or the buffer runs out."""
        sensor = self._target[cols]
        self._budget_s[cols] -= self._slot_s[cols]
        now = remaining[sensor, cols]
        goal = np.full(cols.size, STAY, np.int64)
        if self._robust:
            before = self._before_bit[cols]
            self._fails[cols] = np.where((before >= 0) & (now >= before), self._fails[cols] + 1, 0)
            self._before_bit[cols] = now
            limit = self._fail_slots[cols]
            silent = (limit > 0) & (self._fails[cols] >= limit)
            goal = np.where(self._arrive_m[cols] > 0, sensor, STAY)
        left = now - contract.served_bits(rate_bps[sensor, cols], now, self._slot_s[cols])
        ends = contract.hover_ends(self._budget_s[cols], left)
        if self._robust:
            ends |= silent
            done = cols[ends]
            self._fails[done], self._before_bit[done] = 0, -1.0
            goal = np.where(silent, STAY, goal)
            sensor = np.where(silent, NO_SENSOR, sensor)
        self._hovering[cols[ends]] = False
        self._target[cols[ends]] = NO_SENSOR
        return sensor, goal

    def _away(self, todo: np.ndarray, target: np.ndarray, position: np.ndarray) -> np.ndarray:
        """(C,) True where mission ``todo``'s UAV is not yet at its target's hover point."""
        point = self._geo.hover_m[target, todo]
        here = position[todo]
        away = (here[:, 0] != point[:, 0]) | (here[:, 1] != point[:, 1])
        if self._robust:
            dx, dy = here[:, 0] - point[:, 0], here[:, 1] - point[:, 1]
            away &= np.hypot(dx, dy) > self._arrive_m[todo]
        return away

    def act(
        self,
        position: np.ndarray,
        snr_db: np.ndarray,
        rate_bps: np.ndarray,
        remaining: np.ndarray,
        active: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(served sensor, goal, target), each (B,), this slot.

        ``position`` (B, 2) [m]; ``snr_db`` (seen), ``rate_bps``, ``remaining`` (N, B).
        """
        n_sensors, n_missions = remaining.shape
        en_route = contract.hgad_choice(rate_bps, snr_db, contract.servable(rate_bps, remaining))
        serve = np.full(n_missions, NO_SENSOR, np.int64)
        goal = np.full(n_missions, n_sensors, np.int64)  # home
        shown = np.full(n_missions, NO_SENSOR, np.int64)
        has_data = (remaining > 0).any(axis=0) & active
        in_hover = has_data & self._hovering & (self._target >= 0)
        todo = np.flatnonzero(has_data & ~in_hover)
        hovering = np.flatnonzero(in_hover)
        shown[hovering] = self._target[hovering]
        serve[hovering], goal[hovering] = self._hover_slot(hovering, rate_bps, remaining)
        # a bound on passes (never reached: each pass returns or retires a target)
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
            away = self._away(todo, target, position)
            going = todo[away]
            serve[going], goal[going], shown[going] = en_route[going], target[away], target[away]
            todo, target, passes = todo[~away], target[~away], passes[~away]
            # arrived: hover if there is something to gain, else on to the next waypoint
            self._hovered[target, todo] = True
            left = remaining[target, todo]
            gain = (left > 0) & (self._peak[target, todo] > 0)
            start = todo[gain]
            self._hovering[start] = True
            self._budget_s[start] = contract.hover_budget_s(
                left[gain], self._peak[target[gain], start], self._max_hover_s[start]
            )
            shown[start] = self._target[start]
            serve[start], goal[start] = self._hover_slot(start, rate_bps, remaining)
            self._target[todo[~gain]] = NO_SENSOR
            todo, passes = todo[~gain], passes[~gain]
        return serve, goal, shown
