"""Options: the actions a tour planner thinks in, executed slot by slot for B missions.

An *option* is one of

* **go to sensor k's hover point and hover there serving k for d slots** (d > 0), serving
  the best sensor with data on the way (HGAD's en-route choice, ``contract.hgad_choice``);
* **serve while passing** (d = 0): fly to k's hover point, serving en route, and decide again
  on arrival;
* **hover and serve k for d slots** where the UAV already is (the first kind with no leg);
* **return home**, serving en route (final: no decision follows).

The hover durations offered for sensor k are the fractions :data:`FRACTIONS` of
``cap_k = min(need_k, spare_k)`` slots, where ``need_k = ceil(Q_k / (R*_k dt))`` empties the
buffer at its hover rate R*_k (the peak rate of the context) and ``spare_k`` is the time left
after the leg there and (with return home) the leg home, and HGAD's hover min(cap_k,
``rules.defaults.MAX_HOVER_S``). So a decision picks one of ``N * N_DURATIONS + 1`` options. Sensors
without data or without a usable hover point, hovers that do not fit in the time left and a
"pass" of the point the UAV is at are masked out; a pass may head for a point it cannot reach
before it must turn home (the engine's return home takes over on the way, as for HGAD).

:class:`OptionRunner` keeps each mission's option (its target, the stay left) and executes it
slot by slot: the engine does the flying (fence, speed cap, return-home override), the runner
names the goal and whom to serve. An option ends on arrival (pass), when its stay is over,
when its target's buffer is empty, or after :data:`SILENT_SLOTS` hover slots in which the
target gave nothing (a silent tower under faults). When a stay ends, the next option is chosen
in that last stay slot, so the UAV already flies on while serving the target one last time
(the planner's departure slot). Decisions are therefore tens per mission, not one per slot.

At each decision the runner computes what a planner knows (:class:`Decision`): travel slots
to every hover point and home, the slots left, the data left, the peak rates, the rate now,
whether a sensor was hovered at before; :func:`option_features` turns them into the
features of every option.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from skymule.policies.base import BatchAction, BatchObservation, MissionContext
from skymule.policies.tours import TourGeometry
from skymule.rules import contract
from skymule.rules.contract import NO_SENSOR
from skymule.rules.defaults import MAX_HOVER_S

#: Hover durations offered per sensor, as fractions of min(slots to empty, spare slots);
#: 0 is "serve while passing". One more duration follows them: HGAD's hover,
#: min(slots to empty, MAX_HOVER_S, spare slots).
FRACTIONS = (0.0, 0.25, 0.5, 0.75, 1.0)

#: Durations offered per sensor: the fractions, then HGAD's.
N_DURATIONS = len(FRACTIONS) + 1

#: A hover ends after this many slots in a row in which its target gave nothing.
SILENT_SLOTS = 3

#: A reported position this close to a hover point counts as arrived [m] (GPS error: the
#: reported position never equals the point; the UAV still flies onto it while hovering).
ARRIVE_M = 10.0

#: Per-sensor features (:func:`option_features`), in order.
SENSOR_FEATURES = (
    "travel",  # slots to fly to the hover point / slots left
    "back",  # slots from the hover point home / slots left (0 without return home)
    "onward",  # slots from the hover point to the nearest other usable one / slots left
    "spread",  # mean slots from the hover point to the other usable ones / slots left
    "need",  # slots to empty at the hover rate / slots left (at most 4)
    "peak",  # hover rate / the best hover rate among sensors
    "data",  # data left / the most data left
    "left",  # data left / initial buffer
    "rate_now",  # rate now / hover rate (at most 2)
    "nearest",  # 1 for the sensor nearest in travel slots
    "largest",  # 1 for the sensor with the most data left
    "visited",  # 1 if the UAV has hovered there before
)

#: Per-option features (the duration's), in order.
OPTION_FEATURES = (
    "stay",  # hover slots / slots left
    "fraction",  # the duration's fraction of cap
    "gain",  # bits of the hover / (best hover rate x time left)
    "pace",  # bits of the hover / (travel + stay slots) / best hover bits per slot
    "spare",  # slots left after the leg, the stay and the way home / slots left
    "pass",  # 1 for "serve while passing"
    "hgad",  # 1 for HGAD's next option: the most data among sensors not hovered at yet
    # (all of them once each was), for HGAD's hover time
    "outlook",  # a planner's rough worth of the option and what can follow it: its bits
    # plus the best hover rate over the time left after it, the nearest onward leg and the
    # way home (at most the data left), / (best hover rate x time left)
)

#: Per-mission features, in order.
GLOBAL_FEATURES = (
    "time",  # slots left / mission slots
    "home",  # slots to fly home / slots left
    "open",  # sensors with data / sensors
    "load",  # data left / (best hover rate x time left)
)


def slots_to_empty(remaining: np.ndarray, peak: np.ndarray, slot_s: np.ndarray) -> np.ndarray:
    """(R, N) slots to empty each buffer at its hover rate (0 where there is no rate: such a
    sensor is not usable)."""
    rate = np.where(peak > 0, peak, 1.0) * slot_s[:, None]
    return np.where(peak > 0, contract.slots_to_cover(remaining, rate), 0.0)


@dataclass(frozen=True)
class Decision:
    """What a planner knows at a decision of R missions (mission-major arrays).

    Attributes:
        rows: (R,) the missions deciding.
        travel: (R, N) slots to fly from here to each hover point.
        back: (R, N) slots from each hover point home (0 without return home).
        pair: (R, N, N) slots from hover point k (row) to hover point j.
        home: (R,) slots from here home (0 without return home).
        slots_left: (R,) slots left in the mission (>= 1).
        n_slots: (R,) mission slots.
        slot_s: (R,) slot length [s].
        remaining: (R, N) data left [bit].
        initial: (R, N) initial buffers [bit].
        peak: (R, N) hover rates R*_k [bit/s].
        rate_now: (R, N) rates seen now [bit/s].
        usable: (R, N) sensors with a hover point, data and a hover rate.
        visited: (R, N) sensors hovered at before.
        near: (R, N) the UAV is at the hover point (within :data:`ARRIVE_M`).
    """

    rows: np.ndarray
    travel: np.ndarray
    back: np.ndarray
    pair: np.ndarray
    home: np.ndarray
    slots_left: np.ndarray
    n_slots: np.ndarray
    slot_s: np.ndarray
    remaining: np.ndarray
    initial: np.ndarray
    peak: np.ndarray
    rate_now: np.ndarray
    usable: np.ndarray
    visited: np.ndarray
    near: np.ndarray

    def stays(self) -> tuple[np.ndarray, np.ndarray]:
        """(R, N, D) hover slots of every option and (R, N*D + 1) which options are allowed
        (the last one: return home, always allowed)."""
        need = slots_to_empty(self.remaining, self.peak, self.slot_s)
        spare = self.slots_left[:, None] - self.travel - self.back
        cap = np.clip(np.minimum(need, spare), 0, None)
        fractions = np.asarray(FRACTIONS)
        stay = np.ceil(fractions[None, None, :] * cap[..., None] - contract.ROUND_OFF)
        hgad = np.minimum(cap, contract.slots_to_cover(MAX_HOVER_S, self.slot_s)[:, None])
        stay = np.maximum(np.concatenate([stay, hgad[..., None]], axis=2), 0.0)
        # a pass may head for a point it cannot reach in time (the engine's return home takes
        # over on the way, as it does for HGAD); a hover must fit
        hovers = np.append(fractions > 0, True)
        allowed = self.usable[..., None] & np.where(hovers, stay >= 1, ~self.near[..., None])
        flat = allowed.reshape(len(self.rows), -1)
        return stay, np.concatenate([flat, np.ones((len(self.rows), 1), bool)], axis=1)


def option_features(decision: Decision) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Features of every option of R decisions.

    Returns ``(sensor (R, N, S), option (R, N, D, O), mission (R, G), allowed (R, N*D + 1))``
    with S, O, G the lengths of :data:`SENSOR_FEATURES`, :data:`OPTION_FEATURES` and
    :data:`GLOBAL_FEATURES`; every feature is a ratio of order 1 (invariant to units, to the
    order of the sensors and, pooled, to their number).
    """
    d = decision
    left = d.slots_left[:, None].astype(float)
    usable = d.usable
    peak_max = np.max(np.where(usable, d.peak, 0.0), axis=1, initial=0.0)[:, None]
    peak_max = np.where(peak_max > 0, peak_max, 1.0)
    data_max = np.max(np.where(usable, d.remaining, 0.0), axis=1, initial=0.0)[:, None]
    data_max = np.where(data_max > 0, data_max, 1.0)
    need = slots_to_empty(d.remaining, d.peak, d.slot_s)
    travel_usable = np.where(usable, d.travel, np.inf)
    nearest = usable & (d.travel == travel_usable.min(axis=1, keepdims=True))
    data_usable = np.where(usable, d.remaining, -np.inf)
    largest = usable & (d.remaining == data_usable.max(axis=1, keepdims=True))
    safe_peak = np.where(d.peak > 0, d.peak, 1.0)
    others = usable[:, None, :] & ~np.eye(usable.shape[1], dtype=bool)[None]
    onward = np.min(np.where(others, d.pair, np.inf), axis=2)
    onward = np.where(np.isfinite(onward), onward, 0.0)
    spread = np.where(others, d.pair, 0.0).sum(axis=2) / np.maximum(others.sum(axis=2), 1)
    sensor = np.stack(
        [
            d.travel / left,
            d.back / left,
            onward / left,
            spread / left,
            np.minimum(need / left, 4.0),
            d.peak / peak_max,
            d.remaining / data_max,
            d.remaining / np.where(d.initial > 0, d.initial, 1.0),
            np.minimum(d.rate_now / safe_peak, 2.0),
            nearest.astype(float),
            largest.astype(float),
            d.visited.astype(float),
        ],
        axis=2,
    )
    sensor = np.where(usable[..., None], sensor, 0.0)
    stay, allowed = d.stays()
    # y = min(R dt, Q) over ``stay`` slots at the peak rate
    bits = contract.served_bits(
        d.peak[..., None] * stay, d.remaining[..., None], d.slot_s[:, None, None]
    )
    best = peak_max[..., None] * d.slot_s[:, None, None]  # best hover bits per slot
    spent = np.maximum(d.travel[..., None] + stay, 1.0)
    cap = np.maximum(stay[..., len(FRACTIONS) - 1], 1.0)  # the full fraction's stay
    fractions = np.concatenate(
        [np.broadcast_to(np.asarray(FRACTIONS), (*stay.shape[:2], len(FRACTIONS))),
         (stay[..., -1] / cap)[..., None]],
        axis=2,
    )  # fmt: skip
    pending = usable & ~d.visited
    pending = np.where(pending.any(axis=1, keepdims=True), pending, usable)
    target = np.argmax(np.where(pending, d.remaining, -np.inf), axis=1)
    hgad = np.zeros(stay.shape, bool)
    hgad[np.arange(len(target)), target, -1] = pending.any(axis=1)
    total = np.where(usable, d.remaining, 0.0).sum(axis=1)
    after = left[..., None] - d.travel[..., None] - stay - (onward + d.back)[..., None]
    rest = np.minimum(total[:, None, None] - bits, best * np.maximum(after, 0.0))
    option = np.stack(
        [
            stay / left[..., None],
            fractions,
            bits / (best * left[..., None]),
            bits / (best * spent),
            (left[..., None] - d.travel[..., None] - stay - d.back[..., None]) / left[..., None],
            (fractions == 0).astype(float),
            hgad.astype(float),
            (bits + rest) / (best * left[..., None]),
        ],
        axis=3,
    )
    option = np.where(usable[..., None, None], option, 0.0)
    mission = np.stack(
        [
            d.slots_left / d.n_slots,
            d.home / d.slots_left,
            usable.mean(axis=1),
            total / (peak_max[:, 0] * d.slot_s * d.slots_left),
        ],
        axis=1,
    )
    return sensor, option, mission, allowed


Chooser = Callable[[Decision], np.ndarray]
"""Picks one option per deciding mission: Decision -> (R,) option index in [0, N*D]
(N*D: return home)."""


class OptionRunner:
    """Executes options for B missions slot by slot (module docstring); ``choose`` decides.

    Args:
        contexts: the B missions' contexts (autonomous, one fence, one sensor count).
        choose: the decision rule (a learned scorer's argmax, or a training sampler).
    """

    def __init__(self, contexts: Sequence[MissionContext], choose: Chooser) -> None:
        if any(c.mode != "autonomous" for c in contexts):
            raise ValueError("options steer the UAV: autonomous missions only")
        self.choose = choose
        # hover points plus home as place N: travel to home is travel to "sensor" N
        extended = [
            replace(c, hover_points_m=np.vstack([np.asarray(c.hover_points_m, float), [c.home_m]]))
            for c in contexts
        ]
        self.geometry = TourGeometry.of(extended)
        n_missions, n_sensors = len(contexts), len(contexts[0].sensor_names)
        self.n_sensors = n_sensors
        self.n_options = n_sensors * N_DURATIONS + 1
        self.slot_s = np.array([c.slot_s for c in contexts], float)
        self.n_slots = np.array([c.n_slots for c in contexts], np.int64)
        self.step_m = np.array([c.max_step_m for c in contexts], float)
        self.return_home = np.array([c.return_home for c in contexts], bool)
        self.peak = np.array([c.peak_rate_bps for c in contexts], float).reshape(n_missions, -1)
        self.initial = np.array([c.buffers_bit for c in contexts], float).reshape(n_missions, -1)
        self.known = self.geometry.known[:n_sensors].T.copy()
        hover = self.geometry.hover_m[:n_sensors]  # (N, B, 2)
        # (B, N + 1, N + 1) in-fence distances between the hover points and home (one batched
        # query): most decisions are taken at one of these places and need no path query
        places = np.concatenate([hover.transpose(1, 0, 2), self.geometry.home_m[:, None]], 1)
        known = np.concatenate([self.known, np.ones((n_missions, 1), bool)], axis=1)
        self.places_m = np.where(known[..., None], places, np.nan)
        size = n_sensors + 1
        columns = np.repeat(np.arange(n_missions), size * size)
        start = np.where(known[..., None], places, self.geometry.home_m[:, None])
        start = np.repeat(start.reshape(-1, 2), size, axis=0)
        goal = np.tile(np.arange(size), n_missions * size)
        wanted = np.repeat(known.reshape(-1), size) & known[columns, goal]
        table = np.full(columns.size, np.inf)
        table[wanted] = self.geometry.travel_m(start[wanted], goal[wanted], columns[wanted])
        self.table_m = table.reshape(n_missions, size, size)
        back = self._slots(self.table_m[:, :n_sensors, n_sensors], self.step_m[:, None])
        self.back = np.where(self.return_home[:, None], back, 0.0)
        self.pair = self._slots(self.table_m[:, :n_sensors, :n_sensors], self.step_m[:, None, None])
        # each mission's option: target sensor (N: home, NO_SENSOR: none), stay left
        self.target = np.full(n_missions, NO_SENSOR, np.int64)
        self.stay_left = np.zeros(n_missions, np.int64)
        self.hovering = np.zeros(n_missions, bool)
        self.homebound = np.zeros(n_missions, bool)
        self.visited = np.zeros((n_missions, n_sensors), bool)
        self.silent = np.zeros(n_missions, np.int64)
        self.decisions = 0

    @staticmethod
    def _slots(distance_m: np.ndarray, step_m: np.ndarray) -> np.ndarray:
        """Slots to fly ``distance_m`` at ``step_m`` per slot (0 for the same point)."""
        far = distance_m > 1e-6
        return np.where(far, contract.slots_to_cover(distance_m, step_m), 0.0)

    def decision(
        self,
        rows: np.ndarray,
        position: np.ndarray,
        slot: np.ndarray,
        remaining: np.ndarray,
        rate: np.ndarray,
    ) -> Decision:
        """What a planner knows for missions ``rows`` (positions (B, 2), slots (B,), buffers
        and rates (B, N), all missions)."""
        n = self.n_sensors
        here = position[rows]
        match = (self.places_m[rows] == here[:, None, :]).all(axis=2)
        at = np.argmax(match, axis=1)
        distance = self.table_m[rows, at].copy()  # (R, N + 1), right where a place matched
        other = np.flatnonzero(~match.any(axis=1))
        if other.size:
            known = np.concatenate(
                [self.known[rows[other]], np.ones((other.size, 1), bool)], axis=1
            ).reshape(-1)
            asked = np.full(other.size * (n + 1), np.inf)
            ask = np.flatnonzero(known)
            starts = np.repeat(here[other], n + 1, axis=0)[ask]
            place = np.tile(np.arange(n + 1), other.size)[ask]
            mission = np.repeat(rows[other], n + 1)[ask]
            asked[ask] = self.geometry.travel_m(starts, place, mission)
            distance[other] = asked.reshape(other.size, n + 1)
        slots = self._slots(distance, self.step_m[rows, None])
        left = remaining[rows]
        return Decision(
            rows=rows,
            travel=slots[:, :n],
            back=self.back[rows],
            pair=self.pair[rows],
            home=np.where(self.return_home[rows], slots[:, n], 0.0),
            slots_left=(self.n_slots[rows] - slot[rows]).astype(float),
            n_slots=self.n_slots[rows].astype(float),
            slot_s=self.slot_s[rows],
            remaining=left,
            initial=self.initial[rows],
            peak=self.peak[rows],
            rate_now=rate[rows],
            usable=self.known[rows] & (left > 0) & (self.peak[rows] > 0),
            visited=self.visited[rows],
            near=distance[:, :n] <= ARRIVE_M,
        )

    def _decide(
        self,
        rows: np.ndarray,
        position: np.ndarray,
        slot: np.ndarray,
        remaining: np.ndarray,
        rate: np.ndarray,
    ) -> None:
        """Missions ``rows`` choose their next option (remaining: as it will be after this
        slot's service where the decision is taken in a last stay slot)."""
        if not rows.size:
            return
        decision = self.decision(rows, position, slot, remaining, rate)
        choice = np.asarray(self.choose(decision), np.int64)
        self.decisions += rows.size
        stay, _ = decision.stays()
        width = N_DURATIONS
        home = choice >= self.n_sensors * width
        sensor = np.where(home, 0, choice // width)
        which = np.where(home, 0, choice % width)
        self.target[rows] = np.where(home, self.n_sensors, sensor)
        self.homebound[rows] |= home
        self.stay_left[rows] = np.where(home, 0, stay[np.arange(rows.size), sensor, which])
        self.hovering[rows] = False
        self.silent[rows] = 0

    def act(self, observation: BatchObservation) -> BatchAction:
        """One slot of every mission: decide where an option ended, then execute."""
        position = np.asarray(observation.position_m[:, :2], float)
        remaining = observation.remaining_bit
        rate, snr = observation.rate_bps, observation.snr_db
        slot, active = observation.slot, observation.active
        n_missions, n = remaining.shape
        servable = contract.servable(rate.T, remaining.T)
        en_route = contract.hgad_choice(rate.T, snr.T, servable)
        has_data = (remaining > 0).any(axis=1)
        self.homebound |= ~has_data
        self.target[~has_data] = n
        self.hovering[~has_data] = False
        cols = np.arange(n_missions)
        # a target emptied on the way: the option is over
        flying = (self.target >= 0) & (self.target < n) & ~self.hovering
        emptied = flying & (remaining[cols, np.clip(self.target, 0, n - 1)] <= 0)
        self.target[emptied] = NO_SENSOR
        serve = en_route.copy()
        for _ in range(3):  # a pass of the point the UAV is at is masked: at most 3 rounds
            undecided = active & ~self.homebound & (self.target < 0)
            self._decide(np.flatnonzero(undecided), position, slot, remaining, rate)
            arrived = self._arrivals(position, active)
            if not arrived.size:
                break
            self.visited[arrived, self.target[arrived]] |= self.stay_left[arrived] > 0
            passing = arrived[self.stay_left[arrived] <= 0]
            self.target[passing] = NO_SENSOR
            self.hovering[arrived[self.stay_left[arrived] > 0]] = True
            if not passing.size:
                break
        goal = np.where(self.target >= 0, self.target, n)
        hovering = np.flatnonzero(active & self.hovering)
        if hovering.size:
            serve[hovering] = self._hover_slot(
                hovering, rate, remaining, servable, en_route, position, slot
            )
            goal = np.where(self.target >= 0, self.target, n)
        # a hover holds the hover point (moving onto it if the reported position was only
        # near); the last stay slot already flies on to the next option's goal
        goto = self.geometry.goals_m(goal)
        shown = np.where((self.target >= 0) & (self.target < n), self.target, NO_SENSOR)
        return BatchAction(serve=np.where(active, serve, NO_SENSOR), goto_m=goto, target=shown)

    def _arrivals(self, position: np.ndarray, active: np.ndarray) -> np.ndarray:
        """Missions that reach their (sensor) target's hover point now (not yet hovering)."""
        n = self.n_sensors
        going = np.flatnonzero(active & (self.target >= 0) & (self.target < n) & ~self.hovering)
        if not going.size:
            return going
        point = self.geometry.hover_m[self.target[going], going]
        gap = np.hypot(position[going, 0] - point[:, 0], position[going, 1] - point[:, 1])
        return going[gap <= ARRIVE_M]

    def _hover_slot(
        self,
        rows: np.ndarray,
        rate: np.ndarray,
        remaining: np.ndarray,
        servable: np.ndarray,
        en_route: np.ndarray,
        position: np.ndarray,
        slot: np.ndarray,
    ) -> np.ndarray:
        """Serve the targets of hovering missions ``rows``; where this is the last stay slot,
        choose the next option now (with the buffers as this slot leaves them)."""
        target = self.target[rows]
        can = servable[target, rows]
        serve = np.where(can, target, en_route[rows])
        got = np.where(
            can,
            contract.served_bits(rate[rows, target], remaining[rows, target], self.slot_s[rows]),
            0.0,
        )
        after = remaining[rows, target] - got
        self.silent[rows] = np.where(got > 0, 0, self.silent[rows] + 1)
        self.stay_left[rows] -= 1
        ends = (self.stay_left[rows] <= 0) | (after <= 0) | (self.silent[rows] >= SILENT_SLOTS)
        done = rows[ends]
        if done.size:
            self.hovering[done] = False
            self.target[done] = NO_SENSOR
            projected = np.array(remaining, float)
            projected[done, target[ends]] = after[ends]
            live = done[(projected[done] > 0).any(axis=1)]
            self.homebound[done[~np.isin(done, live)]] = True
            self.target[done[~np.isin(done, live)]] = self.n_sensors
            self._decide(live, position, slot, projected, rate)
        return serve
