"""Degradation curves: every policy over increasing fault intensity, paired draws (issue 15).

For a scenario, one fault ``kind`` and a list of intensity levels, mission m (m = 0..M-1) runs
with seed ``scenario.seed + m`` and buffers drawn from that seed (uniform in
``[0.5, 1.5] x`` the scenario's buffer), at every level and under every policy: the same
missions and, at a level, the same fault draws for every policy (``docs/faults.md``: one draw
per mission, given to every policy). A level is one ``[[faults]]`` entry built by
:data:`LEVELS` (level 0 = no fault: exactly the fault-free mission).

The fault-free upper bound (``skymule bound``) of each mission is reported on fixed
trajectories: faults only take capacity away (a blocked slot delivers nothing, the true rate
is never raised), so it bounds every level -- loose once faults bite.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError
from skymule.scenario import Scenario, scenario_from_dict

FaultLevel = Callable[[float], dict[str, Any]]

LEVELS: dict[str, tuple[str, FaultLevel]] = {
    "outage": (
        "mean outage length per tower [s] (one random window each)",
        lambda x: {"kind": "outage", "params": {"mean_duration_s": x}},
    ),
    "gilbert-elliott": (
        "long-run share of lost slots, bursts of 5 slots",
        lambda x: {
            "kind": "gilbert-elliott",
            "params": {"p_good_to_bad": 0.2 * x / (1.0 - x), "p_bad_to_good": 0.2},
        },
    ),
    "snr-error": (
        "std of the SNR error the policy sees [dB] (3 s correlation)",
        lambda x: {"kind": "snr-error", "params": {"std_db": x, "correlation_s": 3.0}},
    ),
    "missed-polls": (
        "probability that a slot's poll is missed",
        lambda x: {"kind": "missed-polls", "params": {"probability": x}},
    ),
    "gps-error": (
        "std of the reported position error per axis [m]",
        lambda x: {"kind": "gps-error", "params": {"std_m": x}},
    ),
    "wind": (
        "wind speed from the north [m/s]",
        lambda x: {"kind": "wind", "params": {"speed_mps": x, "from_deg": 0.0}},
    ),
}
"""Fault kind -> (what its level means, level -> one ``[[faults]]`` entry)."""

_LEVEL_RANGE = {"gilbert-elliott": (0.0, 1.0), "missed-polls": (0.0, 1.0)}


def parse_levels(text: str, kind: str) -> list[float]:
    """``"0,2,4"`` -> [0.0, 2.0, 4.0]; SkymuleError naming the value and what is allowed."""
    if kind not in LEVELS:
        raise SkymuleError(f"--fault {kind!r} is not a fault kind; allowed: {', '.join(LEVELS)}")
    levels = []
    for part in text.split(","):
        try:
            value = float(part)
        except ValueError:
            raise SkymuleError(
                f"--levels: {part.strip()!r} is not a number; give comma-separated numbers >= 0"
            ) from None
        low, high = _LEVEL_RANGE.get(kind, (0.0, math.inf))
        if not (math.isfinite(value) and low <= value < high):
            bounds = f"in [{low:g}, {high:g})" if high < math.inf else ">= 0 and finite"
            raise SkymuleError(f"--levels: {part.strip()!r} for {kind}; allowed: {bounds}")
        levels.append(value)
    return levels


def leveled(scenario: Scenario, kind: str, level: float, mission: int) -> Scenario:
    """Mission ``mission`` of the study at ``level``: its seed, buffers and one fault entry."""
    data = scenario.to_toml_dict()
    seed = int(scenario.seed) + mission
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(4,)))
    scale = rng.uniform(0.5, 1.5, len(scenario.sensors))
    data["seed"] = seed
    for sensor, factor in zip(data["sensors"], scale, strict=True):
        sensor["buffer_mbit"] = float(sensor["buffer_mbit"]) * float(factor)
    faults = list(data.get("faults") or [])
    if level > 0:
        faults.append(LEVELS[kind][1](level))
    data["faults"] = faults or None
    if data["faults"] is None:
        del data["faults"]
    try:
        source = f"{scenario.name} ({kind} = {level:g})"
        return scenario_from_dict(data, source, Path(scenario.base_dir))
    except SkymuleError as exc:
        raise SkymuleError(f"--levels: {kind} = {level:g} is not allowed here: {exc}") from None


@dataclass(frozen=True)
class Study:
    """Per-mission results: one row per (level, policy, mission)."""

    rows: pd.DataFrame
    bound_mbit: np.ndarray | None


def run_study(
    scenario: Scenario,
    kind: str,
    levels: Sequence[float],
    policies: Sequence[str],
    missions: int,
    with_bound: bool = True,
) -> Study:
    """Run every policy on ``missions`` paired missions at every level."""
    from skymule.tasks.simulate import simulate
    from skymule.world import build_mission

    for level in levels:  # every level's mistake before anything runs
        leveled(scenario, kind, level, 0)
    rows = []
    bounds: list[float] = []
    for level in levels:
        for m in range(missions):
            single = leveled(scenario, kind, level, m)
            mission = build_mission(single)
            for name, variant in zip(policies, single.with_policies(policies), strict=True):
                summary = simulate(variant, mission=mission).summary
                rows.append(
                    {
                        "level": level,
                        "policy": name,
                        "mission": m,
                        "mbit": float(summary["total_downloaded_mbit"]),
                        "aadm_score": float(summary["aadm_score"]),
                    }
                )
    if with_bound and scenario.trajectory.mode == "fixed" and scenario.radio.fading == "none":
        from skymule.bounds.fixed import fixed_mission_bound

        for m in range(missions):
            clean = build_mission(leveled(scenario, kind, 0.0, m))
            bounds.append(fixed_mission_bound(clean).upper_bound_mbit)
    return Study(pd.DataFrame(rows), np.array(bounds) if bounds else None)


def mean_ci(values: np.ndarray) -> tuple[float, float]:
    """Mean and the half-width of its 95 % confidence interval (Student t; 0 for one value)."""
    from scipy import stats

    values = np.asarray(values, float)
    if values.size < 2:
        return float(values.mean()), 0.0
    half = stats.t.ppf(0.975, values.size - 1) * values.std(ddof=1) / math.sqrt(values.size)
    return float(values.mean()), float(half)


def table(study: Study) -> pd.DataFrame:
    """One row per (policy, level): Mbit mean and 95 % CI, AADM score mean, the bound."""
    out = []
    bound = None if study.bound_mbit is None else mean_ci(study.bound_mbit)[0]
    rows = study.rows
    order = {name: i for i, name in enumerate(dict.fromkeys(rows["policy"]))}
    rows = rows.sort_values(
        ["policy", "level"], key=lambda c: c.map(order) if c.name == "policy" else c, kind="stable"
    )
    for (policy, level), group in rows.groupby(["policy", "level"], sort=False):
        mean, half = mean_ci(group["mbit"].to_numpy())
        out.append(
            {
                "policy": policy,
                "level": level,
                "missions": len(group),
                "mbit_mean": round(mean, 3),
                "mbit_ci95": round(half, 3),
                "aadm_score_mean": round(float(group["aadm_score"].mean()), 3),
                "bound_mbit_mean": None if bound is None else round(bound, 3),
            }
        )
    return pd.DataFrame(out)


def paired_difference(study: Study, a: str, b: str, level: float) -> tuple[float, float]:
    """Mean and 95 % CI of (policy a - policy b) Mbit over the paired missions at ``level``."""
    rows = study.rows[study.rows["level"] == level]
    first = rows[rows["policy"] == a].sort_values("mission")["mbit"].to_numpy()
    second = rows[rows["policy"] == b].sort_values("mission")["mbit"].to_numpy()
    return mean_ci(first - second)
