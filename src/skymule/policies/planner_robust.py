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

With ``window_slots = 1``, ``arrive_m = 0`` and no failed slots it is exactly the planner
(tested). Wind and battery are not in what a policy may see (:class:`MissionContext`,
:class:`Observation`): the engine's return-home override steers the UAV home in time under
them, as for every policy; this planner adds nothing there.
"""

from __future__ import annotations

import math

import numpy as np

from skymule.policies.base import Action, MissionContext, Observation
from skymule.policies.planner import XY, Planner


class RobustPlanner(Planner):
    """The tour planner plus the silent-tower, smoothing and arrival rules (module doc)."""

    name = "planner-robust"

    def __init__(
        self,
        fail_slots: int = 3,
        backoff_s: float = 60.0,
        window_slots: int = 3,
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
                backoff = math.ceil(self.backoff_s / self._slot_s() - 1e-9)
                self._down_until[sensor] = slot + backoff * 2 ** int(self._times_down[sensor] - 1)
                self._run_sensor, self._run = -1, 0
        up = (self._down_until <= slot) | (observation.rate_bps > 0)
        self._down_until[up] = -1
        if not np.array_equal(up, self._up):
            changed = bool(((up != self._up) & (remaining > 0)).any())
            self._up = up
        return changed

    def act(self, observation: Observation) -> Action:
        self._smooth(observation)
        if self._update_links(observation) and self._plan is not None:
            self._replan(observation)  # a sensor went down or came back: plan around it
        action = super().act(observation)
        serve = action.serve
        self._last = None if serve is None else (serve, float(observation.remaining_bit[serve]))
        return action
