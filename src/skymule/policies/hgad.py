"""HGAD: Hover-based Greedy Adaptive Download on a fixed trajectory.

Follows the slot contract (``docs/contract.md``; the paper's Section IV-B as we pin it down),
whose one implementation is :mod:`skymule.sim.contract`:

* peak rate R*_i from the historical data; trigger threshold gamma_i = hover_threshold * R*_i;
* at the start of each slot, a sensor whose rate is below gamma_i stops cooling down;
* when not hovering, serve argmax rate among sensors with data (ties: higher SNR, then lower
  index); if that sensor has R_i > 0, R_i >= gamma_i, data left after this slot's download
  and is not cooling down, start hovering on it with budget
  T_hover = min(Q_i / R*_i, max_hover_s) (Q_i after this slot's download);
* while hovering, serve that sensor and count dt off the budget; the hover ends after the slot
  in which the budget reaches 0 or the buffer empties, and the sensor then cools down;
* the trigger slot and every hover slot keep the UAV where it is.

On an autonomous trajectory it follows the paper's Alg. 2 instead (buffer-priority tour,
hovering at each target's hover point; see :mod:`skymule.policies.autonomous`).
"""

from __future__ import annotations

import numpy as np

from skymule.policies.autonomous import HGADTour, Priority
from skymule.policies.base import Action, MissionContext, Observation
from skymule.sim import contract


def hgad_choice(rate_bps: np.ndarray, snr_db: np.ndarray, remaining_bit: np.ndarray) -> int | None:
    """argmax rate over sensors with data and R > 0; ties: higher SNR, then lowest index.

    One mission of :func:`skymule.sim.contract.hgad_choice`.
    """
    rate = rate_bps[:, None]
    usable = contract.servable(rate, remaining_bit[:, None])
    choice = int(contract.hgad_choice(rate, snr_db[:, None], usable)[0])
    return None if choice == contract.NO_SENSOR else choice


class HGAD:
    """Hover where the rate reaches its peak; see the module docstring for the rules."""

    name = "hgad"

    def __init__(
        self,
        hover_threshold: float = 1.0,
        max_hover_s: float = 60.0,
        priority: Priority = "initial",
    ) -> None:
        self.hover_threshold = hover_threshold
        self.max_hover_s = max_hover_s
        self.priority: Priority = priority
        self._tour: HGADTour | None = None
        self._slot_s = np.ones(1)
        self._max_hover_s = np.full(1, max_hover_s)
        self._threshold_bps = np.zeros(0)
        self._peak_bps = np.zeros(0)
        self._state = contract.HoverState.start(0, 1)

    def reset(self, context: MissionContext) -> None:
        self._slot_s = np.full(1, context.slot_s)
        self._max_hover_s = np.full(1, self.max_hover_s)
        self._peak_bps = np.array(context.peak_rate_bps, float)
        self._threshold_bps = self.hover_threshold * self._peak_bps
        self._state = contract.HoverState.start(len(self._peak_bps), 1)
        autonomous = context.mode == "autonomous"
        self._tour = HGADTour(context, self.max_hover_s, self.priority) if autonomous else None

    def act(self, observation: Observation) -> Action:
        if self._tour is not None:
            en_route = hgad_choice(
                observation.rate_bps, observation.snr_db, observation.remaining_bit
            )
            return self._tour.act(observation, en_route)
        # one mission as a batch of one: (N, 1) arrays through the contract
        rate = observation.rate_bps[:, None]
        remaining = observation.remaining_bit[:, None]
        usable = contract.servable(rate, remaining)
        choice = contract.hgad_choice(rate, observation.snr_db[:, None], usable)
        sensor = contract.hover_sensor_or(self._state, choice)
        cell = contract.cells(sensor)
        left = remaining.reshape(-1).take(cell)
        rate_served = rate.reshape(-1).take(cell)
        bits = contract.served_bits(rate_served, left, self._slot_s)
        hover = contract.hgad_update(
            self._state,
            sensor=sensor,
            cell=cell,
            rate_bps=rate,
            rate_served_bps=rate_served,
            left_after_bit=left - bits,
            threshold_bps=self._threshold_bps,
            peak_rate_bps=self._peak_bps,
            max_hover_s=self._max_hover_s,
            slot_s=self._slot_s,
        )
        serve = int(sensor[0])
        if serve == contract.NO_SENSOR:
            return Action(serve=None)
        return Action(serve=serve, hover=bool(hover[0]))


class RobustHGAD(HGAD):
    """HGAD that survives faults (issue 15): a silent tower ends the hover, noisy SNR is
    smoothed. Plain :class:`HGAD` is unchanged; this adds two rules on top of it:

    * **silent tower**: a slot "failed" when the sensor served in the previous slot did not
      lose any data (its buffer is what it was), i.e. nothing was delivered. After
      ``fail_slots`` consecutive failed slots the hover (or, autonomous, the target) is
      abandoned and the sensor cools down like after a normal hover, so the UAV moves on
      instead of hovering up to ``max_hover_s`` on a dead link;
    * **GPS error** (autonomous): a reported position within ``arrive_m`` of a hover point
      counts as arrived (0: exact, as HGAD; default 10 m), and the hover keeps flying to the point;
    * **noisy SNR**: choices and hover triggers use the mean of the last ``window_slots``
      observed rates (a moving estimate), kept at 0 for a sensor that reports nothing now
      (a dead link is never chosen on its past).

    With ``window_slots = 1``, ``arrive_m = 0`` and no failed slots it is exactly HGAD.
    """

    name = "hgad-robust"

    def __init__(
        self,
        hover_threshold: float = 1.0,
        max_hover_s: float = 60.0,
        fail_slots: int = 3,
        window_slots: int = 2,
        arrive_m: float = 10.0,
        priority: Priority = "initial",
    ) -> None:
        super().__init__(hover_threshold, max_hover_s, priority)
        self.fail_slots = fail_slots
        self.window_slots = window_slots
        self.arrive_m = arrive_m
        self._recent: list[np.ndarray] = []
        self._last: tuple[int, float] | None = None  # (sensor served, its buffer before)
        self._fails = 0

    def reset(self, context: MissionContext) -> None:
        super().reset(context)
        if self._tour is not None:
            self._tour = HGADTour(
                context, self.max_hover_s, self.priority, self.fail_slots, self.arrive_m
            )
        self._recent = []
        self._last = None
        self._fails = 0

    def _count_failure(self, remaining_bit: np.ndarray) -> None:
        """Update the run of consecutive slots in which the served sensor delivered nothing."""
        if self._last is None:
            self._fails = 0
            return
        sensor, before = self._last
        self._fails = self._fails + 1 if remaining_bit[sensor] >= before else 0

    def act(self, observation: Observation) -> Action:
        if self._tour is not None:
            return super().act(observation)
        self._count_failure(observation.remaining_bit)
        state = self._state
        hovered = int(state.sensor[0])
        if hovered != contract.NO_SENSOR and self._fails >= self.fail_slots:
            # the tower went silent: give up this hover; it cools down like a finished one
            state.sensor[0] = contract.NO_SENSOR
            state.cooling[hovered] = True
            self._fails = 0
        self._recent = [*self._recent, observation.rate_bps][-self.window_slots :]
        smoothed = np.where(observation.rate_bps > 0, np.mean(self._recent, axis=0), 0.0)
        smoothed.flags.writeable = False
        seen = Observation(
            slot=observation.slot,
            position_m=observation.position_m,
            snr_db=observation.snr_db,
            rate_bps=smoothed,
            remaining_bit=observation.remaining_bit,
        )
        action = super().act(seen)
        if action.serve is None:
            self._last, self._fails = None, 0
        else:
            if self._last is not None and self._last[0] != action.serve:
                self._fails = 0
            self._last = (action.serve, float(observation.remaining_bit[action.serve]))
        return action
