"""Policies, resolved by name through :data:`POLICIES`, or your own by import path.

``policy.name`` (and ``--policy``/``--policies``) accepts a registry name,
``"package.module:Class"``, ``"rl:model.zip"`` or ``"learned:weights.npz"``. A policy is an
object with ``name``, ``reset`` and ``act``, in one of two forms
(:mod:`skymule.policies.base`): per mission, or batched (``batched = True``: B missions at
once, as Greedy, HGAD, hgad-robust and learned are). Its parameters come from the
scenario's ``[policy.params]`` table:

* a registered policy declares a pydantic parameter model at registration
  (``POLICIES.register("hgad", factory, params=HGADParams)``); ``factory(params)`` makes it;
* a ``module:Class`` plug-in that has a ``Params`` attribute (a pydantic model) is made as
  ``Class(params)`` with the validated table; without one, as ``Class(policy_spec)`` or
  ``Class()`` (older plug-ins).

The module is imported from ``PYTHONPATH`` or the current folder (sweep workers import it too),
and only when that policy is made: a file naming a plug-in imports nothing when it is read,
checked, or run under another policy.
"""

from __future__ import annotations

import importlib
import inspect
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel

from skymule.errors import SkymuleError
from skymule.policies.base import (
    Action,
    BatchAction,
    BatchObservation,
    BatchPolicy,
    MissionContext,
    Observation,
    Policy,
)
from skymule.policies.batched import Columns, PerMission, is_batched
from skymule.policies.builtin import HGAD, Greedy, RobustHGAD
from skymule.policies.registry import (
    LEARNED_PREFIX,
    POLICIES,
    WEIGHTS_PREFIX,
    HGADParams,
    NoParams,
    PolicyFactory,
    PolicySpec,
    RobustParams,
    RobustPlannerParams,
    check_policies,
    check_policy_name,
    import_target,
    policy_params_model,
    unknown_policies,
)

BatchFactory = Callable[[list[Any]], BatchPolicy]
"""Makes one batched policy for B missions from each mission's validated parameters."""


def _by_path(path: str) -> PolicyFactory:
    """A factory that imports ``module:Class`` when a policy is first made.

    The planners pull in scipy's LP machinery and the bounds, which `skymule --help`, the
    scenario schema (it reads this registry for parameter models) and the Greedy/HGAD paths
    do not need; registering them by import path, like plug-ins, keeps those light.
    """

    def factory(params: BaseModel) -> Policy | BatchPolicy:
        module, _, attribute = path.partition(":")
        made: Policy = getattr(importlib.import_module(module), attribute)()
        return made

    return factory


def _robust_batch(params: list[Any]) -> BatchPolicy:
    """hgad-robust for B missions: one policy per moving-average window, the rest per mission."""
    by_window: dict[int, list[int]] = {}
    for index, p in enumerate(params):
        by_window.setdefault(p.window_slots, []).append(index)
    parts: list[tuple[BatchPolicy, Any]] = []
    for window, cols in by_window.items():
        chosen = [params[i] for i in cols]
        policy = RobustHGAD(
            [p.hover_threshold for p in chosen],
            [p.max_hover_s for p in chosen],
            [p.fail_slots for p in chosen],
            window,
            [p.arrive_m for p in chosen],
        )
        parts.append((policy, cols))
    return parts[0][0] if len(parts) == 1 else Columns(parts)


POLICIES.register("greedy", lambda p: Greedy(), params=NoParams, batch=lambda ps: Greedy())
POLICIES.register(
    "hgad",
    lambda p: HGAD(p.hover_threshold, p.max_hover_s),
    params=HGADParams,
    batch=lambda ps: HGAD([p.hover_threshold for p in ps], [p.max_hover_s for p in ps]),
)
POLICIES.register(
    "hgad-robust", lambda p: RobustHGAD(**p.model_dump()), params=RobustParams, batch=_robust_batch
)
POLICIES.register("planner", _by_path("skymule.policies.planner:Planner"), params=NoParams)
POLICIES.register(
    "planner-robust",
    lambda p: importlib.import_module("skymule.policies.planner_robust").RobustPlanner(
        **p.model_dump()
    ),
    params=RobustPlannerParams,
)
POLICIES.register(
    "optimal-fixed", _by_path("skymule.policies.optimal_fixed:OptimalFixed"), params=NoParams
)
POLICIES.register("learned", _by_path("skymule.policies.learned:shipped_policy"), params=NoParams)


@dataclass(frozen=True)
class _Checked:
    """Wraps a plug-in's object: it must have name, reset and act."""

    name: str

    def check(self, policy: Any) -> Policy:
        missing = [m for m in ("name", "reset", "act") if not hasattr(policy, m)]
        if missing:
            raise SkymuleError(
                f"policy {self.name!r}: the object it makes has no {', '.join(missing)}; "
                "a policy needs name, reset(context) and act(observation)"
            )
        return policy


def _takes_argument(target: Any) -> bool:
    try:
        return any(
            p.default is inspect.Parameter.empty
            and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
            for p in inspect.signature(target).parameters.values()
        )
    except (TypeError, ValueError):
        return False


def make_policy(spec: PolicySpec) -> Policy | BatchPolicy:
    """A fresh policy for one mission, with its parameters from ``spec``: per-mission, or a
    batched one (run it as a batch of one)."""
    if spec.name.startswith(LEARNED_PREFIX):  # a trained model (skymule.policies.rl, extra rl)
        learned: Policy = importlib.import_module("skymule.policies.rl").RLPolicy(spec)
        return learned
    if spec.name.startswith(WEIGHTS_PREFIX):  # the learned option scorer, your own weights
        weights: BatchPolicy = importlib.import_module("skymule.policies.learned").learned_policy(
            spec.name
        )
        return weights
    if ":" not in spec.name:
        return POLICIES.get(spec.name)(spec.policy_params())
    target = import_target(spec.name)
    checked = _Checked(spec.name)
    params = spec.policy_params()
    if params is not None:
        return checked.check(target(params))
    return checked.check(target(spec) if _takes_argument(target) else target())


def _content(params: dict[str, Any]) -> str:
    """A ``[policy.params]`` table as text, equal for equal tables (key order aside)."""
    return json.dumps(params, sort_keys=True, default=repr)


def batch_policy(specs: Sequence[PolicySpec]) -> BatchPolicy:
    """One batched policy for B missions, mission b under ``specs[b]``.

    Missions under one registered batched policy share one instance (its parameters per
    mission); a batched plug-in gets one instance per distinct ``[policy]``; a per-mission
    policy one instance per mission (:class:`PerMission`). Several of these side by side are
    :class:`Columns`.
    """
    # sweeps repeat a few spec objects many times: each distinct object read once, each
    # distinct content validated once, and missions grouped by content, never by object
    ids = list(map(id, specs))  # specs is held: an id is not reused meanwhile
    by_content: dict[tuple[str, str], tuple[Any, Any]] = {}
    by_object: dict[int, tuple[Any, Any]] = {}
    for ident, spec in dict(zip(ids, specs, strict=True)).items():
        content = (spec.name, _content(spec.params))
        if content not in by_content:
            learned = spec.name.startswith(LEARNED_PREFIX)
            validated = None if learned else spec.policy_params()
            batched = ":" not in spec.name and POLICIES.meta(spec.name, "batch", None) is not None
            own = repr(validated) if validated is not None else content[1]
            by_content[content] = (validated, spec.name if batched else (spec.name, own))
        by_object[ident] = by_content[content]
    params: list[Any] = [by_object[ident][0] for ident in ids]
    keys = [by_object[ident][1] for ident in ids]
    groups: dict[Any, list[int]] = {}
    if len(set(keys)) == 1:
        groups[keys[0]] = list(range(len(keys)))
    else:
        for index, key in enumerate(keys):
            groups.setdefault(key, []).append(index)
    parts: list[tuple[BatchPolicy, Any]] = []
    for key, cols in groups.items():
        first = specs[cols[0]]
        if isinstance(key, str):
            factory: BatchFactory = POLICIES.meta(first.name, "batch")
            parts.append((factory([params[i] for i in cols]), cols))
            continue
        made = make_policy(first)
        if is_batched(made):
            parts.append((made, cols))  # type: ignore[arg-type]
        else:
            rest = [made, *(make_policy(specs[i]) for i in cols[1:])]
            parts.append((PerMission(rest), cols))  # type: ignore[arg-type]
    if len(parts) == 1:
        return parts[0][0]
    return Columns(parts)


def resolve_policy(name: str) -> PolicyFactory:
    """A factory ``spec -> policy`` for a registry name or ``"module:Attr"`` (the name checked
    now, a plug-in imported when the factory first makes one)."""
    check_policy_name(name)  # the one-line error for a name that names no policy

    def factory(spec: PolicySpec) -> Policy | BatchPolicy:
        return make_policy(spec if spec.name == name else spec.model_copy(update={"name": name}))

    return factory


__all__ = [
    "HGAD",
    "POLICIES",
    "Action",
    "BatchAction",
    "BatchObservation",
    "BatchPolicy",
    "Greedy",
    "HGADParams",
    "MissionContext",
    "NoParams",
    "Observation",
    "Policy",
    "RobustHGAD",
    "batch_policy",
    "check_policies",
    "check_policy_name",
    "make_policy",
    "policy_params_model",
    "resolve_policy",
    "unknown_policies",
]
