"""One call from scenario to results: build the mission, run the policy, summarise."""

from __future__ import annotations

import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from skymule.metrics.flights import MissionLog
from skymule.metrics.summary import summarize
from skymule.policies import batch_policy
from skymule.scenario import Scenario
from skymule.sim.run import run_mission
from skymule.world import Mission, build_mission

COMPILED_WORTH_SLOTS = 5000
"""Numpy slots after which loading the compiled engine (numba) pays. Loading it in a fresh
process (importing numba, reading its on-disk cache) costs 0.5-1 s; the numpy slot loop
costs ~0.05-0.1 ms a slot (a 500-slot preset: ~20 ms), the compiled one ~0.5 us
(``python benchmarks/bench_sweep.py``: the ``simulate()`` rows). Both give the same record,
value for value."""

_numpy_slots = [0]
"""Slots this process has run one mission at a time on the numpy loop (:func:`engine_for`)."""


def compiled_loaded() -> bool:
    """True when this process has the compiled engine loaded already (it costs nothing more)."""
    if "numba" not in sys.modules:
        return False
    from skymule.sim import compiled

    return compiled.compiled_loop.cache_info().currsize > 0


def engine_for(n_slots: int) -> str:
    """The engine (``skymule.sim.run.ENGINES``) for one mission of ``n_slots`` slots.

    ``auto`` (compiled where it can) when the compiled engine is loaded in this process or
    when this mission, with the numpy slots this process has run before it, reaches
    :data:`COMPILED_WORTH_SLOTS`: from then on the load has paid for itself (a one-off
    ``skymule run`` of a preset stays on numpy and starts fast; a script that simulates
    mission after mission moves to the compiled loop after a few). Else ``numpy``.
    """
    if compiled_loaded() or _numpy_slots[0] + n_slots >= COMPILED_WORTH_SLOTS:
        return "auto"
    _numpy_slots[0] += n_slots
    return "numpy"


@dataclass(frozen=True)
class RunResult:
    """A finished mission: what was run, what happened, and its summary."""

    mission: Mission
    log: MissionLog
    summary: dict[str, Any]

    def write(self, out_dir: Path) -> None:
        """Write the run folder (summary.json, slots.csv, scenario.json)."""
        from skymule.io.runs import slots_frame, write_run  # pandas: only when writing

        write_run(
            out_dir,
            self.summary,
            slots_frame(self.log, self.mission.frame),
            self.mission.scenario.to_toml_dict(),
        )


def simulate(
    scenario: Scenario, policy: str | None = None, mission: Mission | None = None
) -> RunResult:
    """Run ``scenario`` under its own policy, or under ``policy`` (a registry name).

    Pass a prebuilt ``mission`` to compare several policies on identical signal draws.
    """
    if policy is not None:
        scenario = scenario.with_policy(policy)
    mission = build_mission(scenario) if mission is None else replace(mission, scenario=scenario)
    log = run_mission(mission, batch_policy([scenario.policy]), engine_for(mission.n_slots))
    return RunResult(mission, log, summarize(log, scenario.name))
