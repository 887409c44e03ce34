"""Policies, resolved by name through :data:`POLICIES`, or your own by import path.

``policy.name`` (and ``--policy``/``--policies``) accepts a registry name or
``"package.module:Attr"``, where ``Attr`` is a policy class (or any callable) that takes no
argument or the scenario's ``[policy]`` section and returns an object with ``name``,
``reset(context)`` and ``act(observation)``. The module must be importable (on ``PYTHONPATH``;
sweep workers import it too).
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable

from skymule.errors import SkymuleError
from skymule.policies.base import Action, MissionContext, Observation, Policy
from skymule.policies.greedy import Greedy
from skymule.policies.hgad import HGAD
from skymule.scenario import PolicySpec

PolicyFactory = Callable[[PolicySpec], Policy]

POLICIES: dict[str, PolicyFactory] = {
    "greedy": lambda spec: Greedy(),
    "hgad": lambda spec: HGAD(spec.hover_threshold, spec.max_hover_s),
    "planner": lambda spec: _planner(),
    "optimal-fixed": lambda spec: _optimal_fixed(),
}
"""Policy registry: name -> factory taking the scenario's ``[policy]`` section."""


def _planner() -> Policy:
    # imported on use: the planners pull in scipy's LP machinery, which `skymule --help` and
    # the Greedy/HGAD paths do not need
    from skymule.policies.planner import Planner

    return Planner()


def _optimal_fixed() -> Policy:
    from skymule.policies.optimal_fixed import OptimalFixed

    return OptimalFixed()


def _imported_factory(name: str) -> PolicyFactory:
    module_name, _, attribute = name.partition(":")
    try:
        target = getattr(importlib.import_module(module_name), attribute)
    except (ImportError, AttributeError, ValueError) as exc:
        raise SkymuleError(
            f"policy.name = {name!r}: cannot import {attribute!r} from {module_name!r} ({exc})"
        ) from None
    if not callable(target):
        raise SkymuleError(f"policy.name = {name!r}: {attribute!r} is not a class or function")
    try:
        takes_spec = any(
            p.default is inspect.Parameter.empty
            and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
            for p in inspect.signature(target).parameters.values()
        )
    except (TypeError, ValueError):
        takes_spec = False

    def factory(spec: PolicySpec) -> Policy:
        policy = target(spec) if takes_spec else target()
        missing = [m for m in ("name", "reset", "act") if not hasattr(policy, m)]
        if missing:
            raise SkymuleError(
                f"policy.name = {name!r}: the object it makes has no {', '.join(missing)}; "
                "a policy needs name, reset(context) and act(observation)"
            )
        return policy

    return factory


def resolve_policy(name: str) -> PolicyFactory:
    """The factory for a registry name or a ``"module:Attr"`` import path."""
    factory = POLICIES.get(name)
    if factory is not None:
        return factory
    if name.startswith("rl:"):  # learned models, rl:path/to/model.zip (skymule.policies.rl)
        return lambda spec: importlib.import_module("skymule.policies.rl").RLPolicy(spec)
    if ":" in name:
        return _imported_factory(name)
    raise SkymuleError(
        f"policy.name = {name!r} is not allowed; allowed: {', '.join(sorted(POLICIES))} "
        "or an import path 'package.module:Class'"
    )


def unknown_policies(names: list[str]) -> list[str]:
    """The names among ``names`` that resolve to no policy (empty when all are fine)."""
    unknown = []
    for name in names:
        try:
            resolve_policy(name)
        except SkymuleError:
            unknown.append(name)
    return unknown


def make_policy(spec: PolicySpec) -> Policy:
    """A fresh policy instance for one mission."""
    return resolve_policy(spec.name)(spec)


__all__ = [
    "HGAD",
    "POLICIES",
    "Action",
    "Greedy",
    "MissionContext",
    "Observation",
    "Policy",
    "make_policy",
    "resolve_policy",
    "unknown_policies",
]
