"""``planner-robust``: the tour planner with three rules for faulty links (issue 15).

The plain :class:`~skymule.policies.planner.Planner` plans on the rates it predicts and
serves what it sees; under faults that goes wrong in three ways, each fixed by one rule here
(parameters in the scenario's ``[policy.params]``, see ``docs/resilience.md``):

* **Silent tower.** The planner serves its target at a hover point whatever it observes, for
  the slots its plan allotted; a tower in an outage delivers nothing for all of them. Here a
  slot *failed* when the sensor served in the previous slot kept all its data (nothing was
  delivered). After ``fail_slots`` consecutive failed slots on one sensor it is marked
  *down* for a back-off of ``backoff_s`` (doubled each further time it goes down) and the
  tour is re-planned at once without it (its predicted rates are 0 while down). It is
  back up when the back-off ends or as soon as it reports an SNR again (a dead link reports
  nothing, ``docs/faults.md``), and the tour is then re-planned with it.
* **Noisy SNR.** The planner compares the observed SNR with the model's prediction and, past
  ``replan_db``, re-plans with the offset as a bias; it also picks the en-route sensor and
  decides whether the target empties this slot from the observed rate. Here all three use
  the mean offset (observed - predicted SNR) over the last ``window_slots`` slots in which
  the sensor reported, added to this slot's prediction: the offset, unlike the SNR, does not
  change as the UAV moves, so a short moving mean of it filters noise without lagging the
  geometry. A sensor that reports nothing now counts as rate 0 (never chosen on its past).
  Without a predictor the observed rates themselves are averaged.
* **GPS error.** The planner tests arrival exactly, so with any position error it never
  arrives (it keeps flying to the point, serving en route). Here a reported position within
  ``arrive_m`` of the hover point counts as arrived, and the hover keeps flying to the point.

* **Wind.** Wind is not in what a policy is told (:class:`MissionContext`), but the UAV
  sees its own positions: a slot in which it was sent a full straight step along the in-fence
  path and moved *less*, in exactly that direction, is what the engine's wind triangle does
  (``docs/faults.md``). Every such slot gives the ground velocity v (|v| < V, the speed cap)
  and so one circle the wind w lies on, |v - w| = V; the estimate is the least-squares fit
  (:meth:`RobustPlanner._estimate_wind`). Once ``WIND_MIN_SLOTS`` such slots are in, every
  leg is timed with that wind (``Planner._set_wind``; a tailwind never speeds the UAV up),
  so tours and the way home fit the time left. Reports that do not fit a straight step (off
  its line or longer: GPS error, projected into the fence) count as noisy; while they are
  more than a ``NOISY_SHARE``-th of the slowed slots the wind is not used. Without wind,
  nothing changes. The battery is not observable: the engine's battery override brings the
  UAV home.

With ``window_slots = 1``, ``arrive_m = 0`` and no failed or slowed slots it is exactly the
planner (tested).
"""

from __future__ import annotations

import math

import numpy as np

from skymule.policies.base import Action, MissionContext, Observation
from skymule.policies.planner import XY, Planner
from skymule.rules.contract import slots_to_cover

#: Slowed slots the wind estimate keeps (the latest).
WIND_SAMPLES = 200

#: Slowed slots needed before the legs are timed with a wind.
WIND_MIN_SLOTS = 3

#: The wind is used only while slowed slots outnumber noisy ones (off the commanded line, or
#: longer than a step: inexact position reports) this many times.
NOISY_SHARE = 4

#: The legs are re-timed (and the tour re-planned) when the wind estimate moves this much [m/s].
WIND_CHANGE_MPS = 0.25


class RobustPlanner(Planner):
    """The tour planner plus the silent-tower, smoothing and arrival rules (module doc)."""

    name = "planner-robust"

    def __init__(
        self,
        fail_slots: int = 3,
        backoff_s: float = 60.0,
        window_slots: int = 5,
        arrive_m: float = 10.0,
    ) -> None:
        super().__init__()
        self.fail_slots = fail_slots
        self.backoff_s = backoff_s
        self.window_slots = window_slots
        self.arrive_m = arrive_m

    def reset(self, context: MissionContext) -> None:
        super().reset(context)
        n = self._n
        self._up = np.ones(n, bool)
        self._down_until = np.full(n, -1, np.int64)  # first slot the sensor is up again
        self._times_down = np.zeros(n, np.int64)
        self._last: tuple[int, float] | None = None  # (sensor served, its buffer before)
        self._run_sensor, self._run = -1, 0  # consecutive failed slots on one sensor
        self._window: list[np.ndarray] = []  # last offsets [dB] (or rates without predictor)
        self._offset: np.ndarray | None = None
        self._seen = np.zeros(n)
        self._sent: tuple[XY, XY] | None = None  # (reported position, goal) of the last slot
        self._slowed: list[np.ndarray] = []  # ground velocities [m/s] of slowed slots
        self._noisy = 0  # slots whose reported step did not fit the commanded one

    # --- what the planner sees: masked by the down marks, smoothed -----------------------------

    def _rates(self, snr_db: np.ndarray | None, count: int) -> np.ndarray:
        return super()._rates(snr_db, count) * self._up

    def _hover_rates(self, altitude_m: float) -> np.ndarray:
        return super()._hover_rates(altitude_m) * self._up

    def _snr_offset(self, observation: Observation) -> np.ndarray | None:
        return self._offset

    def _seen_rate_bps(self, observation: Observation) -> np.ndarray:
        return self._seen

    def _arrived(self, here: XY, goal: XY) -> bool:
        return super()._arrived(here, goal) or math.dist(here, goal) <= self.arrive_m

    def _hover_goto(self, goal: XY) -> XY | None:
        return goal if self.arrive_m > 0 else None

    def _smooth(self, observation: Observation) -> None:
        """This slot's smoothed offset and seen rates (see the module doc)."""
        reporting = observation.rate_bps > 0
        position = observation.position_m
        predicted = self._predict_snr(position[None, :2], position[2])
        offset = None if predicted is None else observation.snr_db - predicted[0]
        sample = observation.rate_bps if offset is None else offset
        self._window = [*self._window, np.asarray(sample, float)][-self.window_slots :]
        if self.window_slots == 1:  # exactly what the plain planner sees
            self._offset, self._seen = offset, observation.rate_bps
            return
        stack = np.array(self._window)
        finite = np.isfinite(stack)
        mean = np.where(finite, stack, 0.0).sum(axis=0) / np.maximum(finite.sum(axis=0), 1)
        if predicted is None or offset is None:
            self._offset, self._seen = None, np.where(reporting, mean, 0.0)
            return
        assert self._context is not None and self._context.rate_of_snr_bps is not None
        self._offset = np.where(np.isfinite(offset), mean, offset)
        modelled = reporting & np.isfinite(predicted[0])  # else the observed rate as it is
        estimate = self._context.rate_of_snr_bps(np.where(modelled, predicted[0] + mean, -np.inf))
        self._seen = np.where(modelled, estimate, np.where(reporting, observation.rate_bps, 0.0))

    # --- silent towers ------------------------------------------------------------------------

    def _update_links(self, observation: Observation) -> bool:
        """Count failed slots, mark sensors down / up; True if the set of usable ones changed."""
        slot, remaining = observation.slot, observation.remaining_bit
        changed = False
        if self._last is not None:
            sensor, before = self._last
            if remaining[sensor] >= before:  # served last slot, delivered nothing
                self._run = self._run + 1 if sensor == self._run_sensor else 1
                self._run_sensor = sensor
            else:
                self._run_sensor, self._run = -1, 0
            if self._run >= self.fail_slots:
                self._times_down[sensor] += 1
                backoff = int(slots_to_cover(self.backoff_s, self._slot_s()))
                self._down_until[sensor] = slot + backoff * 2 ** int(self._times_down[sensor] - 1)
                self._run_sensor, self._run = -1, 0
        up = (self._down_until <= slot) | (observation.rate_bps > 0)
        self._down_until[up] = -1
        if not np.array_equal(up, self._up):
            changed = bool(((up != self._up) & (remaining > 0)).any())
            self._up = up
        return changed

    # --- wind ---------------------------------------------------------------------------------

    def _slowed_velocity(self, here: XY) -> np.ndarray | None:
        """Ground velocity [m/s] of the last slot if the wind slowed it (see the module doc).

        Counts a slot whose report does not fit a straight full step (off its line, or longer)
        as *noisy*: position reports that are not exact (GPS error) make any fit meaningless.
        """
        if self._sent is None:
            return None
        assert self._context is not None and self._context.navigator is not None
        start, goal = self._sent
        path = np.asarray(self._context.navigator.shortest_path(start, goal), float)
        if len(path) < 2:
            return None
        first = path[1] - path[0]
        length = float(np.hypot(*first))
        if length < self._step:  # not a full straight step (a corner, or the goal is close)
            return None
        unit = first / length
        moved = np.subtract(here, start)
        along = float(moved @ unit)
        across = abs(float(moved[0] * unit[1] - moved[1] * unit[0]))
        tol = 1e-6 * self._step
        if across > tol or along > self._step + tol:
            self._noisy += 1
            return None
        if not tol < along < self._step - tol:
            return None
        velocity: np.ndarray = unit * along / self._slot_s()
        return velocity

    def _estimate_wind(self) -> np.ndarray:
        """Least-squares wind w [m/s] with |v - w| = V for every slowed velocity v.

        Two circles meet twice, so a local fit can settle on the wrong point: Gauss-Newton
        starts from the best of a 1 m/s grid over |w| < V, the previous estimate and the
        smallest wind that explains each slot (a headwind of V - |v|: exact when every slot
        so far went the same way, where every point of that one circle fits).
        """
        speed = self._step / self._slot_s()
        velocity = np.array(self._slowed)
        norm = np.hypot(velocity[:, 0], velocity[:, 1])

        def cost(wind: np.ndarray) -> np.ndarray:  # (P, 2) -> (P,) mean squared residual
            diff = velocity[None, :, :] - wind[:, None, :]
            return np.mean((np.hypot(diff[..., 0], diff[..., 1]) - speed) ** 2, axis=1)

        axis = np.arange(-math.floor(speed), math.floor(speed) + 1.0)
        grid = np.stack(np.meshgrid(axis, axis), axis=-1).reshape(-1, 2)
        grid = grid[np.hypot(grid[:, 0], grid[:, 1]) < speed]
        headwind = np.mean(velocity * ((norm - speed) / norm)[:, None], axis=0)
        starts = [headwind[None], grid]
        if self._wind_mps is not None:
            starts.append(self._wind_mps[None])
        candidates = np.vstack(starts)
        wind = candidates[int(np.argmin(cost(candidates)))]
        for _ in range(20):  # Gauss-Newton on r_k = |v_k - w| - V
            diff = velocity - wind
            dist = np.maximum(np.hypot(diff[:, 0], diff[:, 1]), 1e-9)
            step = np.linalg.lstsq(-diff / dist[:, None], speed - dist, rcond=None)[0]
            wind = wind + step
            if float(np.hypot(*step)) < 1e-9:
                break
        size = float(np.hypot(*wind))
        return wind * min(1.0, 0.95 * speed / size) if size > 0 else wind

    def _update_wind(self, observation: Observation) -> bool:
        """Add the last slot if the wind slowed it; True when the wind the legs are timed
        with changed (by ``WIND_CHANGE_MPS`` or more, or to / from none)."""
        velocity = self._slowed_velocity(_xy2(observation.position_m))
        if velocity is not None:
            self._slowed = [*self._slowed, velocity][-WIND_SAMPLES:]
        count = len(self._slowed)
        trusted = count >= WIND_MIN_SLOTS and NOISY_SHARE * self._noisy <= count
        if not trusted:
            if self._wind_mps is None:
                return False
            self._set_wind(None)
            return True
        if velocity is None and self._wind_mps is not None:
            return False
        wind = self._estimate_wind()
        if self._wind_mps is not None and np.hypot(*(wind - self._wind_mps)) < WIND_CHANGE_MPS:
            return False
        self._set_wind(wind)
        return True

    def act(self, observation: Observation) -> Action:
        self._smooth(observation)
        links = self._update_links(observation)
        wind = self._update_wind(observation)
        if (links or wind) and self._plan is not None:
            self._replan(observation)  # a sensor went down or came back, or the wind: re-plan
        action = super().act(observation)
        serve = action.serve
        self._last = None if serve is None else (serve, float(observation.remaining_bit[serve]))
        here = _xy2(observation.position_m)
        self._sent = None if action.goto_m is None else (here, action.goto_m)
        return action


def _xy2(point: np.ndarray) -> XY:
    return (float(point[0]), float(point[1]))
