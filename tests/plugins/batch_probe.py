"""Batched plug-ins that record how the engine calls them (sweep batching tests)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np
from pydantic import BaseModel

from skymule.policies.base import BatchAction, BatchObservation, MissionContext


class ServeFirstProbe:
    """Serve sensor 0 while it has data, B missions at once; no ``Params``. Records the size
    of every ``reset`` and ``act`` batch in ``calls`` (class-wide)."""

    name = "serve-first-probe"
    batched = True
    calls: ClassVar[list[tuple[str, int]]] = []

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        type(self).calls.append(("reset", len(contexts)))

    def act(self, observation: BatchObservation) -> BatchAction:
        type(self).calls.append(("act", observation.size))
        return BatchAction(serve=np.where(observation.remaining_bit[:, 0] > 0, 0, -1))


class ServeFirstProbeParams(BaseModel):
    sensor: int = 0


class ServeFirstProbeWithParams(ServeFirstProbe):
    """:class:`ServeFirstProbe` with a ``Params`` model (``sensor``: the one it serves)."""

    Params = ServeFirstProbeParams
    calls: ClassVar[list[tuple[str, int]]] = []

    def __init__(self, params: ServeFirstProbeParams) -> None:
        self.sensor = params.sensor

    def act(self, observation: BatchObservation) -> BatchAction:
        type(self).calls.append(("act", observation.size))
        left = observation.remaining_bit[:, self.sensor] > 0
        return BatchAction(serve=np.where(left, self.sensor, -1))
