"""``planner``: an autonomous tour planner (order of hover points, hover time at each).

The engine moves the UAV at most ``s = max_speed_mps * slot_s`` per slot along the in-fence
shortest path and enforces the fence, the speed cap and the return home; the planner only
decides where to go and whom to serve, from what :class:`MissionContext` offers (hover
points, navigator, the model's SNR predictor and rate table, home, return_home).

Slot accounting (what the plan and its simulation count). A leg of in-fence length ``L``
takes ``ceil(L / s)`` slots from the slot in which the UAV leaves (served from the departure
point) to the slot it starts at the next hover point. At a hover point the UAV serves the
target; it *stays* ``e`` extra slots (or until the target's buffer empties) and leaves in the
slot after. Every slot not spent staying is en route: it serves the sensor with the highest
rate among those with data (opportunistic download).

Plan search (each time the UAV reaches a hover point, at the start, and when the observed SNR
departs from the prediction by more than ``replan_db``):

1. *Orders.* For the sensors with data (``n <= exact_max``, default 7), a Held-Karp dynamic
   programme over subsets gives, for every subset, the visiting order with the fewest travel
   slots from here through the subset and home (exact: every order of every subset is
   covered). Beyond ``exact_max``: nearest-neighbour + 2-opt, then dropping targets while
   that helps.
2. *Hover time* for a given order: the slots left after travel are shared by a fractional
   knapsack: sensors by predicted hover rate ``R*_i``, highest first, each getting the extra
   slots to empty what is left when it is reached (``Q_i`` minus en-route downloads). Since the
   order only changes travel time, this is the best allocation for the order (ties in time go
   to the first-visited target).
3. *Choice.* Subsets are ranked by a quick estimate (en-route download bounded per sensor by
   its predicted rates along the tour's legs and overall by the best rate per slot, plus that
   knapsack for what is left); the best
   ``candidates`` (plus going home now) are simulated slot by slot on the predicted rates,
   with en-route download, and the plan with the most predicted bits wins (ties: earlier
   completion). Its hover slots are then moved between targets (16, 4, 1 at a time) while
   the simulated download improves: a sensor passed again later is partly drained en route.

Execution re-plans on every arrival (so early or late en-route downloads, and what the UAV
observes at the hover point, are taken into account) and when the observed SNR of any sensor
with data differs from the prediction by more than ``replan_db`` (it then keeps that offset
as a per-sensor bias on the predictions), at most once every ``replan_cooldown`` slots.
Without a predictor it predicts no en-route download (conservative) and hover rates from
``peak_rate_bps``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from skymule.errors import SkymuleError
from skymule.policies.base import Action, MissionContext, Observation
from skymule.policies.touring import (
    SAME_POINT_M,
    allocate_hover,
    ground_speed_mps,
    held_karp,
    knapsack_bits,
    leg_slots,
    two_opt_order,
)
from skymule.rules.contract import (
    NO_SENSOR,
    rate_choice,
    seen_snr_db,
    servable,
    served_bits,
    slots_to_cover,
)
from skymule.sim.plans import plans_kernel

__all__ = [
    "Plan",
    "Planner",
    "allocate_hover",
    "ground_speed_mps",
    "held_karp",
    "knapsack_bits",
    "leg_slots",
    "two_opt_order",
]

XY = tuple[float, float]

#: Most plan simulations spent moving hover slots between targets per re-plan.
REFINE_SIMULATIONS = 40

#: Legs timed with a wind take this much longer than the wind triangle says (the engine
#: turns corners and applies the wind per slot; a late return home costs more than a slot).
WIND_MARGIN = 1.05

#: Predicted downloads within this many bits count as equal (then finishing sooner wins).
BITS_TOL = 1.0


def _xy(point: np.ndarray | XY) -> XY:
    return (float(point[0]), float(point[1]))


@dataclass(frozen=True)
class Plan:
    """A tour: the sensors to visit in order and the extra slots to stay at each.

    Attributes:
        order: sensor indices in visiting order.
        extra_slots: (len(order),) slots to stay at each hover point after arriving.
        bits: predicted download over the rest of the mission [bit].
        done_slot: predicted slot after which every buffer is empty (T if never).
    """

    order: tuple[int, ...]
    extra_slots: tuple[int, ...]
    bits: float
    done_slot: int


def _better(plan: Plan, best: Plan) -> bool:
    """More predicted bits (beyond BITS_TOL), or as many and done sooner."""
    if plan.bits > best.bits + BITS_TOL:
        return True
    return plan.bits >= best.bits - BITS_TOL and plan.done_slot < best.done_slot


class Planner:
    """Plans the tour of hover points and hover times; see the module docstring."""

    name = "planner"

    def __init__(
        self,
        exact_max: int = 7,
        candidates: int = 12,
        replan_db: float = 6.0,
        replan_cooldown: int = 10,
    ) -> None:
        self.exact_max = exact_max
        self.candidates = candidates
        self.replan_db = replan_db
        self.replan_cooldown = replan_cooldown
        self._context: MissionContext | None = None

    # --- setup -------------------------------------------------------------------------------

    def reset(self, context: MissionContext) -> None:
        if context.mode != "autonomous":
            raise SkymuleError(
                "policy.name = 'planner' steers the UAV: it needs trajectory.mode = "
                "'autonomous' (use 'optimal-fixed' or 'hgad' on fixed paths)"
            )
        if context.hover_points_m is None or context.home_m is None or context.navigator is None:
            raise SkymuleError("policy 'planner' needs hover points, home and a navigator")
        self._context = context
        hover = context.hover_points_m
        self._known = np.all(np.isfinite(hover), axis=1)
        self._hover = np.nan_to_num(hover)
        self._home = _xy(context.home_m)
        self._step = float(context.max_step_m)
        self._n = len(hover)
        self._bias_db = np.zeros(self._n)
        self._legs: dict[tuple[XY, XY], tuple[int, np.ndarray]] = {}
        self._hover_snr: np.ndarray | None = None
        nodes = [*(_xy(p) for p in self._hover), self._home]
        self._dist = np.zeros((self._n + 1, self._n + 1))
        for a in range(self._n + 1):
            for b in range(a + 1, self._n + 1):
                if (a < self._n and not self._known[a]) or (b < self._n and not self._known[b]):
                    d = np.inf
                else:
                    d = context.navigator.travel_distance(nodes[a], nodes[b])
                self._dist[a, b] = self._dist[b, a] = d
        self._pair_slots = np.full_like(self._dist, np.inf)
        finite = np.isfinite(self._dist)
        self._pair_slots[finite] = [leg_slots(float(d), self._step) for d in self._dist[finite]]
        self._wind_mps: np.ndarray | None = None  # (2,) the wind legs are timed with, if any
        self._altitude = 0.0
        self._homebound = False
        self._plan: Plan | None = None
        self._position = 0  # index into plan.order of the current target
        self._stay_left = 0
        self._at_target = False
        self._last_replan = -(10**9)

    # --- predictions -------------------------------------------------------------------------

    def _predict_snr(self, xy: np.ndarray, altitude_m: float) -> np.ndarray | None:
        """(P, N) predicted SNR [dB] at (P, 2) points, or None without a predictor."""
        assert self._context is not None
        if self._context.predict_snr_db is None or self._context.rate_of_snr_bps is None:
            return None
        points = np.column_stack([xy, np.full(len(xy), altitude_m)])
        return seen_snr_db(self._context.predict_snr_db(points))

    def _rates(self, snr_db: np.ndarray | None, count: int) -> np.ndarray:
        """(count, N) predicted rates [bit/s] (zeros without a predictor)."""
        assert self._context is not None
        if snr_db is None or self._context.rate_of_snr_bps is None:
            return np.zeros((count, self._n))
        return self._context.rate_of_snr_bps(snr_db + self._bias_db)

    def _hover_rates(self, altitude_m: float) -> np.ndarray:
        """(N, N) predicted rate [bit/s] at hover point j (row) to sensor i (column)."""
        assert self._context is not None
        if self._hover_snr is None:
            self._hover_snr = self._predict_snr(self._hover, altitude_m)
        if self._hover_snr is None:
            return np.diag(np.asarray(self._context.peak_rate_bps, float))
        return self._rates(self._hover_snr, self._n) * self._known[:, None]

    def _leg(self, a: XY, b: XY) -> tuple[int, np.ndarray]:
        """Slots of the leg a -> b and (slots - 1, N) predicted SNR at its in-between points."""
        key = (a, b)
        if key not in self._legs:
            assert self._context is not None and self._context.navigator is not None
            path = np.asarray(self._context.navigator.shortest_path(a, b), float)
            seg = np.hypot(*np.diff(path, axis=0).T)
            along = np.concatenate([[0.0], np.cumsum(seg)])
            slots = leg_slots(float(along[-1]), self._step)
            at = np.arange(1, max(slots, 1)) * self._step
            if self._wind_mps is not None and slots > 0:
                # slower or faster per segment: time along the path, points every slot
                dt = self._context.slot_s
                speed = ground_speed_mps(np.diff(path, axis=0), self._wind_mps, self._step / dt)
                time = np.concatenate([[0.0], np.cumsum(WIND_MARGIN * seg / speed)])
                slots = max(int(slots_to_cover(time[-1], dt)), 1)
                at = np.interp(np.arange(1, slots) * dt, time, along)
            pts = np.column_stack(
                [np.interp(at, along, path[:, 0]), np.interp(at, along, path[:, 1])]
            )
            snr = self._predict_snr(pts, self._altitude) if len(pts) else None
            self._legs[key] = (slots, np.zeros((0, self._n)) if snr is None else snr)
        return self._legs[key]

    # --- simulation of candidate plans on the predicted rates ---------------------------------

    def _simulate_many(
        self,
        start: XY,
        slot: int,
        remaining: np.ndarray,
        orders: Sequence[tuple[int, ...]],
        extras: Sequence[np.ndarray],
        altitude_m: float,
    ) -> list[tuple[float, int, np.ndarray]]:
        """Predicted (bits, done slot, remaining at each arrival) of each plan (order, extra).

        All plans run as one batch through :func:`skymule.sim.plans.simulate_plans` (compiled
        when numba is installed); the legs come from the leg cache.
        """
        assert self._context is not None
        context = self._context
        hover_rates = self._hover_rates(altitude_m)
        start_rates = self._rates(self._predict_snr(np.asarray([start]), altitude_m), 1)[0]
        home_rates = self._rates(self._predict_snr(np.asarray([self._home]), altitude_m), 1)[0]
        table: dict[tuple[XY, XY] | None, int] = {None: 0}  # leg 0: no leg (0 slots)
        slots, has_rates, rows, blocks = [0], [False], [0], [np.zeros((0, self._n))]

        def leg(a: XY, b: XY | None) -> int:
            if b is None:
                return 0
            key = (a, b)
            if key not in table:
                n_slots, snr = self._leg(a, b)
                table[key] = len(slots)
                slots.append(n_slots)
                has_rates.append(len(snr) > 0)
                rows.append(sum(len(block) for block in blocks))
                blocks.append(self._rates(snr, len(snr)) if len(snr) else np.zeros((0, self._n)))
            return table[key]

        home = self._home if context.return_home else None
        legs: list[int] = []
        for order in orders:
            here = start
            for j in order:
                legs.append(leg(here, _xy(self._hover[j])))
                here = _xy(self._hover[j])
            legs.append(leg(here, home))
        lengths = np.array([len(order) for order in orders], np.int64)
        first = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        stops = int(lengths.sum())
        flat_order = np.fromiter(itertools.chain.from_iterable(orders), np.int64, stops)
        flat_extra = np.concatenate([np.zeros(0, np.int64), *extras]).astype(np.int64)
        bits = np.zeros(len(orders))
        done = np.zeros(len(orders), np.int64)
        arrival = np.zeros(stops)
        plans_kernel()(
            slot, context.n_slots, context.slot_s, context.return_home, remaining.astype(float),
            start_rates, hover_rates, home_rates, np.array(slots, np.int64),
            np.array(has_rates, bool), np.array(rows, np.int64), np.concatenate(blocks),
            flat_order, flat_extra, first, lengths, np.array(legs, np.int64), bits, done, arrival,
        )  # fmt: skip
        return [
            (float(bits[p]), int(done[p]), arrival[first[p] : first[p] + lengths[p]])
            for p in range(len(orders))
        ]

    # --- planning -----------------------------------------------------------------------------

    def _slots_from(self, position: XY) -> np.ndarray:
        """(N + 1,) leg slots from ``position`` to every hover point and home."""
        assert self._context is not None and self._context.navigator is not None
        nav = self._context.navigator
        nodes = [*(_xy(p) for p in self._hover), self._home]
        out = np.full(self._n + 1, np.inf)
        for k, node in enumerate(nodes):
            if k == self._n or self._known[k]:
                if self._wind_mps is None:
                    out[k] = leg_slots(nav.travel_distance(position, node), self._step)
                else:
                    out[k] = self._leg(position, node)[0]
        return out

    def _set_wind(self, wind_mps: np.ndarray | None) -> None:
        """Time every leg from now on with a steady wind ``wind_mps`` (2,) [m/s] (the vector
        it blows toward), as the engine's wind triangle does (``docs/faults.md``); None: at
        the full speed again."""
        self._wind_mps = None if wind_mps is None else np.asarray(wind_mps, float)
        self._legs.clear()
        nodes = [*(_xy(p) for p in self._hover), self._home]
        for a, b in itertools.permutations(range(self._n + 1), 2):
            if not np.isfinite(self._dist[a, b]):
                continue
            if wind_mps is None:
                self._pair_slots[a, b] = leg_slots(float(self._dist[a, b]), self._step)
            else:
                self._pair_slots[a, b] = self._leg(nodes[a], nodes[b])[0]

    def _candidate_orders(
        self, position: XY, slot: int, remaining: np.ndarray, rates: np.ndarray
    ) -> list[tuple[int, ...]]:
        """Orders worth simulating: the best subsets by :meth:`_score`."""
        assert self._context is not None
        legs: dict[tuple[XY, XY], tuple[np.ndarray, float]] = {}
        n_slots = self._context.n_slots
        targets = np.flatnonzero(self._known & (remaining > 0) & (rates > 0))
        if not len(targets):
            return [()]
        from_here = self._slots_from(position)
        pair_all = self._pair_slots
        start = from_here[targets]
        pair = pair_all[np.ix_(targets, targets)]
        end = pair_all[targets, self._n] if self._context.return_home else np.zeros(len(targets))
        horizon = n_slots - slot
        scored: list[tuple[float, float, tuple[int, ...]]] = []
        if len(targets) <= self.exact_max:
            cost, orders = held_karp(start, pair, end)
            for mask in range(1, len(cost)):
                if cost[mask] > horizon:
                    continue
                local = orders[mask]
                chosen = targets[local]
                value = self._score(position, chosen, horizon - int(cost[mask]), remaining, legs)
                scored.append((value, cost[mask], tuple(int(i) for i in chosen)))
        else:
            local = two_opt_order(start, pair, end)
            while local:
                travel = start[local[0]] + sum(pair[a, b] for a, b in itertools.pairwise(local))
                travel += end[local[-1]]
                chosen = targets[local]
                value = (
                    self._score(position, chosen, horizon - int(travel), remaining, legs)
                    if travel <= horizon
                    else -1.0
                )
                scored.append((value, travel, tuple(int(i) for i in chosen)))
                # drop the target whose removal saves the most travel per bit lost
                drops = []
                for k in range(len(local)):
                    trial = local[:k] + local[k + 1 :]
                    if not trial:
                        continue
                    t_cost = start[trial[0]] + sum(pair[a, b] for a, b in itertools.pairwise(trial))
                    t_cost += end[trial[-1]]
                    drops.append((t_cost, k))
                if not drops:
                    break
                local = local[: min(drops)[1]] + local[min(drops)[1] + 1 :]
        scored.sort(key=lambda item: (-item[0], item[1]))
        return [()] + [order for _, _, order in scored[: self.candidates]]

    def _score(
        self,
        position: XY,
        order: np.ndarray,
        budget: int,
        remaining: np.ndarray,
        legs: dict[tuple[XY, XY], tuple[np.ndarray, float]],
    ) -> float:
        """Quick estimate [bit] of a tour: en-route download plus the hover knapsack.

        En route, sensor i can give at most E_i = sum over the tour's legs of its predicted
        rate x dt, and all sensors together at most M = sum of the best rate x dt per slot; the
        estimate takes min(Q_i, E_i) scaled down to M, then shares the ``budget`` spare slots
        among the targets (knapsack by hover rate) for what is left.
        """
        assert self._context is not None
        dt = self._context.slot_s
        nodes = [position, *(_xy(self._hover[j]) for j in order)]
        if self._context.return_home:
            nodes.append(self._home)
        each = np.zeros(self._n)
        together = 0.0
        for a, b in itertools.pairwise(nodes):
            if (a, b) not in legs:
                _, snr = self._leg(a, b)
                rates = self._rates(snr, len(snr)) if len(snr) else np.zeros((0, self._n))
                legs[(a, b)] = (
                    rates.sum(axis=0) * dt,
                    float(rates.max(axis=1, initial=0).sum() * dt),
                )
            leg_each, leg_together = legs[(a, b)]
            each += leg_each
            together += leg_together
        # what the legs' slots could carry, capped by the buffers: min(sum R dt, Q), an
        # optimistic route total (each sensor as if alone), not a slot's served bits
        en_route = np.minimum(remaining, each)
        if en_route.sum() > together > 0:
            en_route *= together / en_route.sum()
        elif together <= 0:
            en_route[:] = 0.0
        rates = np.diag(self._hover_rates(self._altitude))[order]
        left = remaining[order] - en_route[order]
        return float(en_route.sum()) + knapsack_bits(rates, np.maximum(left, 0.0), budget, dt)

    def _replan(self, observation: Observation) -> None:
        assert self._context is not None
        position = _xy(observation.position_m)
        altitude = float(observation.position_m[2])
        slot, remaining = observation.slot, observation.remaining_bit
        dt, n_slots = self._context.slot_s, self._context.n_slots
        rates = np.diag(self._hover_rates(altitude)).copy()
        orders = self._candidate_orders(position, slot, remaining, rates)
        zeros = [np.zeros(len(order), np.int64) for order in orders]
        first = self._simulate_many(position, slot, remaining, orders, zeros, altitude)
        extras = []
        for order, (_, _, at_arrival) in zip(orders, first, strict=True):
            travel = self._travel_slots(position, order)
            idx = np.asarray(order, int)
            need = at_arrival - served_bits(rates[idx], at_arrival, dt)
            extras.append(allocate_hover(rates[idx], need, n_slots - slot - travel, dt))
        best: Plan | None = None
        simulated = self._simulate_many(position, slot, remaining, orders, extras, altitude)
        for order, extra, (bits, done, _) in zip(orders, extras, simulated, strict=True):
            plan = Plan(order, tuple(int(e) for e in extra), bits, done)
            if best is None or _better(plan, best):
                best = plan
        if best is not None and len(best.order) > 1:
            best = self._refine(best, position, slot, remaining, altitude)
        self._plan = best
        self._homebound = best is None or not best.order
        self._position = 0
        self._stay_left = best.extra_slots[0] if best and best.order else 0
        self._at_target = False
        self._last_replan = slot

    def _refine(
        self, plan: Plan, position: XY, slot: int, remaining: np.ndarray, altitude: float
    ) -> Plan:
        """Move hover slots between targets while the simulated plan improves.

        The knapsack ranks targets by hover rate, but a sensor passed again later in the tour
        is partly drained en route anyway; trading its hover slots for another target's can
        pay. Moves of 16, 4 and 1 slots, at most ``REFINE_SIMULATIONS`` simulations.
        """
        budget = REFINE_SIMULATIONS
        extra = np.asarray(plan.extra_slots, int)
        pairs = list(itertools.permutations(range(len(extra)), 2))
        for size in (16, 4, 1):
            improved = True
            while improved and budget > 0:
                improved = False
                # the moves a one-at-a-time search would try next, simulated as one batch;
                # after an accepted move the search goes on from the move after it
                k = 0
                while k < len(pairs) and budget > 0:
                    moves = [m for m in range(k, len(pairs)) if extra[pairs[m][0]] >= size]
                    moves = moves[:budget]
                    if not moves:
                        break
                    trials = []
                    for m in moves:
                        trial = extra.copy()
                        trial[pairs[m][0]] -= size
                        trial[pairs[m][1]] += size
                        trials.append(trial)
                    orders = [plan.order] * len(trials)
                    results = self._simulate_many(
                        position, slot, remaining, orders, trials, altitude
                    )
                    k = len(pairs)
                    for m, trial, (bits, done, _) in zip(moves, trials, results, strict=True):
                        budget -= 1
                        candidate = Plan(plan.order, tuple(int(e) for e in trial), bits, done)
                        if _better(candidate, plan):
                            plan, extra, improved = candidate, trial, True
                            k = m + 1
                            break
        return plan

    def _travel_slots(self, position: XY, order: tuple[int, ...]) -> int:
        assert self._context is not None
        nodes = [position, *(_xy(self._hover[j]) for j in order)]
        if self._context.return_home:
            nodes.append(self._home)
        return sum(self._leg(a, b)[0] for a, b in itertools.pairwise(nodes))

    # --- acting -------------------------------------------------------------------------------

    def _snr_offset(self, observation: Observation) -> np.ndarray | None:
        """(N,) observed minus predicted SNR [dB] here (None without a predictor)."""
        predicted = self._predict_snr(observation.position_m[None, :2], observation.position_m[2])
        return None if predicted is None else observation.snr_db - predicted[0]

    def _seen_rate_bps(self, observation: Observation) -> np.ndarray:
        """(N,) the rates [bit/s] this slot's choices follow: the observed ones."""
        return observation.rate_bps

    def _arrived(self, here: XY, goal: XY) -> bool:
        """True when the reported position ``here`` counts as being at ``goal``."""
        return math.dist(here, goal) <= SAME_POINT_M

    def _hover_goto(self, goal: XY) -> XY | None:
        """Where to fly while hovering at ``goal``: nowhere (the UAV is exactly there)."""
        return None

    def _check_prediction(self, observation: Observation) -> bool:
        """Update the per-sensor SNR bias; True if the observation departs from the plan."""
        offset = self._snr_offset(observation)
        if offset is None:
            return False
        usable = np.isfinite(offset) & (observation.remaining_bit > 0)
        off = usable & (np.abs(offset - self._bias_db) > self.replan_db)
        if not off.any() or observation.slot - self._last_replan < self.replan_cooldown:
            return False
        self._bias_db[off] = offset[off]
        return True

    def act(self, observation: Observation) -> Action:
        remaining = observation.remaining_bit
        if not (remaining > 0).any():
            return Action(serve=None, goto_m=self._home)
        if self._plan is None:
            self._altitude = float(observation.position_m[2])
            self._replan(observation)
        elif self._check_prediction(observation):
            self._replan(observation)
        assert self._plan is not None
        here = _xy(observation.position_m)
        en_route = self._en_route(observation)
        while True:
            plan = self._plan
            if self._position >= len(plan.order):
                if not self._homebound and observation.slot != self._last_replan:
                    self._replan(observation)  # tour done early: use the time left
                    continue
                return Action(serve=en_route, goto_m=self._home)
            target = plan.order[self._position]
            goal = _xy(self._hover[target])
            arrived = self._arrived(here, goal)
            if not arrived:
                if remaining[target] <= 0 and observation.slot != self._last_replan:
                    self._replan(observation)  # emptied en route: no need to go there
                    continue
                return Action(serve=en_route, goto_m=goal, target=target)
            if not self._at_target:
                # arrival: re-plan with what is left now (the new plan may start here)
                if observation.slot != self._last_replan:
                    self._replan(observation)
                    continue
                self._at_target = True
            serve = target if remaining[target] > 0 else en_route
            rate = self._seen_rate_bps(observation)[target]
            left = remaining[target] - (
                served_bits(rate, remaining[target], self._slot_s()) if serve == target else 0.0
            )
            if self._stay_left > 0 and left > 0:
                self._stay_left -= 1
                return Action(serve=serve, hover=True, goto_m=self._hover_goto(goal), target=target)
            # leave in this slot: on to the next target
            self._position += 1
            self._at_target = False
            if self._position < len(plan.order):
                self._stay_left = plan.extra_slots[self._position]
            nxt = plan.order[self._position] if self._position < len(plan.order) else None
            goto = self._home if nxt is None else _xy(self._hover[nxt])
            if nxt is not None and self._arrived(here, goto):
                continue  # next target served from the same point
            return Action(serve=serve, goto_m=goto, target=nxt)

    def _slot_s(self) -> float:
        assert self._context is not None
        return self._context.slot_s

    def _en_route(self, observation: Observation) -> int | None:
        """Highest seen rate among sensors with data, ties to the lowest index (None if no
        link): :func:`~skymule.rules.contract.rate_choice`, the rule the look-ahead scored the
        plan with (not HGAD's SNR tie-break: the look-ahead predicts rates only)."""
        rate = self._seen_rate_bps(observation)[:, None]
        has_data = servable(rate, observation.remaining_bit[:, None])
        best = int(rate_choice(rate, has_data)[0])
        return None if best == NO_SENSOR else best
