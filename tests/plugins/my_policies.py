"""A user-written policy, imported by path in the conformance tests (``module:Class``)."""

from __future__ import annotations

import numpy as np

from skymule.policies.base import Action, MissionContext, Observation
from skymule.scenario import PolicySpec


class LargestBufferFirst:
    """Serve the sensor with the most data left that has a link; never hover."""

    name = "largest-buffer-first"

    def __init__(self, spec: PolicySpec) -> None:
        self.spec = spec

    def reset(self, context: MissionContext) -> None:
        """No state."""

    def act(self, observation: Observation) -> Action:
        usable = (observation.remaining_bit > 0) & (observation.rate_bps > 0)
        if not usable.any():
            return Action(serve=None)
        return Action(serve=int(np.argmax(np.where(usable, observation.remaining_bit, -1.0))))


class NotAPolicy:
    """Lacks act()."""

    name = "broken"
