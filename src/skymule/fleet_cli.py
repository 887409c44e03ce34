"""``skymule run`` / ``skymule compare`` for scenarios with ``[[uavs]]`` (several UAVs).

The CLI hands a scenario here when it has ``[[uavs]]``; these print one row per UAV plus the
fleet total, and ``compare`` adds the K-UAV upper bound and each policy's gap to it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pandas as pd
from rich import box
from rich.console import Console
from rich.table import Table

from skymule.errors import SkymuleError
from skymule.scenario import Scenario, load_scenario

#: Columns of the per-UAV and comparison tables.
UAV_COLUMNS = ("uav", "total_downloaded_mbit", "lost_slots", "distance_m", "landed_within_5m")
COMPARE_COLUMNS = (
    "policy",
    "total_downloaded_mbit",
    "completion",
    "lost_slots",
    "upper_bound_mbit",
    "gap_to_bound_mbit",
    "gap_to_bound_frac",
)


def _cell(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _table(title: str, rows: list[dict[str, Any]], columns: tuple[str, ...]) -> Table:
    table = Table(title=title, box=box.SIMPLE)
    for column in columns:
        table.add_column(column)
    for row in rows:
        table.add_row(*(_cell(row.get(c, "")) for c in columns))
    return table


def fleet_scenario(spec: str) -> Scenario | None:
    """The scenario at ``spec`` if it has ``[[uavs]]``, else None (the single-UAV path)."""
    scenario = load_scenario(spec)
    return scenario if scenario.uavs else None


def run_fleet_command(
    scenario: Scenario, policy: str | None, out: Path | None, console: Console
) -> None:
    """``skymule run`` on a fleet: per-UAV rows and the fleet total."""
    from skymule.fleet_runner import simulate_fleet

    result = simulate_fleet(scenario, policy)
    if out is not None:
        result.write(out)
    summary = result.summary
    total = {**summary, "uav": "fleet"}
    console.print(
        _table(f"{scenario.name}: {summary['policy']}", [*summary["uavs"], total], UAV_COLUMNS)
    )
    if out is not None:
        console.print(
            f"wrote {out}/summary.json, slots.csv (one row per UAV per slot), scenario.json"
        )


def with_gap(row: dict[str, Any], bound_mbit: float | None) -> dict[str, Any]:
    """``row`` plus upper_bound_mbit, gap_to_bound_mbit and gap_to_bound_frac."""
    if bound_mbit is None:
        return row
    gap = bound_mbit - row["total_downloaded_mbit"]
    frac = gap / bound_mbit if bound_mbit > 0 else 0.0
    return {
        **row,
        "upper_bound_mbit": bound_mbit,
        "gap_to_bound_mbit": gap,
        "gap_to_bound_frac": frac,
    }


def compare_fleet_command(
    scenario: Scenario, names: list[str], out: Path | None, console: Console
) -> None:
    """``skymule compare`` on a fleet: one row per policy, the K-UAV bound and the gaps."""
    from skymule.bounds.fleet import fleet_bound
    from skymule.bounds.result import BoundError
    from skymule.fleet_runner import simulate_fleet
    from skymule.sim.fleet import build_fleet

    fleet = build_fleet(scenario)
    try:
        upper = fleet_bound(fleet)
        bound_mbit: float | None = upper.upper_bound_bit / 1e6
    except BoundError as exc:
        upper, bound_mbit = None, None
        console.print(f"no upper bound: {exc}", markup=False)
    rows = []
    for name in names:
        result = simulate_fleet(scenario, name, fleet=fleet)
        if out is not None:
            result.write(out / name)
        summary = {k: v for k, v in result.summary.items() if not isinstance(v, dict | list)}
        rows.append(with_gap(summary, bound_mbit))
    shown = list(rows)
    if bound_mbit is not None:
        shown.append({"policy": "bound", "total_downloaded_mbit": bound_mbit})
    title = f"{scenario.name}: {fleet.size} UAVs"
    console.print(_table(title, shown, COMPARE_COLUMNS))
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        pd.DataFrame(rows).to_csv(out / "comparison.csv", index=False)
        if upper is not None:
            (out / "bound.json").write_text(json.dumps(upper.to_json_dict(), indent=2))
        console.print(f"wrote {out}/comparison.csv and one folder per policy")


def check_policy_names(names: list[str], text: str) -> None:
    """Reject unknown policy names for a fleet (single-UAV ones plus ``coordinated``)."""
    from skymule.fleet_runner import FLEET_POLICIES
    from skymule.policies import POLICIES, unknown_policies

    unknown = [n for n in unknown_policies(names) if n not in FLEET_POLICIES]
    if not names or unknown:
        raise SkymuleError(
            f"--policies {text!r}: unknown {', '.join(unknown) or '(empty)'}; "
            f"allowed: {', '.join(sorted([*POLICIES, *FLEET_POLICIES]))}"
        )
