"""The policies a scenario may name, and their parameter models: what validating a
``[policy]`` section needs, without importing any policy.

:data:`POLICIES` maps a name to a factory (``factory(params) -> policy``) with its parameter
model as ``params`` metadata (``POLICIES.meta(name, "params")``). :mod:`skymule.policies`
registers the built-in policies in it when imported (which importing this module does first,
as its parent package); you can register your own the same way. Names of the form
``"package.module:Class"`` (plug-ins), ``"rl:model.zip"`` (learned models) and
``"learned:weights.npz"`` (the ``learned`` policy with your own weights) need no entry.

Files are shared, so naming a plug-in or a model in one runs nothing by itself: checking a
name (:func:`check_policy_name`) never imports or reads anything; the module is imported
(:func:`import_target`) and the model loaded only when that policy is made to run.
"""

from __future__ import annotations

import importlib
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Protocol

from pydantic import BaseModel, ConfigDict, Field

from skymule.errors import SkymuleError
from skymule.registry import Registry
from skymule.rules.defaults import HOVER_THRESHOLD, MAX_HOVER_S
from skymule.trust import check_trusted


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
    hover_threshold: Annotated[float, Field(gt=0, le=1)] = HOVER_THRESHOLD
    """Fraction of the peak rate that triggers a hover."""
    max_hover_s: Annotated[float, Field(gt=0)] = MAX_HOVER_S
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


PolicyFactory = Callable[[Any], Any]
"""Makes a fresh policy (per-mission or batched) from its validated parameters."""

POLICIES: Registry[PolicyFactory] = Registry(
    "policy", extra_allowed="or an import path 'package.module:Class'"
)
"""Policy registry: name -> factory(params), with ``params`` = its parameter model."""


LEARNED_PREFIX = "rl:"
"""Policy names ``rl:path/to/model.zip``: a model trained in skymule's environments."""

WEIGHTS_PREFIX = "learned:"
"""Policy names ``learned:path/to/weights.npz``: the ``learned`` option scorer with your own
weights (:mod:`skymule.policies.learned`; plain arrays, no code)."""


_IMPORT_PATH = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*$")


def is_model_file(name: str) -> bool:
    """True for ``rl:PATH`` and ``learned:PATH``: a policy whose file is its parameter (it
    takes no ``[policy.params]``)."""
    return name.startswith((LEARNED_PREFIX, WEIGHTS_PREFIX))


def is_plugin(name: str) -> bool:
    """True for an import path ``"package.module:Class"`` (not an ``rl:`` model or
    ``learned:`` weights file)."""
    return ":" in name and not is_model_file(name)


def plugin_module(name: str) -> str | None:
    """The module a policy name imports when it runs (None: a registered or learned one)."""
    return name.partition(":")[0] if is_plugin(name) else None


def check_policy_name(name: str) -> str:
    """``name`` if it can name a policy; else the one-line error. Imports and reads nothing:
    a plug-in's module and a learned model's file are only looked at when it runs."""
    if name.startswith(LEARNED_PREFIX):
        if len(name) == len(LEARNED_PREFIX):
            raise SkymuleError(f"policy {name!r}: give rl:path/to/model.zip")
    elif name.startswith(WEIGHTS_PREFIX):
        if len(name) == len(WEIGHTS_PREFIX):
            raise SkymuleError(f"policy {name!r}: give learned:path/to/weights.npz")
    elif ":" in name:
        if _IMPORT_PATH.match(name) is None:
            raise SkymuleError(f"policy {name!r}: an import path is 'package.module:Class'")
    else:
        POLICIES.entry(name)  # the one-line "unknown policy ...; did you mean" error
    return name


def import_target(name: str) -> Any:
    """``Attr`` of ``module`` for ``"module:Attr"``, looking in the current folder too."""
    check_policy_name(name)
    module_name, _, attribute = name.partition(":")
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


def _params_of(target: Any) -> type[BaseModel] | None:
    params = getattr(target, "Params", None)
    return params if isinstance(params, type) and issubclass(params, BaseModel) else None


def policy_params_model(name: str) -> type[BaseModel] | None:
    """The parameter model of policy ``name`` (None: a plug-in without ``Params``).

    Imports a plug-in's module (only for a policy that runs). Raises the one-line
    :class:`SkymuleError` for an unknown name or a plug-in that fails to import.
    """
    if is_model_file(name):  # rl:model.zip, learned:weights.npz: the file is the parameter
        return None
    if ":" in name:
        return _params_of(import_target(name))
    params: type[BaseModel] = POLICIES.meta(name, "params", NoParams)
    return params


def unknown_policies(names: list[str]) -> list[str]:
    """The names among ``names`` that can name no policy (empty when all are fine); nothing
    is imported."""
    unknown = []
    for name in names:
        try:
            check_policy_name(name)
        except SkymuleError:
            unknown.append(name)
    return unknown


def check_learned(name: str) -> None:
    """A learned model ``rl:PATH`` that is about to run: the file exists and the user trusts
    it (:mod:`skymule.trust`); nothing of it is read."""
    path = Path(name[len(LEARNED_PREFIX) :])
    if not path.is_file():
        raise SkymuleError(f"policy {name!r}: no such model file")
    check_trusted(name, path)


def check_policies(names: list[str], option: str = "--policies") -> list[str]:
    """``names``, which are about to run, if every one can name a policy (and every learned
    model is trusted); else the first problem as one line. Nothing is imported or read."""
    if not names:
        raise SkymuleError(f"{option} is empty; allowed: {', '.join(POLICIES)}")
    for name in names:
        try:
            check_policy_name(name)
            if name.startswith(LEARNED_PREFIX):
                check_learned(name)
        except SkymuleError as exc:
            raise SkymuleError(f"{option}: {exc}") from None
    return names
