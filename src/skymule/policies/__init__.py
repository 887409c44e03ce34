"""Policies, resolved by name through :data:`POLICIES`, or your own by import path.

``policy.name`` (and ``--policy``/``--policies``) accepts a registry name or
``"package.module:Class"``. A policy is an object with ``name``, ``reset`` and ``act``, in one
of two forms (:mod:`skymule.policies.base`): per mission, or batched (``batched = True``:
B missions at once, as Greedy, HGAD and hgad-robust are). Its parameters come from the
scenario's ``[policy.params]`` table:

* a registered policy declares a pydantic parameter model at registration
  (``POLICIES.register("hgad", factory, params=HGADParams)``); ``factory(params)`` makes it;
* a ``module:Class`` plug-in that has a ``Params`` attribute (a pydantic model) is made as
  ``Class(params)`` with the validated table; without one, as ``Class(policy_spec)`` or
  ``Class()`` (older plug-ins).

The module is imported from ``PYTHONPATH`` or the current folder (sweep workers import it too).
"""

from __future__ import annotations

import importlib
import inspect
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Protocol

from pydantic import BaseModel, ConfigDict, Field

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
from skymule.registry import Registry


class PolicySpec(Protocol):
    """What a factory reads of a scenario's ``[policy]`` section
    (:class:`skymule.scenario.PolicySpec`, which validates against this registry)."""

    name: str
    params: dict[str, Any]

    def policy_params(self) -> BaseModel | None: ...

    def model_copy(self, *, update: dict[str, Any]) -> Any: ...


class NoParams(BaseModel):
    """Parameter model of a policy without parameters (an empty ``[policy.params]``)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)


class HGADParams(NoParams):
    hover_threshold: Annotated[float, Field(gt=0, le=1)] = 1.0
    """Fraction of the peak rate that triggers a hover."""
    max_hover_s: Annotated[float, Field(gt=0)] = 60.0
    """Longest hover [s]."""


class RobustParams(HGADParams):
    fail_slots: Annotated[int, Field(ge=1)] = 3
    """A hover (or target) is abandoned after this many consecutive slots with no data."""
    window_slots: Annotated[int, Field(ge=1)] = 2
    """Slots in the moving average of observed rates that choices and hovers follow."""
    arrive_m: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 10.0
    """Autonomous: a reported position this close to a hover point counts as there [m]."""


class RobustPlannerParams(NoParams):
    fail_slots: Annotated[int, Field(ge=1)] = 3
    """A sensor is marked down after this many consecutive served slots with no data."""
    backoff_s: Annotated[float, Field(gt=0, allow_inf_nan=False)] = 60.0
    """How long a sensor stays down [s] (doubled each further time; back up when it reports)."""
    window_slots: Annotated[int, Field(ge=1)] = 5
    """Slots in the moving mean of the observed - predicted SNR that choices follow."""
    arrive_m: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 10.0
    """A reported position this close to a hover point counts as there [m]."""


PolicyFactory = Callable[[Any], Policy | BatchPolicy]
"""Makes a fresh policy from its validated parameters."""

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


POLICIES: Registry[PolicyFactory] = Registry(
    "policy", extra_allowed="or an import path 'package.module:Class'"
)
"""Policy registry: name -> factory(params), with ``params`` = its parameter model."""


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


def _import_target(name: str) -> Any:
    """``Attr`` of ``module`` for ``"module:Attr"``, looking in the current folder too."""
    module_name, _, attribute = name.partition(":")
    if not module_name or not attribute:
        raise SkymuleError(f"policy {name!r}: an import path is 'package.module:Class'")
    cwd = str(Path.cwd())
    if cwd not in sys.path and "" not in sys.path:
        # `python -m skymule` has the current folder on the path, the installed script does
        # not; a policy file next to the scenario should work either way
        sys.path.append(cwd)
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # any failure inside the user's module is theirs to see
        reason = f"{type(exc).__name__}: {exc}"
        raise SkymuleError(
            f"policy {name!r}: could not import module {module_name}: {reason}"
        ) from None
    try:
        target = getattr(module, attribute)
    except AttributeError:
        public = [n for n in dir(module) if not n.startswith("_")]
        from skymule.registry import did_you_mean

        raise SkymuleError(
            f"policy {name!r}: module {module_name} has no {attribute!r}"
            f"{did_you_mean(attribute, public)}"
        ) from None
    if not callable(target):
        raise SkymuleError(f"policy {name!r}: {attribute!r} is not a class or function")
    return target


LEARNED_PREFIX = "rl:"
"""Policy names ``rl:path/to/model.zip``: a model trained in skymule's environments."""


def _params_of(target: Any) -> type[BaseModel] | None:
    params = getattr(target, "Params", None)
    return params if isinstance(params, type) and issubclass(params, BaseModel) else None


def policy_params_model(name: str) -> type[BaseModel] | None:
    """The parameter model of policy ``name`` (None: a plug-in without ``Params``).

    Raises the one-line :class:`SkymuleError` for an unknown name or a plug-in that fails to
    import.
    """
    if name.startswith(LEARNED_PREFIX):  # rl:path/to/model.zip: the model is the parameter
        return None
    if ":" in name:
        return _params_of(_import_target(name))
    params: type[BaseModel] = POLICIES.meta(name, "params", NoParams)
    return params


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
    if ":" not in spec.name:
        return POLICIES.get(spec.name)(spec.policy_params())
    target = _import_target(spec.name)
    checked = _Checked(spec.name)
    params = spec.policy_params()
    if params is not None:
        return checked.check(target(params))
    return checked.check(target(spec) if _takes_argument(target) else target())


def batch_policy(specs: Sequence[PolicySpec]) -> BatchPolicy:
    """One batched policy for B missions, mission b under ``specs[b]``.

    Missions under one registered batched policy share one instance (its parameters per
    mission); a batched plug-in gets one instance per distinct ``[policy]``; a per-mission
    policy one instance per mission (:class:`PerMission`). Several of these side by side are
    :class:`Columns`.
    """
    groups: dict[Any, list[int]] = {}
    params: list[Any] = []
    cache: dict[int, Any] = {}  # sweeps repeat a few spec objects many times
    for index, spec in enumerate(specs):
        if id(spec) not in cache:
            learned = spec.name.startswith(LEARNED_PREFIX)
            cache[id(spec)] = None if learned else spec.policy_params()
        params.append(cache[id(spec)])
        batched = ":" not in spec.name and POLICIES.meta(spec.name, "batch", None) is not None
        own = repr(params[-1]) if params[-1] is not None else id(spec)
        key: Any = spec.name if batched else (spec.name, own)
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
    """A factory ``spec -> policy`` for a registry name or ``"module:Attr"`` (checked now)."""
    policy_params_model(name)  # raises the one-line error for unknown / unimportable names

    def factory(spec: PolicySpec) -> Policy | BatchPolicy:
        return make_policy(spec if spec.name == name else spec.model_copy(update={"name": name}))

    return factory


def unknown_policies(names: list[str]) -> list[str]:
    """The names among ``names`` that resolve to no policy (empty when all are fine)."""
    unknown = []
    for name in names:
        try:
            policy_params_model(name)
        except SkymuleError:
            unknown.append(name)
    return unknown


def check_policies(names: list[str], option: str = "--policies") -> list[str]:
    """``names`` if every one resolves; else the first problem as one line."""
    if not names:
        raise SkymuleError(f"{option} is empty; allowed: {', '.join(POLICIES)}")
    for name in names:
        try:
            policy_params_model(name)
        except SkymuleError as exc:
            raise SkymuleError(f"{option}: {exc}") from None
    return names


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
    "make_policy",
    "policy_params_model",
    "resolve_policy",
    "unknown_policies",
]
