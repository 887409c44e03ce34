"""Autonomous navigation for Greedy (paper Alg. 1) and HGAD (paper Alg. 2).

Both steer by returning ``Action.goto_m``; the engine moves the UAV at most
``max_speed_mps * slot_s`` per slot along the in-fence shortest path and enforces the
geofence and the return-home deadline, so these tours only decide *where to go next*.

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
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from skymule.policies.base import Action, MissionContext, Observation, slot_download_bit

Priority = Literal["initial", "remaining"]


def _xy(point: np.ndarray) -> tuple[float, float]:
    return (float(point[0]), float(point[1]))


def _require(context: MissionContext) -> tuple[np.ndarray, np.ndarray]:
    if context.hover_points_m is None or context.home_m is None or context.navigator is None:
        raise ValueError("autonomous policies need hover_points_m, home_m and navigator")
    return context.hover_points_m, context.home_m


class GreedyTour:
    """Nearest-first tour of hover points, serving argmax SNR (Alg. 1)."""

    def __init__(self, context: MissionContext) -> None:
        self._hover, self._home = _require(context)
        self._navigator = context.navigator
        self._radius_m = context.visit_radius_m
        self._known = np.all(np.isfinite(self._hover), axis=1)
        self._visited = ~self._known
        self._target: int | None = None

    def _nearest(self, position: tuple[float, float], pending: np.ndarray) -> int:
        assert self._navigator is not None
        candidates = np.flatnonzero(pending)
        distances = [
            self._navigator.travel_distance(position, _xy(self._hover[i])) for i in candidates
        ]
        return int(candidates[int(np.argmin(distances))])

    def steer(self, observation: Observation) -> tuple[tuple[float, float], int | None]:
        """(point to fly toward [m], target sensor or None when heading home) this slot."""
        position = _xy(observation.position_m)
        offset = np.where(self._known[:, None], self._hover - observation.position_m[:2], np.inf)
        self._visited |= np.hypot(offset[:, 0], offset[:, 1]) <= self._radius_m
        pending = ~self._visited & (observation.remaining_bit > 0)
        if not pending.any():
            self._target = None
            return _xy(self._home), None
        if self._target is None or not pending[self._target]:
            self._target = self._nearest(position, pending)
        return _xy(self._hover[self._target]), self._target


class HGADTour:
    """Buffer-priority tour with hovering at each target's hover point (Alg. 2)."""

    def __init__(
        self,
        context: MissionContext,
        max_hover_s: float,
        priority: Priority = "initial",
        fail_slots: int | None = None,
        arrive_m: float = 0.0,
    ) -> None:
        self._hover, self._home = _require(context)
        self._peak_bps = np.asarray(context.peak_rate_bps, float)
        self._slot_s = context.slot_s
        self._max_hover_s = max_hover_s
        self._priority = priority
        self._known = np.all(np.isfinite(self._hover), axis=1)
        buffers = np.asarray(context.buffers_bit, float)
        # stable sort: equal buffers go to the lower index first
        order = np.argsort(-buffers, kind="stable")
        self._plan = [int(i) for i in order if self._known[i] and buffers[i] > 0]
        self._planned = priority == "initial"
        self._hovered = np.zeros(len(self._peak_bps), bool)
        self._target: int | None = None
        self._hovering = False
        self._budget_s = 0.0
        # robust (hgad-robust): abandon a hover after fail_slots slots that delivered nothing
        self._fail_slots = fail_slots
        self._fails = 0
        self._before_bit = -1.0  # the hovered sensor's buffer before the last hover slot
        # robust: a reported position within arrive_m of the hover point counts as there (GPS
        # error: the reported position never equals it); the hover then still flies to it
        self._arrive_m = arrive_m

    def _next_target(self, remaining: np.ndarray) -> int | None:
        if self._planned and self._plan:
            return self._plan.pop(0)
        self._planned = False
        # a hover point where the rate is 0 has nothing to give: never a target of a round
        worth = self._known & (remaining > 0) & (self._peak_bps > 0)
        candidates = worth & ~self._hovered
        if not candidates.any():
            self._hovered[:] = False  # every sensor with data hovered over once: new round
            candidates = worth
        if not candidates.any():
            return None
        return int(np.argmax(np.where(candidates, remaining, -np.inf)))

    def _hover_slot(self, observation: Observation, sensor: int) -> Action:
        """Serve ``sensor`` without moving; end the hover when the budget or buffer runs out."""
        self._budget_s -= self._slot_s
        now = float(observation.remaining_bit[sensor])
        self._fails = self._fails + 1 if now >= self._before_bit >= 0 else 0
        self._before_bit = now
        left = now - slot_download_bit(observation, sensor, self._slot_s)
        silent = self._fail_slots is not None and self._fails >= self._fail_slots
        if silent:  # the tower went silent: leave it (it waits for the next round)
            self._hovering = False
            self._target = None
            self._fails, self._before_bit = 0, -1.0
            return Action(serve=None, hover=False, goto_m=None, target=sensor)
        if self._budget_s <= 1e-12 or left <= 0:
            self._fails, self._before_bit = 0, -1.0
            self._hovering = False
            self._target = None
        goto = _xy(self._hover[sensor]) if self._arrive_m > 0 else None
        return Action(serve=sensor, hover=True, goto_m=goto, target=sensor)

    def act(self, observation: Observation, en_route_serve: int | None) -> Action:
        remaining = observation.remaining_bit
        if not np.any(remaining > 0):
            return Action(serve=None, goto_m=_xy(self._home))
        if self._hovering and self._target is not None:
            return self._hover_slot(observation, self._target)
        position = _xy(observation.position_m)
        # each pass either returns or retires a target: bounded by the plan plus two rounds
        for _ in range(len(self._plan) + 2 * len(self._peak_bps) + 2):
            if self._target is None or (not self._planned and remaining[self._target] <= 0):
                self._target = self._next_target(remaining)
            if self._target is None:
                return Action(serve=en_route_serve, goto_m=_xy(self._home))
            target = self._target
            goal = _xy(self._hover[target])
            if position != goal and math.dist(position, goal) > self._arrive_m:
                return Action(serve=en_route_serve, goto_m=goal, target=target)
            # arrived: hover if there is something to gain, else on to the next waypoint
            self._hovered[target] = True
            if remaining[target] > 0 and self._peak_bps[target] > 0:
                self._hovering = True
                self._budget_s = min(remaining[target] / self._peak_bps[target], self._max_hover_s)
                return self._hover_slot(observation, target)
            self._target = None
        return Action(serve=en_route_serve, goto_m=_xy(self._home))
