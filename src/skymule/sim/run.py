"""Run one mission: dispatch to the engine for its trajectory mode (above the engines)."""

from __future__ import annotations

from skymule.errors import SkymuleError
from skymule.policies.base import Policy
from skymule.sim.autonomous import run_autonomous
from skymule.sim.engine import run_fixed
from skymule.sim.log import MissionLog
from skymule.world import Mission


def run_mission(mission: Mission, policy: Policy) -> MissionLog:
    """Run one mission under ``policy`` (fixed or autonomous trajectory)."""
    if mission.mode == "fixed":
        return run_fixed(mission, policy)
    if mission.mode == "autonomous":
        return run_autonomous(mission, policy)
    raise SkymuleError(
        f"trajectory.mode = {mission.mode!r} is not supported; allowed: fixed, autonomous"
    )
