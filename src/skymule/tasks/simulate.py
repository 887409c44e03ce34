"""One call from scenario to results: build the mission, run the policy, summarise."""

from __future__ import annotations

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
"""Slots from which one mission runs on the compiled engine (numba) when it is installed.
Loading it in a fresh process (importing numba, reading its on-disk cache) costs 0.5-1 s;
the numpy slot loop costs ~0.1 ms a slot, so a 500-slot preset is done in 0.05 s without it
(``python benchmarks/bench_startup.py``); both give the same record, value for value."""


def engine_for(n_slots: int) -> str:
    """The engine (``skymule.sim.run.ENGINES``) for one mission of ``n_slots`` slots:
    ``numpy`` below :data:`COMPILED_WORTH_SLOTS`, else ``auto`` (compiled where it can)."""
    return "numpy" if n_slots < COMPILED_WORTH_SLOTS else "auto"


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
