"""HGAD: Hover-based Greedy Adaptive Download on a fixed trajectory.

Follows the slot contract in DESIGN.md exactly (the paper's Section IV-B as we pin it down):

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
from skymule.policies.base import Action, MissionContext, Observation, slot_download_bit


def hgad_choice(rate_bps: np.ndarray, snr_db: np.ndarray, remaining_bit: np.ndarray) -> int | None:
    """argmax rate over sensors with data; ties: higher SNR, then lowest index."""
    has_data = remaining_bit > 0
    if not np.any(has_data):
        return None
    # lexsort sorts ascending by the last key first: rate, then SNR, then -index
    index = np.arange(len(rate_bps))
    rate = np.where(has_data, rate_bps, -np.inf)
    snr = np.where(has_data, snr_db, -np.inf)
    order = np.lexsort((-index, snr, rate))
    return int(order[-1])


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
        self._slot_s = 1.0
        self._threshold_bps = np.zeros(0)
        self._peak_bps = np.zeros(0)
        self._cooling = np.zeros(0, bool)
        self._hover_sensor: int | None = None
        self._budget_s = 0.0

    def reset(self, context: MissionContext) -> None:
        self._slot_s = context.slot_s
        self._peak_bps = np.asarray(context.peak_rate_bps, float)
        self._threshold_bps = self.hover_threshold * self._peak_bps
        self._cooling = np.zeros(len(self._peak_bps), bool)
        self._hover_sensor = None
        self._budget_s = 0.0
        autonomous = context.mode == "autonomous"
        self._tour = HGADTour(context, self.max_hover_s, self.priority) if autonomous else None

    def act(self, observation: Observation) -> Action:
        rate = observation.rate_bps
        if self._tour is not None:
            en_route = hgad_choice(rate, observation.snr_db, observation.remaining_bit)
            return self._tour.act(observation, en_route)
        self._cooling &= ~(rate < self._threshold_bps)

        if self._hover_sensor is not None:
            hovered = self._hover_sensor
            self._budget_s -= self._slot_s
            left_after = observation.remaining_bit[hovered] - slot_download_bit(
                observation, hovered, self._slot_s
            )
            if self._budget_s <= 1e-12 or left_after <= 0:
                self._hover_sensor = None
                self._cooling[hovered] = True
            return Action(serve=hovered, hover=True)

        sensor = hgad_choice(rate, observation.snr_db, observation.remaining_bit)
        if sensor is None:
            return Action(serve=None)
        left_after = observation.remaining_bit[sensor] - slot_download_bit(
            observation, sensor, self._slot_s
        )
        triggers = (
            rate[sensor] > 0
            and self._peak_bps[sensor] > 0
            and rate[sensor] >= self._threshold_bps[sensor]
            and left_after > 0
            and not self._cooling[sensor]
        )
        if not triggers:
            return Action(serve=sensor)
        self._budget_s = min(left_after / self._peak_bps[sensor], self.max_hover_s)
        self._hover_sensor = sensor
        return Action(serve=sensor, hover=True)
