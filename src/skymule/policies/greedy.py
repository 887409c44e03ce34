"""Greedy: serve the strongest SNR among sensors with data left (the paper's baseline)."""

from __future__ import annotations

import numpy as np

from skymule.policies.base import Action, MissionContext, Observation


def greedy_choice(snr_db: np.ndarray, remaining_bit: np.ndarray) -> int | None:
    """argmax SNR over sensors with Q_i > 0; ties go to the lowest index; None if all empty."""
    candidates = np.where(remaining_bit > 0, snr_db, -np.inf)
    if not np.any(remaining_bit > 0):
        return None
    return int(np.argmax(candidates))


class Greedy:
    """Serve argmax SNR among sensors with data; never hover."""

    name = "greedy"

    def reset(self, context: MissionContext) -> None:
        """Greedy keeps no state."""

    def act(self, observation: Observation) -> Action:
        return Action(serve=greedy_choice(observation.snr_db, observation.remaining_bit))
