"""The upper bound of a built mission, whatever its trajectory mode (``skymule bound``)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from skymule.bounds.fixed import fixed_mission_bound
from skymule.bounds.result import BoundError, MissionBound
from skymule.world import Mission


def _autonomous_mission_bound(mission: Mission) -> MissionBound:
    """``skymule.bounds.autonomous.autonomous_bound`` wrapped as a :class:`MissionBound`."""
    try:
        from skymule.bounds.autonomous import autonomous_bound
    except ModuleNotFoundError as exc:
        if exc.name != "skymule.bounds.autonomous":
            raise
        raise BoundError(
            "bound: the autonomous bound is not available (module skymule.bounds.autonomous "
            "is missing); only trajectory.mode = 'fixed' is supported here"
        ) from None
    result = autonomous_bound(mission)
    return MissionBound(
        scenario=mission.scenario.name,
        mode="autonomous",
        upper_bound_bit=float(result.upper_bound_bit),
        method=result.method,
        status=result.status,
        solve_time_s=float(result.solve_time_s),
        total_buffer_bit=float(np.sum(mission.buffers_bit)),
        warnings=result.warnings,
    )


MISSION_BOUNDS: dict[str, Callable[[Mission], MissionBound]] = {
    "fixed": fixed_mission_bound,
    "autonomous": _autonomous_mission_bound,
}
"""``trajectory.mode`` -> bound of a built mission."""


def unsupported_reason(mission: Mission) -> str | None:
    """One line naming a trajectory mode the bounds do not cover, or None."""
    mode = mission.mode
    if mode not in MISSION_BOUNDS:
        return f"bound: trajectory.mode = {mode!r} is not supported; allowed: " + ", ".join(
            sorted(MISSION_BOUNDS)
        )
    return None


def mission_bound(mission: Mission) -> MissionBound:
    """Upper bound on the bits any policy downloads in ``mission``.

    Raises:
        BoundError: the scenario has something the bound does not model (a trajectory mode
            without a bound, fading on a fixed trajectory), or the autonomous bound is not
            installed.
    """
    reason = unsupported_reason(mission)
    if reason is not None:
        raise BoundError(reason)
    result = MISSION_BOUNDS[mission.mode](mission)
    # no policy downloads more than the buffers hold: clipping keeps it a bound and drops
    # solver round-off above the total
    return replace(result, upper_bound_bit=min(result.upper_bound_bit, result.total_buffer_bit))
