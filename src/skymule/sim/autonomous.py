"""The autonomous engine: B flights whose policies steer, kept legal by the engine.

Every flight is a column: one mission, or one UAV of a fleet mission (its UAVs share one set
of buffers). All flights of a batch share one geofence. Each slot t (the slot contract of
``docs/contract.md``, plus motion):

1. every UAV is at r_t (start of the slot, at its ``altitude_m``) and observes SNR and rates
   there (:class:`~skymule.sim.batch_signal.BatchSignal`: one path-loss evaluation per shared
   model, per-slot fading added; under faults the policy sees the faulty SNR and position);
2. the policy returns, for every column, whom to serve and a point ``goto_m`` to fly toward
   (NaN: stay);
3. the served sensors deliver y = min(R dt, Q) bits (:func:`contract.serve_slot`: the window,
   fleet conflicts and faults first);
4. the engine moves each UAV at most ``max_speed_mps * slot_s`` toward the goal along the
   shortest path inside the geofence (:meth:`~skymule.flight.navigation.Navigator.steps`, or
   its compiled twin :class:`~skymule.sim.batch_paths.CompiledPaths`); a goal outside the
   fence is replaced by the nearest point of the fence (:func:`legal_goals`);
5. with ``return_home`` the engine overrides the goal with home whenever flying to it would
   leave too little time to get back (:class:`HomeRule`): ``d_home(r_{t+1}) <= (T-t-1) step``
   holds after every slot, so the UAV is home when the mission ends. Under a wind or a
   battery limit the UAV's move follows :mod:`skymule.sim.faulted_motion` instead.

A slot in which the UAV stays put by the policy's choice (not because the engine overrode it)
is logged as ``hovering``. :class:`AutonomousEngine` is the state machine (``observe`` /
``step``, and ``restart`` for environments that reset single flights); :func:`run_autonomous`
drives it with a batched policy.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import shapely

from skymule.errors import SkymuleError
from skymule.flight.navigation import Navigator
from skymule.metrics.flights import Flights
from skymule.policies.base import BatchAction, BatchObservation, BatchPolicy, MissionContext
from skymule.rules import contract
from skymule.rules.contract import NO_SENSOR
from skymule.rules.home import FEASIBILITY_SLACK_M, home_budget
from skymule.sim.batch_faults import BatchFaults, add_gps_error, apply_faults, stack_faults
from skymule.sim.batch_paths import Paths, Sight, path_queries
from skymule.sim.batch_signal import BatchSignal
from skymule.sim.columns import (
    affected_slots,
    check_actions,
    fleet_columns,
    flights_record,
    frozen,
    window_slots,
)
from skymule.sim.faulted_motion import FaultedUav, check_wind
from skymule.world import Mission

#: Margin [m] by which a bound on the distance home must clear the budget before the exact
#: distance is skipped (far above float round-off, far below a step).
BOUND_SLACK_M = 1e-3


def legal_goals(navigator: Navigator, goals: np.ndarray) -> np.ndarray:
    """(P, 2) each goal (P, 2) where the fence covers it, else the nearest point of the fence.

    A goal the fence does not cover (``covers_goals``, one vectorised test) is replaced by
    shapely's ``nearest_points(fence, goal)[0]``, the first point of ``shapely.shortest_line``
    (one vectorised call).
    """
    legal = np.array(goals, float).reshape(-1, 2)
    outside = np.flatnonzero(~navigator.covers_goals(legal))
    if outside.size:
        lines = shapely.shortest_line(navigator.fence, shapely.points(legal[outside]))
        legal[outside] = shapely.get_coordinates(shapely.get_point(lines, 0))
    return legal


class HomeRule:
    """The return-home override of B flights, each at its own slot.

    The rule: step toward home instead of the goal when d(position) + step > budget and
    d(moved) > budget, with d the in-fence distance home and budget = (T - t - 1) step +
    FEASIBILITY_SLACK_M. ``d`` is computed only where a bound cannot decide: ``bound`` is an
    upper bound on d(position) (0 at home, exact where last computed, plus one step per slot:
    no slot takes the UAV farther), the straight line a lower bound on d, and d(moved) of a
    UAV that ends the slot there is the next slot's d(position) (the same query, the same
    float). A UAV that flies home anyway is left alone: the override would make the same move.
    """

    def __init__(
        self,
        paths: Paths,
        home_m: np.ndarray,
        n_slots: np.ndarray,
        step_m: np.ndarray,
        on: np.ndarray,
    ) -> None:
        self._paths = paths
        self._home = home_m
        self._sight: Sight = paths.sights(home_m)
        self._n_slots = n_slots
        self._step = step_m
        self.on = on
        self._bound = np.zeros(len(home_m))
        self._exact = np.full(len(home_m), np.nan)
        self._last = np.zeros(len(home_m), bool)  # overridden in the last slot

    def restart(self, which: np.ndarray) -> None:
        """The flights ``which`` (mask) start again at home."""
        self._bound[which] = 0.0
        self._exact[which] = np.nan
        self._last[which] = False

    def unknown(self, rows: np.ndarray) -> None:
        """Flights ``rows`` are somewhere the rule was not told (a real vehicle's position):
        no bound, no exact distance; the next test computes what it needs."""
        self._bound[rows] = np.inf
        self._exact[rows] = np.nan
        self._last[rows] = False

    def forget(self, rows: np.ndarray) -> None:
        """Flights ``rows`` did not end where the rule was told (another rule moved them
        home-ward): their exact distance is unknown, their bound still holds."""
        self._exact[rows] = np.nan

    def home_sight(self, rows: np.ndarray) -> Sight:
        """Sights of the homes of flights ``rows``."""
        return self._sight[0][rows], self._sight[1][rows]

    def _distances(self, rows: np.ndarray, points: np.ndarray) -> np.ndarray:
        return self._paths.travel_distances(
            points, self._home[rows], self.home_sight(rows), checked=False
        )

    def _beeline(self, rows: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Straight-line distance home [m]: a lower bound on the in-fence distance."""
        return np.hypot(points[:, 0] - self._home[rows, 0], points[:, 1] - self._home[rows, 1])

    def likely(self, rows: np.ndarray) -> np.ndarray:
        """Positions among ``rows`` whose goal was overridden last slot (likely again now): the
        engine computes their step home together with the policy's steps."""
        return np.flatnonzero(self._last[rows])

    def apply(
        self,
        rows: np.ndarray,
        slot: np.ndarray,
        here: np.ndarray,
        moved: np.ndarray,
        flying_home: np.ndarray,
        home_move: np.ndarray,
    ) -> np.ndarray:
        """(R,) True where the override binds for flights ``rows`` (R,) at ``slot`` (R,), from
        ``here`` (R, 2); ``moved`` (R, 2) then steps toward home instead (in place).
        ``flying_home``: (R,) the goal is home; ``home_move``: (R, 2) the step home where
        already computed, else NaN (filled in place where needed)."""
        step = self._step[rows]
        budget = home_budget(self._n_slots[rows], slot, step, FEASIBILITY_SLACK_M)
        bound, exact = self._bound[rows], self._exact[rows]
        overridden = np.zeros(rows.size, bool)
        same_move = flying_home & ((moved[:, 0] != here[:, 0]) | (moved[:, 1] != here[:, 1]))
        check = np.flatnonzero(
            self.on[rows] & ~same_move & ~(bound + step < budget - BOUND_SLACK_M)
        )
        if not check.size:  # every bound clears the budget: no distance needed, no override
            self._bound[rows] = bound + step
            self._exact[rows] = np.nan
            self._last[rows] = False
            return overridden
        limit = budget[check]
        # the test is d_home(position) + step > budget; the straight line is a lower bound
        # on d_home, so well past the budget it holds without the exact distance
        sure = self._beeline(rows[check], here[check]) + step[check] > limit + BOUND_SLACK_M
        now = exact[check]
        exact[:] = np.nan  # every UAV moves on
        unknown = np.isnan(now) & ~sure
        # then d_home(moved) > budget; the same lower bound decides most rows, the others
        # (speculatively, with the unknown d_home(position), in one query) need the distance
        back_sure = self._beeline(rows[check], moved[check]) > limit + BOUND_SLACK_M
        ask = ~back_sure & (sure | unknown | (now + step[check] > limit))
        first, then = check[unknown], check[ask]
        found = self._distances(
            rows[np.concatenate([first, then])], np.concatenate([here[first], moved[then]])
        )
        now[unknown] = found[: first.size]
        after = np.full(check.size, np.nan)
        after[ask] = found[first.size :]
        bound[check[~sure]] = now[~sure]
        near = sure | (now + step[check] > limit)
        back = near & (back_sure | (after > limit))
        keep = ask & ~back  # where the UAV ends this slot: the exact distance for the next one
        exact[check[keep]] = after[keep]
        local = check[back]
        if local.size:
            todo = local[np.isnan(home_move[local, 0])]
            if todo.size:
                home_move[todo] = self._paths.steps(
                    here[todo], self._home[rows[todo]], step[todo], self.home_sight(rows[todo]),
                    checked=False,
                )  # fmt: skip
            moved[local] = home_move[local]
            overridden[local] = True
        self._bound[rows] = bound + step
        self._exact[rows] = exact
        self._last[rows] = False
        self._last[rows[local]] = True
        return overridden


def check_autonomous(missions: Sequence[Mission]) -> Navigator:
    """The one navigator of ``missions`` (autonomous, one fence); one-line errors else."""
    for mission in missions:
        if mission.mode != "autonomous" or mission.navigator is None or mission.home_m is None:
            raise SkymuleError("the autonomous engine needs trajectory.mode = 'autonomous'")
        if mission.source is None or mission.hover_points_m is None:
            raise SkymuleError("autonomous missions need signal.source = 'model' or 'radiomap'")
        check_wind(mission)
    navigators = [m.navigator for m in missions if m.navigator is not None]
    keys = [nav.fence_key for nav in navigators]
    for index, key in enumerate(keys):
        if key != keys[0]:
            raise SkymuleError(
                f"mission {index} ({missions[index].scenario.name!r}) has another geofence "
                "than mission 0; one batch of autonomous missions shares one fence"
            )
    return navigators[0]


class AutonomousEngine:
    """B autonomous flights in progress (module docstring for the rules).

    Call :meth:`observe`, then :meth:`step` with the policy's action, until :attr:`done`;
    then :meth:`record`. Missions are only read.

    Args:
        missions: one Mission per column, one geofence and sensor count.
        fleet: (B,) the fleet mission of each column (contiguous, K UAVs each): its UAVs share
            buffers (those of the first column's Mission); None: one UAV per mission.
        detail: keep the per-slot SNR, rates and buffers in the record (run folders).
        engine: path queries ``"auto"`` (compiled when numba is installed and the fence
            small enough), ``"numpy"`` or ``"compiled"``; the same floats either way.
    """

    def __init__(
        self,
        missions: Sequence[Mission],
        fleet: np.ndarray | None = None,
        detail: bool = True,
        engine: str = "auto",
    ) -> None:
        if not missions:
            raise ValueError("the engine needs at least one mission")
        if len({m.n_sensors for m in missions}) != 1:
            raise ValueError("one batch needs one sensor count")
        self.navigator = check_autonomous(missions)
        self.paths = path_queries(self.navigator, engine)
        self.missions = tuple(missions)
        self.detail = detail
        n_flights, n_sensors = len(missions), missions[0].n_sensors
        self.n_sensors = n_sensors
        self.group, self.uavs = fleet_columns(fleet, n_flights)
        self.n_slots = np.array([m.n_slots for m in missions], np.int64)
        self.slot_s = np.array([m.slot_s for m in missions], float)
        self.step_m = np.array([m.max_step_m for m in missions], float)
        self.altitude_m = np.array([m.altitude_m for m in missions], float)
        self.window = window_slots(missions)
        self.home_m = np.array([m.home_m for m in missions], float).reshape(-1, 2)
        self.signal = BatchSignal(missions, n_sensors)
        self.faults: BatchFaults = stack_faults(missions, n_sensors)
        self.home_rule = HomeRule(
            self.paths, self.home_m, self.n_slots, self.step_m,
            np.array([m.return_home for m in missions], bool),
        )  # fmt: skip
        wind = [m.faults is not None and m.faults.wind is not None for m in missions]
        battery = [m.faults is not None and m.faults.battery is not None for m in missions]
        self._windy = np.array(wind, bool)
        self._battery = {b for b, has in enumerate(battery) if has}
        self._uav = {b: FaultedUav(m) for b, m in enumerate(missions) if wind[b] or battery[b]}
        lead = self.group[:: self.uavs]
        self._buffers = np.array([missions[c].buffers_bit for c in lead], float).reshape(
            -1, n_sensors
        )
        self._t_max = int(self.n_slots.max())
        self._k = len(self.navigator.vertices)
        self._columns = np.arange(n_flights)
        self._restart_all()

    def _restart_all(self) -> None:
        n_flights, n_sensors = len(self.missions), self.n_sensors
        self.slot = np.zeros(n_flights, np.int64)
        self.position = self.home_m.copy()
        self.remaining = np.ascontiguousarray(self._buffers.T)
        self.used_j = np.zeros(n_flights)
        self.landed = np.zeros(n_flights, bool)
        # the legal goal last asked for and its sight (NaN distances: not yet known)
        self._goal_asked = np.full((n_flights, 2), np.nan)
        self._goal_legal = np.full((n_flights, 2), np.nan)
        self._goal_vis = np.zeros((n_flights, self._k), bool)
        self._goal_dist = np.full((n_flights, self._k), np.nan)
        # mission-major logs (B, T): the record needs no transpose
        t_max, shape = self._t_max, (n_flights, self._t_max)
        self._positions = np.zeros((n_flights, t_max + 1, 2))
        self._served = np.full(shape, NO_SENSOR, np.int64)
        self._downloaded = np.zeros(shape)
        self._hovering = np.zeros(shape, bool)
        self._target = np.full(shape, NO_SENSOR, np.int64)
        needs_chosen = self.faults.any or self.uavs > 1
        self._chosen = np.full(shape, NO_SENSOR, np.int64) if needs_chosen else None
        self._lost = np.zeros(shape, bool) if self.uavs > 1 else None
        self._used_log = np.full(shape, np.nan) if self._battery else None  # NaN: no battery
        keep = (n_flights, t_max, n_sensors) if self.detail else (n_flights, 0, n_sensors)
        self._snr_log, self._rate_log = np.zeros(keep), np.zeros(keep)
        self._remaining_log = np.zeros(keep)
        self._snr = np.zeros((n_sensors, n_flights))
        self._rate = np.zeros((n_sensors, n_flights))
        self._deliver = self._rate
        self._ok: np.ndarray | None = None
        self._observed = False
        self.last_lost = np.zeros(n_flights, bool)  # the last slot's UAVs that lost a sensor

    # --- what policies know ----------------------------------------------------------------

    def contexts(self) -> list[MissionContext]:
        """Each column's :class:`MissionContext` (peak rates from the batch's signal)."""
        from skymule.sim.context import autonomous_context

        hover = np.stack([np.asarray(m.hover_points_m, float) for m in self.missions], axis=1)
        peak = self.signal.peak_rate_bps(hover)
        return [autonomous_context(m, peak[:, b]) for b, m in enumerate(self.missions)]

    @property
    def active(self) -> np.ndarray:
        """(B,) True where the flight is still running."""
        return self.slot < self.n_slots

    @property
    def done(self) -> bool:
        """True once every flight is over."""
        return not bool((self.slot < self.n_slots).any())

    def observe(self, every: bool = False) -> BatchObservation:
        """What every UAV sees at the start of its current slot.

        ``every``: also the flights that are over (where they ended, no fading, no faults:
        an environment's observation after the last slot)."""
        active = self.active
        snr = self.signal.snr_db(self.position, self.slot, None if every else active)
        rate = self.signal.rate_bps(snr)
        self._snr, self._rate = snr, rate
        seen = contract.seen_snr_db(snr)
        seen_rate, deliver = rate, rate
        position = np.column_stack([self.position, self.altitude_m])
        self._ok = None
        if self.faults.any:  # the policy sees the faulty SNR; `deliver` is what serving yields
            true_seen = seen
            seen_rate, seen, deliver, self._ok = apply_faults(self.faults, self.slot, rate, seen)
            if every and not active.all():  # after the last slot there is no fault draw
                seen_rate[:, ~active], seen[:, ~active] = rate[:, ~active], true_seen[:, ~active]
            live = [b for b in self.faults.index.tolist() if active[b]]
            add_gps_error(self.missions, live, self.slot, position)
        self._deliver = deliver
        remaining = self.remaining if self.uavs == 1 else self.remaining[:, self.group]
        self._observed = True
        return BatchObservation(
            slot=frozen(self.slot.copy()),
            active=frozen(active),
            position_m=frozen(position),
            snr_db=frozen(seen).T,
            rate_bps=frozen(seen_rate).T,
            remaining_bit=frozen(remaining.copy()).T,
        )

    # --- what happens ----------------------------------------------------------------------

    def step(self, action: BatchAction, who: str = "policy") -> np.ndarray:
        """Apply ``action`` to the slot last observed; (B,) bits each flight downloaded."""
        if not self._observed:
            raise SkymuleError("step() before observe(): the engine has no slot to apply")
        self._observed = False
        n_flights = len(self.missions)
        active, slot = self.active, self.slot
        sensor = check_actions(action, n_flights, self.n_sensors, who)
        # a UAV that landed (battery) is not served: the AADM controller stops at disarm
        sensor = np.where(active & (slot < self.window) & ~self.landed, sensor, NO_SENSOR)
        chosen = sensor
        served, bits, lost = contract.serve_slot(
            sensor, self._deliver, self._ok, self.remaining, self.group, self.uavs, self.slot_s
        )
        goto = self._goals(action.goto_m, n_flights, who)
        here = self.position
        moved, overridden = self._move(here, goto, active)
        stayed = (moved[:, 0] == here[:, 0]) & (moved[:, 1] == here[:, 1]) & ~overridden
        rows = np.flatnonzero(active)
        t = slot[rows]
        self._positions[rows, t] = here[rows]
        self._served[rows, t] = served[rows]
        self._downloaded[rows, t] = bits[rows]
        self._hovering[rows, t] = stayed[rows]
        if action.target is not None:
            self._target[rows, t] = np.asarray(action.target, np.int64)[rows]
        if self._chosen is not None:
            self._chosen[rows, t] = chosen[rows]
        self.last_lost = np.zeros(n_flights, bool) if lost is None else lost & active
        if self._lost is not None:
            self._lost[rows, t] = self.last_lost[rows]
        if self._used_log is not None:
            kept = [b for b in rows.tolist() if b in self._battery]
            self._used_log[kept, slot[kept]] = self.used_j[kept]
        if self.detail:
            buffers = self.remaining if self.uavs == 1 else self.remaining[:, self.group]
            self._snr_log[rows, t] = self._snr[:, rows].T
            self._rate_log[rows, t] = self._rate[:, rows].T
            self._remaining_log[rows, t] = buffers[:, rows].T
        self.position = np.where(active[:, None], moved, here)
        self.slot = slot + active
        return bits

    def _goals(self, goto_m: np.ndarray | None, n_flights: int, who: str) -> np.ndarray:
        """(B, 2) the goals asked for (NaN: stay)."""
        if goto_m is None:
            return np.full((n_flights, 2), np.nan)
        goto = goto_m if isinstance(goto_m, np.ndarray) else np.asarray(goto_m, float)
        if goto.shape != (n_flights, 2) or goto.dtype.kind != "f" or np.isinf(goto).any():
            raise SkymuleError(
                f"policy {who!r} returned goto_m of shape {goto.shape} and dtype {goto.dtype}; "
                f"allowed: finite floats of shape ({n_flights}, 2), NaN to stay"
            )
        return goto

    def _legal(self, rows: np.ndarray, goto: np.ndarray) -> np.ndarray:
        """(R, 2) the legal goals of flights ``rows`` (cached while the goal asked for stays)."""
        asked = self._goal_asked[rows]
        changed = (asked[:, 0] != goto[:, 0]) | (asked[:, 1] != goto[:, 1])
        if changed.any():
            new = rows[changed]
            self._goal_asked[new] = goto[changed]
            self._goal_legal[new] = legal_goals(self.navigator, goto[changed])
            self._goal_dist[new] = np.nan
        return self._goal_legal[rows]

    def _move(
        self, here: np.ndarray, goto: np.ndarray, active: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(B, 2) where each UAV ends this slot and (B,) whether the engine overrode its goal."""
        moved = here.copy()
        overridden = self.landed.copy()  # a landed UAV stays down
        staying = np.isnan(goto[:, 0]) | np.isnan(goto[:, 1])
        calm = np.flatnonzero(active & ~self._windy & ~self.landed)
        legal = np.full((len(here), 2), np.nan)
        asks = np.flatnonzero(active & ~staying & ~self.landed)
        if asks.size:
            legal[asks] = self._legal(asks, goto[asks])
        # a step toward the position itself (no goal, or already there) stays put
        there, asked = legal[calm], ~staying[calm]
        going = calm[asked & ((there[:, 0] != here[calm, 0]) | (there[:, 1] != here[calm, 1]))]
        rule = self.home_rule
        calm_home = calm[rule.on[calm]]
        likely = calm_home[rule.likely(calm_home)]
        home_move = np.full((len(here), 2), np.nan)
        if likely.size:  # their step home in the same query as the policy's steps
            home_vis, home_dist = rule.home_sight(likely)
            rows = np.concatenate([going, likely])
            vis = np.concatenate([self._goal_vis[going], home_vis])
            dist = np.concatenate([self._goal_dist[going], home_dist])
            goals = np.concatenate([legal[going], self.home_m[likely]])
        elif going.size:
            rows, goals = going, legal[going]
            vis, dist = self._goal_vis[going], self._goal_dist[going]
        if going.size or likely.size:
            found = self.paths.steps(
                here[rows],
                goals,
                self.step_m[rows],
                (vis, dist),  # sights of new goals are filled in where a path bends
                checked=False,  # positions and legal goals are in the fence by construction
            )
            self._goal_vis[going], self._goal_dist[going] = vis[: going.size], dist[: going.size]
            moved[going] = found[: going.size]
            home_move[likely] = found[going.size :]
        if calm_home.size:
            flying_home = (legal[calm_home, 0] == self.home_m[calm_home, 0]) & (
                legal[calm_home, 1] == self.home_m[calm_home, 1]
            )
            back = moved[calm_home]
            home_steps = home_move[calm_home]
            overridden[calm_home] = rule.apply(
                calm_home, self.slot[calm_home], here[calm_home], back, flying_home, home_steps
            )
            moved[calm_home] = back
        if self._uav:
            self._faulted(here, legal, active, moved, overridden)
        return moved, overridden

    def _faulted(
        self,
        here: np.ndarray,
        legal: np.ndarray,
        active: np.ndarray,
        moved: np.ndarray,
        overridden: np.ndarray,
    ) -> None:
        """The wind and battery rules (:mod:`skymule.sim.faulted_motion`) for their flights,
        in place: a windy UAV's whole move, a battery's check of the move it was given."""
        for b, uav in self._uav.items():
            if not active[b] or self.landed[b]:
                continue
            position = (float(here[b, 0]), float(here[b, 1]))
            goal = position if np.isnan(legal[b, 0]) else (float(legal[b, 0]), float(legal[b, 1]))
            slot = int(self.slot[b])
            if self._windy[b]:
                end, forced, goal = uav.wind_move(position, goal, slot)
            else:
                end = (float(moved[b, 0]), float(moved[b, 1]))
                forced = bool(overridden[b])
                goal = uav.home if forced else goal
            if b in self._battery:
                before = end
                end, forced, self.used_j[b], self.landed[b] = uav.battery_move(
                    position, end, forced, goal, float(self.used_j[b]), slot
                )
                if end != before:
                    self.home_rule.forget(np.array([b]))
            moved[b] = end
            overridden[b] = forced

    def moves_from(
        self, position_m: np.ndarray, goto_m: np.ndarray, slot: np.ndarray
    ) -> np.ndarray:
        """(B, 2) where UAVs at ``position_m`` (B, 2) in slots ``slot`` (B,) would end the slot
        flying toward ``goto_m`` (B, 2; NaN: stay), by the engine's rules (fence, speed cap,
        return home, wind and battery); for positions the engine did not fly itself (a live
        vehicle's). The engine's own flights are not moved."""
        self.slot = np.asarray(slot, np.int64).copy()
        self.home_rule.unknown(self._columns)
        here = np.asarray(position_m, float).reshape(-1, 2)
        return self._move(here, self._goals(goto_m, len(self.missions), "policy"), self.active)[0]

    def restart(self, which: np.ndarray) -> None:
        """Flights ``which`` (mask) start again at home with full buffers (environments that
        reset one episode: single UAVs only)."""
        if self.uavs > 1:
            raise SkymuleError("restart: a fleet mission restarts as a whole")
        self.slot[which] = 0
        self.position[which] = self.home_m[which]
        self.remaining[:, which] = self._buffers.T[:, which]
        self.used_j[which] = 0.0
        self.landed[which] = False
        self.home_rule.restart(which)

    # --- what happened ---------------------------------------------------------------------

    def record(self, policies: Sequence[str]) -> Flights:
        """The run record of the slots run so far (``policies``: each column's name)."""
        n_flights = len(self.missions)
        n_run = np.minimum(self.slot, self.n_slots)
        width = int(n_run.max()) if n_run.size else 0
        positions = self._positions[:, : width + 1].copy()
        positions[self._columns, n_run] = self.position
        track = np.concatenate(
            [
                positions,
                np.broadcast_to(self.altitude_m[:, None, None], (n_flights, width + 1, 1)),
            ],
            axis=2,
        )

        def per_slot(log: np.ndarray | None) -> np.ndarray | None:
            return None if log is None else np.ascontiguousarray(log[:, :width])

        def per_sensor(log: np.ndarray) -> np.ndarray | None:
            return log[:, :width] if self.detail else None

        left = self.remaining if self.uavs == 1 else self.remaining[:, self.group]
        return flights_record(
            self.missions,
            policies,
            n_run=n_run,
            left_bit=np.ascontiguousarray(left.T),
            served=per_slot(self._served),
            downloaded_bit=per_slot(self._downloaded),
            hovering=per_slot(self._hovering),
            track_position_m=track,
            track_samples=n_run + 1,
            track_id=np.arange(n_flights),
            sample=np.minimum(np.arange(width)[None, :], n_run[:, None]),
            end_sample=n_run,
            target=per_slot(self._target),
            snr_db=per_sensor(self._snr_log),
            rate_bps=per_sensor(self._rate_log),
            remaining_bit=per_sensor(self._remaining_log),
            chosen=per_slot(self._chosen),
            affected=affected_slots([m.faults for m in self.missions], width),
            battery_used_j=per_slot(self._used_log),
            fleet=None if self.uavs == 1 else self.group.copy(),
            lost=per_slot(self._lost),
        )


def run_autonomous(
    missions: Sequence[Mission],
    policy: BatchPolicy,
    *,
    fleet: np.ndarray | None = None,
    detail: bool = True,
    engine: str = "auto",
) -> Flights:
    """Run B autonomous flights under one batched policy; their record."""
    from skymule.policies.batched import policy_names

    flights = AutonomousEngine(missions, fleet, detail, engine)
    policy.reset(flights.contexts())
    while not flights.done:
        flights.step(policy.act(flights.observe()), policy.name)
    return flights.record(policy_names(policy, len(missions)))


__all__ = ["AutonomousEngine", "HomeRule", "legal_goals", "run_autonomous"]
