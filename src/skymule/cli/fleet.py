"""``skymule run`` / ``skymule compare`` for scenarios with ``[[uavs]]`` (several UAVs).

The CLI hands a scenario here when it has ``[[uavs]]``: ``run`` prints one row per UAV plus
the fleet total, ``compare`` one row per policy with the K-UAV upper bound and each policy's
gap to it (both through :mod:`skymule.cli.tables`, which never cuts a value); ``--json``
prints the summary or the comparison instead.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import skymule.cli.output as output
from skymule.cli.output import print_json
from skymule.cli.tables import print_table
from skymule.errors import SkymuleError
from skymule.scenario import Scenario

UAV_COLUMNS = ("uav", "total_downloaded_mbit", "lost_slots", "distance_m", "landed_within_5m")
"""Columns of the per-UAV table."""
COMPARE_COLUMNS = (
    "policy",
    "total_downloaded_mbit",
    "completion",
    "lost_slots",
    "upper_bound_mbit",
    "gap_to_bound_mbit",
    "gap_to_bound_frac",
)
"""Columns of the comparison table."""


def run_fleet_command(
    scenario: Scenario, policy: str | None, out: Path | None, json_out: bool
) -> None:
    """``skymule run`` on a fleet: per-UAV rows and the fleet total (or the JSON summary)."""
    from skymule.tasks.fleet import simulate_fleet

    result = simulate_fleet(scenario, policy)
    if out is not None:
        result.write(out)
    summary = result.summary
    if json_out:
        print_json(summary)
        return
    title = f"{scenario.name}: {summary['policy']}"
    print_table(output.console, title, [*summary["uavs"], {**summary, "uav": "fleet"}], UAV_COLUMNS)
    if out is not None:
        output.say(f"wrote {out}/summary.json, slots.csv (one row per UAV per slot), scenario.json")


def compare_fleet_command(
    scenario: Scenario, names: list[str], out: Path | None, json_out: bool
) -> None:
    """``skymule compare`` on a fleet: one row per policy, the K-UAV bound and the gaps."""
    from skymule.tasks.fleet import compare_fleet, write_fleet_compare

    comparison = compare_fleet(scenario, names)
    written = write_fleet_compare(comparison, out) if out is not None else []
    rows = comparison.rows()
    bound = comparison.bound
    if json_out:
        print_json(
            {
                "scenario": scenario.name,
                "n_uavs": comparison.fleet.size,
                "runs": rows,
                "bound": None if bound is None else bound.to_json_dict(),
                "note": comparison.note,
            }
        )
        return
    shown: list[dict[str, Any]] = list(rows)
    if bound is not None:
        shown.append({"policy": "bound", "total_downloaded_mbit": bound.upper_bound_mbit})
    title = f"{scenario.name}: {comparison.fleet.size} UAVs"
    print_table(output.console, title, shown, COMPARE_COLUMNS)
    if comparison.note:
        output.say(f"no upper bound: {comparison.note}")
    if out is not None:
        output.say(f"wrote {', '.join(map(str, written))} and one folder per policy")


def check_policy_names(names: list[str], text: str) -> None:
    """Reject unknown policy names for a fleet (single-UAV ones plus ``coordinated``)."""
    from skymule.policies import POLICIES, unknown_policies
    from skymule.tasks.fleet import FLEET_POLICIES

    unknown = [n for n in unknown_policies(names) if n not in FLEET_POLICIES]
    if not names or unknown:
        raise SkymuleError(
            f"--policies {text!r}: unknown {', '.join(unknown) or '(empty)'}; "
            f"allowed: {', '.join(sorted([*POLICIES, *FLEET_POLICIES]))}"
        )
