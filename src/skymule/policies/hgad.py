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
