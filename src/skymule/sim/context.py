"""What a policy may know before a mission starts: :class:`MissionContext` from a Mission."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import overload

import numpy as np

from skymule.errors import SkymuleError
from skymule.policies.base import MissionContext, read_only
from skymule.world import Mission


def autonomous_context(mission: Mission, peak_rate_bps: np.ndarray) -> MissionContext:
    """The context of an autonomous mission given its peak rates R*_i (N,) (the rate at each
    sensor's own hover point, computed for a whole batch at once)."""
    if mission.source is None:
        raise SkymuleError("autonomous missions need signal.source = 'model' or 'radiomap'")
    return MissionContext(
        sensor_names=mission.sensor_names,
        slot_s=mission.slot_s,
        n_slots=mission.n_slots,
        buffers_bit=mission.buffers_bit,
        peak_rate_bps=peak_rate_bps,
        mode=mission.mode,
        sensor_m=mission.sensor_m,
        hover_points_m=mission.hover_points_m,
        home_m=mission.home_m,
        max_step_m=mission.max_step_m,
        visit_radius_m=mission.visit_radius_m,
        navigator=mission.navigator,
        predict_snr_db=mission.source.snr_db,
        return_home=mission.return_home,
        rate_of_snr_bps=mission.rate_bps,
    )


def fixed_context(
    mission: Mission, rates_bps: np.ndarray, peak_rate_bps: np.ndarray
) -> MissionContext:
    """The context of a fixed-trajectory mission given its track's rates (K, N) and their
    peak (N,) (computed once for every mission on one track)."""
    track = mission.track
    assert track is not None
    return MissionContext(
        sensor_names=mission.sensor_names,
        slot_s=mission.slot_s,
        n_slots=mission.n_slots,
        buffers_bit=mission.buffers_bit,
        peak_rate_bps=peak_rate_bps,
        mode=mission.mode,
        sensor_m=mission.sensor_m,
        visit_radius_m=mission.visit_radius_m,
        track_rate_bps=rates_bps,
        track_hold_at_end=track.hold_at_end,
    )


class Contexts(Sequence[MissionContext]):
    """The B contexts of a batch, each made when first read (a policy that reads none of them,
    or a few, does not pay for the rest; sweeps run thousands of missions a batch).

    ``columns`` maps field names to (B, ...) arrays the engine already holds (peak rates,
    buffers, slot lengths): :func:`skymule.policies.base.stacked` reads them without making a
    context per mission."""

    def __init__(
        self,
        size: int,
        make: Callable[[int], MissionContext],
        columns: Mapping[str, np.ndarray] | None = None,
    ) -> None:
        self._size = size
        self._make = make
        self._made: dict[int, MissionContext] = {}
        self._columns = dict(columns or {})

    def stack(self, field: str) -> np.ndarray | None:
        """(B, ...) the field of every context, read-only, if the engine holds it; else None."""
        values = self._columns.get(field)
        return None if values is None else read_only(values)

    def __len__(self) -> int:
        return self._size

    @overload
    def __getitem__(self, index: int) -> MissionContext: ...

    @overload
    def __getitem__(self, index: slice) -> list[MissionContext]: ...

    def __getitem__(self, index: int | slice) -> MissionContext | list[MissionContext]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._size))]
        if not -self._size <= index < self._size:
            raise IndexError(index)
        index %= self._size
        made = self._made.get(index)
        if made is None:
            made = self._made[index] = self._make(index)
        return made
