"""Greedy: serve the strongest SNR among sensors with data left (the paper's baseline)."""

from __future__ import annotations

import numpy as np

from skymule.policies.autonomous import GreedyTour
from skymule.policies.base import Action, MissionContext, Observation
from skymule.sim import contract


def greedy_choice(
    snr_db: np.ndarray, rate_bps: np.ndarray, remaining_bit: np.ndarray
) -> int | None:
    """argmax SNR over sensors with Q_i > 0 and R_i > 0; ties go to the lowest index; None if
    no sensor is servable. One mission of :func:`skymule.sim.contract.greedy_choice`."""
    usable = contract.servable(rate_bps[:, None], remaining_bit[:, None])
    choice = int(contract.greedy_choice(snr_db[:, None], usable)[0])
    return None if choice == contract.NO_SENSOR else choice


class Greedy:
    """Serve argmax SNR among sensors with data; never hover.

    On an autonomous trajectory it also steers: a nearest-first tour of the hover points,
    then home (paper Alg. 1; see :mod:`skymule.policies.autonomous`).
    """

    name = "greedy"

    def __init__(self) -> None:
        self._tour: GreedyTour | None = None

    def reset(self, context: MissionContext) -> None:
        """Fixed paths: no state. Autonomous: a fresh tour."""
        self._tour = GreedyTour(context) if context.mode == "autonomous" else None

    def act(self, observation: Observation) -> Action:
        serve = greedy_choice(observation.snr_db, observation.rate_bps, observation.remaining_bit)
        if self._tour is None:
            return Action(serve=serve)
        goto_m, target = self._tour.steer(observation)
        return Action(serve=serve, goto_m=goto_m, target=target)
