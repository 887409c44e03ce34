"""Policies, resolved by name through :data:`POLICIES`."""

from __future__ import annotations

from collections.abc import Callable

from skymule.errors import SkymuleError
from skymule.policies.base import Action, MissionContext, Observation, Policy
from skymule.policies.greedy import Greedy
from skymule.policies.hgad import HGAD
from skymule.policies.optimal_fixed import OptimalFixed
from skymule.policies.planner import Planner
from skymule.scenario import PolicySpec

PolicyFactory = Callable[[PolicySpec], Policy]

POLICIES: dict[str, PolicyFactory] = {
    "greedy": lambda spec: Greedy(),
    "hgad": lambda spec: HGAD(spec.hover_threshold, spec.max_hover_s),
    "planner": lambda spec: Planner(),
    "optimal-fixed": lambda spec: OptimalFixed(),
}
"""Policy registry: name -> factory taking the scenario's ``[policy]`` section."""


def make_policy(spec: PolicySpec) -> Policy:
    """A fresh policy instance for one mission."""
    factory = POLICIES.get(spec.name)
    if factory is None:
        raise SkymuleError(
            f"policy.name = {spec.name!r} is not allowed; allowed: {', '.join(sorted(POLICIES))}"
        )
    return factory(spec)


__all__ = [
    "HGAD",
    "POLICIES",
    "Action",
    "Greedy",
    "MissionContext",
    "Observation",
    "Policy",
    "make_policy",
]
