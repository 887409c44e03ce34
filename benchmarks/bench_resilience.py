"""Robust vs plain HGAD and planner under faults: 200 paired random missions per preset (issue 15).

Run: python benchmarks/bench_resilience.py [MISSIONS] (SKYMULE_BENCH_TINY=1: 2 missions)

Mission m of a preset uses seed ``preset.seed + m`` and buffers drawn from it (uniform in
[0.5, 1.5] x the preset's, :func:`skymule.tasks.resilience.leveled`). Two conditions on the same
missions: fault-free, and faulty = one random outage per tower (exponential length, mean 60 s)
plus an SNR error of 6 dB std (3 s correlation) on what the policy sees. Prints per policy the
mean downloaded Mbit with its 95 % CI, and the paired difference robust - plain (mean, 95 % CI)
for HGAD (both presets) and the tour planner (autonomous only: it steers the UAV).

Then, on the autonomous preset, the return home under a 6 m/s wind from the north, alone and
with a 20 Wh battery (a policy is told neither; the engine's return-home override steers
home, ``planner-robust`` infers the wind from its own slowed steps): per policy the mean Mbit
and the share of missions that ended within 5 m of home.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from _results import json_option, write
from _results import table as results_table
from _sizes import size
from skymule.scenario import Scenario, load_scenario, scenario_from_dict
from skymule.tasks.resilience import leveled, mean_ci, paired_difference, run_study, table

POLICIES = {
    "paper-sim-fixed": ("hgad", "hgad-robust"),
    "paper-sim-autonomous": ("hgad", "hgad-robust", "planner", "planner-robust"),
}
PAIRS = (("hgad-robust", "hgad"), ("planner-robust", "planner"))
FAULTS: list[dict[str, Any]] = [
    {"kind": "outage", "params": {"mean_duration_s": 60.0}},
    {"kind": "snr-error", "params": {"std_db": 6.0, "correlation_s": 3.0}},
]
WIND: dict[str, Any] = {"kind": "wind", "params": {"speed_mps": 6.0, "from_deg": 0.0}}
BATTERY: dict[str, Any] = {"kind": "battery", "params": {"capacity_wh": 20.0}}
HOMEWARD = {"wind 6 m/s from the north": [WIND], "wind 6 m/s + 20 Wh battery": [WIND, BATTERY]}


def with_faults(base: Scenario, faults: list[dict[str, Any]], label: str) -> Scenario:
    data = base.to_toml_dict()
    data["faults"] = faults
    return scenario_from_dict(data, f"{base.name} + {label}", Path(base.base_dir))


def compare(preset: str, missions: int) -> list[list[str]]:
    rows: list[list[str]] = []
    base = load_scenario(preset)
    policies = POLICIES[preset]
    faulty = with_faults(base, FAULTS, "faults")
    for label, scenario in (("fault-free", base), ("outages + 6 dB SNR error", faulty)):
        start = time.process_time()
        study = run_study(scenario, "outage", [0.0], policies, missions, with_bound=False)
        cpu = time.process_time() - start
        print(f"{preset}, {label}, {missions} missions ({cpu:.0f} s CPU):")
        for row in table(study).itertuples():
            print(f"  {row.policy:14s} {row.mbit_mean:9.1f} +- {row.mbit_ci95:6.1f} Mbit")
            mbit = f"{row.mbit_mean:.1f} ± {row.mbit_ci95:.1f}"
            rows.append([preset, label, str(row.policy), mbit, ""])
        for robust, plain in PAIRS:
            if robust not in policies:
                continue
            mean, half = paired_difference(study, robust, plain, 0.0)
            plain_mbit = float(study.rows[study.rows["policy"] == plain]["mbit"].mean())
            print(
                f"  robust - plain ({plain}): {mean:+.1f} +- {half:.1f} Mbit "
                f"({100 * mean / plain_mbit:+.2f} % of plain)"
            )
            rows.append([preset, label, f"{robust} − {plain}", f"{mean:+.1f} ± {half:.1f}", ""])
    return rows


def homeward(label: str, faults: list[dict[str, Any]], missions: int) -> list[list[str]]:
    """Mbit and the share of missions ending home, under wind (and a battery limit)."""
    from skymule.tasks.simulate import simulate
    from skymule.world import build_mission

    preset = "paper-sim-autonomous"
    scenario = with_faults(load_scenario(preset), faults, label)
    policies = POLICIES[preset]
    mbit: dict[str, list[float]] = {name: [] for name in policies}
    home: dict[str, list[bool]] = {name: [] for name in policies}
    start = time.process_time()
    for m in range(missions):
        single = leveled(scenario, "wind", 0.0, m)
        mission = build_mission(single)
        for name in policies:
            summary = simulate(single, policy=name, mission=mission).summary
            mbit[name].append(float(summary["total_downloaded_mbit"]))
            home[name].append(bool(summary["landed_within_5m"]))
    cpu = time.process_time() - start
    print(f"{preset}, {label}, {missions} missions ({cpu:.0f} s CPU):")
    rows = []
    for name in policies:
        mean, half = mean_ci(np.array(mbit[name]))
        share = 100 * float(np.mean(home[name]))
        print(f"  {name:14s} {mean:9.1f} +- {half:6.1f} Mbit, ended home in {share:5.1f} %")
        rows.append([preset, label, name, f"{mean:.1f} ± {half:.1f}", f"{share:.1f}"])
    diff, half = mean_ci(np.array(mbit["planner-robust"]) - np.array(mbit["planner"]))
    print(f"  robust - plain (planner): {diff:+.1f} +- {half:.1f} Mbit")
    rows.append([preset, label, "planner-robust − planner", f"{diff:+.1f} ± {half:.1f}", ""])
    return rows


def main() -> None:
    json_path = json_option()
    missions = int(sys.argv[1]) if len(sys.argv) > 1 else size(200, 2)
    rows = []
    for preset in POLICIES:
        rows += compare(preset, missions)
    for label, faults in HOMEWARD.items():
        rows += homeward(label, faults, missions)
    columns = ["preset", "condition", "policy", "Mbit (mean ± 95% CI)", "ended home [%]"]
    write(json_path, {"resilience": results_table(columns, rows, align="lllrr")})


if __name__ == "__main__":
    main()
