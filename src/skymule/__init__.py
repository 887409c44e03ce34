"""skymule: UAV data-mule missions, simulated, replayed, bounded and reported.

What a user imports, from one place (each name is loaded when first used, so importing
``skymule`` stays light)::

    from skymule import load_scenario, simulate, Action, Observation

* scenarios: :class:`Scenario`, :func:`load_scenario`;
* one mission, or many: :func:`simulate` (a scenario's run, ``RunResult``),
  :func:`build_mission`, :func:`run_mission` / :func:`run_missions` (any policy, batched or
  per mission, through the engine of the trajectory mode), :func:`summarize_missions`
  (``summary.json`` rows of many);
* comparisons, bounds and sweeps: :func:`compare_policies` / :func:`compare_sources` (what
  ``skymule compare`` runs) and :func:`write_compare` (its folder), :func:`scenario_bound`
  (what ``skymule bound`` gives), :func:`load_sweep`, :func:`run_sweep`;
  :func:`random_autonomous_scenario` with :class:`LayoutRanges` (random missions);
* writing a policy: :class:`Policy` (one mission: ``reset(context)``, ``act(observation)``
  -> :class:`Action`) or :class:`BatchPolicy` (``batched = True``: ``reset(contexts)``,
  ``act(batch_observation)`` -> :class:`BatchAction`), seeing :class:`MissionContext`,
  :class:`Observation` / :class:`BatchObservation`; :func:`make_policy` (a policy by name,
  from a scenario's ``[policy]``); :class:`AadmAgent` (a policy behind the AADM challenge's
  once-a-second interface);
* the run record: :class:`Flights` (B flights) and :class:`MissionLog` (one of them).

Beside these, a module that declares ``__all__`` (``skymule.envs`` and its environments,
``skymule.faults``, ...) exports the names it lists. Everything else (``skymule.sim``,
``skymule.radio``, ...) is internal: importable, but free to change between releases.
``tests/test_public_api.py`` fails when README.md or docs/ import anything else.
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
    "compare_sources": "skymule.tasks.compare",
    "scenario_bound": "skymule.tasks.compare",
    "write_compare": "skymule.tasks.compare",
    "LayoutRanges": "skymule.experiments.layouts",
    "random_autonomous_scenario": "skymule.experiments.layouts",
    "make_policy": "skymule.policies",
    "AadmAgent": "skymule.aadm.agent",
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
    "AadmAgent",
    "Action",
    "BatchAction",
    "BatchObservation",
    "BatchPolicy",
    "Flights",
    "LayoutRanges",
    "Mission",
    "MissionContext",
    "MissionLog",
    "Observation",
    "Policy",
    "RunResult",
    "Scenario",
    "build_mission",
    "compare_policies",
    "compare_sources",
    "load_scenario",
    "load_sweep",
    "make_policy",
    "random_autonomous_scenario",
    "run_mission",
    "run_missions",
    "run_sweep",
    "scenario_bound",
    "simulate",
    "summarize_missions",
    "write_compare",
]

if TYPE_CHECKING:
    from skymule.aadm.agent import AadmAgent
    from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
    from skymule.experiments.run import run_sweep
    from skymule.experiments.sweep import load_sweep
    from skymule.metrics.flights import Flights, MissionLog
    from skymule.policies import make_policy
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
    from skymule.tasks.compare import (
        compare_policies,
        compare_sources,
        scenario_bound,
        write_compare,
    )
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
