"""Fleet policies: one decision per UAV per slot, from every UAV's observation.

* independent UAVs -- the baseline: each UAV runs its own single-UAV policy (Greedy, HGAD,
  the planner, ...) as if alone, one column of the engine each; the slot contract settles the
  sensors they both choose (:func:`skymule.tasks.fleet.make_fleet_policy`);
* :class:`Coordinated` -- ``coordinated``: assigns every sensor to one UAV before take-off (the
  partition that minimises the longest UAV's tour time, travel plus the hover time to empty
  its sensors, :func:`partition`), then each UAV runs the tour planner
  (:mod:`skymule.policies.planner`) on its own sensors only, so the UAVs never compete for a
  sensor; a UAV whose sensors are all empty joins in on whatever is left.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from skymule.errors import SkymuleError
from skymule.policies.base import Action, MissionContext, Observation
from skymule.policies.planner import Planner
from skymule.policies.touring import held_karp, leg_slots
from skymule.rules.contract import slots_to_cover

#: Largest number of assignments :func:`partition` enumerates (K^n); beyond, a greedy split.
MAX_ASSIGNMENTS = 200_000

#: Most sensors held_karp is run on per UAV (2^n subsets).
EXACT_MAX_SENSORS = 10

COORDINATED = "coordinated"


def tour_cost_slots(context: MissionContext, sensors: np.ndarray) -> np.ndarray:
    """(2^n,) slots for one UAV to tour every subset of ``sensors`` from home and back, and
    hover long enough to empty them at their peak rates (bit i of the index: sensors[i])."""
    assert context.hover_points_m is not None and context.home_m is not None
    assert context.navigator is not None
    nav, step = context.navigator, context.max_step_m
    points = [(float(x), float(y)) for x, y in context.hover_points_m[sensors]]
    home = (float(context.home_m[0]), float(context.home_m[1]))
    start = np.array([leg_slots(nav.travel_distance(home, p), step) for p in points], float)
    pair = np.array(
        [[leg_slots(nav.travel_distance(a, b), step) for b in points] for a in points], float
    ).reshape(len(points), len(points))
    travel, _ = held_karp(start, pair, start)
    peak = np.asarray(context.peak_rate_bps, float)[sensors]
    buffers = np.asarray(context.buffers_bit, float)[sensors]
    with np.errstate(divide="ignore"):
        hover = np.where(peak > 0, slots_to_cover(buffers, peak * context.slot_s), np.inf)
    members = (np.arange(1 << len(sensors))[:, None] >> np.arange(len(sensors))) & 1
    return travel + (members * np.minimum(hover, context.n_slots)).sum(axis=1)


def partition(contexts: Sequence[MissionContext]) -> np.ndarray:
    """(N,) UAV each sensor is assigned to (-1: no position or no data).

    Minimises the longest UAV's :func:`tour_cost_slots` (ties: the smaller total) over every
    assignment when there are at most MAX_ASSIGNMENTS of them; otherwise each sensor goes, in
    decreasing buffer order, to the UAV whose cost grows least in max-then-sum order.
    """
    first = contexts[0]
    assert first.hover_points_m is not None
    usable = np.flatnonzero(
        np.all(np.isfinite(first.hover_points_m), axis=1) & (np.asarray(first.buffers_bit) > 0)
    )
    owner = np.full(len(first.sensor_names), -1, np.int64)
    n, k = len(usable), len(contexts)
    if n == 0:
        return owner
    if n > EXACT_MAX_SENSORS or k**n > MAX_ASSIGNMENTS:
        return _greedy_partition(contexts, usable, owner)
    costs = np.stack([tour_cost_slots(c, usable) for c in contexts])  # (K, 2^n)
    best_key, best = (math.inf, math.inf), None
    bit = 1 << np.arange(n)
    for assignment in itertools.product(range(k), repeat=n):
        chosen = np.asarray(assignment)
        masks = [int(bit[chosen == u].sum()) for u in range(k)]
        spans = [costs[u, m] for u, m in enumerate(masks)]
        key = (max(spans), sum(spans))
        if key < best_key:
            best_key, best = key, chosen
    assert best is not None
    owner[usable] = best
    return owner


def _greedy_partition(
    contexts: Sequence[MissionContext], usable: np.ndarray, owner: np.ndarray
) -> np.ndarray:
    buffers = np.asarray(contexts[0].buffers_bit, float)
    load = np.zeros(len(contexts))
    for sensor in usable[np.argsort(-buffers[usable], kind="stable")]:
        added = []
        for context in contexts:
            assert context.hover_points_m is not None and context.home_m is not None
            assert context.navigator is not None
            far = context.navigator.travel_distance(
                (float(context.home_m[0]), float(context.home_m[1])),
                (
                    float(context.hover_points_m[sensor, 0]),
                    float(context.hover_points_m[sensor, 1]),
                ),
            )
            peak = float(context.peak_rate_bps[sensor])
            hover = buffers[sensor] / (peak * context.slot_s) if peak > 0 else math.inf
            added.append(2 * leg_slots(far, context.max_step_m) + hover)
        after = load + np.asarray(added)
        u = int(np.argmin([max(after[u], *np.delete(load, u)) for u in range(len(load))]))
        owner[sensor], load[u] = u, after[u]
    return owner


def _masked(observation: Observation, mine: np.ndarray) -> Observation:
    return replace(observation, remaining_bit=np.where(mine, observation.remaining_bit, 0.0))


class Coordinated:
    """Partition the sensors between the UAVs, then one tour planner per UAV (module doc)."""

    name = COORDINATED

    def __init__(self) -> None:
        self._planners: list[Planner] = []
        self._contexts: list[MissionContext] = []
        self._mine: list[np.ndarray] = []
        self.owner = np.zeros(0, np.int64)

    def names(self) -> tuple[str, ...]:
        return (self.name,) * len(self._contexts)

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        if any(c.mode != "autonomous" for c in contexts):
            raise SkymuleError(
                "policy.name = 'coordinated' steers the UAVs: it needs trajectory.mode = "
                "'autonomous'"
            )
        self._contexts = list(contexts)
        self.owner = partition(contexts)
        self._mine = [self.owner == u for u in range(len(contexts))]
        self._planners = []
        for context, mine in zip(contexts, self._mine, strict=True):
            planner = Planner()
            planner.reset(replace(context, buffers_bit=np.where(mine, context.buffers_bit, 0.0)))
            self._planners.append(planner)

    def act(self, observations: Sequence[Observation]) -> tuple[Action, ...]:
        actions = []
        for u, observation in enumerate(observations):
            mine = self._mine[u]
            left = observation.remaining_bit > 0
            if not (left & mine).any() and (left & ~mine).any():
                # own sensors emptied: help with the rest (a fresh plan from here)
                self._mine[u] = np.ones_like(mine)
                self._planners[u] = Planner()
                self._planners[u].reset(self._contexts[u])
                mine = self._mine[u]
            actions.append(self._planners[u].act(_masked(observation, mine)))
        return tuple(actions)
