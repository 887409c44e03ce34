"""Fault models for resilience studies: pure, seeded, engine-independent (``docs/faults.md``).

A scenario lists faults under ``[[faults]]`` (``kind`` + ``params``); all are off by default.
:func:`draw_faults` draws one mission's :class:`FaultDraws` (per-slot masks and errors) from
:func:`fault_rng`; :class:`Wind` and :class:`Battery` act on motion and energy.
"""

from skymule.faults.draws import (
    FAULT_STREAM,
    TOWER_FIELDS,
    UAV_FAULT_STREAM,
    FaultDraws,
    FaultEntry,
    draw_faults,
    draw_uav_faults,
    fault_rng,
    no_faults,
    stack_draws,
    uav_fault_rng,
)
from skymule.faults.motion import Battery, Wind
from skymule.faults.specs import FAULT_KINDS, SINGLE_KINDS, fault_params

__all__ = [
    "FAULT_KINDS",
    "FAULT_STREAM",
    "SINGLE_KINDS",
    "TOWER_FIELDS",
    "UAV_FAULT_STREAM",
    "Battery",
    "FaultDraws",
    "FaultEntry",
    "Wind",
    "draw_faults",
    "draw_uav_faults",
    "fault_params",
    "fault_rng",
    "no_faults",
    "stack_draws",
    "uav_fault_rng",
]
