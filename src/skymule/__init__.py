"""skymule: UAV data-mule missions, simulated, replayed, bounded and reported.

What a user imports, from one place (each name is loaded when first used, so importing
``skymule`` stays light)::

    from skymule import load_scenario, simulate, Action, Observation

* scenarios: :class:`Scenario`, :func:`load_scenario`;
* one mission, or many: :func:`simulate` (a scenario's run, ``RunResult``),
  :func:`build_mission`, :func:`run_mission` / :func:`run_missions` (any policy, batched or
  per mission, through the engine of the trajectory mode), :func:`summarize_missions`
  (``summary.json`` rows of many);
* comparisons and sweeps: :func:`compare_policies`, :func:`load_sweep`, :func:`run_sweep`;
* writing a policy: :class:`Policy` (one mission: ``reset(context)``, ``act(observation)``
  -> :class:`Action`) or :class:`BatchPolicy` (``batched = True``: ``reset(contexts)``,
  ``act(batch_observation)`` -> :class:`BatchAction`), seeing :class:`MissionContext`,
  :class:`Observation` / :class:`BatchObservation`;
* the run record: :class:`Flights` (B flights) and :class:`MissionLog` (one of them).

Everything else (``skymule.sim``, ``skymule.radio``, ...) is internal: importable, but free to
change between releases.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

_EXPORTS = {
    "Scenario": "skymule.scenario",
    "load_scenario": "skymule.scenario",
    "simulate": "skymule.tasks.simulate",
    "RunResult": "skymule.tasks.simulate",
    "build_mission": "skymule.world",
    "Mission": "skymule.world",
    "run_mission": "skymule.sim.run",
    "run_missions": "skymule.sim.run",
    "summarize_missions": "skymule.sim.run",
    "compare_policies": "skymule.tasks.compare",
    "load_sweep": "skymule.experiments.sweep",
    "run_sweep": "skymule.experiments.run",
    "Action": "skymule.policies.base",
    "Observation": "skymule.policies.base",
    "MissionContext": "skymule.policies.base",
    "Policy": "skymule.policies.base",
    "BatchAction": "skymule.policies.base",
    "BatchObservation": "skymule.policies.base",
    "BatchPolicy": "skymule.policies.base",
    "Flights": "skymule.metrics.flights",
    "MissionLog": "skymule.metrics.flights",
}

__all__ = [
    "Action",
    "BatchAction",
    "BatchObservation",
    "BatchPolicy",
    "Flights",
    "Mission",
    "MissionContext",
    "MissionLog",
    "Observation",
    "Policy",
    "RunResult",
    "Scenario",
    "build_mission",
    "compare_policies",
    "load_scenario",
    "load_sweep",
    "run_mission",
    "run_missions",
    "run_sweep",
    "simulate",
    "summarize_missions",
]

if TYPE_CHECKING:
    from skymule.experiments.run import run_sweep
    from skymule.experiments.sweep import load_sweep
    from skymule.metrics.flights import Flights, MissionLog
    from skymule.policies.base import (
        Action,
        BatchAction,
        BatchObservation,
        BatchPolicy,
        MissionContext,
        Observation,
        Policy,
    )
    from skymule.scenario import Scenario, load_scenario
    from skymule.sim.run import run_mission, run_missions, summarize_missions
    from skymule.tasks.compare import compare_policies
    from skymule.tasks.simulate import RunResult, simulate
    from skymule.world import Mission, build_mission


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'skymule' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
